"""Declared switch times of a right-hand side that is not smooth in t (``OdeModel(switch_times=...)``).

A model whose rhs (or a derivative of it) jumps at known instants of its forcing period declares
them: the times in [0, T) at which it switches, repeated every forcing period T. The engine then
integrates segment by segment: every integration route of the model (the event solvers of
FirstEvent/Crossing/periods, the plain and trajectory solvers of Floquet, StateAt, Steady, History,
Kick, the shared trajectory; dop853, radau and auto) ends a step exactly on each switch and starts
the next step there afresh, so no step, dense output, event search or stiffness count straddles a
switch.

The side of the switch the rhs is evaluated on (and the model's jac, and a Floquet's own
variational system): never at a switch time itself. While a segment
[a, b] is integrated, the time the solvers pass to the rhs is kept in [a + d(a), b - d(b)], d(x) =
SIDE * |x| (about ten ulps): the step that ends on b sees the interval before b, the step that
starts at b the interval after it, whatever the rhs does at b exactly and even when its own
switch is a few ulps off the declared one (a switch computed as ``math.cos(t) > 0`` switches within
an ulp of the float nearest pi/2). The integration's own start (t = 0, or a restart at an event)
is not moved.

What this module holds:
- ``source(model, at)``: the generated kernel code (compile.py, trajectory.py) of the switches: the
  clamped ``rhs``, ``switch_check(p)`` (the run-time validation), ``next_switch(t, p)`` and the
  wrapped ``dop853``/``radau`` name spaces whose ``make_*`` factories return the segmented solvers.
- the segmented solvers: ``event_solver``, ``solver``, ``trajectory_solver``; each has the signature
  of the solver it wraps (ode/dop853.py), so every generated call site stays as it is.

Each segment is a new call of the wrapped solver: its first step is chosen again (scipy's
select_initial_step: 2 rhs calls, counted; radau likewise) and its step budget is what is left of
``max_steps`` after the accepted steps before it. A trajectory segment whose last sample lies
before the switch is integrated on to the switch by the plain solver (another restart). The
shared trajectory (measure.make_shared) keeps its step size across a switch and re-evaluates f
there (1 rhs call, counted).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .. import status as st
from .._jit import jit

SIDE = 2e-15  # relative distance from a switch at which the rhs is evaluated for either side of it


def check_declaration(model) -> None:
    """The declaration-time rules of ``switch_times`` (ValueError naming the model and the argument)."""
    sw = model.switch_times
    where = f"model {model.name!r}: switch_times"
    if model.forcing_period is None:
        raise ValueError(f"{where} are times within one forcing period, repeated every period: declare "
                         "forcing_period=, a function forcing_period(p) returning T (e.g. 2 * math.pi)")
    if model.accel is not None:
        raise ValueError(f"{where}: the symplectic method (accel) takes fixed steps that do not end on the "
                         "switches; declare either accel (a smooth separable model) or switch_times, not both")
    if callable(sw):
        return
    try:
        values = tuple(float(x) for x in sw)
    except (TypeError, ValueError):
        raise ValueError(f"{where} = {sw!r}; expected increasing numbers in [0, T) (a tuple of constants) or a "
                         "function switch_times(p) -> tuple of floats") from None
    if not values:
        raise ValueError(f"{where} is empty; leave it out for a smooth rhs")
    if not all(math.isfinite(x) and x >= 0.0 for x in values) or any(b <= a for a, b in zip(values, values[1:])):
        raise ValueError(f"{where} = {sw!r}; expected strictly increasing finite numbers >= 0 (times in [0, T) "
                         "of one forcing period)")


def constants(model) -> tuple | None:
    """The switch times as floats when declared as constants, else None (a function)."""
    sw = model.switch_times
    return None if sw is None or callable(sw) else tuple(float(x) for x in sw)


def source(model, at: str, refs: dict, guarded: bool = True) -> str:
    """Generated kernel code: the switches of ``model`` read from and kept in p[at], p[at + 1] (the
    clamp of the rhs's time; ``at`` is source text). Put after the guards (it rebinds ``rhs``,
    ``dop853`` and ``radau``) and before any solver is made. ``guarded=False``: without their ``try``
    (the one-point module catches a model's exception once per point: model/compile.py strip_guards, the
    one-point module's own mechanism, _one_try)."""
    text = _source(model, at, refs)
    if not guarded:
        from .compile import strip_guards
        text = strip_guards(text)
    return text


def _source(model, at: str, refs: dict) -> str:
    c = constants(model)
    if c is not None:
        lst = f"@jit\ndef switch_list(p):\n    return {tuple(c)!r}\n"
    else:
        assert "switch_times" in refs
        lst = "@jit\ndef switch_list(p):\n    return user_switch_times(p)\n"
    # the other functions of t the solvers call: the model's jac, a Floquet's own variational system
    timed = [n for n in refs if n == "jac" or n.rstrip("0123456789") in ("variational", "variational_jac")]
    clamped = "".join(f"""

{n}_at = {n}


@jit
def {n}(t, a, p, out):
    {n}_at(min(max(t, p[SW]), p[SW + 1]), a, p, out)
""" for n in timed)
    return f"""

# ---- switch times (model/switches.py): every step ends on them; the rhs never sees one itself
SW = {at}  # p[SW], p[SW + 1]: the rhs's time is kept in [p[SW], p[SW + 1]] (the segment's inside)
{lst}

@jit
def switch_check(p):
    # OK, or INFEASIBLE where the switch times are not increasing times in [0, T), T finite > 0;
    # USER_ERROR (the point flagged) where switch_times raised
    try:
        T = forcing(p)
        if not (math.isfinite(T) and T > 0.0):
            return st.INFEASIBLE
        last = -1.0
        n = 0
        for b in switch_list(p):
            x = float(b)
            if not (math.isfinite(x) and x >= 0.0 and x < T and x > last):
                return st.INFEASIBLE
            last = x
            n += 1
        return st.OK if n > 0 else st.INFEASIBLE
    except Exception:
        p[NPI] = 1.0
        return st.USER_ERROR


@jit
def next_switch(t, p):
    # the first switch time after t (k T + b > t); NaN where switch_times raises
    try:
        T = forcing(p)
        k = math.floor(t / T) - 1.0
        best = math.inf
        for j in range(3):
            base = (k + j) * T
            for b in switch_list(p):
                x = base + float(b)
                if x > t and x < best:
                    best = x
        return best
    except Exception:
        p[NPI] = 1.0
        return math.nan


@jit
def switch_clamp(p, lo, hi):
    p[SW] = lo
    p[SW + 1] = hi


rhs_at = rhs  # the guarded rhs; the rhs every solver below calls keeps its time off the switches


@jit
def rhs(t, y, p, dydt):
    rhs_at(min(max(t, p[SW]), p[SW + 1]), y, p, dydt)
{clamped}

from mechsweep.model import switches as _switches  # noqa: E402

dop853 = _switches.Segmented(dop853, next_switch, switch_check, switch_clamp)
radau = _switches.Segmented(radau, next_switch, switch_check, switch_clamp)
"""


def Segmented(module, nxt, check, clamp):
    """A copy of a solver module (ode.dop853, ode.radau) whose ``make_solver``, ``make_event_solver``
    and ``make_trajectory_solver`` return the segmented solvers of one model's switches; everything
    else is the module's (a module object: numba reads ``workspace`` from it inside the kernels)."""
    import types

    seg = types.ModuleType(f"{module.__name__}_switched")
    seg.__dict__.update({k: v for k, v in vars(module).items() if not k.startswith("__")})
    seg.make_event_solver = lambda *a, **kw: event_solver(module.make_event_solver(*a, **kw), nxt, check, clamp)
    seg.make_solver = lambda *a, **kw: solver(module.make_solver(*a, **kw), nxt, check, clamp)
    seg.make_trajectory_solver = lambda *a, **kw: trajectory_solver(
        module.make_trajectory_solver(*a, **kw), module.make_solver(*a, **kw), nxt, check, clamp)
    return seg


@jit
def _below(x):
    return x - SIDE * abs(x)


@jit
def _above(x):
    return x + SIDE * abs(x)


@functools.cache
def event_solver(solve, nxt, check, clamp):
    """``solve``'s signature and contract, integrating from switch to switch: the root of the first
    segment that has one; NO_EVENT only at t_max."""
    @jit
    def run(t0, y, p, t_max, rtol, atol, h0, max_steps, work):
        c = check(p)
        if c != st.OK:
            return c, t0, 0, 0
        t = t0
        lo = -math.inf  # the start itself is not moved
        h = h0
        n_steps = 0
        n_rhs = 0
        while True:
            tb = nxt(t, p)
            if not tb > t:
                c, tr = st.NONFINITE, t
                break
            hi = min(tb, t_max)
            clamp(p, lo, _below(tb))
            c, tr, a, b_ = solve(t, y, p, hi, rtol, atol, h, max_steps - n_steps, work)
            n_steps += a
            n_rhs += b_
            if c != st.NO_EVENT or hi >= t_max:
                break
            t = hi
            lo = _above(tb)
            h = 0.0
        clamp(p, -math.inf, math.inf)
        return c, tr, n_steps, n_rhs

    return run


@functools.cache
def solver(solve, nxt, check, clamp):
    """``solve``'s signature and contract (to t_end exactly), integrating from switch to switch."""
    @jit
    def run(t0, y, p, t_end, rtol, atol, h0, max_steps, work):
        c = check(p)
        if c != st.OK:
            return c, 0, 0
        t = t0
        lo = -math.inf
        h = h0
        n_steps = 0
        n_rhs = 0
        while t < t_end:
            tb = nxt(t, p)
            if not tb > t:
                c = st.NONFINITE
                break
            hi = min(tb, t_end)
            clamp(p, lo, _below(tb))
            c, a, b_ = solve(t, y, p, hi, rtol, atol, h, max_steps - n_steps, work)
            n_steps += a
            n_rhs += b_
            if c != st.OK:
                break
            t = hi
            lo = _above(tb)
            h = 0.0
        clamp(p, -math.inf, math.inf)
        return c, n_steps, n_rhs

    return run


@functools.cache
def trajectory_solver(traj, plain, nxt, check, clamp):
    """``traj``'s signature and contract (rows of out at t_eval; ends at t_eval[-1]), integrating
    from switch to switch: the rows of each segment from its own call of ``traj``, then ``plain`` on
    to the switch where the segment's last row lies before it."""
    @jit
    def run(t0, y, p, t_eval, rtol, atol, h0, max_steps, work, out):
        out[:, :] = np.nan
        n = t_eval.size
        if n == 0:
            return st.OK, 0, 0
        c = check(p)
        if c != st.OK:
            return c, 0, 0
        t_end = t_eval[n - 1]
        t = t0
        lo = -math.inf
        h = h0
        k = 0
        n_steps = 0
        n_rhs = 0
        while True:
            tb = nxt(t, p)
            if not tb > t:
                c = st.NONFINITE
                break
            hi = min(tb, t_end)
            k1 = k
            while k1 < n and t_eval[k1] <= hi:
                k1 += 1
            clamp(p, lo, _below(tb))
            tl = t
            if k1 > k:
                c, a, b_ = traj(t, y, p, t_eval[k:k1], rtol, atol, h, max_steps - n_steps, work, out[k:k1])
                n_steps += a
                n_rhs += b_
                tl = max(t, t_eval[k1 - 1])
                h = 0.0
            if c == st.OK and tl < hi:
                c, a, b_ = plain(tl, y, p, hi, rtol, atol, h, max_steps - n_steps, work)
                n_steps += a
                n_rhs += b_
            if c != st.OK or hi >= t_end:
                break
            k = k1
            t = hi
            lo = _above(tb)
            h = 0.0
        clamp(p, -math.inf, math.inf)
        return c, n_steps, n_rhs

    return run
