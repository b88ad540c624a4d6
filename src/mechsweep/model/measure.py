"""Generic measurements of an :class:`~mechsweep.model.ode.OdeModel`.

Each measurement declares its output (name, unit, long name) and knows how to write, as Python
source, one jitted function ``measure(y, p, rtol, atol, max_steps, work) -> (status, value, n_steps,
n_rhs)`` for the generated chunk kernel (see compile.py). ``y`` holds the initial state on entry and
is scratch afterwards; ``p`` is the point's parameter row followed by ``len(states)`` scratch slots
(the user's rhs only reads its declared parameters). Every measurement integrates from t = 0 with
the DOP853 of ``mechsweep.ode.dop853``; each one integrates on its own (no trajectory is shared).
Nothing raises: a failure is a status code of :mod:`mechsweep.status` and a NaN value.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..models._spec import Output

DIRECTIONS = ("down", "up")


def _check_state(state, states, what):
    if state not in states:
        raise ValueError(f"{what}: state {state!r} is not one of the model's states {states}")
    return states.index(state)


def _crossing_events(k: int, idx: int, level: float, direction: str) -> str:
    """Two event functions, ``ev{k}_fwd`` (the wanted direction) and ``ev{k}_back`` (the other);
    dop853's event solver finds a change of sign from > 0 to <= 0."""
    sign = 1.0 if direction == "down" else -1.0
    return (f"@jit\ndef ev{k}_fwd(t, y, p):\n    return {sign!r} * (y[{idx}] - {level!r})\n\n"
            f"@jit\ndef ev{k}_back(t, y, p):\n    return {-sign!r} * (y[{idx}] - {level!r})\n\n"
            f"solve{k}_fwd = dop853.make_event_solver(rhs, ev{k}_fwd)\n"
            f"solve{k}_back = dop853.make_event_solver(rhs, ev{k}_back)\n")


@dataclass(frozen=True)
class Crossing:
    """Time of the ``n``-th crossing of ``level`` by a state in ``direction`` ("down": from above
    to at-or-below, "up": the reverse), searched on [0, t_max].

    Status: NO_EVENT when fewer than ``n`` such crossings happen before ``t_max``; an integration
    failure (MAX_STEPS, STEP_UNDERFLOW, NONFINITE) as the integrator reports it.
    Cost: one integration to the n-th crossing, 2 n - 1 event searches (crossings in the other
    direction separate consecutive ones, so a search never restarts on the root it just found).
    ``max_steps`` bounds each search. Accuracy: the root of the 7th-order dense output, to a few
    ulp of t; the time itself carries the integration error (rtol/atol)."""

    name: str
    state: str
    level: float = 0.0
    direction: str = "down"
    n: int = 1
    t_max: float = 100.0
    unit: str = "s"
    long_name: str = ""

    def output(self) -> Output:
        return Output(self.name, self.name, self.unit,
                      self.long_name or f"time of crossing {self.n} of {self.state} = {self.level:g} ({self.direction})",
                      integrated=True)

    def validate(self, states):
        _check_state(self.state, states, self.name)
        if self.direction not in DIRECTIONS:
            raise ValueError(f"{self.name}: direction {self.direction!r} is not one of {DIRECTIONS}")
        if not (isinstance(self.n, int) and self.n >= 1):
            raise ValueError(f"{self.name}: n = {self.n!r}; expected a whole number >= 1")
        if not (math.isfinite(self.t_max) and self.t_max > 0):
            raise ValueError(f"{self.name}: t_max = {self.t_max!r}; expected a finite number > 0")

    def source(self, k: int, states) -> str:
        idx = states.index(self.state)
        return _crossing_events(k, idx, float(self.level), self.direction) + f"""
@jit
def measure{k}(y, p, rtol, atol, max_steps, work):
    ns = 0
    nr = 0
    t = 0.0
    for j in range({self.n}):
        if j > 0:
            code, t, a, b = solve{k}_back(t, y, p, {float(self.t_max)!r}, rtol, atol, 0.0, max_steps, work)
            ns += a
            nr += b
            if code != st.OK:
                return code, math.nan, ns, nr
        code, t, a, b = solve{k}_fwd(t, y, p, {float(self.t_max)!r}, rtol, atol, 0.0, max_steps, work)
        ns += a
        nr += b
        if code != st.OK:
            return code, math.nan, ns, nr
    return st.OK, t, ns, nr
"""


@dataclass(frozen=True)
class Period:
    """Period of an autonomous oscillation: the time between the first and the second crossing of
    ``level`` by a state in ``direction``, searched on [0, t_max]. Exact for a periodic motion
    whatever the initial phase (the first crossing is the reference, not t = 0).

    Status: NO_EVENT when the second crossing does not happen before ``t_max`` (no oscillation
    about ``level``, or a horizon shorter than about two periods); integration failures as reported.
    Cost: integration over one to two periods, three event searches."""

    name: str
    state: str
    level: float = 0.0
    direction: str = "down"
    t_max: float = 100.0
    unit: str = "s"
    long_name: str = ""

    def output(self) -> Output:
        return Output(self.name, "T", self.unit, self.long_name or f"period of {self.state} (crossings of {self.level:g})",
                      integrated=True)

    def validate(self, states):
        Crossing(self.name, self.state, self.level, self.direction, 2, self.t_max).validate(states)

    def source(self, k: int, states) -> str:
        idx = states.index(self.state)
        tm = float(self.t_max)
        return _crossing_events(k, idx, float(self.level), self.direction) + f"""
@jit
def measure{k}(y, p, rtol, atol, max_steps, work):
    code, t1, ns, nr = solve{k}_fwd(0.0, y, p, {tm!r}, rtol, atol, 0.0, max_steps, work)
    if code != st.OK:
        return code, math.nan, ns, nr
    code, t2, a, b = solve{k}_back(t1, y, p, {tm!r}, rtol, atol, 0.0, max_steps, work)
    ns += a
    nr += b
    if code != st.OK:
        return code, math.nan, ns, nr
    code, t3, a, b = solve{k}_fwd(t2, y, p, {tm!r}, rtol, atol, 0.0, max_steps, work)
    ns += a
    nr += b
    if code != st.OK:
        return code, math.nan, ns, nr
    return st.OK, t3 - t1, ns, nr
"""


@dataclass(frozen=True)
class StateAt:
    """The value of a state at time ``t`` (integrated from 0 to exactly ``t``, last step clipped).

    Status: integration failures as reported (MAX_STEPS, STEP_UNDERFLOW, NONFINITE).
    Cost: one integration over [0, t]."""

    name: str
    state: str
    t: float
    unit: str = ""
    long_name: str = ""

    def output(self) -> Output:
        return Output(self.name, f"{self.state}(t)", self.unit, self.long_name or f"{self.state} at t = {self.t:g}",
                      integrated=True)

    def validate(self, states):
        _check_state(self.state, states, self.name)
        if not (math.isfinite(self.t) and self.t >= 0):
            raise ValueError(f"{self.name}: t = {self.t!r}; expected a finite number >= 0")

    def source(self, k: int, states) -> str:
        idx = states.index(self.state)
        return f"""
solve{k} = dop853.make_solver(rhs)


@jit
def measure{k}(y, p, rtol, atol, max_steps, work):
    code, ns, nr = solve{k}(0.0, y, p, {float(self.t)!r}, rtol, atol, 0.0, max_steps, work)
    if code != st.OK:
        return code, math.nan, ns, nr
    return st.OK, y[{idx}], ns, nr
"""


@dataclass(frozen=True)
class Extremum:
    """The maximum (``kind="max"``) or minimum (``"min"``) of a state over [t0, t1].

    Candidates are the state at t0 and t1 and at every interior turning point, located as a
    root of the state's derivative (the rhs component) on the dense output, so the value is as
    accurate as the integration (no sampling error). Status: integration failures as reported.
    Cost: one integration over [0, t1] plus event searches that alternate between maxima and
    minima; every evaluation of the event costs one rhs evaluation, which n_rhs does not count."""

    name: str
    state: str
    t0: float
    t1: float
    kind: str = "max"
    unit: str = ""
    long_name: str = ""

    def output(self) -> Output:
        return Output(self.name, f"{self.kind} {self.state}", self.unit,
                      self.long_name or f"{self.kind} of {self.state} over [{self.t0:g}, {self.t1:g}]", integrated=True)

    def validate(self, states):
        _check_state(self.state, states, self.name)
        if self.kind not in ("max", "min"):
            raise ValueError(f"{self.name}: kind {self.kind!r} is not one of ('max', 'min')")
        if not (math.isfinite(self.t0) and math.isfinite(self.t1) and 0 <= self.t0 < self.t1):
            raise ValueError(f"{self.name}: [t0, t1] = [{self.t0!r}, {self.t1!r}]; expected finite 0 <= t0 < t1")

    def source(self, k: int, states) -> str:
        idx = states.index(self.state)
        ns_ = len(states)
        sign = 1.0 if self.kind == "max" else -1.0
        # p[NP:] is scratch for the derivative: the user's rhs never reads beyond its parameters
        return f"""
@jit
def ev{k}_turn(t, y, p):  # s * dy_i/dt from > 0 to <= 0: a maximum of s * y_i
    d = p[p.size - {ns_}:]
    rhs(t, y, p, d)
    return {sign!r} * d[{idx}]


@jit
def ev{k}_other(t, y, p):
    d = p[p.size - {ns_}:]
    rhs(t, y, p, d)
    return {-sign!r} * d[{idx}]


solve{k}_to = dop853.make_solver(rhs)
solve{k}_turn = dop853.make_event_solver(rhs, ev{k}_turn)
solve{k}_other = dop853.make_event_solver(rhs, ev{k}_other)


@jit
def measure{k}(y, p, rtol, atol, max_steps, work):
    s = {sign!r}
    code, ns, nr = solve{k}_to(0.0, y, p, {float(self.t0)!r}, rtol, atol, 0.0, max_steps, work)
    if code != st.OK:
        return code, math.nan, ns, nr
    best = s * y[{idx}]
    t = {float(self.t0)!r}
    turn = True
    while True:
        if turn:
            code, t, a, b = solve{k}_turn(t, y, p, {float(self.t1)!r}, rtol, atol, 0.0, max_steps, work)
        else:
            code, t, a, b = solve{k}_other(t, y, p, {float(self.t1)!r}, rtol, atol, 0.0, max_steps, work)
        ns += a
        nr += b
        if code == st.NO_EVENT:  # y is the state at t1
            best = max(best, s * y[{idx}])
            return st.OK, s * best, ns, nr
        if code != st.OK:
            return code, math.nan, ns, nr
        if turn:
            best = max(best, s * y[{idx}])
        turn = not turn
"""


MEASUREMENTS = (Crossing, Period, StateAt, Extremum)
