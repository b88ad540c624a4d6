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

This module holds the declaration's rules (``check_declaration``, ``constants``); the kernels' side,
the segmented solvers and the clamp, is engine/switches.py. Each segment is a new call of the wrapped
solver: its first step is chosen again (scipy's select_initial_step: 2 rhs calls, counted; radau
likewise) and its step budget is what is left of ``max_steps`` after the accepted steps before it.
A trajectory segment whose last sample lies before the switch is integrated on to the switch by the
plain solver (another restart). The shared trajectory (engine/shared.py) keeps its step size across a
switch and re-evaluates f there (1 rhs call, counted).
"""
from __future__ import annotations

import math

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
