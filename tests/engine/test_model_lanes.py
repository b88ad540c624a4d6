"""SIMD lanes for the model layer's first-event kernels (engine/lanes.py): bitwise the one-point route.

Each comparison runs the same points through the lane kernel and the one-point kernel
(engine.kernels.USE_LANES switched) and asks for identical outputs, status, n_steps and n_rhs."""
import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.engine import kernels as mc
from mechsweep.engine import lane_rhs, lanes
from mechsweep.model import user
from mechsweep.models import MODELS
from tests.evaluating import evaluate

DATA = Path(__file__).resolve().parents[1] / "data"
USER = Path(__file__).resolve().parents[1] / "user_models"
_spec = importlib.util.spec_from_file_location("record_reference", DATA / "record_reference.py")
rr = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(rr)


def _evaluate(spec, P, wanted, use_lanes, monkeypatch, status0=None, **solver):
    monkeypatch.setattr(mc, "USE_LANES", use_lanes)
    out, status, ns, nr = evaluate(spec, P, wanted, status=status0, **solver)
    return {**out, "status": status, "n_steps": ns, "n_rhs": nr}


def _lane_kernels_used():
    """Names of the kernels' binding modules imported so far that integrate in lanes."""
    return {name for name in mc._KERNELS if "rhs_lanes" in Path(sys.modules[name].__file__).read_text()}


def _same(spec, P, wanted, monkeypatch, status0=None, **solver):
    """(one-point results, names of the lane kernels that served the lane evaluation)."""
    monkeypatch.setattr(mc, "_KERNELS", {})  # every kernel fetched anew (from the disk cache): those used are listed
    one = _evaluate(spec, P, wanted, False, monkeypatch, status0, **solver)
    monkeypatch.setattr(mc, "_KERNELS", {})
    lan = _evaluate(spec, P, wanted, True, monkeypatch, status0, **solver)
    for key, value in one.items():
        assert np.array_equal(value, lan[key], equal_nan=True), f"{spec.name} {wanted} {solver} {key}: lanes differ"
    return one, _lane_kernels_used()


def _duffing_points():
    P = rr.duffing_points()
    rng = np.random.default_rng(5)  # and extreme amplitudes and stiffnesses, both signs
    extra = np.column_stack([10.0 ** rng.uniform(-3, 3, 120), rng.choice([-1.0, 1.0], 120) * 10.0 ** rng.uniform(-6, 6, 120),
                             10.0 ** rng.uniform(-8, 1, 120)])
    return np.vstack([P, extra])


WANTED = ("period", "period_exact", "period_error")  # the kernel of tests/model/test_model_layer_builtin.py's w0 case


def test_duffing_lanes_bitwise_one_point_route(monkeypatch):
    wanted = WANTED
    P = _duffing_points()
    spec = MODELS["duffing"]
    seen = set()
    cases = [dict(rtol=1e-10, atol=1e-12), dict(rtol=1e-6, atol=1e-9), dict(rtol=1e-13, atol=1e-15),
             dict(rtol=1e-10, atol=1e-12, max_steps=7), dict(rtol=1e-10, atol=1e-12, t_max_periods=0.1)]
    for kw in cases:
        out, new = _same(spec, P, wanted, monkeypatch, method="dop853", **kw)
        seen |= set(out["status"].tolist())
        assert new, "the lane kernel was not used"
    # every status the model gives on this grid, through the lanes
    assert {st.OK, st.NO_MOTION, st.INFEASIBLE, st.NOT_OSCILLATORY, st.ILL_CONDITIONED, st.MAX_STEPS,
            st.NO_EVENT} <= seen


@pytest.mark.slow  # ~30 s cold: its own two kernels
def test_torsional_circuit_period_lanes_bitwise_one_point_route(monkeypatch):
    """A FirstEvent of a System (its own rhs, initial state and prepare) in lanes."""
    P = rr.torsional_points()
    spec = MODELS["torsional_circuit"]
    for kw in (dict(rtol=1e-10, atol=1e-12), dict(rtol=1e-6, atol=1e-9), dict(rtol=1e-10, atol=1e-12, max_steps=7)):
        out, new = _same(spec, P, ("period",), monkeypatch, method="dop853", **kw)
        assert new, "the lane kernel was not used"
    assert {st.OK, st.MAX_STEPS} <= set(out["status"].tolist())


def test_lanes_chunk_shapes_and_skipped_points(monkeypatch):
    """One point, a count that is no multiple of the lanes, and points the caller already settled."""
    spec = MODELS["duffing"]
    P = _duffing_points()
    for n in (1, 3, lanes.lanes_for(2) + 5):
        _same(spec, P[:n], WANTED, monkeypatch, method="dop853")
    status0 = np.zeros(P.shape[0], np.int8)
    status0[::3] = st.INFEASIBLE
    one, _ = _same(spec, P, WANTED, monkeypatch, status0=status0, method="dop853")
    assert (one["status"][::3] == st.INFEASIBLE).all() and (one["n_steps"][::3] == 0).all()


@pytest.mark.slow  # four kernels of their own: about 1-2 min cold on the shared 2-core machine
def test_user_models_lanes_bitwise(monkeypatch):
    P = np.array([[1.0, a, c, f] for a in (0.1, 1.0, 2.5, 3.1, -0.5, 0.0) for c in (0.0, 0.3) for f in (0.0, 0.7)])
    forced = user.resolve(f"{USER / 'lanes_models.py'}:FORCED")  # a lone first Crossing, math calls, t
    out, new = _same(forced, P, ("t_cross",), monkeypatch, method="dop853", rtol=1e-9, atol=1e-11)
    assert new, "the lane kernel was not used"
    assert {st.OK, st.NO_EVENT} <= set(out["status"].tolist())
    mod = _module("lanes_models")  # an rhs calling a helper, or another method: one point at a time
    assert mc.lanes_apply(mod.HELPER, mod.HELPER.measurements[:1], "dop853") is None
    assert mc.lanes_apply(mod.FORCED, mod.FORCED.measurements[1:], "dop853") is not None
    assert mc.lanes_apply(mod.FORCED, mod.FORCED.measurements[1:], "radau") is None
    assert mc.lanes_apply(mod.FORCED, mod.FORCED.measurements, "dop853") is None  # two measurements
    layer = user.resolve(f"{USER / 'layer_methods.py'}:LINEAR")  # classify, prepare, settings, closed forms
    P2 = np.array([[w, a] for w in (0.5, 1.0, 4.0, 6.0) for a in (-1.0, 0.0, 0.3, 2.0)])
    _, new = _same(layer, P2, ("period", "period_exact", "period_error"), monkeypatch, method="dop853",
                   rtol=1e-10, atol=1e-12, horizon=3.0)
    assert new
    # an event raising (USER_ERROR) in lanes: test_model_layer_builtin's run-time exception test


def test_lane_rhs_rewrite_is_the_scalar_rhs_per_lane():
    """The rewritten rhs, run as plain Python on (state, lane) arrays, gives per lane the floats of
    the scalar rhs; what the rewrite does not cover gives None (the one-point route)."""
    mod = _module("lanes_models")
    src = lane_rhs.lane_rhs_source(mod.forced_rhs)
    assert src is not None and "math.cos(_lt[_ll])" in src and "_lp[2, _ll]" in src
    namespace = {"math": math, "jit_noalloc": lambda f: f}
    exec(src, namespace)
    rng = np.random.default_rng(0)
    L = 11
    tau, Z, Pl = rng.normal(size=L) * 10, rng.normal(size=(2, L)) * 3, rng.normal(size=(4, L))
    dZ = np.empty((2, L))
    namespace["rhs_lanes"](tau, Z, Pl, dZ)
    for lane in range(L):
        d = np.empty(2)
        mod.forced_rhs(tau[lane], Z[:, lane].copy(), Pl[:, lane].copy(), d)
        assert np.array_equal(d, dZ[:, lane])
    assert lane_rhs.lane_rhs_source(mod.helper_rhs) is None  # a call to a helper

    def raising(t, y, p, dydt):
        if y[0] > 1.0:
            raise ValueError("no")
        dydt[0] = y[1]

    def writes_p(t, y, p, dydt):
        p[0] = 1.0
        dydt[0] = y[0]

    def whole(t, y, p, dydt):
        dydt[:] = y

    def early(t, y, p, dydt):
        dydt[0] = y[0]
        if y[0] > 0:
            return
        dydt[1] = y[1]

    for f in (raising, writes_p, whole, early):
        assert lane_rhs.lane_rhs_source(f) is None, f.__name__


def _module(name):
    spec = importlib.util.spec_from_file_location(name, USER / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _per_lane(scalar, src, n_s, n_p, rng, lanes=11, tau=None, Z=None, P=None, fn=None):
    """The rewritten rhs (plain Python, or ``fn``: it compiled) on (state, lane) arrays against the
    scalar rhs per lane: the lane results and the bit patterns compared."""
    namespace = {"math": math, "jit_noalloc": lambda f: f}
    exec(src, namespace)
    f = fn or namespace["rhs_lanes"]
    tau = rng.normal(size=lanes) * 10 if tau is None else tau
    Z = rng.normal(size=(n_s, lanes)) * 3 if Z is None else Z
    P = rng.normal(size=(n_p, lanes)) if P is None else P
    dZ = np.empty((n_s, lanes))
    f(tau, Z, P, dZ)
    for lane in range(lanes):
        d = np.empty(n_s)
        scalar(tau[lane], Z[:, lane].copy(), P[:, lane].copy(), d)
        assert np.array_equal(d.view(np.int64), dZ[:, lane].view(np.int64)), (lane, d, dZ[:, lane])
    return f, dZ


def test_lane_rhs_inlines_helper_functions_called_as_statements():
    """An rhs calling a module-level function on a slice of p (which calls another, returning a
    tuple): the rewrite inlines both, the offset added to the indices, and gives per lane the scalar
    rhs's floats; a helper the rewrite does not cover (a while loop) leaves the rhs to the one-point
    route."""
    mod = _module("lanes_models")
    src = lane_rhs.lane_rhs_source(mod.inline_rhs)
    assert src is not None and "scaled" not in src.split("\n", 1)[1] and "accel(" not in src
    assert "_lp[3, _ll]" in src and "_lp[2, _ll]" in src  # q[2] and q[1] of p[OFF:]
    _per_lane(mod.inline_rhs, src, 2, 4, np.random.default_rng(1))
    assert lane_rhs.lane_rhs_source(mod.uncovered_rhs) is None
    for f in (mod.recursive_rhs, mod.tail_rhs):  # inlined without end: refused, no RecursionError
        assert lane_rhs.lane_rhs_source(f) is None


def _autobalancer_cases(rng):
    """(tau, Z, P) of lanes of the auto-balancer: in range, angles beyond sincos_reduced's range
    (sincos's libm branch), infinite, NaN; 16 lanes (the vector body) or 19 (a scalar remainder)."""
    from mechsweep.models import autobalancer as ab
    from mechsweep.special import SINCOS_MAX

    from tests.models.test_autobalancer import random_p

    n_p = ab.OFF + ab.NP + 3
    for case, (g, t) in enumerate([(None, None), (3.0 * SINCOS_MAX, None), (-SINCOS_MAX, None), (math.inf, None),
                                   (None, 2.0 * SINCOS_MAX), (math.nan, None)]):
        L = 19 if case % 2 else 16
        P = rng.normal(size=(n_p, L))
        for lane in range(L):
            P[ab.OFF:ab.OFF + ab.NP, lane] = random_p(rng, A1=bool(lane % 2))
        Z = rng.normal(size=(8, L)) * 3
        tau = rng.uniform(0.0, 2000.0, L)
        if g is not None:
            Z[2 + case % 2, L // 2] = g
        if t is not None:
            tau[L - 1] = t
        yield case, g, tau, Z, P


def test_lane_rhs_of_the_autobalancer_is_its_rhs_per_lane():
    """The engine's lane form of the auto-balancer's rhs (rhs -> scaled_rhs -> accelerations ->
    accelerations_trig -> conrod_terms, sincos, ieee_sqrt, inlined; run here as plain Python, the
    same IEEE arithmetic): per lane bitwise the scalar rhs, also for angles beyond sincos_reduced's
    range (sincos's libm branch, taken by the loop run again) and infinite; a NaN angle gives NaN as
    the scalar rhs does (the fast loop's sincos_reduced, as the hand-written rhs_lanes);
    and in every case the bits of the hand-written rhs_lanes (tests/reference/autobalancer_kernels.py)."""
    from mechsweep.models import autobalancer as ab
    from tests.reference import autobalancer_kernels as ref

    src = lane_rhs.lane_rhs_source(ab.MODEL.rhs)
    assert src is not None and "if _lb:" in src
    fast, again = src.split("if _lb:")  # the fast loop: no call of sincos's libm branch; again: sincos
    assert "_lsincos_red(" in fast and "_lsincos(" not in fast and "_lsincos(" in again
    rng = np.random.default_rng(7)
    for case, g, tau, Z, P in _autobalancer_cases(rng):
        L = tau.size
        if g is not None and math.isnan(g):  # NaN in, NaN out (its bits are sincos_reduced's)
            namespace = {"math": math, "jit_noalloc": lambda f: f}
            exec(src, namespace)
            dZ = np.empty((8, L))
            namespace["rhs_lanes"](tau, Z, P, dZ)
            one = np.empty(8)
            ab.MODEL.rhs(tau[L // 2], Z[:, L // 2].copy(), P[:, L // 2].copy(), one)
            assert np.array_equal(np.isnan(one), np.isnan(dZ[:, L // 2]))
        else:
            _, dZ = _per_lane(ab.MODEL.rhs, src, 8, P.shape[0], rng, L, tau, Z, P)
        hand = np.empty((8, L))
        ref.rhs_lanes(tau, Z, np.ascontiguousarray(P[ab.OFF:ab.OFF + ab.NP]), hand)
        assert np.array_equal(hand.view(np.int64), dZ.view(np.int64)), case


@pytest.mark.slow  # numba compiles the lane rhs (about 13 s; it is not in the disk cache)
@pytest.mark.skipif(__import__("platform").machine() not in ("x86_64", "AMD64"), reason="x86 assembly")
def test_lane_rhs_of_the_autobalancer_is_vectorised():
    """Compiled, the same bits per lane, and LLVM vectorises the fast loop (packed multiplies, no
    fused multiply-adds), as the hand-written rhs_lanes."""
    import re

    from mechsweep.models import autobalancer as ab

    import numba

    src = lane_rhs.lane_rhs_source(ab.MODEL.rhs)
    namespace = {"math": math, "jit_noalloc": lambda f: numba.njit(fastmath=False, error_model="numpy")(f)}
    exec(src, namespace)
    f = namespace["rhs_lanes"]
    rng = np.random.default_rng(8)
    for case, g, tau, Z, P in _autobalancer_cases(rng):
        if g is None or not math.isnan(g):
            _per_lane(ab.MODEL.rhs, src, 8, P.shape[0], rng, tau.size, tau, Z, P, fn=f)
    asm = "".join(f.inspect_asm().values())
    assert len(re.findall(r"\bv?mulpd\b", asm)) > 20, "no packed multiply: the lane loop was not vectorised"
    assert not re.findall(r"vfn?m(add|sub)\d+[ps]d", asm)


@pytest.mark.slow  # compiles the auto-balancer's sampled kernel both ways (about a minute cold)
def test_autobalancer_sampled_lanes_bitwise_one_trajectory(monkeypatch):
    """The auto-balancer's Kick, Steady and History (the recorded design grid: every status it
    gives) in the engine's lanes and one trajectory at a time: the same values, status, n_steps and
    n_rhs, bitwise; the lanes were taken."""
    from mechsweep.engine import sampling as trajectory

    _rec = importlib.util.spec_from_file_location("record_autobalancer", DATA / "record_autobalancer.py")
    rec = importlib.util.module_from_spec(_rec)
    _rec.loader.exec_module(rec)
    P = rec.design_points()
    wanted = rec.SIM
    calls = []
    run_lanes = trajectory._run_lanes
    monkeypatch.setattr(trajectory, "_run_lanes", lambda *a, **k: calls.append(1) or run_lanes(*a, **k))
    res = []
    for use in (False, True):
        monkeypatch.setattr(trajectory, "USE_LANES", use)
        res.append(rec.evaluate_case(P, wanted, dict(method="dop853", horizon_revolutions=20.0,
                                                     trajectory_samples=7)))
    assert calls, "the lanes were not taken"
    for key, value in res[0].items():
        assert np.array_equal(value, res[1][key], equal_nan=True), key
    assert len(set(res[0]["status"].tolist())) >= 4


@pytest.mark.skipif(__import__("platform").machine() not in ("x86_64", "AMD64"), reason="x86 assembly")
def test_lane_rhs_of_duffing_is_vectorised():
    """LLVM turns the generated lane loop into packed (SIMD) arithmetic, without fused multiply-adds
    (which would change the floats): checked on the assembly of the duffing lane rhs."""
    import re

    import numba

    from mechsweep.models import duffing

    namespace = {"math": math, "jit_noalloc": lambda f: numba.njit(fastmath=False, error_model="numpy")(f)}
    exec(lane_rhs.lane_rhs_source(duffing.MODEL.rhs), namespace)
    f = namespace["rhs_lanes"]
    L = lanes.lanes_for(2)
    f(np.zeros(L), np.zeros((2, L)), np.zeros((10, L)), np.zeros((2, L)))
    asm = "".join(f.inspect_asm().values())
    assert re.findall(r"\bv?mulpd\b", asm), "no packed multiply: the lane loop was not vectorised"
    assert not re.findall(r"vfn?m(add|sub)\d+[ps]d", asm)



def test_lane_blocks_are_taken_once_each_by_whichever_thread_is_free(monkeypatch):
    """The lane kernel's threads take its points in batches (lanes.take, an atomic counter) instead of
    being dealt blocks in advance: every take is handed out exactly once (10 x 10^6 takes racing on two
    threads), and a launch of several workers on two threads gives bitwise the one-point route's
    results at every point."""
    import numba

    from mechsweep._jit import pjit, prange

    @pjit
    def hand_out(n, counter):
        got = np.empty(n, dtype=np.int64)
        for i in prange(n):
            got[i] = lanes.take(counter)
        return got

    counter = np.zeros(1, dtype=np.int64)
    assert [lanes.take(counter) for _ in range(3)] == [0, 1, 2] and counter[0] == 3
    before = numba.get_num_threads()
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    try:
        for _ in range(10):  # (a plain load-add-store lost takes in about 1 of 10 such calls on 2 busy cores)
            counter[0] = 0
            got = hand_out(1_000_000, counter)
            assert counter[0] == 1_000_000 and np.array_equal(np.sort(got), np.arange(1_000_000))  # none lost or twice
        rng = np.random.default_rng(11)  # 5,000 points: 5 workers of the lane kernel, batches of 16 points
        P = np.column_stack([np.ones(5000), 10.0 ** rng.uniform(-3, 3, 5000), 10.0 ** rng.uniform(-2, 0, 5000)])
        one, used = _same(MODELS["duffing"], P, WANTED, monkeypatch, method="dop853")
        assert used and (one["status"] == st.OK).all()
    finally:
        numba.set_num_threads(before)
