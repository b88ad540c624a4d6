"""The shared trajectory of the one-point kernel: Crossing, Period, StateAt and Extremum of a point
observe ONE DOP853 integration from t = 0 (``make_shared``); each is a row of a float table
(model/measure.py ``shared_row``: kind, state index, sign, level, n, ta, tb)."""
from __future__ import annotations

import functools
import math

import numpy as np

from .. import status as st_
from .._jit import jit, jit_into_caller
from ..model.measure import K_CROSSING, K_EXTREMUM, K_EXTREMUM_OF, K_PERIOD, K_STATE_AT
from ..model.switches import SIDE as _SIDE
from ..ode import dop853
from ..ode._common import ROOT_RTOL, make_brent


def rows(plan) -> tuple:
    """The rows of the kernel's shared measurements (plan.group), in order; an expression's row
    (K_EXTREMUM_OF) carries its measurement's index, which ``observer`` dispatches on."""
    out = []
    for k in plan.group:
        row = list(plan.chosen[k].shared_row(plan.model.states))
        if _expression(plan.chosen[k]) is not None:
            row[1] = float(k)
        out.append(tuple(row))
    return tuple(out)


def _expression(m):
    """An Extremum's expression f(t, y, p) (None for a state's row)."""
    x = getattr(m, "state", None)
    return x if callable(x) and not isinstance(x, str) else None


def integration(plan):
    """The link that integrates the shared trajectory before the measurements read it: initial(p, y),
    the windows given by functions of p into the rows (M[j, 5], M[j, 6]), then ``make_shared``."""
    view = plan.view
    exprs = tuple((k, view.fn(_expression(plan.chosen[k]), f"of{k}", "t,y,p")) for k in plan.group
                  if _expression(plan.chosen[k]) is not None)
    windows = []
    for j, k in enumerate(plan.group):
        for col, role in ((5, "t0"), (6, "t1")):
            f = getattr(plan.chosen[k], role, None)
            if callable(f):
                windows.append((j, col, view.fn(f, f"{role}{k}", "p")))
    fns = plan.switch_fns
    sw = None if fns is None else (fns[1], fns[0], fns[2])
    shared = make_shared(plan.equation().rhs, observer(exprs) if exprs else None, sw)
    return _integration(plan.initial, _windows(tuple(windows)), shared)


@functools.cache
def observer(exprs: tuple):
    """``observe(t, y, p, j)``: the expression of shared row j (``exprs``: (j, f) pairs), NaN for none."""
    if not exprs:
        @jit_into_caller
        def nothing(t, y, p, j):
            return math.nan
        return nothing
    (k, f), rest = exprs[0], observer(exprs[1:])

    @jit_into_caller
    def observe(t, y, p, j):
        if j == k:
            return f(t, y, p)
        return rest(t, y, p, j)

    return observe


@functools.cache
def _windows(windows: tuple):
    """``set(p, M)``: the window ends that are functions of p into the rows."""
    if not windows:
        @jit_into_caller
        def nothing(p, M):
            pass
        return nothing
    (j, col, f), rest = windows[0], _windows(windows[1:])

    @jit_into_caller
    def set_window(p, M):
        M[j, col] = f(p)
        rest(p, M)

    return set_window


@functools.cache
def _integration(initial, windows, shared):
    @jit_into_caller
    def link(i, p, y, rtol, atol, max_steps, ws, table, cv, n_steps, n_rhs, code):
        initial(p, y)
        M = ws[3]
        windows(p, M)
        a, b = shared(y, p, M, rtol, atol, max_steps, ws[0], ws[1], ws[2])
        n_steps[i] += a
        n_rhs[i] += b
        return code

    return link


def member(plan, k):
    """The block of shared measurement k: its status and value from the shared integration."""
    return _member(plan.group.index(k))


@functools.cache
def _member(j):
    @jit_into_caller
    def block(i, p, y, rtol, atol, max_steps, ws, table, n_steps, n_rhs):
        return ws[2][j], ws[1][j]

    return block


@functools.cache
def make_shared(rhs, observe=None, switches=None):
    """Jitted ``shared(y, p, M, rtol, atol, max_steps, work, values, codes) -> (n_steps, n_rhs)``:
    every measurement row of ``M`` (see ``shared_row``) observes one DOP853 integration from
    t = 0 (y: the initial state on entry, scratch after). The integration runs towards the
    largest time any row needs and stops as soon as every row is done. No step is forced to land
    on a measurement's time: values inside a step come from the step's 7th-order dense output
    (built at most once per step, 3 rhs calls), roots from Brent's method on it. Only the horizon
    clips the last step. ``max_steps`` bounds the shared integration; a failure gives its status
    to every row not yet done (rows done before keep their values); a spent budget is STIFF where
    dop853's stiffness test fired on its last steps, as dop853's solvers report it.

    ``observe(t, y, p, j) -> float`` (``observer``): the expression of an Extremum row
    of kind K_EXTREMUM_OF (column 1: j). Its rate along the trajectory is the central difference
    (f(t + e, y + e F) - f(t - e, y - e F)) / 2e, F = rhs(t, y), e = cbrt(eps) |h| (the step's
    size h as the time scale). An Extremum row whose window is not finite 0 <= t0 < t1 (a window
    given as a function of p) gets INFEASIBLE.

    ``switches``: (next_switch, switch_check, switch_clamp) of a model's declared switch times
    (engine/switches.py): every step then ends on each switch, f is evaluated again there on the far
    side (1 rhs call, counted) and the step size carries on; a point whose switch times are not valid
    gives switch_check's status to every row. None: exactly the integration without them."""
    d = dop853

    start = d._make_start(rhs)
    advance = d._make_advance(rhs)
    dense_output = d._make_dense_output(rhs)
    interpolate = d._interpolate
    commit = d._commit
    failure, tests_stiffness, stiffness_update = d._failure, d._tests_stiffness, d._stiffness_update
    Y_STAGE, Y_NEW, K_FSAL = d.Y_STAGE, d.Y_NEW, d.K_FSAL
    N_ST = d.N_STAGES
    N_DENSE = d.N_STAGES_EXTENDED - d.N_STAGES - 1
    OK, NO_EVENT, INFEASIBLE, NONFINITE = st_.OK, st_.NO_EVENT, st_.INFEASIBLE, st_.NONFINITE
    CBRT_EPS = 6.055454452393343e-06
    if switches is None:
        has_sw = False

        @jit
        def nxt(t, p):
            return math.inf

        @jit
        def check(p):
            return 0

        @jit
        def clamp(p, lo, hi):
            pass
    else:
        has_sw = True
        nxt, check, clamp = switches
    SIDE = _SIDE

    if observe is None:  # state rows only: the value and the rate are components of y and of the rhs
        @jit
        def value_of(t, y, p, idx, expr):
            return y[idx]

        @jit
        def rate_of(t, y, p, F, idx, expr, h, yt):
            return F[idx]
    else:
        @jit
        def value_of(t, y, p, idx, expr):
            if expr:
                return observe(t, y, p, idx)
            return y[idx]

        @jit
        def rate_of(t, y, p, F, idx, expr, h, yt):
            if not expr:
                return F[idx]
            e = CBRT_EPS * abs(h)
            up = t + e
            dn = t - e
            for i in range(y.size):
                yt[i] = y[i] + (up - t) * F[i]
            fu = observe(up, yt, p, idx)
            for i in range(y.size):
                yt[i] = y[i] + (dn - t) * F[i]
            return (fu - observe(dn, yt, p, idx)) / (up - dn)

    @jit
    def g_on_interpolant(t, ctx):
        t_old, h, y_old, p, work, idx, sign, level, turn, fs, expr, yt, calls = ctx
        y_at = work[Y_STAGE]  # free once the dense output is built
        interpolate((t - t_old) / h, y_old, work, y_at)
        if turn:
            rhs(t, y_at, p, fs)
            calls[0] += 1  # the caller adds them to n_rhs
            return sign * rate_of(t, y_at, p, fs, idx, expr, h, yt)
        return sign * (y_at[idx] - level)

    brent = make_brent(g_on_interpolant)

    @jit
    def shared(y, p, M, rtol, atol, max_steps, work, values, codes):
        m = M.shape[0]
        n = y.size
        ya = np.empty(n)
        fa = np.empty(n)
        yt = np.empty(n)
        calls = np.zeros(1, dtype=np.int64)  # rhs calls inside a turning point's root search
        g_old = np.zeros(m)
        count = np.zeros(m)
        t_first = np.zeros(m)
        best = np.zeros(m)
        started = np.zeros(m, dtype=np.bool_)
        done = np.zeros(m, dtype=np.bool_)
        t_end = 0.0
        left = m
        for i in range(m):
            values[i] = math.nan
            codes[i] = OK
            if M[i, 0] >= K_EXTREMUM and not (0.0 <= M[i, 5] < M[i, 6] and M[i, 6] < math.inf):
                codes[i] = INFEASIBLE  # a window from functions of p that is not one
                done[i] = True
                left -= 1
                continue
            t_end = max(t_end, M[i, 6] if M[i, 0] >= K_EXTREMUM else M[i, 5])
        if left == 0:
            return 0, 0
        t_sw = math.inf  # the next switch time (none: inf)
        if has_sw:
            c0 = check(p)
            if c0 != OK:
                for i in range(m):
                    if not done[i]:
                        codes[i] = c0
                return 0, 0
            t_sw = nxt(0.0, p)
            clamp(p, -math.inf, t_sw - SIDE * abs(t_sw))
        status, h_abs, n_rhs = start(0.0, y, p, min(t_end, t_sw), rtol, atol, 0.0, work)
        n_steps = 0
        if status != OK:
            for i in range(m):
                if not done[i]:
                    codes[i] = status
            return n_steps, n_rhs
        f0 = work[0]
        h0 = h_abs
        for i in range(m):  # what t = 0 already tells
            if done[i]:
                continue
            kind = M[i, 0]
            idx = int(M[i, 1])
            s = M[i, 2]
            if kind == K_CROSSING or kind == K_PERIOD:
                g_old[i] = s * (y[idx] - M[i, 3])
            elif kind == K_STATE_AT:
                if M[i, 5] <= 0.0:
                    values[i] = y[idx]
                    done[i] = True
                    left -= 1
            elif M[i, 5] <= 0.0:  # extremum from t0 = 0
                expr = kind == K_EXTREMUM_OF
                best[i] = s * value_of(0.0, y, p, idx, expr)
                g_old[i] = s * rate_of(0.0, y, p, f0, idx, expr, h0, yt)
                started[i] = True
        t = 0.0
        attempts = 0
        # dop853's stiffness test, late in the step budget (a spent budget there: STIFF); np.int64, not 0:
        # a call typed for Literal[int](0) too compiles each stiffness helper twice
        n_stiff = np.int64(0)
        n_nonstiff = np.int64(0)
        while left > 0 and t < t_end:
            status, t_new, h_abs, a = advance(t, y, p, min(t_end, t_sw), h_abs, rtol, atol, work, max_steps - attempts)
            attempts += a
            n_rhs += N_ST * a
            if status != OK:
                status = failure(status, n_stiff)
                break
            n_steps += 1
            h = t_new - t
            if tests_stiffness(False, attempts, max_steps, n_stiff):  # before a dense output reuses its row
                n_stiff, n_nonstiff = stiffness_update(h, work, n_stiff, n_nonstiff)
            dense = False
            y_new = work[Y_NEW]
            f_new = work[K_FSAL]
            for i in range(m):
                if done[i]:
                    continue
                kind = M[i, 0]
                idx = int(M[i, 1])
                s = M[i, 2]
                ta = M[i, 5]
                if kind == K_CROSSING or kind == K_PERIOD:
                    g = s * (y_new[idx] - M[i, 3])
                    if g_old[i] > 0.0 and g <= 0.0:
                        if not dense:
                            dense_output(t, h, y, p, work)
                            n_rhs += N_DENSE
                            dense = True
                        tr = brent(t, g_old[i], t_new, g, ROOT_RTOL * abs(h),
                                   (t, h, y, p, work, idx, s, M[i, 3], False, fa, False, yt, calls))
                        if tr > ta:
                            codes[i] = NO_EVENT
                            done[i] = True
                        else:
                            count[i] += 1.0
                            if count[i] == 1.0:
                                t_first[i] = tr
                            if count[i] == M[i, 4]:
                                values[i] = tr if kind == K_CROSSING else tr - t_first[i]
                                done[i] = True
                    if not done[i] and t_new >= ta:
                        codes[i] = NO_EVENT
                        done[i] = True
                    g_old[i] = g
                elif kind == K_STATE_AT:
                    if ta <= t_new:
                        if ta == t_new:
                            values[i] = y_new[idx]
                        else:
                            if not dense:
                                dense_output(t, h, y, p, work)
                                n_rhs += N_DENSE
                                dense = True
                            interpolate((ta - t) / h, y, work, ya)
                            values[i] = ya[idx]
                        done[i] = True
                else:  # extremum of s * y[idx] (or of expression idx) over [ta, tb]
                    tb = M[i, 6]
                    expr = kind == K_EXTREMUM_OF
                    if not started[i]:
                        if ta > t_new:
                            continue
                        if ta == t_new:
                            best[i] = s * value_of(t_new, y_new, p, idx, expr)
                            g_old[i] = s * rate_of(t_new, y_new, p, f_new, idx, expr, h, yt)
                            started[i] = True
                            continue
                        if not dense:
                            dense_output(t, h, y, p, work)
                            n_rhs += N_DENSE
                            dense = True
                        interpolate((ta - t) / h, y, work, ya)
                        rhs(ta, ya, p, fa)
                        n_rhs += 1
                        best[i] = s * value_of(ta, ya, p, idx, expr)
                        g_old[i] = s * rate_of(ta, ya, p, fa, idx, expr, h, yt)
                        started[i] = True
                        lo = ta
                    else:
                        lo = t
                    if tb >= t_new:
                        hi = t_new
                        g = s * rate_of(t_new, y_new, p, f_new, idx, expr, h, yt)
                        y_hi = value_of(t_new, y_new, p, idx, expr)
                    else:
                        if not dense:
                            dense_output(t, h, y, p, work)
                            n_rhs += N_DENSE
                            dense = True
                        hi = tb
                        interpolate((tb - t) / h, y, work, ya)
                        rhs(tb, ya, p, fa)
                        n_rhs += 1
                        g = s * rate_of(tb, ya, p, fa, idx, expr, h, yt)
                        y_hi = value_of(tb, ya, p, idx, expr)
                    if g_old[i] > 0.0 and g <= 0.0:
                        if not dense:
                            dense_output(t, h, y, p, work)
                            n_rhs += N_DENSE
                            dense = True
                        calls[0] = 0
                        tr = brent(lo, g_old[i], hi, g, ROOT_RTOL * abs(h),
                                   (t, h, y, p, work, idx, s, 0.0, True, fa, expr, yt, calls))
                        n_rhs += calls[0]  # one rhs call per evaluation of the derivative
                        interpolate((tr - t) / h, y, work, ya)
                        best[i] = max(best[i], s * value_of(tr, ya, p, idx, expr))
                    g_old[i] = g
                    if tb <= t_new:
                        best[i] = max(best[i], s * y_hi)
                        values[i] = s * best[i]
                        done[i] = True
                if done[i]:
                    left -= 1
            commit(y, work)
            t = t_new
            if has_sw and t >= t_sw and left > 0 and t < t_end:  # on a switch: f again on its far side
                lo = t_sw + SIDE * abs(t_sw)
                t_sw = nxt(t, p)
                if not t_sw > t:
                    status = NONFINITE
                    break
                clamp(p, lo, t_sw - SIDE * abs(t_sw))
                rhs(t, y, p, work[0])
                n_rhs += 1
        if has_sw:
            clamp(p, -math.inf, math.inf)
        for i in range(m):
            if not done[i]:
                values[i] = math.nan
                codes[i] = status if status != OK else NO_EVENT
        return n_steps, n_rhs

    return shared
