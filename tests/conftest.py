"""Shared fixtures: small scenes and a temporary working directory."""
from __future__ import annotations

import contextlib
import copy
import signal
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SWEEPS = REPO / "sweeps"
if str(REPO) not in sys.path:  # the developer benchmarks (benchmarks/) and tests/reference, imported from the root
    sys.path.insert(0, str(REPO))

SMALL_DUFFING = {
    "scene": {"name": "small", "model": "duffing",
              "outputs": ["period", "period_exact", "period_error", "kv", "epsilon"]},
    "axes": {"A": {"start": 0.1, "stop": 1.0, "num": 7},
             "mu": {"start": -0.5, "stop": 20.0, "num": 9}},
    "fixed": {"omega": 2.0},
    "solver": {"rtol": 1e-10, "atol": 1e-12},
    "storage": {"chunk_size": 10},
}


@pytest.fixture
def small_duffing():
    return copy.deepcopy(SMALL_DUFFING)


def assert_run_refused_naming(folder, capsys, scene, path, expected):
    """``mechsweep run SCENE`` exits 2 with a message naming ``path`` and each of ``expected``, no
    traceback, and no file written below ``folder``."""
    from mechsweep.cli import main

    def files():
        return sorted(p.relative_to(folder) for p in folder.rglob("*") if "__pycache__" not in p.parts)

    before = files()
    assert main(["run", str(scene), "--no-progress", "--threads", "1"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err, err
    for piece in expected:
        assert piece in err, err
    assert "Traceback" not in err
    assert files() == before


@pytest.fixture
def in_tmp(tmp_path, monkeypatch):
    """Run in an empty directory with a data/runs folder, like a fresh checkout."""
    (tmp_path / "data" / "runs").mkdir(parents=True)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@contextlib.contextmanager
def ctrl_c_as_from_a_terminal():
    """Children started inside the block get Ctrl-C's default action, as from a terminal. A suite
    started in the background by a script (``python -m pytest &``: a non-interactive shell starts it
    with SIGINT ignored) passes the ignored signal on to every child, where Python then installs no
    KeyboardInterrupt handler: a test that sends SIGINT to a child would see it ignored."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)

