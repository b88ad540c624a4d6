"""Generic measurements of an :class:`~mechsweep.model.ode.OdeModel`: declarations of what to record.

Each measurement declares its output(s) (name, unit, long name) and what it records in a kernel:
Crossing, Period, StateAt and Extremum are rows (``shared_row``) of one shared DOP853 integration per
point (engine/shared.py); the others give their block in the one-point kernel (engine/point.py) from
``point(plan, k)``: FirstEvent (and a lone first Crossing) integrates on its own by the scene's method
(engine/events.py), Floquet integrates its variational equations (engine/floquet.py). The sampled
measurements (Steady, Kick, History, RMS: model/sampled.py) give their ``observer(plan, k)`` of the
one sampled trajectory per point (engine/trajectory.py). ClosedForm (a formula output) and System (a second equation) are
declarations the kernels read. Nothing raises in a kernel: a failure is a status code of
:mod:`mechsweep.status` and a NaN value.

Over 700 lines on purpose: each measurement keeps its declaration, checks and what it records in a
kernel together (the user-facing docstrings are most of it).
"""
from __future__ import annotations

import functools
import math
import numbers
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


def _g(x) -> str:
    """A number as %g for a default long name; anything else as its repr (validate() refuses it, naming
    the field: the long name is made first, and must not fail on it)."""
    return f"{x:g}" if isinstance(x, numbers.Real) else repr(x)


def _check_state(state, states, what):
    if state not in states:
        raise ValueError(f"{what}: state {state!r} is not one of the model's states {states}")
    return states.index(state)



def _check_function(m, field_name, text):
    """``field_name`` of measurement ``m`` is a function (or None where it is optional)."""
    if getattr(m, field_name) is not None and not callable(getattr(m, field_name)):
        raise ValueError(f"{m.name}: {field_name} must be a function {text}")


def _observable(x, states, what):
    """A state name (checked) or a function ``f(t, y, p) -> float``."""
    if isinstance(x, str):
        _check_state(x, states, what)
    elif not callable(x):
        raise ValueError(f"{what}: expected a state name or a function f(t, y, p) -> float (got {x!r})")


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


# Crossing, Period, StateAt and Extremum of one point observe ONE DOP853 integration from t = 0
# (engine/shared.py). Each is a row of a float table, its ``shared_row``: (kind, state index, sign,
# level, n, ta, tb).
K_CROSSING, K_PERIOD, K_STATE_AT, K_EXTREMUM, K_EXTREMUM_OF = 0.0, 1.0, 2.0, 3.0, 4.0  # OF: of an expression


def _crossing_row(m, kind, n, states):
    sign = 1.0 if m.direction == "down" else -1.0
    return (kind, float(states.index(m.state)), sign, float(m.level), float(n), float(m.t_max), 0.0)


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
                      self.long_name or f"time of crossing {self.n} of {self.state} = {_g(self.level)} ({self.direction})",
                      integrated=True)

    def validate(self, states):
        _check_state(self.state, states, self.name)
        if self.direction not in DIRECTIONS:
            raise ValueError(f"{self.name}: direction {self.direction!r} is not one of {DIRECTIONS}")
        if not (isinstance(self.n, int) and self.n >= 1):
            raise ValueError(f"{self.name}: n = {self.n!r}; expected a whole number >= 1")
        if not (isinstance(self.t_max, numbers.Real) and not isinstance(self.t_max, bool)
                and math.isfinite(self.t_max) and self.t_max > 0):
            raise ValueError(f"{self.name}: t_max = {self.t_max!r}; expected a finite number > 0 (the same for "
                             "every point: a horizon that depends on the parameters is FirstEvent's t_max(p))")
        if isinstance(self.level, bool) or not isinstance(self.level, (int, float)) or not math.isfinite(self.level):
            raise ValueError(f"{self.name}: level = {self.level!r}; expected a finite number")

    @property
    def direct_alone(self) -> bool:
        """Whether it integrates on its own (engine/events.py) when it is the kernel's only measurement:
        a first crossing needs no shared trajectory."""
        return self.n == 1

    def point(self, plan, k):
        """Its block in the one-point kernel (engine/point.py) when it is the kernel's only measurement
        (a first crossing): integrated on its own (else a row of the shared trajectory)."""
        from ..engine import events
        return events.block(plan, self, k)

    def shared_row(self, states):
        return _crossing_row(self, K_CROSSING, self.n, states)


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
        return Output(self.name, "T", self.unit, self.long_name or f"period of {self.state} (crossings of {_g(self.level)})",
                      integrated=True)

    def validate(self, states):
        Crossing(self.name, self.state, self.level, self.direction, 2, self.t_max).validate(states)

    def shared_row(self, states):
        return _crossing_row(self, K_PERIOD, 2, states)


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

    def shared_row(self, states):
        return (K_STATE_AT, float(states.index(self.state)), 1.0, 0.0, 0.0, float(self.t), 0.0)


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
            return _g(x) if not callable(x) else f"{getattr(x, '__name__', 't')}(p)"
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
        """(role, function) pairs the kernel calls: the expression, the window's ends."""
        return tuple((role, f) for role, f in (("of", self.state), ("t0", self.t0), ("t1", self.t1)) if callable(f))

    def key(self) -> tuple:
        """What the kernel depends on beyond its functions (engine/kernels.py adds their sources)."""
        def num(x):
            return None if callable(x) else float(x)
        return ("Extremum", self.name, self.state if isinstance(self.state, str) else None, num(self.t0),
                num(self.t1), self.kind)

    def shared_row(self, states):
        """A state's row; an expression's (K_EXTREMUM_OF) gets its measurement's index in column 1
        from engine/shared.py. A window end that is a function of p is NaN here (the kernel writes it
        per point)."""
        sign = 1.0 if self.kind == "max" else -1.0
        t0, t1 = (math.nan if callable(x) else float(x) for x in (self.t0, self.t1))
        if not isinstance(self.state, str):
            return (K_EXTREMUM_OF, -1.0, sign, 0.0, 0.0, t0, t1)
        return (K_EXTREMUM, float(states.index(self.state)), sign, 0.0, 0.0, t0, t1)


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
    variational_route = True  # integrated on its own by dop853, radau or auto (ModelSpec.methods_for)

    def point(self, plan, k):
        """Its block in the one-point kernel (engine/point.py, engine/floquet.py)."""
        from ..engine import floquet
        return floquet.block(plan, self, k)

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
        _check_function(self, "initial", "initial(p, y0) (the start of the orbit)")
        _check_function(self, "variational", "variational(t, Phi, p, dPhi) (the variational system about the known "
                        f"orbit; got {self.variational!r})")
        if self.variational_jac is not None and self.variational is None:
            raise ValueError(f"{self.name}: variational_jac is the Jacobian of variational; give variational= "
                             "too (or neither: the engine then integrates the state with its variational system)")
        _check_function(self, "variational_jac", f"variational_jac(t, Phi, p, JJ) (got {self.variational_jac!r})")

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
    declares ``accel``): the kernel integrates it on its own by that method (engine/events.py), one
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
    direct = True  # integrates on its own with solver.method (engine/events.py)
    latex: str = ""  # Output.latex: the symbol in mathtext, for figures

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
        _check_function(self, "value", "value(p, t) -> float")
        if self.system is not None and not isinstance(self.system, System):
            raise ValueError(f"{self.name}: system must be a mechsweep.model.System (got {self.system!r})")
        _check_function(self, "refine", "refine(p, rtol, value) -> float")
        if not (isinstance(self.n, int) and not isinstance(self.n, bool) and self.n >= 1):
            raise ValueError(f"{self.name}: n = {self.n!r}; expected a whole number >= 1")
        if self.direction not in DIRECTIONS:
            raise ValueError(f"{self.name}: direction {self.direction!r} is not one of {DIRECTIONS}")
        if not (isinstance(self.since, int) and not isinstance(self.since, bool) and 0 <= self.since < self.n):
            raise ValueError(f"{self.name}: since = {self.since!r}; expected a whole number 0 <= since < n = {self.n!r}")

    def point(self, plan, k):
        """Its block in the one-point kernel (engine/point.py): integrated on its own, by the scene's
        method (engine/events.py)."""
        from ..engine import events
        return events.block(plan, self, k)

    def functions(self):
        """(role, function) pairs the kernel calls."""
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
        """What the kernel depends on beyond its functions (engine/kernels.py adds their names and sources)."""
        key = ("FirstEvent", self.name, None if callable(self.t_max) else float(self.t_max))
        return key if (self.n, self.direction) == (1, "down") else key + (self.n, self.direction, self.since)


@_records_where
@dataclass(frozen=True)
class ClosedForm:
    """An output given by a formula: ``func(p, *needed) -> float``, plain numba-compilable Python
    of the point's parameters and settings (``p[0 .. len(params) + len(settings) - 1]``) and of the
    values of the outputs named in ``needs`` (other closed forms or measurements), passed in the
    order of ``needs``; e.g. kv = v_max T / A or period_error = |T - T_exact| / T_exact.

    Computed in the kernel only when wanted (or needed by a wanted output), after the
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


MEASUREMENTS = (Crossing, Period, StateAt, Extremum, Floquet, FirstEvent)  # model/sampled.py adds its own
