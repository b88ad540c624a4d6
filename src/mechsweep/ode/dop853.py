"""Adaptive Dormand-Prince 8(5,3) integrator (DOP853) in numba.

Same algorithm as ``scipy.integrate.solve_ivp(method="DOP853")``: Hairer's
coefficients, the error norm that combines the 5th- and 3rd-order estimates,
the step-size controller (safety 0.9, factors in [0.2, 10], exponent -1/8),
scipy's ``select_initial_step`` and first-same-as-last. It adds the 7th-order
dense output of dop853.f, event location on that interpolant, and is written
for throughput: the solve functions never allocate, so millions of short
integrations can run inside a ``prange`` loop.

Usage::

    @jit
    def rhs(t, y, p, dydt):          # writes dy/dt into dydt, returns nothing
        dydt[0] = y[1]
        dydt[1] = -p[0] * y[0]

    @jit
    def event(t, y, p):              # root wanted where this goes from > 0 to <= 0
        return y[0]

    solve = make_event_solver(rhs, event)
    work = workspace(2)              # once per block of points, reused
    status, t_root, n_steps, n_rhs = solve(0.0, y, p, t_max, 1e-10, 1e-12, 0.0, 100_000, work)

The ``make_*`` factories return jitted closures over the user's jitted ``rhs``
and ``event``; they can be called from Python or from other numba functions
(including ``prange`` loops, one ``work`` array per thread or per point).
Factories are memoised on their arguments, so asking twice for the solver of
the same ``rhs`` returns the same compiled function.

Conventions:
- Forward integration only: ``t_end`` / ``t_max`` / ``t_eval`` must be >= t0.
  A zero-length (or backward) interval takes no step.
- ``work`` must be ``workspace(y.size)`` (exact shape; not checked, numba does
  no bounds checking). Its contents on return are scratch.
- Statuses are the ints of :mod:`mechsweep.status`; nothing raises inside numba.
- ``max_steps`` bounds the number of *attempted* steps (accepted + rejected). An
  integration that spends it with Hairer's stiffness test firing on its last steps
  (STIFF_WINDOW) ends with STIFF instead of MAX_STEPS: with ``stiffness_test`` the test runs on
  every step and stops the integration at once (method auto).
- A trial step whose error norm, new state or new derivative is not finite is
  rejected and the step shrunk by the minimum factor, as scipy does; if the step
  then falls below the round-off of t the status is NONFINITE (STEP_UNDERFLOW
  when the last rejection was an ordinary error-test failure). A non-finite
  initial state or derivative gives NONFINITE at once.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .._jit import jit, jit_internal_noalloc, jit_llvm_inline, jit_noalloc
from ._common import ROOT_RTOL, _all_finite, _copy, _min_step, _rms_scaled, _rms_scaled_difference, make_brent
from ..status import MAX_STEPS, NO_EVENT, NONFINITE, OK, STEP_UNDERFLOW, STIFF
from ._dop853_tableau import (
    A,
    B,
    C,
    D,
    E3,
    E5,
    INTERPOLATOR_POWER,
    N_STAGES,
    N_STAGES_EXTENDED,
)

__all__ = [
    "workspace",
    "WORK_ROWS",
    "make_stepper",
    "make_solver",
    "make_event_solver",
    "make_trajectory_solver",
]

# Step-size controller, as in scipy.integrate._ivp.rk.
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
ERROR_EXPONENT = -1.0 / 8.0  # -1 / (error estimator order 7 + 1)

# Stiffness detection of dop853.f (Hairer & Wanner, Solving ODEs II, IV.2): after an accepted
# step, h * |f(y_new) - f(y_12)| / |y_new - y_12| estimates |h lambda| of the dominant eigenvalue
# from the last two stages (both at t + h); the step sits on the stability boundary when it
# exceeds 6.1. Fifteen such steps (counting reset after six that are not) mean the step size is
# limited by stability, not accuracy: the problem is stiff there.
STIFF_H_LAMBDA = 6.1
STIFF_STEPS = 15
NONSTIFF_RESET = 6
# Without ``stiffness_test`` (plain dop853) the solvers run the same test only on the accepted steps
# among the last STIFF_WINDOW attempts of their step budget, and report STIFF instead of MAX_STEPS
# when it counted STIFF_STEPS there: the budget was spent with the step held at the stability limit,
# where an implicit method would not spend it. dop853.f samples its test too (every NSTIFF = 1000
# accepted steps, then on every step while it keeps firing); here the sample is where the integration
# fails. No other step runs the test and the test changes no step: a point that ends otherwise is
# bitwise what it was. Near the limit h lambda hovers about the threshold, rejections interleave and
# six steps below it reset the count: on the auto-balancer at h / (m a^2 Omega) = 1e3 the count reached
# 10 within the last 100 attempts, 27 within 200 and 102 within 1000 (tests/data/stiff_window.py).
STIFF_WINDOW = 1000


# Rows of the workspace (each of length n).
K_FSAL = N_STAGES  # stage 12 = f(t + h, y_new), becomes stage 0 of the next step
Y_STAGE = N_STAGES_EXTENDED  # argument of the rhs for the current stage
Y_NEW = Y_STAGE + 1  # proposed state at t + h
F_DENSE = Y_NEW + 1  # first of the INTERPOLATOR_POWER dense-output rows
WORK_ROWS = F_DENSE + INTERPOLATOR_POWER


@jit
def workspace(n):
    """Scratch array for a state of size ``n``: stages, trial state, dense output.

    Jitted so that numba code (e.g. one workspace per thread in a ``prange``)
    can allocate it too.
    """
    return np.zeros((WORK_ROWS, n), dtype=np.float64)


# ---------------------------------------------------------------------------
# Helpers that do not depend on the right-hand side.
# ---------------------------------------------------------------------------


@jit_llvm_inline
def _stage_argument(y, h, work, s, out):
    """out = y + h * sum_{j<s} A[s, j] K[j]: the state at which stage s is evaluated."""
    for i in range(y.size):
        acc = 0.0
        for j in range(s):
            acc += A[s, j] * work[j, i]
        out[i] = y[i] + h * acc


@jit_llvm_inline
def _combine_solution(y, h, work, out):
    """out = y + h * sum_j B[j] K[j]: the 8th-order solution."""
    for i in range(y.size):
        acc = 0.0
        for j in range(N_STAGES):
            acc += B[j] * work[j, i]
        out[i] = y[i] + h * acc


@jit_llvm_inline
def _error_norm(y, work, h, rtol, atol):
    """scipy's DOP853 error norm of the step from y to work[Y_NEW] (< 1: accept).

    Both estimates are scaled by atol + rtol * max(|y|, |y_new|); the 5th-order
    one is damped by the 3rd-order one: |h| |e5|^2 / sqrt(n (|e5|^2 + 0.01 |e3|^2)).
    """
    n = y.size
    y_new = work[Y_NEW]
    sum5 = 0.0
    sum3 = 0.0
    for i in range(n):
        e5 = 0.0
        e3 = 0.0
        for j in range(N_STAGES):  # E3/E5 vanish on the FSAL stage
            e5 += E5[j] * work[j, i]
            e3 += E3[j] * work[j, i]
        scale = atol + max(abs(y[i]), abs(y_new[i])) * rtol
        sum5 += (e5 / scale) ** 2
        sum3 += (e3 / scale) ** 2
    if sum5 == 0.0 and sum3 == 0.0:
        return 0.0
    return abs(h) * sum5 / math.sqrt((sum5 + 0.01 * sum3) * n)






@jit_llvm_inline
def _step_factor(error_norm, rejected_before):
    """Growth factor after an accepted step (error_norm < 1)."""
    if error_norm == 0.0:
        factor = MAX_FACTOR
    else:
        factor = min(MAX_FACTOR, SAFETY * error_norm**ERROR_EXPONENT)
    if rejected_before:  # do not grow right after a rejection
        factor = min(1.0, factor)
    return factor




@jit_llvm_inline
def _stiffness_count(h, num, den, stiff_count, nonstiff_count):
    """The counters of Hairer's stiffness test after an accepted step of size h, from
    num = |f(y_new) - f(y_s)|^2 and den = |y_new - y_s|^2 (y_s: the argument of the step's last stage,
    also at t + h). stiff_count reaching STIFF_STEPS means the problem is stiff."""
    if den > 0.0 and abs(h) * math.sqrt(num / den) > STIFF_H_LAMBDA:
        return stiff_count + 1, 0
    nonstiff_count += 1
    if nonstiff_count >= NONSTIFF_RESET:
        return 0, nonstiff_count
    return stiff_count, nonstiff_count


@jit_llvm_inline
def _stiffness_update(h, work, stiff_count, nonstiff_count):
    """Hairer's stiffness test after an accepted (uncommitted) step; returns the new counters.
    Needs work as rk_step left it."""
    num = 0.0
    den = 0.0
    for i in range(work.shape[1]):
        num += (work[K_FSAL, i] - work[N_STAGES - 1, i]) ** 2
        den += (work[Y_NEW, i] - work[Y_STAGE, i]) ** 2
    return _stiffness_count(h, num, den, stiff_count, nonstiff_count)


@jit_llvm_inline
def _tests_stiffness(stiffness_test, n_attempts, max_steps, stiff_count):
    """Whether the accepted step that brought the attempts to n_attempts runs the stiffness test: every
    step with ``stiffness_test`` (auto), else only within the last STIFF_WINDOW attempts of the budget,
    until the test has counted STIFF_STEPS (then the count stays: the failure is STIFF)."""
    return stiffness_test or (n_attempts > max_steps - STIFF_WINDOW and stiff_count < STIFF_STEPS)


@jit_llvm_inline
def _failure(status, stiff_count):
    """The status of a failed integration: STIFF for a spent budget where the test counted STIFF_STEPS."""
    if status == MAX_STEPS and stiff_count >= STIFF_STEPS:
        return STIFF
    return status


@jit_llvm_inline
def _commit(y, work):
    """Accept the trial step: y <- y_new and, first-same-as-last, K0 <- K12."""
    _copy(work[Y_NEW], y)
    _copy(work[K_FSAL], work[0])


@jit_llvm_inline
def _dense_coefficients(h, y, work):
    """The seven dense-output rows F of dop853 (needs all 16 stages in work)."""
    n = y.size
    f_old = work[0]
    f_new = work[K_FSAL]
    y_new = work[Y_NEW]
    for i in range(n):
        delta = y_new[i] - y[i]
        work[F_DENSE, i] = delta
        work[F_DENSE + 1, i] = h * f_old[i] - delta
        work[F_DENSE + 2, i] = 2.0 * delta - h * (f_new[i] + f_old[i])
        for r in range(INTERPOLATOR_POWER - 3):
            acc = 0.0
            for j in range(N_STAGES_EXTENDED):
                acc += D[r, j] * work[j, i]
            work[F_DENSE + 3 + r, i] = h * acc


@jit_llvm_inline
def _interpolate(x, y_old, work, out):
    """State at fraction x of the step (0: y_old, 1: y_new); out may alias y_old.

    Horner-like scheme of dop853's CONTD8 (alternating factors x and 1 - x).
    """
    for i in range(y_old.size):
        acc = 0.0
        for k in range(INTERPOLATOR_POWER):
            acc += work[F_DENSE + INTERPOLATOR_POWER - 1 - k, i]
            acc *= x if k % 2 == 0 else 1.0 - x
        out[i] = acc + y_old[i]


# ---------------------------------------------------------------------------
# Factories of rhs-dependent pieces (memoised: one compiled copy per rhs).
# ---------------------------------------------------------------------------


@functools.cache
def _make_rk_step(rhs):
    @jit_internal_noalloc
    def rk_step(t, y, h, p, work):
        """One DOP853 step: stages 1..11, y_new in work[Y_NEW], f(t+h, y_new) in
        work[K_FSAL]. work[0] must hold f(t, y). Costs 12 rhs evaluations."""
        y_stage = work[Y_STAGE]
        for s in range(1, N_STAGES):
            _stage_argument(y, h, work, s, y_stage)
            rhs(t + C[s] * h, y_stage, p, work[s])
        y_new = work[Y_NEW]
        _combine_solution(y, h, work, y_new)
        rhs(t + h, y_new, p, work[K_FSAL])

    return rk_step


@functools.cache
def _make_start(rhs):
    @jit_internal_noalloc
    def start(t0, y, p, t_bound, rtol, atol, h0, work):
        """f(t0, y) into work[0] and the first step size (scipy's
        select_initial_step when h0 <= 0). Returns (status, h_abs, n_rhs)."""
        f0 = work[0]
        rhs(t0, y, p, f0)
        if not (_all_finite(y) and _all_finite(f0)):
            return NONFINITE, 0.0, 1
        if h0 > 0.0:
            return OK, h0, 1
        interval = abs(t_bound - t0)
        if interval == 0.0:
            return OK, 0.0, 1
        d0 = _rms_scaled(y, y, rtol, atol)
        d1 = _rms_scaled(f0, y, rtol, atol)
        h_try = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
        h_try = min(h_try, interval)
        # Explicit Euler probe; work[1] and Y_STAGE are free before the first step.
        y1 = work[Y_STAGE]
        f1 = work[1]
        for i in range(y.size):
            y1[i] = y[i] + h_try * f0[i]
        rhs(t0 + h_try, y1, p, f1)
        d2 = _rms_scaled_difference(f1, f0, y, rtol, atol) / h_try
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, h_try * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
        h_abs = min(100.0 * h_try, h1, interval)
        if not math.isfinite(h_abs):  # e.g. NaN from the probe: let the controller cope
            h_abs = min(1e-6, interval)
        return OK, h_abs, 2

    return start


@functools.cache
def _make_advance(rhs):
    rk_step = _make_rk_step(rhs)

    @jit_internal_noalloc
    def advance(t, y, p, t_bound, h_abs, rtol, atol, work, budget):
        """The adaptive step shared by every solver: try steps from (t, y) until
        one passes the error test; leave it in work (y itself is not changed:
        the caller may still need y_old for dense output, then calls _commit).
        At most ``budget`` attempts; each costs N_STAGES rhs evaluations.

        Returns (status, t_new, next h_abs, attempts made).
        """
        min_step = _min_step(t)
        h_abs = max(h_abs, min_step)  # as scipy: a too small proposal is raised
        rejected = False
        last_was_nonfinite = False
        attempts = 0
        while True:
            if h_abs < min_step:
                status = NONFINITE if last_was_nonfinite else STEP_UNDERFLOW
                return status, t, h_abs, attempts
            if attempts >= budget:
                return MAX_STEPS, t, h_abs, attempts
            attempts += 1
            t_new = min(t + h_abs, t_bound)
            h = t_new - t
            rk_step(t, y, h, p, work)
            error = _error_norm(y, work, h, rtol, atol)
            finite = (
                math.isfinite(error)
                and _all_finite(work[Y_NEW])
                and _all_finite(work[K_FSAL])
            )
            if finite and error < 1.0:
                return OK, t_new, h * _step_factor(error, rejected), attempts
            if finite:
                h_abs = h * max(MIN_FACTOR, SAFETY * error**ERROR_EXPONENT)
            else:  # overflow or NaN in the trial step: shrink hard and retry
                h_abs = h * MIN_FACTOR
            last_was_nonfinite = not finite
            rejected = True

    return advance


@functools.cache
def _make_dense_output(rhs):
    @jit_internal_noalloc
    def dense_output(t, h, y, p, work):
        """After an accepted (uncommitted) step from (t, y) of size h: the three
        extra stages and the interpolation rows. Costs 3 rhs evaluations."""
        y_stage = work[Y_STAGE]
        for s in range(N_STAGES + 1, N_STAGES_EXTENDED):
            _stage_argument(y, h, work, s, y_stage)
            rhs(t + C[s] * h, y_stage, p, work[s])
        _dense_coefficients(h, y, work)

    return dense_output


@functools.cache
def _make_root_locator(event):
    @jit_internal_noalloc
    def event_on_interpolant(t, ctx):
        t_old, h, y_old, p, work = ctx
        y_at = work[Y_STAGE]  # free once the dense output is built
        _interpolate((t - t_old) / h, y_old, work, y_at)
        return event(t, y_at, p)

    brent = make_brent(event_on_interpolant)

    @jit_internal_noalloc
    def locate_root(t_old, h, g_old, t_new, g_new, y_old, p, work):
        """Root of event(t, interpolant(t)) in [t_old, t_new] where g_old > 0 >= g_new."""
        return brent(t_old, g_old, t_new, g_new, ROOT_RTOL * abs(h), (t_old, h, y_old, p, work))

    return locate_root


# ---------------------------------------------------------------------------
# Public factories.
# ---------------------------------------------------------------------------


@functools.cache
def make_stepper(rhs):
    """Jitted ``step(t, y, f, h, p, rtol, atol, work, y_new, f_new) -> error_norm``.

    One DOP853 step of size h from (t, y), f = rhs(t, y): writes the 8th-order
    y_new and f_new = rhs(t + h, y_new) and returns scipy's error norm for
    rtol/atol (< 1 means the adaptive solver would accept the step).
    Fixed-step use, e.g. to measure the order of convergence.
    """
    rk_step = _make_rk_step(rhs)

    @jit_noalloc
    def step(t, y, f, h, p, rtol, atol, work, y_new, f_new):
        _copy(f, work[0])
        rk_step(t, y, h, p, work)
        _copy(work[Y_NEW], y_new)
        _copy(work[K_FSAL], f_new)
        return _error_norm(y, work, h, rtol, atol)

    return step


@functools.cache
def make_solver(rhs, stiffness_test=False):
    """Jitted ``solve(t0, y, p, t_end, rtol, atol, h0, max_steps, work)
    -> (status, n_steps, n_rhs)``.

    Integrates from t0 to exactly t_end (last step clipped), y in place.
    h0 <= 0 selects the first step automatically. n_steps counts accepted
    steps, n_rhs right-hand-side evaluations. On failure y holds the last
    accepted state; a spent budget whose last steps the stiffness test found at the
    stability limit is STIFF (STIFF_WINDOW). With ``stiffness_test`` the solver stops
    with STIFF as soon as Hairer's test finds the step size limited by stability
    (see STIFF_H_LAMBDA).
    """
    start = _make_start(rhs)
    advance = _make_advance(rhs)

    @jit_internal_noalloc
    def solve(t0, y, p, t_end, rtol, atol, h0, max_steps, work):
        status, h_abs, n_rhs = start(t0, y, p, t_end, rtol, atol, h0, work)
        n_steps = 0
        n_attempts = 0
        n_stiff = np.int64(0)  # not 0: a call typed for Literal[int](0) too compiles each stiffness helper twice
        n_nonstiff = np.int64(0)
        t = t0
        while status == OK and t < t_end:
            status, t_new, h_abs, attempts = advance(
                t, y, p, t_end, h_abs, rtol, atol, work, max_steps - n_attempts
            )
            n_attempts += attempts
            n_rhs += N_STAGES * attempts
            if status == OK:
                if _tests_stiffness(stiffness_test, n_attempts, max_steps, n_stiff):
                    n_stiff, n_nonstiff = _stiffness_update(t_new - t, work, n_stiff, n_nonstiff)
                _commit(y, work)
                t = t_new
                n_steps += 1
                if stiffness_test and n_stiff >= STIFF_STEPS and t < t_end:
                    return STIFF, n_steps, n_rhs
        return _failure(status, n_stiff), n_steps, n_rhs

    return solve


@functools.cache
def make_event_solver(rhs, event, stiffness_test=False):
    """Jitted ``solve(t0, y, p, t_max, rtol, atol, h0, max_steps, work)
    -> (status, t, n_steps, n_rhs)``.

    Integrates from t0 until event(t, y, p) goes from > 0 to <= 0 within an
    accepted step (direction -1), then locates the root on the step's 7th-order
    interpolant (3 extra rhs evaluations) and returns (OK, t_root, ...) with
    the interpolated state at t_root in y. The event is tested at step ends
    only, so two roots inside one step are missed (step sizes are set by the
    tolerance, not by the event). Without an event before t_max: (NO_EVENT,
    t_max, ...) with y at t_max. On failure: (status, t of the last accepted
    step, ...) with y there (STIFF as make_solver says).
    """
    start = _make_start(rhs)
    advance = _make_advance(rhs)
    dense_output = _make_dense_output(rhs)
    locate_root = _make_root_locator(event)

    @jit_internal_noalloc
    def solve(t0, y, p, t_max, rtol, atol, h0, max_steps, work):
        status, h_abs, n_rhs = start(t0, y, p, t_max, rtol, atol, h0, work)
        n_steps = 0
        n_attempts = 0
        n_stiff = np.int64(0)  # not 0: a call typed for Literal[int](0) too compiles each stiffness helper twice
        n_nonstiff = np.int64(0)
        t = t0
        if status != OK:
            return status, t, n_steps, n_rhs
        g_old = event(t, y, p)
        while t < t_max:
            status, t_new, h_abs, attempts = advance(
                t, y, p, t_max, h_abs, rtol, atol, work, max_steps - n_attempts
            )
            n_attempts += attempts
            n_rhs += N_STAGES * attempts
            if status != OK:
                return _failure(status, n_stiff), t, n_steps, n_rhs
            n_steps += 1
            g_new = event(t_new, work[Y_NEW], p)
            if g_old > 0.0 and g_new <= 0.0:
                h = t_new - t
                dense_output(t, h, y, p, work)
                n_rhs += N_STAGES_EXTENDED - N_STAGES - 1
                t_root = locate_root(t, h, g_old, t_new, g_new, y, p, work)
                _interpolate((t_root - t) / h, y, work, y)
                return OK, t_root, n_steps, n_rhs
            if _tests_stiffness(stiffness_test, n_attempts, max_steps, n_stiff):
                n_stiff, n_nonstiff = _stiffness_update(t_new - t, work, n_stiff, n_nonstiff)
            _commit(y, work)
            t = t_new
            g_old = g_new
            if stiffness_test and n_stiff >= STIFF_STEPS and t < t_max:
                return STIFF, t, n_steps, n_rhs
        return NO_EVENT, t, n_steps, n_rhs

    return solve


@jit
def _store_rows_at_step_end(t_eval, k, t_new, y_new, out):
    """Copy the exact step-end state into every out row with t_eval == t_new."""
    while k < t_eval.size and t_eval[k] == t_new:
        _copy(y_new, out[k])
        k += 1
    return k


@functools.cache
def make_trajectory_solver(rhs, stiffness_test=False):
    """Jitted ``solve(t0, y, p, t_eval, rtol, atol, h0, max_steps, work, out)
    -> (status, n_steps, n_rhs)``.

    t_eval: increasing float64 array with t_eval[0] >= t0; out: (len(t_eval), n).
    out[k] is the state at t_eval[k], from the dense output of the step that
    contains it (3 extra rhs evaluations per such step) or the exact step end.
    Integration stops at t_eval[-1], where y ends. On failure the rows not
    reached are NaN and y holds the last accepted state (STIFF as make_solver says).
    """
    start = _make_start(rhs)
    advance = _make_advance(rhs)
    dense_output = _make_dense_output(rhs)

    @jit_internal_noalloc
    def solve(t0, y, p, t_eval, rtol, atol, h0, max_steps, work, out):
        out[:, :] = np.nan
        n_eval = t_eval.size
        if n_eval == 0:
            return OK, 0, 0
        t_end = t_eval[n_eval - 1]
        k = 0
        while k < n_eval and t_eval[k] <= t0:
            _copy(y, out[k])
            k += 1
        status, h_abs, n_rhs = start(t0, y, p, t_end, rtol, atol, h0, work)
        n_steps = 0
        n_attempts = 0
        n_stiff = np.int64(0)  # not 0: a call typed for Literal[int](0) too compiles each stiffness helper twice
        n_nonstiff = np.int64(0)
        t = t0
        while status == OK and t < t_end:
            status, t_new, h_abs, attempts = advance(
                t, y, p, t_end, h_abs, rtol, atol, work, max_steps - n_attempts
            )
            n_attempts += attempts
            n_rhs += N_STAGES * attempts
            if status != OK:
                break
            n_steps += 1
            # before the dense output, which reuses the last stage's argument row
            if _tests_stiffness(stiffness_test, n_attempts, max_steps, n_stiff):
                n_stiff, n_nonstiff = _stiffness_update(t_new - t, work, n_stiff, n_nonstiff)
            if k < n_eval and t_eval[k] < t_new:  # output points inside this step
                h = t_new - t
                dense_output(t, h, y, p, work)
                n_rhs += N_STAGES_EXTENDED - N_STAGES - 1
                while k < n_eval and t_eval[k] < t_new:
                    _interpolate((t_eval[k] - t) / h, y, work, out[k])
                    k += 1
            k = _store_rows_at_step_end(t_eval, k, t_new, work[Y_NEW], out)
            _commit(y, work)
            t = t_new
            if stiffness_test and n_stiff >= STIFF_STEPS and t < t_end:
                return STIFF, n_steps, n_rhs
        return _failure(status, n_stiff), n_steps, n_rhs

    return solve
