"""The sampled-trajectory kernels: ONE integration per point from ``initial(p)``, sampled at t = T s
(T = ``forcing_period(p)``, or 1 for a model without one; ``s``: the instants in forcing periods, the
same for every point), observed by every sampled measurement of the model that is asked for
(Steady, Kick, History, ... : each one's ``observer``, model/sampled.py).

    kernel(P, S, s, bits, K, hoff, rtol, atol, max_steps, vals, hist, rawv, rawh, status, mstat, n_steps,
           n_rhs, first, step)                      (the points first, first + step, ...: point.Threaded
                                                     runs one stride per thread)
        status = classify(p), prepare(p)            -> non-OK: that status, outputs NaN
        T = forcing(p) (or 1)                       -> not finite > 0: INFEASIBLE
        each measurement's classify                 (mstat[i, k]: which ones observe; none: not integrated)
        trajectory by the method                    (auto: dop853 with the stiffness test; a stiff point
                                                     again from initial(p) by radau, the costs added)
        each measurement observes its rows          -> its columns of vals / hist, its status

Which measurements observe is a run-time choice (``mstat`` before the kernel: UNUSED, NOT_RUN,
NO_CLASSIFY per measurement), so one kernel per model and method serves every subset of outputs.
By dop853, for an rhs the engine rewrites in lane form (engine/lane_rhs.py), ``setup`` and ``queue``
integrate the points of one forcing period in SIMD lanes (ode/dop853_lanes.py) and observe each
trajectory as it ends: the same observers, the same floats. The model's functions are called through
guards (engine/calls.py): an exception at a point gives it USER_ERROR, the others are computed.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .. import status as st
from .._jit import jit_internal, jit_into_caller
from ..ode import dop853_lanes
from . import binding, equations, point, switches

BLOCK = 8  # the fewest points a thread of point.Threaded is given (fewer points: fewer threads)
NOT_RUN = 127  # mstat before a point's measurements ran (a status no measurement gives)
UNUSED = 126  # mstat of a measurement not chosen (the kernel leaves it)
NO_CLASSIFY = 125  # mstat before the kernel of a chosen measurement whose classify is not applied
KERNEL_ARGS = ("P, S, s, bits, K, hoff, rtol, atol, max_steps, vals, hist, rawv, rawh, status, mstat, n_steps, n_rhs, "
               "first, step")
SETUP_ARGS = "P, S, rtol, PF, Z0, TT, status, mstat"
QUEUE_ARGS = ("lanes, idx, first, step, PF, Z0, te, s, bits, K, hoff, rtol, atol, max_steps, vals, hist, rawv, rawh, "
              "status, mstat, n_steps, n_rhs")


def columns(chosen):
    """First value column of each sampled measurement (its ``n_values`` columns), and the end."""
    cols, c = [], 0
    for m in chosen:
        cols.append(c)
        c += m.n_values
    return cols + [c]


class Plan:
    """What one sampled-trajectory kernel is composed from (the measurements' ``observer(plan, k)``
    build on it): the model's view (guarded), the measurements' value columns, the re-check's
    variant (``always``: the index of the Kick observed also where its classify skips it, ``lock``:
    the per-state rates of the lock test, ``raw``: the values also before value/time_value)."""

    def __init__(self, model, chosen, method, always=-1, lock=(), raw=False):
        self.view = view = equations.View(model, guarded=True)
        self.model, self.chosen, self.method = model, tuple(chosen), method
        self.always, self.lock, self.raw = always, tuple(lock), raw
        self.cols = columns(chosen)
        n_s = view.n_s
        self.fd_count = method.jacobian and model.jac is None  # the engine's Jacobian, its rhs calls counted
        self.switched = getattr(model, "switch_times", None) is not None
        self.sw = view.scr + 3 * n_s + 1 if self.switched else -1  # switches: two slots of p after the scratch
        self.p_size = view.scr + 3 * n_s + 1 + (2 if self.switched else 0)
        fn = view.fn
        self.initial = fn(model.initial, "initial", "initial")
        self.classify = fn(model.classify, "classify", "status1") or point._ok1
        self.prepare = fn(model.prepare, "prepare", "status2") or point._ok2
        self.forcing = fn(model.forcing_period, "forcing", "p") or _unit_period
        self.reset = switches.no_reset
        self.integrator = method
        if self.switched:
            times = model.switch_times
            # the list itself unguarded: switches.functions guards its callers (a tuple has no NaN)
            lst = (view.raw(times, "switch_times") if callable(times)
                   else switches.constant_list(tuple(float(x) for x in times)))
            check, nxt, clamp = switches.functions(lst, self.forcing, self.sw, view.npi, True)
            self.reset = switches.reset(self.sw)
            self.integrator = switches.switched(method, nxt, check, clamp)

    def equation(self):
        return equations.equation(self.view, None, clamp_at=self.sw, fd_at=self.view.scr, fd_count=self.fd_count)

    # ---- helpers of the measurements' observers
    def observable(self, x, role: str):
        """``f(t, y, p)``: a state's value (x its name) or the model's function x (guarded)."""
        if isinstance(x, str):
            return _state(self.model.states.index(x))
        return self.view.fn(x, role, "t,y,p")

    def transform(self, f, role: str):
        """``value(p, x)`` of a measurement (guarded), or None."""
        return self.view.fn(f, role, "p,x")


@jit_into_caller
def _unit_period(p):
    return 1.0


@functools.cache
def _state(idx):
    @jit_into_caller
    def f(t, y, p):
        return y[idx]

    return f


# ----------------------------------------------------------------------------- per-point pieces
@functools.cache
def _check_link(k, classify, fold):
    """Measurement k's classify before the integration (chosen ones only, by mstat[i, k] before):
    -status where it does not apply (skipped, its status folded into the point's), OK where it
    observes; ``go``: whether any measurement is left to observe."""
    if classify is None:
        @jit_into_caller
        def link(i, p, mstat, code, go):
            if mstat[i, k] != UNUSED:
                mstat[i, k] = st.OK
                go = True
            return code, go
        return link

    @jit_into_caller
    def link(i, p, mstat, code, go):
        if mstat[i, k] == NOT_RUN:
            c = classify(p)
            if c != st.OK:
                mstat[i, k] = -c
                code = fold(code, c)
            else:
                mstat[i, k] = st.OK
                go = True
        elif mstat[i, k] == NO_CLASSIFY:
            mstat[i, k] = st.OK
            go = True
        return code, go

    return link


@functools.cache
def _checks(links: tuple):
    """``checks(i, p, mstat, code, go) -> (code, go)``: the links in order."""
    if not links:
        @jit_into_caller
        def none(i, p, mstat, code, go):
            return code, go
        return none
    if len(links) == 1:
        return links[0]
    first, rest = links[0], _checks(links[1:])

    @jit_into_caller
    def both(i, p, mstat, code, go):
        code, go = first(i, p, mstat, code, go)
        return rest(i, p, mstat, code, go)

    return both


@functools.cache
def _observe_link(obs, k, always: bool, fold):
    """Measurement k observes its rows where it is chosen and applies (``always``: also where its
    classify skipped it, when K[k, -1] != 0, its status only where it applies). Each link, the chain's
    ``observe`` and ``admit`` are functions of their own (jit_internal), not inlined into the kernel:
    numba's compile time grows faster than a function's size, and a kernel with every observer inlined
    spent most of its cold compile in that one function (`python benchmarks/startup.py --only compile
    --scene sweeps/autobalancer_residual.toml` shows each function's share); a call per trajectory
    costs nothing beside its integration."""
    if always:
        @jit_internal
        def link(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, code):
            if mstat[i, k] == st.OK or (mstat[i, k] != UNUSED and K[k, K.shape[1] - 1] != 0.0):
                c = obs(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2)
                if mstat[i, k] == st.OK:
                    mstat[i, k] = c
                    code = fold(code, c)
            return code
        return link

    @jit_internal
    def link(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, code):
        if mstat[i, k] == st.OK:
            c = obs(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2)
            mstat[i, k] = c
            code = fold(code, c)
        return code

    return link


@functools.cache
def _observe_chain(links: tuple):
    if not links:
        @jit_into_caller
        def none(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, code):
            return code
        return none
    if len(links) == 1:
        return links[0]
    first, rest = links[0], _observe_chain(links[1:])

    @jit_into_caller
    def both(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, code):
        code = first(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, code)
        return rest(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, code)

    return both


@functools.cache
def _lock(rates: tuple, n_m: int, n_s: int, col: int):
    """The largest change of the state over one forcing period (bits[:, n_m]: the whole periods of the
    second half of the Kick's horizon), less ``rates`` times the time for the states that turn with the
    forcing: into vals[i, col] where the kernel has that column (Recheck.skip_locked)."""
    lock_rates = np.array(rates or (0.0,))
    enabled = bool(rates)

    @jit_into_caller
    def lock(i, te, traj, bits, vals):
        if enabled and vals.shape[1] > col:  # the lock test asked for (a re-check that skips locked points)
            lock = 0.0
            kr = -1
            nrev = 0
            for j in range(te.size):
                if bits[j, n_m]:
                    if kr >= 0:
                        for q in range(n_s):
                            dz = traj[j, q] - traj[kr, q]
                            if lock_rates[q] != 0.0:
                                dz -= lock_rates[q] * (te[j] - te[kr])
                            if not abs(dz) <= lock:  # NaN propagates
                                lock = abs(dz)
                    kr = j
                    nrev += 1
            vals[i, col] = lock if nrev >= 2 else math.inf

    return lock


@functools.cache
def _failed(n_m, fold):
    """After a failed integration (status c): every measurement not skipped gets c."""
    @jit_into_caller
    def failed(i, mstat, code, c):
        for k in range(n_m):
            if mstat[i, k] == st.OK:
                mstat[i, k] = c
        return fold(code, c)

    return failed


def _parts(plan):
    """(checks, observe(i, p, ..., mstat, code) -> code, failed) of the kernel's measurements."""
    view = plan.view
    checks, observes = [], []
    for k, m in enumerate(plan.chosen):
        classify = view.fn(getattr(m, "classify", None), f"mclassify{k}", "status1")
        checks.append(_check_link(k, classify, view.fold))
        observes.append(_observe_link(m.observer(plan, k), k, k == plan.always and classify is not None,
                                      view.fold))
    lock = _lock(plan.lock, len(plan.chosen), view.n_s, plan.cols[-1])
    return (_checks(tuple(checks)), _observe(_observe_chain(tuple(observes)), lock),
            _failed(len(plan.chosen), view.fold))


@functools.cache
def _observe(chain, lock):
    @jit_internal
    def observe(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, code):
        code = chain(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, code)
        lock(i, te, traj, bits, vals)
        return code

    return observe


# ----------------------------------------------------------------------------- the kernels
def build(model, chosen, method, always=-1, lock=(), raw=False, rhs_lanes=None):
    """The entry points of the model's sampled-trajectory kernel: ``kernel`` (one trajectory at a
    time), and with ``rhs_lanes`` (dop853) ``setup`` and ``queue`` (the lanes)."""
    plan = Plan(model, chosen, method, always, lock, raw)
    view = plan.view
    checks, observe, failed = _parts(plan)
    fd_at = view.scr + 3 * view.n_s if plan.fd_count else -1
    run = plan.integrator.trajectory_pass(plan.equation(), plan.initial)
    admit = _admit(plan.classify, plan.prepare, plan.forcing, checks, plan.reset, view.n_p, view.n_set)
    kernel = _kernel(admit, run, plan.integrator.workspace(view.n_s), observe, failed, view.n_s, plan.p_size,
                     view.npi, fd_at)
    entries = dict(kernel=kernel)
    if rhs_lanes is not None:
        entries["setup"] = _setup(admit, plan.initial)
        load, run_lanes = dop853_lanes.make_lane_trajectory_solver(rhs_lanes, plan.equation().rhs)
        entries["queue"] = _queue(load, run_lanes, observe, failed, view.n_s, view.npi)
    return binding.Entries(**entries)


@functools.cache
def _admit(classify, prepare, forcing, checks, reset, n_p, n_set):
    @jit_internal
    def admit(i, p, P, S, rtol, mstat):
        """Point i's p filled from its row of P and the settings S: (status, T, whether it is
        integrated): the model's classify and prepare, the forcing period T (not finite > 0:
        INFEASIBLE) and the measurements' classify (none applies: not integrated)."""
        for j in range(n_p):
            p[j] = P[i, j]
        for j in range(n_set):
            p[n_p + j] = S[j]
        for j in range(n_p + n_set, p.size):
            p[j] = 0.0
        reset(p)
        c = classify(p)
        if c != st.OK:
            return c, math.nan, False
        c = prepare(p, rtol)
        if c != st.OK:
            return c, math.nan, False
        T = forcing(p)
        if not (math.isfinite(T) and T > 0.0):
            return st.INFEASIBLE, T, False
        code, go = checks(i, p, mstat, st.OK, False)
        return code, T, go

    return admit


@functools.cache
def _kernel(admit, run, new_work, observe, failed, n_s, p_size, npi, fd_at):
    @jit_into_caller  # compiled into the binding's cached trampoline (no link of its own)
    def kernel(P, S, s, bits, K, hoff, rtol, atol, max_steps, vals, hist, rawv, rawh, status, mstat, n_steps, n_rhs,
               first, step):
        # the points first, first + step, ... (strided: cost varies along the grid); point.Threaded runs
        # one such stride per thread (nogil), without numba's parallel compile
        n = P.shape[0]
        ns_ = s.size
        if first < n:
            p = np.empty(p_size)
            y = np.empty(n_s)
            te = np.empty(ns_)
            ob = np.zeros(ns_)
            ob2 = np.zeros(ns_)
            traj = np.empty((ns_, n_s))
            work = new_work()
            for i in range(first, n, step):
                if status[i] != st.OK:
                    continue
                code, T, go = admit(i, p, P, S, rtol, mstat)
                if not go:  # not integrated
                    status[i] = code
                    continue
                for j in range(ns_):
                    te[j] = T * s[j]
                c, a, b = run(p, y, te, rtol, atol, max_steps, work, traj)
                n_steps[i] += a
                n_rhs[i] += b
                if fd_at >= 0:
                    n_rhs[i] += int(p[fd_at])  # the rhs calls of the engine's Jacobian
                if c != st.OK:
                    if p[npi] != 0.0:  # the model's code raised (its guard wrote NaN): USER_ERROR, not NONFINITE
                        c = st.USER_ERROR
                    status[i] = failed(i, mstat, code, c)
                    continue
                code = observe(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, code)
                if p[npi] != 0.0:
                    code = st.USER_ERROR
                status[i] = code

    return kernel


@functools.cache
def _setup(admit, initial):
    @jit_internal
    def setup(P, S, rtol, PF, Z0, TT, status, mstat):
        # serial: a point's classify, prepare and initial state are little beside its integration
        n = P.shape[0]
        for i in range(n):
            if status[i] != st.OK:
                continue
            p = PF[i]
            code, T, go = admit(i, p, P, S, rtol, mstat)
            status[i] = code
            if not go:  # not integrated (TT stays NaN)
                continue
            TT[i] = T
            initial(p, Z0[i])

    return setup


@functools.cache
def _queue(load, run, observe, failed, n_s, npi):
    @jit_internal
    def observed(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, status):
        code = observe(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, status[i])
        if p[npi] != 0.0:
            code = st.USER_ERROR
        return code

    @jit_internal
    def queue(lanes, idx, first, step, PF, Z0, te, s, bits, K, hoff, rtol, atol, max_steps, vals, hist, rawv, rawh,
              status, mstat, n_steps, n_rhs):
        ws = dop853_lanes.workspace(n_s, PF.shape[1], lanes, te.size)
        traj = ws[dop853_lanes.TRAJ]
        ob = np.zeros(s.size)
        ob2 = np.zeros(s.size)
        nxt = first
        m = idx.size
        for lane in range(lanes):
            if nxt < m:
                load(ws, lane, nxt, 0.0, Z0[idx[nxt]], PF[idx[nxt]], te, rtol, atol)
                nxt += step
            else:
                dop853_lanes.idle(ws, lane)
        while True:
            lane = run(ws, te, rtol, atol, max_steps)
            if lane < 0:
                return
            j, c, a, b = dop853_lanes.lane_result(ws, lane)
            i = idx[j]
            if c == st.OK:
                c = observed(i, PF[i], te, traj[lane], s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, status)
            else:
                if PF[i, npi] != 0.0:  # the model's code raised (its guard wrote NaN): USER_ERROR, not NONFINITE
                    c = st.USER_ERROR
                c = failed(i, mstat, status[i], c)
            status[i] = c
            n_steps[i] += a
            n_rhs[i] += b
            if nxt < m:
                load(ws, lane, nxt, 0.0, Z0[idx[nxt]], PF[idx[nxt]], te, rtol, atol)
                nxt += step
            else:
                dop853_lanes.idle(ws, lane)

    return queue
