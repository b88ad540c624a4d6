"""Measurements of expressions and n-th roots (tests/user_models/measure_more.py, a linear
oscillator x = A cos(w t), v = -A w sin(w t)): FirstEvent's n-th root and direction by every
method, Extremum of an expression f(t, y, p) and over a window given by functions of p; against
closed forms."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.scene import load_scene
from tests import evaluating

MODEL = f"{Path(__file__).resolve().parents[1] / 'user_models' / 'measure_more.py'}:MODEL"
W = np.array([0.5, 1.0, 1.7, 3.0])
A = 0.7
P = np.column_stack([W, np.full(W.size, A)])


def evaluate(outputs, method="dop853", rtol=1e-12, atol=1e-14):
    scene = load_scene({"scene": {"name": "t", "model": MODEL, "outputs": list(outputs)},
                        "axes": {"w": {"start": 0.5, "stop": 3.0, "num": 3}}, "fixed": {"A": A},
                        "solver": {"rtol": rtol, "atol": atol, "method": method}})
    return evaluating.evaluate(scene.model, P, outputs, scene.solver)


def test_nth_root_of_an_expression_in_either_direction_and_a_period():
    """x + v / w = A sqrt(2) cos(w t + pi/4): its downward zeros at w t = pi/4 + 2 pi k, its upward
    ones at 5 pi / 4 + 2 pi k. The third downward one (fewer than 3 before t_max = 10 is NO_EVENT)
    and the time from the first upward one to the second, 2 pi / w."""
    out, status, ns, nr = evaluate(("down3_short", "period_up"), rtol=1e-10, atol=1e-12)
    short = 17 * math.pi / 4 / W > 10.0
    assert short.tolist() == [True, True, False, False]
    assert status.tolist() == [st.NO_EVENT, st.NO_EVENT, st.OK, st.OK]
    assert np.isnan(out["down3_short"][short]).all()
    np.testing.assert_allclose(out["down3_short"][~short], 17 * math.pi / 4 / W[~short], rtol=1e-9, atol=0)
    np.testing.assert_allclose(out["period_up"], 2 * math.pi / W, rtol=1e-9, atol=0)


@pytest.mark.slow  # one more kernel of three n-th roots
def test_more_nth_roots_by_dop853():
    """The 3rd downward and 2nd upward zero of x + v / w; v^2 = (A w)^2 sin^2(w t) peaks every
    pi / w (its rate goes from > 0 to <= 0 there): from the second peak to the fourth, 2 pi / w."""
    out, status, ns, nr = evaluate(("down3", "up2", "two_periods"), rtol=1e-10, atol=1e-12)
    assert (status == st.OK).all()
    np.testing.assert_allclose(out["down3"], 17 * math.pi / 4 / W, rtol=1e-9, atol=0)
    np.testing.assert_allclose(out["up2"], 13 * math.pi / 4 / W, rtol=1e-9, atol=0)
    np.testing.assert_allclose(out["two_periods"], 2 * math.pi / W, rtol=1e-9, atol=0)


@pytest.mark.slow  # a kernel per method (~30 s of compilation each from an empty cache)
@pytest.mark.parametrize("method, tol", [("radau", 1e-9), ("auto", 1e-9), ("symplectic", 1e-8)])
def test_nth_root_upwards_by_the_other_methods(method, tol):
    out, status, _, _ = evaluate(("up1", "up2"), method, rtol=1e-10, atol=1e-12)
    assert (status == st.OK).all()
    np.testing.assert_allclose(out["up1"], 5 * math.pi / 4 / W, rtol=tol, atol=0)
    np.testing.assert_allclose(out["up2"], 13 * math.pi / 4 / W, rtol=tol, atol=0)


def test_extremum_of_an_expression_and_over_windows_given_by_functions_of_p():
    out, status, _, _ = evaluate(("ke_max", "power_early", "power_late", "x_min_late", "bad_window"))
    # max of v^2 / 2 over [0, 10]: (A w)^2 / 2 at interior turning points
    np.testing.assert_allclose(out["ke_max"], 0.5 * (A * W) ** 2, rtol=1e-10, atol=0)
    # x v = -(A^2 w / 2) sin(2 w t): decreasing over w t in [0.1, 0.5] (the max is the window's start)
    np.testing.assert_allclose(out["power_early"], -(A * A * W / 2) * math.sin(0.2), rtol=1e-10, atol=0)
    # over w t in [pi/4, pi] its max A^2 w / 2 at 2 w t = 3 pi / 2, inside
    np.testing.assert_allclose(out["power_late"], A * A * W / 2, rtol=1e-10, atol=0)
    # a state over the same window: -A at its end
    np.testing.assert_allclose(out["x_min_late"], -A, rtol=0, atol=1e-10)
    # [1 / w, 1] is empty for w <= 1: INFEASIBLE there (the other outputs are still written); the
    # other points get the max of x over it, A cos(1) at the window's start
    assert status.tolist() == [st.INFEASIBLE, st.INFEASIBLE, st.OK, st.OK]
    np.testing.assert_allclose(out["bad_window"][2:], A * math.cos(1.0), rtol=1e-10)
    assert np.isnan(out["bad_window"][:2]).all()


def test_a_first_event_beside_shared_path_measurements_generates_one_kernel():
    """The kernel of a FirstEvent with an Extremum and a Period-like shared row (composed, not
    compiled): the FirstEvent gets its own event solver, the others the shared trajectory (the kernel
    generator once failed: FirstEvent has no shared-path source)."""
    from mechsweep.engine import kernels, point
    from mechsweep.model import load
    from mechsweep.ode.methods import DOP853

    path = Path(MODEL.rpartition(":")[0])
    decl = load.import_module(load.module_name(path), str(path)).MODEL
    chosen, _ = decl._plan(("down3_short", "ke_max", "period_up"))
    assert kernels.kernel_for(decl, chosen, route="point") is not None
    plan = point.Plan(decl, chosen, (), DOP853)
    firsts = [k for k, m in enumerate(chosen) if type(m).__name__ == "FirstEvent"]
    assert len(firsts) == 2
    for k in firsts:  # each FirstEvent by its own event solver, as when asked alone
        assert k in plan.alone and k not in plan.group
    assert len(plan.group) == 1  # the Extremum: a row of the one shared trajectory


@pytest.mark.slow  # one more kernel (~25 s of compilation from an empty cache)
def test_a_first_event_beside_shared_path_measurements_gives_what_each_gives_alone():
    """A FirstEvent (integrated on its own) asked together with shared-trajectory measurements
    (here Extremum; Period, Crossing, StateAt, Floquet take the same path) in one kernel: each value
    bitwise what the measurement gives when asked alone (the kernel once failed to generate:
    FirstEvent has no shared-path source), the status the first failure of either."""
    first, s1, _, _ = evaluate(("down3_short", "period_up"))
    ext, s2, _, _ = evaluate(("ke_max", "power_early", "power_late", "x_min_late", "bad_window"))
    both, status, ns, _ = evaluate(("down3_short", "ke_max", "power_early", "power_late", "x_min_late",
                                    "period_up", "bad_window"))
    for name, alone in list(first.items()) + list(ext.items()):
        np.testing.assert_array_equal(both[name], alone)  # NaN where alone is NaN, else bitwise
    assert not np.isnan(both["period_up"]).any() and not np.isnan(both["ke_max"]).any()
    assert ((status == st.OK) == ((s1 == st.OK) & (s2 == st.OK))).all()
    assert set(status[status != st.OK].tolist()) <= {st.NO_EVENT, st.INFEASIBLE}


def test_declarations_are_checked():
    from mechsweep.model import Extremum, FirstEvent

    with pytest.raises(ValueError, match="n = 0"):
        FirstEvent("e", lambda t, y, p: y[0], n=0).validate(("x",))
    with pytest.raises(ValueError, match="since = 2; expected a whole number 0 <= since < n = 2"):
        FirstEvent("e", lambda t, y, p: y[0], n=2, since=2).validate(("x",))
    with pytest.raises(ValueError, match="direction 'sideways'"):
        FirstEvent("e", lambda t, y, p: y[0], direction="sideways").validate(("x",))
    with pytest.raises(ValueError, match="t1 = nan"):
        Extremum("e", "x", 0.0, math.nan).validate(("x",))
    with pytest.raises(ValueError, match="expected a state name or a function"):
        Extremum("e", 3, 0.0, 1.0).validate(("x",))


def test_a_division_by_zero_in_a_users_numba_helper_is_ieee_not_an_exception():
    """``_inverse`` is the user's own ``@numba.njit`` helper (numba's default error model raises
    ZeroDivisionError on 1 / 0, which made the point USER_ERROR): the engine compiles it again with
    its own options, so 1 / 0 is inf as in the rest of the engine. At w = 1 the closed form's
    classify sees the inf and gives SINGULAR; without a classify the value is inf (which the runner
    stores as NaN with status NONFINITE). The model loads although its probe point is w = 1."""
    global P
    keep = P
    P = np.column_stack([[0.5, 1.0, 3.0], [A, A, A]])
    try:
        out, status, _, _ = evaluate(("detuning",))
        assert status.tolist() == [st.OK, st.SINGULAR, st.OK]
        np.testing.assert_array_equal(out["detuning"], [1.0 / (0.5 - 1.0), np.nan, 1.0 / (3.0 - 1.0)])
        out, status, _, _ = evaluate(("detuning_raw",))
        assert status.tolist() == [st.OK] * 3  # the runner stores an inf as NaN with status NONFINITE
        assert out["detuning_raw"][1] == np.inf
    finally:
        P = keep


@pytest.mark.parametrize("method, outputs", [
    pytest.param("dop853", ("t_zero", "rhs_calls"), marks=pytest.mark.slow),
    pytest.param("radau", ("t_zero", "rhs_calls"), marks=pytest.mark.slow),  # radau's kernel: ~30-60 s cold
    pytest.param("radau", ("mult", "rhs_calls_floquet"), marks=pytest.mark.slow),
    pytest.param("dop853", ("mult", "rhs_calls_floquet"), marks=pytest.mark.slow),
    pytest.param("dop853", ("v_max", "rhs_calls_extremum"), marks=pytest.mark.slow)])
def test_n_rhs_counts_every_rhs_call_also_those_of_the_engines_jacobian(method, outputs, monkeypatch):
    """The rhs of COUNTED counts its own calls (an internal slot, read by a closed form after the
    measurement): n_rhs is exactly that count, also by radau with the engine's finite-difference
    Jacobian (2 n rhs calls each, which n_rhs used not to count), by Floquet's variational
    integration (its Jacobian by differences: 2 n + 1 calls per evaluation, and radau's own), and
    by an Extremum's root search of the derivative on the shared trajectory (one call per
    evaluation, which n_rhs used not to count). An rhs that writes into p is refused when a model
    is loaded (model/writes.py); this instrument does it on purpose, so the check is off here."""
    from mechsweep.model import user

    monkeypatch.setattr(user, "_check_writes", lambda *args: None)
    scene = load_scene({"scene": {"name": "t", "model": MODEL.replace(":MODEL", ":COUNTED"),
                                  "outputs": list(outputs)},
                        "axes": {"w": {"start": 0.5, "stop": 3.0, "num": 3}}, "fixed": {"A": A},
                        "solver": {"rtol": 1e-8, "atol": 1e-10, "method": method}})
    out, status, ns, nr = evaluating.evaluate(scene.model, P, outputs, scene.solver)
    assert (status == st.OK).all()
    if outputs[0] == "t_zero":
        np.testing.assert_allclose(out["t_zero"], math.pi / 2 / W, rtol=1e-6)
    elif outputs[0] == "v_max":
        np.testing.assert_allclose(out["v_max"], A * W, rtol=1e-6)
    else:
        np.testing.assert_allclose(out["mult"], 1.0, rtol=1e-6)
    np.testing.assert_array_equal(nr, out[outputs[1]])


@pytest.mark.slow  # two fresh processes, the first compiling from an empty cache
def test_second_process_compiles_nothing_for_the_new_measurements(tmp_path):
    """numba's cache statistics: a kernel with an Extremum of an expression over a window from
    functions of p, an n-th root upwards and a closed form calling the user's own @numba.njit helper
    (compiled again with the engine's options) is loaded from the disk cache in a second process."""
    import json
    import os
    import subprocess
    import sys

    here = Path(__file__).resolve().parents[1]
    env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(tmp_path), PYTHONPATH=str(here.parent / "src"))
    runs = []
    for _ in range(2):
        res = subprocess.run([sys.executable, str(here / "user_models" / "cache_probe.py"), MODEL,
                              "power_late,x_min_late,detuning"], capture_output=True, text=True, env=env, cwd=tmp_path)
        assert res.returncode == 0, res.stderr
        runs.append(json.loads(res.stdout.strip().splitlines()[-1]))
    first, second = runs
    assert first["misses"] > 0
    # nothing compiled; the functions the load check calls from Python are cache hits (the engine's
    # copy of the user's helper is only called from inside the cached kernel: neither)
    assert second["misses"] == 0 and second["hits"] >= 8
    assert second["power_late"] == first["power_late"]


def test_an_expression_reading_an_undeclared_parameter_is_refused_when_loaded(tmp_path):
    """The load check runs an Extremum's expression and window functions at the probe point too:
    an undeclared parameter is an InputError naming the measurement and the file."""
    from mechsweep.errors import InputError

    src = Path(MODEL.rpartition(":")[0]).read_text().replace("return 0.5 * y[1] * y[1]", "return 0.5 * y[1] * p[7]")
    bad = tmp_path / "bad_expression.py"
    bad.write_text(src)
    with pytest.raises(InputError, match=r"ke_max\.of indexes beyond its arrays.*bad_expression\.py"):
        load_scene({"scene": {"name": "t", "model": f"{bad}:MODEL", "outputs": ["ke_max"]},
                    "axes": {"w": {"start": 0.5, "stop": 3.0, "num": 3}}, "fixed": {"A": A}})
