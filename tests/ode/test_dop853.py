"""Tests of the numba DOP853 integrator (mechsweep.ode.dop853).

Few distinct right-hand sides on purpose: every (rhs, solver kind) pair is a
separate JIT compilation, and the whole file should run in well under 30 s.
"""
from __future__ import annotations

import time

import numba
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mechsweep import status
from mechsweep._jit import jit
from mechsweep.ode import _dop853_tableau as tableau
from mechsweep.ode.dop853 import (
    WORK_ROWS,
    make_event_solver,
    make_solver,
    make_stepper,
    make_trajectory_solver,
    workspace,
)

# A NumbaWarning (e.g. "cannot cache") fails the test that triggers it.
pytestmark = pytest.mark.filterwarnings("error::numba.NumbaWarning")


@jit
def harmonic(t, y, p, dydt):
    """y'' = -w^2 y with w = p[0]."""
    dydt[0] = y[1]
    dydt[1] = -p[0] * p[0] * y[0]


@jit
def coordinate_above_level(t, y, p):
    """Event: y[0] comes down to the level p[1]."""
    return y[0] - p[1]


@jit
def van_der_pol(t, y, p, dydt):
    """x'' - mu (1 - x^2) x' + x = 0 with mu = p[0]."""
    dydt[0] = y[1]
    dydt[1] = p[0] * (1.0 - y[0] * y[0]) * y[1] - y[0]


@jit
def riccati(t, y, p, dydt):
    """y' = 1 + y^2: y = tan(t) from y(0) = 0."""
    dydt[0] = 1.0 + y[0] * y[0]


@jit
def scalar_misbehaving(t, y, p, dydt):
    """y' = p[0] y^2 + p[1] y until t = p[2], NaN after (one rhs, one compilation):
    p = (1, 0, inf) blows up at t = 1 from y(0) = 1; p = (0, -1, 1) decays, then NaN."""
    dydt[0] = p[0] * y[0] * y[0] + p[1] * y[0] if t <= p[2] else np.nan


harmonic_event = make_event_solver(harmonic, coordinate_above_level)
harmonic_trajectory = make_trajectory_solver(harmonic)
van_der_pol_solve = make_solver(van_der_pol)
scalar_solve = make_solver(scalar_misbehaving)
BLOW_UP = np.array([1.0, 0.0, np.inf])
DECAY_THEN_NAN = np.array([0.0, -1.0, 1.0])


def harmonic_exact(t, w):
    return np.array([np.cos(w * t), -w * np.sin(w * t)])


def harmonic_until_level(w, level, t_max, rtol=1e-12, atol=1e-14, h0=0.0, t0=0.0):
    """From y(t0) = (1, 0) until y[0] comes down to level: (status, t, n_steps, n_rhs, y)."""
    y = np.array([1.0, 0.0])
    p = np.array([w, level])
    result = harmonic_event(t0, y, p, t_max, rtol, atol, h0, 10_000, workspace(2))
    return (*result, y)


# --------------------------------------------------------------------------
# Tableau and workspace
# --------------------------------------------------------------------------


def test_tableau_equals_scipy_coefficients():
    from scipy.integrate._ivp import dop853_coefficients as ref

    for name in ("A", "B", "C", "E3", "E5", "D"):
        assert np.array_equal(getattr(tableau, name), getattr(ref, name)), name
        assert getattr(tableau, name).dtype == np.float64
    assert (tableau.N_STAGES, tableau.N_STAGES_EXTENDED, tableau.INTERPOLATOR_POWER) == (
        ref.N_STAGES,
        ref.N_STAGES_EXTENDED,
        ref.INTERPOLATOR_POWER,
    )
    # Consistency of the 8th-order weights and the time nodes.
    assert tableau.B.sum() == pytest.approx(1.0, abs=1e-15)
    for s in range(1, tableau.N_STAGES_EXTENDED):
        assert tableau.A[s, :s].sum() == pytest.approx(tableau.C[s], abs=1e-14)


def test_workspace_shape():
    work = workspace(3)
    assert work.shape == (WORK_ROWS, 3) and work.dtype == np.float64
    assert WORK_ROWS >= tableau.N_STAGES_EXTENDED + tableau.INTERPOLATOR_POWER + 2


# --------------------------------------------------------------------------
# Event location
# --------------------------------------------------------------------------


@pytest.mark.parametrize("w", [0.37, 1.0, 2.0, 7.3, 40.0])
def test_harmonic_quarter_period_event(w):
    st, t, n_steps, n_rhs, y = harmonic_until_level(w, 0.0, 10.0 / w)
    t_exact = np.pi / (2 * w)
    assert st == status.OK
    assert abs(t - t_exact) <= 1e-12 * t_exact, (t, t_exact, (t - t_exact) / t_exact)
    # State at the event from the interpolant: (0, -w).
    assert abs(y[0]) <= 1e-12, y
    assert abs(y[1] + w) <= 1e-12 * w, y
    assert 0 < n_steps < 100
    # 1 + 1 (f0, initial-step probe) + 12 per attempt + 3 for the dense output.
    assert (n_rhs - 5) % 12 == 0 and n_rhs >= 12 * n_steps + 5


def test_event_with_given_first_step():
    w = 3.0
    st, t, _, n_rhs, _ = harmonic_until_level(w, 0.0, 10.0, h0=1e-3)
    assert st == status.OK
    assert t == pytest.approx(np.pi / (2 * w), rel=1e-12)
    assert (n_rhs - 4) % 12 == 0  # no initial-step probe


def test_event_at_nonzero_level_and_state():
    # y[0] = cos(w t) comes down to 0.5 at w t = pi / 3.
    w = 1.7
    st, t, _, _, y = harmonic_until_level(w, 0.5, 10.0)
    assert st == status.OK
    assert t == pytest.approx(np.pi / (3 * w), rel=1e-12)
    np.testing.assert_allclose(y, harmonic_exact(t, w), rtol=0, atol=1e-11)


def test_event_never_happens_returns_no_event_at_t_max():
    w, t_max = 2.0, 7.0
    st, t, n_steps, _, y = harmonic_until_level(w, -2.0, t_max, rtol=1e-10, atol=1e-12)
    assert st == status.NO_EVENT
    assert t == t_max
    assert n_steps > 0
    np.testing.assert_allclose(y, harmonic_exact(t_max, w), rtol=0, atol=1e-8)


def test_event_after_t_max_and_empty_interval():
    st, t, _, _, _ = harmonic_until_level(1.0, 0.0, 1.0)
    assert (st, t) == (status.NO_EVENT, 1.0)  # crossing at pi/2 > 1
    st, t, n_steps, _, y = harmonic_until_level(1.0, 0.0, 2.0, t0=2.0)
    assert (st, t, n_steps) == (status.NO_EVENT, 2.0, 0)
    assert np.array_equal(y, [1.0, 0.0])


# --------------------------------------------------------------------------
# Agreement with scipy's DOP853
# --------------------------------------------------------------------------


@pytest.mark.parametrize("rtol,atol", [(1e-6, 1e-9), (1e-8, 1e-10), (1e-11, 1e-13)])
def test_van_der_pol_agrees_with_scipy(rtol, atol):
    mu, t_end, y0 = 1.0, 20.0, np.array([2.0, 0.0])
    y = y0.copy()
    st, n_steps, n_rhs = van_der_pol_solve(
        0.0, y, np.array([mu]), t_end, rtol, atol, 0.0, 100_000, workspace(2)
    )
    ref = solve_ivp(
        lambda t, z: [z[1], mu * (1 - z[0] ** 2) * z[1] - z[0]],
        (0.0, t_end),
        y0,
        method="DOP853",
        rtol=rtol,
        atol=atol,
    )
    ref_steps = ref.t.size - 1
    msg = (
        f"accepted steps: ours {n_steps}, scipy {ref_steps}; rhs evaluations: ours {n_rhs}, "
        f"scipy {ref.nfev}; y(t_end): ours {y}, scipy {ref.y[:, -1]}"
    )
    assert st == status.OK
    assert abs(n_steps - ref_steps) <= 3, msg
    assert abs(n_rhs - ref.nfev) <= 3 * 12, msg
    # Same algorithm: the two differ only by round-off, far below the tolerance.
    np.testing.assert_allclose(y, ref.y[:, -1], rtol=0, atol=rtol * 1e-2, err_msg=msg)


# --------------------------------------------------------------------------
# Order of convergence with fixed steps
# --------------------------------------------------------------------------


def test_fixed_step_convergence_order_is_eight():
    step = make_stepper(riccati)
    work, p = workspace(1), np.empty(0)
    t_end = 1.2  # tan(1.2) = 2.57: errors from 3e-8 down to 6e-13, all far above round-off

    def integrate(n_steps):
        h = t_end / n_steps
        y, f = np.zeros(1), np.empty(1)
        y_new, f_new = np.empty(1), np.empty(1)
        riccati(0.0, y, p, f)
        for k in range(n_steps):
            step(k * h, y, f, h, p, 1e-6, 1e-9, work, y_new, f_new)
            y[:], f[:] = y_new, f_new
        return y[0]

    counts = np.array([8, 12, 16, 24, 32])
    errors = np.array([abs(integrate(n) - np.tan(t_end)) for n in counts])
    assert errors.min() > 1e3 * np.spacing(np.tan(t_end)), errors
    slope = np.polyfit(np.log(t_end / counts), np.log(errors), 1)[0]
    assert 7.5 <= slope <= 8.7, (slope, errors)


def test_stepper_error_norm_drives_acceptance():
    # The returned norm scales like h^8 (7th-order estimator damped by the 3rd).
    step = make_stepper(van_der_pol)
    p, work = np.array([1.0]), workspace(2)
    y = np.array([2.0, 0.0])
    f = np.empty(2)
    van_der_pol(0.0, y, p, f)
    y_new, f_new = np.empty(2), np.empty(2)
    big = step(0.0, y, f, 0.4, p, 1e-10, 1e-12, work, y_new, f_new)
    small = step(0.0, y, f, 0.05, p, 1e-10, 1e-12, work, y_new, f_new)
    assert big > 1.0 > small > 0.0, (big, small)
    f_check = np.empty(2)
    van_der_pol(0.05, y_new, p, f_check)
    assert np.array_equal(f_new, f_check)


# --------------------------------------------------------------------------
# Dense output through the trajectory solver
# --------------------------------------------------------------------------


def test_trajectory_matches_exact_harmonic_solution():
    w, rtol, atol = 1.3, 1e-10, 1e-12
    t_eval = np.linspace(0.0, 15.0, 401)  # ~3 periods, several points per step
    y = np.array([1.0, 0.0])
    out = np.empty((t_eval.size, 2))
    st, n_steps, n_rhs = harmonic_trajectory(
        0.0, y, np.array([w]), t_eval, rtol, atol, 0.0, 10_000, workspace(2), out
    )
    assert st == status.OK
    assert n_steps < t_eval.size  # so most values come from the interpolant
    exact = harmonic_exact(t_eval, w).T
    error = np.abs(out - exact).max()
    assert error <= 100 * rtol, error
    assert np.array_equal(out[0], [1.0, 0.0])
    assert np.array_equal(out[-1], y)  # y ends at t_eval[-1], the exact step end


def test_trajectory_failure_leaves_nan_rows():
    t_eval = np.linspace(0.5, 100.0, 50)
    y = np.array([1.0, 0.0])
    out = np.zeros((t_eval.size, 2))
    st, n_steps, _ = harmonic_trajectory(
        0.0, y, np.array([1.0]), t_eval, 1e-10, 1e-12, 0.0, 10, workspace(2), out
    )
    assert st == status.MAX_STEPS
    reached = ~np.isnan(out[:, 0])
    assert reached[0] and not reached[-1]
    assert np.all(np.isnan(out[~reached]))
    # Reached rows form a prefix and are accurate.
    k = reached.sum()
    assert reached[:k].all()
    np.testing.assert_allclose(out[:k], harmonic_exact(t_eval[:k], 1.0).T, atol=1e-8)


# --------------------------------------------------------------------------
# Statuses
# --------------------------------------------------------------------------


def test_max_steps():
    y = np.array([2.0, 0.0])
    st, n_steps, n_rhs = van_der_pol_solve(
        0.0, y, np.array([1.0]), 1000.0, 1e-10, 1e-12, 0.0, 5, workspace(2)
    )
    assert st == status.MAX_STEPS
    assert n_steps <= 5
    assert n_rhs == 2 + 5 * 12  # every attempt was made, no more
    assert np.all(np.isfinite(y))


def test_nan_rhs_is_nonfinite():
    st, t, n_steps, _, _ = harmonic_until_level(np.nan, 0.0, 10.0)
    assert (st, t, n_steps) == (status.NONFINITE, 0.0, 0)


def test_nan_appearing_mid_run_is_nonfinite():
    y = np.array([1.0])
    st, n_steps, _ = scalar_solve(
        0.0, y, DECAY_THEN_NAN, 2.0, 1e-10, 1e-12, 0.0, 10_000, workspace(1)
    )
    assert st == status.NONFINITE, status.MEANINGS.get(st)
    assert n_steps > 0 and np.isfinite(y[0])
    # The last accepted state is on the exact solution, at some t <= 1.
    t_last = -np.log(y[0])
    assert 0.0 < t_last <= 1.0 + 1e-9
    # Without NaN the same problem is fine.
    y = np.array([1.0])
    p = np.array([0.0, -1.0, np.inf])
    st, _, _ = scalar_solve(0.0, y, p, 2.0, 1e-10, 1e-12, 0.0, 10_000, workspace(1))
    assert st == status.OK and y[0] == pytest.approx(np.exp(-2.0), rel=1e-9)


def test_blow_up_is_not_ok_and_returns():
    y = np.array([1.0])
    st, _, _ = scalar_solve(0.0, y, BLOW_UP, 0.5, 1e-8, 1e-10, 0.0, 1_000_000, workspace(1))
    assert st == status.OK and y[0] == pytest.approx(2.0, rel=1e-7)  # also compiles
    y = np.array([1.0])
    start = time.perf_counter()
    st, n_steps, _ = scalar_solve(0.0, y, BLOW_UP, 2.0, 1e-8, 1e-10, 0.0, 1_000_000, workspace(1))
    elapsed = time.perf_counter() - start
    assert st in (status.STEP_UNDERFLOW, status.NONFINITE, status.MAX_STEPS), st
    assert n_steps < 10_000
    assert elapsed < 1.0  # gives up near t = 1 instead of shrinking h forever


# --------------------------------------------------------------------------
# Use inside a user's parallel numba function
# --------------------------------------------------------------------------


@numba.njit(parallel=True)
def _event_times_in_prange(params, t_out, y_out, counts_out):
    for i in numba.prange(params.shape[0]):
        work = workspace(2)
        y = np.array([1.0, 0.0])
        st, t, n_steps, n_rhs = harmonic_event(
            0.0, y, params[i], 100.0, 1e-11, 1e-13, 0.0, 10_000, work
        )
        t_out[i] = t
        y_out[i, 0] = y[0]
        y_out[i, 1] = y[1]
        counts_out[i, 0] = st
        counts_out[i, 1] = n_steps
        counts_out[i, 2] = n_rhs


def test_prange_caller_matches_serial_calls_bitwise():
    m = 24
    params = np.column_stack([np.linspace(0.5, 6.0, m), np.linspace(-0.5, 0.5, m)])
    t_par = np.empty(m)
    y_par = np.empty((m, 2))
    counts_par = np.empty((m, 3), dtype=np.int64)
    _event_times_in_prange(params, t_par, y_par, counts_par)
    work = workspace(2)
    for i in range(m):
        y = np.array([1.0, 0.0])
        st, t, n_steps, n_rhs = harmonic_event(
            0.0, y, params[i], 100.0, 1e-11, 1e-13, 0.0, 10_000, work
        )
        assert st == status.OK
        assert t == t_par[i] and np.array_equal(y, y_par[i]), i
        assert (st, n_steps, n_rhs) == tuple(counts_par[i]), i


# ----------------------------------------------------------------------------- stiffness detection
def test_stiffness_test_stops_van_der_pol_in_its_stiff_phase():
    """Van der Pol with mu = 1000 is stiff on its slow branches: the explicit step is held at
    the stability boundary there, and the test must say so instead of grinding on."""
    solve = make_solver(van_der_pol, stiffness_test=True)
    y = np.array([2.0, 0.0])
    code, n_steps, _ = solve(0.0, y, np.array([1000.0]), 3000.0, 1e-6, 1e-9, 0.0, 10**6, workspace(2))
    assert code == status.STIFF
    assert n_steps < 2000  # detected early: scipy's DOP853 needs ~10^6 steps for this interval
    plain = make_solver(van_der_pol)
    y = np.array([2.0, 0.0])
    code, _, _ = plain(0.0, y, np.array([1000.0]), 3000.0, 1e-6, 1e-9, 0.0, 5000, workspace(2))
    # without the test on every step the same budget is used up; the test on its last steps says why
    assert code == status.STIFF


def _plain(kind, rhs, p, t_end, budget, stiffness_test=False):
    """(status, n_steps, y) of dop853's solver ``kind`` from (2, 0) to t_end (the event never fires)."""
    y = np.array([2.0, 0.0])
    if kind == "solve":
        r = make_solver(rhs, stiffness_test=stiffness_test)(0.0, y, p, t_end, 1e-6, 1e-9, 0.0, budget, workspace(2))
    elif kind == "event":
        r = make_event_solver(rhs, coordinate_above_level, stiffness_test=stiffness_test)(
            0.0, y, p, t_end, 1e-6, 1e-9, 0.0, budget, workspace(2))
        r = (r[0], r[2])
    else:
        r = make_trajectory_solver(rhs, stiffness_test=stiffness_test)(
            0.0, y, p, np.array([0.0, 1.0, t_end]), 1e-6, 1e-9, 0.0, budget, workspace(2), np.empty((3, 2)))
    return r[0], r[1], y


@pytest.mark.parametrize("kind", ["solve", "event", "trajectory"])
def test_plain_solvers_say_stiff_where_their_budget_ends_at_the_stability_limit(kind):
    """Without ``stiffness_test`` the test runs on the last STIFF_WINDOW attempts of the budget only:
    van der Pol's slow branch (mu = 1000) spends 5000 attempts at the stability limit: STIFF. A budget
    of 10 (too few for the 15 steps the test needs) and a harmonic oscillator cut short keep
    MAX_STEPS, and the test changes no step: the state where they stop is the solver's without it."""
    vdp = np.array([1000.0, -5.0])  # level -5: never reached
    assert _plain(kind, van_der_pol, vdp, 3000.0, 5000)[0] == status.STIFF
    assert _plain(kind, van_der_pol, vdp, 3000.0, 10)[0] == status.MAX_STEPS
    osc = np.array([1.0, -5.0])
    code, n_steps, y = _plain(kind, harmonic, osc, 2000 * np.pi, 3000)
    assert code == status.MAX_STEPS and n_steps > 2000
    with_test = _plain(kind, harmonic, osc, 2000 * np.pi, 3000, stiffness_test=True)
    assert with_test[:2] == (code, n_steps) and np.array_equal(with_test[2], y)


@pytest.mark.parametrize("kind", ["solve", "event", "trajectory"])
def test_stiffness_test_is_silent_on_a_nonstiff_problem(kind):
    """1000 periods of a harmonic oscillator, loose and tight tolerances: never STIFF, and the
    result is identical to the solver without the test."""
    p = np.array([1.0, -2.0])  # level -2 is never reached: the event solver runs to t_max
    t_end = 2000 * np.pi
    for rtol in (1e-4, 1e-12):
        results = []
        for test in (False, True):
            y = np.array([1.0, 0.0])
            if kind == "solve":
                r = make_solver(harmonic, stiffness_test=test)(0.0, y, p, t_end, rtol, 1e-14, 0.0, 10**6, workspace(2))
            elif kind == "event":
                r = make_event_solver(harmonic, coordinate_above_level, stiffness_test=test)(
                    0.0, y, p, t_end, rtol, 1e-14, 0.0, 10**6, workspace(2))
            else:
                out = np.empty((3, 2))
                r = make_trajectory_solver(harmonic, stiffness_test=test)(
                    0.0, y, p, np.array([0.0, 1.0, t_end]), rtol, 1e-14, 0.0, 10**6, workspace(2), out)
            results.append((r, y.copy()))
        (r0, y0), (r1, y1) = results
        assert r1[0] != status.STIFF
        assert r0 == r1 and np.array_equal(y0, y1)
