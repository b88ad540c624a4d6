"""Closed-form models on the declarative layer (mechsweep.model.ClosedFormModel): a user's model from
a file outside the package sweeps, stores its curves over an extra dimension and resumes; bad user
closed-form models are refused (exit 2, file and line named, nothing written); the generated
kernel and the user's function come from numba's disk cache in a second process."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import mechsweep
from mechsweep import status as st
from mechsweep.cli import main
from mechsweep.errors import InputError
from mechsweep.store.journal import partial_path
from mechsweep.model import ClosedFormModel, ExtraDim, Output, Param
from mechsweep.scene import load_scene

from tests.data.interrupt import interrupted_after
from tests.conftest import assert_run_refused_naming

HERE = Path(__file__).resolve().parents[1]
CAM = HERE / "user_models" / "cam.py"


def cam_scene(outputs, chunk_size=None):
    scene = {"scene": {"name": "cam", "model": f"{CAM}:CAM", "outputs": list(outputs)},
             "axes": {"beta": {"start": 0.6, "stop": 2.0, "num": 8}, "law": ["cycloidal", "harmonic"]},
             "fixed": {"h": 0.02, "omega": 30.0, "rb": 0.04}}
    if chunk_size:
        scene["storage"] = {"chunk_size": chunk_size}
    return scene


def cam_exact(beta, law, h=0.02, omega=30.0):
    if law == "cycloidal":
        return 2 * h * omega / beta, 2 * math.pi * h * omega ** 2 / beta ** 2
    return math.pi * h * omega / (2 * beta), math.pi ** 2 * h * omega ** 2 / (2 * beta ** 2)


def check_cam(ds):
    u = np.linspace(0, 1, 101)
    assert ds["s_u"].dims == ("beta", "law", "u") and ds["u"].size == 101
    assert ds["a_u"].attrs["units"] == "m/s^2"
    n_ok = 0
    for i, beta in enumerate(ds["beta"].values):
        for j, law in enumerate(ds["law"].values):
            code = int(ds["status"].values[i, j])
            alpha = np.arctan(np.max(np.gradient(ds["s_u"].values[i, j], u * beta)
                                     / (0.04 + ds["s_u"].values[i, j]))) if code == st.OK else None
            if code != st.OK:
                assert code == st.INFEASIBLE  # jams: steep rise on a small cam
                assert np.isnan(ds["v_max"].values[i, j]) and np.isnan(ds["s_u"].values[i, j]).all()
                continue
            n_ok += 1
            v, a = cam_exact(beta, str(law))
            assert ds["v_max"].values[i, j] == pytest.approx(v, rel=1e-12)
            assert ds["a_max"].values[i, j] == pytest.approx(a, rel=1e-12)
            assert ds["pressure_angle_max"].values[i, j] == pytest.approx(alpha, rel=2e-3)
            if law == "cycloidal":
                ref = 0.02 * (u - np.sin(2 * np.pi * u) / (2 * np.pi))
            else:
                ref = 0.01 * (1 - np.cos(np.pi * u))
            np.testing.assert_allclose(ds["s_u"].values[i, j], ref, rtol=1e-13, atol=1e-16)
            assert np.abs(ds["a_u"].values[i, j]).max() == pytest.approx(a, rel=1e-12)
    assert 0 < n_ok < ds["status"].size  # both statuses occur on this grid


def test_user_closed_form_model_sweeps_and_stores_curves(in_tmp):
    ds = mechsweep.run(cam_scene(["v_max", "a_max", "pressure_angle_max", "s_u", "a_u"]), output="cam.h5",
                       progress=False)
    check_cam(ds)


def test_user_closed_form_model_resumes_to_the_same_dataset(in_tmp):
    outputs = ["v_max", "a_max", "pressure_angle_max", "s_u", "a_u"]
    ref = mechsweep.run(cam_scene(outputs, chunk_size=3), output="ref.h5", progress=False)
    with interrupted_after(2), pytest.raises(mechsweep.RunInterrupted):
        mechsweep.run(cam_scene(outputs, chunk_size=3), output="out.h5", progress=False)
    partial = mechsweep.open_dataset("out.h5", allow_partial=True)
    pending = int((partial["status"].values == st.PENDING).sum())
    assert 0 < pending < 16  # two chunks were stored, the rest is missing
    ds = mechsweep.run(cam_scene(outputs, chunk_size=3), output="out.h5", resume=True, progress=False)
    assert not partial_path(in_tmp / "out.h5").exists()
    for name in outputs + ["status"]:
        np.testing.assert_array_equal(ds[name].values, ref[name].values, err_msg=name)
    check_cam(ds)


def test_only_wanted_curves_are_computed_and_slots_follow_them():
    """A curve asked for alone lands in slot 0 (the other curve has slot -1 and is skipped)."""
    scene = load_scene(cam_scene(["a_u"]))
    spec = scene.model
    P = np.array([[0.02, 1.5, 30.0, 0.0, 0.04, math.pi / 6]])
    out = {"a_u": np.full((1, 101), np.nan)}
    status = np.zeros(1, st.DTYPE)
    spec.evaluate(P, ("a_u",), None, out, status, None, None)
    assert status[0] == st.OK
    u = np.linspace(0, 1, 101)
    np.testing.assert_allclose(out["a_u"][0], 2 * np.pi * 0.02 * 900 / 1.5 ** 2 * np.sin(2 * np.pi * u),
                               rtol=1e-12, atol=1e-12)
    # another length of the extra dimension (8th argument), e.g. for a convergence study
    out = {"a_max": np.full(1, np.nan), "a_u": np.full((1, 11), np.nan)}
    spec.evaluate(P, ("a_max", "a_u"), None, out, status, None, None, 11)
    u11 = np.linspace(0, 1, 11)  # no sample at x = 1/4 now: the sampled maximum is lower
    assert out["a_max"][0] == pytest.approx(2 * np.pi * 0.02 * 900 / 1.5 ** 2 * np.abs(np.sin(2 * np.pi * u11)).max(),
                                            rel=1e-12)
    np.testing.assert_allclose(out["a_u"][0], 2 * np.pi * 0.02 * 900 / 1.5 ** 2 * np.sin(2 * np.pi * u11),
                               rtol=1e-12, atol=1e-12)


def test_run_accepts_a_closed_form_model_object(in_tmp):
    """mechsweep.run(scene, models={name: ClosedFormModel}) checks it as a file's model and runs it."""
    from mechsweep.model import load, user

    user.resolve(f"{CAM}:CAM")  # imports the file as mechsweep makes a module of it
    model = load.import_module(load.module_name(CAM.resolve()), str(CAM.resolve())).CAM
    assert isinstance(model, ClosedFormModel)
    scene = cam_scene(["v_max", "a_max", "pressure_angle_max", "s_u", "a_u"])
    scene["scene"]["model"] = "my_cam"
    check_cam(mechsweep.run(scene, output="obj.h5", progress=False, models={"my_cam": model}))


def test_declaration_errors():
    d1 = ExtraDim("u", "1", "u", values=lambda s: np.zeros(3))
    d2 = ExtraDim("w", "1", "w", values=lambda s: np.zeros(3))
    kw = dict(name="m", description="d", params=(Param("k", "k", "1", "k"),), compute=len, size=3)
    with pytest.raises(ValueError, match="same single extra dimension"):
        ClosedFormModel(outputs=(Output("a", "a", "1", "a", extra_dims=(d1,)),
                                 Output("b", "b", "1", "b", extra_dims=(d2,))), **kw)
    with pytest.raises(ValueError, match="output names repeat"):
        ClosedFormModel(outputs=(Output("a", "a", "1", "a"), Output("a", "a", "1", "a")), **kw)
    with pytest.raises(ValueError, match="size must be"):
        ClosedFormModel(outputs=(Output("a", "a", "1", "a"),), **dict(kw, size=0))


# ---------------------------------------------------------------- bad user models: exit 2, file and line named
HEAD = ("import math\nimport fractions\nimport numpy as np\nfrom mechsweep.model import ClosedFormModel, ExtraDim, "
        "Output, Param\n\n\n"  # lines 1-4
        "def grid(n):\n    return (np.linspace(0.0, 1.0, n),)\n\n\n"  # lines 7-8
        "def compute(p, want, row, curves, slot, scratch, x):\n"  # line 11
        "    for j in range(x.shape[0] if slot[0] >= 0 else 0):\n"  # line 12
        "        curves[slot[0], j] = p[0] * x[j]\n")  # line 13; line 14 is the body under test
TAIL = ('\n\nX = ExtraDim("x", "1", "x", values=lambda s: np.linspace(0.0, 1.0, 5))\n'
        'M = ClosedFormModel(name="bad", description="d", params=(Param("k", "k", "1", "k", lo=0.0),), '
        'outputs=(Output("top", "t", "1", "t"), Output("line", "l", "1", "l", extra_dims=(X,))), '
        'compute=compute, size=5, data=grid)\nNOT_A_MODEL = 3\n')
GOOD = "    row[0] = p[0]\n    return 0"
BAD = {
    "does_not_compile": ("    row[0] = float(fractions.Fraction(1, 2)) * p[0]\n    return 0", "M",
                         ["numba cannot compile compute", "line 14"]),
    "undeclared_param": ("    row[0] = p[1]\n    return 0", "M",
                         ["compute indexes beyond", "1 parameter(s)", "line 14"]),
    "output_beyond_row": ("    row[0] = p[0]\n    row[1] = 0.0\n    return 0", "M",
                          ["compute indexes beyond", "1 scalar output(s)", "line 15"]),
    "scratch_not_declared": ("    scratch[0, 0] = 1.0\n    row[0] = p[0]\n    return 0", "M",
                             ["compute indexes beyond", "0 scratch row(s)", "line 14"]),
    "raises": ("    raise ValueError('negative lift')", "M", ["compute raised", "negative lift", "line 14"]),
    "unwritten_output": ("    return 0", "M", ["without writing top"]),
    "no_status": ("    row[0] = p[0]", "M", ["compute returned None", "expected a status code"]),
    # the probe point (k = 1) takes the early return; the path it skips returns no status: the compiled
    # kernel failed there on None inside its parallel loop (a traceback, exit 1)
    "bare_return_off_the_probe": ("    if p[0] > 0.5:\n        return 4\n    row[0] = p[0]\n    return", "M",
                                  ["compute can return None", "OptionalType(int64)", "a return without a value",
                                   "line 17)"]),
    "end_reached_off_the_probe": ("    if p[0] > 0.5:\n        return 4\n    row[0] = p[0]", "M",
                                  ["compute can return None", "its end is reached without a return", "line 16)"]),
    "float_status_off_the_probe": ("    if p[0] > 0.5:\n        return 4\n    row[0] = p[0]\n    return 0.5", "M",
                                   ["compute returns float64, not a status code"]),
    "missing_name": (GOOD, "NOPE", ["does not define 'NOPE'", "models it defines: M"]),
    "not_a_model": (GOOD, "NOT_A_MODEL", ["is a int, not a mechsweep.model.OdeModel or ClosedFormModel"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_user_closed_form_model_exits_2_naming_the_file_and_writes_nothing(case, in_tmp, capsys):
    path = in_tmp / f"bad_{case}.py"
    body, name, expected = BAD[case]
    path.write_text(HEAD + body + TAIL)
    scene = in_tmp / "s.toml"
    scene.write_text(f'[scene]\nname = "bad"\nmodel = "{path.name}:{name}"\noutputs = ["top", "line"]\n'
                     '[axes]\nk = { start = 1.0, stop = 2.0, num = 2 }\n')
    assert_run_refused_naming(in_tmp, capsys, scene, path, expected)


@pytest.mark.parametrize("latex,why", [("$k_{$", "matplotlib's mathtext parser cannot read it"),
                                        ("k_0", "it is not mathtext between $ signs")])
def test_a_latex_matplotlib_cannot_read_is_refused_at_loading_naming_it(latex, why, in_tmp, capsys):
    """A declared latex labels every figure of the model: one matplotlib's mathtext parser cannot read
    was dropped silently when a figure was drawn; it is refused at loading, naming it (exit 2)."""
    path = in_tmp / "latex.py"
    path.write_text(HEAD + GOOD + TAIL.replace('Param("k", "k", "1", "k", lo=0.0)',
                                               f'Param("k", "k", "1", "k", lo=0.0, latex={latex!r})'))
    scene = in_tmp / "s.toml"
    scene.write_text(f'[scene]\nname = "l"\nmodel = "latex.py:M"\noutputs = ["top"]\n[axes]\nk = [1.0, 2.0]\n')
    assert main(["check", str(scene)]) == 2
    err = capsys.readouterr().err
    assert f"parameter 'k': latex = {latex!r}: {why}" in err, err


def test_good_template_runs(in_tmp):
    """The template of the bad cases, with a correct body, runs (so each bad case fails for its own line)."""
    path = in_tmp / "good.py"
    path.write_text(HEAD + GOOD + TAIL)
    ds = mechsweep.run({"scene": {"name": "g", "model": f"{path}:M", "outputs": ["top", "line"]},
                        "axes": {"k": [1.0, 2.0]}}, output="g.h5", progress=False)
    np.testing.assert_array_equal(ds["top"].values, [1.0, 2.0])
    np.testing.assert_array_equal(ds["line"].values, np.outer([1.0, 2.0], np.linspace(0, 1, 5)))


def test_compute_raising_at_a_point_the_probe_did_not_see_is_a_user_error_with_a_warning(in_tmp):
    """The probe (k = 1) passes; at k = 3 the compiled compute raises inside the parallel loop: that
    design is USER_ERROR (as an OdeModel's point is; it was NONFINITE, without a word) with NaN
    outputs, the others are computed, and the run warns once with the exception replayed in plain
    Python, its file and line and the design."""
    from mechsweep.errors import UserModelWarning

    path = in_tmp / "late.py"
    path.write_text(HEAD + "    if p[0] > 2.5:\n        raise ValueError('too stiff')\n" + GOOD + TAIL)
    with pytest.warns(UserModelWarning) as seen:
        ds = mechsweep.run({"scene": {"name": "late", "model": f"{path}:M", "outputs": ["top", "line"]},
                            "axes": {"k": [1.0, 3.0, 2.0]}}, output="late.h5", progress=False)
    text = " ".join(str(w.message) for w in seen if issubclass(w.category, UserModelWarning))
    assert "first seen at k = 3: compute raised ValueError: too stiff" in text, text
    assert f"{path}, line 15, in compute" in text, text
    assert ds["status"].values.tolist() == [st.OK, st.USER_ERROR, st.OK]
    assert np.isnan(ds["top"].values[1]) and np.isnan(ds["line"].values[1]).all()
    np.testing.assert_array_equal(ds["top"].values[[0, 2]], [1.0, 2.0])


def test_declared_statuses_add_to_those_the_outputs_imply():
    """statuses=(INFEASIBLE,) lists infeasible beside nonfinite and user_error, which the runner gives
    any model (a declared list replaced them before: a docs-only trial lost them from `models`)."""
    import dataclasses

    from mechsweep.model import user
    spec = user.resolve(f"{CAM}:CAM")
    assert set(dataclasses.replace(spec, statuses=()).possible_statuses()) == {st.OK, st.NONFINITE, st.USER_ERROR}
    declared = dataclasses.replace(spec, statuses=(st.INFEASIBLE,)).possible_statuses()
    assert declared == (st.OK, st.NONFINITE, st.INFEASIBLE, st.USER_ERROR)


def test_user_error_warnings_name_a_categorical_parameter_by_its_choice():
    """The user_error warning says where a model's code raised as a scene gives the point: a
    categorical parameter by its choice's name (it said 'spring = 0', the index the kernel gets),
    for an OdeModel and a ClosedFormModel alike (diagnose.point_text); nothing is compiled."""
    import warnings

    from mechsweep.errors import UserModelWarning
    from mechsweep.model import OdeModel, Period, closed, ode

    params = (Param("k", "k", "1", "k", lo=0.0), Param("law", "law", "1", "law", choices=("linear", "cubic")))

    def rhs(t, y, p, dydt):
        if p[1] == 1.0:
            raise ValueError("cubic law not written yet")
        dydt[0] = y[1]
        dydt[1] = -p[0] * y[0]

    def initial(p, y0):
        y0[0] = 1.0
        y0[1] = 0.0

    def compute(p, want, row, curves, slot, scratch):
        if p[1] == 1.0:
            raise ValueError("cubic law not written yet")
        row[0] = p[0]
        return 0

    P = np.array([[2.0, 0.0], [3.0, 1.0]])
    status = np.array([st.OK, st.USER_ERROR], dtype=st.DTYPE)
    o_model = OdeModel(name="cat_ode", description="d", params=params, states=("x", "v"), rhs=rhs, initial=initial,
                       measurements=(Period("period", "x"),))
    c_model = ClosedFormModel(name="cat_closed", description="d", params=params, outputs=(Output("o", "o", "1", "o"),),
                              compute=compute)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        ode._warn_user_error(o_model, P, status, np.zeros(0), 1e-10)
        closed._warn_user_error(c_model, P, status, np.ones(1, dtype=bool), np.zeros(0, dtype=np.int64), 0, 1, ())
    texts = [str(w.message) for w in seen if issubclass(w.category, UserModelWarning)]
    assert len(texts) == 2, texts
    for text in texts:
        assert "first seen at k = 3, law = cubic:" in text and "ValueError: cubic law not written yet" in text, text
    assert "rhs at t = 0 raised" in texts[0] and "compute raised" in texts[1], texts


def test_the_user_error_description_says_where_the_message_goes():
    """The status description stored with every dataset points to the warning that carries the
    exception's message (the replay above), not to a message that is lost."""
    text = st.DESCRIPTIONS[st.USER_ERROR]
    assert "lost" not in text and "UserModelWarning" in text and "file and line" in text, text


def test_a_status_code_that_is_none_of_mechsweeps_is_a_user_error(in_tmp):
    """compute returns 99 (or -1, PENDING's code) at designs the probe (k = 1) did not see, after writing
    its row: those designs are USER_ERROR with NaN outputs, not stored as codes no reader knows."""
    path = in_tmp / "code.py"
    path.write_text(HEAD + "    row[0] = p[0]\n    if p[0] > 2.5:\n        return 99\n"
                    "    if p[0] < 0.5:\n        return -1\n    return 0" + TAIL)
    ds = mechsweep.run({"scene": {"name": "code", "model": f"{path}:M", "outputs": ["top", "line"]},
                        "axes": {"k": [1.0, 3.0, 0.2, 2.0]}}, output="code.h5", progress=False)
    assert ds["status"].values.tolist() == [st.OK, st.USER_ERROR, st.USER_ERROR, st.OK]
    assert np.isnan(ds["top"].values[[1, 2]]).all() and np.isnan(ds["line"].values[[1, 2]]).all()
    np.testing.assert_array_equal(ds["top"].values[[0, 3]], [1.0, 2.0])


def test_a_closed_form_user_model_from_python_is_checked():
    from mechsweep.model import user

    def compute(p, want, row, curves, slot, scratch):
        row[0] = p[0]
        return 0
    bad = ClosedFormModel(name="local", description="d", params=(Param("k", "k", "1", "k"),),
                          outputs=(Output("a", "a", "1", "a"),), compute=compute)
    with pytest.raises(InputError, match="compute must be a function defined at the top level"):
        user.from_object("local", bad)


# ---------------------------------------------------------------- disk cache
PROBE = """
import json, sys
import numpy as np
from mechsweep.scene import load_scene
from mechsweep.model import closed, load

scene = load_scene({"scene": {"name": "probe", "model": sys.argv[1], "outputs": ["a_max", "s_u"]},
                    "axes": {"beta": [1.0, 2.0]}, "fixed": {"h": 0.02, "omega": 30.0}})
P = np.array([[0.02, 1.0, 30.0, 0.0, 0.05, 0.5236], [0.02, 2.0, 30.0, 1.0, 0.05, 0.5236]])
out = {"a_max": np.full(2, np.nan), "s_u": np.full((2, 101), np.nan)}
status = np.zeros(2, np.int8)
scene.model.evaluate(P, ("a_max", "s_u"), scene.solver, out, status, None, None)
dispatchers = list(closed._KERNELS.values()) + list(load._JITTED.values())
print(json.dumps({"a_max": out["a_max"].tolist(),
                  "misses": sum(sum(d.stats.cache_misses.values()) for d in dispatchers),
                  "hits": sum(sum(d.stats.cache_hits.values()) for d in dispatchers),
                  "n": len(dispatchers)}))
"""


def test_second_process_compiles_nothing_for_a_closed_form_user_model(tmp_path):
    """numba's cache statistics (not timing): the generated kernel and the user's compute are both
    loaded from the disk cache in a second fresh process."""
    env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(tmp_path), PYTHONPATH=str(HERE.parent / "src"))
    runs = []
    for _ in range(2):
        res = subprocess.run([sys.executable, "-c", PROBE, f"{CAM}:CAM"], capture_output=True, text=True, env=env,
                             cwd=tmp_path)
        assert res.returncode == 0, res.stderr
        runs.append(json.loads(res.stdout.strip().splitlines()[-1]))
    first, second = runs
    assert first["misses"] > 0  # the first process did compile (an empty cache)
    assert second["misses"] == 0 and second["hits"] == second["n"] == 2
    assert second["a_max"] == first["a_max"]
    assert list(tmp_path.rglob("mechsweep_closed_*.py"))  # the kernel's module lives in the cache folder


BUILTIN_PROBE = """
import json
import numpy as np
from benchmarks import linkage as bl
from mechsweep.model import closed, load

out, status = bl.mechsweep_residuals(bl.design_family(50, 1))
dispatchers = list(closed._KERNELS.values()) + list(load._JITTED.values())
print(json.dumps({"R_axis": out["R_axis"].tolist(),
                  "misses": sum(sum(d.stats.cache_misses.values()) for d in dispatchers),
                  "kernel_hits": sum(sum(d.stats.cache_hits.values()) for d in closed._KERNELS.values()),
                  "n_kernels": len(closed._KERNELS)}))
"""


@pytest.mark.slow  # compiles the four-bar model from an empty cache (about 20 s)
def test_second_process_compiles_nothing_for_the_builtin_fourbar(tmp_path):
    """The built-in linkage models go through the same generated module: in a second process the
    kernel comes from numba's disk cache (the per-design function is compiled into it: not
    compiled again either)."""
    env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(tmp_path),
               PYTHONPATH=os.pathsep.join([str(HERE.parent / "src"), str(HERE.parent)]))  # mechsweep; benchmarks
    runs = []
    for _ in range(2):
        res = subprocess.run([sys.executable, "-c", BUILTIN_PROBE], capture_output=True, text=True, env=env,
                             cwd=tmp_path)
        assert res.returncode == 0, res.stderr
        runs.append(json.loads(res.stdout.strip().splitlines()[-1]))
    first, second = runs
    assert first["misses"] > 0
    assert second["misses"] == 0 and second["kernel_hits"] == second["n_kernels"] == 1
    assert second["R_axis"] == first["R_axis"]


@pytest.mark.slow  # a worker process and its JIT load: ~15-25 s on 2 cores
def test_dask_worker_runs_a_closed_form_user_model(tmp_path, monkeypatch):
    """The worker resolves the model file relative to the scene's folder, as for ODE models."""
    import shutil

    distributed = pytest.importorskip("distributed")
    (tmp_path / "models").mkdir()
    shutil.copy(CAM, tmp_path / "models" / "cam.py")
    (tmp_path / "s.toml").write_text(
        '[scene]\nname = "cam"\nmodel = "models/cam.py:CAM"\n'
        'outputs = ["v_max", "a_max", "pressure_angle_max", "s_u", "a_u"]\n'
        '[axes]\nbeta = { start = 0.6, stop = 2.0, num = 8 }\nlaw = ["cycloidal", "harmonic"]\n'
        '[fixed]\nh = 0.02\nomega = 30.0\nrb = 0.04\n[storage]\nchunk_size = 4\n')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        ds = mechsweep.run(tmp_path / "s.toml", output=elsewhere / "d.h5", scheduler=c.scheduler_address, threads=1,
                           progress=False)
    assert ds.attrs["execution"].startswith("dask scheduler")
    check_cam(ds)


def test_mechsweep_models_describes_a_closed_form_user_model(capsys):
    assert main(["models", f"{CAM}:CAM"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("cam_rise:") and "s_u" in out and "(per u)" in out and "law" in out


def test_engine_keeps_a_per_design_function_without_reference_counting():
    """The four-bar's and slider-crank's per-design functions are jit_noalloc: compiled with numba's
    reference counting, every call paid atomic increments and decrements for the views it takes of
    its arrays (docs/performance.md, "Reference counting in the kernels"). The engine compiles its
    own copy of a model's function (load.jitted): that copy must keep the option; a plain one gets none."""
    from mechsweep import special
    from mechsweep.model import load
    from mechsweep.models import fourbar_balancing, slidercrank_balancing

    for f in (fourbar_balancing.fourbar_design, slidercrank_balancing.slider_design):
        assert load.jitted(*load.function_ref(f, "compute", "m")).targetoptions.get("_nrt") is False
    assert load.jitted(*load.function_ref(special.ellipk, "compute", "m")).targetoptions.get("_nrt") is not False
