"""User models through every door (issue 13, item 3): models= from Python, entry points,
`mechsweep models` for user models, a run resumed from another working directory, a dask
worker importing the user's file, and an rhs that raises only at some grid points.

All tests share one user model (tests/user_models/api_models.py, one StateAt measurement), so
its kernel is compiled once per cache."""
import math
import os
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

import mechsweep
from mechsweep.execution import execute, runner
from mechsweep import status as st
from mechsweep.cli import main
from mechsweep.errors import InputError
from mechsweep.store.journal import partial_path
from mechsweep.model import load, user

HERE = Path(__file__).parents[1] / "user_models"
FILE = HERE / "api_models.py"
SCENE_TEXT = """[scene]
name = "api"
model = "{model}"
outputs = ["x_at_1"]

[axes]
w = [0.5, 1.0, 1.5, 2.0]

[storage]
path = "out.h5"
chunk_size = 1

[solver]
rtol = 1e-12
atol = 1e-14
"""


@pytest.fixture(scope="module")
def osc():
    """The OdeModel object, imported from its file (the module mechsweep makes of that file, so
    every test here shares one compiled kernel)."""
    user.resolve(f"{FILE}:OSC")
    return load.import_module(load.module_name(FILE.resolve())).OSC


def _check(ds, w=(0.5, 1.0, 1.5, 2.0)):
    assert ds["w"].values.tolist() == list(w)
    np.testing.assert_allclose(ds["x_at_1"].values, np.cos(np.array(w)), rtol=0, atol=1e-9)
    assert (ds["status"].values == st.OK).all()


def _scene_folder(root: Path) -> Path:
    """root/scenes/s.toml naming tests/user_models/api_models.py by a path relative to root/scenes
    (not copied: one model file, one kernel for all tests)."""
    folder = root / "scenes"
    folder.mkdir()
    (folder / "s.toml").write_text(SCENE_TEXT.format(model=_ref(folder)))
    return folder


def _ref(folder: Path) -> str:
    return f"{os.path.relpath(FILE.resolve(), folder.resolve())}:OSC"


def test_run_accepts_an_ode_model_from_python(in_tmp, osc):
    scene = {"scene": {"name": "api", "model": "my_osc", "outputs": ["x_at_1"]},
             "axes": {"w": [0.5, 1.0, 1.5, 2.0]}, "solver": {"rtol": 1e-12, "atol": 1e-14}}
    ds = mechsweep.run(scene, output="a.h5", models={"my_osc": osc})
    _check(ds)
    assert ds.attrs["model"] == "api_oscillator"
    # the ModelSpec works as well
    ds = mechsweep.run(scene, output="b.h5", models={"my_osc": osc.spec()})
    _check(ds)
    # refused before anything is written: a built-in name, not a model, a cluster
    with pytest.raises(InputError, match="'duffing' is a built-in model"):
        mechsweep.run({**scene, "scene": {**scene["scene"], "model": "duffing"}}, output="c.h5",
                      models={"duffing": osc})
    with pytest.raises(InputError, match=r"models\['my_osc'\] is a int; expected a mechsweep.model.OdeModel"):
        mechsweep.run(scene, output="c.h5", models={"my_osc": 3})
    with pytest.raises(InputError, match="dask worker cannot import it"):
        mechsweep.run(scene, output="c.h5", models={"my_osc": osc}, scheduler="tcp://127.0.0.1:1")
    with pytest.raises(InputError, match="unknown model|not allowed|expected one of"):
        mechsweep.run(scene, output="c.h5")  # without models= the name means nothing
    assert sorted(p.name for p in in_tmp.iterdir()) == ["a.h5", "b.h5", "data"]


@pytest.fixture
def entry_point(monkeypatch):
    """An installed package registering tests/user_models/ep_models.py:OSC as "ep_osc"."""
    ep = metadata.EntryPoint(name="ep_osc", value="tests.user_models.ep_models:OSC", group=user.ENTRY_POINT_GROUP)
    real = metadata.entry_points

    def entry_points(**kw):
        if kw.get("group") == user.ENTRY_POINT_GROUP:
            return metadata.EntryPoints([ep])
        return real(**kw)
    monkeypatch.setattr(metadata, "entry_points", entry_points)
    return ep


def test_entry_point_model_runs_and_is_listed(in_tmp, entry_point, capsys):
    (in_tmp / "s.toml").write_text(SCENE_TEXT.format(model="ep_osc"))
    assert main(["run", "s.toml"]) == 0
    _check(mechsweep.open_dataset("out.h5"))
    capsys.readouterr()
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    assert "duffing:" in out and "ep_oscillator: x'' + w^2 x = 0" in out and "x_at_1" in out
    assert main(["models", "ep_osc"]) == 0
    assert capsys.readouterr().out.startswith("ep_oscillator:")


def test_one_file_under_two_module_names_shares_no_disk_cache_entry(tmp_path):
    """A model file the user imported under one name in one process (run(models=...)), then named
    by path in a scene in the next: before, numba loaded the first name's disk-cache entry and
    failed with "numba cannot compile initial: No module named ..." (exit 2 for ever after)."""
    path = tmp_path / "twice.py"
    path.write_text(FILE.read_text().replace("api_oscillator", "twice_oscillator"))
    first = (f"from mechsweep.model import load, user; "
             f"user.from_object('twice', load.import_module('twice_alias', {str(path)!r}).OSC)")
    second = f"from mechsweep.model import user; print(user.resolve({str(path) + ':OSC'!r}).name)"
    for code in (first, second):
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
        assert out.returncode == 0, out.stderr[-500:]
    assert out.stdout.strip() == "twice_oscillator"


def test_models_command_shows_a_user_model_by_file_or_scene(in_tmp, capsys):
    folder = _scene_folder(in_tmp)
    assert main(["models", f"{FILE}:OSC"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("api_oscillator:") and "w          [rad/s]" in out and "x_at_1" in out
    assert main(["models", "--scene", str(folder / "s.toml")]) == 0  # found relative to the scene
    assert capsys.readouterr().out == out
    assert main(["models", "api_models.py:OSC"]) == 2  # relative to the cwd: not there
    err = capsys.readouterr().err
    assert "api_models.py:OSC" in err and "does not exist" in err and "Traceback" not in err
    assert main(["models", "no_such_model"]) == 2
    assert "unknown model 'no_such_model'" in capsys.readouterr().err


def test_unfinished_run_reads_and_resumes_from_another_directory(tmp_path, monkeypatch):
    folder = _scene_folder(tmp_path)
    monkeypatch.chdir(folder)
    with pytest.MonkeyPatch.context() as mp:
        real, calls = execute.evaluate_chunk, {"n": 0}

        def flaky(scene, chunk, *rest):
            calls["n"] += 1
            if calls["n"] > 2:
                raise KeyboardInterrupt
            return real(scene, chunk, *rest)
        mp.setattr(execute, "evaluate_chunk", flaky)
        with pytest.raises(mechsweep.RunInterrupted):
            mechsweep.run("s.toml")
    elsewhere = tmp_path / "elsewhere" / "deeper"
    elsewhere.mkdir(parents=True)
    monkeypatch.chdir(elsewhere)  # the stored scene text's relative model path leads nowhere from here
    partial = mechsweep.open_dataset(folder / "out.h5", allow_partial=True)
    assert (partial["status"].values == st.PENDING).sum() == 2
    ds = mechsweep.run(folder / "s.toml", output=folder / "out.h5", resume=True)
    _check(ds)
    assert ds.attrs["scene_folder"] == str(folder.resolve())
    assert not partial_path(folder / "out.h5").exists()


def test_rhs_raising_at_a_point_the_probe_did_not_see_is_a_status(in_tmp, capsys):
    """The probe (w = 1) passes; at w = 3 the compiled rhs raises inside the parallel loop. numba does
    not propagate it; the generated guard flags the point: status USER_ERROR (no crash, no
    traceback), the others OK, and one warning line says why."""
    _scene_folder(in_tmp)
    text = SCENE_TEXT.format(model=_ref(in_tmp / "scenes")).replace("[0.5, 1.0, 1.5, 2.0]", "[1.0, 3.0, 2.0]")
    (in_tmp / "scenes" / "r.toml").write_text(text)
    from mechsweep.model import ode
    ode._EXPLAINED.clear()  # warned once per cause in a process
    assert main(["run", "scenes/r.toml", "-o", "r.h5"]) == 0
    err = capsys.readouterr().err
    # the replay in plain Python names the exception, the user's file and line, and the point
    assert "mechsweep run: warning: model 'api_oscillator': its own code raised (status user_error" in err
    assert "first seen at w = 3: rhs at t = 0 raised ValueError: w too large for this model" in err
    assert "api_models.py, line 9, in rhs" in err
    ds = mechsweep.open_dataset("r.h5")
    assert ds["status"].values.tolist() == [st.OK, st.USER_ERROR, st.OK]
    assert math.isnan(ds["x_at_1"].values[1])
    np.testing.assert_allclose(ds["x_at_1"].values[[0, 2]], np.cos([1.0, 2.0]), atol=1e-9)


def test_one_point_module_has_one_try_around_a_point(osc):
    """The one-point kernel catches a model's exception once per point, around point(): the model's
    functions are called without guards, compiled into their callers (a try per guard cost most of
    their compile). No compile."""
    import inspect

    from mechsweep.engine import events, floquet, point, shared
    from mechsweep.ode.methods import DOP853

    source = inspect.getsource(point._points)  # the loop over points
    tries = [line for line in source.splitlines() if line.strip().startswith("try:")]
    assert len(tries) == 1 and "code = point(i, " in source.split(tries[0])[1].split("except")[0]
    for module in (events, floquet, shared):  # the point and the measurements' blocks: no try of their own
        assert "try:" not in inspect.getsource(module)
    assert "try:" not in inspect.getsource(point._point)
    chosen, _ = osc._plan(("x_at_1",))
    plan = point.Plan(osc, chosen, (), DOP853)
    assert plan.equation().rhs is load.inlined(*load.function_ref(osc.rhs, "rhs", osc.name))


def test_guards_inline_a_users_function_only_when_it_has_no_raise_statement():
    """The one-point kernel's guards compile the model's functions into themselves (load.inlined; a
    compile of its own less per function), except one with a raise statement of its own: numba's try
    does not catch a raise inlined into its body (the test above then crashed the run). Cheap: no
    compile."""
    from mechsweep.model import load
    from mechsweep.models import duffing

    module = load.import_module(load.module_name(FILE.resolve()), str(FILE.resolve()))
    rhs = load.function_ref(module.OSC.rhs, "rhs", module.OSC.name)  # raises for w > 2.5
    initial = load.function_ref(module.OSC.initial, "initial", module.OSC.name)
    assert load.inlined(*rhs) is load.jitted(*rhs)
    assert load.inlined(*initial).targetoptions.get("inline") == "always"
    quarter = load.function_ref(duffing.quarter_event, "event0", "duffing")
    assert load.inlined(*quarter).targetoptions.get("inline") == "always"


@pytest.mark.slow  # a worker process and its JIT load: ~15-25 s on 2 cores
def test_dask_worker_imports_the_user_model_file_relative_to_the_scene(tmp_path, monkeypatch):
    """The worker gets the scene text (a model path relative to the scene) and the scene's absolute
    folder; its own working directory (here: another folder) plays no part."""
    distributed = pytest.importorskip("distributed")
    folder = _scene_folder(tmp_path)
    elsewhere = tmp_path / "elsewhere" / "deeper"
    elsewhere.mkdir(parents=True)
    monkeypatch.chdir(elsewhere)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        ds = mechsweep.run(folder / "s.toml", output=elsewhere / "d.h5", scheduler=c.scheduler_address, threads=1,
                           progress=False)
    _check(ds)
    assert ds.attrs["execution"].startswith("dask scheduler")
