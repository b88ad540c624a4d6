"""Declared switch times (OdeModel(switch_times=...), model/switches.py): a rhs that jumps at known
times of its forcing period. On the square-wave stiffness oscillator x'' + (delta + eps sign(cos t)) x
= 0 (tests/user_models/switched.py), whose exact solution is a product of 2 x 2 matrices, the
declared switches bring the error to about rtol where the undeclared equation is 25-40 times rtol;
bad declarations are refused with the model and the argument named; a point whose switch times are
not times in [0, T) gets INFEASIBLE."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.errors import InputError
from mechsweep.model import Floquet, OdeModel, Param, StateAt

HERE = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(HERE / "user_models"))
sys.path.insert(0, str(HERE / "data"))
import switched  # noqa: E402
from tests.evaluating import evaluate  # noqa: E402

T = 2.0 * math.pi


def _M(k, tau):
    if k > 0:
        w = math.sqrt(k)
        return np.array([[math.cos(w * tau), math.sin(w * tau) / w], [-w * math.sin(w * tau), math.cos(w * tau)]])
    w = math.sqrt(-k)
    return np.array([[math.cosh(w * tau), math.sinh(w * tau) / w], [w * math.sinh(w * tau), math.cosh(w * tau)]])


def exact(delta, eps, t):
    """(x, v)(t) from (1, 0): sign(cos t) is + on [0, pi/2), - on (pi/2, 3 pi/2), + on (3 pi/2, 2 pi)."""
    z, t0, k = np.array([1.0, 0.0]), 0.0, 0
    while t0 < t:
        for end, s in ((0.5 * math.pi, 1.0), (1.5 * math.pi, -1.0), (T, 1.0)):
            hi = min(k * T + end, t)
            if hi > t0:
                z = _M(delta + eps * s, hi - t0) @ z
                t0 = hi
        k += 1
    return z


def spec(model):
    return model.spec(origin=str(HERE / "user_models" / "switched.py"), module="switched",
                      attr=model.name.upper())


# (delta, eps): the undeclared equation's x(10) is 25-39 rtol off at rtol 1e-8 (test_undeclared_...)
ROWS = np.array([(0.2, 0.3), (0.8, 0.3), (1.4, 0.9), (2.0, 0.9)])
# (delta, eps): x(10) 18-40 rtol off with the switch times declared 0.3 after the rhs's own
SHIFTED = np.array([(0.2, 0.3), (1.0, 0.3), (0.6, 0.9), (1.0, 0.9)])


def _error(out, P):
    ref = np.array([exact(d, e, 10.0)[0] for d, e in P[:, :2]])
    return np.abs(out - ref) / np.maximum(1.0, np.abs(ref)) / 1e-8


def test_steps_on_the_switches_reach_rtol():
    """One kernel (SWITCHED_FN: switch_times(p) = (pi/2, 3 pi/2) + shift), StateAt x(10) on the shared
    trajectory, dop853 at rtol 1e-8: with the declared times on the rhs's own switches (shift 0) the
    worst error is about 1 rtol; the same times moved by 0.3 (the jumps then fall inside steps, as
    without a declaration) give 18-40 rtol. A point whose switch times leave [0, T) gets
    INFEASIBLE and NaN, the others are computed."""
    on = np.column_stack([ROWS, np.zeros(len(ROWS))])
    off = np.column_stack([SHIFTED, np.full(len(SHIFTED), 0.3)])
    bad = np.array([(0.8, 0.3, 2.0), (0.8, 0.3, -2.0)])  # 3 pi/2 + 2 >= 2 pi; pi/2 - 2 < 0
    P = np.vstack([on, off, bad])
    out, status, ns, nr = evaluate(spec(switched.SWITCHED_FN), P, ["x_end"], rtol=1e-8, atol=1e-10)
    assert (status[:8] == st.OK).all() and (status[8:] == st.INFEASIBLE).all(), status
    assert np.isnan(out["x_end"][8:]).all() and (ns[8:] == 0).all()
    err_on, err_off = _error(out["x_end"][:4], on), _error(out["x_end"][4:8], off)
    assert err_on.max() < 3.0, err_on
    assert err_off.min() > 10.0, err_off
    assert st.INFEASIBLE in spec(switched.SWITCHED_FN).possible_statuses()
    assert "switch times" in dict(spec(switched.SWITCHED_FN).status_notes)[st.INFEASIBLE]


def _rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -y[0]


def _initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


def _accel(t, q, p, a):
    a[0] = -q[0]


def _period(p):
    return 1.0


@pytest.mark.parametrize("kw, match", [
    (dict(switch_times=(0.5,), forcing_period=None, measurements=(StateAt("x1", "x", 1.0),)),
     "switch_times are times within one forcing period"),
    (dict(switch_times=(0.5,), accel=_accel, symplectic_step=lambda p, r: 0.1), "accel"),
    (dict(switch_times=()), "switch_times is empty"),
    (dict(switch_times=(0.5, 0.5)), "strictly increasing"),
    (dict(switch_times=(-0.1, 0.5)), "strictly increasing finite numbers >= 0"),
    (dict(switch_times=("a",)), "expected increasing numbers"),
    (dict(switch_times=0.5), "expected increasing numbers"),
])
def test_bad_declarations_are_refused(kw, match):
    base = dict(name="bad", description="", params=(Param("a", "a", "1", "a"),), states=("x", "v"), rhs=_rhs,
                initial=_initial, forcing_period=_period, measurements=(Floquet("mu"),))
    base.update(kw)
    with pytest.raises(ValueError, match="model 'bad': switch_times") as info:
        OdeModel(**base)
    assert match in str(info.value)


def test_a_list_is_kept_as_a_tuple():
    m = OdeModel(name="ok", description="", params=(Param("a", "a", "1", "a"),), states=("x", "v"), rhs=_rhs,
                 initial=_initial, forcing_period=_period, switch_times=[0.25, 0.75], measurements=(Floquet("mu"),))
    assert m.switch_times == (0.25, 0.75)


def test_load_check_refuses_a_function_not_returning_floats(tmp_path):
    """A user's switch_times(p) that returns ints is refused when the model is loaded (exit 2)."""
    from mechsweep.model import user

    def ints(p):
        return (1, 2)

    m = OdeModel(name="ints", description="", params=(Param("a", "a", "1", "a"),), states=("x", "v"), rhs=_rhs,
                 initial=_initial, forcing_period=_period, switch_times=ints, measurements=(Floquet("mu"),))
    with pytest.raises(InputError, match="switch_times returned \\(1, 2\\); expected a non-empty tuple of floats"):
        user.check(m, "x.py:INTS", "x.py")


@pytest.mark.slow
@pytest.mark.parametrize("method", ["dop853", "radau", "auto"])
def test_every_route_reaches_rtol(method):
    """Every integration route with the switch times declared as constants, at rtol 1e-8 against the
    exact solution: the first zero of x (FirstEvent: the method's event solver), x at 2 T s
    (History: the sampled trajectory), the Floquet multiplier (the variational integration), the
    largest x on [5, 10] (Extremum on the shared trajectory, dop853 only); the function form gives
    bitwise the same values."""
    from scipy.optimize import minimize_scalar
    rows = np.column_stack([ROWS, np.zeros(len(ROWS))])
    wanted = ["t_zero", "x_hist", "mu", "x_max"] if method == "dop853" else ["t_zero", "x_hist"]
    out, status, _, _ = evaluate(spec(switched.SWITCHED), rows, wanted, rtol=1e-8, atol=1e-10, method=method)
    assert (status == st.OK).all()
    for i, (d, e, _) in enumerate(rows):
        ts = np.linspace(0.0, 40.0, 4001)
        xs = [exact(d, e, x)[0] for x in ts]
        j = next(j for j in range(len(xs) - 1) if xs[j] > 0 >= xs[j + 1])
        from scipy.optimize import brentq
        tz = brentq(lambda x: exact(d, e, x)[0], ts[j], ts[j + 1], xtol=1e-15, rtol=1e-15)
        assert abs(out["t_zero"][i] - tz) < 5e-8 * tz
        hist = [exact(d, e, T * s)[0] for s in np.linspace(0.0, 2.0, 5)]
        np.testing.assert_allclose(out["x_hist"][i], hist, rtol=0, atol=5e-8)
        if "x_max" in wanted:
            ts = np.linspace(5.0, 10.0, 2001)
            xs = [exact(d, e, x)[0] for x in ts]
            j = int(np.argmax(xs))
            best = max(xs[j], -minimize_scalar(lambda x: -exact(d, e, x)[0], method="bounded", bounds=(
                ts[max(j - 1, 0)], ts[min(j + 1, 2000)]), options={"xatol": 1e-12}).fun)  # an end: xs[j]
            assert abs(out["x_max"][i] - best) < 5e-8 * max(1.0, abs(best))
        if "mu" in wanted:
            m = _M(d + e, 0.5 * math.pi) @ _M(d - e, math.pi) @ _M(d + e, 0.5 * math.pi)
            mu = max(abs(np.linalg.eigvals(m)))
            assert abs(out["mu"][i] - mu) < 5e-8 * mu
    if method == "dop853":
        out2, _, _, _ = evaluate(spec(switched.SWITCHED_FN), rows, wanted, rtol=1e-8, atol=1e-10, method=method)
        for k in wanted:
            np.testing.assert_array_equal(out[k], out2[k])


@pytest.mark.slow
def test_undeclared_switches_cost_accuracy_and_steps():
    """The same equation without switch_times (UNDECLARED): x(10) 25-39 rtol off at ROWS, where the
    declared constants give about 1 rtol in fewer steps."""
    P = np.column_stack([ROWS, np.zeros(len(ROWS))])
    err, steps = {}, {}
    for model in (switched.UNDECLARED, switched.SWITCHED):
        out, status, ns, _ = evaluate(spec(model), P, ["x_end"], rtol=1e-8, atol=1e-10)
        assert (status == st.OK).all()
        err[model.name] = _error(out["x_end"], P).max()
        steps[model.name] = ns.sum()
    assert err["switched"] < 3.0 and err["undeclared"] > 20.0, err
    assert steps["switched"] < steps["undeclared"], steps


def test_a_model_with_switch_times_takes_no_simd_lanes():
    """The lane kernels (engine/lanes.py, the sampled lanes) do not step onto switches: a model that
    declares them is integrated one point at a time, whatever engine.kernels.USE_LANES says."""
    from mechsweep.engine import kernels
    from mechsweep.engine import sampling as trajectory

    first = tuple(m for m in switched.SWITCHED.measurements if m.name == "t_zero")
    assert kernels.lanes_apply(switched.UNDECLARED, first, "dop853") is not None  # the same rhs without them: lanes
    assert kernels.lanes_apply(switched.SWITCHED, first, "dop853") is None
    assert trajectory.lane_rhs_for(switched.UNDECLARED, "dop853") is not None
    assert trajectory.lane_rhs_for(switched.SWITCHED, "dop853") is None


@pytest.mark.parametrize("output", [pytest.param("x_end", marks=pytest.mark.slow), "x_hist"])  # a compile each
def test_a_raise_on_the_switch_route_is_diagnosed(output):
    """A point whose switch_times raises, or whose rhs raises only past a switch (tests/user_models/
    switch_raises.py, k = 2 and k = 1), gets USER_ERROR on the one-point kernel (x_end) and on the
    sampled trajectory (x_hist: its guarded rhs's NaN made it NONFINITE, undiagnosed); the plain-Python
    replay (model/diagnose.py) follows the solvers' route (switch_times before the first rhs call, the
    rhs just after each switch) and names the exception, the file and the line. One small kernel each
    (about 15 s of compile on 2 cores: the one-point kernel's case is slow)."""
    import warnings

    import switch_raises
    from mechsweep.errors import UserModelWarning
    from mechsweep.model import ode
    from mechsweep.model.diagnose import explain

    model = switch_raises.RAISES
    sp = model.spec(origin=str(HERE / "user_models" / "switch_raises.py"), module="switch_raises", attr="RAISES")
    P = np.array([[0.0], [1.0], [2.0]])
    ode._EXPLAINED.clear()  # warned once per cause in a process
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        out, status, _, _ = evaluate(sp, P, [output], rtol=1e-8, atol=1e-10)
    assert status.tolist() == [st.OK, st.USER_ERROR, st.USER_ERROR]
    times = [4.0] if output == "x_end" else [0.0, T / 2, T]
    assert np.abs(np.ravel(out[output][0]) - [exact(1.0, 0.5, t)[0] for t in times]).max() < 1e-6
    assert np.isnan(out[output][1:]).all()
    file = str(HERE / "user_models" / "switch_raises.py")
    lines = Path(file).read_text().splitlines()
    at = {word: 1 + next(j for j, x in enumerate(lines) if f'raise ValueError("{word}' in x)
          for word in ("no", "switch")}
    why = [str(w.message) for w in seen if issubclass(w.category, UserModelWarning)]
    assert len(why) == 1 and "first seen at k = 1: rhs just after the switch at t = 1.5708" in why[0], why
    assert f"raised ValueError: no stiffness table for the negative piece ({file}, line {at['no']}, in rhs)" in why[0]
    assert explain(model, P[2], np.zeros(0), 1e-8) == (
        f"switch_times raised ValueError: switch times undefined for k = 2 ({file}, line {at['switch']}, "
        "in switch_times)")
    assert explain(model, P[0], np.zeros(0), 1e-8).startswith("no exception in plain Python")
