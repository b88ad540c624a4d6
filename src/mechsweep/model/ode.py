"""OdeModel: a declarative ODE model. The user writes the physics and what to measure; the engine
composes the chunk kernel (mechsweep.engine) and the ModelSpec the runner, store and scene read."""
from __future__ import annotations

import dataclasses
import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .. import status as st
from ..status import mark_not_reproducible, worse
from ..errors import InputError
from .spec import ModelSpec, Param, Setting, setting_value
from .measure import FLOQUET_MARGIN, ClosedForm, Floquet, declared_at

SYMPLECTIC_ORDERS = (2, 4, 6, 8)


def _outputs(m):
    """The outputs of one measurement (most have one; Floquet has three)."""
    return m.outputs() if hasattr(m, "outputs") else (m.output(),)


_EXPLAINED: set = set()  # (model, explanation) already warned about in this process


def _warn_user_error(model, P, status, S, rtol) -> None:
    """Points with status USER_ERROR: replay the first in plain Python and warn (once per model and
    cause in a process) with the exception, its file and line, and the point."""
    bad = np.nonzero(status == st.USER_ERROR)[0]
    if not bad.size:
        return
    from .diagnose import explain, point_text
    why = explain(model, P[bad[0]], S, rtol)
    if (model.name, why) in _EXPLAINED:
        return
    _EXPLAINED.add((model.name, why))
    import warnings

    from ..errors import UserModelWarning
    at = point_text(model.params, P[bad[0]])  # a categorical parameter by its choice's name
    warnings.warn(f"model {model.name!r}: its own code raised (status user_error; the run's status counts say "
                  f"how often); first seen at {at}: {why}", UserModelWarning, stacklevel=2)


def _moved(rc, settings, solver, first, second, status2) -> np.ndarray:
    """Which re-checked points moved (sampled.Recheck's rule): an asked-for output that differs by more
    than factor (rtol max(|v|, |v'|) + atol), NaN in one run only, or a second run that failed."""
    factor = setting_value(rc.factor, settings)
    bad = status2 != st.OK
    for name, a in first.items():
        bad |= rc.moved(a, second[name], factor, solver)
    return bad


def _check_method(model, method: str, wanted) -> None:
    allowed = model.methods_for(wanted)
    if method not in allowed:
        raise InputError(f"solver.method: {method!r} is not offered by model {model.name!r} for the outputs "
                         f"{', '.join(wanted)} (allowed: {', '.join(allowed)})")


def _lanes(route, family: str) -> bool | None:
    """The lane choice for the kernels of ``family`` ("kernel", "trajectory") in a plan's ``route``
    ({family: "lanes" or "point"}); None when no route is given (the engine's default)."""
    return None if route is None else route.get(family) == "lanes"


def _facts(name: str, from_points: int, after_points: int, forced) -> dict:
    """What a plan decides a lane route from (execution/plan.py, choose_route)."""
    from ..engine.kernels import lanes_recorded, points_tallied

    recorded = lanes_recorded(name)
    return {"record": name, "recorded": recorded, "tallied": 0 if recorded else points_tallied(name),
            "from_points": int(from_points), "after_points": int(after_points), "forced": forced}


@contextmanager
def _at_declaration(m):
    """A ValueError about measurement ``m`` carries where ``m`` was written (``mechsweep_declared_at``):
    loading a model file then names that line, not the OdeModel(...) call's."""
    try:
        yield
    except ValueError as exc:
        if declared_at(m) is not None and not hasattr(exc, "mechsweep_declared_at"):
            exc.mechsweep_declared_at = declared_at(m)
        raise


@dataclass(frozen=True)
class Invariant:
    """A quantity the model's equation conserves along undamped trajectories (e.g. the energy of a
    conservative oscillator, or of a damped one with its damping set to zero), declared as
    ``OdeModel(invariant=Invariant(...))``. The engine never computes it in a sweep; the
    work-precision bench (``mechsweep bench workprecision MODEL``) reports its drift: the relative
    error |I(t) - I(0)| / |I(0)| after each of ``periods`` periods of one long integration from the
    model's ``initial(p, y0)``, by dop853 at each of ``rtols`` (atol = 1e-2 rtol) and, where the model
    declares ``accel``, by the symplectic method at its ``symplectic_step(p, rtol)``.

    - ``func(y, p) -> float``: plain Python (called outside any kernel) of the state and the point's
      ``p`` laid out as the engine's (parameters, settings, internal slots after ``prepare``).
    - ``at``: {parameter or setting name: value} of the point the drift is measured at (one where
      the quantity is conserved, e.g. zero damping); every required parameter given, the others
      take their defaults.
    - ``period``: the time unit the drift is counted in, in the equation's own time (the rhs's t):
      a number, or ``period(p) -> float`` (after ``classify`` and ``prepare`` at the first rtol).
    - ``name``: what the quantity is, for the report ("energy").
    - ``problem``: a one-line statement of the drift problem for the report (default: the model
      and ``at``).
    """

    func: Callable = field(repr=False, compare=False)
    at: object = field(default=(), compare=False)
    period: object = field(default=1.0, repr=False, compare=False)
    name: str = "energy"
    periods: tuple = (1, 10, 100, 1000, 10000)
    rtols: tuple = (1e-6, 1e-9)
    problem: str = ""

    def validate(self, model) -> None:
        where = f"model {model.name!r}: invariant"
        if not callable(self.func):
            raise ValueError(f"{where}: func must be a function func(y, p) -> float (got {self.func!r})")
        if not isinstance(self.at, dict):
            raise ValueError(f"{where}: at must be a dict {{parameter or setting: value}} (got {self.at!r})")
        known = [q.name for q in model.params] + [x.name for x in model.settings]
        bad = [k for k in self.at if k not in known]
        if bad:
            raise ValueError(f"{where}: at names {bad}, which are not parameters or settings ({', '.join(known)})")
        missing = [q.name for q in model.params if q.required and q.name not in self.at]
        if missing:
            raise ValueError(f"{where}: at does not give the required parameters {missing}")
        if not callable(self.period) and not (isinstance(self.period, (int, float)) and math.isfinite(self.period)
                                              and self.period > 0):
            raise ValueError(f"{where}: period = {self.period!r}; expected a finite number > 0 or a function "
                             "period(p)")
        periods = tuple(self.periods)
        if not periods or any(not (isinstance(n, int) and n > 0) for n in periods) or list(periods) != sorted(
                set(periods)):
            raise ValueError(f"{where}: periods = {self.periods!r}; expected increasing whole numbers > 0")
        if not self.rtols or any(not (isinstance(r, float) and 0.0 < r < 1.0) for r in self.rtols):
            raise ValueError(f"{where}: rtols = {self.rtols!r}; expected numbers 0 < rtol < 1")


@dataclass(frozen=True)
class OdeModel:
    """An ODE model: y' = rhs(t, y, p) from ``initial(p, y0)`` at t = 0, and what to measure.

    A model of your own is one of these, declared in a Python file (docs/your-own-model.md): the
    engine compiles one parallel kernel for it and runs, stores and plots it like a built-in model.

    The layout of ``p`` (float64, one row per point): ``p[0 .. P-1]`` the declared ``params`` in
    order (a categorical parameter as the index of its choice), ``p[P .. P+S-1]`` the values of the
    declared ``settings`` (solver settings of this model, e.g. a horizon), ``p[P+S .. P+S+I-1]`` the
    ``internal`` slots (written by ``prepare``, zero before), then scratch the engine uses: read
    nothing beyond ``P + S + I``.

    Parameters
    ----------
    name : str
        The model's name: how a scene names it (with ``models=`` or an entry point) and the
        dataset's ``model`` attribute.
    description : str
        One line saying what the model is (``mechsweep models``, the glossary).
    params : tuple of Param
        The parameters, in the order ``p`` holds them.
    states : tuple of str
        Names of the components of y.
    rhs : callable
        ``rhs(t, y, p, dydt)``: plain numba-compilable Python (no decorator needed) writing every
        ``dydt[i]``; returns nothing.
    initial : callable
        ``initial(p, y0)``: writes every ``y0[i]``.
    measurements : tuple, optional
        Instances of the measurement classes (:class:`Crossing`, :class:`Period`, :class:`StateAt`,
        :class:`Extremum`, :class:`Floquet`, :class:`FirstEvent`, :class:`Steady`, :class:`Kick`,
        :class:`History`); each gives its output(s) named by its ``name``.
    forcing_period : callable, optional
        ``forcing_period(p) -> T`` of a T-periodic forcing (Floquet and the sampled trajectories
        need it).
    jac : callable, optional
        ``jac(t, y, p, J)`` writing every ``J[i, j]`` = d dydt[i] / d y[j]; radau and Floquet use
        it, else the engine differentiates ``rhs`` (central differences).
    source : str, optional
        Where the equations come from (the dataset's ``model_source``).
    settings : tuple of Setting, optional
        The model's own solver settings (``[solver]`` keys, e.g. a horizon).
    statuses : tuple of int, optional
        Status codes the model's points can get beyond those its outputs imply (``mechsweep info``
        and the glossary list them).
    status_notes : Mapping, optional
        Status code -> what that status means for this model.
    closed_forms : tuple of ClosedForm, optional
        Outputs that are formulas of p and of other outputs, computed only when wanted.
    internal : tuple of str, optional
        Names of the slots after the settings that ``prepare`` writes (e.g. a scaling).
    classify : callable, optional
        ``classify(p) -> status``: a status code of :mod:`mechsweep.status` before any computation
        (non-OK: every output NaN with that status; e.g. NO_MOTION, INFEASIBLE).
    prepare : callable, optional
        ``prepare(p, rtol) -> status``: runs before the measurements of each point (after the
        closed forms): writes the ``internal`` slots the rhs, event and value read and may refuse
        the integration (non-OK: measurements NaN with that status; closed forms kept).
    accel : callable, optional
        The separable form for the symplectic method: y = (q, v), q' = v and ``accel(t, q, p, a)``
        writes v' (``len(states)`` even, q the first half); together with ``symplectic_step(p,
        rtol) -> h`` (the fixed step for a tolerance) and ``symplectic_order`` (2, 4, 6 or 8).
        Only then is ``symplectic`` one of the model's methods.
    symplectic_step : callable, optional
        See ``accel``.
    symplectic_order : int, optional
        See ``accel`` (default 8).
    output_order : tuple of str, optional
        The order of the outputs (default: measurements, then closed forms).
    references : tuple of str, optional
        The documents the model implements: the dataset's CF ``references`` attribute.
    recheck : Recheck, optional
        The sampled outputs integrated again at a tighter rtol, to flag those that move.
    status_order : tuple of int, optional
        Status codes, most severe first. Without it a point's status is the first failure in the
        kernel's order (classify, closed forms, prepare, the measurements in declared order, the
        sampled ones last). With it, every stage runs on every point the model's
        ``classify``/``prepare`` accept and whose integration did not fail, and the point's status
        is the most severe (first in this order) among the statuses of the outputs asked for; a
        status not listed ranks above every listed one. A measurement's own ``classify(p) ->
        status`` skips that measurement at a point (its outputs NaN, its status counted only when
        one of its outputs is asked for or needed) with or without an order.
    check : callable, optional
        ``check(given) -> list of problems``: cross-parameter rules of a scene; ``given`` =
        {parameter: tuple of the values the scene gives it (a range axis: its two ends)}, the
        parameters the scene does not give absent; each problem a string "key: message". The
        scene is refused (exit 2) with them.
    invariant : Invariant, optional
        A quantity the equation conserves along undamped trajectories (an energy); the
        work-precision bench reports its drift (sweeps never compute it).
    workprecision : WorkPrecision, optional
        The default scene, output and exact reference of the model's work-precision report.
    switch_times : tuple of float or callable, optional
        Times in [0, T) of one forcing period at which the rhs (or a derivative of it) jumps,
        repeated every period T = forcing_period(p): increasing constants, or ``switch_times(p) ->
        tuple of floats`` (numba-compilable). Every integration then ends a step exactly on each
        switch and starts the next step there afresh; the rhs is never evaluated at a switch time
        itself. A point where they are not increasing times in [0, T) gets INFEASIBLE. Needs
        ``forcing_period``; not with ``accel``.

    Notes
    -----
    Methods (``solver.method``): dop853, radau, auto (dop853 with the stiffness test; a stiff point
    is integrated again by radau) and, with ``accel``, symplectic. FirstEvent measurements (and a
    lone first Crossing) offer them all; the other measurements observe one DOP853 trajectory and
    offer dop853 only (a scene asking another method for them is refused when it is loaded).

    Examples
    --------
    A harmonic oscillator and its period (in a file ``harmonic.py``; a scene names it
    ``model = "harmonic.py:HARMONIC"``):

    >>> import math
    >>> from mechsweep.model import OdeModel, Param, Period
    >>> def rhs(t, y, p, dydt):
    ...     dydt[0] = y[1]
    ...     dydt[1] = -p[0] * p[0] * y[0]
    >>> def initial(p, y0):
    ...     y0[0] = 1.0
    ...     y0[1] = 0.0
    >>> HARMONIC = OdeModel(
    ...     name="harmonic", description="x'' + w^2 x = 0 from x = 1 at rest",
    ...     params=(Param("w", "ω", "rad s-1", "angular frequency", lo=0.0, lo_open=True),),
    ...     states=("x", "v"), rhs=rhs, initial=initial,
    ...     measurements=(Period("period", "x", unit="s", long_name="period"),))
    >>> HARMONIC.spec().output_names()
    ('period',)
    """

    name: str
    description: str
    params: tuple[Param, ...]
    states: tuple[str, ...]
    rhs: Callable = field(repr=False)
    initial: Callable = field(repr=False)
    measurements: tuple = ()
    forcing_period: Callable | None = field(default=None, repr=False)
    jac: Callable | None = field(default=None, repr=False)
    source: str = ""
    settings: tuple[Setting, ...] = ()
    statuses: tuple[int, ...] = ()  # ModelSpec.statuses: added to those derived from the outputs
    status_notes: object = ()  # ModelSpec.status_notes: {code: what the status means for this model}
    closed_forms: tuple[ClosedForm, ...] = ()
    internal: tuple[str, ...] = ()
    classify: Callable | None = field(default=None, repr=False)
    prepare: Callable | None = field(default=None, repr=False)
    accel: Callable | None = field(default=None, repr=False)
    symplectic_step: Callable | None = field(default=None, repr=False)
    symplectic_order: int = 8
    output_order: tuple[str, ...] = ()
    references: tuple[str, ...] = ()  # ModelSpec.references: the source documents
    recheck: object = None  # sampled.Recheck: the sampled outputs integrated again at a tighter rtol
    status_order: tuple[int, ...] = ()  # most severe first: a point's status among its outputs' (see worse)
    check: Callable | None = field(default=None, repr=False)  # ModelSpec.check: the cross-parameter rules
    invariant: Invariant | None = field(default=None, repr=False, compare=False)  # conserved when undamped
    workprecision: object = field(default=None, repr=False, compare=False)  # model.workprecision.WorkPrecision
    switch_times: object = field(default=None, repr=False)  # model/switches.py: where the rhs jumps in [0, T)

    def __post_init__(self):
        if self.switch_times is not None:
            from .switches import check_declaration
            if not callable(self.switch_times) and not isinstance(self.switch_times, tuple):
                object.__setattr__(self, "switch_times", tuple(self.switch_times)
                                   if isinstance(self.switch_times, (list, np.ndarray)) else self.switch_times)
            check_declaration(self)
        if self.invariant is not None:
            if not isinstance(self.invariant, Invariant):
                raise ValueError(f"model {self.name!r}: invariant must be a mechsweep.model.Invariant "
                                 f"(got {self.invariant!r})")
            self.invariant.validate(self)
        if self.recheck is not None:
            from .sampled import Recheck
            if not isinstance(self.recheck, Recheck):
                raise ValueError(f"model {self.name!r}: recheck must be a mechsweep.model.Recheck (got {self.recheck!r})")
            self.recheck.validate(self.measurements, self.settings)
            bad = [x for x, _ in self.recheck.lock_rates if x not in self.states]
            if bad:
                raise ValueError(f"model {self.name!r}: recheck lock_rates name {bad}, which are not states "
                                 f"({', '.join(self.states)})")
        for name in ("params", "states", "measurements", "closed_forms", "internal", "settings", "output_order",
                     "status_order"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        object.__setattr__(self, "status_notes", tuple(sorted(dict(self.status_notes).items())))
        if not self.states:
            raise ValueError(f"model {self.name!r}: states is empty")
        for what, names in (("parameter", [p.name for p in self.params]), ("state", list(self.states))):
            if len(set(names)) != len(names):  # a scene key, a dataset coordinate, a measured state: one each
                raise ValueError(f"model {self.name!r}: {what} names repeat: {names}")
        if self.check is not None and not callable(self.check):
            raise ValueError(f"model {self.name!r}: check must be a function check(given) -> list of problems "
                             f"(got {self.check!r})")
        for m in self.measurements:
            if not hasattr(m, "validate"):  # e.g. a ClosedForm put among the measurements
                from .sampled import MEASUREMENTS
                where = ("a ClosedForm belongs in closed_forms=(...), not in measurements="
                         if isinstance(m, ClosedForm) else
                         f"measurements= takes {', '.join(c.__name__ for c in MEASUREMENTS)}")
                raise ValueError(f"model {self.name!r}: measurements= holds {type(m).__name__} "
                                 f"{getattr(m, 'name', m)!r}, which is not a measurement: {where}")
        codes = set(st.MEANINGS) - {st.PENDING, st.OK}
        bad = [c for c in self.status_order if not (isinstance(c, (int, np.integer)) and int(c) in codes)]
        if bad or len(set(self.status_order)) != len(self.status_order):
            raise ValueError(f"model {self.name!r}: status_order must list status codes of mechsweep.status once each "
                             f"(got {self.status_order!r}; allowed: {sorted(codes)})")
        for m in self.measurements:  # output_meta first: the names below come from it
            if hasattr(m, "_check_meta"):
                m._check_meta()
        names = [o.name for m in self.measurements for o in _outputs(m)] + [c.name for c in self.closed_forms]
        if len(set(names)) != len(names):
            raise ValueError(f"model {self.name!r}: output names repeat: {names}")
        for m in self.measurements:
            with _at_declaration(m):
                self._check_measurement(m)
        if self.forcing_period is None:  # T = 1: a History's instants are times, labelled so
            from .sampled import History
            default = History.__dataclass_fields__["dim_long_name"].default
            object.__setattr__(self, "measurements", tuple(
                dataclasses.replace(m, dim_long_name="time t (the model declares no forcing period: T = 1)")
                if isinstance(m, History) and m.dim_long_name == default else m for m in self.measurements))
        unreadable = {o.name: m for m in self.measurements if not getattr(m, "sampled", False)
                      and hasattr(m, "values") for o in _outputs(m) if o.name not in m.values()}
        for c in self.closed_forms:
            bad = [x for x in c.needs if x not in names or x == c.name]
            if bad:
                raise ValueError(f"model {self.name!r}: closed form {c.name!r} needs {bad}, which are not other "
                                 f"outputs of the model ({names})")
            bad = [x for x in c.needs if x in unreadable]
            if bad:
                m = unreadable[bad[0]]
                raise ValueError(f"model {self.name!r}: closed form {c.name!r} needs {bad[0]!r}, which closed forms "
                                 f"cannot read (it is decided after the kernel); of {type(m).__name__} {m.name!r} "
                                 f"they can read {', '.join(m.values())}")
        if self.accel is not None:
            if len(self.states) % 2:
                raise ValueError(f"model {self.name!r}: accel needs y = (q, v), an even number of states "
                                 f"(got {len(self.states)})")
            if self.symplectic_step is None:
                raise ValueError(f"model {self.name!r}: accel is given without symplectic_step(p, rtol) -> h")
            if self.symplectic_order not in SYMPLECTIC_ORDERS:
                raise ValueError(f"model {self.name!r}: symplectic_order = {self.symplectic_order!r}; "
                                 f"expected one of {SYMPLECTIC_ORDERS}")
        for m in self.measurements:
            system = getattr(m, "system", None)
            if system is not None and self.accel is not None and (system.accel is None
                                                                  or system.symplectic_step is None):
                raise ValueError(f"model {self.name!r}: measurement {m.name!r} integrates a System without "
                                 "accel and symplectic_step, but the model offers the symplectic method (accel)")
        known = {x.name for x in self.settings}
        for m in self.measurements:
            bad = [x for x in getattr(m, "setting_names", lambda: ())() if x not in known]
            if bad:
                raise ValueError(f"model {self.name!r}: measurement {m.name!r} reads settings {bad}, which the model "
                                 f"does not declare (settings: {sorted(known)})")
        sampled = {o.name for m in self.measurements if getattr(m, "sampled", False) for o in _outputs(m)}
        for c in self.closed_forms:
            if sampled & set(c.needs):
                raise ValueError(f"model {self.name!r}: closed form {c.name!r} needs the sampled-trajectory outputs "
                                 f"{sorted(sampled & set(c.needs))}, which closed forms cannot read yet")
        if self.output_order and sorted(self.output_order) != sorted(names):
            raise ValueError(f"model {self.name!r}: output_order {self.output_order} must list every output once "
                             f"({names})")
        if self.workprecision is not None:
            from .workprecision import WorkPrecision
            if not isinstance(self.workprecision, WorkPrecision):
                raise ValueError(f"model {self.name!r}: workprecision must be a mechsweep.model.WorkPrecision "
                                 f"(got {self.workprecision!r})")
            self.workprecision.validate(self)

    def _check_measurement(self, m) -> None:
        m.validate(self.states)
        if getattr(m, "needs_forcing", False) and self.forcing_period is None:
            raise ValueError(f"model {self.name!r}: {type(m).__name__} {m.name!r} needs forcing_period(p): the "
                             "period T of the rhs's time-periodic coefficients, over which the monodromy is taken "
                             "(e.g. 2 * math.pi / p[0] for a forcing at frequency p[0]); declare forcing_period=")
        if hasattr(m, "check_settings"):
            m.check_settings(self.settings)

    @property
    def methods(self) -> tuple[str, ...]:
        """The values of solver.method the declaration offers."""
        return ("dop853", "radau") + (("symplectic",) if self.accel is not None else ()) + ("auto",)

    def _plan(self, wanted):
        """(measurements, closed forms in dependency order) to compute for the outputs ``wanted``."""
        by_name = {c.name: c for c in self.closed_forms}
        need = set(wanted)
        stack = list(wanted)
        while stack:
            x = stack.pop()
            for y in (by_name[x].needs if x in by_name else ()):
                if y not in need:
                    need.add(y)
                    stack.append(y)
        chosen = tuple(m for m in self.measurements if any(o.name in need for o in _outputs(m)))
        order, done = [], set()

        def visit(c):
            if c.name in done:
                return
            done.add(c.name)
            for y in c.needs:
                if y in by_name:
                    visit(by_name[y])
            order.append(c)

        for c in self.closed_forms:
            if c.name in need:
                visit(c)
        return chosen, tuple(order)

    def computable_closed_forms(self, chosen) -> tuple:
        """The closed forms a kernel for the measurements ``chosen`` can compute (those whose
        measurement needs are among them), in dependency order."""
        _, order = self._plan(tuple(c.name for c in self.closed_forms))
        have = {o.name for m in chosen for o in _outputs(m)}
        meas = {o.name for m in self.measurements for o in _outputs(m)}
        ok, done = [], set()
        for c in order:
            if all((x in have) if x in meas else (x in done) for x in c.needs):
                ok.append(c)
                done.add(c.name)
        return tuple(ok)

    def methods_for(self, outputs) -> tuple[str, ...]:
        """The methods that the chosen outputs can be computed by (see the class docstring)."""
        from ..engine.point import floquet_only, is_direct

        chosen, _ = self._plan(outputs)
        rest = tuple(m for m in chosen if not getattr(m, "sampled", False))
        if not rest or is_direct(rest):
            methods = self.methods
        elif floquet_only(rest):  # the variational integration: dop853, radau, auto
            methods = tuple(x for x in self.methods if x != "symplectic")
        else:
            methods = ("dop853",)
        if len(rest) < len(chosen):  # a sampled trajectory: the methods that make a trajectory solver
            from ..engine.sampling import METHODS as trajectory_methods

            methods = tuple(x for x in methods if x in trajectory_methods)
        return methods

    def spec(self, *, origin: str = "", module: str = "", attr: str = "") -> ModelSpec:
        """The ModelSpec the engine runs. ``module``/``attr`` say where the declaration can be
        imported from in another process (unused: the kernels import the model's functions by module path)."""
        from ..engine.kernels import kernel_for
        from ..engine.point import columns

        model = self

        def evaluate(P, wanted, solver, out, status, n_steps, n_rhs, route=None):
            chosen, closed = model._plan(wanted)
            if not chosen and not closed:
                return
            sampled = tuple(m for m in chosen if getattr(m, "sampled", False))
            if sampled:  # one sampled trajectory per point (engine/sampling.py), after the other outputs
                from ..engine import sampling as trajectory
                _check_method(model, solver.method, wanted)
                before = status.copy()
                rest = [o for o in wanted if not any(o == x.name for m in sampled for x in _outputs(m))]
                if rest:
                    evaluate(P, tuple(rest), solver, out, status, n_steps, n_rhs, route)
                code = before.copy()
                trajectory.evaluate(model, sampled, P, wanted, solver, out, code, n_steps, n_rhs,
                                    lanes=_lanes(route, "trajectory"))
                S = np.array([float(solver.settings.get(x.name, x.default)) for x in model.settings], dtype=np.float64)
                _warn_user_error(model, P, code, S, solver.rtol)
                status[:] = worse(status, code, model.status_order)
                return
            method = solver.method if (solver is not None and chosen) else "dop853"
            _check_method(model, method, wanted)
            # closed forms by a run-time mask (one kernel for every choice of them), or none at all
            # when none is wanted (a lean kernel: a cold compile of a period-only scene compiles no formula)
            computable = model.computable_closed_forms(chosen) if closed else ()
            kernel = kernel_for(model, chosen, origin=origin, module=module, attr=attr, closed=computable,
                                method=method, lanes=_lanes(route, "kernel"))
            wanted_closed = {c.name for c in closed}
            need = np.array([c.name in wanted_closed for c in computable], dtype=np.bool_)
            cols = columns(chosen)
            table = np.full((P.shape[0], cols[-1] + len(computable)), np.nan)
            settings = solver.settings if solver is not None else {}
            S = np.array([float(settings.get(s.name, s.default)) for s in model.settings], dtype=np.float64)
            rtol, atol, max_steps = ((solver.rtol, solver.atol, solver.max_steps) if solver is not None
                                     else (1e-10, 1e-12, 1))
            P = np.ascontiguousarray(P, dtype=np.float64)
            kernel(P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs)
            _warn_user_error(model, P, status, S, rtol)
            rc = model.recheck if chosen and solver is not None and model.recheck is not None else None
            again = (np.flatnonzero(status == st.OK)
                     if rc is not None and rc.every_measurement and setting_value(rc.factor, settings) > 0.0 else None)
            if again is not None and again.size:  # the same kernel at the tighter rtol, closed forms left out
                t2 = np.full((again.size, table.shape[1]), np.nan)
                s2 = np.zeros(again.size, dtype=status.dtype)
                ns2, nr2 = np.zeros(again.size, dtype=n_steps.dtype), np.zeros(again.size, dtype=n_rhs.dtype)
                kernel(np.ascontiguousarray(P[again]), S, np.zeros_like(need), rc.tight_rtol(rtol), atol, max_steps,
                       t2, s2, ns2, nr2)
                n_steps[again] += ns2
                n_rhs[again] += nr2
            finished = _finish_measurements(model, chosen, cols, table, wanted, solver, out, status)
            if again is not None and again.size:
                out2 = {name: np.full(again.size, np.nan) for name in finished}
                _finish_measurements(model, chosen, cols, t2, wanted, solver, out2, s2)
                moved = _moved(rc, settings, solver, {n: out[n][again] for n in finished}, out2, s2)
                flag = np.zeros(status.size, dtype=bool)
                flag[again] = moved
                mark_not_reproducible(status, flag, model.status_order)
            for j, c in enumerate(computable):
                if c.name in out:
                    out[c.name][:] = table[:, cols[-1] + j]

        def plan(wanted, solver) -> dict:
            """What ``evaluate(P, wanted, solver, ...)`` computes and which of its kernels have a lane
            route (see ModelSpec.plan), decided as evaluate decides, without compiling anything."""
            chosen, closed = model._plan(wanted)
            return {"measurements": [m.name for m in chosen], "closed_forms": [c.name for c in closed],
                    "lanes": lane_facts(wanted, solver)}

        def lane_facts(wanted, solver) -> dict:
            from ..engine import kernels as engine, sampling as trajectory

            chosen, closed = model._plan(wanted)
            if not chosen and not closed:
                return {}
            sampled = tuple(m for m in chosen if getattr(m, "sampled", False))
            if sampled:
                rest = [o for o in wanted if not any(o == x.name for m in sampled for x in _outputs(m))]
                facts = lane_facts(tuple(rest), solver) if rest else {}
                name = trajectory.lane_name(model, solver.method)
                if name is not None:
                    facts["trajectory"] = _facts(name, trajectory.LANES_FROM_POINTS, trajectory.LANES_AFTER_POINTS,
                                                 trajectory.USE_LANES)
                return facts
            method = solver.method if (solver is not None and chosen) else "dop853"
            computable = model.computable_closed_forms(chosen) if closed else ()
            name = engine.lane_name(model, chosen, origin=origin, closed=computable, method=method)
            return {} if name is None else {"kernel": _facts(name, engine.LANES_FROM_POINTS, engine.LANES_AFTER_POINTS,
                                                                engine.USE_LANES)}

        def _finish_measurements(model, chosen, cols, table, wanted, solver, out, status) -> list[str]:
            """The measurements' outputs from the kernel's table into ``out`` (their statuses into
            ``status``); the names written."""
            written = []
            for j, m in enumerate(chosen):
                if hasattr(m, "finish") and model.status_order:  # its own status (OK where it has a value), ranked
                    own = np.zeros_like(status)
                    m.finish(table[:, cols[j]:cols[j + 1]], wanted, solver, out, own)
                    status[:] = worse(status, own, model.status_order)
                elif hasattr(m, "finish"):
                    m.finish(table[:, cols[j]:cols[j + 1]], wanted, solver, out, status)
                elif m.name in out:
                    out[m.name][:] = table[:, cols[j]]
                written += [o.name for o in _outputs(m) if o.name in out]
            return written

        outputs = (tuple(o for m in self.measurements for o in _outputs(m))
                   + tuple(c.output() for c in self.closed_forms))
        if self.forcing_period is None:  # a window or harmonic counted in T (Steady, RMS): T = 1, said so
            timed = {o.name for m in self.measurements if getattr(m, "SAYS_PERIOD", False) for o in _outputs(m)}
            outputs = tuple(dataclasses.replace(o, long_name=f"{o.long_name.replace(' (forcing period)', '')} (T = 1 "
                                                "time unit: the model declares no forcing period)")
                            if o.name in timed else o for o in outputs)
        if self.output_order:
            by_name = {o.name: o for o in outputs}
            outputs = tuple(by_name[n] for n in self.output_order)
        spec = ModelSpec(
            name=self.name,
            description=self.description,
            params=self.params,
            outputs=outputs,
            evaluate=evaluate,
            source=self.source or origin,
            settings=self.settings + tuple(
                FLOQUET_MARGIN for _ in (0,) if any(isinstance(m, Floquet) for m in self.measurements)
                and FLOQUET_MARGIN.name not in {s.name for s in self.settings}),
            methods=self.methods,
            methods_for=self.methods_for,
            statuses=self.statuses,
            status_notes=self.status_notes,
            references=self.references,
            check=self.check,
            declaration=self,
            plan=plan,
        )
        if self.recheck is not None:  # the re-check adds NOT_REPRODUCIBLE to the statuses a point can get
            spec = dataclasses.replace(spec, statuses=spec.possible_statuses() + (st.NOT_REPRODUCIBLE,))
        if self.switch_times is not None:  # a point whose switch times are not increasing times in [0, T)
            notes = dict(spec.status_notes)
            notes.setdefault(st.INFEASIBLE, "(also) the switch times are not strictly increasing times in [0, T) "
                                            "of the forcing period T here")
            spec = dataclasses.replace(spec, status_notes=tuple(sorted(notes.items())), statuses=tuple(
                dict.fromkeys(spec.possible_statuses() + (st.INFEASIBLE,))))
        return spec
