"""DOP853 for many trajectories side by side: one trajectory per SIMD lane.

The one-trajectory solver (:mod:`.dop853`) computes a step of an 8-state system in scalar code:
its right-hand side, its stage sums, its error norm each handle one float at a time. Here
``lanes`` trajectories advance together, the state of lane l in column l of (n, lanes) arrays,
and every loop over the lanes is written so that LLVM vectorises it (no call, no branch that
it cannot turn into a select, lanes innermost): with AVX2 four lanes share one instruction.

Each lane keeps its own time, step size, error test, step-size control, stiffness counters (the
test late in the step budget: a spent budget there is STIFF) and output samples, so a lane computes
the same floats, step for step, as :func:`.dop853.make_trajectory_solver` on the same trajectory
(tests/ode/test_dop853_lanes.py checks bitwise equality). The lanes only share the
moment of their attempts: every active lane attempts a step in every round, accepted or not,
and the three extra stages of the dense output are computed for all lanes when any accepted
lane has a sample inside its step. A lane whose trajectory ends is handed back to the caller,
which reads its samples and loads the next trajectory into it (a thread runs one queue at a
time). At the end of a queue lanes idle; finishing the last few in scalar code instead measured no faster (a
round of 16 lanes cost about four scalar steps) and cost 12 s more JIT compile, so it is not done.

Requirements on ``rhs_lanes`` (else LLVM leaves the loop scalar, at about a third of the speed):
lanes innermost, no call (numba's math.sqrt is one: use special.ieee_sqrt), branches only of
the kind LLVM turns into selects, and few output rows per loop (the run-time aliasing checks it
adds per pair of arrays have a limit). The tableau sums are generated (_dop853_lane_sums.py).
Lane counts that are multiples of 8 keep every loop in its vector body.

Usage (numba code; ``rhs_lanes(tau, Z, P, dZ)`` is the lane form of ``rhs(t, y, p, dy)``,
``tau`` one time per lane, ``P`` the parameters column per lane)::

    load, run = make_lane_trajectory_solver(rhs_lanes, rhs)
    ws = workspace(n, n_params, lanes, t_eval.size)
    load(ws, lane, point, t0, y0, p, t_eval, rtol, atol)   # for every lane
    while True:
        lane = run(ws, t_eval, rtol, atol, max_steps)      # -1: no lane left
        point, status, n_steps, n_rhs = lane_result(ws, lane)  # samples: ws[TRAJ][lane]
        load(...) or idle(ws, lane)

``n_rhs`` counts what the one-trajectory solver would evaluate (the dense stages only for lanes
that need them), so datasets are the same whichever solver made them; the time of the stages
computed for nothing shows in the benchmark's steps per second, not in the counts.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .._jit import jit, jit_inline, jit_internal_noalloc, jit_noalloc
from ..status import MAX_STEPS, NONFINITE, OK, STEP_UNDERFLOW
from ._common import _all_finite, _min_step
from . import _dop853_lane_sums as sums
from ._dop853_tableau import C, N_STAGES, N_STAGES_EXTENDED
from .dop853 import (ERROR_EXPONENT, F_DENSE, K_FSAL, MIN_FACTOR, SAFETY, WORK_ROWS, Y_NEW, Y_STAGE, _failure,
                     _interpolate, _make_start, _stage_argument, _step_factor, _stiffness_count, _tests_stiffness)

__all__ = ["workspace", "make_lane_trajectory_solver", "idle", "lane_result", "TRAJ"]


# Positions in the workspace tuple.
W, Y, PL, LF, LI, TRAJ, SW, WF, YF, HK = range(10)
# Rows of LF (per-lane floats).
T, T_NEW, H, H_ABS, MIN_STEP, TAU, SUM5, SUM3 = range(8)
N_LF = 8
# Rows of LI (per-lane integers).
STATE, POINT, STATUS, N_STEPS, N_RHS, N_ATTEMPTS, K_NEXT, REJECTED, LAST_NONFINITE, ACCEPTED, DENSE = range(11)
N_STIFF, N_NONSTIFF = 11, 12  # the counters of dop853's stiffness test (run late in the step budget only)
N_LI = 13
# Lane states.
IDLE, ACTIVE, DONE = 0, 1, 2


@jit_inline
def _error_test(w, lf, li, l, n):
    """dop853's advance() for one attempting lane l (rows as in this module; engine/lanes.py shares
    them): accepted (ACCEPTED set, the next step size) or rejected (the smaller step, REJECTED and
    LAST_NONFINITE set); returns whether it was accepted."""
    h = lf[H, l]
    sum5 = lf[SUM5, l]
    sum3 = lf[SUM3, l]
    if sum5 == 0.0 and sum3 == 0.0:
        error = 0.0
    else:
        error = abs(h) * sum5 / math.sqrt((sum5 + 0.01 * sum3) * n)
    finite = math.isfinite(error) and _all_finite(w[Y_NEW, :, l]) and _all_finite(w[K_FSAL, :, l])
    if finite and error < 1.0:
        li[ACCEPTED, l] = 1
        lf[H_ABS, l] = h * _step_factor(error, li[REJECTED, l] != 0)
        return True
    if finite:
        lf[H_ABS, l] = h * max(MIN_FACTOR, SAFETY * error**ERROR_EXPONENT)
    else:  # overflow or NaN in the trial step: shrink hard and retry
        lf[H_ABS, l] = h * MIN_FACTOR
    li[LAST_NONFINITE, l] = 0 if finite else 1
    li[REJECTED, l] = 1
    return False


@jit_internal_noalloc
def _stiffness_lane(h, y, w, l, scratch, stiff_count, nonstiff_count):
    """dop853._stiffness_update for lane l after its accepted step, before its commit (engine/lanes.py
    shares it). The lanes reuse the row of the last stage's argument as scratch, so that argument is
    computed again into ``scratch`` by dop853's own _stage_argument: the floats of the one-trajectory
    solver, hence its counts. A function of its own (called late in a budget only): inlined into the
    lanes' per-lane loops it cost them speed."""
    _stage_argument(y[:, l], h, w[:, :, l], N_STAGES - 1, scratch)
    num = 0.0
    den = 0.0
    for i in range(scratch.size):
        num += (w[K_FSAL, i, l] - w[N_STAGES - 1, i, l]) ** 2
        den += (w[Y_NEW, i, l] - scratch[i]) ** 2
    return _stiffness_count(h, num, den, stiff_count, nonstiff_count)


@jit
def workspace(n, n_params, lanes, n_eval):
    """Everything the lanes need, as a tuple (indexed by W, Y, PL, LF, LI, TRAJ, SW, WF, YF, HK):
    stages W (WORK_ROWS, n, lanes) in the row layout of dop853, states Y (n, lanes), parameters
    PL (n_params, lanes), per-lane floats LF and integers LI, samples TRAJ (lanes, n_eval, n), the
    one-trajectory workspace SW that picks a lane's first step, flat views WF, YF of W and Y
    (n * lanes per row) for the tableau sums, and HK, the step per flat element."""
    w = np.zeros((WORK_ROWS, n, lanes))
    y = np.zeros((n, lanes))
    return (w, y, np.zeros((n_params, lanes)), np.zeros((N_LF, lanes)), np.zeros((N_LI, lanes), dtype=np.int64),
            np.full((lanes, n_eval, n), np.nan), np.zeros((WORK_ROWS, n)), w.reshape((WORK_ROWS, n * lanes)),
            y.reshape(n * lanes), np.zeros(n * lanes))


@jit_noalloc
def idle(ws, lane):
    """Leave the lane empty (no trajectory left for it). Its stale state keeps being stepped
    with h = 0 alongside the others, and is never read."""
    ws[LI][STATE, lane] = IDLE


@jit_noalloc
def lane_result(ws, lane):
    """(point, status, n_steps, n_rhs) of the trajectory that has just ended in the lane."""
    li = ws[LI]
    return li[POINT, lane], li[STATUS, lane], li[N_STEPS, lane], li[N_RHS, lane]


@jit_internal_noalloc
def _finish(li, lane, status):
    li[STATE, lane] = DONE
    li[STATUS, lane] = status


@jit_internal_noalloc
def _error_sums(y, w, e5, e3, rtol, atol, sum5, sum3):
    """The sums of squares of scipy's DOP853 error norm per lane (dop853._error_norm), from the
    flat estimates e5, e3 (component i of lane l at i * lanes + l)."""
    n, lanes = y.shape
    for l in range(lanes):
        sum5[l] = 0.0
        sum3[l] = 0.0
    for i in range(n):
        for l in range(lanes):
            scale = atol + max(abs(y[i, l]), abs(w[Y_NEW, i, l])) * rtol
            sum5[l] += (e5[i * lanes + l] / scale) ** 2
            sum3[l] += (e3[i * lanes + l] / scale) ** 2


@jit_internal_noalloc
def _first_dense_rows(h, y, w):
    """The first three dense-output rows of every lane (dop853._dense_coefficients)."""
    n, lanes = y.shape
    for i in range(n):
        for l in range(lanes):
            delta = w[Y_NEW, i, l] - y[i, l]
            w[F_DENSE, i, l] = delta
            w[F_DENSE + 1, i, l] = h[l] * w[0, i, l] - delta
            w[F_DENSE + 2, i, l] = 2.0 * delta - h[l] * (w[K_FSAL, i, l] + w[0, i, l])


@jit_internal_noalloc
def _spread(h, hk, lanes):
    """hk[i * lanes + l] = h[l]: the step of each lane beside each of its components (two loops: an
    index k % lanes cost an integer division per element, measurable at 2 states x 64 lanes)."""
    for i in range(hk.size // lanes):
        for l in range(lanes):
            hk[i * lanes + l] = h[l]


@jit_internal_noalloc
def _begin_advance(lf, li, lane):
    """What dop853's advance() does on entry: floor the step at 10 ulp of t, clear the flags."""
    lf[MIN_STEP, lane] = _min_step(lf[T, lane])
    lf[H_ABS, lane] = max(lf[H_ABS, lane], lf[MIN_STEP, lane])
    li[REJECTED, lane] = 0
    li[LAST_NONFINITE, lane] = 0


@functools.cache
def lane_stages(rhs_lanes):
    """``stages(w, pl, lf, wf, yf, hk, first, last)``: stages first..last of every lane; 1..12 make a step
    (dop853 rk_step; stage 12 is f(t + h, y_new), C[12] = 1), 13..15 the dense output. One loop, so that
    the lane right-hand side is compiled into one place; a function of its own (compiled into its caller,
    the lanes ran slower)."""
    @jit_internal_noalloc
    def stages(w, pl, lf, wf, yf, hk, first, last):
        tau = lf[TAU]
        for s in range(first, last + 1):
            for l in range(tau.size):
                tau[l] = lf[T, l] + C[s] * lf[H, l]
            if s == K_FSAL:
                sums.solution(yf, hk, wf, wf[Y_NEW])
                rhs_lanes(tau, w[Y_NEW], pl, w[s])
            else:
                sums.stage_argument(s, yf, hk, wf, wf[Y_STAGE])
                rhs_lanes(tau, w[Y_STAGE], pl, w[s])

    return stages


@functools.cache
def make_lane_trajectory_solver(rhs_lanes, rhs):
    """(load, run) for the lanes of ``rhs_lanes``; ``rhs`` (the one-trajectory form) picks each
    lane's first step exactly as dop853's solvers do.

    ``load(ws, lane, point, t0, y0, p, t_eval, rtol, atol)``: start trajectory ``point`` (any
    integer the caller wants back) from (t0, y0) with parameters p in the lane; its samples at
    t_eval go to ``ws[TRAJ][lane]`` (NaN where not reached).
    ``run(ws, t_eval, rtol, atol, max_steps) -> lane``: advance the active lanes until one ends
    and return it (-1 when none is left); its outcome is ``lane_result(ws, lane)``, and the caller
    must ``load`` or ``idle`` the lane before the next ``run``. Every lane has the same t_eval.
    """
    start = _make_start(rhs)

    @jit_noalloc
    def load(ws, lane, point, t0, y0, p, t_eval, rtol, atol):
        w, y, pl, lf, li, traj, sw, wf, yf, hk = ws
        n_eval = t_eval.size
        for k in range(n_eval):
            for i in range(y0.size):
                traj[lane, k, i] = math.nan
        k = 0
        while k < n_eval and t_eval[k] <= t0:
            for i in range(y0.size):
                traj[lane, k, i] = y0[i]
            k += 1
        for i in range(y0.size):
            y[i, lane] = y0[i]
        for j in range(p.size):
            pl[j, lane] = p[j]
        li[STATE, lane] = ACTIVE
        li[POINT, lane] = point
        li[STATUS, lane] = OK
        li[N_STEPS, lane] = 0
        li[N_ATTEMPTS, lane] = 0
        li[K_NEXT, lane] = k
        li[ACCEPTED, lane] = 0
        li[DENSE, lane] = 0
        li[N_STIFF, lane] = 0
        li[N_NONSTIFF, lane] = 0
        if n_eval == 0:
            li[N_RHS, lane] = 0
            _finish(li, lane, OK)
            return
        t_end = t_eval[n_eval - 1]
        status, h_abs, n_rhs = start(t0, y0, p, t_end, rtol, atol, 0.0, sw)
        li[N_RHS, lane] = n_rhs
        for i in range(y0.size):
            w[0, i, lane] = sw[0, i]
        lf[T, lane] = t0
        lf[H_ABS, lane] = h_abs
        if status != OK:
            _finish(li, lane, status)
        elif not t0 < t_end:
            _finish(li, lane, OK)
        else:
            _begin_advance(lf, li, lane)

    stages = lane_stages(rhs_lanes)

    @jit_noalloc
    def prepare_attempts(lf, li, t_end, max_steps):
        """The checks of dop853's advance() before an attempt, and its step, per lane.
        Returns the number of lanes that attempt a step."""
        attempting = 0
        for l in range(li.shape[1]):
            li[ACCEPTED, l] = 0
            lf[H, l] = 0.0
            lf[T_NEW, l] = lf[T, l]
            if li[STATE, l] != ACTIVE:
                continue
            if lf[H_ABS, l] < lf[MIN_STEP, l]:
                _finish(li, l, NONFINITE if li[LAST_NONFINITE, l] else STEP_UNDERFLOW)
                continue
            if li[N_ATTEMPTS, l] >= max_steps:
                _finish(li, l, _failure(MAX_STEPS, li[N_STIFF, l]))
                continue
            li[N_ATTEMPTS, l] += 1
            li[N_RHS, l] += N_STAGES
            t_new = min(lf[T, l] + lf[H_ABS, l], t_end)
            lf[T_NEW, l] = t_new
            lf[H, l] = t_new - lf[T, l]
            attempting += 1
        return attempting

    @jit_noalloc
    def error_tests(w, lf, li, t_eval, n):
        """Accept or reject each attempting lane (dop853's advance()); returns whether an accepted
        lane has a sample inside its step (the dense output is needed)."""
        n_eval = t_eval.size
        any_dense = False
        for l in range(li.shape[1]):
            if li[STATE, l] != ACTIVE:
                continue
            if _error_test(w, lf, li, l, n):
                k = li[K_NEXT, l]
                li[DENSE, l] = 1 if (k < n_eval and t_eval[k] < lf[T_NEW, l]) else 0
                any_dense = any_dense or li[DENSE, l] == 1
        return any_dense

    @jit_noalloc
    def commit(w, y, lf, li, traj, t_eval, max_steps, scratch):
        """Samples and new state of every accepted lane (dop853's trajectory solver; its stiffness
        test late in the step budget, ``scratch`` a row of n floats)."""
        n, lanes = y.shape
        n_eval = t_eval.size
        t_end = t_eval[n_eval - 1]
        for l in range(lanes):
            if not li[ACCEPTED, l]:
                continue
            t = lf[T, l]
            t_new = lf[T_NEW, l]
            h = lf[H, l]
            li[N_STEPS, l] += 1
            if _tests_stiffness(False, li[N_ATTEMPTS, l], max_steps, li[N_STIFF, l]):
                li[N_STIFF, l], li[N_NONSTIFF, l] = _stiffness_lane(h, y, w, l, scratch, li[N_STIFF, l],
                                                                    li[N_NONSTIFF, l])
            k = li[K_NEXT, l]
            if li[DENSE, l]:
                li[N_RHS, l] += N_STAGES_EXTENDED - N_STAGES - 1
                while k < n_eval and t_eval[k] < t_new:
                    _interpolate((t_eval[k] - t) / h, y[:, l], w[:, :, l], traj[l, k])  # the lane's view
                    k += 1
            while k < n_eval and t_eval[k] == t_new:
                for i in range(n):
                    traj[l, k, i] = w[Y_NEW, i, l]
                k += 1
            li[K_NEXT, l] = k
            for i in range(n):
                y[i, l] = w[Y_NEW, i, l]
                w[0, i, l] = w[K_FSAL, i, l]  # first same as last
            lf[T, l] = t_new
            if t_new < t_end:
                _begin_advance(lf, li, l)
            else:
                _finish(li, l, OK)

    @jit_noalloc
    def run(ws, t_eval, rtol, atol, max_steps):
        w, y, pl, lf, li, traj, sw, wf, yf, hk = ws
        n, lanes = y.shape
        t_end = t_eval[t_eval.size - 1]
        e5 = wf[Y_STAGE]  # scratch rows of the error estimates, free after the step
        e3 = wf[F_DENSE]  # (the dense output rewrites both before it needs them)
        while True:
            active = 0
            for l in range(lanes):
                if li[STATE, l] == DONE:
                    return l
                if li[STATE, l] == ACTIVE:
                    active += 1
            if active == 0:
                return -1
            if prepare_attempts(lf, li, t_end, max_steps) == 0:
                continue  # every active lane ended in the checks
            _spread(lf[H], hk, lanes)
            stages(w, pl, lf, wf, yf, hk, 1, N_STAGES)
            sums.error_estimates(wf, e5, e3)
            _error_sums(y, w, e5, e3, rtol, atol, lf[SUM5], lf[SUM3])
            if error_tests(w, lf, li, t_eval, n):
                stages(w, pl, lf, wf, yf, hk, N_STAGES + 1, N_STAGES_EXTENDED - 1)
                _first_dense_rows(lf[H], y, w)
                sums.dense_rows(hk, wf, F_DENSE + 3)
            commit(w, y, lf, li, traj, t_eval, max_steps, sw[Y_STAGE])

    return load, run
