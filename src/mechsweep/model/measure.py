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


@dataclass(frozen=True)
class Floquet:
    """Largest modulus of the Floquet multipliers of the model linearised about its motion from
    ``initial(p)`` over one forcing period T = ``forcing_period(p)`` (the model must declare it).

    The monodromy matrix is integrated from the variational equations Phi' = J(t, y) Phi,
    Phi(0) = I, together with the state (n + n^2 equations); J is the rhs's Jacobian by central
    differences (step cbrt(eps) max(1, |y_j|), exact up to round-off for an rhs linear in y),
    2 n + 1 rhs calls per evaluation. The multipliers are the eigenvalues of Phi(T) (LAPACK).
    The value is the largest |multiplier|: <= 1 (within the integration error) for a stable
    linearisation. Near a stability boundary it is sensitive: a double multiplier +-1 moves like the
    square root of any error, so the boundary is where the value leaves 1, not a value to compare
    to 1 at tolerance.
    Status: INFEASIBLE when T is not finite and > 0; integration failures as reported; NONFINITE
    for a non-finite monodromy. Cost: one integration of n + n^2 equations over [0, T];
    n_rhs counts calls of the user's rhs."""

    name: str
    unit: str = "1"
    long_name: str = ""
    needs_forcing = True

    def output(self) -> Output:
        return Output(self.name, "max |λ|", self.unit,
                      self.long_name or "largest modulus of the Floquet multipliers over one forcing period",
                      integrated=True, kind="floquet_max")

    def validate(self, states):
        pass

    def scratch(self, n: int) -> int:
        return 3 * n + n * n

    def source(self, k: int, states, n_p: int = 0) -> str:
        n = len(states)
        N = n + n * n
        o_yp, o_fp, o_fm, o_J = n_p, n_p + n, n_p + 2 * n, n_p + 3 * n
        return f"""
@jit
def var_rhs{k}(t, z, p, dz):
    # z = (y, Phi row by row); dz = (f(t, y), J Phi), J by central differences
    rhs(t, z[:{n}], p, dz[:{n}])
    yp = p[{o_yp}:{o_yp + n}]
    fp = p[{o_fp}:{o_fp + n}]
    fm = p[{o_fm}:{o_fm + n}]
    for j in range({n}):
        for i in range({n}):
            yp[i] = z[i]
        h = 6.055454452393343e-06 * max(1.0, abs(z[j]))  # cbrt(eps)
        up = z[j] + h
        dn = z[j] - h
        yp[j] = up
        rhs(t, yp, p, fp)
        yp[j] = dn
        rhs(t, yp, p, fm)
        for i in range({n}):
            p[{o_J} + i * {n} + j] = (fp[i] - fm[i]) / (up - dn)
    for i in range({n}):
        for j in range({n}):
            acc = 0.0
            for m in range({n}):
                acc += p[{o_J} + i * {n} + m] * z[{n} + m * {n} + j]
            dz[{n} + i * {n} + j] = acc


solve{k}_var = dop853.make_solver(var_rhs{k})


@jit
def measure{k}(y, p, rtol, atol, max_steps, work):
    T = forcing(p)
    if not (math.isfinite(T) and T > 0.0):
        return st.INFEASIBLE, math.nan, 0, 0
    z = np.zeros({N})
    for i in range({n}):
        z[i] = y[i]
        z[{n} + i * {n} + i] = 1.0
    wz = dop853.workspace({N})
    code, ns, nr = solve{k}_var(0.0, z, p, T, rtol, atol, 0.0, max_steps, wz)
    nr = nr * {2 * n + 1}
    if code != st.OK:
        return code, math.nan, ns, nr
    M = np.empty(({n}, {n}), dtype=np.complex128)
    for i in range({n}):
        for j in range({n}):
            v = z[{n} + i * {n} + j]
            if not math.isfinite(v):
                return st.NONFINITE, math.nan, ns, nr
            M[i, j] = v
    lam = np.linalg.eigvals(M)
    big = 0.0
    for i in range({n}):
        big = max(big, abs(lam[i]))
    return st.OK, big, ns, nr
"""


MEASUREMENTS = (Crossing, Period, StateAt, Extremum, Floquet)
