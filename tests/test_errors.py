"""The exception tree (errors.py): bad input and a run that failed on the way are told apart, by a
caller's except clause and by the command's exit code."""
from __future__ import annotations

import signal

import pytest

import mechsweep
from mechsweep import errors, store
from mechsweep.execution import runner
from mechsweep.cli import main
from mechsweep.store.journal import BadChunk
from mechsweep.scene import SceneError

from .conftest import SWEEPS

INPUT = [errors.InputError, SceneError, errors.StoreError, errors.FileBusy, BadChunk]
RUN = [errors.RunError, errors.WriteFailed, errors.OutOfSpace, errors.ClusterLost, errors.RunInterrupted]


@pytest.mark.parametrize("cls", INPUT, ids=lambda c: c.__name__)
def test_bad_input_is_an_input_error_and_a_value_error(cls):
    assert issubclass(cls, errors.MechsweepError) and issubclass(cls, errors.InputError) and issubclass(cls, ValueError)
    assert not issubclass(cls, errors.RunError)


@pytest.mark.parametrize("cls", RUN, ids=lambda c: c.__name__)
def test_a_failed_run_is_a_run_error_not_bad_input(cls):
    """A full disk or a lost cluster is not a ValueError: `except ValueError` (or InputError,
    StoreError) around a run does not take it for bad input."""
    assert issubclass(cls, errors.MechsweepError) and issubclass(cls, errors.RunError) and issubclass(cls, RuntimeError)
    assert not issubclass(cls, ValueError) and not issubclass(cls, errors.InputError)


def test_the_names_users_catch_stay_importable_where_they_were():
    for name in ("MechsweepError", "InputError", "RunError", "StoreError", "FileBusy", "OutOfSpace", "ClusterLost",
                 "RunInterrupted"):
        assert getattr(mechsweep, name) is getattr(errors, name)
    assert mechsweep.SceneError is SceneError
    assert runner.OutOfSpace is errors.OutOfSpace and runner.RunInterrupted is errors.RunInterrupted
    assert store.StoreError is errors.StoreError
    assert errors.RunInterrupted("stopped").signum == signal.SIGINT


FAILURES = [
    (errors.OutOfSpace("disk full: 41.2 MiB needed on the disk of /x; journal kept"), 2),
    (errors.ClusterLost("lost the dask scheduler at tcp://h:1; journal kept"), 2),
    (errors.RunError("chunk files were found damaged again"), 2),
    (errors.StoreError("x.h5 holds a finished run of a different scene"), 2),
    (errors.RunInterrupted("interrupted: journal kept", signal.SIGTERM), 128 + signal.SIGTERM),
    (errors.RunInterrupted("interrupted: journal kept"), 128 + signal.SIGINT),
]


@pytest.mark.parametrize("exc, code", FAILURES, ids=lambda x: type(x).__name__ if isinstance(x, Exception) else str(x))
def test_the_run_command_exits_with_the_documented_code_and_one_line(exc, code, monkeypatch, capsys):
    """docs/cli.md: 2 for bad input and for a run that failed on the way (disk full, lost cluster: one
    line, the journal kept), 128 + the signal for an interruption."""
    def compute(*args, **kwargs):
        raise exc

    monkeypatch.setattr(runner, "compute", compute)
    assert main(["run", str(SWEEPS / "quickstart.toml"), "--no-progress"]) == code
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(exc) in err and "Traceback" not in err


def test_anything_else_is_a_bug_with_its_traceback(monkeypatch):
    def compute(*args, **kwargs):
        raise RuntimeError("a bug")

    monkeypatch.setattr(runner, "compute", compute)
    with pytest.raises(RuntimeError, match="a bug"):  # python exits 1 and prints it
        main(["run", str(SWEEPS / "quickstart.toml"), "--no-progress"])
