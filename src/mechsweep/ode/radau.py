"""Adaptive implicit Radau IIA integrator (order 5, 3 stages) in numba.

Over 700 lines on purpose: one integrator, its step, Newton iteration, error estimate, controller
and allocation-free linear algebra read together, as in Hairer and Wanner's code it follows.

Same algorithm as ``scipy.integrate.solve_ivp(method="Radau")`` (Hairer &
Wanner, *Solving ODEs II*, Sec. IV.8): the collocation system is solved by
simplified Newton iterations on the transformed system (one real n x n and
one complex n x n linear system per iteration, matrices ``MU_REAL / h - J``
and ``MU_COMPLEX / h - J``), at most ``NEWTON_MAXITER = 6`` iterations with
scipy's convergence-rate test; the 3rd-order embedded error estimate
``(MU_REAL / h - J)^-1 (f + Z^T E / h)`` and, after a rejection within the same
step, the "second" estimate that starts from ``f(t, y + error)``; the
predictive (Gustafsson) step controller with safety
``0.9 (2 NEWTON_MAXITER + 1) / (2 NEWTON_MAXITER + n_iter)``; scipy's rules for
reusing the Jacobian (re-evaluated after a step whose Newton iteration needed
more than 2 iterations at a rate above 1e-3, or when Newton fails with an old
Jacobian) and the LU factors (kept while the step size is unchanged, i.e. the
step factor was < 1.2 and clipped to 1); the first Newton guess extrapolated
from the previous step's collocation polynomial; the cubic collocation
polynomial as dense output; scipy's ``select_initial_step`` with error
order 3. Like :mod:`mechsweep.ode.dop853` it never allocates in the solve, so
millions of short integrations can run inside a ``prange`` loop: the LU
factorisations (partial pivoting, row interchanges as LAPACK's getrf) and the
triangular solves are our own and work on the workspace.

Usage::

    @jit
    def rhs(t, y, p, dydt):          # writes dy/dt into dydt, returns nothing
        dydt[0] = y[1]
        dydt[1] = p[0] * (1.0 - y[0] * y[0]) * y[1] - y[0]

    @jit
    def jac(t, y, p, J):             # writes J[i, j] = d rhs_i / d y_j (all entries)
        J[0, 0] = 0.0
        J[0, 1] = 1.0
        J[1, 0] = -2.0 * p[0] * y[0] * y[1] - 1.0
        J[1, 1] = p[0] * (1.0 - y[0] * y[0])

    solve = make_solver(rhs, jac)
    work = workspace(2)              # once per block of points, reused
    status, n_steps, n_rhs = solve(0.0, y, p, t_end, 1e-6, 1e-9, 0.0, 100_000, work)

The public solvers have the signatures of dop853's (``make_solver``,
``make_event_solver``, ``make_trajectory_solver``, ``make_stepper``), with
``jac`` as an extra factory argument and a different ``work``; a model switches
method by swapping the factory and the workspace.

Workspace: ``workspace(n)`` returns a tuple ``(real, cplx, pivots, state)``:

- ``real``: float64 ``(VECTOR_ROWS + 2 n, n)``: vector rows (f, Z, W, stage
  derivatives, trial state, dense output ...), then the Jacobian (rows
  ``JAC_ROW .. JAC_ROW + n``, ``JAC_ROW = VECTOR_ROWS``) and the LU factors
  of ``MU_REAL / h - J`` (the next n rows);
- ``cplx``: complex128 ``(n + 1, n)``: the complex LU factors and one vector;
- ``pivots``: int64 ``(2, n)``: row interchanges of the real and complex LU;
- ``state``: float64 ``(STATE_SIZE,)``: step-controller memory between steps,
  and the counters ``state[STATE_N_JAC]`` (Jacobian evaluations) and
  ``state[STATE_N_LU]`` (LU decompositions, real and complex counted
  separately as in scipy's ``nlu``) of the last solve; read them with
  :func:`jacobian_and_lu_counts`. ``n_rhs`` returned by the solvers counts
  right-hand-side evaluations only.

Conventions (as :mod:`mechsweep.ode.dop853`):
- Forward integration only; a zero-length (or backward) interval takes no step.
- ``work`` must be ``workspace(y.size)`` (not checked). Contents are scratch.
- Statuses are the ints of :mod:`mechsweep.status`; nothing raises inside numba.
- ``max_steps`` bounds the number of *attempted* steps: every trial step size
  counts (error-test rejections and Newton failures included).
- rtol below ``100 eps`` is raised to ``100 eps`` (scipy does the same, with a
  warning). Tolerances are scalars.
- Non-finite values: a non-finite initial state, derivative or Jacobian gives
  NONFINITE at once. A Newton iteration meeting a non-finite stage derivative
  or correction counts as a Newton failure (step halved, as scipy); a trial
  step whose error norm, new state or new derivative is not finite is rejected
  and shrunk by ``MIN_FACTOR``. If the step then falls below the round-off of t
  (``10 ulp(t)``, as scipy) the status reports the last failure: NONFINITE,
  SINGULAR (an LU factorisation met a zero pivot at every step size, even with
  a fresh Jacobian) or STEP_UNDERFLOW (error test or Newton convergence).

Deliberate differences from scipy (all outside its normal path, or bugs there):
- The LU factors are recomputed when the step size differs by more than
  ``LU_H_TOLERANCE`` (20 %) from the one they were made for. scipy reuses them
  whenever it kept the step size, also when the last step is then clipped to
  t_end (possibly to a tiny fraction), so the Newton matrix and the error
  estimate use a wrong h there. Within 20 % we reuse them as scipy does
  (clipping by a few ulp happens on every step).
- A zero pivot (singular iteration matrix) is a Newton failure at once; scipy
  goes on with inf/NaN, which fails the Newton iteration one iteration later.
- Non-finite error norms, states or f(t + h, y_new) reject the step (scipy
  would accept a NaN error norm, since ``NaN > 1`` is false).
- The Newton tolerance ``max(10 eps / rtol, min(0.03, sqrt(rtol)))`` uses the
  raised rtol (scipy uses the caller's rtol there, so rtol = 1e-20 would give a
  Newton tolerance of 2e5).
- The two-step controller treats a previous error norm of exactly 0 like a
  missing one (scipy's formula gives a step factor 0 then).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .._jit import jit, jit_inline, jit_noalloc
from ._common import ROOT_RTOL, _all_finite, _copy, _min_step, _rms_scaled, _rms_scaled_difference, make_brent
from ..status import MAX_STEPS, NO_EVENT, NONFINITE, OK, SINGULAR, STEP_UNDERFLOW

__all__ = [
    "JAC_ROW",
    "STATE_N_JAC",
    "STATE_N_LU",
    "STATE_SIZE",
    "VECTOR_ROWS",
    "jacobian_and_lu_counts",
    "make_event_solver",
    "make_solver",
    "make_stepper",
    "make_trajectory_solver",
    "workspace",
]

# ---------------------------------------------------------------------------
# Method coefficients: exactly scipy.integrate._ivp.radau's.
# ---------------------------------------------------------------------------

S6 = 6**0.5
C = np.array([(4 - S6) / 10, (4 + S6) / 10, 1.0])  # collocation nodes
E = np.array([-13 - 7 * S6, -13 + 7 * S6, -1.0]) / 3  # error estimate weights
# A = T diag(MU_REAL, MU_COMPLEX, conj) T^-1, the eigenvalues of A^-1.
MU_REAL = 3 + 3 ** (2 / 3) - 3 ** (1 / 3)
MU_COMPLEX = 3 + 0.5 * (3 ** (1 / 3) - 3 ** (2 / 3)) - 0.5j * (3 ** (5 / 6) + 3 ** (7 / 6))
T = np.array(
    [
        [0.09443876248897524, -0.14125529502095421, 0.03002919410514742],
        [0.25021312296533332, 0.20412935229379994, -0.38294211275726192],
        [1.0, 1.0, 0.0],
    ]
)
TI = np.array(
    [
        [4.17871859155190428, 0.32768282076106237, 0.52337644549944951],
        [-4.17871859155190428, -0.32768282076106237, 0.47662355450055044],
        [0.50287263494578682, -2.57192694985560522, 0.59603920482822492],
    ]
)
# Collocation polynomial: y(t_old + x h) = y_old + sum_k (Z^T P)[:, k] x^(k+1).
P = np.array(
    [
        [13 / 3 + 7 * S6 / 3, -23 / 3 - 22 * S6 / 3, 10 / 3 + 5 * S6],
        [13 / 3 - 7 * S6 / 3, -23 / 3 + 22 * S6 / 3, 10 / 3 - 5 * S6],
        [1 / 3, -8 / 3, 10 / 3],
    ]
)

NEWTON_MAXITER = 6
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
EPS = float(np.finfo(np.float64).eps)
MIN_RTOL = 100.0 * EPS

# The LU factors of an earlier step size are reused while the step size is within
# this relative distance of it (see module doc); scipy keeps the step size
# unchanged while it would grow by less than 20 %.
LU_H_TOLERANCE = 0.2


# LU outcomes.
_LU_OK = 0
_LU_SINGULAR = 1
_LU_NONFINITE = 2

# Vector rows of the real workspace (each of length n).
F0 = 0  # f(t, y) at the start of the step
Z_ROW = 1  # 3 rows: Z, stage increments (stage s state = y + Z[s])
W_ROW = 4  # 3 rows: W = TI Z, transformed increments
FS_ROW = 7  # 3 rows: stage derivatives
Y_STAGE = 10  # argument of the rhs
Y_NEW = 11  # proposed state at t + h
F_NEW = 12  # f(t + h, y_new)
SCALE = 13  # atol + rtol |y| (error-norm scale)
ERR = 14  # error estimate
DW = 15  # real Newton correction; then Z^T E / h
Q_ROW = 16  # 3 rows: dense output Q = Z^T P of the last accepted step
Y_OLD = 19  # state at the start of the last accepted step
VECTOR_ROWS = 20
# Then n rows of the Jacobian J[i, j] = d f_i / d y_j from JAC_ROW, and n rows of
# the LU factors of MU_REAL / h - J from JAC_ROW + n.
JAC_ROW = VECTOR_ROWS

# Step-controller memory and counters (float64 array).
S_H_ABS_OLD = 0  # previous proposed |h| (< 0: none)
S_ERR_OLD = 1  # previous error norm (< 0: none)
S_CURRENT_JAC = 2  # 1 if J was evaluated at the current (t, y)
S_LU_VALID = 3  # 1 if the LU factors are those of S_LU_H and the current J
S_LU_H = 4  # step size h of the LU factors
S_HAVE_SOL = 5  # 1 once a step was accepted (dense output available)
S_T_OLD = 6  # start of the last accepted step
S_H_OLD = 7  # size of the last accepted step
STATE_N_JAC = 8  # Jacobian evaluations of the last solve
STATE_N_LU = 9  # LU decompositions (real and complex each count one)
# Scratch of the current step.
S_STEP_H_OLD = 10  # S_H_ABS_OLD as used by this step's controller
S_STEP_ERR_OLD = 11
S_H_ENTRY = 12  # the proposed |h| this step started from
S_REJECTED = 13  # 1 after a rejection within this step
S_FAILURE = 14  # status to report if the step size collapses
S_RATE = 15  # last Newton convergence rate (< 0: none)
S_DW_NORM_OLD = 16  # previous Newton correction norm (< 0: none)
STATE_SIZE = 17


@jit
def workspace(n):
    """Scratch storage for a state of size ``n``: ``(real, cplx, pivots, state)``.

    See the module docstring for the layout. Jitted so that numba code (e.g. one
    workspace per thread in a ``prange``) can allocate it too.
    """
    return (
        np.zeros((VECTOR_ROWS + 2 * n, n), dtype=np.float64),
        np.zeros((n + 1, n), dtype=np.complex128),
        np.zeros((2, n), dtype=np.int64),
        np.zeros(STATE_SIZE, dtype=np.float64),
    )


@jit
def jacobian_and_lu_counts(work):
    """(Jacobian evaluations, LU decompositions) of the last solve with ``work``."""
    state = work[3]
    return int(state[STATE_N_JAC]), int(state[STATE_N_LU])


# ---------------------------------------------------------------------------
# Helpers that do not depend on the right-hand side.
# ---------------------------------------------------------------------------


@jit_noalloc
def _all_finite_2d(a):
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            if not math.isfinite(a[i, j]):
                return False
    return True


@jit_noalloc
def _lu_factor(jac_rows, mu, a, piv):
    """a <- LU of (mu I - J) with partial pivoting, row interchanges in piv (as LAPACK's getrf),
    for the real (mu real, a float64) and the complex (mu complex, a complex128) matrix alike:
    numba compiles it once per type. Pivots by |Re| + |Im| (LAPACK's idamax / izamax; for a real
    number that is |x|). Returns _LU_OK, _LU_SINGULAR (a zero pivot column) or _LU_NONFINITE."""
    n = jac_rows.shape[0]
    for i in range(n):
        for j in range(n):
            a[i, j] = -jac_rows[i, j]
        a[i, i] += mu
    for k in range(n):
        p = k
        amax = abs(a[k, k].real) + abs(a[k, k].imag)
        for i in range(k + 1, n):
            v = abs(a[i, k].real) + abs(a[i, k].imag)
            if v > amax:
                amax = v
                p = i
        piv[k] = p
        if not math.isfinite(amax):
            return _LU_NONFINITE
        if amax == 0.0:
            return _LU_SINGULAR
        if p != k:
            for j in range(n):
                tmp = a[k, j]
                a[k, j] = a[p, j]
                a[p, j] = tmp
        pivot = a[k, k]
        for i in range(k + 1, n):
            factor = a[i, k] / pivot
            a[i, k] = factor
            if factor != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= factor * a[k, j]
    return _LU_OK


@jit_noalloc
def _lu_solve(a, piv, b):
    """b <- (LU)^-1 P b in place; works for the real and the complex factors."""
    n = b.size
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= a[i, j] * b[j]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= a[i, j] * b[j]
        b[i] = acc / a[i, i]


@jit_noalloc
def _factorize(h, rw, cw, piv, state):
    """Both LU factorisations for step h from the Jacobian in rw. Returns an _LU_* code."""
    n = rw.shape[1]
    jac_rows = rw[JAC_ROW : JAC_ROW + n]
    state[STATE_N_LU] += 2.0
    code = _lu_factor(jac_rows, MU_REAL / h, rw[JAC_ROW + n : JAC_ROW + 2 * n], piv[0])
    if code != _LU_OK:
        return code
    return _lu_factor(jac_rows, MU_COMPLEX / h, cw[:n], piv[1])


@jit_inline
def _predict_factor(h_abs, h_abs_old, error_norm, error_norm_old):
    """scipy's predict_factor (Gustafsson's predictive controller); negative
    'old' values mean none. A zero old error norm counts as none (see module doc)."""
    if error_norm == 0.0:
        return math.inf
    if error_norm_old <= 0.0 or h_abs_old < 0.0:
        multiplier = 1.0
    else:
        multiplier = h_abs / h_abs_old * (error_norm_old / error_norm) ** 0.25
    return min(1.0, multiplier) * error_norm**-0.25


@jit_noalloc
def _predict_stages(t, h, y, rw, state):
    """First Newton guess Z0: the previous step's collocation polynomial at
    t + C h (minus y), or zero before the first accepted step."""
    n = y.size
    if state[S_HAVE_SOL] == 0.0:
        for s in range(3):
            for i in range(n):
                rw[Z_ROW + s, i] = 0.0
        return
    t_old = state[S_T_OLD]
    h_old = state[S_H_OLD]
    for s in range(3):
        x = (t + h * C[s] - t_old) / h_old
        x2 = x * x
        x3 = x2 * x
        for i in range(n):
            value = rw[Q_ROW, i] * x + rw[Q_ROW + 1, i] * x2 + rw[Q_ROW + 2, i] * x3
            rw[Z_ROW + s, i] = (value + rw[Y_OLD, i]) - y[i]


@jit_noalloc
def _store_dense_output(t, h, y, rw, state):
    """After acceptance: Q = Z^T P, y_old = y, t_old = t, h_old = h."""
    for i in range(y.size):
        z0 = rw[Z_ROW, i]
        z1 = rw[Z_ROW + 1, i]
        z2 = rw[Z_ROW + 2, i]
        for k in range(3):
            rw[Q_ROW + k, i] = z0 * P[0, k] + z1 * P[1, k] + z2 * P[2, k]
        rw[Y_OLD, i] = y[i]
    state[S_T_OLD] = t
    state[S_H_OLD] = h
    state[S_HAVE_SOL] = 1.0


@jit_noalloc
def _interpolate(x, rw, out):
    """State at fraction x of the last accepted step (0: its start, 1: its end)."""
    x2 = x * x
    x3 = x2 * x
    for i in range(out.size):
        value = rw[Q_ROW, i] * x + rw[Q_ROW + 1, i] * x2 + rw[Q_ROW + 2, i] * x3
        out[i] = value + rw[Y_OLD, i]


@jit_noalloc
def _error_estimate(y, h, rtol, atol, rw, piv):
    """First error estimate: ERR <- (MU_REAL / h - J)^-1 (f + Z^T E / h), Y_NEW,
    DW <- Z^T E / h, SCALE <- atol + rtol max(|y|, |y_new|). Returns its norm."""
    n = y.size
    lu = rw[JAC_ROW + n : JAC_ROW + 2 * n]
    for i in range(n):
        z0 = rw[Z_ROW, i]
        z1 = rw[Z_ROW + 1, i]
        z2 = rw[Z_ROW + 2, i]
        y_new = y[i] + z2
        rw[Y_NEW, i] = y_new
        ze = (z0 * E[0] + z1 * E[1] + z2 * E[2]) / h
        rw[DW, i] = ze
        rw[ERR, i] = rw[F0, i] + ze
        rw[SCALE, i] = atol + max(abs(y[i]), abs(y_new)) * rtol
    _lu_solve(lu, piv[0], rw[ERR])
    return _scaled_rms(rw[ERR], rw[SCALE])


@jit_noalloc
def _scaled_rms(v, scale):
    acc = 0.0
    for i in range(v.size):
        acc += (v[i] / scale[i]) ** 2
    return math.sqrt(acc) / math.sqrt(v.size)


@jit_noalloc
def _commit(y, rw):
    """Accept the trial step: y <- y_new, f <- f(t + h, y_new)."""
    _copy(rw[Y_NEW], y)
    _copy(rw[F_NEW], rw[F0])


# The step logic is split into rhs-independent helpers (compiled once) and thin
# rhs-dependent drivers (compiled once per rhs): numba's compile time grows with
# function size, and only the drivers are recompiled for each new model.

_NEWTON_CONTINUE = 0
_NEWTON_CONVERGED = 1
_NEWTON_FAILED = 2

_TRIAL_PASS = 0
_TRIAL_TOO_LARGE = 1
_TRIAL_NONFINITE = 2


@jit_noalloc
def _start_checks(y, rw, state):
    """Reset the controller memory; True when y and f(t0, y) (in rw[F0]) are finite."""
    for k in range(STATE_SIZE):
        state[k] = 0.0
    state[S_H_ABS_OLD] = -1.0
    state[S_ERR_OLD] = -1.0
    state[S_CURRENT_JAC] = 1.0
    return _all_finite(y) and _all_finite(rw[F0])


@jit_noalloc
def _initial_step_probe(t0, y, t_bound, rtol, atol, rw):
    """First half of scipy's select_initial_step: the explicit Euler probe in
    rw[Y_STAGE]; returns its step (0.0 for an empty interval)."""
    interval = abs(t_bound - t0)
    if interval == 0.0:
        return 0.0
    f0 = rw[F0]
    d0 = _rms_scaled(y, y, rtol, atol)
    d1 = _rms_scaled(f0, y, rtol, atol)
    h_try = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h_try = min(h_try, interval)
    for i in range(y.size):
        rw[Y_STAGE, i] = y[i] + h_try * f0[i]
    return h_try


@jit_noalloc
def _initial_step_finish(h_try, t0, t_bound, y, rtol, atol, rw):
    """Second half of select_initial_step (error order 3); rw[FS_ROW] holds the probe's f."""
    f0 = rw[F0]
    d1 = _rms_scaled(f0, y, rtol, atol)
    d2 = _rms_scaled_difference(rw[FS_ROW], f0, y, rtol, atol) / h_try
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h_try * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 4.0)
    interval = abs(t_bound - t0)
    h_abs = min(100.0 * h_try, h1, interval)
    if not math.isfinite(h_abs):  # e.g. NaN from the probe: let the controller cope
        h_abs = min(1e-6, interval)
    return h_abs


@jit_noalloc
def _begin_step(t, h_abs, state):
    """Controller memory for a new step; as scipy, a proposal below the minimum
    step is raised to it and the two-step history forgotten. Returns (min_step, h_abs)."""
    min_step = _min_step(t)
    state[S_H_ENTRY] = h_abs
    state[S_STEP_H_OLD] = state[S_H_ABS_OLD]
    state[S_STEP_ERR_OLD] = state[S_ERR_OLD]
    if h_abs < min_step:
        h_abs = min_step
        state[S_STEP_H_OLD] = -1.0
        state[S_STEP_ERR_OLD] = -1.0
    state[S_REJECTED] = 0.0
    state[S_FAILURE] = STEP_UNDERFLOW
    return min_step, h_abs


@jit_noalloc
def _begin_attempt(t, y, t_bound, h_abs, rtol, atol, rw, state):
    """Trial step (clipped at t_bound), Newton guess and Newton scale. Returns (t_new, h)."""
    t_new = min(t + h_abs, t_bound)
    h = t_new - t
    _predict_stages(t, h, y, rw, state)
    for i in range(y.size):
        rw[SCALE, i] = atol + abs(y[i]) * rtol
    return t_new, h


@jit_noalloc
def _ensure_lu(h, rw, cw, piv, state):
    """True when LU factors usable for step h are ready (reused or computed);
    False when a factorisation failed (S_FAILURE says why)."""
    lu_h = state[S_LU_H]
    if state[S_LU_VALID] != 0.0 and abs(h - lu_h) <= LU_H_TOLERANCE * lu_h:
        return True
    code = _factorize(h, rw, cw, piv, state)
    state[S_LU_H] = h
    if code == _LU_OK:
        state[S_LU_VALID] = 1.0
        return True
    state[S_LU_VALID] = 0.0
    state[S_FAILURE] = SINGULAR if code == _LU_SINGULAR else NONFINITE
    return False


@jit_noalloc
def _jacobian_updated(t, h, y, rw, state):
    """After a fresh J(t, y): count it, drop the LU factors, restore the Newton guess."""
    state[STATE_N_JAC] += 1.0
    state[S_CURRENT_JAC] = 1.0
    state[S_LU_VALID] = 0.0
    _predict_stages(t, h, y, rw, state)


@jit_noalloc
def _newton_start(rw, state):
    """W = TI Z from the guess in the Z rows."""
    for i in range(rw.shape[1]):
        z0 = rw[Z_ROW, i]
        z1 = rw[Z_ROW + 1, i]
        z2 = rw[Z_ROW + 2, i]
        for r in range(3):
            rw[W_ROW + r, i] = TI[r, 0] * z0 + TI[r, 1] * z1 + TI[r, 2] * z2
    state[S_DW_NORM_OLD] = -1.0
    state[S_RATE] = -1.0


@jit_noalloc
def _stage_argument(y, rw, s):
    for i in range(y.size):
        rw[Y_STAGE, i] = y[i] + rw[Z_ROW + s, i]


@jit_noalloc
def _newton_iteration(k, h, tol, rw, cw, piv, state):
    """Iteration k of scipy's solve_collocation_system once the stage derivatives
    are in the FS rows: solve for dW, rate tests, W += dW, Z = T W.
    Returns _NEWTON_CONTINUE, _NEWTON_CONVERGED or _NEWTON_FAILED."""
    n = rw.shape[1]
    for s in range(3):
        if not _all_finite(rw[FS_ROW + s]):
            state[S_FAILURE] = NONFINITE
            return _NEWTON_FAILED
    lu_real = rw[JAC_ROW + n : JAC_ROW + 2 * n]
    dw_real = rw[DW]
    dw_cplx = cw[n]
    m_real = MU_REAL / h
    m_complex = MU_COMPLEX / h
    for i in range(n):
        f0 = rw[FS_ROW, i]
        f1 = rw[FS_ROW + 1, i]
        f2 = rw[FS_ROW + 2, i]
        dw_real[i] = f0 * TI[0, 0] + f1 * TI[0, 1] + f2 * TI[0, 2] - m_real * rw[W_ROW, i]
        fc = complex(
            f0 * TI[1, 0] + f1 * TI[1, 1] + f2 * TI[1, 2],
            f0 * TI[2, 0] + f1 * TI[2, 1] + f2 * TI[2, 2],
        )
        dw_cplx[i] = fc - m_complex * complex(rw[W_ROW + 1, i], rw[W_ROW + 2, i])
    _lu_solve(lu_real, piv[0], dw_real)
    _lu_solve(cw[:n], piv[1], dw_cplx)
    acc = 0.0
    for i in range(n):
        s_i = rw[SCALE, i]
        acc += (dw_real[i] / s_i) ** 2 + (dw_cplx[i].real / s_i) ** 2 + (dw_cplx[i].imag / s_i) ** 2
    dw_norm = math.sqrt(acc) / math.sqrt(3 * n)
    if not math.isfinite(dw_norm):
        state[S_FAILURE] = NONFINITE
        return _NEWTON_FAILED
    dw_norm_old = state[S_DW_NORM_OLD]
    has_rate = dw_norm_old >= 0.0
    rate = -1.0
    if has_rate:
        rate = dw_norm / dw_norm_old
        state[S_RATE] = rate
        if rate >= 1.0 or rate ** (NEWTON_MAXITER - k) / (1.0 - rate) * dw_norm > tol:
            state[S_FAILURE] = STEP_UNDERFLOW
            return _NEWTON_FAILED
    for i in range(n):
        w0 = rw[W_ROW, i] + dw_real[i]
        w1 = rw[W_ROW + 1, i] + dw_cplx[i].real
        w2 = rw[W_ROW + 2, i] + dw_cplx[i].imag
        rw[W_ROW, i] = w0
        rw[W_ROW + 1, i] = w1
        rw[W_ROW + 2, i] = w2
        for r in range(3):
            rw[Z_ROW + r, i] = T[r, 0] * w0 + T[r, 1] * w1 + T[r, 2] * w2
    if dw_norm == 0.0 or (has_rate and rate / (1.0 - rate) * dw_norm < tol):
        return _NEWTON_CONVERGED
    state[S_DW_NORM_OLD] = dw_norm
    return _NEWTON_CONTINUE


@jit_noalloc
def _second_estimate_argument(y, rw):
    for i in range(y.size):
        rw[Y_STAGE, i] = y[i] + rw[ERR, i]


@jit_noalloc
def _second_estimate(rw, piv):
    """Hairer's improved estimate after a rejection: (MU_REAL / h - J)^-1
    (f(t, y + err) + Z^T E / h), with f(t, y + err) in rw[FS_ROW]. Returns its norm."""
    n = rw.shape[1]
    for i in range(n):
        rw[ERR, i] = rw[FS_ROW, i] + rw[DW, i]
    _lu_solve(rw[JAC_ROW + n : JAC_ROW + 2 * n], piv[0], rw[ERR])
    return _scaled_rms(rw[ERR], rw[SCALE])


@jit_noalloc
def _trial_verdict(error_norm, rw):
    if not (math.isfinite(error_norm) and _all_finite(rw[Y_NEW])):
        return _TRIAL_NONFINITE
    return _TRIAL_PASS if error_norm <= 1.0 else _TRIAL_TOO_LARGE


@jit_inline
def _safety(n_iter):
    return 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + n_iter)


@jit_noalloc
def _reject(h_abs, error_norm, n_iter, nonfinite, state):
    """New trial step after a rejected one (error test or non-finite trial)."""
    if nonfinite:  # overflow or NaN in the trial step: shrink hard
        h_abs *= MIN_FACTOR
        state[S_FAILURE] = NONFINITE
    else:
        factor = _predict_factor(h_abs, state[S_STEP_H_OLD], error_norm, state[S_STEP_ERR_OLD])
        h_abs *= max(MIN_FACTOR, _safety(n_iter) * factor)
        state[S_FAILURE] = STEP_UNDERFLOW
    state[S_LU_VALID] = 0.0
    state[S_REJECTED] = 1.0
    return h_abs


@jit_noalloc
def _accept(t, h, y, error_norm, n_iter, rw, state):
    """Controller after an accepted step of size h > 0 from (t, y): dense output,
    memory, Jacobian / LU reuse. Returns (next h_abs, recompute the Jacobian)."""
    recompute_jac = n_iter > 2 and state[S_RATE] > 1e-3
    factor = _predict_factor(h, state[S_STEP_H_OLD], error_norm, state[S_STEP_ERR_OLD])
    factor = min(MAX_FACTOR, _safety(n_iter) * factor)
    if not recompute_jac and factor < 1.2:
        factor = 1.0
    else:
        state[S_LU_VALID] = 0.0
    if recompute_jac:
        state[STATE_N_JAC] += 1.0
        state[S_CURRENT_JAC] = 1.0
    else:
        state[S_CURRENT_JAC] = 0.0
    _store_dense_output(t, h, y, rw, state)
    state[S_H_ABS_OLD] = state[S_H_ENTRY]
    state[S_ERR_OLD] = error_norm
    return h * factor, recompute_jac


# ---------------------------------------------------------------------------
# Factories of rhs-dependent pieces (memoised: one compiled copy per rhs/jac).
# ---------------------------------------------------------------------------


@functools.cache
def _make_newton(rhs):
    @jit_noalloc
    def newton(t, y, h, p, tol, rw, cw, piv, state):
        """Simplified Newton iterations for the collocation system (scipy's
        solve_collocation_system) from the guess in the Z rows; SCALE must hold
        atol + rtol |y|. Returns (converged, n_iter); the last rate is in
        state[S_RATE]. Costs 3 rhs evaluations per iteration."""
        _newton_start(rw, state)
        for k in range(NEWTON_MAXITER):
            for s in range(3):
                _stage_argument(y, rw, s)
                rhs(t + h * C[s], rw[Y_STAGE], p, rw[FS_ROW + s])
            code = _newton_iteration(k, h, tol, rw, cw, piv, state)
            if code != _NEWTON_CONTINUE:
                return code == _NEWTON_CONVERGED, k + 1
        state[S_FAILURE] = STEP_UNDERFLOW
        return False, NEWTON_MAXITER

    return newton


@functools.cache
def _make_start(rhs, jac):
    @jit_noalloc
    def start(t0, y, p, t_bound, rtol, atol, h0, work):
        """f(t0, y), J(t0, y), controller reset and the first step size (scipy's
        select_initial_step with error order 3 when h0 <= 0).
        Returns (status, h_abs, n_rhs)."""
        rw, _, _, state = work
        n = y.size
        rhs(t0, y, p, rw[F0])
        if not _start_checks(y, rw, state):
            return NONFINITE, 0.0, 1
        jac_rows = rw[JAC_ROW : JAC_ROW + n]
        jac(t0, y, p, jac_rows)
        state[STATE_N_JAC] = 1.0
        if not _all_finite_2d(jac_rows):
            return NONFINITE, 0.0, 1
        if h0 > 0.0:
            return OK, h0, 1
        h_try = _initial_step_probe(t0, y, t_bound, rtol, atol, rw)
        if h_try == 0.0:
            return OK, 0.0, 1
        rhs(t0 + h_try, rw[Y_STAGE], p, rw[FS_ROW])
        return OK, _initial_step_finish(h_try, t0, t_bound, y, rtol, atol, rw), 2

    return start


@functools.cache
def _make_advance(rhs, jac):
    newton = _make_newton(rhs)

    @jit_noalloc
    def advance(t, y, p, t_bound, h_abs, rtol, atol, newton_tol, work, budget):
        """One Radau step as scipy's Radau._step_impl: try step sizes from (t, y)
        until one is accepted; leave y_new / f_new / the dense output in work
        (y itself is not changed, the caller commits). rw[F0] must hold f(t, y)
        and the controller memory in work must come from start / earlier steps.
        At most ``budget`` attempts.

        Returns (status, t_new, next h_abs, attempts made, rhs evaluations).
        """
        rw, cw, piv, state = work
        n = y.size
        min_step, h_abs = _begin_step(t, h_abs, state)
        attempts = 0
        n_rhs = 0
        while True:
            if h_abs < min_step:
                return int(state[S_FAILURE]), t, h_abs, attempts, n_rhs
            if attempts >= budget:
                return MAX_STEPS, t, h_abs, attempts, n_rhs
            attempts += 1
            t_new, h = _begin_attempt(t, y, t_bound, h_abs, rtol, atol, rw, state)
            h_abs = h
            converged = False
            n_iter = 0
            while True:  # Newton; on failure with an old Jacobian, refresh it once
                if _ensure_lu(h, rw, cw, piv, state):
                    converged, n_iter = newton(t, y, h, p, newton_tol, rw, cw, piv, state)
                    n_rhs += 3 * n_iter
                    if converged:
                        break
                if state[S_CURRENT_JAC] != 0.0:
                    break
                jac(t, y, p, rw[JAC_ROW : JAC_ROW + n])
                _jacobian_updated(t, h, y, rw, state)
            if not converged:
                h_abs *= 0.5
                state[S_LU_VALID] = 0.0
                continue
            error_norm = _error_estimate(y, h, rtol, atol, rw, piv)
            if state[S_REJECTED] != 0.0 and error_norm > 1.0:
                _second_estimate_argument(y, rw)
                rhs(t, rw[Y_STAGE], p, rw[FS_ROW])
                n_rhs += 1
                error_norm = _second_estimate(rw, piv)
            verdict = _trial_verdict(error_norm, rw)
            if verdict == _TRIAL_PASS:
                rhs(t_new, rw[Y_NEW], p, rw[F_NEW])
                n_rhs += 1
                if not _all_finite(rw[F_NEW]):
                    verdict = _TRIAL_NONFINITE
            if verdict != _TRIAL_PASS:
                h_abs = _reject(h_abs, error_norm, n_iter, verdict == _TRIAL_NONFINITE, state)
                continue
            h_next, recompute_jac = _accept(t, h, y, error_norm, n_iter, rw, state)
            if recompute_jac:
                jac(t_new, rw[Y_NEW], p, rw[JAC_ROW : JAC_ROW + n])
            return OK, t_new, h_next, attempts, n_rhs

    return advance


@functools.cache
def _make_root_locator(event):
    @jit_noalloc
    def event_on_interpolant(t, ctx):
        t_old, h, p, rw = ctx
        y_at = rw[Y_STAGE]  # free after the step
        _interpolate((t - t_old) / h, rw, y_at)
        return event(t, y_at, p)

    brent = make_brent(event_on_interpolant)

    @jit_noalloc
    def locate_root(t_old, h, g_old, t_new, g_new, p, rw):
        """Root of event(t, interpolant(t)) in [t_old, t_new] where g_old > 0 >= g_new."""
        return brent(t_old, g_old, t_new, g_new, ROOT_RTOL * abs(h), (t_old, h, p, rw))

    return locate_root


@jit_inline
def _effective_tolerances(rtol):
    """(rtol raised to 100 eps, Newton tolerance) as scipy's Radau."""
    rtol = max(rtol, MIN_RTOL)
    return rtol, max(10.0 * EPS / rtol, min(0.03, rtol**0.5))


# ---------------------------------------------------------------------------
# Public factories.
# ---------------------------------------------------------------------------


@functools.cache
def make_stepper(rhs, jac):
    """Jitted ``step(t, y, f, h, p, rtol, atol, work, y_new, f_new) -> error_norm``.

    One Radau IIA step of size h from (t, y), f = rhs(t, y), with the Jacobian
    evaluated at (t, y), fresh LU factors and a zero Newton guess: writes y_new
    and f_new = rhs(t + h, y_new) and returns the (first) error norm for
    rtol/atol (< 1: the adaptive solver would accept). If the Newton iteration
    does not converge (the adaptive solver would halve h) it returns inf and
    y_new / f_new are NaN. Fixed-step use, e.g. to measure the order.
    """
    newton = _make_newton(rhs)

    @jit_noalloc
    def step(t, y, f, h, p, rtol, atol, work, y_new, f_new):
        rw, cw, piv, state = work
        n = y.size
        rtol, newton_tol = _effective_tolerances(rtol)
        _copy(f, rw[F0])
        jac(t, y, p, rw[JAC_ROW : JAC_ROW + n])
        state[S_HAVE_SOL] = 0.0
        state[S_LU_VALID] = 0.0
        converged = False
        if _ensure_lu(h, rw, cw, piv, state):
            _begin_attempt(t, y, t + h, h, rtol, atol, rw, state)
            converged, _ = newton(t, y, h, p, newton_tol, rw, cw, piv, state)
        if not converged:
            for i in range(n):
                y_new[i] = np.nan
                f_new[i] = np.nan
            return math.inf
        error_norm = _error_estimate(y, h, rtol, atol, rw, piv)
        _copy(rw[Y_NEW], y_new)
        rhs(t + h, y_new, p, f_new)
        return error_norm

    return step


@functools.cache
def make_solver(rhs, jac):
    """Jitted ``solve(t0, y, p, t_end, rtol, atol, h0, max_steps, work)
    -> (status, n_steps, n_rhs)``.

    Integrates from t0 to exactly t_end (last step clipped), y in place.
    h0 <= 0 selects the first step automatically. n_steps counts accepted
    steps, n_rhs right-hand-side evaluations (Jacobian evaluations and LU
    decompositions: :func:`jacobian_and_lu_counts`). On failure y holds the
    last accepted state.
    """
    start = _make_start(rhs, jac)
    advance = _make_advance(rhs, jac)

    @jit_noalloc
    def solve(t0, y, p, t_end, rtol, atol, h0, max_steps, work):
        rtol, newton_tol = _effective_tolerances(rtol)
        status, h_abs, n_rhs = start(t0, y, p, t_end, rtol, atol, h0, work)
        n_steps = 0
        n_attempts = 0
        t = t0
        while status == OK and t < t_end:
            status, t_new, h_abs, attempts, used = advance(
                t, y, p, t_end, h_abs, rtol, atol, newton_tol, work, max_steps - n_attempts
            )
            n_attempts += attempts
            n_rhs += used
            if status == OK:
                _commit(y, work[0])
                t = t_new
                n_steps += 1
        return status, n_steps, n_rhs

    return solve


@functools.cache
def make_event_solver(rhs, jac, event):
    """Jitted ``solve(t0, y, p, t_max, rtol, atol, h0, max_steps, work)
    -> (status, t, n_steps, n_rhs)``.

    Integrates from t0 until event(t, y, p) goes from > 0 to <= 0 within an
    accepted step, then locates the root on the step's collocation polynomial
    (no extra rhs evaluations) by Brent's method and returns (OK, t_root, ...)
    with the interpolated state at t_root in y. The event is tested at step
    ends only. Without an event before t_max: (NO_EVENT, t_max, ...) with y at
    t_max. On failure: (status, t of the last accepted step, ...) with y there.
    """
    start = _make_start(rhs, jac)
    advance = _make_advance(rhs, jac)
    locate_root = _make_root_locator(event)

    @jit_noalloc
    def solve(t0, y, p, t_max, rtol, atol, h0, max_steps, work):
        rtol, newton_tol = _effective_tolerances(rtol)
        rw = work[0]
        status, h_abs, n_rhs = start(t0, y, p, t_max, rtol, atol, h0, work)
        n_steps = 0
        n_attempts = 0
        t = t0
        if status != OK:
            return status, t, n_steps, n_rhs
        g_old = event(t, y, p)
        while t < t_max:
            status, t_new, h_abs, attempts, used = advance(
                t, y, p, t_max, h_abs, rtol, atol, newton_tol, work, max_steps - n_attempts
            )
            n_attempts += attempts
            n_rhs += used
            if status != OK:
                return status, t, n_steps, n_rhs
            n_steps += 1
            g_new = event(t_new, rw[Y_NEW], p)
            if g_old > 0.0 and g_new <= 0.0:
                h = t_new - t
                t_root = locate_root(t, h, g_old, t_new, g_new, p, rw)
                if t_root == t_new:
                    _copy(rw[Y_NEW], y)
                else:
                    _interpolate((t_root - t) / h, rw, y)
                return OK, t_root, n_steps, n_rhs
            _commit(y, rw)
            t = t_new
            g_old = g_new
        return NO_EVENT, t, n_steps, n_rhs

    return solve


@jit_noalloc
def _store_rows_at_step_end(t_eval, k, t_new, y_new, out):
    """Copy the exact step-end state into every out row with t_eval == t_new."""
    while k < t_eval.size and t_eval[k] == t_new:
        _copy(y_new, out[k])
        k += 1
    return k


@functools.cache
def make_trajectory_solver(rhs, jac):
    """Jitted ``solve(t0, y, p, t_eval, rtol, atol, h0, max_steps, work, out)
    -> (status, n_steps, n_rhs)``.

    t_eval: increasing float64 array with t_eval[0] >= t0; out: (len(t_eval), n).
    out[k] is the state at t_eval[k], from the collocation polynomial of the
    step that contains it (no extra rhs evaluations) or the exact step end.
    Integration stops at t_eval[-1], where y ends. On failure the rows not
    reached are NaN and y holds the last accepted state.
    """
    start = _make_start(rhs, jac)
    advance = _make_advance(rhs, jac)

    @jit_noalloc
    def solve(t0, y, p, t_eval, rtol, atol, h0, max_steps, work, out):
        out[:, :] = np.nan
        rw = work[0]
        n_eval = t_eval.size
        if n_eval == 0:
            return OK, 0, 0
        rtol, newton_tol = _effective_tolerances(rtol)
        t_end = t_eval[n_eval - 1]
        k = 0
        while k < n_eval and t_eval[k] <= t0:
            _copy(y, out[k])
            k += 1
        status, h_abs, n_rhs = start(t0, y, p, t_end, rtol, atol, h0, work)
        n_steps = 0
        n_attempts = 0
        t = t0
        while status == OK and t < t_end:
            status, t_new, h_abs, attempts, used = advance(
                t, y, p, t_end, h_abs, rtol, atol, newton_tol, work, max_steps - n_attempts
            )
            n_attempts += attempts
            n_rhs += used
            if status != OK:
                break
            n_steps += 1
            h = t_new - t
            while k < n_eval and t_eval[k] < t_new:
                _interpolate((t_eval[k] - t) / h, rw, out[k])
                k += 1
            k = _store_rows_at_step_end(t_eval, k, t_new, rw[Y_NEW], out)
            _commit(y, rw)
            t = t_new
        return status, n_steps, n_rhs

    return solve
