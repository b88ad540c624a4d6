"""Declarations of model parameters and outputs: one place for names, units and ranges.

A model module declares a :class:`ModelSpec` beside its kernels. Everything else
(scene validation, dataset attributes, the docs glossary, figure labels) reads it.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from collections.abc import Mapping
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class Param:
    """A model parameter: a float in [lo, hi] (ends open or closed) or one of ``choices``.

    A scene gives every required parameter once, as an axis or as a fixed value; a value outside
    the range is refused before anything runs, with the key, the value and :meth:`allowed` named.

    Parameters
    ----------
    name : str
        The key in a scene's ``[axes]`` or ``[fixed]`` table and the dataset's coordinate name.
    symbol : str
        How the parameter is written in formulas (``"ω"``, ``"λ1"``), for labels and the glossary.
    unit : str
        UDUNITS-2 unit string, as CF datasets store it (``"rad s-1"``, ``"kg m2"``, ``"1"`` for a
        dimensionless value); a label only: nothing converts values.
    long_name : str
        What the parameter is, in words (the dataset's ``long_name`` attribute).
    lo, hi : float, optional
        The physical range (default: unbounded).
    lo_open, hi_open : bool, optional
        Whether ``lo`` / ``hi`` themselves are excluded (default: included).
    choices : tuple of str, optional
        The names of a categorical parameter (the scene gives a name, the kernel receives its
        index as a float: 0.0, 1.0, ...).
    required : bool, optional
        False: the scene may leave the parameter out, and ``default`` is used.
    default : float or None, optional
        The value of an optional parameter a scene does not give.
    latex : str, optional
        The symbol in matplotlib mathtext for figure labels (e.g. ``r"$\\omega_\\xi$"``; it may
        define the symbol, as in ``r"$\\varepsilon = \\mu A^2/\\omega^2$"``). Without one, figures
        write ``symbol`` as mathtext themselves.
    aliases : tuple of str, optional
        Former names a scene, a stored scene or a call may still use for the parameter (e.g.
        ``"lambda"``, a Python keyword, for the slider-crank's ``lam``); datasets use ``name``.

    Examples
    --------
    >>> from mechsweep.model import Param
    >>> L = Param("L", "L", "m", "pendulum length", lo=0.0, lo_open=True)
    >>> L.allowed()
    'a finite number in (0, inf)'
    >>> L.problem(-1.0)
    '-1.0 m is outside the physical range; expected a finite number in (0, inf)'
    """

    name: str
    symbol: str
    unit: str
    long_name: str
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[str, ...] = ()
    required: bool = True
    default: float | None = None
    latex: str = ""  # stored as the variable's ``latex`` attribute
    aliases: tuple[str, ...] = field(default=(), repr=False)  # not in the repr, which keys a user model's scenes

    def __post_init__(self):
        # a range no value satisfies, or a default its own range refuses, would be found by a scene
        # (every value refused, "in [10, 0]") or never (the default used as it is): refused here
        if not self.categorical:
            lo, hi = float(self.lo), float(self.hi)
            if math.isnan(lo) or math.isnan(hi) or lo > hi or (lo == hi and (self.lo_open or self.hi_open)):
                raise ValueError(f"parameter {self.name!r}: lo = {self.lo!r}, hi = {self.hi!r} (lo_open = "
                                 f"{self.lo_open}, hi_open = {self.hi_open}) admit no value; expected lo < hi")
        default = self.default
        if default is None and not self.required:  # the kernel would receive NaN: every point nonfinite
            raise ValueError(f"parameter {self.name!r}: required=False needs a default (the value used where a "
                             "scene leaves the parameter out; NaN for 'not given', for the model's check)")
        if default is None or (isinstance(default, numbers.Real) and math.isnan(default)):
            return  # no default, or NaN: "not given", for a model's check() to tell apart
        if self.categorical:
            if (isinstance(default, bool) or not isinstance(default, numbers.Real) or not float(default).is_integer()
                    or not 0 <= default < len(self.choices)):
                raise ValueError(f"parameter {self.name!r}: default = {default!r} is not the index of one of its "
                                 f"choices; expected a whole number in [0, {len(self.choices) - 1}]")
        elif (why := self.problem(default)) is not None:
            raise ValueError(f"parameter {self.name!r}: default = {why}")

    @property
    def categorical(self) -> bool:
        return bool(self.choices)

    def allowed(self) -> str:
        """Human-readable allowed range, used in every error message."""
        if self.categorical:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        left = "(" if self.lo_open or self.lo == -math.inf else "["
        right = ")" if self.hi_open or self.hi == math.inf else "]"
        return f"a finite number in {left}{_fmt(self.lo)}, {_fmt(self.hi)}{right}"

    def problem(self, value) -> str | None:
        """Why ``value`` is not allowed, or None when it is."""
        if self.categorical:
            if not isinstance(value, str) or value not in self.choices:
                return f"{value!r} is not allowed; expected {self.allowed()}"
            return None
        if isinstance(value, bool) or not isinstance(value, numbers.Real):  # numpy numbers are numbers
            return f"{value!r} is not a number; expected {self.allowed()}"
        v = float(value)
        if not math.isfinite(v):
            return f"{value!r} is not finite; expected {self.allowed()}"
        below = v <= self.lo if self.lo_open else v < self.lo
        above = v >= self.hi if self.hi_open else v > self.hi
        if below or above:
            unit = f" {self.unit}" if self.unit not in ("", "1") else ""
            return f"{value!r}{unit} is outside the physical range; expected {self.allowed()}"
        return None

    def encode(self, value) -> float:
        """The float a kernel sees: the value, or the index of a choice."""
        return float(self.choices.index(value)) if self.categorical else float(value)


@dataclass(frozen=True)
class Setting:
    """A model-specific numerical setting, given in the scene's ``[solver]`` table (e.g. a horizon).

    Its value reaches the model's functions in ``p`` after the parameters (see
    :class:`~mechsweep.model.OdeModel`) and is stored in the dataset's attributes.

    Parameters
    ----------
    name : str
        The key in ``[solver]``.
    default : float
        The value when the scene does not give one.
    unit : str
        UDUNITS-2 unit string.
    long_name : str
        What the setting is, in words.
    lo, hi : float
        The allowed range (both ends included).
    integer : bool, optional
        True: only whole numbers are allowed.
    """

    name: str
    default: float
    unit: str
    long_name: str
    lo: float
    hi: float
    integer: bool = False

    def problem(self, value) -> str | None:
        kind = "a whole number" if self.integer else "a number"
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or (
                self.integer and not isinstance(value, numbers.Integral)):
            return f"{value!r} is not allowed; expected {kind} in [{_fmt(self.lo)}, {_fmt(self.hi)}]"
        if not math.isfinite(float(value)) or not self.lo <= value <= self.hi:
            return f"{value!r} is outside the allowed range [{_fmt(self.lo)}, {_fmt(self.hi)}] ({self.long_name})"
        return None


@dataclass(frozen=True)
class ExtraDim:
    """A dimension an output has beyond the grid's (e.g. time samples of a trajectory).

    Parameters
    ----------
    name : str
        The dimension's name in the dataset.
    unit : str
        UDUNITS-2 unit string of its coordinate.
    long_name : str
        What the coordinate is, in words.
    values : callable
        ``values(settings) -> numpy.ndarray``: the coordinate, from the scene's solver settings.
    """

    name: str
    unit: str
    long_name: str
    values: Callable = field(repr=False, compare=False)


@dataclass(frozen=True)
class Output:
    """A model output: one data variable of the dataset.

    The measurements of :mod:`mechsweep.model` declare their outputs themselves; a
    :class:`~mechsweep.model.ClosedFormModel` declares them with this class.

    Parameters
    ----------
    name : str
        The name a scene lists in ``outputs`` and the dataset's variable name.
    symbol : str
        How the output is written in formulas, for labels and the glossary.
    unit : str
        UDUNITS-2 unit string (``"1"`` for a dimensionless value).
    long_name : str
        What the output is, in words (the variable's ``long_name``).
    integrated : bool, optional
        True when computing it needs an integration (the scene's ``[solver]`` then applies).
    needs : tuple of str, optional
        Outputs it is derived from: computed, not stored, unless the scene asks for them too.
    needs_params : tuple of str, optional
        Optional parameters it requires: a scene asking for it must give them.
    extra_dims : tuple of ExtraDim, optional
        The dimensions it has beyond the grid's (e.g. crank positions, time samples).
    kind : str, optional
        What the value means, for the generic figures: one of ``OUTPUT_KINDS``
        (``"floquet_max"``: a largest Floquet multiplier modulus, stable below 1; ``"verdict"``:
        1 stable or feasible, 0 not) or ``""``.
    latex : str, optional
        The symbol in matplotlib mathtext for figure labels (see :class:`Param`).
    """

    name: str
    symbol: str
    unit: str
    long_name: str
    integrated: bool = False
    needs: tuple[str, ...] = ()
    needs_params: tuple[str, ...] = ()
    extra_dims: tuple[ExtraDim, ...] = ()
    kind: str = ""  # what the value is, for generic figures: OUTPUT_KINDS names the known ones
    latex: str = ""  # the symbol in mathtext, for figures (as Param.latex)

    def __post_init__(self):
        if self.kind not in ("",) + OUTPUT_KINDS:  # a misspelt kind would silently draw the wrong figure
            raise ValueError(f"output {self.name!r}: kind = {self.kind!r} is not allowed; expected one of "
                             + ", ".join(repr(k) for k in OUTPUT_KINDS) + " or '' (no kind: a generic figure)")


# Kinds of output the generic figures know (stored as the variable's ``mechsweep_kind``):
# "floquet_max": the largest modulus of the Floquet multipliers; below 1 the motion is stable.
# "verdict": 1 = stable (or feasible), 0 = not; NaN where undecided. `mechsweep info` compares any two.
OUTPUT_KINDS = ("floquet_max", "verdict")


@dataclass(frozen=True)
class ModelSpec:
    """Everything the engine knows about a model.

    ``evaluate(P, wanted, solver, out, status, n_steps, n_rhs)`` fills one chunk:
    ``P`` float64 [n, len(params)] in declared order (absent optional parameters
    hold their default), ``wanted`` the tuple of output names to compute (closed
    under ``needs``), ``solver`` the scene's :class:`~mechsweep.scene.Solver` (its
    ``settings`` hold this model's :class:`Setting` values), ``out`` a dict
    name -> float64 array (n,) or (n, *extra dims) prefilled with NaN, ``status``
    int8 (n,) prefilled OK, ``n_steps``/``n_rhs`` int64 (n,) to add counts to.

    ``check(given)`` (optional) receives {parameter: tuple of the values the scene
    gives it} and returns problems of cross-parameter rules as "key: message". A range axis
    gives only its two ends (a range is monotone: they are its extremes), so that a check
    never expands a grid.
    ``methods``: the values of ``solver.method`` this model's integrated outputs support.
    ``statuses``: the status codes (:mod:`mechsweep.status`) a point of this model can get besides
    OK and those its outputs imply (:meth:`possible_statuses`). ``status_notes``: what a
    status means for this model, {code: text} (given as a mapping or as (code, text) pairs; kept
    as sorted pairs), shown with the generic text where this model's datasets and docs are described.
    ``references``: the source documents the model implements (stored as the CF ``references``
    attribute of its datasets; ``source`` when empty).
    ``methods_for(outputs)`` (optional): the methods a choice of outputs (closed under ``needs``)
    supports, when some outputs offer fewer than ``methods``; a scene asking another is refused.
    ``plan(wanted, solver) -> dict`` (optional): what ``evaluate`` computes for ``wanted``, decided
    before any chunk (mechsweep/execution/plan.py stores it with the run): ``measurements`` and ``closed_forms``
    (names), and ``lanes``: {kernel family: {"record", "recorded", "tallied", "from_points", "after_points",
    "forced"}} for each kernel that can also integrate points side by side (its record name, whether it
    is compiled for this CPU, the points earlier runs computed one at a time, the run size from which
    the lanes pay, the tally with the run from which their whole compile pays, the engine's override
    or None; execution/plan.py, ``choose_route``). A spec that has
    ``plan`` takes ``evaluate(..., route={family: "lanes" or "point"})``: the route the run's plan
    chose for each family (bitwise the same results either way); without ``route`` the engine's default.
    """

    name: str
    description: str
    params: tuple[Param, ...]
    outputs: tuple[Output, ...]
    evaluate: Callable = field(repr=False)
    source: str = ""
    settings: tuple[Setting, ...] = ()
    check: Callable | None = field(default=None, repr=False)
    methods: tuple[str, ...] = ("dop853",)  # integration methods `evaluate` offers (solver.method)
    statuses: tuple[int, ...] = ()  # status codes a point can get besides OK and those the outputs imply
    status_notes: tuple[tuple[int, str], ...] = ()  # (code, what the status means for this model)
    references: tuple[str, ...] = ()  # source documents (a dataset's CF `references`; default: source)
    declaration: object = field(default=None, repr=False, compare=False)  # the OdeModel/ClosedFormModel, if any

    def __post_init__(self):
        notes = self.status_notes
        pairs = notes.items() if isinstance(notes, Mapping) else notes
        object.__setattr__(self, "status_notes", tuple(sorted((int(c), str(t)) for c, t in pairs)))
        object.__setattr__(self, "statuses", tuple(sorted({int(c) for c in self.statuses})))
        refs = self.references
        object.__setattr__(self, "references", (refs,) if isinstance(refs, str) else tuple(refs))

    def possible_statuses(self) -> tuple[int, ...]:
        """The status codes a point of this model can get: OK, the declared ``statuses``, and those
        its outputs imply (a declared list adds to them: ``statuses=(INFEASIBLE,)`` alone would
        hide nonfinite and user_error, which the runner gives any model): NONFINITE (a value that is
        not finite) and USER_ERROR (the model's code raised, or returned a code that is no status); for integrated
        outputs the integrator's failures (MAX_STEPS, STEP_UNDERFLOW, NO_EVENT, and STIFF when it
        offers dop853: a step budget spent at the stability limit); for a "floquet_max" output
        INFEASIBLE (no admissible forcing period) and for a "verdict" output UNDECIDED."""
        from .. import status as st

        codes = {st.OK, *self.statuses, st.NONFINITE, st.USER_ERROR}
        if any(o.integrated for o in self.outputs):
            codes |= {st.MAX_STEPS, st.STEP_UNDERFLOW, st.NO_EVENT}
            if "dop853" in self.methods:
                codes.add(st.STIFF)
        kinds = {o.kind for o in self.outputs}
        if "floquet_max" in kinds:
            codes.add(st.INFEASIBLE)
        if "verdict" in kinds:
            codes.add(st.UNDECIDED)
        return tuple(sorted(codes))

    def status_note(self, code: int) -> str:
        """What status ``code`` means for this model ("" when it declares nothing)."""
        return dict(self.status_notes).get(int(code), "")
    methods_for: Callable | None = field(default=None, repr=False)
    plan: Callable | None = field(default=None, repr=False, compare=False)

    def param(self, name: str) -> Param:
        return self._params_by_name()[name]

    def output(self, name: str) -> Output:
        return self._outputs_by_name()[name]

    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def aliases(self) -> dict[str, str]:
        """{former name: parameter name} of the parameters declared with ``aliases``."""
        return {a: p.name for p in self.params for a in p.aliases}

    def output_names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.outputs)

    def _params_by_name(self) -> dict[str, Param]:
        return {p.name: p for p in self.params}

    def _outputs_by_name(self) -> dict[str, Output]:
        return {o.name: o for o in self.outputs}

    def closure(self, requested) -> tuple[str, ...]:
        """Requested outputs plus everything they depend on, in declaration order."""
        by_name = self._outputs_by_name()
        seen: set[str] = set()
        stack = list(requested)
        while stack:
            name = stack.pop()
            if name not in seen:
                seen.add(name)
                stack.extend(by_name[name].needs)
        return tuple(o.name for o in self.outputs if o.name in seen)

    def needs_integration(self, requested) -> bool:
        by_name = self._outputs_by_name()
        return any(by_name[n].integrated for n in self.closure(requested))


def setting_value(x, settings) -> float:
    """A declared number, or the name of one of the model's settings: its value in ``settings``
    (name -> value, the scene's [solver] settings)."""
    return float(settings[x]) if isinstance(x, str) else float(x)


def wanted_flags(all_names: tuple[str, ...], wanted: tuple[str, ...]) -> np.ndarray:
    """Boolean mask over a kernel's full output layout."""
    return np.array([n in wanted for n in all_names], dtype=np.bool_)


def _fmt(x: float) -> str:
    if x == math.inf:
        return "inf"
    if x == -math.inf:
        return "-inf"
    short = f"{x:g}"
    # the exact bound where 6 digits would move it (pi read as 3.14159 made 3.141592 look out of range)
    return short if float(short) == x else repr(float(x))
