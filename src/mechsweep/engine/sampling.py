"""The sampled-trajectory route of the model layer: the sampled measurements (Steady, Kick, History,
RMS: model/sampled.py) observe ONE integration per point from ``initial(p)``, sampled on one grid of
instants.

The grid is built in Python from the solver settings (``grid``): the union of the chosen
measurements' instants in forcing periods s, with a column of role bits per measurement; it is
the same for every point, so it does not depend on the point or on which other outputs are asked
for beyond adding rows (the integrators' steps do not depend on the sample instants: samples come
from the dense output; only the last instant, the horizon, ends the integration). Each point's
instants are t = T s, T = ``forcing_period(p)`` (after ``prepare``), or T = 1 for a model without
one.

The kernel (engine/trajectory.py, one per model and method: ``kernel_for``) integrates and observes
each point; this module builds the grid, chooses the route (one trajectory at a time, or the SIMD
lanes per forcing period: ``_run_lanes``), reads the kernel's value columns into the outputs (each
measurement's ``finish``: statuses NO_EVENT, UNDECIDED) and runs the model's Recheck.
"""
from __future__ import annotations

import itertools
import math
import threading
from types import SimpleNamespace

import numpy as np

from .. import _jit
from .. import status as st
from ..model.spec import setting_value
from .point import Threaded, on_threads
from .trajectory import NO_CLASSIFY, NOT_RUN, UNUSED, columns

METHODS = ("dop853", "radau", "auto")  # the methods that make a trajectory solver (OdeModel.methods_for offers these)
_KERNELS: dict[str, object] = {}


def grid(chosen, settings, wanted=None):
    """(s, bits, K): the sample instants in forcing periods (sorted, unique), bits[j, k] the roles of
    instant j for measurement k (0: not its instant), K[k] its constants (for the outputs ``wanted``
    only, as the measurement declares them: ``constants_for``; None: for all of its outputs)."""
    parts = [(m, inst) for m in chosen for inst in m.instants(settings)]
    s = np.unique(np.concatenate([x for _, (x, _) in parts]))
    bits = np.zeros((s.size, len(chosen)), dtype=np.int64)
    for k, m in enumerate(chosen):
        for x, b in m.instants(settings):
            rows = np.isin(s, x)
            bits[:, k] |= np.where(rows, b(s, settings) if callable(b) else b, 0)
    consts = [m.constants(settings) if wanted is None else m.constants_for(settings, wanted) for m in chosen]
    K = np.zeros((len(chosen), max([len(c) for c in consts] + [1])))
    for k, c in enumerate(consts):
        K[k, :len(c)] = c
    return s, bits, K


def lane_rhs_for(model, method) -> str | None:
    """The engine's lane form of the model's rhs (engine/lane_rhs.py) for dop853, or None (another
    method, or an rhs the rewrite does not cover: one trajectory at a time)."""
    if method != "dop853" or getattr(model, "switch_times", None) is not None:  # switches: one at a time
        return None
    from .lane_rhs import lane_rhs_source
    return lane_rhs_source(model.rhs)


def sampled_measurements(model) -> tuple:
    """Every sampled measurement the model declares, in declaration order: the kernel's columns."""
    return tuple(m for m in model.measurements if getattr(m, "sampled", False))


def recheck_variant(model, measurements):
    """(always, lock, raw) of the model's Recheck as compiled into a kernel of ``measurements``
    (whether it runs is decided per call, its factor being possibly a setting): ``always`` the
    index of its skip_settled Kick among them (-1: none), ``lock`` the per-state rates of its lock
    test (skip_locked), ``raw`` its measured_units."""
    rc = getattr(model, "recheck", None)
    names = [m.name for m in measurements]
    if rc is None or rc.skip_settled is None or rc.skip_settled not in names:
        return -1, (), False
    always = names.index(rc.skip_settled)
    lock = ()
    if rc.skip_locked:
        rates = dict(rc.lock_rates)
        lock = tuple(float(rates.get(x, 0.0)) for x in model.states)
    return always, lock, bool(rc.measured_units)


def kernel_for(model, method, measurements=None):
    """The model's one sampled-trajectory kernel for ``method`` (engine/trajectory.py): every sampled
    measurement it declares (or only ``measurements``, the model's own, in their order: a kernel per
    subset, for comparison), the ones that observe chosen per call (``evaluate``), as the closed forms
    are (one kernel per model and method, whatever subset of outputs is asked for). Its entry points:
    ``kernel``; with the lanes (dop853, an rhs the engine rewrites) ``setup`` and ``queue``."""
    from . import binding
    from . import trajectory as engine
    from .lane_rhs import binding_text

    chosen = sampled_measurements(model) if measurements is None else tuple(measurements)
    name, m, lane_rhs, (always, lock, raw) = _binding(model, method, chosen)
    known = _KERNELS.get(name)
    if known is not None:
        return known
    entries = {"kernel": engine.KERNEL_ARGS}
    if lane_rhs:
        entries.update(setup=engine.SETUP_ARGS, queue=engine.QUEUE_ARGS)
    mod = binding.bind(name, f"model {model.name!r}, sampled trajectories, method {m.name}", entries,
                       lambda *lane: engine.build(model, chosen, m, always, lock, raw, *lane),
                       extra=binding_text(lane_rhs) if lane_rhs else "",
                       lane_names=("rhs_lanes",) if lane_rhs else ())
    # its entry points (the one-trajectory kernel on threads: point.Threaded), and its name
    out = SimpleNamespace(name=name, **{e: getattr(mod, e) for e in entries})
    out.kernel = Threaded(mod.kernel, name, block=engine.BLOCK)
    _KERNELS[name] = out
    return out


def _binding(model, method, chosen):
    """(binding name of the kernel of the sampled measurements ``chosen``, the method object, the lane
    rhs or None, and the re-check's variant: always, lock, raw)."""
    from .kernels import binding_name
    from ..ode.methods import method as method_of

    variant = recheck_variant(model, chosen)
    lane_rhs = lane_rhs_for(model, method)
    m = method_of(method)
    always, lock, raw = variant
    return (binding_name(model, chosen, (), m, "trajectory", repr((always, tuple(lock), raw)) + (lane_rhs or "")),
            m, lane_rhs, variant)


def lane_name(model, method) -> str | None:
    """The name under which the lanes of the model's one sampled-trajectory kernel for ``method`` are
    recorded once compiled (kernels.lanes_recorded), or None when the lanes do not apply (another
    method, an rhs the rewrite does not cover: one trajectory at a time)."""
    if lane_rhs_for(model, method) is None:
        return None
    memo = (id(model), method)
    known = _LANE_NAMES.get(memo)
    if known is not None and known[0] is model:
        return known[1]
    name = _binding(model, method, sampled_measurements(model))[0] + ".lanes"
    _LANE_NAMES[memo] = (model, name)
    return name


_LANE_NAMES: dict[tuple, tuple] = {}  # lane_name's memo: (model, name) by (id(model), method)


def evaluate(model, chosen, P, wanted, solver, out, status, n_steps, n_rhs, lanes=None, per_subset=False):
    """Run the sampled measurements ``chosen`` on the points still OK in ``status``; with ``lanes`` by
    DOP853 lanes for dop853 when the engine rewrites the model's rhs in lane form (False: one trajectory
    at a time, the same values; None: as USE_LANES says, one at a time unless it is True). The model's
    one kernel (``kernel_for``) observes only the chosen ones; ``per_subset``: a kernel of the chosen
    ones alone instead (a compile per subset; the same values bitwise, for tests)."""
    method = solver.method
    settings = dict(solver.settings)
    rc = _active_recheck(model, settings)
    if rc is not None and rc.skip_settled is not None and rc.skip_settled not in [m.name for m in chosen]:
        import dataclasses  # its Kick observed everywhere, asked for or not
        kick = next(m for m in model.measurements if m.name == rc.skip_settled)
        chosen = tuple(chosen) + (dataclasses.replace(kick, classify=None),)
    always, lock, raw = (-1, (), False) if rc is None else recheck_variant(model, chosen)
    s, bits, K = grid(chosen, settings, wanted)
    if lock:  # the whole forcing periods of the second half of the Kick's horizon: one more bits column
        H = setting_value(chosen[always].horizon, settings)
        whole = np.arange(math.ceil(0.5 * H), math.floor(H) + 1, dtype=np.float64)
        s2 = np.unique(np.concatenate([s, whole]))
        bits2 = np.zeros((s2.size, bits.shape[1] + 1), dtype=np.int64)
        bits2[np.searchsorted(s2, s), :bits.shape[1]] = bits
        bits2[:, -1] = np.isin(s2, whole)
        s, bits = s2, bits2
    hw = history_widths(chosen, bits)
    hoff = np.array([sum(hw[:k]) if w else 0 for k, w in enumerate(hw)], dtype=np.int64)
    n_hist = sum(hw)
    cols = columns(chosen)
    n = P.shape[0]
    vals = np.full((n, cols[-1] + (1 if lock else 0)), np.nan)
    hist = np.full((n, n_hist), np.nan)
    rawv = np.full((n, cols[-1] if raw else 0), np.nan)
    rawh = np.full((n, n_hist if raw else 0), np.nan)
    S = np.array([float(settings.get(x.name, x.default)) for x in model.settings], dtype=np.float64)
    full = sampled_measurements(model)
    if per_subset:
        full = tuple(next(x for x in full if x.name == m.name) for m in chosen)
    mod = kernel_for(model, method, None if not per_subset else full)
    code = status.copy()
    mstat = np.full((n, len(chosen)), NOT_RUN, dtype=np.int64)
    P = np.ascontiguousarray(P, dtype=np.float64)
    order = tuple(getattr(model, "status_order", ()))
    # the kernel's layout: every sampled measurement of the model (kernel_for); the chosen ones
    # observe, the others are UNUSED (their bits columns zero, no value columns read back)
    f_lock = recheck_variant(model, full)[1]
    at = np.array([[x.name for x in full].index(m.name) for m in chosen], dtype=np.int64)
    fcols = columns(full)
    vcols = np.concatenate([np.arange(fcols[at[k]], fcols[at[k] + 1]) for k in range(len(chosen))]
                           + ([np.array([fcols[-1]])] if lock else []) + [np.zeros(0, np.int64)]).astype(np.int64)
    fbits = np.zeros((s.size, len(full) + (1 if f_lock else 0)), dtype=np.int64)
    fbits[:, at] = bits[:, :len(chosen)]
    if lock:
        fbits[:, len(full)] = bits[:, len(chosen)]
    fK = np.zeros((len(full), max([len(m.constants(settings)) for m in full] + [1]) + 1))
    fK[at, :K.shape[1]] = K
    if always >= 0:  # the skip_settled Kick observed also where its classify skips it
        fK[at[always], -1] = 1.0
    fhoff = np.zeros(len(full), dtype=np.int64)
    fhoff[at] = hoff
    first = np.full(len(full), UNUSED, dtype=np.int64)  # mstat before the kernel: which ones observe
    first[at] = NOT_RUN
    for k, m in enumerate(chosen):
        if getattr(m, "classify", None) is None and getattr(full[at[k]], "classify", None) is not None:
            first[at[k]] = NO_CLASSIFY  # the skip_settled Kick added above without its classify

    use_lanes = (hasattr(mod, "queue") and bool(USE_LANES if lanes is None else lanes)
                 and lane_count(s.size, model) > 0)

    def run(P, rtol, vals, hist, rawv, rawh, code, mstat, n_steps, n_rhs):
        m = P.shape[0]
        fvals = np.full((m, fcols[-1] + (1 if lock else 0)), np.nan)
        frawv = np.full((m, fcols[-1] if raw else 0), np.nan)
        fmstat = np.repeat(first[None, :], m, axis=0)
        if use_lanes:
            _run_lanes(mod, model, P, S, s, fbits, fK, fhoff, solver, fvals, hist, frawv, rawh, code, fmstat, n_steps,
                       n_rhs, rtol)
        else:
            mod.kernel(P, S, s, fbits, fK, fhoff, rtol, solver.atol, solver.max_steps, fvals, hist, frawv, rawh, code,
                       fmstat, n_steps, n_rhs)
        vals[:] = fvals[:, vcols]
        if raw:
            rawv[:] = frawv[:, vcols[:rawv.shape[1]]]
        mstat[:] = np.where(fmstat[:, at] == NO_CLASSIFY, NOT_RUN, fmstat[:, at])

    run(P, solver.rtol, vals, hist, rawv, rawh, code, mstat, n_steps, n_rhs)
    if use_lanes and not per_subset and mod.queue.signatures:  # compiled and saved: a later plan may take them
        from .kernels import record_compiled
        record_compiled(mod.name + ".lanes")
    moved = None
    if rc is not None:
        moved = _recheck(rc, chosen, wanted, settings, solver, P, run, (vals, hist, rawv, rawh), code, mstat, n_steps,
                         n_rhs, cols, hw, hoff, order, lock)
    good = measured(mstat, code, order)
    for k, m in enumerate(chosen):
        if m.n_values == 0:
            if m.name in out:
                out[m.name][:] = np.where(good[:, k, None], hist[:, hoff[k]:hoff[k] + hw[k]], np.nan)
        else:
            v = np.where(good[:, k, None], vals[:, cols[k]:cols[k + 1]], np.nan)
            if order:  # its own status (OK where it has values), ranked into the point's
                own = np.zeros_like(code)
                m.finish(v, wanted, solver, out, own)
                code[:] = st.worse(code, own, order)
            else:
                m.finish(v, wanted, solver, out, code)
    if moved is not None:
        st.mark_not_reproducible(code, moved, order)
    status[:] = code




def measured(mstat, code, order) -> np.ndarray:
    """good[i, k]: whether measurement k's values at point i stand. mstat[i, k]: OK, its failure
    (> 0), -status where its classify skipped it, NOT_RUN where the point was not integrated.
    With a status order only its own status counts; without one (first failure wins) any failure
    of another measurement at the point voids it too (not a skip)."""
    ok = (mstat == st.OK) & (code != st.USER_ERROR)[:, None]
    if order:
        return ok
    return ok & ~(mstat > 0).any(axis=1)[:, None]


def integrated(mstat, code) -> np.ndarray:
    """Points whose trajectory was integrated and observed without failure (skips allowed)."""
    return (mstat <= 0).all(axis=1) & (mstat == st.OK).any(axis=1) & (code != st.USER_ERROR)


def _active_recheck(model, settings):
    """The model's Recheck where its factor is > 0 (else None: no re-check)."""
    rc = getattr(model, "recheck", None)
    if rc is None or not setting_value(rc.factor, settings) > 0.0:
        return None
    return rc


def history_widths(chosen, bits) -> list[int]:
    """The number of rows of each chosen History (0 for the other measurements)."""
    return [int(np.count_nonzero(bits[:, k])) if m.n_values == 0 else 0 for k, m in enumerate(chosen)]


def _compared(chosen, wanted, cols, hw):
    """The columns the re-check compares, the value columns then the History columns: those of the
    asked-for outputs (a Steady's or Kick's j-th output is its j-th column)."""
    use = np.zeros(cols[-1], dtype=bool)
    for k, m in enumerate(chosen):
        for j, o in enumerate(m.outputs() if m.n_values else ()):
            use[cols[k] + j] = o.name in wanted
    huse = [m.name in wanted for m, w in zip(chosen, hw) for _ in range(w)]
    return np.concatenate([use, np.array(huse, dtype=bool)])


def _recheck(rc, chosen, wanted, settings, solver, P, run, arrays, code, mstat, n_steps, n_rhs, cols, hw, hoff, order,
             lock):
    """The model's Recheck (sampled.Recheck): which points moved when integrated again at the
    tighter rtol."""
    vals, hist, rawv, rawh = arrays
    factor = setting_value(rc.factor, settings)
    check = integrated(mstat, code)
    names = [m.name for m in chosen]
    if rc.skip_settled in names:  # settled early (integration time, before time_value): not again
        c0 = cols[names.index(rc.skip_settled)]
        t_settle, t_end = vals[:, c0 + 3], vals[:, c0 + 4]
        with np.errstate(invalid="ignore"):
            check &= ~(np.isfinite(t_settle) & (t_settle <= rc.settled_fraction * t_end))
            if lock:  # locked to the forcing period through the second half
                check &= ~(vals[:, cols[-1]] <= factor * (solver.rtol + solver.atol))
    moved = np.zeros(code.size, dtype=bool)
    idx = np.flatnonzero(check)
    if idx.size == 0:
        return moved
    P2 = np.ascontiguousarray(P[idx])
    vals2, hist2, rawv2, rawh2 = (np.full((idx.size, x.shape[1]), np.nan) for x in arrays)
    code2 = np.zeros(idx.size, dtype=code.dtype)
    mstat2 = np.full((idx.size, mstat.shape[1]), NOT_RUN, dtype=mstat.dtype)
    ns2, nr2 = np.zeros(idx.size, dtype=n_steps.dtype), np.zeros(idx.size, dtype=n_rhs.dtype)
    run(P2, rc.tight_rtol(solver.rtol), vals2, hist2, rawv2, rawh2, code2, mstat2, ns2, nr2)
    n_steps[idx] += ns2
    n_rhs[idx] += nr2
    # the asked-for outputs where their measurement applies, as stored (after value/time_value) or
    # as measured (measured_units)
    use = _compared(chosen, wanted, cols, hw)
    if rc.measured_units:
        vals, hist, vals2, hist2 = rawv, rawh, rawv2, rawh2

    def table(v, h, good):  # each measurement's columns (a History's in hist) from its own mask
        cv = [np.where(good[:, k, None], v[:, cols[k]:cols[k + 1]], np.nan) for k in range(len(chosen))]
        ch = [np.where(good[:, k, None], h[:, hoff[k]:hoff[k] + w], np.nan) for k, w in enumerate(hw) if w]
        return np.concatenate(cv + ch + [np.empty((v.shape[0], 0))], axis=1)[:, use]

    a = table(vals[idx], hist[idx], measured(mstat[idx], code[idx], order))
    b = table(vals2, hist2, measured(mstat2, code2, order))
    moved[idx] = rc.moved(a, b, factor, solver).any(axis=1) | ~integrated(mstat2, code2)
    return moved


# The lanes (method dop853, an rhs the engine rewrites in lane form). Each lane keeps its trajectory's
# samples (n_samples x n_states floats) until it ends: with long horizons or dense sampling fewer
# lanes, so that a queue's samples stay within LANE_SAMPLES_BYTES (32, 16, then 8 lanes, else the
# one-trajectory kernel).
LANES = (32, 16, 8)
LANE_SAMPLES_BYTES = 256 * 2**20
# evaluate's route where the lanes apply and the caller names none: True the lanes, False or None one
# trajectory at a time. A run names the route its plan chose (execution/plan.py, ``choose_route``, which
# reads this as an override): the lanes for a run of at least LANES_FROM_POINTS points, or once they are
# compiled (kernels.lanes_recorded, under ``lane_name``). Bitwise the same results either way.
USE_LANES: bool | None = None
# The lanes compile 6-8 s of CPU longer than the one-trajectory kernel and save a model-dependent CPU
# time a point, so they pay from about 1.3e3 points (sweeps/autobalancer_residual.toml, 6.1 ms a point
# saved) to 2.1e4 (the forced oscillator of tests/user_models/forced.py, 0.29 ms): `python
# tests/data/trajectory_lanes_cost.py both 256 residual` (models: autobalancer, forced, rms) prints the
# crossover. 2000 keeps the most a wrong route costs at either end alike, about 6 s of CPU once (then
# the lanes are compiled).
LANES_FROM_POINTS = 2000
# Once the one-trajectory kernel is compiled, the lanes cost their whole compile, about 2.2 times their
# extra compile (the residual scene on a 2-core Zen 3: 27.3 against 12.2 s of CPU, `python
# tests/data/trajectory_lanes_cost.py cold 4 residual`): a plan takes them once the points a model's
# runs computed one trajectory at a time (kernels.tally_points) and its own reach this many.
LANES_AFTER_POINTS = 4500
# The lanes of a queue share one forcing period (one t_eval): the points of a period shared by fewer
# than LANE_GROUP_MIN points (a sweep of the forcing frequency in physical time: each its own) are
# integrated one trajectory at a time (a round of 32 lanes with one active one costs more than ten
# scalar steps; docs/model-layer.md, "Lanes").
LANE_GROUP_MIN = 16


def lane_count(n_samples: int, model) -> int:
    for lanes in LANES:
        if lanes * n_samples * len(model.states) * 8 <= LANE_SAMPLES_BYTES:
            return lanes
    return 0


def group_lanes(most: int, points: int, queues: int) -> tuple[int, int]:
    """(lanes per queue, queues) for the ``points`` of one forcing period split into at most ``queues``
    queues of at least LANES[-1] points each, with at most ``most`` lanes (lane_count) and about half as
    many lanes as a queue has points (at least LANES[-1]): a lane without a point is stepped all the
    same, and a queue's last points run in partly idle lanes. Which lane computes a point does not
    change its results."""
    queues = max(1, min(queues, points // LANES[-1]))
    per_queue = -(-points // queues)
    lanes = next((n for n in LANES if n <= most and 2 * n <= per_queue), min(most, LANES[-1]))
    return lanes, queues


def _lane_tasks(groups, most: int, threads: int) -> list[tuple]:
    """(idx, te, lanes, first, step) of every queue of the forcing periods ``groups`` ((idx, te) each),
    the largest first: a period gets queues in proportion to its share of the points (one for a
    period among many), so that the threads take whole queues of different periods side by side."""
    total = sum(idx.size for idx, _ in groups)
    tasks = []
    for idx, te in groups:
        lanes, n = group_lanes(most, idx.size, -(-threads * idx.size // total))
        tasks += [(idx, te, lanes, b, n) for b in range(n)]
    tasks.sort(key=lambda t: -(t[0].size // t[4]))
    return tasks


def _run_lanes(mod, model, P, S, s, bits, K, hoff, solver, vals, hist, rawv, rawh, code, mstat, n_steps, n_rhs,
               rtol=None):
    """setup, then the points of each forcing period through the lanes in queues (``_lane_tasks``)
    that numba.get_num_threads() threads take one after another (the nogil queue: the calling thread
    and the kernel pool's, point.on_threads); the points of periods shared by fewer than LANE_GROUP_MIN
    points by the one-trajectory kernel (from their status before setup: it runs classify and prepare
    again)."""
    n = P.shape[0]
    n_s = len(model.states)
    n_p, n_set, n_int = len(model.params), len(model.settings), len(model.internal)
    PF = np.zeros((n, n_p + n_set + n_int + 1 + 3 * n_s))
    Z0 = np.zeros((n, n_s))
    TT = np.full(n, np.nan)
    rtol = solver.rtol if rtol is None else rtol
    code0, mstat0 = code.copy(), mstat.copy()
    mod.setup(P, S, rtol, PF, Z0, TT, code, mstat)
    lanes = lane_count(s.size, model)
    ok = np.isfinite(TT)  # the points setup left to integrate
    periods, counts = np.unique(TT[ok], return_counts=True)
    few = ok & np.isin(TT, periods[counts < LANE_GROUP_MIN])
    if few.any():  # forcing periods shared by too few points to fill lanes: one trajectory at a time
        i = np.flatnonzero(few)
        sub = [a[i] for a in (vals, hist, rawv, rawh, code0, mstat0, n_steps, n_rhs)]
        mod.kernel(np.ascontiguousarray(P[i]), S, s, bits, K, hoff, rtol, solver.atol, solver.max_steps, *sub)
        for a, b in zip((vals, hist, rawv, rawh, code, mstat, n_steps, n_rhs), sub):
            a[i] = b
    # te: the same products as the one-trajectory kernel's te[j] = T * s[j]
    groups = [(np.flatnonzero(ok & (TT == T)).astype(np.int64), T * s) for T in periods[counts >= LANE_GROUP_MIN]]
    if not groups:
        return
    threads = _jit.num_threads()
    tasks = _lane_tasks(groups, lanes, threads)
    taken, lock, stopped = itertools.count(), threading.Lock(), []

    def work():  # each thread takes the next queue until none is left, or another thread stopped (Ctrl-C)
        while not stopped:
            with lock:
                k = next(taken)
            if k >= len(tasks):
                return
            idx, te, width, first, step = tasks[k]
            try:
                mod.queue(width, idx, first, step, PF, Z0, te, s, bits, K, hoff, rtol, solver.atol,
                          solver.max_steps, vals, hist, rawv, rawh, code, mstat, n_steps, n_rhs)
            except BaseException:
                stopped.append(True)
                raise

    on_threads(work, [()] * min(threads, len(tasks)))
