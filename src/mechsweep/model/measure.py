"""Generic measurements of an :class:`~mechsweep.model.ode.OdeModel`.

FirstEvent (an event function, any method) and ClosedForm (a formula output) are at the end.

Each measurement declares its output (name, unit, long name) and knows how to write, as Python
source, one jitted function ``measure(y, p, rtol, atol, max_steps, work) -> (status, value, n_steps,
n_rhs)`` for the generated chunk kernel (see compile.py). ``y`` holds the initial state on entry and
is scratch afterwards; ``p`` is the point's parameter row followed by ``len(states)`` scratch slots
(the user's rhs only reads its declared parameters). Every measurement integrates from t = 0 with
the DOP853 of ``mechsweep.ode.dop853``. In the generated kernel Crossing, Period, StateAt and
Extremum do not use their ``source``: they are rows (``shared_row``) of one shared integration per
point (``make_shared``); ``source`` is kept for ``compile.kernel_for(..., shared=False)`` (one
integration per measurement, for comparison). Floquet always integrates on its own.
Nothing raises: a failure is a status code of :mod:`mechsweep.status` and a NaN value.
"""
from __future__ import annotations

import functools
import math
import os
import sys
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .spec import Output, Setting

_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep


def _records_where(cls):
    """Class decorator: each instance remembers where it was written (the first caller outside the
    package: file, line), so an error found when the model is validated can name that line rather
    than the OdeModel(...) call's (``declared_at``)."""
    init = cls.__init__

    @functools.wraps(init)
    def __init__(self, *args, **kwargs):
        init(self, *args, **kwargs)
        f = sys._getframe(1)
        while f is not None and (f.f_code.co_filename.startswith(_PACKAGE) or f.f_code.co_filename == "<string>"):
            f = f.f_back
        object.__setattr__(self, "_declared_at", (f.f_code.co_filename, f.f_lineno) if f is not None else None)

    cls.__init__ = __init__
    return cls


def declared_at(obj):
    """(file, line) where a measurement or closed form was written, or None."""
    return getattr(obj, "_declared_at", None)


DIRECTIONS = ("down", "up")


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


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


_META_KEYS = ("name", "symbol", "unit", "long_name", "latex")


class _Outputs:
    """Settable names and metadata of a measurement's outputs (Floquet, Steady, Kick, History):
    ``output_meta`` maps a generic output name (``name`` + suffix, e.g. ``"sim_settling"``) to
    overrides {name, symbol, unit, long_name, latex} (any of them; ``name`` not for the main output,
    which is the measurement's ``name``). Kept as sorted pairs (hashable, compared)."""

    def __post_init__(self):
        meta = self.output_meta
        try:
            pairs = meta.items() if hasattr(meta, "items") else meta
            norm = tuple(sorted((str(k), tuple(sorted(dict(v).items()))) for k, v in pairs))
        except (TypeError, ValueError):
            raise ValueError(f"{self.name}: output_meta must map generic output names to dicts of "
                             f"{', '.join(_META_KEYS)} (got {meta!r})") from None
        object.__setattr__(self, "output_meta", norm)

    def _suffixes(self) -> tuple[str, ...]:
        return ("",)

    def _meta(self, generic: str) -> dict:
        return dict(dict(self.output_meta).get(generic, ()))

    def output_name(self, suffix: str = "") -> str:
        """The name of the output whose generic name is ``name + suffix``."""
        return self._meta(self.name + suffix).get("name", self.name + suffix)

    def _output(self, suffix, symbol, unit, long_name, latex="", **kw) -> Output:
        d = self._meta(self.name + suffix)
        return Output(self.output_name(suffix), d.get("symbol", symbol), d.get("unit", unit),
                      d.get("long_name", long_name), latex=d.get("latex", latex), **kw)

    def _check_meta(self):
        generic = [self.name + x for x in self._suffixes()]
        for k, d in self.output_meta:
            if k not in generic:
                raise ValueError(f"{self.name}: output_meta names {k!r}, which is not one of its generic outputs "
                                 f"({', '.join(generic)})")
            for key, v in d:
                if key not in _META_KEYS:
                    raise ValueError(f"{self.name}: output_meta[{k!r}] sets {key!r}; allowed: {', '.join(_META_KEYS)}")
                if not isinstance(v, str) or (key == "name" and not v.isidentifier()):
                    raise ValueError(f"{self.name}: output_meta[{k!r}][{key!r}] = {v!r}; expected a string"
                                     + (" that is an identifier" if key == "name" else ""))
            if dict(d).get("name", k) != k and k == self.name:
                raise ValueError(f"{self.name}: output_meta cannot rename the main output {k!r} (it is the "
                                 "measurement's name: rename the measurement)")
        names = [self.output_name(x) for x in self._suffixes()]
        if len(set(names)) != len(names):
            raise ValueError(f"{self.name}: output_meta gives repeated output names {names}")


@_records_where
@dataclass(frozen=True)
class Crossing:
    """Time of the ``n``-th crossing of ``level`` by a state in ``direction`` ("down": from above
    to at-or-below, "up": the reverse), searched on [0, t_max].

    Status: NO_EVENT when fewer than ``n`` such crossings happen before ``t_max``; an integration
    failure (MAX_STEPS, STEP_UNDERFLOW, NONFINITE, STIFF) as the integrator reports it.
    Cost: one integration to the n-th crossing, 2 n - 1 event searches (crossings in the other
    direction separate consecutive ones, so a search never restarts on the root it just found).
    ``max_steps`` bounds each search. Accuracy: the root of the 7th-order dense output, to a few
    ulp of t; the time itself carries the integration error (rtol/atol).

    Parameters
    ----------
    name : str
        The output's name.
    state : str
        The state whose crossing is timed.
    level : float, optional
        The level crossed (default 0).
    direction : {"down", "up"}, optional
        "down": from above to at-or-below the level; "up": the reverse.
    n : int, optional
        The n-th such crossing (default the first).
    t_max : float, optional
        The crossing must happen at or before this time (else NO_EVENT).
    unit : str, optional
        UDUNITS-2 unit of the output.
    long_name : str, optional
        What the output is, in words (default: made from the declaration).
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its outputs NaN with that status).
    """

    name: str
    state: str
    level: float = 0.0
    direction: str = "down"
    n: int = 1
    t_max: float = 100.0
    unit: str = "s"
    long_name: str = ""
    classify: Callable | None = field(default=None, repr=False, compare=False)  # where it applies (OdeModel)

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
        if isinstance(self.level, bool) or not isinstance(self.level, (int, float)) or not math.isfinite(self.level):
            raise ValueError(f"{self.name}: level = {self.level!r}; expected a finite number")

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


@_records_where
@dataclass(frozen=True)
class Period:
    """Period of an autonomous oscillation: the time between the first and the second crossing of
    ``level`` by a state in ``direction``, searched on [0, t_max]. Exact for a periodic motion
    whatever the initial phase (the first crossing is the reference, not t = 0).

    Status: NO_EVENT when the second crossing does not happen before ``t_max`` (no oscillation
    about ``level``, or a horizon shorter than about two periods); integration failures as reported.
    Cost: integration over one to two periods, three event searches.

    Parameters
    ----------
    name : str
        The output's name.
    state : str
        The state whose crossings are timed.
    level : float, optional
        The level crossed (default 0).
    direction : {"down", "up"}, optional
        The direction of the two crossings.
    t_max : float, optional
        The second crossing must happen at or before this time (else NO_EVENT).
    unit : str, optional
        UDUNITS-2 unit of the output.
    long_name : str, optional
        What the output is, in words (default: made from the declaration).
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its outputs NaN with that status).
    """

    name: str
    state: str
    level: float = 0.0
    direction: str = "down"
    t_max: float = 100.0
    unit: str = "s"
    long_name: str = ""
    classify: Callable | None = field(default=None, repr=False, compare=False)  # where it applies (OdeModel)

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


@_records_where
@dataclass(frozen=True)
class StateAt:
    """The value of a state at time ``t`` (integrated from 0 to exactly ``t``, last step clipped).

    Status: integration failures as reported (MAX_STEPS, STEP_UNDERFLOW, NONFINITE, STIFF).
    Cost: one integration over [0, t].

    Parameters
    ----------
    name : str
        The output's name.
    state : str
        The state whose value is taken.
    t : float
        The time (a number, the same for every point).
    unit : str, optional
        UDUNITS-2 unit of the output.
    long_name : str, optional
        What the output is, in words (default: made from the declaration).
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its outputs NaN with that status).
    """

    name: str
    state: str
    t: float
    unit: str = ""
    long_name: str = ""
    classify: Callable | None = field(default=None, repr=False, compare=False)  # where it applies (OdeModel)

    def output(self) -> Output:
        at = f"{self.t:g}" if _is_number(self.t) else repr(self.t)  # validate() refuses a non-number
        return Output(self.name, f"{self.state}(t)", self.unit, self.long_name or f"{self.state} at t = {at}",
                      integrated=True)

    def validate(self, states):
        _check_state(self.state, states, self.name)
        if not (_is_number(self.t) and math.isfinite(self.t) and self.t >= 0):
            raise ValueError(f"{self.name}: StateAt t = {self.t!r}; expected a finite number >= 0 (a fixed time: "
                             "for a time that depends on the parameters use Extremum's t0/t1 or FirstEvent)")

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


@_records_where
@dataclass(frozen=True)
class Extremum:
    """The maximum (``kind="max"``) or minimum (``"min"``) over [t0, t1] of a state, or of an
    expression ``f(t, y, p) -> float`` given instead of the state's name (e.g. a kinetic energy,
    a contact force, a state's distance from a point).

    ``t0`` and ``t1`` are numbers, or functions ``t0(p) -> float`` of the point (e.g. the last
    forcing period before a horizon: ``t1 = lambda p: 50 T(p)``, ``t0 = lambda p: 49 T(p)``); a
    window that is not finite 0 <= t0 < t1 at a point gives that point INFEASIBLE.

    Candidates are the value at t0 and t1 and at every interior turning point, located as a root
    of the derivative on the dense output, so the value is as accurate as the integration (no
    sampling error): for a state its derivative is the rhs component; for an expression, its rate
    along the trajectory by a central difference (f(t + e, y + e F) - f(t - e, y - e F)) / 2e,
    F = rhs(t, y), e = cbrt(eps) |h| with the step's size h (only the turning point's time carries
    the difference's error; the value is the expression's own at that time).
    Status: integration failures as reported; INFEASIBLE for a window that is not one.
    Cost: one integration over [0, t1] plus event searches that alternate between maxima and
    minima; every evaluation of the event costs one rhs evaluation (and 2 of the expression),
    which n_rhs does not count.

    Parameters
    ----------
    name : str
        The output's name.
    state : str or callable
        A state's name, or an expression ``f(t, y, p) -> float``.
    t0, t1 : float or callable
        The window: numbers, or functions ``t0(p)``, ``t1(p)``.
    kind : {"max", "min"}, optional
        The largest or the smallest value over the window.
    unit : str, optional
        UDUNITS-2 unit of the output.
    long_name : str, optional
        What the output is, in words (default: made from the declaration).
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its outputs NaN with that status).
    """

    name: str
    state: object  # a state's name, or a function f(t, y, p) -> float
    t0: object  # a number, or a function t0(p) -> float
    t1: object
    kind: str = "max"
    unit: str = ""
    long_name: str = ""
    classify: Callable | None = field(default=None, repr=False, compare=False)  # where it applies (OdeModel)

    def _window(self) -> str:
        def one(x):
            return f"{x:g}" if not callable(x) else f"{getattr(x, '__name__', 't')}(p)"
        return f"[{one(self.t0)}, {one(self.t1)}]"

    def output(self) -> Output:
        what = self.state if isinstance(self.state, str) else getattr(self.state, "__name__", self.name)
        return Output(self.name, f"{self.kind} {what}", self.unit,
                      self.long_name or f"{self.kind} of {what} over {self._window()}", integrated=True)

    def validate(self, states):
        _observable(self.state, states, self.name)
        if self.kind not in ("max", "min"):
            raise ValueError(f"{self.name}: kind {self.kind!r} is not one of ('max', 'min')")
        for f in ("t0", "t1"):
            x = getattr(self, f)
            if not callable(x) and not (isinstance(x, (int, float)) and math.isfinite(x)):
                raise ValueError(f"{self.name}: {f} = {x!r}; expected a finite number or a function {f}(p)")
        if not callable(self.t0) and not callable(self.t1) and not 0 <= self.t0 < self.t1:
            raise ValueError(f"{self.name}: [t0, t1] = [{self.t0!r}, {self.t1!r}]; expected finite 0 <= t0 < t1")

    def functions(self):
        """(role, function) pairs the generated module imports: the expression, the window's ends."""
        return tuple((role, f) for role, f in (("of", self.state), ("t0", self.t0), ("t1", self.t1)) if callable(f))

    def key(self) -> tuple:
        """What the generated code depends on (compile.py adds the functions' sources)."""
        def num(x):
            return None if callable(x) else float(x)
        return ("Extremum", self.name, self.state if isinstance(self.state, str) else None, num(self.t0),
                num(self.t1), self.kind)

    def source(self, k: int, states) -> str:
        if self.functions():
            raise ValueError(f"{self.name}: an Extremum of an expression or over a window given by functions of p is "
                             "measured on the shared trajectory only (not with shared=False)")
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


@_records_where
@dataclass(frozen=True)
class Floquet(_Outputs):
    """Floquet multipliers of the model linearised about its motion from ``initial(p)`` over one
    forcing period T = ``forcing_period(p)`` (the model must declare it). Three outputs:

    - ``name``: the largest modulus of the multipliers: <= 1 (within the integration error) for a
      stable linearisation;
    - ``name_stable``: 1 if it is below 1 - margin, 0 if above 1 + margin, else NaN with status
      UNDECIDED; margin = max(``solver.floquet_margin``, 100 rtol) (the setting is added to the
      model's settings, default 1e-8, unless the model declares its own);
    - ``name_kind``: how the critical multiplier (the one of largest modulus) sits on or leaves the
      unit circle: +1 (real, positive: T-periodic mode, e.g. a saddle-node or symmetry-breaking
      loss of stability), -1 (real, negative: period doubling), 0 (a complex pair: Neimark-Sacker,
      or on the stable side an oscillating mode). Real means |Im| <= 1e-8 |mu| (eigenvalues of a
      real matrix computed in complex arithmetic: a real one carries an imaginary part of round-off);
    - ``name_angle``: the argument of the critical multiplier, in rad, folded to [0, pi] (a complex
      pair is mu = |mu| exp(+-i angle)): exactly 0 for kind +1 and pi for kind -1 (the same test);
      on a boundary |mu| = 1, so the critical multiplier there is exp(+-i angle).

    The monodromy matrix is integrated from the variational equations Phi' = J(t, y) Phi,
    Phi(0) = I, together with the state (n + n^2 equations). J is the model's ``jac(t, y, p, J)``
    when it declares one, else the rhs's Jacobian by central differences (step cbrt(eps)
    max(1, |y_j|), exact up to round-off for an rhs linear in y; 2 n + 1 rhs calls per
    evaluation). The multipliers are the eigenvalues of Phi(T) (LAPACK). Near a stability boundary
    the modulus is sensitive: a double multiplier +-1 moves like the square root of any error, so
    the boundary is where the value leaves 1, not a value to compare to 1 at tolerance.
    ``initial(p, y0)`` (optional): the start of the orbit when it is not the model's initial state.
    Status: INFEASIBLE when T is not finite and > 0; integration failures as reported; NONFINITE
    for a non-finite monodromy; UNDECIDED (only when ``name_stable`` is asked for, and only on a
    point whose status is still OK) within the margin. Cost: one integration of n + n^2 equations
    over [0, T]; n_rhs counts calls of the user's rhs (not of jac).

    A model whose periodic orbit is known in closed form can give the variational system itself:
    ``variational(t, Phi, p, dPhi)`` writes dPhi = J(t, y*(t)) Phi about that orbit (Phi and dPhi:
    n*n values, column-major: column c is Phi[c*n:(c+1)*n]), and optionally
    ``variational_jac(t, Phi, p, JJ)`` its (n*n, n*n) Jacobian for radau (block diagonal: J(t, y*(t))
    n times; without it radau and auto's radau differentiate ``variational`` by central differences,
    2 n*n + 1 calls per Jacobian, counted in n_rhs). The engine then integrates only the n*n
    equations from Phi(0) = I (no state, no J Phi product of its own; ``initial`` is not called,
    though the work-precision reference still uses it); n_rhs counts calls of ``variational``.
    Everything else (margin, kind, angle, statuses, methods) is as above.

    Parameters
    ----------
    name : str
        The output of the largest multiplier modulus (``name_stable``, ``name_kind`` and
        ``name_angle`` come with it).
    unit : str, optional
        Unit of the modulus (default ``"1"``).
    long_name : str, optional
        What the output is, in words.
    initial : callable, optional
        ``initial(p, y0)``: where the linearised motion starts, when not the model's ``initial``.
    stable_name, kind_name : str, optional
        Other names for the verdict and kind outputs.
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its outputs NaN with that status).
    output_meta : Mapping, optional
        Output name -> dict of ``symbol``/``long_name``/``unit`` for the derived outputs.
    variational : callable, optional
        ``variational(t, Phi, p, dPhi)``: the variational system about a known orbit, integrated
        instead of the model linearised along its own motion.
    variational_jac : callable, optional
        ``variational_jac(t, Phi, p, J)``: its Jacobian, for radau.
    """

    name: str
    unit: str = "1"
    long_name: str = ""
    initial: Callable | None = field(default=None, repr=False, compare=False)
    stable_name: str = ""  # the verdict output's name; default name + "_stable"
    kind_name: str = ""  # the kind output's name; default name + "_kind"
    classify: Callable | None = field(default=None, repr=False, compare=False)  # where it applies (OdeModel)
    output_meta: object = ()  # {generic output name: {name, symbol, unit, long_name, latex}} (_Outputs)
    variational: Callable | None = field(default=None, repr=False, compare=False)  # f(t, Phi, p, dPhi) about the known orbit
    variational_jac: Callable | None = field(default=None, repr=False, compare=False)  # g(t, Phi, p, JJ), for radau
    needs_forcing = True
    n_values = 3  # the largest modulus, the kind and the critical multiplier's argument

    def _suffixes(self):
        return ("", "_stable", "_kind", "_angle")

    def output_name(self, suffix: str = "") -> str:
        named = {"_stable": self.stable_name, "_kind": self.kind_name}.get(suffix)
        return named or super().output_name(suffix)

    @property
    def stable(self) -> str:
        return self.output_name("_stable")

    @property
    def kind(self) -> str:
        return self.output_name("_kind")

    @property
    def angle(self) -> str:
        return self.output_name("_angle")

    def output(self) -> Output:
        return self._output("", "max |λ|", self.unit,
                            self.long_name or "largest modulus of the Floquet multipliers over one forcing period",
                            latex=r"$\max|\lambda|$", integrated=True, kind="floquet_max")

    def outputs(self) -> tuple[Output, ...]:
        return (self.output(),
                self._output("_stable", "stable", "1",
                             f"1 if {self.name} < 1 - margin, 0 if > 1 + margin (margin = max(floquet_margin, 100 "
                             "rtol); NaN and status undecided within it)", integrated=True, needs=(self.name,),
                             kind="verdict"),
                self._output("_kind", "kind", "1",
                             "critical Floquet multiplier: +1 real positive, -1 real negative, 0 complex pair",
                             integrated=True, needs=(self.name,)),
                self._output("_angle", "arg μ", "rad",
                             "argument of the critical Floquet multiplier, folded to [0, π]: 0 real positive, π "
                             "real negative, else a complex pair |μ| exp(±i angle)", integrated=True,
                             needs=(self.name,)))

    def values(self) -> tuple[str, ...]:
        """The outputs the kernel computes, in the order of its columns (closed forms can read
        these; the verdict ``name_stable`` is decided after the kernel, with the margin)."""
        return (self.name, self.kind, self.angle)

    def validate(self, states):
        self._check_meta()
        for suffix, field_name in (("_stable", "stable_name"), ("_kind", "kind_name")):
            if getattr(self, field_name) and "name" in self._meta(self.name + suffix):
                raise ValueError(f"{self.name}: both {field_name} and output_meta[{self.name + suffix!r}]['name'] "
                                 "name the same output; give one")
        if self.initial is not None and not callable(self.initial):
            raise ValueError(f"{self.name}: initial must be a function initial(p, y0) (the start of the orbit)")
        if self.variational is not None and not callable(self.variational):
            raise ValueError(f"{self.name}: variational must be a function variational(t, Phi, p, dPhi) (the "
                             f"variational system about the known orbit; got {self.variational!r})")
        if self.variational_jac is not None:
            if self.variational is None:
                raise ValueError(f"{self.name}: variational_jac is the Jacobian of variational; give variational= "
                                 "too (or neither: the engine then integrates the state with its variational system)")
            if not callable(self.variational_jac):
                raise ValueError(f"{self.name}: variational_jac must be a function variational_jac(t, Phi, p, JJ) "
                                 f"(got {self.variational_jac!r})")

    def functions(self):
        """``initial``: where the linearisation starts when it is not the model's ``initial(p)``
        (e.g. the exact periodic orbit, while the model's initial state is a kicked one);
        ``variational``, ``variational_jac``: the variational system about a known orbit."""
        return tuple((role, f) for role, f in (("initial", self.initial), ("variational", self.variational),
                                               ("variational_jac", self.variational_jac)) if f is not None)

    def scratch(self, n: int) -> int:
        if self.variational is not None:  # radau's differences of variational: Phi+h, f(Phi+h), f(Phi-h), counter
            return 3 * n * n + 1
        return 3 * n + n * n + 1  # y+h, f(y+h), f(y-h), J, the counter of var_jac's rhs calls

    @staticmethod
    def _solvers(k, n, jac_code, method, count=""):
        """The variational system's solver(s) for ``method``; radau's Newton matrix is block
        diagonal, J(t, y) on the state and on every column of Phi (the second derivatives of the
        rhs, d(J Phi)/dy, are left out: they only steer Newton's convergence, not the result)."""
        out = []
        if method in ("dop853", "auto"):
            out.append(f"solve{k}_var = dop853.make_solver(var_rhs{k}, stiffness_test={method == 'auto'})")
        if method in ("radau", "auto"):
            out.append(f"""

@jit
def var_jac{k}(t, z, p, JJ):
{jac_code}{count}    JJ[:, :] = 0.0
    for i in range({n}):
        for m in range({n}):
            JJ[i, m] = p[O_J{k} + i * {n} + m]
            for j in range({n}):
                JJ[{n} + i * {n} + j, {n} + m * {n} + j] = p[O_J{k} + i * {n} + m]


solve{k}_var_r = radau.make_solver(var_rhs{k}, var_jac{k})""")
        return "\n".join(out)

    @staticmethod
    def _integrate(k, n, N, method, known=False):
        """Kernel code: the variational integration over [0, T] by the method (auto: dop853 with the
        stiffness test; a stiff point again from the start by radau, the costs added). ``known``: z
        is Phi alone (the model's variational system), else (y, Phi)."""
        if method == "dop853":
            return (f"    wz = dop853.workspace({N})\n"
                    f"    code, ns, nr = solve{k}_var(0.0, z, p, T, rtol, atol, 0.0, max_steps, wz)\n")
        radau_call = (f"    rz = radau.workspace({N})\n"
                      f"    code, ns, nr = solve{k}_var_r(0.0, z, p, T, rtol, atol, 0.0, max_steps, rz)\n")
        if method == "radau":
            return radau_call
        return (f"    wz = dop853.workspace({N})\n"
                f"    code, ns, nr = solve{k}_var(0.0, z, p, T, rtol, atol, 0.0, max_steps, wz)\n"
                f"    if code == st.STIFF:\n"
                f"        z[:] = 0.0\n"
                f"        for i in range({n}):\n"
                + (f"            z[i * {n} + i] = 1.0\n" if known else
                   f"            z[i] = y[i]\n"
                   f"            z[{n} + i * {n} + i] = 1.0\n")
                + "        ns0, nr0 = ns, nr\n"
                + radau_call.replace("\n    ", "\n        ").replace("    rz", "        rz", 1)
                + "        ns += ns0\n        nr += nr0\n")

    @staticmethod
    def _eigen(n, at):
        """Kernel code: the monodromy matrix M[i, j] = z[at] (NONFINITE if any entry is not finite),
        its eigenvalues, the largest modulus, the critical multiplier's kind and angle."""
        return f"""    M = np.empty(({n}, {n}), dtype=np.complex128)
    for i in range({n}):
        for j in range({n}):
            v = z[{at}]
            if not math.isfinite(v):
                return st.NONFINITE, math.nan, math.nan, math.nan, ns, nr
            M[i, j] = v
    lam = np.linalg.eigvals(M)
    big = -1.0
    crit = lam[0]
    for i in range({n}):
        if abs(lam[i]) > big:
            big = abs(lam[i])
            crit = lam[i]
    if abs(crit.imag) <= 1e-8 * big:
        kind = 1.0 if crit.real > 0.0 else -1.0
        angle = 0.0 if crit.real > 0.0 else math.pi
    else:
        kind = 0.0
        angle = abs(math.atan2(crit.imag, crit.real))
    return st.OK, big, kind, angle, ns, nr
"""

    def _source_known(self, k, n, n_p, method):
        """Kernel code of the route with the model's variational system: the n*n equations alone."""
        N = n * n
        o_yp, o_cnt = n_p, n_p + 3 * N  # scratch: Phi + h, f(Phi + h), f(Phi - h), the counter
        out = [f"\nsolve{k}_var = dop853.make_solver(variational{k}, stiffness_test={method == 'auto'})\n"
               if method in ("dop853", "auto") else ""]
        fd = self.variational_jac is None and method in ("radau", "auto")
        if method in ("radau", "auto"):
            if fd:  # the engine's central differences of variational{k}, its calls counted in p[o_cnt]
                from .compile import _fd_jac
                out.append(_fd_jac(f"variational_jac{k}", f"variational{k}", count=True, n=str(N), at=str(o_yp)))
            out.append(f"\nsolve{k}_var_r = radau.make_solver(variational{k}, variational_jac{k})\n")
        count = (f"    nr += int(p[{o_cnt}])  # radau's Jacobians by differences\n    p[{o_cnt}] = 0.0\n"
                 if fd else "")
        return "".join(out) + f"""

@jit
def measure{k}(y, p, rtol, atol, max_steps, work):
    # the model's variational system about its known orbit: Phi column-major, n*n = {N} equations
    T = forcing(p)
    if not (math.isfinite(T) and T > 0.0):
        return st.INFEASIBLE, math.nan, math.nan, math.nan, 0, 0
    z = np.zeros({N})
    for i in range({n}):
        z[i * {n} + i] = 1.0
{self._integrate(k, n, N, method, known=True)}{count}    if code != st.OK:
        return code, math.nan, math.nan, math.nan, ns, nr
{self._eigen(n, f"j * {n} + i")}"""

    def finish(self, values, wanted, solver, out, status):
        """Python's reading of the kernel's three columns (modulus, kind, angle): the outputs and
        UNDECIDED."""
        from .. import status as st
        big, kind, angle = values[:, 0], values[:, 1], values[:, 2]
        good = np.isfinite(big)
        if self.name in out:
            out[self.name][:] = big
        if self.kind in out:
            out[self.kind][:] = np.where(good, kind, np.nan)
        if self.angle in out:
            out[self.angle][:] = np.where(good, angle, np.nan)
        if self.stable in wanted:
            margin = max(float(solver.settings.get("floquet_margin", 1e-8)), 100.0 * solver.rtol)
            decided = good & (np.abs(big - 1.0) > margin)
            out[self.stable][:] = np.where(decided, (big < 1.0).astype(float), np.nan)
            status[:] = np.where((status == st.OK) & good & ~decided, st.UNDECIDED, status)

    def source(self, k: int, states, n_p: int = 0, has_jac: bool = False, method: str = "dop853") -> str:
        if self.variational is not None:
            return self._source_known(k, len(states), n_p, method)
        n = len(states)
        N = n + n * n
        o_yp, o_fp, o_fm, o_J = n_p, n_p + n, n_p + 2 * n, n_p + 3 * n
        per_eval = 1 if has_jac else 2 * n + 1
        # J into p[o_J:o_J + n * n] (row by row): the model's jac, or the engine's central differences
        # of its rhs (compile._fd_jac, scratch p[o_yp:o_yp + 3 n] = y + h, f(y + h), f(y - h); its
        # 2 n rhs calls are in per_eval, not in a counter)
        jac_code = f"""    J = p[{o_J}:{o_J + n * n}].reshape(({n}, {n}))
    {"jac" if has_jac else f"fd_jac{k}"}(t, z[:{n}], p, J)
"""
        fd = ""
        if not has_jac:
            from .compile import _fd_jac
            assert (o_fp, o_fm) == (o_yp + n, o_yp + 2 * n)  # _fd_jac's scratch layout
            fd = _fd_jac(f"fd_jac{k}", "rhs", n=str(n), at=str(o_yp))
        return f"""{fd}
O_J{k} = {o_J}


@jit
def var_rhs{k}(t, z, p, dz):
    # z = (y, Phi row by row); dz = (f(t, y), J Phi), J {"from the model's jac" if has_jac else "by central differences"}
    rhs(t, z[:{n}], p, dz[:{n}])
{jac_code}    for i in range({n}):
        for j in range({n}):
            acc = 0.0
            for m in range({n}):
                acc += p[{o_J} + i * {n} + m] * z[{n} + m * {n} + j]
            dz[{n} + i * {n} + j] = acc


{self._solvers(k, n, jac_code, method, "" if has_jac else f"    p[{o_J + n * n}] += {2.0 * n!r}  # its rhs calls{chr(10)}")}


@jit
def measure{k}(y, p, rtol, atol, max_steps, work):
{"    initial" + str(k) + "(p, y)" + chr(10) if self.initial is not None else ""}    T = forcing(p)
    if not (math.isfinite(T) and T > 0.0):
        return st.INFEASIBLE, math.nan, math.nan, math.nan, 0, 0
    z = np.zeros({N})
    for i in range({n}):
        z[i] = y[i]
        z[{n} + i * {n} + i] = 1.0
{self._integrate(k, n, N, method)}    nr = nr * {per_eval}{"" if has_jac or method == "dop853" else f"{chr(10)}    nr += int(p[{o_J + n * n}])  # radau's Jacobians by differences{chr(10)}    p[{o_J + n * n}] = 0.0"}
    if code != st.OK:
        return code, math.nan, math.nan, math.nan, ns, nr
{self._eigen(n, f"{n} + i * {n} + j")}"""


# ---------------------------------------------------------------- methods-aware measurements
@dataclass(frozen=True)
class System:
    """A second equation of a model, integrated by the FirstEvent measurements that name it
    (``FirstEvent(..., system=S)``): the same states and the same ``p`` (parameters, settings,
    internal slots) as the model, its own ``rhs(t, y, p, dydt)`` and ``initial(p, y0)``, optional
    ``jac`` (else central differences of its rhs for radau), ``accel`` + ``symplectic_step`` (the
    symplectic method; required when the model declares ``accel``) and ``prepare(p, rtol) ->
    status`` (run just before the measurement; non-OK: that measurement is NaN with that status,
    the others are computed)."""

    rhs: Callable = field(repr=False, compare=False)
    initial: Callable = field(repr=False, compare=False)
    jac: Callable | None = field(default=None, repr=False, compare=False)
    accel: Callable | None = field(default=None, repr=False, compare=False)
    symplectic_step: Callable | None = field(default=None, repr=False, compare=False)
    prepare: Callable | None = field(default=None, repr=False, compare=False)

    def functions(self):
        return tuple((role, getattr(self, role)) for role in ("rhs", "initial", "jac", "accel", "symplectic_step",
                                                              "prepare") if getattr(self, role) is not None)


@_records_where
@dataclass(frozen=True)
class FirstEvent:
    """The value at the first root of an event function: ``event(t, y, p)`` going from > 0 to
    <= 0, searched on [0, t_max] from ``initial(p, y0)`` (after ``prepare``).

    - ``event(t, y, p) -> float``: plain numba-compilable Python; it may read the model's
      parameters, settings and internal slots (``p``), so the level and direction may depend on
      the point (e.g. the Duffing saddle formulation's level).
    - ``t_max``: a number, or ``t_max(p) -> float`` (e.g. a horizon from a setting and a time scale).
    - ``value(p, t) -> float`` (optional): the output from the root's time ``t`` (e.g. the period
      T = 4 tau_q / w of a quarter period in scaled time); default: ``t`` itself.

    Offered by every method the model declares (dop853, radau, auto; symplectic when the model
    declares ``accel``): the generated kernel calls that method's event solver directly, one
    integration per point and measurement. The root is located on the method's own interpolant
    (dop853: 7th-order dense output; radau: the collocation polynomial; symplectic: the quintic
    Hermite interpolant of each fixed step), so values differ between methods by their errors.
    Status: NO_EVENT when no root before t_max; integration failures as the integrator reports
    them (MAX_STEPS, STEP_UNDERFLOW, NONFINITE; STIFF with dop853 where its stiffness test fired on
    the last steps of a spent budget; with auto STIFF is never final: radau starts again).

    - ``direction``: "down" (default) the roots where the event goes from > 0 to <= 0, "up" from
      < 0 to >= 0 (the event negated).
    - ``n``: the ``n``-th such root instead of the first (NO_EVENT when fewer than n before
      t_max); ``value`` gets its time. Cost: 2 n - 1 event searches on one integration, each
      restarting the integrator at the previous root (a new first step); the searches alternate
      with the other direction's, so none restarts on the root it just found; what is left of
      ``max_steps`` after the accepted steps of the searches before bounds the next. Not in SIMD
      lanes (n > 1 or "up": one point at a time).
    - ``since`` (0 <= since < n): the time from root ``since`` to root n instead of from t = 0
      (``n=2, since=1``: the period of an autonomous oscillation of the event's expression, exact
      for a periodic motion whatever the initial phase); ``value`` gets that interval.

    - ``system`` (optional): a :class:`System`, a second equation of the same model (its own rhs,
      initial state, jac, accel/symplectic_step and prepare) that this measurement integrates
      instead of the model's; e.g. a truncated and an exact form of one mechanism, measured at the
      same point. Its ``prepare`` runs just before this measurement (after the model's).
    - ``refine(p, rtol, value) -> factor`` (optional): after a successful pass, a bound on how much
      the integration error is amplified in ``value`` at this point. ``factor <= 1``: the value
      stands; a finite ``factor > 1``: the measurement is integrated once more from the start at
      ``rtol / factor``, ``atol / factor`` with what is left of ``max_steps`` (none left: MAX_STEPS),
      and that pass's value (or status) is the result; not a finite number (e.g. ``math.inf``):
      ILL_CONDITIONED (no tolerance can give ``rtol`` here). Both passes count in n_steps/n_rhs.

    Parameters
    ----------
    name : str
        The output's name.
    event : callable
        ``event(t, y, p) -> float``: the function whose root (from > 0 to <= 0) is found.
    t_max : float or callable, optional
        The root must come at or before this time (a number, or ``t_max(p)``), else NO_EVENT.
    value : callable, optional
        ``value(p, t) -> float``: the output from the root's time (default: the time itself).
    symbol : str, optional
        How the output is written in formulas.
    unit : str, optional
        UDUNITS-2 unit of the output.
    long_name : str, optional
        What the output is, in words (default: made from the declaration).
    system : System, optional
        Another equation integrated for this measurement instead of the model's.
    refine : callable, optional
        ``refine(p, rtol) -> factor``: integrate again at rtol / factor where the first pass says so.
    needs_params : tuple of str, optional
        Optional parameters the output requires.
    n : int, optional
        The n-th root instead of the first.
    direction : {"down", "up"}, optional
        "up": the roots where the event goes from < 0 to >= 0.
    since : int, optional
        The time from root ``since`` to root ``n`` instead of from t = 0.
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its outputs NaN with that status).
    latex : str, optional
        The output's symbol in matplotlib mathtext, for figure labels (see :class:`Output`).
    """

    name: str
    event: Callable = field(repr=False, compare=False)
    t_max: object = field(default=100.0, compare=False)
    value: Callable | None = field(default=None, repr=False, compare=False)
    symbol: str = ""
    unit: str = ""
    long_name: str = ""
    system: System | None = field(default=None, repr=False, compare=False)
    refine: Callable | None = field(default=None, repr=False, compare=False)
    needs_params: tuple[str, ...] = ()  # Output.needs_params: optional parameters the value requires
    n: int = 1  # the n-th root (in direction) instead of the first
    direction: str = "down"  # "down": event from > 0 to <= 0; "up": from < 0 to >= 0
    since: int = 0  # > 0: the time from root `since` to root n (n=2, since=1: a period), not from t = 0
    classify: Callable | None = field(default=None, repr=False, compare=False)  # where it applies (OdeModel)
    latex: str = ""  # Output.latex: the symbol in mathtext, for figures
    direct = True  # integrates on its own with solver.method (compile.py)

    def output(self) -> Output:
        which = "first" if self.n == 1 else f"root {self.n}" + (f" counted from root {self.since}" if self.since else "")
        return Output(self.name, self.symbol or self.name, self.unit,
                      self.long_name or f"value at the {which} root of {self.name}'s event"
                      + ("" if self.direction == "down" else " (upwards)"), integrated=True,
                      needs_params=tuple(self.needs_params), latex=self.latex)

    def validate(self, states):
        if not callable(self.event):
            raise ValueError(f"{self.name}: event must be a function event(t, y, p) -> float")
        if not callable(self.t_max) and not (isinstance(self.t_max, (int, float)) and math.isfinite(self.t_max)
                                             and self.t_max > 0):
            raise ValueError(f"{self.name}: t_max = {self.t_max!r}; expected a finite number > 0 "
                             "or a function t_max(p)")
        if self.value is not None and not callable(self.value):
            raise ValueError(f"{self.name}: value must be a function value(p, t) -> float")
        if self.system is not None and not isinstance(self.system, System):
            raise ValueError(f"{self.name}: system must be a mechsweep.model.System (got {self.system!r})")
        if self.refine is not None and not callable(self.refine):
            raise ValueError(f"{self.name}: refine must be a function refine(p, rtol, value) -> float")
        if not (isinstance(self.n, int) and not isinstance(self.n, bool) and self.n >= 1):
            raise ValueError(f"{self.name}: n = {self.n!r}; expected a whole number >= 1")
        if self.direction not in DIRECTIONS:
            raise ValueError(f"{self.name}: direction {self.direction!r} is not one of {DIRECTIONS}")
        if not (isinstance(self.since, int) and not isinstance(self.since, bool) and 0 <= self.since < self.n):
            raise ValueError(f"{self.name}: since = {self.since!r}; expected a whole number 0 <= since < n = {self.n!r}")

    def functions(self):
        """(role, function) pairs the generated module imports."""
        out = [("event", self.event)]
        if callable(self.t_max):
            out.append(("t_max", self.t_max))
        if self.value is not None:
            out.append(("value", self.value))
        if self.refine is not None:
            out.append(("refine", self.refine))
        if self.system is not None:
            out += self.system.functions()
        return tuple(out)

    def key(self) -> tuple:
        """What the generated code depends on (with the functions' names, compile.py adds their sources)."""
        key = ("FirstEvent", self.name, None if callable(self.t_max) else float(self.t_max))
        return key if (self.n, self.direction) == (1, "down") else key + (self.n, self.direction, self.since)


@_records_where
@dataclass(frozen=True)
class ClosedForm:
    """An output given by a formula: ``func(p, *needed) -> float``, plain numba-compilable Python
    of the point's parameters and settings (``p[0 .. len(params) + len(settings) - 1]``) and of the
    values of the outputs named in ``needs`` (other closed forms or measurements), passed in the
    order of ``needs``; e.g. kv = v_max T / A or period_error = |T - T_exact| / T_exact.

    Computed in the generated kernel only when wanted (or needed by a wanted output), after the
    model's ``classify`` (a point it rejects gets NaN) and before ``prepare`` (so the internal
    slots are not written yet). One that needs a measurement is computed after the measurements
    (NaN when a needed value is NaN).
    ``output_needs``: what the ModelSpec says the output needs (the runner then computes those
    too and a describe shows them); default: ``needs``. Give ``()`` for a formula whose inputs
    are internal to it (kv needs v_max and period_exact to be computed, not to be stored).
    ``classify(p) -> status`` (optional): where the formula does not apply (e.g. the Duffing
    closed forms of a model whose two-term approximation is past its separatrix): non-OK, the
    output is NaN and, when the closed form is computed, the point gets that status (the first
    failure in the kernel's order: classify, these closed forms, the measurements).

    Parameters
    ----------
    name : str
        The output's name.
    func : callable
        The formula: ``func(p)``, or ``func(p, *needs)`` of the outputs it needs.
    symbol : str, optional
        How the output is written in formulas.
    unit : str, optional
        UDUNITS-2 unit of the output.
    long_name : str, optional
        What the output is, in words (default: made from the declaration).
    needs : tuple of str, optional
        Outputs the formula takes as arguments, after ``p``.
    output_needs : tuple of str, optional
        The outputs it is derived from for the scene's purposes (default: ``needs``).
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its outputs NaN with that status).
    needs_params : tuple of str, optional
        Optional parameters it requires.
    kind : str, optional
        What the value means for the generic figures (see :class:`Output`).
    latex : str, optional
        The symbol in matplotlib mathtext, for figure labels (see :class:`Output`).
    """

    name: str
    func: Callable = field(repr=False, compare=False)
    symbol: str = ""
    unit: str = ""
    long_name: str = ""
    needs: tuple[str, ...] = ()
    output_needs: tuple[str, ...] | None = None
    classify: Callable | None = field(default=None, repr=False, compare=False)
    needs_params: tuple[str, ...] = ()  # Output.needs_params: optional parameters the formula requires
    kind: str = ""  # Output.kind: what the value is, for generic figures (e.g. "verdict")
    latex: str = ""  # Output.latex: the symbol in mathtext, for figures

    def __post_init__(self):
        if self.kind:  # refused here, at the line that wrote it, rather than when the model's spec is built
            Output(self.name, "", "", "", kind=self.kind)

    def output(self) -> Output:
        return Output(self.name, self.symbol or self.name, self.unit, self.long_name or self.name,
                      needs=tuple(self.needs if self.output_needs is None else self.output_needs),
                      needs_params=tuple(self.needs_params), kind=self.kind, latex=self.latex)



FLOQUET_MARGIN = Setting("floquet_margin", 1e-8, "1",
                         "|max multiplier - 1| within which a Floquet measurement's stable verdict is undecided "
                         "(the margin used is max(floquet_margin, 100 rtol))", 0.0, 0.1)


# ---------------------------------------------------------------- one shared trajectory
# Crossing, Period, StateAt and Extremum of one point observe ONE DOP853 integration from t = 0
# (make_shared). Each is a row of a float table: (kind, state index, sign, level, n, ta, tb).
K_CROSSING, K_PERIOD, K_STATE_AT, K_EXTREMUM, K_EXTREMUM_OF = 0.0, 1.0, 2.0, 3.0, 4.0  # OF: of an expression
SHARED_COLS = 7


def _row_crossing(m, states):
    sign = 1.0 if m.direction == "down" else -1.0
    return (K_CROSSING, float(states.index(m.state)), sign, float(m.level), float(m.n), float(m.t_max), 0.0)


def _row_period(m, states):
    sign = 1.0 if m.direction == "down" else -1.0
    return (K_PERIOD, float(states.index(m.state)), sign, float(m.level), 2.0, float(m.t_max), 0.0)


def _row_state_at(m, states):
    return (K_STATE_AT, float(states.index(m.state)), 1.0, 0.0, 0.0, float(m.t), 0.0)


def _row_extremum(m, states):
    """A state's row; an expression's (K_EXTREMUM_OF) gets its index j in column 1 from compile.py.
    A window end that is a function of p is NaN here (the kernel writes it per point)."""
    sign = 1.0 if m.kind == "max" else -1.0
    t0, t1 = (math.nan if callable(x) else float(x) for x in (m.t0, m.t1))
    if not isinstance(m.state, str):
        return (K_EXTREMUM_OF, -1.0, sign, 0.0, 0.0, t0, t1)
    return (K_EXTREMUM, float(states.index(m.state)), sign, 0.0, 0.0, t0, t1)


Crossing.shared_row = _row_crossing
Period.shared_row = _row_period
StateAt.shared_row = _row_state_at
Extremum.shared_row = _row_extremum


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

    ``observe(t, y, p, j) -> float`` (generated by compile.py): the expression of an Extremum row
    of kind K_EXTREMUM_OF (column 1: j). Its rate along the trajectory is the central difference
    (f(t + e, y + e F) - f(t - e, y - e F)) / 2e, F = rhs(t, y), e = cbrt(eps) |h| (the step's
    size h as the time scale). An Extremum row whose window is not finite 0 <= t0 < t1 (a window
    given as a function of p) gets INFEASIBLE.

    ``switches``: (next_switch, switch_check, switch_clamp) of a model's declared switch times
    (model/switches.py): every step then ends on each switch, f is evaluated again there on the far
    side (1 rhs call, counted) and the step size carries on; a point whose switch times are not valid
    gives switch_check's status to every row. None: exactly the integration without them."""
    from ..ode import dop853 as d
    from ..ode._common import ROOT_RTOL, make_brent
    from .._jit import jit
    from .. import status as st_

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
    SIDE = 2e-15  # switches.SIDE

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
                codes[i] = status
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
        n_stiff = 0  # dop853's stiffness test, late in the step budget (a spent budget there: STIFF)
        n_nonstiff = 0
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


# ---------------------------------------------------------------- sampled-trajectory measurements
# Steady, Kick and History observe ONE sampled trajectory per point (model/trajectory.py): the
# integration from initial(p) to horizon forcing periods, sampled at instants given in forcing
# periods s (t = T s, T = forcing_period(p), or T = 1 for a model without one); the union of the
# chosen measurements' instants is one grid shared by every point. Offered by dop853, radau and
# auto (the engine's one method switch). A number field may instead name one of the model's
# settings (a str): its value is read from the scene's solver settings.


def _number(x, settings) -> float:
    """A measurement field: a number, or the name of one of the model's settings."""
    return float(settings[x]) if isinstance(x, str) else float(x)


def _observable(x, states, what):
    """A state name (checked) or a function ``f(t, y, p) -> float``."""
    if isinstance(x, str):
        _check_state(x, states, what)
    elif not callable(x):
        raise ValueError(f"{what}: expected a state name or a function f(t, y, p) -> float (got {x!r})")


def _check_numbers(m, fields):
    for f in fields:
        x = getattr(m, f)
        if not isinstance(x, str) and not (isinstance(x, (int, float)) and math.isfinite(x)):
            raise ValueError(f"{m.name}: {f} = {x!r}; expected a finite number or the name of a setting")


@dataclass(frozen=True)
class _Range:
    """The allowed values of a numeric field of a sampled-trajectory measurement."""
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False
    integer: bool = False

    def holds(self, x) -> bool:
        if self.integer and not float(x).is_integer():
            return False
        return ((x > self.lo if self.lo_open else x >= self.lo)
                and (x < self.hi if self.hi_open else x <= self.hi))

    def text(self) -> str:
        kind = "a whole number" if self.integer else "a number"
        if self.hi == math.inf:
            return f"{kind} {'>' if self.lo_open else '>='} {self.lo:g}"
        return f"{kind} in {'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}{')' if self.hi_open else ']'}"


_POSITIVE = _Range(0.0, lo_open=True)
_NONNEGATIVE = _Range(0.0)


def _check_ranges(m, rules: dict, settings=None):
    """Each field's value in its range (a number, or, with ``settings`` (the model's), the range
    of the setting it names: every value the scene may give it must be allowed)."""
    for f, rule in rules.items():
        x = getattr(m, f)
        if x is None:
            continue
        what = f"{type(m).__name__} {m.name!r}: {f} = {x!r}"
        if isinstance(x, str):
            if settings is None:
                continue
            s = {t.name: t for t in settings}.get(x)
            if s is not None and not (rule.holds(s.lo) and rule.holds(s.hi) and (s.integer or not rule.integer)):
                raise ValueError(f"{what} names the setting {x!r}, whose range [{s.lo:g}, {s.hi:g}]"
                                 f"{'' if s.integer or not rule.integer else ' (not integer=True)'} allows values "
                                 f"outside what {f} accepts: {rule.text()}")
        elif isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) or not rule.holds(x):
            raise ValueError(f"{what} is not allowed; expected {rule.text()} (or the name of a setting)")


_STEADY = {"horizon": _POSITIVE, "window": _Range(0.0, 0.5, lo_open=True),
           "samples_per_period": _Range(3.0), "settle_rtol": _NONNEGATIVE, "settle_atol": _NONNEGATIVE}
_KICK = {"horizon": _POSITIVE, "settle_threshold": _POSITIVE, "decay_ratio": _Range(0.0, 1.0, lo_open=True),
         "growth_ratio": _Range(1.0), "monitor_per_period": _Range(1.0, integer=True),
         "dense_per_period": _Range(1.0, integer=True), "late": _Range(0.0, 0.5, lo_open=True),
         "early": _Range(0.0, 1.0, lo_open=True), "growth_floor": _NONNEGATIVE}
_HISTORY = {"horizon": _POSITIVE, "samples": _Range(2.0, integer=True)}


def _check_value(m, field_name):
    f = getattr(m, field_name)
    if f is not None and not callable(f):
        raise ValueError(f"{m.name}: {field_name} must be a function {field_name}(p, x) -> float (got {f!r})")


@_records_where
@dataclass(frozen=True)
class Steady(_Outputs):
    """Steady-state amplitude of an observable ``of`` (a state name or ``f(t, y, p)``) after a
    transient, over the last ``window`` (a fraction) of a simulation of ``horizon`` forcing periods.
    Three outputs (and a fourth kernel value):

    - ``name``: the peak, max |of| over the window's samples (``samples_per_period`` per period;
      a sampled maximum: it underestimates a sinusoid's amplitude by at most 1 - cos(pi /
      samples_per_period), 1.2e-3 relative at 64);
    - ``name_h1``: the amplitude of the first harmonic of the forcing period T over the window,
      sqrt(a1^2 + b1^2) with a1 = (2 / L) int of cos(2 pi t / T) dt, b1 with sin (trapezoid rule
      over the samples; exact to round-off for a T-periodic signal when the window is a whole
      number of periods);
    - ``name_phase``: its phase lag atan2(b1, a1) in (-pi, pi]: of = A cos(2 pi t / T - phase);
    - ``name_settled``: internal (not an output): whether it settled.

    ``value(p, x) -> float`` (optional): the stored peak and first-harmonic amplitude from the
    measured ones, per point (e.g. ``x * p[k]`` for an observable in units of a length p[k], or a
    scaled model's amplitude back in SI units); applied after the settling test, to finite values
    only (the phase is not transformed).

    Settling (``settle_rtol`` not None): the peak over the window before the last one (same
    length) must agree with the last one to settle_rtol max(peaks) + settle_atol; otherwise the
    point is NO_EVENT (the transient has not died out within the horizon) and the outputs NaN.
    Status: integration failures as reported; NONFINITE for a non-finite sample.
    Cost: one integration over the horizon (shared with the other sampled measurements) plus one
    dense-output evaluation (3 rhs calls) per step that contains a sample.

    Parameters
    ----------
    name : str
        The output of the peak (``name_h1`` and ``name_phase`` come with it).
    of : str or callable
        A state's name, or ``f(t, y, p) -> float``.
    horizon : float, optional
        Forcing periods simulated.
    window : float, optional
        The fraction of the horizon at its end that is measured, in (0, 0.5].
    samples_per_period : int, optional
        Samples per forcing period in the window.
    settle_rtol, settle_atol : float, optional
        The settling test between the last two windows' peaks (``settle_rtol=None``: no test).
    unit : str, optional
        UDUNITS-2 unit of the output.
    long_name : str, optional
        What the output is, in words (default: made from the declaration).
    value : callable, optional
        ``value(p, x) -> float``: the stored peak and amplitude from the measured ones.
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its outputs NaN with that status).
    output_meta : Mapping, optional
        Output name -> dict of ``symbol``/``long_name``/``unit`` for the derived outputs.
    """

    name: str
    of: object
    horizon: object = 100.0
    window: object = 0.1
    samples_per_period: object = 64
    settle_rtol: object = 1e-3
    settle_atol: object = 0.0
    unit: str = ""
    long_name: str = ""
    value: Callable | None = field(default=None, repr=False, compare=False)
    classify: Callable | None = field(default=None, repr=False, compare=False)  # where it applies (OdeModel)
    output_meta: object = ()  # {generic output name: {name, symbol, unit, long_name, latex}} (_Outputs)
    sampled = True
    n_values = 4

    def _suffixes(self):
        return ("", "_h1", "_phase")

    def outputs(self) -> tuple[Output, ...]:
        what = self.of if isinstance(self.of, str) else self.name
        # the derived outputs carry the user's words for the main one (its long_name) when given
        about = f"{self.long_name}: " if self.long_name else ""
        return (self._output("", f"max |{what}|", self.unit,
                             self.long_name or f"steady-state peak of |{what}| over the last {self.window} of the "
                             "horizon", integrated=True),
                self._output("_h1", "A1", self.unit,
                             f"{about}first-harmonic amplitude (forcing period)" if about else
                             f"first-harmonic amplitude of {what} (forcing period)", latex=r"$A_1$",
                             integrated=True),
                self._output("_phase", "phase", "rad",
                             f"{about}phase lag of the first harmonic (forcing period)" if about else
                             f"phase lag of the first harmonic of {what}: {what} ≈ A1 cos(2π t / T − phase)",
                             latex=r"$\varphi_1$", integrated=True))

    def validate(self, states):
        self._check_meta()
        _observable(self.of, states, self.name)
        _check_numbers(self, ("horizon", "window", "samples_per_period", "settle_atol"))
        if self.settle_rtol is not None:
            _check_numbers(self, ("settle_rtol",))
        _check_ranges(self, _STEADY)
        _check_value(self, "value")

    def check_settings(self, settings):
        """The fields that name a setting: the setting's range within the field's."""
        _check_ranges(self, _STEADY, settings)

    def setting_names(self):
        return tuple(x for x in (self.horizon, self.window, self.samples_per_period, self.settle_rtol,
                                 self.settle_atol) if isinstance(x, str))

    def functions(self):
        out = () if isinstance(self.of, str) else (("of", self.of),)
        return out + ((("value", self.value),) if self.value is not None else ())

    def key(self) -> tuple:
        return ("Steady", self.name, self.of if isinstance(self.of, str) else None)

    def instants(self, settings):
        """(s, bits): this measurement's sample instants in forcing periods and their roles
        (1: the last window, 2: the window before it)."""
        H, w = _number(self.horizon, settings), _number(self.window, settings)
        n = max(2, int(math.ceil(_number(self.samples_per_period, settings) * w * H)) + 1)
        out = [(np.linspace((1.0 - w) * H, H, n), 1)]
        if self.settle_rtol is not None:  # the window before, for the settling test
            out.append((np.linspace((1.0 - 2.0 * w) * H, (1.0 - w) * H, n), 2))
        return out

    def constants(self, settings):
        """The numbers the kernel's observer reads (K row)."""
        check = self.settle_rtol is not None
        # the third: whether the first harmonic is computed (trajectory.evaluate clears it when
        # neither name_h1 nor name_phase is asked for: no cos/sin per sample then)
        return (_number(self.settle_rtol, settings) if check else -1.0, _number(self.settle_atol, settings), 1.0)

    def finish(self, values, wanted, solver, out, status):
        from .. import status as st
        settled = values[:, 3] == 1.0
        unsettled = np.isfinite(values[:, 0]) & ~settled
        names = [self.output_name(x) for x in self._suffixes()]
        for j, name in enumerate(names):
            if name in out:
                out[name][:] = np.where(settled, values[:, j], np.nan)
        if any(x in wanted for x in names):
            status[:] = np.where((status == st.OK) & unsettled, st.NO_EVENT, status)


@_records_where
@dataclass(frozen=True)
class Kick(_Outputs):
    """Stability verdict of a motion from a kick: the model's ``initial(p)`` is the kicked state,
    ``error(t, y, p) >= 0`` the distance from the reference motion (e.g. a phase error), optional
    ``response(t, y, p) >= 0`` a second quantity that must decay too (e.g. a platform amplitude);
    both sampled ``monitor_per_period`` times per forcing period over ``horizon`` periods and
    ``dense_per_period`` times in the last ``late`` fraction. With e0 = max error over the first
    period, e_late / e_before = max error over the last ``late`` fraction / the one before it,
    r_ref / r_late = max response over the first ``early`` fraction / the last ``late`` fraction:

    - stable (1): e_late <= settle_threshold, e_late <= decay_ratio e0, r_late <= decay_ratio r_ref,
      and not growing at the end (e_late <= e_before, or e_late <= growth_floor, by default
      1e-3 settle_threshold: raise it to the error's noise floor, e.g. the integration error of the
      reference motion, when e_late sits there; e_late is sampled ``dense_per_period``, e_before
      ``monitor_per_period`` times per period, so an error that no longer decays reads as growing);
    - unstable (0): e_late >= growth_ratio e0 and e_before >= growth_ratio e0;
    - otherwise NaN with status UNDECIDED (slow convergence or slow growth within the horizon).

    Outputs: ``name`` (the verdict), ``name_settling`` (the time after which the error stays below
    settle_threshold, linear interpolation between samples; 0 if it never exceeds it; NaN with
    status NO_EVENT if it is above it at the end), ``name_final`` (the error at the last sample).
    ``time_value(p, t) -> float`` (optional): the stored settling time from the integration's time
    t, per point (e.g. ``t / p[k]`` for a model integrated in a scaled time tau = Omega t), applied
    to a finite settling time only.
    Status: integration failures as reported; NONFINITE for a non-finite error or response sample.
    Cost: one integration over the horizon (shared), one dense output per step with a sample.

    Parameters
    ----------
    name : str
        The verdict's output (``name_settling`` and ``name_final`` come with it).
    error : callable
        ``error(t, y, p) >= 0``: the distance from the reference motion.
    response : callable, optional
        A second quantity that must decay too.
    horizon : float, optional
        Forcing periods simulated.
    settle_threshold, decay_ratio, growth_ratio : float, optional
        The verdict's thresholds (see above).
    monitor_per_period, dense_per_period : int, optional
        Samples per period over the whole horizon and in its last part.
    late, early : float, optional
        The fractions of the horizon compared at its end and start.
    growth_floor : float, optional
        Below this error the end is not read as growing.
    unit : str, optional
        Unit of ``name_final``.
    time_unit : str, optional
        Unit of ``name_settling`` (default ``"s"``).
    time_value : callable, optional
        ``time_value(p, t) -> float``: the stored settling time from the integration's time.
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its outputs NaN with that status).
    output_meta : Mapping, optional
        Output name -> dict of ``symbol``/``long_name``/``unit`` for the derived outputs.
    """

    name: str
    error: Callable = field(repr=False, compare=False)
    response: Callable | None = field(default=None, repr=False, compare=False)
    horizon: object = 300.0
    settle_threshold: object = 0.01
    decay_ratio: object = 0.5
    growth_ratio: object = 2.0
    monitor_per_period: object = 8
    dense_per_period: object = 64
    late: float = 0.1
    early: float = 0.1
    growth_floor: object = None  # e_late at or below it counts as not growing; None: 1e-3 settle_threshold
    unit: str = ""
    time_unit: str = "s"
    time_value: Callable | None = field(default=None, repr=False, compare=False)
    classify: Callable | None = field(default=None, repr=False, compare=False)  # where it applies (OdeModel)
    output_meta: object = ()  # {generic output name: {name, symbol, unit, long_name, latex}} (_Outputs)
    sampled = True
    n_values = 5  # verdict, settling time, final error; the settling time before time_value, the simulated time

    def _suffixes(self):
        return ("", "_settling", "_final")

    def outputs(self) -> tuple[Output, ...]:
        return (self._output("", "stable (kick)", "1",
                             "1 if the kicked motion settles back, 0 if it departs (direct simulation)",
                             integrated=True, kind="verdict"),
                self._output("_settling", "t_s", self.time_unit,
                             "time after which the error stays below settle_threshold", integrated=True),
                self._output("_final", "e_end", self.unit, "error at the end of the simulation", integrated=True))

    def validate(self, states):
        self._check_meta()
        _observable(self.error, states, self.name)
        if self.response is not None:
            _observable(self.response, states, self.name)
        _check_numbers(self, ("horizon", "settle_threshold", "decay_ratio", "growth_ratio", "monitor_per_period",
                              "dense_per_period") + (() if self.growth_floor is None else ("growth_floor",)))
        _check_ranges(self, _KICK)
        _check_value(self, "time_value")

    def check_settings(self, settings):
        """The fields that name a setting: the setting's range within the field's."""
        _check_ranges(self, _KICK, settings)

    def setting_names(self):
        return tuple(x for x in (self.horizon, self.settle_threshold, self.decay_ratio, self.growth_ratio,
                                 self.monitor_per_period, self.dense_per_period, self.growth_floor)
                     if isinstance(x, str))

    def functions(self):
        out = [] if isinstance(self.error, str) else [("error", self.error)]
        if self.response is not None and not isinstance(self.response, str):
            out.append(("response", self.response))
        if self.time_value is not None:
            out.append(("value", self.time_value))
        return tuple(out)

    def key(self) -> tuple:
        return ("Kick", self.name, self.error if isinstance(self.error, str) else None,
                self.response if isinstance(self.response, str) else None, self.response is None,
                float(self.late), float(self.early))

    def instants(self, settings):
        """(s, bits): 1 every monitor row, 2 the first period, 4 the first ``early`` fraction, 8 the
        last ``late`` fraction, 16 the ``late`` fraction before it (bits 2-16 only on monitor rows)."""
        H = _number(self.horizon, settings)
        mon = int(_number(self.monitor_per_period, settings))
        dense = int(_number(self.dense_per_period, settings))
        late0 = (1.0 - self.late) * H
        parts = [np.linspace(0.0, H, max(2, int(math.ceil(mon * H)) + 1)),
                 np.linspace(late0, H, max(2, int(math.ceil(dense * self.late * H)) + 1)),
                 np.linspace(0.0, min(1.0, H), mon + 1)]
        return [(x, self._bits) for x in parts]

    def _bits(self, s, settings):
        H = _number(self.horizon, settings)
        late0, before0 = (1.0 - self.late) * H, (1.0 - 2.0 * self.late) * H
        return (1 | np.where(s <= min(1.0, H), 2, 0) | np.where(s <= self.early * H, 4, 0)
                | np.where(s >= late0, 8, 0) | np.where((s >= before0) & (s < late0), 16, 0))

    def constants(self, settings):
        settle = _number(self.settle_threshold, settings)
        floor = 1e-3 * settle if self.growth_floor is None else _number(self.growth_floor, settings)
        return (settle, _number(self.decay_ratio, settings), _number(self.growth_ratio, settings), floor)

    def finish(self, values, wanted, solver, out, status):
        from .. import status as st
        ok = np.isfinite(values[:, 2])
        verdict, t_settle = values[:, 0], values[:, 1]
        for j, suffix in enumerate(self._suffixes()):
            if self.output_name(suffix) in out:
                out[self.output_name(suffix)][:] = values[:, j]
        if self.name in wanted:
            status[:] = np.where((status == st.OK) & ok & np.isnan(verdict), st.UNDECIDED, status)
        if self.output_name("_settling") in wanted:
            status[:] = np.where((status == st.OK) & ok & np.isnan(t_settle), st.NO_EVENT, status)


@_records_where
@dataclass(frozen=True)
class History(_Outputs):
    """Samples of an observable ``of`` (a state name or ``f(t, y, p)``) at ``samples`` instants
    evenly spread over [0, horizon] forcing periods: an output with one extra dimension ``dim``
    (coordinate: the instants in forcing periods; every History of a model with the same ``dim``
    must use the same horizon and samples). ``value(p, x) -> float`` (optional): each stored sample
    from the observed one, per point (applied to finite samples). Status: integration failures as
    reported; NONFINITE for a non-finite sample. Cost: shared integration, one dense output per step with a sample.

    Parameters
    ----------
    name : str
        The output's name.
    of : str or callable
        A state's name, or ``f(t, y, p) -> float``.
    horizon : float, optional
        Forcing periods simulated.
    samples : int, optional
        Instants stored, evenly spread over [0, horizon] periods.
    dim : str, optional
        The extra dimension's name (Histories sharing one share horizon and samples).
    dim_long_name : str, optional
        Its coordinate's long name.
    unit : str, optional
        UDUNITS-2 unit of the output.
    long_name : str, optional
        What the output is, in words (default: made from the declaration).
    value : callable, optional
        ``value(p, x) -> float`` per stored sample.
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its outputs NaN with that status).
    output_meta : Mapping, optional
        Output name -> dict of ``symbol``/``long_name``/``unit`` for the derived outputs.
    """

    name: str
    of: object
    horizon: object = 100.0
    samples: object = 200
    dim: str = "period"
    dim_long_name: str = "time in forcing periods t / T"
    unit: str = ""
    long_name: str = ""
    value: Callable | None = field(default=None, repr=False, compare=False)
    classify: Callable | None = field(default=None, repr=False, compare=False)  # where it applies (OdeModel)
    output_meta: object = ()  # {name: {symbol, unit, long_name, latex}} (_Outputs; its one output is the main one)
    sampled = True
    n_values = 0

    def coordinate(self, settings) -> np.ndarray:
        return np.linspace(0.0, _number(self.horizon, settings), int(_number(self.samples, settings)))

    def outputs(self) -> tuple[Output, ...]:
        from .spec import ExtraDim
        what = self.of if isinstance(self.of, str) else self.name
        dim = ExtraDim(self.dim, "1", self.dim_long_name, self._coordinate_defaults)
        return (self._output("", f"{what}(t)", self.unit, self.long_name or f"{what} over the simulation",
                             integrated=True, extra_dims=(dim,)),)

    def _coordinate_defaults(self, settings):
        return self.coordinate(settings)

    def validate(self, states):
        self._check_meta()
        _observable(self.of, states, self.name)
        _check_numbers(self, ("horizon", "samples"))
        _check_ranges(self, _HISTORY)
        _check_value(self, "value")

    def check_settings(self, settings):
        """The fields that name a setting: the setting's range within the field's."""
        _check_ranges(self, _HISTORY, settings)

    def setting_names(self):
        return tuple(x for x in (self.horizon, self.samples) if isinstance(x, str))

    def functions(self):
        out = () if isinstance(self.of, str) else (("of", self.of),)
        return out + ((("value", self.value),) if self.value is not None else ())

    def key(self) -> tuple:
        return ("History", self.name, self.of if isinstance(self.of, str) else None)

    def instants(self, settings):
        return [(self.coordinate(settings), 1)]

    def constants(self, settings):
        return ()


@dataclass(frozen=True)
class Recheck:
    """The reproducibility re-check of the sampled-trajectory outputs (an ``OdeModel(recheck=...)``
    option): the points whose trajectory integrated successfully are integrated once more by the
    same method at rtol' = min(rtol, max(rtol / ``tighten``, ``rtol_floor``)) (the same atol and
    max_steps), and every value of the chosen sampled measurements is compared (Steady's peak,
    harmonic and phase, Kick's verdict, settling time and final error, every History sample, as
    stored, i.e. after ``value``/``time_value``): a value that moved by more than
    factor (rtol max(|v|, |v'|) + atol), or is NaN in one run only, or a second run that fails,
    gives the point NOT_REPRODUCIBLE. The first run's values are kept; NOT_REPRODUCIBLE replaces
    OK, NO_EVENT and UNDECIDED (it ranks above the statuses that leave a value NaN for a reason,
    below integration failures). ``factor`` is a number or the name of one of the model's
    settings; factor <= 0 turns the check off. ``skip_settled`` (optional): the name of a Kick
    whose points are not integrated again when its settling time (before ``time_value``) is at
    most ``settled_fraction`` of the simulated time (they end on an attracting motion); that Kick
    is observed at every integrated point for this (also where its own classify skips it, and when
    none of its outputs is asked for). ``skip_locked`` (with ``skip_settled``): neither are the
    points whose state, sampled at the whole forcing periods of the second half of that Kick's
    horizon, changes by at most factor (rtol + atol) from one period to the next (the largest
    change of any state, less ``rate`` times the elapsed time for the states of ``lock_rates`` =
    ((state, rate), ...), e.g. an angle that turns with the forcing): locked to the forcing period.
    Only the asked-for outputs are compared (where their measurement applies at the point);
    ``measured_units``: before ``value``/``time_value`` (in the units the integration measures).
    Both runs count in n_steps/n_rhs. Cost: up to one more integration per point, at the tighter rtol.
    ``every_measurement``: the measurements outside the sampled trajectory too (FirstEvent, Crossing,
    Period, StateAt, Extremum, Floquet): the points where they succeeded (status OK) are integrated
    again at rtol' and their asked-for outputs compared by the same rule, as stored -- the generic
    conditioning test of a user model (e.g. a period near a separatrix that carries fewer correct
    digits than factor x rtol gets NOT_REPRODUCIBLE instead of ok)."""

    factor: object = 1000.0
    tighten: float = 100.0
    rtol_floor: float = 1e-14
    skip_settled: str | None = None
    settled_fraction: float = 0.5
    skip_locked: bool = False
    lock_rates: tuple = ()
    measured_units: bool = False
    every_measurement: bool = False

    def validate(self, measurements, settings):
        if isinstance(self.factor, str):
            if self.factor not in {x.name for x in settings}:
                raise ValueError(f"recheck: factor = {self.factor!r} is not one of the model's settings")
        elif not (isinstance(self.factor, (int, float)) and math.isfinite(self.factor)):
            raise ValueError(f"recheck: factor = {self.factor!r}; expected a finite number or the name of a setting")
        if not (self.tighten >= 1.0 and math.isfinite(self.tighten)):
            raise ValueError(f"recheck: tighten = {self.tighten!r}; expected a finite number >= 1")
        if not self.rtol_floor > 0.0:
            raise ValueError(f"recheck: rtol_floor = {self.rtol_floor!r}; expected a number > 0")
        if self.skip_settled is not None:
            kicks = [m.name for m in measurements if type(m).__name__ == "Kick"]
            if self.skip_settled not in kicks:
                raise ValueError(f"recheck: skip_settled = {self.skip_settled!r}; expected the name of one of the "
                                 f"model's Kick measurements ({', '.join(kicks) or 'none'})")
            if not 0.0 <= self.settled_fraction <= 1.0:
                raise ValueError(f"recheck: settled_fraction = {self.settled_fraction!r}; expected a fraction in "
                                 "[0, 1]")

        if self.skip_locked and self.skip_settled is None:
            raise ValueError("recheck: skip_locked needs skip_settled (the Kick whose horizon the lock test spans)")

    def tight_rtol(self, rtol: float) -> float:
        return min(rtol, max(rtol / self.tighten, self.rtol_floor))


MEASUREMENTS = (Crossing, Period, StateAt, Extremum, Floquet, FirstEvent, Steady, Kick, History)
