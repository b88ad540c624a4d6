"""DOP853 in SIMD lanes (ode/dop853_lanes.py) against the one-trajectory DOP853: bitwise the
same samples, step counts and statuses, however the trajectories share the lanes."""
import math

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from mechsweep import status as st
from tests.reference.literal_switch import call_with_literal
from tests.reference import autobalancer_kernels as ab  # the hand-written kernels (reference implementation)
from mechsweep.ode import METHOD_CODES, _lane_sums_codegen
from mechsweep.scene import Solver
from mechsweep.special import SINCOS_MAX

from tests.models.test_autobalancer import random_p


def test_generated_tableau_sums_are_up_to_date():
    assert _lane_sums_codegen.TARGET.read_text() == _lane_sums_codegen.source()


# ----------------------------------------------------------------------------- the lane right-hand side
angles = hs.one_of(hs.floats(-50.0, 50.0), hs.floats(-2e6, 2e6), hs.sampled_from([SINCOS_MAX, -SINCOS_MAX, 3e15,
                                                                                   math.inf, math.nan]))


@settings(max_examples=60, deadline=None)
@given(seed=hs.integers(0, 2**32 - 1), lanes=hs.sampled_from([1, 3, 8, 16, 19]), g1=angles, tau=angles)
def test_lane_rhs_is_rhs_in_every_lane(seed, lanes, g1, tau):
    """Bitwise, including the lanes beyond sincos's reduction range (libm) and NaN; any lane count
    (the vectorised loops have scalar remainders)."""
    rng = np.random.default_rng(seed)
    P = np.stack([random_p(rng, A1=bool(l % 2)) for l in range(lanes)], axis=1)
    Z = rng.normal(size=(8, lanes)) * 3
    T = rng.uniform(0, 2000, lanes)
    Z[2, lanes // 2] = g1
    T[lanes - 1] = tau
    dZ = np.empty((8, lanes))
    ab.rhs_lanes(T, Z, P, dZ)
    one = np.empty(8)
    for l in range(lanes):
        ab.rhs(T[l], Z[:, l].copy(), P[:, l].copy(), one)
        np.testing.assert_array_equal(dZ[:, l], one)


# ----------------------------------------------------------------------------- whole simulations
def mixed_points(n, seed=11):
    """Scaled parameters of n varied mechanisms: conrod terms on half of them, unbalance below
    what the pendulums can balance (A0 < 2 m a), pendulum damping from none to moderate."""
    rng = np.random.default_rng(seed)
    pp = np.stack([random_p(rng, A1=bool(i % 2)) for i in range(n)])
    ok = pp[:, ab.IP_ALPHA0] < 2.0  # a balanced state exists: start from it, as evaluate does
    th = np.where(ok, np.arccos(np.clip(-pp[:, ab.IP_ALPHA0] / 2, -1, 1)), 0.0)
    pp[:, ab.IP_TH1], pp[:, ab.IP_TH2] = th, -th
    return pp


def simulate(pp, lanes, max_steps=100_000, histories=True, run=None, threads=None):
    """The lane kernel with `lanes` lanes per thread, or (lanes=0) the one-trajectory kernel, on the
    points: (meas, hist, code, n_steps, n_rhs)."""
    s = Solver.for_model(ab.SPEC, horizon_revolutions=40.0, max_steps=max_steps)
    n = pp.shape[0]
    t_eval, n_rev1, n_early, i_prev, i_late, hist_idx, meas_rows = ab.sample_grid(s.settings, histories)
    hist = np.full((n, 4, hist_idx.size), np.nan)
    meas = np.full((n, ab.N_MEAS), np.nan)
    code, n_steps, n_rhs = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
    run = np.ones(n, bool) if run is None else run
    args = (pp, run, s.settings["perturbation"], t_eval, n_rev1, n_early, i_prev, i_late, s.rtol, s.atol, max_steps,
            s.settings["settle_threshold"], hist_idx, meas_rows, hist, meas, code, n_steps, n_rhs)
    before = numba.get_num_threads()
    numba.set_num_threads(threads or before)
    try:
        if lanes:
            ab.simulate_lanes(lanes, *args)
        else:
            call_with_literal(ab.simulation_kernel, METHOD_CODES["dop853"], *args)
    finally:
        numba.set_num_threads(before)
    return meas, hist, code, n_steps, n_rhs


def assert_same(a, b):
    for x, y, name in zip(a, b, ("meas", "hist", "code", "n_steps", "n_rhs")):
        np.testing.assert_array_equal(x, y, err_msg=name)


@pytest.fixture(scope="module")
def mixed():
    pp = mixed_points(70)
    run = np.ones(70, bool)
    run[[3, 40]] = False  # points the kernel must leave alone
    return pp, run, simulate(pp, lanes=0, run=run)


# The hand-written auto-balancer kernels (tests/reference/autobalancer_kernels.py) are a reference since the
# swap: no model runs them. Their lane simulations compile the whole lane solver for them (about a
# minute cold), so these tests of them are slow; the model's own lanes run in every auto-balancer test.
@pytest.mark.slow
@pytest.mark.parametrize("threads", [1, 2])
def test_lanes_give_the_one_trajectory_results_bitwise(mixed, threads):
    """70 points through the lanes (queues refill lanes as trajectories end), on one and on two
    threads (other queues, other lane mates)."""
    pp, run, reference = mixed
    result = simulate(pp, lanes=ab.LANES, run=run, threads=threads)
    assert_same(result, reference)
    code, n_steps = result[2], result[3]
    assert (n_steps[~run] == 0).all() and (code[~run] == 0).all()
    assert np.isfinite(result[0][run]).any() and (n_steps[run] > 100).all()


@pytest.mark.slow  # the reference kernels' lanes (above)
def test_lanes_end_with_the_same_statuses(mixed):
    """A step budget that some trajectories exhaust (MAX_STEPS, at different moments in
    different lanes) and parameters that make the mass matrix singular (non-finite)."""
    pp, _, _ = mixed
    pp = pp[:24].copy()
    pp[5, ab.IP_MU] = 2.0 / pp[5, ab.IP_IOTA]  # K11 K22 - K12^2 = 0: infinite accelerations
    pp[9, ab.IP_MU] = math.nan
    a = simulate(pp, lanes=0, max_steps=1500)
    for lanes in (ab.LANES, 16, 5):  # 5: the vector loops run their scalar remainders too
        assert_same(simulate(pp, lanes=lanes, max_steps=1500), a)
    codes = set(a[2].tolist())
    assert st.MAX_STEPS in codes and st.OK in codes and (codes & {st.NONFINITE, st.STEP_UNDERFLOW}), codes


def test_lanes_shrink_to_keep_the_samples_within_budget():
    """Each lane holds its trajectory's samples: long horizons get 16, then 8 lanes, then one
    trajectory at a time (what the one-trajectory kernel always holds)."""
    n_eval = [ab.sample_grid(Solver.for_model(ab.SPEC, horizon_revolutions=H).settings, False)[0].size
              for H in (300.0, 1e4, 3e4, 1e5)]
    assert [ab.simulation_lanes(k) for k in n_eval] == [ab.LANES, 16, 8, 0]
    assert all(ab.simulation_lanes(k) * k * 64 <= ab.LANE_SAMPLES_BYTES for k in n_eval)


@pytest.mark.slow  # the reference kernels' lanes (above)
def test_fewer_points_than_lanes():
    pp = mixed_points(5, seed=4)
    assert_same(simulate(pp, lanes=ab.LANES, histories=False), simulate(pp, lanes=0, histories=False))
