"""A measurement integrated on its own to a root of an event: FirstEvent, a lone first Crossing
(engine/point.py's direct measurements), by the kernel's method (ode/methods.py ``event_pass``).

A FirstEvent with a ``System`` integrates that equation (its own initial state, jac, accel and
symplectic_step; its ``prepare`` runs first); with ``refine``, a successful pass is checked and, where
the factor asks for it, integrated once more from the start at the tightened tolerance with what is
left of the step budget (both passes counted).
"""
from __future__ import annotations

import functools
import math

from .. import status as st
from .._jit import jit_into_caller
from ..ode.methods import negated


@functools.cache
def crossing_event(sign: float, idx: int, level: float):
    """``event(t, y, p) = sign (y[idx] - level)``: a state crossing a level (sign 1: downwards)."""
    @jit_into_caller
    def event(t, y, p):
        return sign * (y[idx] - level)

    return event


@functools.cache
def constant(x: float):
    """``f(p) = x``."""
    @jit_into_caller
    def f(p):
        return x

    return f


@jit_into_caller
def identity_value(p, x):
    return x


@jit_into_caller
def no_refine(p, rtol, x):
    return 1.0


@jit_into_caller
def _ok2(p, x):
    return st.OK


def parts(plan, m, k):
    """(event, t_max, value, n, since, system) of direct measurement k as the kernel's route calls them."""
    view = plan.view
    if not hasattr(m, "event"):  # a lone first Crossing of a state
        sign = 1.0 if m.direction == "down" else -1.0
        return (crossing_event(sign, plan.model.states.index(m.state), float(m.level)), constant(float(m.t_max)),
                identity_value, 1, 0, None)
    event = view.fn(m.event, f"event{k}", "t,y,p")
    if m.direction == "up":  # the roots where the event goes from < 0 to >= 0
        event = negated(event)
    t_max = view.fn(m.t_max, f"t_max{k}", "p") if callable(m.t_max) else constant(float(m.t_max))
    value = view.fn(m.value, f"value{k}", "p,x") or identity_value
    return event, t_max, value, int(m.n), int(m.since), m.system


def block(plan, m, k):
    """``block(i, p, y, rtol, atol, max_steps, ws, table, n_steps, n_rhs) -> (status, value)`` of
    direct measurement k in the one-point kernel."""
    view = plan.view
    event, t_max, value, n, since, system = parts(plan, m, k)
    start = plan.initial if system is None else view.fn(system.initial, f"initial{k}", "initial")
    prepare = _ok2 if system is None or system.prepare is None else view.fn(system.prepare, f"prepare{k}", "status2")
    refine = view.fn(getattr(m, "refine", None), f"refine{k}", "p,x,y") or no_refine
    run = plan.integrator().event_pass(plan.equation(system), start, event, n, since)
    return _block(run, t_max, value, prepare, refine)


@functools.cache
def _block(run, t_max, value, prepare, refine):
    @jit_into_caller
    def measure(i, p, y, rtol, atol, max_steps, ws, table, n_steps, n_rhs):
        val = math.nan
        c = prepare(p, rtol)
        if c == st.OK:
            c, val, a, b = run(p, y, t_max(p), rtol, atol, max_steps, ws[0])
            n_steps[i] += a
            n_rhs[i] += b
            if c == st.OK:
                val = value(p, val)
            if c == st.OK:
                f = refine(p, rtol, val)
                if not f <= 1.0:  # NaN-safe: not a number is ILL_CONDITIONED below
                    if not math.isfinite(f):
                        c = st.ILL_CONDITIONED
                    elif a >= max_steps:
                        c = st.MAX_STEPS
                    else:  # once more at the tightened tolerance, with what is left of the step budget
                        c, val, a2, b2 = run(p, y, t_max(p), rtol / f, atol / f, max_steps - a, ws[0])
                        n_steps[i] += a2
                        n_rhs[i] += b2
                        if c == st.OK:
                            val = value(p, val)
        return c, val

    return measure
