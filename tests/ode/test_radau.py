"""Tests of the numba Radau IIA integrator (mechsweep.ode.radau).

Every (rhs, solver kind) pair is a separate JIT compilation costing seconds, so
all test problems share ONE right-hand side and Jacobian, selected by p[0]
(``zoo`` below); the whole file then compiles one solver, one event solver,
one trajectory solver, one stepper and one prange kernel.
"""
from __future__ import annotations

import time

import numba
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from mechsweep import status
from mechsweep._jit import jit
from mechsweep.ode import radau
from mechsweep.ode.radau import (
    jacobian_and_lu_counts,
    make_event_solver,
    make_solver,
    make_stepper,
    make_trajectory_solver,
    workspace,
)

# A NumbaWarning (e.g. "cannot cache") fails the test that triggers it.
pytestmark = pytest.mark.filterwarnings("error::numba.NumbaWarning")

# --------------------------------------------------------------------------
# The test problems (p[0] selects one)
# --------------------------------------------------------------------------

QUADRATIC, VAN_DER_POL, ROBERTSON = 0.0, 1.0, 2.0


@jit
def zoo(t, y, p, dydt):
    """p[0] = 0: y' = A y + b * y**2 (componentwise) while t <= p[1], NaN after;
    p = (0, t_nan, A row-major (n*n), b (n), event level).
    p[0] = 1: Van der Pol x'' - mu (1 - x^2) x' + x = 0, p = (1, mu).
    p[0] = 2: Robertson's chemical kinetics."""
    n = y.size
    if p[0] == 0.0:
        if t > p[1]:
            for i in range(n):
                dydt[i] = np.nan
            return
        for i in range(n):
            acc = p[2 + n * n + i] * y[i] * y[i]
            for j in range(n):
                acc += p[2 + i * n + j] * y[j]
            dydt[i] = acc
    elif p[0] == 1.0:
        mu = p[1]
        dydt[0] = y[1]
        dydt[1] = mu * (1.0 - y[0] * y[0]) * y[1] - y[0]
    else:
        dydt[0] = -0.04 * y[0] + 1e4 * y[1] * y[2]
        dydt[1] = 0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] * y[1]
        dydt[2] = 3e7 * y[1] * y[1]


@jit
def zoo_jac(t, y, p, J):
    n = y.size
    if p[0] == 0.0:
        for i in range(n):
            for j in range(n):
                J[i, j] = p[2 + i * n + j]
            J[i, i] += 2.0 * p[2 + n * n + i] * y[i]
    elif p[0] == 1.0:
        mu = p[1]
        J[0, 0] = 0.0
        J[0, 1] = 1.0
        J[1, 0] = -2.0 * mu * y[0] * y[1] - 1.0
        J[1, 1] = mu * (1.0 - y[0] * y[0])
    else:
        J[0, 0] = -0.04
        J[0, 1] = 1e4 * y[2]
        J[0, 2] = 1e4 * y[1]
        J[1, 0] = 0.04
        J[1, 1] = -1e4 * y[2] - 6e7 * y[1]
        J[1, 2] = -1e4 * y[1]
        J[2, 0] = 0.0
        J[2, 1] = 6e7 * y[1]
        J[2, 2] = 0.0


@jit
def first_coordinate_down_to_level(t, y, p):
    return y[0] - p[p.size - 1]


def quadratic_params(A, b=None, t_nan=np.inf, level=0.0):
    A = np.atleast_2d(np.asarray(A, dtype=float))
    b = np.zeros(A.shape[0]) if b is None else np.asarray(b, dtype=float)
    return np.concatenate([[QUADRATIC, t_nan], A.ravel(), b, [level]])


def harmonic_matrix(w):
    return np.array([[0.0, 1.0], [-w * w, 0.0]])


def harmonic_exact(t, w):
    return np.array([np.cos(w * t), -w * np.sin(w * t)])


solve = make_solver(zoo, zoo_jac)
event_solve = make_event_solver(zoo, zoo_jac, first_coordinate_down_to_level)
trajectory_solve = make_trajectory_solver(zoo, zoo_jac)


def scipy_reference(p, y0, t_end, rtol, atol):
    """scipy's Radau on the same problem with the same analytic Jacobian."""
    def f(t, y):
        out = np.empty_like(y)
        zoo(t, y, p, out)
        return out

    def jac(t, y):
        J = np.empty((y.size, y.size))
        zoo_jac(t, y, p, J)
        return J

    return solve_ivp(f, (0.0, t_end), y0, method="Radau", rtol=rtol, atol=atol, jac=jac)


# --------------------------------------------------------------------------
# Coefficients, workspace and linear algebra
# --------------------------------------------------------------------------


def test_coefficients_equal_scipy():
    from scipy.integrate._ivp import radau as ref

    for name in ("C", "E", "T", "TI", "P"):
        assert np.array_equal(getattr(radau, name), getattr(ref, name)), name
    assert radau.MU_REAL == ref.MU_REAL and radau.MU_COMPLEX == ref.MU_COMPLEX
    assert radau.NEWTON_MAXITER == ref.NEWTON_MAXITER
    # T diagonalises the Radau IIA matrix: T^-1 A^-1 T = diag(MU_REAL, MU_COMPLEX pair).
    assert np.allclose(radau.T @ radau.TI, np.eye(3), atol=1e-14)


def test_workspace_layout():
    real, cplx, pivots, state = workspace(3)
    assert real.shape == (radau.VECTOR_ROWS + 6, 3) and real.dtype == np.float64
    assert cplx.shape == (4, 3) and cplx.dtype == np.complex128
    assert pivots.shape == (2, 3) and pivots.dtype == np.int64
    assert state.shape == (radau.STATE_SIZE,) and state.dtype == np.float64


@pytest.mark.parametrize("n", [1, 2, 5])
def test_lu_matches_numpy_and_reports_singular(n):
    rng = np.random.default_rng(n)
    J = rng.normal(size=(n, n))
    b = rng.normal(size=n)
    mu_real, mu_complex = 0.7, 0.4 - 1.3j
    lu = np.empty((n, n))
    piv = np.empty(n, dtype=np.int64)
    assert radau._lu_factor(J, mu_real, lu, piv) == radau._LU_OK
    x = b.copy()
    radau._lu_solve(lu, piv, x)
    np.testing.assert_allclose(x, np.linalg.solve(mu_real * np.eye(n) - J, b), rtol=1e-12)
    lu_c = np.empty((n, n), dtype=np.complex128)
    assert radau._lu_factor(J, mu_complex, lu_c, piv) == radau._LU_OK
    xc = b.astype(np.complex128)
    radau._lu_solve(lu_c, piv, xc)
    np.testing.assert_allclose(xc, np.linalg.solve(mu_complex * np.eye(n) - J, b), rtol=1e-12)
    # mu I - J singular (mu equal to an eigenvalue of a triangular J): no exception.
    J_tri = np.triu(J)
    J_tri[n - 1, n - 1] = mu_real
    assert radau._lu_factor(J_tri, mu_real, lu, piv) == radau._LU_SINGULAR
    J_nan = J.copy()
    J_nan[0, 0] = np.nan
    assert radau._lu_factor(J_nan, mu_real, lu, piv) == radau._LU_NONFINITE


# --------------------------------------------------------------------------
# Agreement with scipy's Radau (same algorithm: same steps, same counts)
# --------------------------------------------------------------------------

# Measured (scipy 1.17): accepted steps equal to scipy's in 5 of 6 cases
# (VdP mu=1000 at rtol 1e-3: 285 vs 286; round-off differences in the LU/dot
# products change the step sequence of this stiff case slightly), rhs and
# Jacobian evaluations equal or within 1 %, final states within 0.03 of the
# tolerance scale.
@pytest.mark.parametrize(
    "mu,t_end,rtol,atol",
    [
        (1000.0, 3000.0, 1e-3, 1e-6),
        (1000.0, 3000.0, 1e-6, 1e-9),
        (1.0, 20.0, 1e-6, 1e-9),
        (1.0, 20.0, 1e-9, 1e-12),
    ],
)
def test_van_der_pol_agrees_with_scipy(mu, t_end, rtol, atol):
    p = np.array([VAN_DER_POL, mu])
    y0 = np.array([2.0, 0.0])
    y = y0.copy()
    work = workspace(2)
    st, n_steps, n_rhs = solve(0.0, y, p, t_end, rtol, atol, 0.0, 1_000_000, work)
    n_jac, n_lu = jacobian_and_lu_counts(work)
    ref = scipy_reference(p, y0, t_end, rtol, atol)
    ref_steps = ref.t.size - 1
    msg = (
        f"steps ours {n_steps} scipy {ref_steps}; nfev {n_rhs} / {ref.nfev}; "
        f"njev {n_jac} / {ref.njev}; nlu {n_lu} / {ref.nlu}; y {y} / {ref.y[:, -1]}"
    )
    assert st == status.OK
    assert abs(n_steps - ref_steps) <= max(2, 0.01 * ref_steps), msg
    assert abs(n_rhs - ref.nfev) <= max(10, 0.02 * ref.nfev), msg
    assert abs(n_jac - ref.njev) <= max(2, 0.02 * ref.njev), msg
    assert abs(n_lu - ref.nlu) <= max(4, 0.02 * ref.nlu), msg
    scale = atol + rtol * np.abs(ref.y[:, -1])
    assert np.all(np.abs(y - ref.y[:, -1]) <= 0.1 * scale), msg


def test_robertson_agrees_with_scipy():
    p = np.array([ROBERTSON])
    y0 = np.array([1.0, 0.0, 0.0])
    rtol, atol, t_end = 1e-6, 1e-10, 1e5
    y = y0.copy()
    work = workspace(3)
    st, n_steps, n_rhs = solve(0.0, y, p, t_end, rtol, atol, 0.0, 100_000, work)
    ref = scipy_reference(p, y0, t_end, rtol, atol)
    ref_steps = ref.t.size - 1
    msg = f"steps ours {n_steps} scipy {ref_steps}; nfev {n_rhs} / {ref.nfev}; y {y} / {ref.y[:, -1]}"
    assert st == status.OK
    assert abs(n_steps - ref_steps) <= max(2, 0.01 * ref_steps), msg
    assert abs(n_rhs - ref.nfev) <= max(10, 0.015 * ref.nfev), msg
    assert np.all(np.abs(y - ref.y[:, -1]) <= 3 * (atol + rtol * np.abs(ref.y[:, -1]))), msg
    assert abs(y.sum() - 1.0) <= 1e-9  # mass is conserved (linear invariant, kept by RK)


# --------------------------------------------------------------------------
# Accuracy and order
# --------------------------------------------------------------------------


def test_stiff_linear_system_matches_matrix_exponential():
    V = np.array([[1.0, 1.0], [1.0, 2.0]])
    A = V @ np.diag([-1.0, -1e6]) @ np.linalg.inv(V)
    y0 = np.array([1.0, 3.0])
    rtol, atol = 1e-8, 1e-12
    for t_end in (1e-4, 1.0, 5.0):
        y = y0.copy()
        st, n_steps, _ = solve(
            0.0, y, quadratic_params(A), t_end, rtol, atol, 0.0, 100_000, workspace(2)
        )
        exact = expm(A * t_end) @ y0
        assert st == status.OK
        np.testing.assert_allclose(y, exact, rtol=20 * rtol, atol=20 * atol)
        # Measured 212 / 246 / 375 steps; an explicit method needs ~1e6 t_end for stability.
        assert n_steps < 1000, n_steps


def test_fixed_step_convergence_order_is_five():
    # Van der Pol mu = 1, nonlinear: step-end error of Radau IIA (3 stages) is O(h^5).
    p = np.array([VAN_DER_POL, 1.0])
    step = make_stepper(zoo, zoo_jac)
    work = workspace(2)
    t_end = 2.0
    y0 = np.array([2.0, 0.0])
    ref = solve_ivp(
        lambda t, z: [z[1], (1 - z[0] ** 2) * z[1] - z[0]],
        (0.0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-15,
    ).y[:, -1]

    def integrate(n_steps):
        h = t_end / n_steps
        y, f = y0.copy(), np.empty(2)
        y_new, f_new = np.empty(2), np.empty(2)
        zoo(0.0, y, p, f)
        for k in range(n_steps):
            # Tight tolerances: the Newton iteration stops far below the step's error.
            err = step(k * h, y, f, h, p, 1e-12, 1e-12, work, y_new, f_new)
            assert np.isfinite(err), (n_steps, k)  # Newton converged from a zero guess
            y[:], f[:] = y_new, f_new
        return y

    # Measured errors 5.8e-8 ... 1.3e-10 (slope 5.0); with h >= 0.15 the Newton
    # iteration from a zero guess fails scipy's rate test (the solver would halve h).
    counts = np.array([20, 28, 40, 56, 64])
    errors = np.array([np.abs(integrate(n) - ref).max() for n in counts])
    assert errors.min() > 1e-11, errors  # far above the reference's error
    slope = np.polyfit(np.log(t_end / counts), np.log(errors), 1)[0]
    assert 4.5 <= slope <= 5.8, (slope, errors)


def test_stepper_error_norm_drives_acceptance():
    # The embedded estimate is O(h^4) (3rd order): big step fails, small one passes.
    p = np.array([VAN_DER_POL, 1.0])
    step = make_stepper(zoo, zoo_jac)
    work = workspace(2)
    y = np.array([2.0, 0.0])
    f = np.empty(2)
    zoo(0.0, y, p, f)
    y_new, f_new = np.empty(2), np.empty(2)
    big = step(0.0, y, f, 0.125, p, 1e-6, 1e-8, work, y_new, f_new)  # measured 50
    half = step(0.0, y, f, 0.0625, p, 1e-6, 1e-8, work, y_new, f_new)
    small = step(0.0, y, f, 0.02, p, 1e-6, 1e-8, work, y_new, f_new)
    assert big > 1.0 > small > 0.0, (big, half, small)
    assert 8.0 < big / half < 32.0, big / half  # ~2^4
    f_check = np.empty(2)
    zoo(0.02, y_new, p, f_check)
    assert np.array_equal(f_new, f_check)
    # Newton failure (zero guess, h too large) is reported as inf, not an exception.
    assert step(0.0, y, f, 0.5, p, 1e-8, 1e-10, work, y_new, f_new) == np.inf
    assert np.all(np.isnan(y_new))


def test_tiny_rtol_is_raised_like_scipy():
    y = np.array([1.0])
    st, n_steps, _ = solve(
        0.0, y, quadratic_params([[-1.0]]), 1.0, 1e-30, 1e-30, 0.0, 100_000, workspace(1)
    )
    assert st == status.OK and 0 < n_steps < 20_000
    assert y[0] == pytest.approx(np.exp(-1.0), rel=1e-12)


# --------------------------------------------------------------------------
# Event location and dense output
# --------------------------------------------------------------------------


@pytest.mark.parametrize("w", [0.37, 1.0, 7.3])
def test_harmonic_quarter_period_event(w):
    rtol, atol = 1e-10, 1e-12
    y = np.array([1.0, 0.0])
    p = quadratic_params(harmonic_matrix(w), level=0.0)
    st, t, n_steps, _ = event_solve(0.0, y, p, 10.0 / w, rtol, atol, 0.0, 100_000, workspace(2))
    t_exact = np.pi / (2 * w)
    assert st == status.OK
    # Measured relative errors below 1e-13 (t) and 4e-12 (y).
    assert abs(t - t_exact) <= 0.1 * rtol * t_exact, (t, t_exact, (t - t_exact) / t_exact)
    np.testing.assert_allclose(y, [0.0, -w], rtol=0, atol=rtol * w)
    assert 0 < n_steps < 1000


def test_event_at_level_and_no_event():
    w = 1.7
    p = quadratic_params(harmonic_matrix(w), level=0.5)
    y = np.array([1.0, 0.0])
    st, t, _, _ = event_solve(0.0, y, p, 10.0, 1e-10, 1e-12, 0.0, 100_000, workspace(2))
    assert st == status.OK
    assert t == pytest.approx(np.pi / (3 * w), rel=1e-9)
    np.testing.assert_allclose(y, harmonic_exact(t, w), rtol=0, atol=1e-9)
    p = quadratic_params(harmonic_matrix(w), level=-2.0)
    y = np.array([1.0, 0.0])
    st, t, n_steps, _ = event_solve(0.0, y, p, 7.0, 1e-10, 1e-12, 0.0, 100_000, workspace(2))
    assert (st, t) == (status.NO_EVENT, 7.0) and n_steps > 0
    np.testing.assert_allclose(y, harmonic_exact(7.0, w), rtol=0, atol=1e-8)


def test_trajectory_matches_exact_harmonic_solution():
    w, rtol, atol = 1.3, 1e-6, 1e-8
    t_eval = np.linspace(0.0, 15.0, 401)
    y = np.array([1.0, 0.0])
    out = np.empty((t_eval.size, 2))
    st, n_steps, _ = trajectory_solve(
        0.0, y, quadratic_params(harmonic_matrix(w)), t_eval, rtol, atol, 0.0, 100_000,
        workspace(2), out,
    )
    assert st == status.OK
    assert n_steps < t_eval.size  # most rows come from the collocation polynomial
    error = np.abs(out - harmonic_exact(t_eval, w).T).max()
    assert error <= rtol, error  # measured 0.15 rtol
    assert np.array_equal(out[0], [1.0, 0.0])
    assert np.array_equal(out[-1], y)


def test_trajectory_failure_leaves_nan_rows():
    t_eval = np.linspace(0.5, 100.0, 200)
    y = np.array([1.0, 0.0])
    out = np.zeros((t_eval.size, 2))
    st, _, _ = trajectory_solve(
        0.0, y, quadratic_params(harmonic_matrix(1.0)), t_eval, 1e-7, 1e-9, 0.0, 60,
        workspace(2), out,
    )
    assert st == status.MAX_STEPS
    reached = ~np.isnan(out[:, 0])
    k = reached.sum()
    assert 2 <= k < t_eval.size and reached[:k].all()
    np.testing.assert_allclose(out[:k], harmonic_exact(t_eval[:k], 1.0).T, atol=1e-8)


# --------------------------------------------------------------------------
# Statuses
# --------------------------------------------------------------------------


def test_max_steps():
    y = np.array([2.0, 0.0])
    st, n_steps, _ = solve(
        0.0, y, np.array([VAN_DER_POL, 1000.0]), 3000.0, 1e-6, 1e-9, 0.0, 5, workspace(2)
    )
    assert st == status.MAX_STEPS
    assert n_steps <= 5 and np.all(np.isfinite(y))


def test_nan_rhs_is_nonfinite():
    y = np.array([1.0, 0.0])
    st, t, n_steps, _ = event_solve(
        0.0, y, quadratic_params(harmonic_matrix(np.nan)), 10.0, 1e-8, 1e-10, 0.0, 1000,
        workspace(2),
    )
    assert (st, t, n_steps) == (status.NONFINITE, 0.0, 0)


def test_nan_appearing_mid_run_is_nonfinite():
    y = np.array([1.0])
    st, n_steps, _ = solve(
        0.0, y, quadratic_params([[-1.0]], t_nan=1.0), 2.0, 1e-10, 1e-12, 0.0, 10_000, workspace(1)
    )
    assert st == status.NONFINITE, status.MEANINGS.get(st)
    assert n_steps > 0 and np.isfinite(y[0])
    t_last = -np.log(y[0])  # the last accepted state is on the exact solution
    assert 0.0 < t_last <= 1.0 + 1e-9


def test_blow_up_is_not_ok_and_returns():
    p = quadratic_params([[0.0]], b=[1.0])  # y' = y^2, y = 1 / (1 - t)
    y = np.array([1.0])
    st, _, _ = solve(0.0, y, p, 0.5, 1e-8, 1e-10, 0.0, 1_000_000, workspace(1))
    assert st == status.OK and y[0] == pytest.approx(2.0, rel=1e-7)
    y = np.array([1.0])
    start = time.perf_counter()
    st, n_steps, _ = solve(0.0, y, p, 2.0, 1e-8, 1e-10, 0.0, 1_000_000, workspace(1))
    elapsed = time.perf_counter() - start
    assert st in (status.STEP_UNDERFLOW, status.NONFINITE, status.MAX_STEPS), st
    assert n_steps < 10_000 and y[0] > 1e3  # went up the singularity, not past it
    assert elapsed < 1.0


# --------------------------------------------------------------------------
# Use inside a user's parallel numba function
# --------------------------------------------------------------------------


@numba.njit(parallel=True)
def _van_der_pol_blocks_in_prange(mus, block, y_out, counts_out):
    n_blocks = (mus.size + block - 1) // block
    for b in numba.prange(n_blocks):
        work = workspace(2)  # one workspace per block, reused by its points
        p = np.empty(2)
        p[0] = 1.0
        for i in range(b * block, min((b + 1) * block, mus.size)):
            p[1] = mus[i]
            y = np.array([2.0, 0.0])
            st, n_steps, n_rhs = solve(0.0, y, p, 3.0, 1e-7, 1e-10, 0.0, 100_000, work)
            y_out[i, 0] = y[0]
            y_out[i, 1] = y[1]
            counts_out[i, 0] = st
            counts_out[i, 1] = n_steps
            counts_out[i, 2] = n_rhs


# Compiling the parallel kernel re-optimises the whole solver inside it: ~10 s
# of the file's ~50 s cold-cache CPU time, hence marked slow.
@pytest.mark.slow
def test_prange_caller_matches_serial_calls_bitwise():
    mus = np.geomspace(0.1, 300.0, 13)
    y_par = np.empty((mus.size, 2))
    counts_par = np.empty((mus.size, 3), dtype=np.int64)
    _van_der_pol_blocks_in_prange(mus, 4, y_par, counts_par)
    work = workspace(2)
    for i, mu in enumerate(mus):
        y = np.array([2.0, 0.0])
        result = solve(0.0, y, np.array([VAN_DER_POL, mu]), 3.0, 1e-7, 1e-10, 0.0, 100_000, work)
        assert result[0] == status.OK
        assert np.array_equal(y, y_par[i]), i
        assert tuple(result) == tuple(counts_par[i]), i
