"""The engine side of the model layer: methods, per-point preparation, FirstEvent, closed forms, and
the built-in Duffing declared on it.

The Duffing reference values (tests/data/duffing_reference.npz, torsional_circuit_reference.npz)
were written by tests/data/record_reference.py on the code before the built-in Duffing moved onto
the layer (commit 28a0ab7, hand-written chunk kernels): outputs, status, n_steps and n_rhs of every
method, several output subsets, tight and loose tolerances, a step budget and a short horizon, over
a grid with every status the model gives. The layer must reproduce them bit for bit."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.model import user
from mechsweep.models import MODELS
from mechsweep.scene import SceneError, load_scene
from tests.evaluating import evaluate as _evaluate

DATA = Path(__file__).resolve().parents[1] / "data"
USER = Path(__file__).resolve().parents[1] / "user_models" / "layer_methods.py"
_spec = importlib.util.spec_from_file_location("record_reference", DATA / "record_reference.py")
rr = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(rr)
slow = pytest.mark.slow


def _compare(model, method):
    ref = np.load(DATA / f"{model}_reference.npz")
    n = 0
    for label, P, wanted, kw in rr.cases(model):
        if not label.startswith(method + "-"):
            continue
        out, status, n_steps, n_rhs = rr.evaluate_case(MODELS[model], P, wanted, kw)
        for key, value in {**out, "status": status, "n_steps": n_steps, "n_rhs": n_rhs}.items():
            expected = ref[f"{label}/{key}"]
            assert value.dtype == expected.dtype and np.array_equal(value, expected, equal_nan=True), \
                f"{model} {label} {key}: differs from the hand-written kernels' values"
            n += 1
    assert n > 20


@pytest.mark.parametrize("method", ["dop853", pytest.param("radau", marks=slow),
                                    pytest.param("symplectic", marks=slow), pytest.param("auto", marks=slow)])
def test_duffing_on_the_layer_is_bitwise_the_hand_written_kernels(method):
    _compare("duffing", method)


@slow
def test_torsional_circuit_unchanged_bitwise():
    _compare("torsional_circuit", "dop853")


def test_duffing_spec_is_a_declaration_with_every_method():
    from mechsweep.models import duffing

    assert duffing.SPEC.methods == ("dop853", "radau", "symplectic", "auto")
    assert duffing.SPEC.output_names() == ("period", "period_exact", "period_error", "v_max", "a_max", "kv", "ka",
                                           "epsilon")
    assert duffing.SPEC.output("kv").needs == () and duffing.SPEC.output("period_error").needs == (
        "period", "period_exact")
    for name in ("period_kernel", "algebraic_kernel", "quarter_period", "make_quarter_period"):
        assert not hasattr(duffing, name), f"duffing.py still defines {name}"


def _user():
    return user.resolve(f"{USER}:LINEAR")


@pytest.mark.parametrize("method", ["dop853", pytest.param("radau", marks=slow), pytest.param("symplectic", marks=slow),
                                    pytest.param("auto", marks=slow)])
def test_user_model_methods_prepare_and_closed_forms(method):
    spec = _user()
    assert spec.methods == ("dop853", "radau", "symplectic", "auto")  # accel declared: symplectic offered
    P = np.array([[1.0, 0.5], [2.0, -0.3], [0.7, 0.0], [6.0, 1.0]])
    out, status, ns, _ = _evaluate(spec, P, ("period", "period_exact", "period_error"), method=method,
                                   rtol=1e-10, atol=1e-12)
    # released at -0.3 the event's sign (an internal slot prepare wrote) follows: still the period
    np.testing.assert_allclose(out["period"][:2], 2 * np.pi / P[:2, 0], rtol=1e-8)
    assert (out["period_error"][:2] < 1e-8).all()
    assert status.tolist() == [st.OK, st.OK, st.NO_MOTION, st.INFEASIBLE]  # classify, then prepare
    assert np.isnan(out["period_exact"][2]) and out["period_exact"][3] == 2 * np.pi / 6.0  # kept after prepare
    assert np.isnan(out["period"][3]) and np.isnan(out["period_error"][3]) and ns[3] == 0
    # the horizon is a setting in p: too short, no event (the outputs above: their kernel, no other)
    out, status, _, _ = _evaluate(spec, P[:1], ("period", "period_exact", "period_error"), method=method, rtol=1e-10,
                                  atol=1e-12, horizon=1.0)
    assert status[0] == st.NO_EVENT


def test_closed_forms_alone_need_no_solver_and_no_integration():
    spec = _user()
    P = np.array([[1.0, 0.5], [2.0, 0.0]])
    out = {"period_exact": np.full(2, np.nan)}
    status, ns, nr = np.zeros(2, np.int8), np.zeros(2, np.int64), np.zeros(2, np.int64)
    spec.evaluate(P, ("period_exact",), None, out, status, ns, nr)
    assert out["period_exact"][0] == 2 * np.pi and np.isnan(out["period_exact"][1])
    assert status.tolist() == [st.OK, st.NO_MOTION] and (ns == 0).all()


def test_a_method_the_model_or_measurement_does_not_offer_is_refused():
    base = {"scene": {"name": "x", "model": "user_models/oscillators.py:LINEAR", "outputs": ["period"]},
            "axes": {"w": {"start": 1.0, "stop": 2.0, "num": 2}}, "fixed": {"A": 0.5},
            "solver": {"method": "symplectic"}}
    root = Path(__file__).resolve().parents[1]
    with pytest.raises(SceneError, match=r"solver.method.*'symplectic'.*allowed: dop853, radau, auto"):
        _load(base, root)
    base["solver"]["method"] = "radau"  # offered by the model, but Period observes the shared dop853 trajectory
    with pytest.raises(SceneError, match=r"solver.method: 'radau' is not offered .* for the outputs period "
                                         r"\(allowed for them: dop853\)"):
        _load(base, root)


def _load(scene, root):
    import os

    cwd = os.getcwd()
    os.chdir(root)
    try:
        return load_scene(scene)
    finally:
        os.chdir(cwd)


# the one-point kernel in the default suite; the SIMD-lane kernel (a run of this size takes it only
# when told to) is slow: about 20 s more of compile, for a kernel of its own
@pytest.mark.parametrize("lanes", [False, pytest.param(True, marks=slow)], ids=["point", "lanes"])
def test_an_exception_in_the_models_code_at_run_time_is_user_error(monkeypatch, lanes):
    """The probe (w = 1) passes; inside the kernel the closed form raises for w > 2 and the event for
    w > 3: those points get USER_ERROR (not NONFINITE) and NaN, the others are computed (the event's
    exception in the one-point kernel and in the SIMD-lane kernel)."""
    from mechsweep.errors import UserModelWarning
    from mechsweep.engine import kernels as mc
    from mechsweep.model import ode
    monkeypatch.setattr(mc, "USE_LANES", lanes)
    ode._EXPLAINED.clear()  # warned once per cause in a process
    spec = user.resolve(f"{USER}:RAISING")
    P = np.array([[1.0, 0.5], [2.5, 0.5], [4.0, 0.5]])
    with pytest.warns(UserModelWarning, match=r"at w = 2.5, .*closed form inverse raised ValueError: w too large "
                      r"for this formula \(.*layer_methods.py, line 85, in raising_closed_form\)"):
        out, status, _, _ = _evaluate(spec, P, ("inverse",))
    assert status.tolist() == [st.OK, st.USER_ERROR, st.USER_ERROR] and out["inverse"][0] == 1.0
    assert np.isnan(out["inverse"][1:]).all()
    with pytest.warns(UserModelWarning, match=r"period: event at t = 0 raised ValueError: w too large for this event"):
        out, status, _, _ = _evaluate(spec, P, ("period",), rtol=1e-10, atol=1e-12)
    assert status.tolist() == [st.OK, st.OK, st.USER_ERROR] and np.isnan(out["period"][2])
    np.testing.assert_allclose(out["period"][:2], 2 * np.pi / P[:2, 0], rtol=1e-8)
    assert st.MEANINGS[st.USER_ERROR] == "user_error"


_BUILTIN_PROBE = """
import json
import numpy as np
from mechsweep.engine import kernels as mc
from mechsweep.model import load
from mechsweep.models import duffing
P = np.array([[1.0, 0.5, 0.5], [2.0, -0.1, 1.0]])
wanted = ("period", "period_exact", "kv")
out = {k: np.full(2, np.nan) for k in wanted}
status, ns, nr = np.zeros(2, np.int8), np.zeros(2, np.int64), np.zeros(2, np.int64)
from mechsweep.scene import Solver
duffing.evaluate(P, wanted, Solver.for_model(duffing.SPEC), out, status, ns, nr)
ds = list(mc._KERNELS.values()) + list(load._JITTED.values())
print(json.dumps({"period": out["period"].tolist(), "n": len(ds),
                  "kernel_hits": sum(sum(k.stats.cache_hits.values()) for k in mc._KERNELS.values()),
                  "misses": sum(sum(d.stats.cache_misses.values()) for d in ds),
                  "hits": sum(sum(d.stats.cache_hits.values()) for d in ds)}))
"""


@slow
def test_second_process_compiles_nothing_for_the_built_in_duffing(tmp_path):
    """The built-in model takes the generated-module route too: a second fresh process loads its
    kernel and the model's functions from numba's disk cache (cache statistics, not timing)."""
    import json
    import os
    import subprocess
    import sys

    env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(tmp_path),
               PYTHONPATH=str(Path(__file__).resolve().parents[2] / "src"))
    runs = []
    for _ in range(2):
        res = subprocess.run([sys.executable, "-c", _BUILTIN_PROBE], capture_output=True, text=True, env=env,
                             cwd=tmp_path)
        assert res.returncode == 0, res.stderr
        runs.append(json.loads(res.stdout.strip().splitlines()[-1]))
    first, second = runs
    assert first["misses"] > 0
    assert second["misses"] == 0 and second["kernel_hits"] == 1  # the model's functions: not even loaded
    assert second["period"] == first["period"]
