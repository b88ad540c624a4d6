"""Loading a model is an input step: whatever ends it (sys.exit, os._exit, a KeyboardInterrupt or
another BaseException raised by the model's code, at import or when its functions are probed) is
exit 2 naming the file and line, through every door a model comes in (a file, "package.module:NAME",
an entry point, a module the model file imports). A real Ctrl-C or SIGTERM while a model loads is
still the interruption it is (130, 143). A model named in a file that is not a Python file says so.
Before: sys.exit(0) and os._exit(0) at import made `run` exit 0 with nothing written and nothing
said, a KeyboardInterrupt raised at import was reported as a SIGINT, /etc/passwd:X as a model gave
"AttributeError: 'NoneType' object has no attribute 'loader'"."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import pytest

import mechsweep
from mechsweep.cli import main
from mechsweep.errors import InputError
from mechsweep.model import user

from tests.conftest import ctrl_c_as_from_a_terminal

HERE = Path(__file__).resolve().parents[1]
USER = HERE / "user_models"
SRC = Path(mechsweep.__file__).resolve().parents[1]  # the children import the mechsweep this process tests


def scene(model: str) -> str:
    return (f'[scene]\nname = "exits"\nmodel = "{model}"\noutputs = ["y1"]\n[axes]\nk = [0.5, 1.0]\n'
            '[storage]\npath = "data/runs/exits.h5"\n')


@pytest.fixture
def importable(monkeypatch):
    monkeypatch.syspath_prepend(str(USER))  # helper modules and the exitpkg package, by name


@pytest.mark.parametrize("ref, fragments", [
    (f"{USER}/exit_sys.py:M", ["importing", "SystemExit(0) raised", f"{USER}/exit_sys.py, line 5", "may not exit"]),
    (f"{USER}/exit_base.py:M", ["Stop raised (a BaseException, not an Exception): no model today",
                                f"{USER}/exit_base.py, line 9"]),
    (f"{USER}/exit_via_helper.py:M", ["SystemExit(3) raised", f"{USER}/exit_helper_module.py, line 5",
                                      f"reached from {USER}/exit_via_helper.py, line 4"]),
    ("exitpkg.models:M", ["importing exitpkg.models", "SystemExit('bye') raised", "exitpkg/models.py, line 2"]),
    (f"{USER}/exit_probe.py:M", ["running its functions at the probe point", "SystemExit(0) raised",
                                 f"{USER}/exit_probe.py, line 18"]),
], ids=["sys_exit", "base_exception", "helper_module", "package_module", "at_the_probe"])
def test_an_exit_while_a_model_loads_is_an_input_error_with_file_and_line(ref, fragments, importable):
    with pytest.raises(InputError) as info:
        user.resolve(ref)
    for piece in fragments:
        assert piece in str(info.value), str(info.value)


def test_an_exit_in_an_entry_points_module_is_exit_2(in_tmp, importable, monkeypatch, capsys):
    ep = metadata.EntryPoint(name="exit_ep", value="exitpkg.models:M", group=user.ENTRY_POINT_GROUP)
    real = metadata.entry_points

    def entry_points(**kw):
        return metadata.EntryPoints([ep]) if kw.get("group") == user.ENTRY_POINT_GROUP else real(**kw)
    monkeypatch.setattr(metadata, "entry_points", entry_points)
    (in_tmp / "s.toml").write_text(scene("exit_ep"))
    for argv in (["check", "s.toml"], ["run", "s.toml", "--no-progress"], ["models", "exit_ep"]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "entry point 'exit_ep'" in err and "SystemExit('bye') raised" in err and "Traceback" not in err, err
    assert list((in_tmp / "data" / "runs").iterdir()) == []


def test_the_stand_ins_and_the_signal_handlers_are_put_back(importable):
    real_exit, real_abort = os._exit, os.abort
    handlers = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    with pytest.raises(InputError):
        user.resolve(f"{USER}/exit_sys.py:M")
    with pytest.raises(InputError, match=r"os\._exit\(7\) called"):
        with user.exits_refused("test"):
            os._exit(7)
    assert os._exit is real_exit and os.abort is real_abort
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == handlers


def _cli(tmp_path, model, *command, env=None):
    (tmp_path / "data" / "runs").mkdir(parents=True, exist_ok=True)
    (tmp_path / "s.toml").write_text(scene(model))
    with ctrl_c_as_from_a_terminal():
        return subprocess.Popen([sys.executable, "-m", "mechsweep", *command, "s.toml"], cwd=tmp_path, text=True,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                env={**os.environ, "PYTHONPATH": str(SRC), **(env or {})})


@pytest.mark.parametrize("file, said", [("exit_os.py", "os._exit(0) called"),
                                        ("exit_keyboard.py", "KeyboardInterrupt raised by the code (no Ctrl-C")])
@pytest.mark.parametrize("command", ["check", "run"])
def test_os_exit_and_a_raised_keyboard_interrupt_at_import_are_exit_2(tmp_path, file, said, command):
    """In a process of its own: os._exit would end the test run."""
    child = _cli(tmp_path, f"{USER}/{file}:M", command)
    out, err = child.communicate(timeout=300)
    assert child.returncode == 2, (child.returncode, out, err)
    assert said in err and f"{USER}/{file}, line" in err and "Traceback" not in err, err
    assert list((tmp_path / "data" / "runs").iterdir()) == []


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_real_signal_while_a_model_imports_is_still_an_interruption(tmp_path, sig):
    started = tmp_path / "started"
    child = _cli(tmp_path, f"{USER}/exit_slow.py:M", "run", env={"MECHSWEEP_TEST_STARTED": str(started)})
    deadline = time.monotonic() + 240
    while not started.exists() and child.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert started.exists(), child.communicate(timeout=60)
    child.send_signal(sig)
    out, err = child.communicate(timeout=120)
    assert child.returncode == 128 + sig, (child.returncode, err)
    assert f"interrupted ({signal.Signals(sig).name})" in err and "Traceback" not in err, err


@pytest.mark.parametrize("ref, said", [
    ("/etc/passwd:X", "/etc/passwd is not a Python file: a model file's name ends in .py"),
    ("/dev/null:X", "/dev/null is a character device, not a Python file"),
    (f"{HERE}:X", f"{HERE} is a folder, not a Python file"),
    (f"{USER}/exit_sys:M", f"{USER}/exit_sys does not exist (did you mean exit_sys.py?)"),
])
def test_a_model_file_that_is_not_a_python_file_is_named_as_what_it_is(ref, said, capsys):
    with pytest.raises(InputError) as info:
        user.resolve(ref)
    assert said in str(info.value) and "AttributeError" not in str(info.value), str(info.value)


def test_a_module_name_that_is_a_file_beside_the_scene_is_named_as_that_file(tmp_path):
    (tmp_path / "notes.txt").write_text("not Python\n")
    with pytest.raises(InputError, match=r"notes.txt is not a Python file: a model file's name ends in .py"):
        user.resolve("notes.txt:X", tmp_path)
    with pytest.raises(InputError, match=r"module 'no_such_module.sub' is not importable"):
        user.resolve("no_such_module.sub:X", tmp_path)


def test_models_command_on_a_file_that_is_not_python(capsys):
    assert main(["models", "/etc/passwd"]) == 2
    err = capsys.readouterr().err
    assert "/etc/passwd is not a Python file" in err and "Traceback" not in err, err
