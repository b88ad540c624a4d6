"""The sampled-trajectory measurements of an :class:`~mechsweep.model.ode.OdeModel`: Steady, Kick,
History, RMS, and the re-check of their outputs (Recheck).

They observe ONE integration per point from ``initial(p)`` (engine/trajectory.py), sampled at instants
given in forcing periods s (t = T s, T = ``forcing_period(p)``, or T = 1 for a model without one); the
union of the chosen measurements' instants is one grid shared by every point. Offered by dop853, radau
and auto. A number field may instead name one of the model's settings (a str): its value is read from
the scene's solver settings.

Each declares what it records, in one place:

- ``instants(settings)``: [(s, bits)]: its sample instants and the roles of each (bits, or a function
  of s); ``constants(settings)``: the numbers its observer reads (its row of K), and
  ``constants_for(settings, wanted)`` those when only the outputs ``wanted`` are asked for;
- ``n_values``: its columns in the kernel's value table (0: a History's samples, in ``hist``);
- ``observer(plan, k)``: the jitted ``observe(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh,
  ob, ob2) -> status`` of measurement k in the kernel: its observable(s) on its rows (te: the sample
  times, traj: the states there), its values into vals[i, its columns];
- ``finish(values, wanted, solver, out, status)``: its outputs from its value columns, in Python.

What they check and report alike (fields and ranges, settings named, functions, key) is ``_Sampled``'s.

Over 700 lines on purpose: each measurement keeps its declaration, checks and what it records
(instants, observer, finish) together, so that a new one is one class here and its tests.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .spec import Output, setting_value
from .. import status as st
from ..status import NONFINITE as st_NONFINITE, OK as st_OK
from . import measure
from .measure import _Outputs, _check_function, _observable, _records_where

__all__ = ["Steady", "Kick", "History", "RMS", "Recheck"]  # mechsweep.model exports them

TWO_PI = 2.0 * math.pi


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
_RMS = {"horizon": _POSITIVE, "window": _Range(0.0, 1.0, lo_open=True), "samples_per_period": _Range(2.0)}


class _Sampled(_Outputs):
    """What every sampled measurement checks and reports the same way: its observables (``OBSERVED``:
    a state's name or a function f(t, y, p)), its numeric fields and their ranges (``RULES``; each may
    name a setting unless in ``FIXED``; one in ``OPTIONAL`` may be None) and its ``value`` transform
    (the field ``VALUE``)."""

    OBSERVED = ("of",)
    RULES = {}
    FIXED = ()
    OPTIONAL = ()
    VALUE = "value"
    sampled = True
    # its outputs' long names say "T = 1 time unit" where the model declares no forcing period (a window
    # or a harmonic counted in T; OdeModel.spec)
    SAYS_PERIOD = False

    def _present(self, fields):
        return [f for f in fields if not (f in self.OPTIONAL and getattr(self, f) is None)]

    def validate(self, states):
        self._check_meta()
        for f in self._present(self.OBSERVED):
            _observable(getattr(self, f), states, self.name)
        _check_numbers(self, self._present(f for f in self.RULES if f not in self.FIXED))
        _check_ranges(self, self.RULES)
        _check_function(self, self.VALUE, f"{self.VALUE}(p, x) -> float (got {getattr(self, self.VALUE)!r})")

    def constants_for(self, settings, wanted):
        """Its constants when only the outputs ``wanted`` are asked for: those of ``constants`` unless
        one switches off work whose outputs nobody asked for."""
        return self.constants(settings)

    def check_settings(self, settings):
        """The fields that name a setting: the setting's range within the field's."""
        _check_ranges(self, self.RULES, settings)

    def setting_names(self):
        return tuple(x for x in (getattr(self, f) for f in self.RULES if f not in self.FIXED) if isinstance(x, str))

    def functions(self):
        observed = [(f, getattr(self, f)) for f in self._present(self.OBSERVED)]
        value = getattr(self, self.VALUE)
        functions = tuple((f, x) for f, x in observed if not isinstance(x, str))
        return functions + ((("value", value),) if value is not None else ())

    def key(self) -> tuple:
        return (type(self).__name__, self.name) + tuple(
            x if isinstance(x, str) else None for x in (getattr(self, f) for f in self.OBSERVED))

    def _value(self, plan, k):
        """Its ``value`` transform in the kernel (the identity when it has none)."""
        return plan.transform(getattr(self, self.VALUE), f"value{k}") or compiled(_same_value, True)

    def finish(self, values, wanted, solver, out, status):
        """Its outputs from its value columns (its j-th output is its j-th column)."""
        for j, suffix in enumerate(self._suffixes()):
            if self.output_name(suffix) in out:
                out[self.output_name(suffix)][:] = values[:, j]

    def _window(self, settings):
        """(H, w, n): the horizon, the window's fraction of it and the window's number of samples."""
        H, w = setting_value(self.horizon, settings), setting_value(self.window, settings)
        return H, w, max(2, int(math.ceil(setting_value(self.samples_per_period, settings) * w * H)) + 1)


@_records_where
@dataclass(frozen=True)
class Steady(_Sampled):
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
    RULES = _STEADY
    OPTIONAL = ("settle_rtol",)
    SAYS_PERIOD = True
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

    def instants(self, settings):
        """(s, bits): this measurement's sample instants in forcing periods and their roles
        (1: the last window, 2: the window before it)."""
        H, w, n = self._window(settings)
        out = [(np.linspace((1.0 - w) * H, H, n), 1)]
        if self.settle_rtol is not None:  # the window before, for the settling test
            out.append((np.linspace((1.0 - 2.0 * w) * H, (1.0 - w) * H, n), 2))
        return out

    def constants(self, settings):
        """The numbers the kernel's observer reads (K row)."""
        check = self.settle_rtol is not None
        # the third: whether the first harmonic is computed (see constants_for)
        return (setting_value(self.settle_rtol, settings) if check else -1.0, setting_value(self.settle_atol, settings),
                1.0)

    def constants_for(self, settings, wanted):
        """Without the first harmonic when neither name_h1 nor name_phase is asked for: the observer
        then skips its cos/sin per sample."""
        c = self.constants(settings)
        return c if {self.output_name("_h1"), self.output_name("_phase")} & set(wanted) else c[:2] + (0.0,)

    def observer(self, plan, k):
        """Its observer in the sampled-trajectory kernel (engine/trajectory.py): the observable on its
        rows, then ``steady_observe`` into its columns; ``value`` on the peak and first harmonic."""
        return _steady_observer(plan.observable(self.of, f"of{k}"), self._value(plan, k), k, plan.cols[k],
                                plan.cols[k + 1], plan.raw)

    def finish(self, values, wanted, solver, out, status):
        settled = values[:, 3] == 1.0
        super().finish(np.where(settled[:, None], values, np.nan), wanted, solver, out, status)
        if any(self.output_name(x) in wanted for x in self._suffixes()):
            unsettled = np.isfinite(values[:, 0]) & ~settled
            status[:] = np.where((status == st.OK) & unsettled, st.NO_EVENT, status)


@_records_where
@dataclass(frozen=True)
class Kick(_Sampled):
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
    OBSERVED = ("error", "response")
    RULES = _KICK
    FIXED = ("late", "early")
    OPTIONAL = ("response", "growth_floor")
    VALUE = "time_value"
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

    def key(self) -> tuple:
        return super().key() + (self.response is None, float(self.late), float(self.early))

    def instants(self, settings):
        """(s, bits): 1 every monitor row, 2 the first period, 4 the first ``early`` fraction, 8 the
        last ``late`` fraction, 16 the ``late`` fraction before it (bits 2-16 only on monitor rows)."""
        H = setting_value(self.horizon, settings)
        mon = int(setting_value(self.monitor_per_period, settings))
        dense = int(setting_value(self.dense_per_period, settings))
        late0 = (1.0 - self.late) * H
        parts = [np.linspace(0.0, H, max(2, int(math.ceil(mon * H)) + 1)),
                 np.linspace(late0, H, max(2, int(math.ceil(dense * self.late * H)) + 1)),
                 np.linspace(0.0, min(1.0, H), mon + 1)]
        return [(x, self._bits) for x in parts]

    def _bits(self, s, settings):
        H = setting_value(self.horizon, settings)
        late0, before0 = (1.0 - self.late) * H, (1.0 - 2.0 * self.late) * H
        return (1 | np.where(s <= min(1.0, H), 2, 0) | np.where(s <= self.early * H, 4, 0)
                | np.where(s >= late0, 8, 0) | np.where((s >= before0) & (s < late0), 16, 0))

    def constants(self, settings):
        settle = setting_value(self.settle_threshold, settings)
        floor = 1e-3 * settle if self.growth_floor is None else setting_value(self.growth_floor, settings)
        return (settle, setting_value(self.decay_ratio, settings), setting_value(self.growth_ratio, settings), floor)

    def observer(self, plan, k):
        """Its observer in the sampled-trajectory kernel (engine/trajectory.py): error (and response) on
        its rows, then ``kick_observe`` into its columns; ``time_value`` on the settling time."""
        response = (compiled(_no_response, True) if self.response is None
                    else plan.observable(self.response, f"response{k}"))
        return _kick_observer(plan.observable(self.error, f"error{k}"), response, self.response is not None,
                              self._value(plan, k), k, plan.cols[k], plan.cols[k + 1], plan.raw)

    def finish(self, values, wanted, solver, out, status):
        super().finish(values, wanted, solver, out, status)
        ok = np.isfinite(values[:, 2])
        verdict, t_settle = values[:, 0], values[:, 1]
        if self.name in wanted:
            status[:] = np.where((status == st.OK) & ok & np.isnan(verdict), st.UNDECIDED, status)
        if self.output_name("_settling") in wanted:
            status[:] = np.where((status == st.OK) & ok & np.isnan(t_settle), st.NO_EVENT, status)


@_records_where
@dataclass(frozen=True)
class History(_Sampled):
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
    RULES = _HISTORY
    n_values = 0

    def coordinate(self, settings) -> np.ndarray:
        return np.linspace(0.0, setting_value(self.horizon, settings), int(setting_value(self.samples, settings)))

    def outputs(self) -> tuple[Output, ...]:
        from .spec import ExtraDim
        what = self.of if isinstance(self.of, str) else self.name
        dim = ExtraDim(self.dim, "1", self.dim_long_name, self._coordinate_defaults)
        return (self._output("", f"{what}(t)", self.unit, self.long_name or f"{what} over the simulation",
                             integrated=True, extra_dims=(dim,)),)

    def _coordinate_defaults(self, settings):
        return self.coordinate(settings)

    def observer(self, plan, k):
        """Its observer in the sampled-trajectory kernel (engine/trajectory.py): the observable at each
        of its rows into its columns of ``hist`` (from hoff[k]), ``value`` applied to finite samples."""
        return _history_observer(plan.observable(self.of, f"of{k}"), self._value(plan, k), k, plan.raw)

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
            kicks = [m.name for m in measurements if isinstance(m, Kick)]
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

    def moved(self, a, b, factor, solver):
        """Where a value of the first run ``a`` moved in the second ``b``: by more than
        factor (rtol max(|a|, |b|) + atol), or NaN in one run only."""
        with np.errstate(invalid="ignore"):
            tol = factor * (solver.rtol * np.maximum(np.abs(a), np.abs(b)) + solver.atol)
            return (np.abs(a - b) > tol) | (np.isnan(a) != np.isnan(b))




@functools.cache
def compiled(func, into_caller: bool = False):
    """``func``, a per-sample helper of this module, compiled by numba (``into_caller``: inlined into
    its callers): made on first use, so that importing the declarations loads no numba."""
    from .._jit import jit, jit_into_caller

    return (jit_into_caller if into_caller else jit)(func)


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
                return st_NONFINITE
            prev = max(prev, abs(ob[j]))
        if bits[j] & 1:
            x = ob[j]
            if not math.isfinite(x):
                return st_NONFINITE
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
    return st_OK


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
            return st_NONFINITE
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
    return st_OK


# ---------------------------------------------------------------- the sampled measurements' observers
# ``observe(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2) -> status`` of measurement k
# (engine/trajectory.py): te the sample times, traj the states there, bits[:, k] its rows' roles, K[k] its
# constants, vals[i] its value columns (rawv: before value/time_value, where the kernel has them), hist[i]
# the History rows from hoff[k]; ob, ob2 scratch of one float per sample.
def _same_value(p, x):
    return x


def _no_response(t, y, p):
    return 0.0


@functools.cache
def _steady_observer(of, value, k, c0, c1, raw):
    from .._jit import jit_into_caller

    steady = compiled(steady_observe)

    @jit_into_caller
    def observe(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2):
        for j in range(s.size):
            if bits[j, k]:
                ob[j] = of(te[j], traj[j], p)
        c = steady(ob, s, bits[:, k], K[k], vals[i, c0:c1])
        if raw and rawv.shape[1] != 0:  # the measured values, before the transform
            for q in range(c0, c1):
                rawv[i, q] = vals[i, q]
        if c == st_OK:
            for q in range(c0, c0 + 2):
                if math.isfinite(vals[i, q]):
                    vals[i, q] = value(p, vals[i, q])
        return c

    return observe


@functools.cache
def _kick_observer(error, response, has_r, value, k, c0, c1, raw):
    from .._jit import jit_into_caller

    kick = compiled(kick_observe)

    @jit_into_caller
    def observe(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2):
        for j in range(s.size):
            if bits[j, k]:
                ob[j] = error(te[j], traj[j], p)
                if has_r:
                    ob2[j] = response(te[j], traj[j], p)
        c = kick(ob, ob2, has_r, te, bits[:, k], K[k], vals[i, c0:c1])
        vals[i, c0 + 3] = vals[i, c0 + 1]  # the settling time before time_value
        vals[i, c0 + 4] = te[s.size - 1]  # the simulated time
        if raw and rawv.shape[1] != 0:
            for q in range(c0, c1):
                rawv[i, q] = vals[i, q]
        if c == st_OK:
            for q in range(c0 + 1, c0 + 2):
                if math.isfinite(vals[i, q]):
                    vals[i, q] = value(p, vals[i, q])
        return c

    return observe


@functools.cache
def _history_observer(of, value, k, raw):
    from .._jit import jit_into_caller

    @jit_into_caller
    def observe(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2):
        raw_h = raw and rawh.shape[1] != 0
        c = st_OK
        h = hoff[k]
        for j in range(s.size):
            if bits[j, k]:
                v = of(te[j], traj[j], p)
                if raw_h:
                    rawh[i, h] = v
                if math.isfinite(v):
                    v = value(p, v)
                if not math.isfinite(v):
                    c = st_NONFINITE
                hist[i, h] = v
                h += 1
        return c

    return observe


@_records_where
@dataclass(frozen=True)
class RMS(_Sampled):
    """Root mean square of an observable ``of`` (a state name or ``f(t, y, p)``) over the last
    ``window`` (a fraction, 0 < window <= 1) of a simulation of ``horizon`` forcing periods:
    sqrt(int x^2 dt / L) over the window of length L, by the trapezoid rule on ``samples_per_period``
    samples per forcing period (exact to round-off for a T-periodic signal x = A cos(2 pi t / T - phi)
    over a whole number of periods: A / sqrt(2)). ``value(p, x) -> float`` (optional): the stored RMS
    from the measured one, per point (e.g. in SI units), applied to a finite value.
    Status: integration failures as reported; NONFINITE for a non-finite sample.
    Cost: the shared sampled integration plus one dense-output evaluation per step with a sample.

    Parameters
    ----------
    name : str
        The output's name.
    of : str or callable
        A state's name, or ``f(t, y, p) -> float``.
    horizon : float or str, optional
        Forcing periods simulated (or the name of a setting).
    window : float or str, optional
        The fraction of the horizon at its end that is measured, in (0, 1].
    samples_per_period : int or str, optional
        Samples per forcing period in the window (at least 2).
    unit : str, optional
        UDUNITS-2 unit of the output.
    long_name : str, optional
        What the output is, in words (default: made from the declaration).
    value : callable, optional
        ``value(p, x) -> float``: the stored RMS from the measured one.
    classify : callable, optional
        ``classify(p) -> status``: skip this measurement at a point (its output NaN with that status).
    output_meta : Mapping, optional
        Output name -> dict of ``symbol``/``long_name``/``unit``/``latex`` for its output.
    """

    name: str
    of: object
    horizon: object = 100.0
    window: object = 0.1
    samples_per_period: object = 64
    unit: str = ""
    long_name: str = ""
    value: Callable | None = field(default=None, repr=False, compare=False)
    classify: Callable | None = field(default=None, repr=False, compare=False)  # where it applies (OdeModel)
    output_meta: object = ()  # {name: {symbol, unit, long_name, latex}} (_Outputs; its one output is the main one)
    RULES = _RMS
    SAYS_PERIOD = True
    n_values = 1

    def outputs(self) -> tuple[Output, ...]:
        what = self.of if isinstance(self.of, str) else self.name
        return (self._output("", f"rms {what}", self.unit,
                             self.long_name or f"root mean square of {what} over the last {self.window} of the horizon",
                             integrated=True),)

    def instants(self, settings):
        """(s, bits): the window's sample instants in forcing periods, role 1."""
        H, w, n = self._window(settings)
        return [(np.linspace((1.0 - w) * H, H, n), 1)]

    def constants(self, settings):
        return ()

    def observer(self, plan, k):
        """The observable on its rows, the trapezoid rule of its square, ``value`` on the result."""
        return _rms_observer(plan.observable(self.of, f"of{k}"), self._value(plan, k), k, plan.cols[k], plan.raw)


def rms_observe(ob, s, bits):
    """sqrt((1 / L) int ob^2 ds) over the rows with bits (trapezoid rule), L their span; NaN for a
    non-finite sample."""
    acc = 0.0
    s_first = math.nan
    s_old = 0.0
    x2_old = 0.0
    started = False
    for j in range(s.size):
        if bits[j]:
            x = ob[j]
            if not math.isfinite(x):
                return math.nan
            x2 = x * x
            if started:
                acc += 0.5 * (s[j] - s_old) * (x2_old + x2)
            else:
                s_first = s[j]
                started = True
            s_old = s[j]
            x2_old = x2
    return math.sqrt(acc / (s_old - s_first))


@functools.cache
def _rms_observer(of, value, k, col, raw):
    from .._jit import jit_into_caller

    rms = compiled(rms_observe)

    @jit_into_caller
    def observe(i, p, te, traj, s, bits, K, hoff, vals, hist, rawv, rawh, ob, ob2):
        for j in range(s.size):
            if bits[j, k]:
                ob[j] = of(te[j], traj[j], p)
        r = rms(ob, s, bits[:, k])
        if raw and rawv.shape[1] != 0:
            rawv[i, col] = r
        if not math.isfinite(r):
            return st_NONFINITE
        vals[i, col] = value(p, r)
        return st_OK

    return observe


MEASUREMENTS = measure.MEASUREMENTS + (Steady, Kick, History, RMS)
