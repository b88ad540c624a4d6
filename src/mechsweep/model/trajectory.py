"""The sampled-trajectory path of the model layer: Steady, Kick and History (measure.py) observe
ONE integration per point from ``initial(p)``, sampled on one grid of instants.

The grid is built in Python from the solver settings (``grid``): the union of the chosen
measurements' instants in forcing periods s, with a column of role bits per measurement; it is
the same for every point, so it does not depend on the point or on which other outputs are asked
for beyond adding rows (the integrators' steps do not depend on the sample instants: samples come
from the dense output; only the last instant, the horizon, ends the integration). Each point's
instants are t = T s, T = ``forcing_period(p)`` (after ``prepare``), or T = 1 for a model without
one.

The generated kernel (``kernel_source``; a module file in the cache folder, as compile.py's):

    for each block of BLOCK points (prange; strided), scratch: p, y, the method's workspace(s),
    the trajectory (n_samples x n_states), the observables:
        status = classify(p), prepare(p)      -> non-OK: that status, outputs NaN
        T = forcing(p) (or 1)                 -> not finite > 0: INFEASIBLE
        trajectory by the method              (auto: dop853 with the stiffness test; a stiff point
                                               again from initial(p) by radau, the costs added:
                                               the engine's one method switch for trajectories)
        for each measurement: its observable on its rows, then its generic jitted observer
        (steady_observe, kick_observe, or the history copy) -> its columns of the value table

Python's ``finish`` of each measurement turns the value columns into outputs and statuses
(NO_EVENT, UNDECIDED), as Floquet's does.
"""
from __future__ import annotations

import hashlib
import math

import numpy as np

from .. import status as st
from .. import _jit
from .._jit import jit
from . import load, sources
from .ode import worse

BLOCK = 8  # points per scratch allocation (a block holds one trajectory of n_samples x n_states)
METHODS = ("dop853", "radau", "auto")
TWO_PI = 2.0 * math.pi
_KERNELS: dict[str, object] = {}


def is_sampled(m) -> bool:
    return getattr(m, "sampled", False)


def grid(chosen, settings):
    """(s, bits, K, hist_rows): the sample instants in forcing periods (sorted, unique), bits[j, k]
    the roles of instant j for measurement k (0: not its instant), K[k] its constants, and for
    each History the number of its rows."""
    parts = [(m, inst) for m in chosen for inst in m.instants(settings)]
    s = np.unique(np.concatenate([x for _, (x, _) in parts]))
    bits = np.zeros((s.size, len(chosen)), dtype=np.int64)
    for k, m in enumerate(chosen):
        for x, b in m.instants(settings):
            rows = np.isin(s, x)
            bits[:, k] |= np.where(rows, b(s, settings) if callable(b) else b, 0)
    width = max([len(m.constants(settings)) for m in chosen] + [1])
    K = np.zeros((len(chosen), width))
    for k, m in enumerate(chosen):
        c = m.constants(settings)
        K[k, :len(c)] = c
    return s, bits, K


@jit
def steady_observe(ob, s, bits, K, out):
    """Steady: out = (peak, first-harmonic amplitude, phase lag, settled 1/0) from the observable
    ob on the rows with bit 1 (last window) and bit 2 (the window before); K = (settle_rtol (< 0:
    no check), settle_atol, harmonic wanted (0: amplitude and phase NaN, no cos/sin)). Returns OK
    or NONFINITE."""
    peak = 0.0
    prev = 0.0
    a = 0.0
    b = 0.0
    s_first = math.nan
    s_last = math.nan
    s_old = 0.0
    c_old = 0.0
    d_old = 0.0
    started = False
    for j in range(s.size):
        if bits[j] & 2:
            if not math.isfinite(ob[j]):
                return st.NONFINITE
            prev = max(prev, abs(ob[j]))
        if bits[j] & 1:
            x = ob[j]
            if not math.isfinite(x):
                return st.NONFINITE
            peak = max(peak, abs(x))
            c = 0.0
            d = 0.0
            if K[2] != 0.0:
                ph = TWO_PI * s[j]
                c = x * math.cos(ph)
                d = x * math.sin(ph)
            if started:
                a += 0.5 * (s[j] - s_old) * (c_old + c)
                b += 0.5 * (s[j] - s_old) * (d_old + d)
            else:
                s_first = s[j]
                started = True
            s_old = s[j]
            c_old = c
            d_old = d
            s_last = s[j]
    length = s_last - s_first
    a1 = 2.0 * a / length
    b1 = 2.0 * b / length
    out[0] = peak
    out[1] = math.sqrt(a1 * a1 + b1 * b1) if K[2] != 0.0 else math.nan
    out[2] = math.atan2(b1, a1) if K[2] != 0.0 else math.nan
    settled = True
    if K[0] >= 0.0:
        settled = abs(peak - prev) <= K[0] * max(peak, prev) + K[1]
    out[3] = 1.0 if settled else 0.0
    return st.OK


@jit
def kick_observe(e, r, has_r, t, bits, K, out):
    """Kick: out = (verdict 1 / 0 / NaN, settling time or NaN, final error) from the error e and
    the response r on the monitor rows (bit 1); bits 2 first period, 4 early, 8 late, 16 before
    late; K = (settle_threshold, decay_ratio, growth_ratio, growth_floor). Returns OK or NONFINITE."""
    settle, decay, growth = K[0], K[1], K[2]
    e0 = 0.0
    e_late = 0.0
    e_before = 0.0
    r_ref = 0.0
    r_late = 0.0
    last_above = -1
    k_prev = -1
    k_next = -1
    e_prev = 0.0
    e_last_above = 0.0
    e_next = 0.0
    for k in range(t.size):
        bk = bits[k]
        if not bk & 1:
            continue
        ek = e[k]
        rk = r[k] if has_r else 0.0
        if not (math.isfinite(ek) and math.isfinite(rk)):
            return st.NONFINITE
        if bk & 2:
            e0 = max(e0, ek)
        if bk & 4:
            r_ref = max(r_ref, rk)
        if bk & 8:
            e_late = max(e_late, ek)
            r_late = max(r_late, rk)
        elif bk & 16:
            e_before = max(e_before, ek)
        if ek > settle:
            last_above = k
            e_last_above = ek
        elif last_above >= 0 and last_above == k_prev:
            e_next = ek
            k_next = k
        e_prev = ek
        k_prev = k
    if last_above == k_prev:
        out[1] = math.nan  # never settled within the horizon
    elif last_above < 0:
        out[1] = 0.0
    else:  # linear interpolation of the last crossing of the threshold
        t0 = t[last_above]
        t1 = t[k_next]
        out[1] = t0 + (t1 - t0) * (e_last_above - settle) / (e_last_above - e_next)
    stable = e_late <= settle and e_late <= decay * e0 and r_late <= decay * r_ref
    stable = stable and (e_late <= e_before or e_late <= K[3])  # K[3]: by default 1e-3 settle
    unstable = e_late >= growth * e0 and e_before >= growth * e0
    out[0] = 1.0 if stable else (0.0 if unstable else math.nan)
    out[2] = e_prev
    return st.OK


def columns(chosen):
    cols, c = [], 0
    for m in chosen:
        cols.append(c)
        c += m.n_values
    return cols + [c]


def _obs_source(name, x, states):
    """A generated observable: a state read, or the guarded user function."""
    if isinstance(x, str):
        return f"@jit\ndef {name}(t, y, p):\n    return y[{states.index(x)}]\n\n"
    return (f"@jit\ndef {name}(t, y, p):\n    try:\n        return user_{name}(t, y, p)\n    except Exception:\n"
            f"        p[NPI] = 1.0\n        return np.nan\n\n")


def _val_source(name):
    """A generated guarded transform value(p, x) of a measured value (Steady/History ``value``,
    Kick ``time_value``)."""
    return (f"@jit\ndef {name}(p, x):\n    try:\n        return user_{name}(p, x)\n    except Exception:\n"
            f"        p[NPI] = 1.0\n        return np.nan\n\n")


def kernel_source(model, chosen, refs, method, always=-1, lock=(), raw=False) -> str:
    """``chosen``: every sampled measurement of the model (``sampled_measurements``); which of them
    observe is a run-time choice (``mstat``'s first value per column: UNUSED, NOT_RUN, NO_CLASSIFY;
    ``evaluate``). ``always``: the measurement that may be observed even where its classify skips
    it (a Recheck's skip_settled Kick: where K[always, -1] != 0 at run time); ``lock``: the
    per-state rates of the lock test (Recheck.skip_locked), its rows the last column of bits, its
    value the column after the measurements' (computed where vals has that column); ``raw``: the
    measured values also before value/time_value into rawv/rawh (where they have columns;
    Recheck.measured_units)."""
    from .compile import _GUARD, _guard_numbered, layout, rank_source

    n_p, n_set, n_int = layout(model)
    n_s = len(model.states)
    npi = n_p + n_set + n_int
    lines = [f'"""Generated by mechsweep.model.trajectory for model {model.name!r}, method {method}: one\n'
             'sampled trajectory per point. Do not edit: a changed model gets a new file."""\n'
             "import math\n\nimport numpy as np\n\n"
             "from mechsweep import status as st\n"
             "from mechsweep._jit import jit, pjit, prange\n"
             "from mechsweep.ode import dop853, radau\n"
             "from mechsweep.model.load import jitted\n"
             "from mechsweep.model.trajectory import kick_observe, steady_observe\n\n"]
    for name, ref in refs.items():
        lines.append(f"user_{name} = jitted{ref!r}\n")
    lines.append(f"\nNP = {n_p}\nNSET = {n_set}\nNPI = {npi}\nSCR = NPI + 1\nNS = {n_s}\nBLOCK = {BLOCK}\n"
                 f"NM = {len(chosen)}\nNOT_RUN = {NOT_RUN}\nUNUSED = {UNUSED}\nNO_CLASSIFY = {NO_CLASSIFY}\n\n")
    if lock:
        lines.append(f"LOCK_RATES = np.array({[float(x) for x in lock]!r})\nLOCKCOL = {columns(chosen)[-1]}\n\n")
    for name in refs:
        if name in _GUARD:
            lines.append(_GUARD[name] + "\n")
        elif name.startswith("mclassify"):
            lines.append(_guard_numbered(name) + "\n")
    lines.append(rank_source(_order(model)))
    if getattr(model, "switch_times", None) is not None:  # steps end on the switches (switches.SW: 2 slots of p)
        from .switches import source as switch_source
        lines.append(switch_source(model, "SCR + 3 * NS + 1", refs))
    fd_count = method in ("radau", "auto") and "jac" not in refs
    if fd_count:  # its rhs calls counted in p[SCR + 3 NS], added to n_rhs after the integration
        from .compile import _fd_jac
        lines.append(_fd_jac("jac", "rhs", count=True) + "\n")
    if method in ("dop853", "auto"):
        lines.append(f"traj_d = dop853.make_trajectory_solver(rhs, stiffness_test={method == 'auto'})\n")
    if method in ("radau", "auto"):
        lines.append("traj_r = radau.make_trajectory_solver(rhs, jac)\n")
    for k, m in enumerate(chosen):
        kind = type(m).__name__
        if kind == "Kick":
            lines.append(_obs_source(f"error{k}", m.error, model.states))
            if m.response is not None:
                lines.append(_obs_source(f"response{k}", m.response, model.states))
        else:
            lines.append(_obs_source(f"of{k}", m.of, model.states))
        if f"value{k}" in refs:
            lines.append(_val_source(f"value{k}"))
    body = _observe_body(chosen, refs, _order(model), always, bool(lock), raw)
    OBSERVE[:] = [b.replace("\n            ", "\n    ") for b in body]
    lane_rhs = lane_rhs_for(model, method)
    lines.append(_lanes_source(model, chosen, refs, lane_rhs) if lane_rhs else "")
    order = _order(model)
    return _kernel_tail(lines, body, refs, method, _measurement_checks(chosen, refs, order, 12),
                        _failed(order, 16), getattr(model, "switch_times", None) is not None)


def _failed(order, indent: int) -> str:
    """Kernel code after a failed integration (status c): every measurement not skipped gets c."""
    from .compile import combine
    pad = " " * indent
    return (f"\n{pad}for k in range(NM):\n{pad}    if mstat[i, k] == st.OK:\n{pad}        mstat[i, k] = c"
            + combine(order, "code", "c", indent))


def _order(model) -> tuple:
    return tuple(getattr(model, "status_order", ()))


def _observe_body(chosen, refs, order, always=-1, lock=False, raw=False) -> list[str]:
    """Kernel code: every measurement's observables on its rows and its observer (12 spaces
    indent; reads te, traj, p, s, bits, K, hoff, ob, ob2; writes vals[i], hist[i], mstat[i], code).
    A measurement is observed only where it is chosen and applies (mstat[i, k] == OK after the
    checks: an unchosen one (UNUSED) costs one test per point, nothing per sample); the
    ``always`` one also where its classify skipped it, when K[always, -1] != 0 (its status only
    where it applies)."""
    from .compile import combine
    cols = columns(chosen)
    body = []
    for k, m in enumerate(chosen):
        kind = type(m).__name__
        # the measurement's transform of its values (value(p, x) / time_value(p, t)): the
        # columns it applies to (Steady: peak and first harmonic; Kick: the settling time)
        fn = getattr(m, "time_value", None) if kind == "Kick" else getattr(m, "value", None)
        transform = ""
        if raw and kind != "History":  # the measured values, before the transform
            transform = f"""
            if rawv.shape[1] != 0:
                for q in range({cols[k]}, {cols[k + 1]}):
                    rawv[i, q] = vals[i, q]"""
        if fn is not None and kind != "History":
            first, last = (cols[k], cols[k] + 2) if kind == "Steady" else (cols[k] + 1, cols[k] + 2)
            transform += f"""
            if c == st.OK:
                for q in range({first}, {last}):
                    if math.isfinite(vals[i, q]):
                        vals[i, q] = value{k}(p, vals[i, q])"""
        if kind == "Steady":
            obs = f"""
            for j in range(ns_):
                if bits[j, {k}]:
                    ob[j] = of{k}(te[j], traj[j], p)
            c = steady_observe(ob, s, bits[:, {k}], K[{k}], vals[i, {cols[k]}:{cols[k + 1]}])""" + transform
        elif kind == "Kick":
            has_r = m.response is not None
            obs = f"""
            for j in range(ns_):
                if bits[j, {k}]:
                    ob[j] = error{k}(te[j], traj[j], p)""" + (f"""
                    ob2[j] = response{k}(te[j], traj[j], p)""" if has_r else "") + f"""
            c = kick_observe(ob, ob2, {has_r}, te, bits[:, {k}], K[{k}], vals[i, {cols[k]}:{cols[k + 1]}])
            vals[i, {cols[k] + 3}] = vals[i, {cols[k] + 1}]  # the settling time before time_value
            vals[i, {cols[k] + 4}] = te[ns_ - 1]  # the simulated time""" + transform
        else:  # History: its rows in order into hist[i, offset ...]
            value = f"""
                    if math.isfinite(v):
                        v = value{k}(p, v)""" if fn is not None else ""
            raw_h = """
                    if raw_h:
                        rawh[i, h] = v""" if raw else ""
            obs = ("""
            raw_h = rawh.shape[1] != 0""" if raw else "") + f"""
            c = st.OK
            h = hoff[{k}]
            for j in range(ns_):
                if bits[j, {k}]:
                    v = of{k}(te[j], traj[j], p){raw_h}{value}
                    if not math.isfinite(v):
                        c = st.NONFINITE
                    hist[i, h] = v
                    h += 1"""
        if k == always and f"mclassify{k}" in refs:  # observed everywhere; its status only where it applies
            inner = (obs + f"""
            if mstat[i, {k}] == st.OK:
                mstat[i, {k}] = c""" + combine(order, "code", "c", 16)).replace("\n", "\n    ")
            body.append(f"""
            if mstat[i, {k}] == st.OK or (mstat[i, {k}] != UNUSED and K[{k}, K.shape[1] - 1] != 0.0):{inner}""")
            continue
        inner = (obs + f"""
            mstat[i, {k}] = c""" + combine(order, "code", "c", 12)).replace("\n", "\n    ")
        body.append(f"""
            if mstat[i, {k}] == st.OK:{inner}""")
    if lock:  # the largest change of the state over one forcing period (bits[:, NM]: whole periods)
        body.append("""
            if vals.shape[1] > LOCKCOL:  # the lock test asked for (a re-check that skips locked points)
                lock = 0.0
                kr = -1
                nrev = 0
                for j in range(ns_):
                    if bits[j, NM]:
                        if kr >= 0:
                            for q in range(NS):
                                dz = traj[j, q] - traj[kr, q]
                                if LOCK_RATES[q] != 0.0:
                                    dz -= LOCK_RATES[q] * (te[j] - te[kr])
                                if not abs(dz) <= lock:  # NaN propagates
                                    lock = abs(dz)
                        kr = j
                        nrev += 1
                vals[i, LOCKCOL] = lock if nrev >= 2 else math.inf""")
    return body


def _measurement_checks(chosen, refs, order, indent: int) -> str:
    """Kernel code run before a point's integration: each chosen measurement's classify (where
    declared) into mstat[i, k] (-status where it does not apply: skipped) and folded into
    ``code``; ``go``: whether any measurement is left to observe (else the point is not
    integrated). Which measurements are chosen is mstat[i, k]'s value before: UNUSED (not chosen:
    left so), NOT_RUN (chosen), NO_CLASSIFY (chosen, its classify not applied: a Recheck's
    skip_settled Kick observed although none of its outputs is asked for)."""
    from .compile import combine
    pad = " " * indent
    out = f"\n{pad}code = st.OK\n{pad}go = False"
    for k in range(len(chosen)):
        if f"mclassify{k}" in refs:
            out += (f"\n{pad}if mstat[i, {k}] == NOT_RUN:\n{pad}    c = mclassify{k}(p)\n{pad}    if c != st.OK:"
                    f"\n{pad}        mstat[i, {k}] = -c" + combine(order, "code", "c", indent + 8)
                    + f"\n{pad}    else:\n{pad}        mstat[i, {k}] = st.OK\n{pad}        go = True"
                    f"\n{pad}elif mstat[i, {k}] == NO_CLASSIFY:\n{pad}    mstat[i, {k}] = st.OK\n{pad}    go = True")
        else:
            out += f"\n{pad}if mstat[i, {k}] != UNUSED:\n{pad}    mstat[i, {k}] = st.OK\n{pad}    go = True"
    return out


def _kernel_tail(lines, body, refs, method, checks="", fail="", switched=False) -> str:
    if method == "dop853":
        integrate = """
            c, a, b_ = traj_d(0.0, y, p, te, rtol, atol, 0.0, max_steps, work, traj)"""
    elif method == "radau":
        integrate = """
            c, a, b_ = traj_r(0.0, y, p, te, rtol, atol, 0.0, max_steps, rwork, traj)"""
    else:
        integrate = """
            c, a, b_ = traj_d(0.0, y, p, te, rtol, atol, 0.0, max_steps, work, traj)
            if c == st.STIFF:  # a stiff point starts again with radau; the costs add up
                initial(p, y)
                c, a2, b2 = traj_r(0.0, y, p, te, rtol, atol, 0.0, max_steps, rwork, traj)
                a += a2
                b_ += b2"""
    scratch = "\n        work = dop853.workspace(NS)" if method != "radau" else ""
    scratch += "\n        rwork = radau.workspace(NS)" if method != "dop853" else ""
    classify, prepare = _point_checks(refs, 12)
    forcing = "forcing(p)" if "forcing" in refs else "1.0"
    fd_add = ("\n            n_rhs[i] += int(p[SCR + 3 * NS])  # the rhs calls of the engine's Jacobian"
              if method in ("radau", "auto") and "jac" not in refs else "")
    clamp_reset = "\n            switch_clamp(p, -math.inf, math.inf)" if switched else ""
    lines.append(f"""

@pjit
def kernel(P, S, s, bits, K, hoff, rtol, atol, max_steps, vals, hist, rawv, rawh, status, mstat, n_steps, n_rhs):
    n = P.shape[0]
    ns_ = s.size
    n_blocks = (n + BLOCK - 1) // BLOCK
    for blk in prange(n_blocks):
        p = np.empty(SCR + 3 * NS + 1{" + 2" if switched else ""})
        y = np.empty(NS)
        te = np.empty(ns_)
        ob = np.zeros(ns_)
        ob2 = np.zeros(ns_)
        traj = np.empty((ns_, NS)){scratch}
        for i in range(blk, n, n_blocks):
            if status[i] != st.OK:
                continue
            for j in range(NP):
                p[j] = P[i, j]
            for j in range(NSET):
                p[NP + j] = S[j]
            for j in range(NP + NSET, p.size):
                p[j] = 0.0{clamp_reset}{classify}{prepare}
            T = {forcing}
            if not (math.isfinite(T) and T > 0.0):
                status[i] = st.INFEASIBLE
                continue
{checks}
            if not go:  # no measurement applies here: not integrated
                status[i] = code
                continue
            for j in range(ns_):
                te[j] = T * s[j]
            initial(p, y){integrate}
            n_steps[i] += a
            n_rhs[i] += b_{fd_add}
            if c != st.OK:
                if p[NPI] != 0.0:  # the model's code raised (its guard wrote NaN): USER_ERROR, not NONFINITE
                    c = st.USER_ERROR{fail}
                status[i] = code
                continue{''.join(body)}
            if p[NPI] != 0.0:
                code = st.USER_ERROR
            status[i] = code
""")
    return "".join(lines)


def _point_checks(refs, indent: int) -> tuple[str, str]:
    """Kernel code of the model's classify and prepare (each where declared) at ``indent`` spaces:
    a point they do not pass gets their status and is left."""
    def check(call):
        pad = " " * indent
        return (f"\n{pad}c = {call}\n{pad}if c != st.OK:\n{pad}    status[i] = c\n{pad}    continue")
    return (check("classify(p)") if "classify" in refs else "",
            check("prepare(p, rtol)") if "prepare" in refs else "")


def lane_rhs_for(model, method) -> str | None:
    """The engine's lane form of the model's rhs (model/lanes.py's rewrite) for dop853, or None
    (another method, or an rhs the rewrite does not cover: one trajectory at a time)."""
    if method != "dop853" or getattr(model, "switch_times", None) is not None:  # switches: one at a time
        return None
    from .lanes import lane_rhs_source
    return lane_rhs_source(model.rhs)


def _lanes_source(model, chosen, refs, lane_rhs) -> str:
    """The DOP853 lanes path (dop853, an rhs the engine rewrites in lane form: ``lane_rhs``, the
    source of ``rhs_lanes``): ``setup`` prepares every point
    (p, status, T, initial state), ``queue`` runs a queue of points of one forcing
    period through ``dop853_lanes`` and observes each trajectory as it ends (the same observers,
    the same floats as the one-trajectory kernel: the lanes give dop853's steps bitwise)."""
    classify, prepare = _point_checks(refs, 8)
    forcing = "forcing(p)" if "forcing" in refs else "1.0"
    order = _order(model)
    checks = _measurement_checks(chosen, refs, order, 8)
    fail = _failed(order, 12).replace("code", "cc")
    return f"""

from mechsweep._jit import jit_noalloc
from mechsweep.ode import dop853_lanes

{lane_rhs}

lane_load, lane_run = dop853_lanes.make_lane_trajectory_solver(rhs_lanes, rhs)


@jit
def setup(P, S, rtol, PF, Z0, TT, status, mstat):
    # serial: a parallel region just before the lane queues (Python threads) may leave the threading
    # layer's workers spinning while they run (two threads: 0.93 of the hand-written kernels with it
    # parallel, 0.95-0.99 serial, side by side; docs/model-layer.md)
    n = P.shape[0]
    for i in range(n):
        if status[i] != st.OK:
            continue
        p = PF[i]
        for j in range(NP):
            p[j] = P[i, j]
        for j in range(NSET):
            p[NP + j] = S[j]
        for j in range(NP + NSET, p.size):
            p[j] = 0.0{classify}{prepare}
        T = {forcing}
        if not (math.isfinite(T) and T > 0.0):
            status[i] = st.INFEASIBLE
            continue{checks}
        status[i] = code
        if not go:  # no measurement applies here: not integrated (TT stays NaN)
            continue
        TT[i] = T
        initial(p, Z0[i])


@jit
def observe(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, status):
    ns_ = s.size
    code = status[i]{''.join(OBSERVE)}
    if p[NPI] != 0.0:
        code = st.USER_ERROR
    return code


@jit
def queue(lanes, idx, first, step, PF, Z0, te, s, bits, K, hoff, rtol, atol, max_steps, vals, hist, rawv, rawh,
          status, mstat, n_steps, n_rhs):
    ws = dop853_lanes.workspace(NS, PF.shape[1], lanes, te.size)
    traj = ws[dop853_lanes.TRAJ]
    ob = np.zeros(s.size)
    ob2 = np.zeros(s.size)
    nxt = first
    m = idx.size
    for lane in range(lanes):
        if nxt < m:
            lane_load(ws, lane, nxt, 0.0, Z0[idx[nxt]], PF[idx[nxt]], te, rtol, atol)
            nxt += step
        else:
            dop853_lanes.idle(ws, lane)
    while True:
        lane = lane_run(ws, te, rtol, atol, max_steps)
        if lane < 0:
            return
        j, c, a, b_ = dop853_lanes.lane_result(ws, lane)
        i = idx[j]
        if c == st.OK:
            c = observe(i, PF[i], te, traj[lane], s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2, mstat, status)
        else:
            if PF[i, NPI] != 0.0:  # the model's code raised (its guard wrote NaN): USER_ERROR, not NONFINITE
                c = st.USER_ERROR
            cc = status[i]{fail}
            c = cc
        status[i] = c
        n_steps[i] += a
        n_rhs[i] += b_
        if nxt < m:
            lane_load(ws, lane, nxt, 0.0, Z0[idx[nxt]], PF[idx[nxt]], te, rtol, atol)
            nxt += step
        else:
            dop853_lanes.idle(ws, lane)
"""


OBSERVE: list[str] = []  # set by kernel_source for _lanes_source (the observation body, 4 spaces indent)


def sampled_measurements(model) -> tuple:
    """Every sampled measurement the model declares, in declaration order: the kernel's columns."""
    return tuple(m for m in model.measurements if is_sampled(m))


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
    """The model's one sampled-trajectory kernel for ``method``: every sampled measurement it
    declares (or only ``measurements``, the model's own, in their order: a kernel per subset, as
    before; for comparison), the ones that observe chosen per call (``evaluate``), as the closed
    forms are (one kernel per model and method, whatever subset of outputs is asked for)."""
    from .compile import load_generated

    chosen = sampled_measurements(model) if measurements is None else tuple(measurements)
    name, refs, always, lock, raw = _module_name(model, method, chosen)
    if name not in _KERNELS:
        _KERNELS[name] = load_generated(name, kernel_source(model, chosen, refs, method, always, lock, raw))
    return _KERNELS[name]


def _module_name(model, method, chosen):
    """(module name of the kernel of the sampled measurements ``chosen``, the function references, and
    the re-check's variant: always, lock, raw)."""
    from .compile import _functions

    always, lock, raw = recheck_variant(model, chosen)
    funcs = [(n, f) for n, f in _functions(model, (), ()) if n in ("rhs", "initial", "forcing", "jac", "classify",
                                                                      "prepare", "switch_times")]
    for k, m in enumerate(chosen):
        for role, func in m.functions():
            funcs.append((f"{role}{k}", func))
        if getattr(m, "classify", None) is not None:
            funcs.append((f"mclassify{k}", m.classify))
    refs = {name: load.function_ref(func, name, model.name) for name, func in funcs}
    key = hashlib.sha256()
    for name, ref in refs.items():
        key.update(name.encode())
        key.update(repr(ref).encode())
        key.update(load.module_source(ref[0], ref[1]))
    key.update(sources.record(model).digest.encode())  # the user modules the model imports, recursively
    key.update((lane_rhs_for(model, method) or "").encode())  # its helpers may live in other modules
    from .compile import _switch_key
    key.update(_switch_key(model).encode())
    key.update(repr((model.name, _layout(model), len(model.states), tuple(m.key() for m in chosen), method,
                     _order(model), always, tuple(lock), raw)).encode())
    return "mechsweep_traj_" + key.hexdigest()[:20], refs, always, lock, raw


def lane_name(model, method) -> str | None:
    """The name under which the lanes of the model's one sampled-trajectory kernel for ``method`` are
    recorded once compiled (compile.lanes_recorded), or None when the lanes do not apply (another
    method, an rhs the rewrite does not cover: one trajectory at a time)."""
    if lane_rhs_for(model, method) is None:
        return None
    memo = (id(model), method)
    known = _LANE_NAMES.get(memo)
    if known is not None and known[0] is model:
        return known[1]
    name = _module_name(model, method, sampled_measurements(model))[0] + ".lanes"
    _LANE_NAMES[memo] = (model, name)
    return name


_LANE_NAMES: dict[tuple, tuple] = {}  # lane_name's memo: (model, name) by (id(model), method)


def _layout(model):
    from .compile import layout
    return layout(model)


def evaluate(model, chosen, P, wanted, solver, out, status, n_steps, n_rhs, lanes=None, per_subset=False):
    """Run the sampled measurements ``chosen`` on the points still OK in ``status``; with ``lanes`` by
    DOP853 lanes for dop853 when the engine rewrites the model's rhs in lane form (False: one trajectory
    at a time, the same values; None: as USE_LANES says, one at a time unless it is True). The model's one kernel (``kernel_for``) observes only the chosen ones;
    ``per_subset``: a kernel of the chosen ones alone instead (a compile per subset; the same values
    bitwise, for tests)."""
    method = solver.method
    settings = dict(solver.settings)
    rc = _active_recheck(model, settings)
    always, lock, raw = -1, (), False
    if rc is not None and rc.skip_settled is not None:  # its Kick observed everywhere, asked for or not
        names = [m.name for m in chosen]
        if rc.skip_settled not in names:
            import dataclasses
            kick = next(m for m in model.measurements if m.name == rc.skip_settled)
            chosen = tuple(chosen) + (dataclasses.replace(kick, classify=None),)
        always = [m.name for m in chosen].index(rc.skip_settled)
        if rc.skip_locked:
            rates = dict(rc.lock_rates)
            lock = tuple(float(rates.get(x, 0.0)) for x in model.states)
        raw = bool(rc.measured_units)
    s, bits, K = grid(chosen, settings)
    if lock:  # the whole forcing periods of the second half of the Kick's horizon: one more bits column
        from .measure import _number
        H = _number(chosen[always].horizon, settings)
        whole = np.arange(math.ceil(0.5 * H), math.floor(H) + 1, dtype=np.float64)
        s2 = np.unique(np.concatenate([s, whole]))
        bits2 = np.zeros((s2.size, bits.shape[1] + 1), dtype=np.int64)
        bits2[np.searchsorted(s2, s), :bits.shape[1]] = bits
        bits2[:, -1] = np.isin(s2, whole)
        s, bits = s2, bits2
    for k, m in enumerate(chosen):
        if type(m).__name__ == "Steady" and not {m.output_name("_h1"), m.output_name("_phase")} & set(wanted):
            K[k, 2] = 0.0  # no first harmonic asked for: the observer skips its cos/sin per sample
    hoff = np.zeros(len(chosen), dtype=np.int64)
    n_hist = 0
    for k, m in enumerate(chosen):
        if m.n_values == 0:
            hoff[k] = n_hist
            n_hist += int(np.count_nonzero(bits[:, k]))
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
    order = _order(model)
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
        from .compile import record_compiled
        record_compiled(mod.__name__ + ".lanes")
    moved = None
    if rc is not None:
        moved = _recheck(rc, chosen, wanted, settings, solver, P, run, (vals, hist, rawv, rawh), code, mstat, n_steps,
                         n_rhs, cols, bits, order, lock)
    good = measured(mstat, code, order)
    for k, m in enumerate(chosen):
        if m.n_values == 0:
            if m.name in out:
                w = int(np.count_nonzero(bits[:, k]))
                out[m.name][:] = np.where(good[:, k, None], hist[:, hoff[k]:hoff[k] + w], np.nan)
        else:
            v = np.where(good[:, k, None], vals[:, cols[k]:cols[k + 1]], np.nan)
            if order:  # its own status (OK where it has values), ranked into the point's
                own = np.zeros_like(code)
                m.finish(v, wanted, solver, out, own)
                code[:] = worse(code, own, order)
            else:
                m.finish(v, wanted, solver, out, code)
    if moved is not None and order:
        code[:] = worse(code, np.where(moved, st.NOT_REPRODUCIBLE, st.OK), order)
    elif moved is not None:  # above the statuses that leave a value NaN for a reason, below failures
        soft = (code == st.OK) | (code == st.NO_EVENT) | (code == st.UNDECIDED)
        code[:] = np.where(moved & soft, st.NOT_REPRODUCIBLE, code)
    status[:] = code


NOT_RUN = 127  # mstat before a point's measurements ran (a status no measurement gives)
UNUSED = 126  # mstat of a measurement not chosen (the kernel leaves it)
NO_CLASSIFY = 125  # mstat before the kernel of a chosen measurement whose classify is not applied


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
    from .measure import _number
    rc = getattr(model, "recheck", None)
    if rc is None or not _number(rc.factor, settings) > 0.0:
        return None
    return rc


def _compared(chosen, wanted, cols, bits, width):
    """(value columns, History columns) the re-check compares: those of the asked-for outputs (a
    Steady's or Kick's j-th output is its j-th column)."""
    use = np.zeros(width, dtype=bool)
    huse = []
    for k, m in enumerate(chosen):
        if m.n_values == 0:
            huse += [m.name in wanted] * int(np.count_nonzero(bits[:, k]))
            continue
        for j, o in enumerate(m.outputs()):
            use[cols[k] + j] = o.name in wanted
    return use, np.array(huse, dtype=bool)


def _recheck(rc, chosen, wanted, settings, solver, P, run, arrays, code, mstat, n_steps, n_rhs, cols, bits, order,
             lock):
    """The model's Recheck (measure.Recheck): which points moved when integrated again at the
    tighter rtol."""
    from .measure import _number
    vals, hist, rawv, rawh = arrays
    factor = _number(rc.factor, settings)
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
    vals2 = np.full((idx.size, vals.shape[1]), np.nan)
    hist2 = np.full((idx.size, hist.shape[1]), np.nan)
    rawv2 = np.full((idx.size, rawv.shape[1]), np.nan)
    rawh2 = np.full((idx.size, rawh.shape[1]), np.nan)
    code2 = np.zeros(idx.size, dtype=code.dtype)
    mstat2 = np.full((idx.size, mstat.shape[1]), NOT_RUN, dtype=mstat.dtype)
    ns2, nr2 = np.zeros(idx.size, dtype=n_steps.dtype), np.zeros(idx.size, dtype=n_rhs.dtype)
    run(P2, rc.tight_rtol(solver.rtol), vals2, hist2, rawv2, rawh2, code2, mstat2, ns2, nr2)
    n_steps[idx] += ns2
    n_rhs[idx] += nr2
    # the asked-for outputs where their measurement applies, as stored (after value/time_value) or
    # as measured (measured_units)
    use, huse = _compared(chosen, wanted, cols, bits, cols[-1])
    if rc.measured_units:
        vals, hist, vals2, hist2 = rawv, rawh, rawv2, rawh2

    def table(v, h, good):
        cv = [np.where(good[:, k, None], v[:, cols[k]:cols[k + 1]], np.nan) for k in range(len(chosen))]
        hh = np.full(h.shape, np.nan)
        pos = 0
        for k, m in enumerate(chosen):  # each History's own columns from its own mask
            if m.n_values == 0:
                w = int(np.count_nonzero(bits[:, k]))
                hh[:, pos:pos + w] = np.where(good[:, k, None], h[:, pos:pos + w], np.nan)
                pos += w
        return np.concatenate(cv + [np.empty((v.shape[0], 0))], axis=1)[:, use], hh[:, huse]

    a1, a2 = table(vals[idx], hist[idx], measured(mstat[idx], code[idx], order))
    b1, b2 = table(vals2, hist2, measured(mstat2, code2, order))
    a = np.concatenate([a1, a2], axis=1)
    b = np.concatenate([b1, b2], axis=1)
    with np.errstate(invalid="ignore"):
        tol = factor * (solver.rtol * np.maximum(np.abs(a), np.abs(b)) + solver.atol)
        bad = (np.abs(a - b) > tol) | (np.isnan(a) != np.isnan(b))
    moved[idx] = bad.any(axis=1) | ~integrated(mstat2, code2)
    return moved


# The lanes (method dop853, an rhs the engine rewrites in lane form): as the hand-written auto-balancer kernels
# chose them. Each lane keeps its trajectory's samples (n_samples x n_states floats) until it
# ends: with long horizons or dense sampling fewer lanes, so that a queue's samples stay within
# LANE_SAMPLES_BYTES (32, 16, then 8 lanes, else the one-trajectory kernel).
LANES = (32, 16, 8)
LANE_SAMPLES_BYTES = 256 * 2**20
# evaluate's route where the lanes apply and the caller names none: True the lanes, False or None one
# trajectory at a time. A run names the route its plan chose (mechsweep/plan.py, ``choose_route``, which
# reads this as an override): the lanes for a run of at least LANES_FROM_POINTS points, or once they are
# compiled (compile.lanes_recorded, under ``lane_name``). Bitwise the same results either way. The lanes'
# cold compile and speed: docs/model-layer.md ("Lanes"; tests/data/trajectory_lanes_cost.py).
USE_LANES: bool | None = None
LANES_FROM_POINTS = 1000
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


def _run_lanes(mod, model, P, S, s, bits, K, hoff, solver, vals, hist, rawv, rawh, code, mstat, n_steps, n_rhs,
               rtol=None):
    """setup, then per forcing period the points' queues through the lanes, one queue per thread
    (numba.get_num_threads() Python threads running the nogil queue); the points of periods shared
    by fewer than LANE_GROUP_MIN points by the one-trajectory kernel (from their status before
    setup: it runs classify and prepare again)."""
    from .compile import layout

    n = P.shape[0]
    n_s = len(model.states)
    n_p, n_set, n_int = layout(model)
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
    for T in periods[counts >= LANE_GROUP_MIN]:
        idx = np.flatnonzero(ok & (TT == T)).astype(np.int64)
        te = T * s  # the same products as the one-trajectory kernel's te[j] = T * s[j]
        n_queues = max(1, min(_jit.num_threads(), -(-idx.size // max(1, lanes // 2))))

        def queue(b, idx=idx, te=te, n_queues=n_queues):
            mod.queue(lanes, idx, b, n_queues, PF, Z0, te, s, bits, K, hoff, rtol, solver.atol,
                      solver.max_steps, vals, hist, rawv, rawh, code, mstat, n_steps, n_rhs)

        if n_queues == 1:
            queue(0)
            continue
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=n_queues, thread_name_prefix="mechsweep-lanes") as pool:
            for _ in pool.map(queue, range(n_queues)):
                pass
