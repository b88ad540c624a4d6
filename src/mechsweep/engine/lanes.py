"""SIMD lanes for the one-point route's first-event kernels: LANES points integrated side by side per
thread, bitwise the one-point kernel's results (tests/engine/test_model_lanes.py).

Where it applies (engine/kernels.py ``lanes_apply``): one measurement that integrates on its own (a
FirstEvent, possibly of a System, or a lone first Crossing) to its first root downwards, without
refine, by dop853, of an rhs the engine rewrites in lane form (engine/lane_rhs.py), for a model
without switch times or a status order and a measurement without classify.

**The solver** is ode/dop853_lanes.py's step (stages by the generated tableau sums, per-lane error test
and step-size control) with dop853.make_event_solver's event logic per lane: after every accepted step
the event is evaluated on the lane's new state (the scalar event function, on a copy of the lane's
column), and at a sign change the lane's stages are copied into a one-point workspace where dop853's
own dense output (3 scalar rhs calls) and Brent's root search on its interpolant run unchanged. The
first step is chosen by dop853's own ``start``. Every lane therefore computes the one-point route's
floats step for step: value, status, n_steps and n_rhs.

**The kernel**: each thread's lanes take the launch's points in batches (GRAB at a time) from one
counter shared by the launch's threads (``take``), and a lane whose point is done is refilled at
once; the per-point work before and after the integration (classify, closed forms, prepare, the
value) runs in scalar code around the lanes as in the one-point kernel (``feed``, ``conclude``), with
the model's functions behind guards (engine/calls.py).
"""
from __future__ import annotations

import functools
import math

import numpy as np
from numba.core import cgutils, types as nbtypes
from numba.extending import intrinsic

from .. import status as st
from .._jit import jit_internal, jit_internal_noalloc, jit_into_caller
from ..status import MAX_STEPS, NO_EVENT, NONFINITE, OK, STEP_UNDERFLOW
from ..ode import _dop853_lane_sums as sums
from ..ode._dop853_tableau import N_STAGES, N_STAGES_EXTENDED
from ..ode.dop853 import (F_DENSE, K_FSAL, WORK_ROWS, Y_NEW, Y_STAGE, _make_dense_output, _make_root_locator,
                          _make_start)
from ..ode.dop853 import _failure, _tests_stiffness
from ..ode.dop853_lanes import (_begin_advance, _error_sums, _error_test, _finish, _spread, _stiffness_lane,
                                lane_stages)
from . import binding, calls, events

LANES = 0  # points side by side per thread; 0: lanes_for(number of states)
QUEUE = 32  # the lane kernel has a worker (its own lanes) per LANES * QUEUE points of a launch
GRAB = 16  # points a thread of the lane kernel takes at a time from its launch's shared counter
ARGS = "P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs, taken"


def lanes_for(n_states: int) -> int:
    """Points side by side per thread: about 256 floats per stage row (a multiple of 8 lanes,
    8 to 64), so that the loops over (state, lane) run long vector bodies."""
    if LANES:
        return LANES
    return max(8, min(64, (256 // max(1, n_states)) // 8 * 8))


# Positions in the workspace tuple.
W, Y, PL, LF, LI, SW, WF, YF, HK, PR, YV = range(11)
# Rows of LF (per-lane floats); T .. SUM3 are dop853_lanes' rows (its helpers index them).
T, T_NEW, H, H_ABS, MIN_STEP, TAU, SUM5, SUM3, T_MAX, G_OLD, RESULT = range(11)
N_LF = 11
# Rows of LI (per-lane integers), as dop853_lanes' where its helpers read them.
STATE, POINT, STATUS, N_STEPS, N_RHS, N_ATTEMPTS, K_NEXT, REJECTED, LAST_NONFINITE, ACCEPTED = range(10)
N_STIFF, N_NONSTIFF = 10, 11  # the counters of dop853's stiffness test (run late in the step budget only)
N_LI = 12
IDLE, ACTIVE, DONE = 0, 1, 2


@jit_internal
def workspace(n, n_lp, lanes, n_p):
    """Everything the lanes of one thread need, as a tuple (indexed by W, Y, PL, LF, LI, SW, WF, YF,
    HK, PR, YV): stages W (WORK_ROWS, n, lanes) in dop853's row layout, states Y (n, lanes), the
    rhs's parameters PL (n_lp, lanes), per-lane floats LF and integers LI, a one-point workspace SW,
    flat views WF, YF of W and Y, the step per flat element HK, each lane's p PR (lanes, n_p) and
    two state vectors YV."""
    w = np.zeros((WORK_ROWS, n, lanes))
    y = np.zeros((n, lanes))
    return (w, y, np.zeros((n_lp, lanes)), np.zeros((N_LF, lanes)), np.zeros((N_LI, lanes), dtype=np.int64),
            np.zeros((WORK_ROWS, n)), w.reshape((WORK_ROWS, n * lanes)), y.reshape(n * lanes), np.zeros(n * lanes),
            np.zeros((lanes, n_p)), np.zeros((2, n)))


@intrinsic
def _fetch_add(typingctx, counter, k):
    """Atomically add ``k`` to ``counter[0]`` (an int64 array), returning its value before: LLVM's
    ``atomicrmw add``, sequentially consistent."""
    if not (isinstance(counter, nbtypes.Array) and counter.dtype == nbtypes.int64
            and isinstance(k, nbtypes.Integer)):
        return None

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, [context.get_constant(nbtypes.intp, 0)])
        inc = context.cast(builder, args[1], signature.args[1], nbtypes.int64)
        return builder.atomic_rmw("add", ptr, inc, "seq_cst")

    return nbtypes.int64(counter, k), codegen


@jit_internal_noalloc
def take(counter, k=1):
    """The first of the next ``k`` items of a launch for the calling thread: counter[0], then
    counter[0] += k, as one atomic step. The lane kernel's threads take their points this way, in
    batches, as their lanes free up, so a thread that got a core for less of the launch (another
    thread or process had it) computes fewer points instead of the others waiting for it at the
    launch's end. Which thread or lane computes a point does not change its results."""
    return _fetch_add(counter, k)


@jit_internal_noalloc
def idle(ws, lane):
    """No point left for the lane: it keeps being stepped with h = 0 and is never read."""
    ws[LI][STATE, lane] = IDLE


@jit_internal_noalloc
def lane_result(ws, lane):
    """(point, status, t, n_steps, n_rhs) of the point that has just ended in the lane (t: the
    root's time when OK, else the time reached, as dop853's event solver returns them)."""
    li = ws[LI]
    return li[POINT, lane], li[STATUS, lane], ws[LF][RESULT, lane], li[N_STEPS, lane], li[N_RHS, lane]


@functools.cache
def make_lane_event_solver(rhs_lanes, rhs, event):
    """(load, run): dop853.make_event_solver(rhs, event) for LANES points side by side.

    ``load(ws, lane, point, y0, t_max, rtol, atol)``: start point ``point`` from (0, y0) with the
    parameters ``ws[PR][lane]`` (written by the caller) in the lane.
    ``run(ws, rtol, atol, max_steps) -> lane``: advance the active lanes until one ends and return
    it (-1 when none is left); its outcome is ``lane_result(ws, lane)``; the caller must ``load``
    or ``idle`` the lane before the next ``run``."""
    start = _make_start(rhs)
    dense_output = _make_dense_output(rhs)
    locate_root = _make_root_locator(event)
    stages = lane_stages(rhs_lanes)

    @jit_internal_noalloc
    def load(ws, lane, point, y0, t_max, rtol, atol):
        w, y, pl, lf, li, sw, wf, yf, hk, pr, yv = ws
        p = pr[lane]
        li[STATE, lane] = ACTIVE
        li[POINT, lane] = point
        li[STATUS, lane] = OK
        li[N_STEPS, lane] = 0
        li[N_ATTEMPTS, lane] = 0
        li[ACCEPTED, lane] = 0
        li[N_STIFF, lane] = 0
        li[N_NONSTIFF, lane] = 0
        lf[T, lane] = 0.0
        lf[RESULT, lane] = 0.0
        status, h_abs, n_rhs = start(0.0, y0, p, t_max, rtol, atol, 0.0, sw)
        li[N_RHS, lane] = n_rhs
        if status != OK:
            _finish(li, lane, status)
            return
        lf[G_OLD, lane] = event(0.0, y0, p)
        for i in range(y0.size):
            y[i, lane] = y0[i]
            w[0, i, lane] = sw[0, i]
        for j in range(pl.shape[0]):
            pl[j, lane] = p[j]
        lf[T_MAX, lane] = t_max
        lf[H_ABS, lane] = h_abs
        if not 0.0 < t_max:
            _finish(li, lane, NO_EVENT)
        else:
            _begin_advance(lf, li, lane)

    @jit_internal_noalloc
    def prepare_attempts(lf, li, max_steps):
        """The checks of dop853's advance() before an attempt, and its step, per lane."""
        attempting = 0
        for l in range(li.shape[1]):
            li[ACCEPTED, l] = 0
            lf[H, l] = 0.0
            lf[T_NEW, l] = lf[T, l]
            if li[STATE, l] != ACTIVE:
                continue
            if lf[H_ABS, l] < lf[MIN_STEP, l]:
                _finish(li, l, NONFINITE if li[LAST_NONFINITE, l] else STEP_UNDERFLOW)
                lf[RESULT, l] = lf[T, l]
                continue
            if li[N_ATTEMPTS, l] >= max_steps:
                _finish(li, l, _failure(MAX_STEPS, li[N_STIFF, l]))
                lf[RESULT, l] = lf[T, l]
                continue
            li[N_ATTEMPTS, l] += 1
            li[N_RHS, l] += N_STAGES
            t_new = min(lf[T, l] + lf[H_ABS, l], lf[T_MAX, l])
            lf[T_NEW, l] = t_new
            lf[H, l] = t_new - lf[T, l]
            attempting += 1
        return attempting

    @jit_internal_noalloc
    def error_tests(w, lf, li, n):
        """Accept or reject each attempting lane (dop853's advance())."""
        for l in range(li.shape[1]):
            if li[STATE, l] != ACTIVE:
                continue
            _error_test(w, lf, li, l, n)

    @jit_internal_noalloc
    def events(w, y, lf, li, sw, pr, yv, max_steps):
        """dop853 event solver's logic after an accepted step, per accepted lane: the event at the
        step end; a sign change: dense output and root on the one-point workspace; else its stiffness
        test late in the step budget, and commit."""
        n, lanes = y.shape
        y_new = yv[0]
        y_old = yv[1]
        for l in range(lanes):
            if not li[ACCEPTED, l]:
                continue
            li[N_STEPS, l] += 1
            t = lf[T, l]
            t_new = lf[T_NEW, l]
            p = pr[l]
            for i in range(n):
                y_new[i] = w[Y_NEW, i, l]
            g_new = event(t_new, y_new, p)
            g_old = lf[G_OLD, l]
            if g_old > 0.0 and g_new <= 0.0:
                h = t_new - t
                for r in range(K_FSAL + 1):
                    for i in range(n):
                        sw[r, i] = w[r, i, l]
                for i in range(n):
                    sw[Y_NEW, i] = y_new[i]
                    y_old[i] = y[i, l]
                dense_output(t, h, y_old, p, sw)
                li[N_RHS, l] += N_STAGES_EXTENDED - N_STAGES - 1
                lf[RESULT, l] = locate_root(t, h, g_old, t_new, g_new, y_old, p, sw)
                _finish(li, l, OK)
                continue
            if _tests_stiffness(False, li[N_ATTEMPTS, l], max_steps, li[N_STIFF, l]):
                li[N_STIFF, l], li[N_NONSTIFF, l] = _stiffness_lane(t_new - t, y, w, l, sw[Y_STAGE], li[N_STIFF, l],
                                                                    li[N_NONSTIFF, l])
            for i in range(n):
                y[i, l] = y_new[i]
                w[0, i, l] = w[K_FSAL, i, l]  # first same as last
            lf[T, l] = t_new
            lf[G_OLD, l] = g_new
            if t_new < lf[T_MAX, l]:
                _begin_advance(lf, li, l)
            else:
                lf[RESULT, l] = t_new
                _finish(li, l, NO_EVENT)

    @jit_internal_noalloc
    def run(ws, rtol, atol, max_steps):
        w, y, pl, lf, li, sw, wf, yf, hk, pr, yv = ws
        n, lanes = y.shape
        e5 = wf[Y_STAGE]  # scratch rows of the error estimates, free after the step
        e3 = wf[F_DENSE]
        while True:
            active = 0
            for l in range(lanes):
                if li[STATE, l] == DONE:
                    return l
                if li[STATE, l] == ACTIVE:
                    active += 1
            if active == 0:
                return -1
            if prepare_attempts(lf, li, max_steps) == 0:
                continue  # every active lane ended in the checks
            _spread(lf[H], hk, lanes)
            stages(w, pl, lf, wf, yf, hk, 1, N_STAGES)
            sums.error_estimates(wf, e5, e3)
            _error_sums(y, w, e5, e3, rtol, atol, lf[SUM5], lf[SUM3])
            error_tests(w, lf, li, n)
            events(w, y, lf, li, sw, pr, yv, max_steps)

    return load, run


# --------------------------------------------------------------------------- the kernel
def build(model, chosen, closed, rhs_lanes):
    """The lane kernel's entry points (``binding.Entries(kernel=...)``) of ``model`` for its one
    measurement ``chosen[0]`` and the closed forms ``closed``; ``rhs_lanes``: the lane form of the
    rhs it integrates (engine/lane_rhs.py, compiled from the binding module)."""
    from ..ode.methods import DOP853
    from . import point

    plan = point.Plan(model, chosen, closed, DOP853, guarded=True)
    view = plan.view
    (m,) = plan.chosen
    event, t_max, value, _, _, system = events.parts(plan, m, 0)
    start = plan.initial if system is None else view.fn(system.initial, "initial0", "initial")
    prepare0 = (events._ok2 if system is None or system.prepare is None
                else view.fn(system.prepare, "prepare0", "status2"))
    load, run = make_lane_event_solver(rhs_lanes, plan.equation(system).rhs, event)
    conclude = _conclude(value, calls.chain(point.closed_links(plan, True)), plan.cols[0], 1 + plan.slot[m.name],
                         view.npi)
    feed = _feed(plan.classify, calls.chain(point.closed_links(plan, False)), plan.prepare,
                 calls.chain(point.closed_links(plan, True)), prepare0, t_max, start, load, conclude,
                 1 + plan.slot[m.name], point.filler(view.n_p, view.n_set, view.scr + plan.n_scr), view.npi)
    work = _work(feed, conclude, run, lanes_for(view.n_s), view.n_s, view.npi, view.scr + plan.n_scr,
                 1 + plan.n_values, plan.n_buf)
    return binding.Entries(kernel=work)


@functools.cache
def _feed(classify, before, prepare, after, prepare0, t_max, start, load, conclude, m_at, fill, npi):
    @jit_internal_noalloc
    def feed(lane, i, n, stride, ws, keep, y, buf, P, S, need, rtol, atol, table, status, n_steps, n_rhs):
        """The next point of this queue (from i on, every stride-th) that needs the integration goes
        into the lane (returns the index after it); points settled before it are written here. keep[lane]:
        the point's status so far, then its value row."""
        p = ws[PR][lane]
        kp = keep[lane]
        cv = kp[1:]
        while i < n:
            ii = i
            i += stride
            if status[ii] != st.OK:
                continue
            fill(p, P, ii, S)
            code = st.OK
            c = classify(p)
            if c != st.OK:
                status[ii] = c
                continue
            code = before(ii, p, need, cv, buf, table, code)
            kp[m_at] = math.nan
            c = prepare(p, rtol)
            if c != st.OK:
                code = after(ii, p, need, cv, buf, table, c)
                if p[npi] != 0.0 and code == st.OK:
                    code = st.USER_ERROR
                status[ii] = code
                continue
            kp[0] = code
            c = prepare0(p, rtol)
            if c != st.OK:
                conclude(ii, p, kp, c, math.nan, 0, 0, buf, need, table, status, n_steps, n_rhs)
                continue
            tm = t_max(p)
            start(p, y)
            load(ws, lane, ii, y, tm, rtol, atol)
            return i
        idle(ws, lane)
        return n

    return feed


@functools.cache
def _conclude(value, after, col, m_at, npi):
    @jit_internal_noalloc
    def conclude(i, p, kp, c, val, a, b, buf, need, table, status, n_steps, n_rhs):
        """What the one-point kernel does after the integration of point i (status c, root time val,
        a steps, b rhs calls); kp: what the point kept from before it."""
        code = np.int64(kp[0])
        cv = kp[1:]
        kp[m_at] = math.nan
        n_steps[i] += a
        n_rhs[i] += b
        if c == st.OK:
            val = value(p, val)
        if p[npi] != 0.0:
            c = st.USER_ERROR
        if c == st.OK and not math.isfinite(val):
            c = st.NONFINITE
        if c == st.OK:
            table[i, col] = val
            kp[m_at] = val
        elif code == st.OK:
            code = c
        code = after(i, p, need, cv, buf, table, code)
        if p[npi] != 0.0 and code == st.OK:
            code = st.USER_ERROR
        status[i] = code

    return conclude


@functools.cache
def _work(feed, conclude, run, lanes, n_s, npi, filled, n_keep, n_buf):
    @jit_internal_noalloc
    def refill(lane, mine, taken, n, ws, keep, y, buf, P, S, need, rtol, atol, table, status, n_steps, n_rhs):
        """The lane's next point: from this thread's batch mine = [next, end) of the launch's points, and
        when it is used up from a new batch of GRAB points taken from the launch's shared counter; the
        lane idles when every point is taken."""
        while True:
            if mine[0] >= mine[1]:
                lo = take(taken, GRAB)
                if lo >= n:
                    idle(ws, lane)
                    return
                mine[0] = lo
                mine[1] = min(lo + GRAB, n)
            mine[0] = feed(lane, mine[0], mine[1], 1, ws, keep, y, buf, P, S, need, rtol, atol, table, status,
                           n_steps, n_rhs)
            if ws[LI][STATE, lane] != IDLE:
                return

    @jit_into_caller  # compiled into the binding's trampoline (no link of its own)
    def work(P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs, taken):
        """One thread's share of the launch (engine/point.py's Threaded runs it on each thread): its lanes,
        each refilled as its point ends, from batches of points it takes from the launch's counter
        ``taken`` until none is left (nothing is allocated if none is left at its start).

        Points are taken, not dealt: a thread that lost its core for a while (the run's writer thread,
        another process) takes fewer, so the threads end within about a point's integration of each
        other, and each thread's lanes run idle only once per launch, at its end."""
        n = P.shape[0]
        lo = take(taken, GRAB)
        if lo >= n:
            return
        mine = np.empty(2, dtype=np.int64)
        mine[0] = lo
        mine[1] = min(lo + GRAB, n)
        ws = workspace(n_s, npi, lanes, filled)
        keep = np.empty((lanes, n_keep))
        y = np.empty(n_s)
        buf = np.empty(n_buf)
        for lane in range(lanes):
            refill(lane, mine, taken, n, ws, keep, y, buf, P, S, need, rtol, atol, table, status, n_steps, n_rhs)
        while True:
            lane = run(ws, rtol, atol, max_steps)
            if lane < 0:
                break
            i, c, val, a, b = lane_result(ws, lane)
            conclude(i, ws[PR][lane], keep[lane], c, val, a, b, buf, need, table, status, n_steps, n_rhs)
            refill(lane, mine, taken, n, ws, keep, y, buf, P, S, need, rtol, atol, table, status, n_steps, n_rhs)

    return work


def workers(n: int, lanes: int) -> int:
    """The threads worth starting for a launch of ``n`` points (engine/point.py's Threaded starts at most
    numba.get_num_threads()): one per LANES * QUEUE points, and for a small launch up to 16, one per
    16 * LANES points."""
    return max((n + lanes * QUEUE - 1) // (lanes * QUEUE), min((n + 16 * lanes - 1) // (16 * lanes), 16))


def shared_counter(n: int, threads: int, lanes: int) -> list[tuple]:
    """The last argument of each thread's call of the lane kernel (Threaded's ``tails``): one counter of
    the launch's points taken, shared by its threads (``take``)."""
    taken = np.zeros(1, dtype=np.int64)
    return [(taken,)] * max(1, min(threads, workers(n, lanes)))
