"""The one-point kernel: a model's chosen measurements and closed forms at every point, one point at a
time per thread, composed from closures (no generated code but the binding, engine/binding.py).

    kernel(P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs, first, step)
    for i = first, first + step, ...:       (strided: cost varies along the grid; Threaded runs one
                                             stride per thread)
        p = (parameters, settings, internal slots = 0, flag = 0, scratch = 0)
        try: status[i] = point(i, ...)       (an exception of the model's code ends the point:
        except: status[i] = USER_ERROR       USER_ERROR, the other points computed; the arrays
                                             borrowed, engine/borrow.py: no reference counting)

    point:  classify(p)                     -> non-OK: that status, nothing else
            closed forms that need no measurement (where need[j]; a closed form's classify)
            prepare(p, rtol)                -> non-OK: the measurements NaN, closed forms kept
            the measurements, in declared order: a shared trajectory (Crossing, Period, StateAt,
              Extremum: engine/shared.py), a direct integration (FirstEvent, a lone first Crossing:
              engine/events.py), Floquet (engine/floquet.py); each behind its own classify
            closed forms that need a measurement

Values go to ``table`` (the measurements' columns, then the closed forms') and to the point's value
row ``cv`` (what closed forms read); a stage's status folds into the point's (first failure, or
the model's status order). The model's functions are compiled into their callers (load.inlined):
numba types a ``try`` with every operation of its body split off, so one try per point costs far
less compile than a guard per function.
"""
from __future__ import annotations

import functools
import math
from concurrent.futures import ThreadPoolExecutor, wait
import threading

import numpy as np

from .. import _jit
from .. import status as st
from .._jit import jit_internal, jit_into_caller
from ..ode import methods
from . import binding, calls, equations, shared, switches
from .borrow import borrowed

BLOCK = 16  # the fewest points a thread of Threaded is given (fewer points: fewer threads)
ARGS = "P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs, first, step"


# ----------------------------------------------------------------------------- what a choice integrates
def is_direct(chosen) -> bool:
    """Whether the chosen measurements integrate on their own with any method: FirstEvents, or one
    Crossing with n = 1 alone (no shared trajectory to build for a single first crossing)."""
    if not chosen:
        return False
    if all(getattr(m, "direct", False) for m in chosen):
        return True
    return len(chosen) == 1 and getattr(chosen[0], "direct_alone", False)


def floquet_only(chosen) -> bool:
    """Whether the chosen measurements are Floquet measurements only (they offer dop853, radau and
    auto: their variational integration has its own method switch)."""
    return bool(chosen) and all(getattr(m, "variational_route", False) for m in chosen)


def integration_method(chosen, method):
    """The method the one-point kernel integrates with: the scene's, or dop853 for the measurements of
    the shared trajectory (ModelSpec.methods_for offers only dop853 for them)."""
    if is_direct(chosen) or floquet_only(chosen):
        return method
    return methods.DOP853


def columns(chosen) -> list[int]:
    """First column of each chosen measurement in the kernel's table (a measurement with
    ``n_values`` > 1, Floquet, has that many columns)."""
    cols, c = [], 0
    for m in chosen:
        cols.append(c)
        c += getattr(m, "n_values", 1)
    return cols + [c]


class Plan:
    """Where one kernel keeps what (the layout of p's scratch, the table's columns, the value row):
    what the measurements' point factories (``m.point(plan, k)``) build on."""

    def __init__(self, model, chosen, closed, method, guarded: bool = False):
        self.view = view = equations.View(model, guarded=guarded)
        self.model, self.chosen, self.closed = model, tuple(chosen), tuple(closed)
        self.direct = is_direct(chosen)
        self.method = integration_method(chosen, method)
        n_s = view.n_s
        self.group = [] if self.direct else [k for k, m in enumerate(chosen) if hasattr(m, "shared_row")]
        # a FirstEvent beside shared-path measurements integrates on its own too (dop853, as alone)
        self.alone = [k for k, m in enumerate(chosen) if self.direct or getattr(m, "direct", False)]
        fd_own = any(getattr(m, "system", None) is not None and m.system.jac is None for m in chosen)
        self.fd_count = self.direct and self.method.jacobian and (model.jac is None or fd_own)
        scratch = [n_s]
        if self.fd_count:  # the engine's Jacobian: 3 NS of scratch and the counter of its rhs calls
            scratch.append(3 * n_s + 1)
        scratch += [m.scratch(n_s) for m in chosen if hasattr(m, "scratch")]
        self.n_scr = max(scratch)
        self.switched = getattr(model, "switch_times", None) is not None
        self.sw = view.switch_slot(self.n_scr) if self.switched else -1
        # p: the scratch, with switches their two slots and NS more (a measurement that takes the last
        # NS slots of p as scratch stays off them)
        self.p_size = view.scr + self.n_scr + (2 + n_s if self.switched else 0)
        self.cols = columns(chosen)
        # the value row: each measurement's value, its further values (Floquet's kind and angle), the
        # closed forms'
        self.slot, self.extra, k = {}, {}, 0
        for j, m in enumerate(chosen):
            self.slot[m.name] = k
            k += 1
            for e, x in enumerate(getattr(m, "values", lambda: ())()):
                if e > 0:
                    self.extra[x] = (j, e, k)
                    self.slot[x] = k
                    k += 1
        for c in closed:
            self.slot[c.name] = k
            k += 1
        self.n_values = max(k, 1)
        self.n_buf = max([len(c.needs) for c in closed] + [1])
        self._functions()

    def _functions(self):
        view, model = self.view, self.model
        fn = view.fn
        self.initial = fn(model.initial, "initial", "initial")
        self.classify = fn(model.classify, "classify", "status1") or _ok1
        self.prepare = fn(model.prepare, "prepare", "status2") or _ok2
        self.forcing = fn(model.forcing_period, "forcing", "p")
        self.reset = switches.no_reset
        self.switch_fns = None
        if self.switched:
            times = model.switch_times
            # the list itself unguarded: switches.functions guards its callers (a tuple has no NaN)
            lst = (view.raw(times, "switch_times") if callable(times)
                   else switches.constant_list(tuple(float(x) for x in times)))
            self.switch_fns = switches.functions(lst, self.forcing, self.sw, view.npi, view.guarded)
            self.reset = switches.reset(self.sw)

    def equation(self, system=None):
        """The model's (or a System's) equation as this kernel integrates it."""
        return equations.equation(self.view, system, clamp_at=self.sw, fd_at=self.view.scr,
                                  fd_count=self.fd_count)

    def integrator(self, method=None):
        """``method`` (default: the kernel's) with the model's switches, if it declares any."""
        method = method or self.method
        if self.switch_fns is None:
            return method
        check, nxt, clamp = self.switch_fns
        return switches.switched(method, nxt, check, clamp)


@jit_into_caller
def _ok1(p):
    return st.OK


@jit_into_caller
def _ok2(p, x):
    return st.OK


# ----------------------------------------------------------------------------- the measurements' links
@functools.cache
def measure_link(block, classify, col: int, slot: int, extras: tuple, npi: int, fold):
    """A measurement's part of a point: ``block`` gives its (status, value) (``classify``, or None:
    where it applies; elsewhere its status); the value into ``table[i, col]`` and ``cv[slot]`` when OK
    and finite (``extras``: (column offset, value slot) of further values the block wrote into the
    table), else its status into the point's."""
    n_extra = len(extras)
    offsets = np.array([e[0] for e in extras] or [0], dtype=np.int64)
    slots = np.array([e[1] for e in extras] or [0], dtype=np.int64)
    applies = classify or _ok1

    @jit_into_caller
    def link(i, p, y, rtol, atol, max_steps, ws, table, cv, n_steps, n_rhs, code):
        val = math.nan
        c = applies(p)
        if c == st.OK:
            c, val = block(i, p, y, rtol, atol, max_steps, ws, table, n_steps, n_rhs)
        if p[npi] != 0.0:
            c = st.USER_ERROR
        if c == st.OK and not math.isfinite(val):
            c = st.NONFINITE
        if c == st.OK:
            table[i, col] = val
            cv[slot] = val
            for e in range(n_extra):
                cv[slots[e]] = table[i, col + offsets[e]]
        else:
            code = fold(code, c)
        return code

    return link


@functools.cache
def measures_chain(links: tuple):
    """``run(i, p, y, rtol, atol, max_steps, ws, table, cv, n_steps, n_rhs, code) -> code``: the links
    in order."""
    if not links:
        @jit_into_caller
        def none(i, p, y, rtol, atol, max_steps, ws, table, cv, n_steps, n_rhs, code):
            return code
        return none
    if len(links) == 1:
        return links[0]
    first, rest = links[0], measures_chain(links[1:])

    @jit_into_caller
    def both(i, p, y, rtol, atol, max_steps, ws, table, cv, n_steps, n_rhs, code):
        code = first(i, p, y, rtol, atol, max_steps, ws, table, cv, n_steps, n_rhs, code)
        return rest(i, p, y, rtol, atol, max_steps, ws, table, cv, n_steps, n_rhs, code)

    return both


def closed_links(plan, which: bool) -> tuple:
    """The links of the closed forms that need a measurement's value (``which``) or not."""
    out = []
    values = set(plan.slot) - {c.name for c in plan.closed}
    n_cols = plan.cols[-1]
    for j, c in enumerate(plan.closed):
        if which != any(x in values for x in c.needs):
            continue
        call = calls.closed_call(plan.view.raw(c.func, f"closed{j}"),
                                 calls.user(plan.model.name, c.func, f"closed{j}"),
                                 tuple(plan.slot[x] for x in c.needs), plan.view.npi, plan.view.guarded)
        classify = plan.view.fn(getattr(c, "classify", None), f"cfclassify{j}", "status1")
        out.append(calls.closed_link(call, classify, j, n_cols + j, plan.slot[c.name], plan.view.fold))
    return tuple(out)


# ----------------------------------------------------------------------------- the kernel
def build(model, chosen, closed, method):
    """The one-point kernel's entry points (``binding.Entries(kernel=...)``) of ``model`` for the
    measurements ``chosen`` and closed forms ``closed`` (dependency order) by ``method``."""
    plan = Plan(model, chosen, closed, method)
    view = plan.view
    links = []
    if plan.group:
        links.append(shared.integration(plan))
    for k, m in enumerate(plan.chosen):
        block = shared.member(plan, k) if k in plan.group else m.point(plan, k)
        slots = tuple((e, plan.extra[x][2]) for x, (j, e, _) in plan.extra.items() if j == k)
        classify = view.fn(getattr(m, "classify", None), f"mclassify{k}", "status1")
        links.append(measure_link(block, classify, plan.cols[k], plan.slot[m.name], tuple(sorted(slots)), view.npi,
                                  view.fold))
    work = (plan.method.workspace(view.n_s) if plan.chosen else _no_work)
    shared_M = shared.rows(plan) if plan.group else ()
    point = _point(plan.classify, calls.chain(closed_links(plan, False)), plan.prepare, measures_chain(tuple(links)),
                   calls.chain(closed_links(plan, True)), bool(plan.chosen),
                   tuple([plan.slot[m.name] for m in plan.chosen] + [s for (_, _, s) in plan.extra.values()]),
                   view.scr + 3 * view.n_s if plan.fd_count else -1, view.npi, bool(view.order), view.fold)
    kernel = _kernel(point, work, shared_M, len(plan.group), plan.reset, view.n_p, view.n_set, view.scr + plan.n_scr,
                     plan.p_size, view.n_s, plan.n_values, plan.n_buf)
    return binding.Entries(kernel=kernel)


@jit_into_caller
def _no_work():
    return np.empty((0, 0))


@functools.cache
def _point(classify, before, prepare, measures, after, measured: bool, m_slots: tuple, fd_at: int, npi: int,
           ordered: bool, fold):
    m_slots = np.array(m_slots, dtype=np.int64)

    @jit_internal
    def point(i, need, rtol, atol, max_steps, table, n_steps, n_rhs, p, y, ws, cv, buf):
        # one point, p filled: its status. An exception of the model's code ends it in the kernel's try
        code = st.OK
        c = classify(p)
        if c != st.OK:
            return c
        code = before(i, p, need, cv, buf, table, code)
        if measured:
            for s in m_slots:
                cv[s] = math.nan
            c = prepare(p, rtol)
            if c != st.OK:
                code = fold(code, c) if ordered else c
            else:
                code = measures(i, p, y, rtol, atol, max_steps, ws, table, cv, n_steps, n_rhs, code)
            code = after(i, p, need, cv, buf, table, code)
        if fd_at >= 0:
            n_rhs[i] += int(p[fd_at])  # the rhs calls of the engine's Jacobian
        if p[npi] != 0.0 and code == st.OK:
            code = st.USER_ERROR
        return code

    return point


@functools.cache
def _kernel(point, new_work, shared_rows: tuple, n_shared: int, reset, n_p: int, n_set: int, filled: int,
            p_size: int, n_s: int, n_values: int, n_buf: int):
    new_ws = _workspace(new_work, shared_rows, n_shared)
    points = _points(point, reset, filler(n_p, n_set, filled))

    @jit_into_caller  # compiled into the binding's cached trampoline (no link of its own)
    def kernel(P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs, first, step):
        # the points first, first + step, ... (strided: cost varies along the grid); Threaded runs one
        # such stride per thread (nogil), as a prange would, without numba's parallel compile
        if first < P.shape[0]:
            points(P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs, first, step, np.empty(p_size),
                   np.empty(n_s), new_ws(), np.empty(n_values), np.empty(n_buf))

    return kernel


@functools.cache
def filler(n_p: int, n_set: int, filled: int):
    """``fill(p, P, i, S)``: a point's p: its parameters from row i of P, the settings S, then zeros up to
    slot ``filled`` (the internal slots, the flag, the scratch)."""
    @jit_into_caller
    def fill(p, P, i, S):
        for j in range(n_p):
            p[j] = P[i, j]
        for j in range(n_set):
            p[n_p + j] = S[j]
        for j in range(n_p + n_set, filled):
            p[j] = 0.0

    return fill


@functools.cache
def _points(point, reset, fill):
    @jit_internal
    def points(P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs, first, step, p, y, ws, cv, buf):
        # the point function takes the arrays borrowed (engine/borrow.py): the caller holds them for
        # this call, and numba then counts no reference at every point
        P, S, need, table, status, n_steps, n_rhs = borrowed((P, S, need, table, status, n_steps, n_rhs))
        p, y, ws, cv, buf = borrowed((p, y, ws, cv, buf))
        for i in range(first, P.shape[0], step):
            if status[i] != st.OK:
                continue
            fill(p, P, i, S)
            reset(p)
            try:  # the one try: what a point computes after its model code raised is not computed
                code = point(i, need, rtol, atol, max_steps, table, n_steps, n_rhs, p, y, ws, cv, buf)
            except Exception:
                code = st.USER_ERROR
            status[i] = code

    return points


@functools.cache
def _workspace(new_work, shared_rows: tuple, n_shared: int):
    """``new_ws()``: the point's workspace tuple: the method's workspace and, where measurements share a
    trajectory (engine/shared.py), its values, statuses and rows; without one, the method's alone."""
    if not n_shared:
        @jit_into_caller
        def alone():
            return (new_work(),)
        return alone
    shared_M = np.array(shared_rows, dtype=np.float64)  # the shared trajectory's rows

    @jit_into_caller
    def with_shared():
        return (new_work(), np.empty(n_shared), np.empty(n_shared, dtype=np.int64), shared_M.copy())
    return with_shared


# ----------------------------------------------------------------------------- threads
_POOL: list[ThreadPoolExecutor] = []
_POOL_LOCK = threading.Lock()


def _pool() -> ThreadPoolExecutor:
    with _POOL_LOCK:
        if not _POOL:
            import numba
            _POOL.append(ThreadPoolExecutor(max_workers=max(1, numba.config.NUMBA_NUM_THREADS - 1),
                                            thread_name_prefix="mechsweep-kernel"))
        return _POOL[0]


def strides(n: int, threads: int, block: int = BLOCK) -> list[tuple]:
    """The last arguments of each thread's call of a strided kernel (Threaded's ``tails``): thread t of
    T computes the points t, t + T, ... (strided: cost varies along the grid), at least ``block``
    points a thread."""
    threads = max(1, min(threads, (n + block - 1) // block))
    return [(t, threads) for t in range(threads)]


class Threaded:
    """A chunk kernel ``kernel(P, ...)`` on numba.get_num_threads() threads: the serial
    ``kernel(P, ..., *tail)`` (nogil) once per thread, with the thread's ``tails(n, threads)`` (n: the
    rows of P; ``strides``: the one-point, sampled-trajectory and closed-form kernels;
    lanes.shared_counter: the lane kernel), the calling thread one of them. A ``prange`` cost numba's
    parallel compile (parfor passes, the gufunc and its two wrappers, each linking and optimising the
    whole call tree again): about 2.3 s of the one-point kernel's compile CPU and more of the other
    kernels' (`python benchmarks/startup.py --only compile`, ``--only routes``,
    docs/performance-startup.md). Each point is computed alone, so the results are the same whatever
    the split. Anything else (``py_func``, ``stats``) is the serial kernel's."""

    def __init__(self, serial, name: str = "", tails=None, block: int = BLOCK):
        # tails: by default ``strides`` of at least ``block`` points a thread
        self.serial, self.name = serial, name
        self.tails = tails or functools.partial(strides, block=block)

    def __getattr__(self, name):
        return getattr(self.serial, name)

    def __call__(self, *args):
        on_threads(lambda *tail: self.serial(*args, *tail), self.tails(args[0].shape[0], _jit.num_threads()))


def on_threads(call, tails) -> None:
    """``call(*tail)`` for each of ``tails`` at once: the first on the calling thread, the others on the
    kernel pool's threads (at most numba.config.NUMBA_NUM_THREADS in all); returns once every one has
    finished, raising the first one's error."""
    first, *others = tails
    futures = [_pool().submit(call, *tail) for tail in others]
    try:
        call(*first)
    finally:  # never return (nor raise, e.g. KeyboardInterrupt) while a thread still writes the arrays
        interrupted = None
        while not all(f.done() for f in futures):
            try:
                wait(futures)
            except BaseException as e:  # noqa: BLE001 - raised once every thread has finished
                interrupted = e
        if interrupted is not None:
            raise interrupted
    for f in futures:
        f.result()
