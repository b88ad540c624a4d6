"""The work-precision case of any model declared as a :class:`mechsweep.model.OdeModel` (a user's or
a built-in one), built from its declaration: scipy's ``solve_ivp`` gets the model's OWN right-hand
side (its numba-compiled ``rhs``, wrapped as ``f(t, y)``), its own ``initial(p, y0)`` and, for
Floquet, its own ``jac`` when it declares one; each generic measurement is re-done with scipy's
tools (events, dense output, the variational equations), so nothing is copied by hand.

- Crossing / Period: event times (``terminal`` = the crossing's count), relative error;
- FirstEvent: the n-th root of the model's own ``event(t, y, p)`` in its direction (scipy's
  ``direction``, ``terminal`` = n), over its ``t_max`` (a number or the model's ``t_max(p)``), the
  model's ``value(p, t)``; relative error. With a ``system=``, the System's own rhs, initial state,
  jac and prepare (run after the model's, as the engine's); with a ``refine``, its factor decides
  as in the engine (a second pass at rtol / f, atol / f; not finite: NaN);
- StateAt: the state at t, absolute error;
- Extremum: the state (or expression) at t0, t1 and at the roots of its derivative in [t0, t1]
  (events on the rhs component; for an expression its rate along the flow, a central difference
  as the engine's), absolute error; t0, t1 as numbers or the model's functions of p;
- Floquet: the largest modulus of the eigenvalues of the monodromy matrix integrated from the
  variational equations (n + n^2 equations) with the model's ``jac``, else central differences of
  its rhs (step cbrt(eps) max(1, |y_j|): exact for an rhs linear in y, otherwise ~1e-10 relative,
  which then bounds the reference), absolute error.

A model that declares ``switch_times`` (model/switches.py) is integrated as the engine does: from
switch to switch, ``solve_ivp`` restarted at each (its first step chosen again), the time passed to the
rhs (and jac) kept about ten ulps inside the segment (switches.SIDE); a point whose switch times are
not increasing times in [0, T) is refused (NaN: the engine's INFEASIBLE). solve_ivp has no stops of
its own: a jump inside a step would cost the reference (and every scipy run) its accuracy.

Every point's ``p`` is laid out as the engine's (parameters, the scene's settings, internal slots);
the model's ``classify(p)`` and ``prepare(p, rtol)`` run first (not OK: NaN, as the engine's
point would be). Radau and LSODA get the model's ``jac`` where it declares one (else scipy's
finite differences). The reference is scipy DOP853 at rtol 1e-13 (atol 1e-15), or a closed form of
the model (the ``reference`` of its ``WorkPrecision`` declaration, evaluated by the engine). Used by
``mechsweep bench workprecision MODEL`` for every model declared as an OdeModel, built-in or a
user's (workprecision.main).
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

REFERENCE_RTOL = 1e-13
REFERENCE_ATOL = 1e-15


def _plain(f):
    """A declaration's Python function (a jitted one's py_func)."""
    return getattr(f, "py_func", f)


def _compiled(model, func, what):
    """The model's function ``func`` compiled as the engine's (None where it declares none)."""
    from ..model import load

    if func is None or not callable(func):
        return None
    return load.jitted(*load.function_ref(func, what, model.name))


class OdeReference:
    """scipy's version of one measured output of an OdeModel."""

    def __init__(self, model, output: str, settings: dict | None = None):
        from ..model import measure as ms

        self.model = model
        chosen = None
        for m in model.measurements:
            names = [o.name for o in (m.outputs() if hasattr(m, "outputs") else (m.output(),))]
            if output in names:
                chosen = m
        if chosen is None:
            raise InputError(f"model {model.name!r} has no measured output {output!r}")
        if isinstance(chosen, ms.Floquet) and output != chosen.name:
            raise InputError(f"output {output!r} is derived from {chosen.name!r}; measure {chosen.name!r} instead")
        kinds = (ms.Crossing, ms.Period, ms.StateAt, ms.Extremum, ms.Floquet, ms.FirstEvent)
        if not isinstance(chosen, kinds):
            raise InputError(f"output {output!r} is measured by {type(chosen).__name__}, which this bench has no "
                             f"scipy version of (it has: {', '.join(k.__name__ for k in kinds)})")
        self.m = chosen
        self.output = output
        self.n = len(model.states)
        settings = settings or {}
        # p as the engine lays it out: parameters, settings, internal slots, then scratch
        self._settings = np.array([float(settings.get(x.name, x.default)) for x in model.settings])
        self._tail = len(model.internal) + 1 + 3 * self.n + self.n * self.n + 1

        def compiled(func, what):
            return _compiled(model, func, what)
        self._rhs = compiled(model.rhs, "rhs")
        self._initial = compiled(model.initial, "initial")
        self._jac = compiled(model.jac, "jac")
        self._classify = compiled(model.classify, "classify")
        self._prepare = compiled(model.prepare, "prepare")
        self._fn = {role: compiled(f, f"{chosen.name}.{role}") for role, f in getattr(chosen, "functions", lambda: ())()}
        # the equation integrated: the model's, or a FirstEvent's own System (its rhs, initial, jac and
        # prepare, compiled from the System's functions as the engine's pass does)
        self._system = getattr(chosen, "system", None) is not None
        if self._system:
            self._rhs, self._initial, self._jac = self._fn["rhs"], self._fn["initial"], self._fn.get("jac")
        # where the measurement applies (e.g. Floquet about an isolated balanced state), as the engine asks it
        self._m_classify = compiled(getattr(chosen, "classify", None), f"{chosen.name}.classify")
        self.error = "relative" if isinstance(chosen, (ms.Crossing, ms.Period, ms.FirstEvent)) else "absolute"
        what = {ms.Crossing: "time of the crossing", ms.Period: "period", ms.StateAt: "state value",
                ms.Extremum: "extremum", ms.Floquet: "largest Floquet multiplier modulus",
                ms.FirstEvent: "value at the event"}[type(chosen)]
        self.norm = f"{self.error} error of {output} ({what})"
        jac = "the model's jac" if self._jac is not None else "central differences of the model's rhs"
        self.reference_name = (f"scipy DOP853 at rtol {REFERENCE_RTOL:g}, atol {REFERENCE_ATOL:g}, on the model's "
                               "own rhs" + (f" (variational equations with {jac})"
                                            if isinstance(chosen, ms.Floquet) else "")
                               + (", restarted at each of its switch times" if model.switch_times is not None else ""))

    # ------------------------------------------------------------------ the model's own functions
    def f(self, p):
        rhs = self._rhs

        def f(t, y):
            d = np.empty(y.shape[0])
            rhs(t, y, p, d)
            return d
        return f

    def y0(self, p):
        y = np.empty(self.n)
        self._initial(p, y)
        return y

    def point(self, row, rtol):
        """The engine's p of a parameter row after the model's classify and prepare, the
        measurement's classify and its System's prepare (run just before the measurement, as the
        engine's), or None where one of them refuses the point."""
        from .. import status as st

        p = np.concatenate([np.asarray(row, dtype=np.float64)[:len(self.model.params)], self._settings,
                            np.zeros(self._tail)])
        if self._classify is not None and self._classify(p) != st.OK:
            return None
        if self._prepare is not None and self._prepare(p, rtol) != st.OK:
            return None
        if self._m_classify is not None and self._m_classify(p) != st.OK:
            return None
        if self._system and "prepare" in self._fn and self._fn["prepare"](p, rtol) != st.OK:
            return None
        if self.model.switch_times is not None and self._switches(p) is None:
            return None
        return p

    def _switches(self, p):
        """(T, switch times in [0, T)) at ``p``, or None where the engine's check refuses them
        (switches.switch_check: INFEASIBLE)."""
        T = float(_plain(self.model.forcing_period)(p))
        sw = self.model.switch_times
        times = tuple(float(x) for x in (_plain(sw)(p) if callable(sw) else sw))
        if not (math.isfinite(T) and T > 0.0 and times and all(math.isfinite(x) and 0.0 <= x < T for x in times)
                and all(a < b for a, b in zip(times, times[1:]))):
            return None
        return T, times

    def _cuts(self, p, t_end):
        """The switch instants k T + b inside (0, t_end), increasing (the engine's next_switch: the
        same sum (k T) + b)."""
        if self.model.switch_times is None:
            return []
        T, times = self._switches(p)
        out = []
        k = 0.0
        while k * T < t_end:
            out += [k * T + b for b in times if 0.0 < k * T + b < t_end]
            k += 1.0
        return out

    def _integrate(self, p, fun, t_end, y0, method, rtol, atol, jac=None, events=None, dense_output=False):
        """solve_ivp of ``fun`` from (0, y0) to t_end; with the model's switch times, from switch to
        switch (a restart at each, the time passed to ``fun``/``jac`` kept inside the segment as the
        engine's), the segments' results joined into one result of the fields the callers read (t, y,
        nfev, status, t_events, y_events, sol). Without switch times the one solve_ivp call as before."""
        from scipy.integrate import solve_ivp

        kw = {} if jac is None else {"jac": jac}
        if events is not None:
            kw["events"] = events
        if dense_output:
            kw["dense_output"] = True
        cuts = self._cuts(p, t_end)
        if not cuts:
            return solve_ivp(fun, (0.0, t_end), y0, method=method, rtol=rtol, atol=atol, **kw)
        from types import SimpleNamespace

        from ..model.switches import SIDE
        ends = cuts + [t_end]
        y = np.asarray(y0, dtype=np.float64)
        ts, te, ye, pieces = [0.0], [], [], []
        nfev, status = 0, 0
        need = getattr(events, "terminal", 0) if events is not None else 0
        for j, b in enumerate(ends):
            a = 0.0 if j == 0 else ends[j - 1]
            lo = -math.inf if j == 0 else a + SIDE * abs(a)  # the start itself is not moved
            hi = b - SIDE * abs(b) if j < len(cuts) else math.inf

            def f(t, z, lo=lo, hi=hi):
                return fun(min(max(t, lo), hi), z)
            seg = dict(kw)
            if jac is not None:
                seg["jac"] = lambda t, z, lo=lo, hi=hi: jac(min(max(t, lo), hi), z)
            if events is not None:
                ev = lambda t, z: events(t, z)  # noqa: E731 - the same event, its count what is left
                ev.direction = getattr(events, "direction", 0.0)
                ev.terminal = need - len(te) if need else False
                seg["events"] = ev
            sol = solve_ivp(f, (a, b), y, method=method, rtol=rtol, atol=atol, **seg)
            nfev += sol.nfev
            ts += list(sol.t[1:])
            if events is not None:
                te += list(sol.t_events[0])
                ye += list(sol.y_events[0])
            if dense_output and sol.sol is not None:
                pieces.append((a, sol.sol))
            status = sol.status
            y = sol.y[:, -1]
            if status != 0:
                break
        starts = [a for a, _ in pieces]

        def dense(t):
            return pieces[max(0, int(np.searchsorted(starts, t, side="right")) - 1)][1](t)
        return SimpleNamespace(t=np.array(ts), y=y[:, None], nfev=nfev, status=status, t_events=[np.array(te)],
                               y_events=[np.array(ye)], sol=dense if dense_output else None)

    def _jac_kw(self, p, method):
        """scipy's jac= for Radau and LSODA: the model's own where it declares one."""
        if self._jac is None or method == "DOP853":
            return {}
        jac, J = self._jac, np.empty((self.n, self.n))

        def f(t, y):
            jac(t, y, p, J)
            return J.copy()
        return {"jac": f}

    def _window(self, p):
        m = self.m
        t0 = self._fn["t0"](p) if "t0" in self._fn else float(m.t0)
        t1 = self._fn["t1"](p) if "t1" in self._fn else float(m.t1)
        return t0, t1

    # ------------------------------------------------------------------ one point
    def value(self, row, method, rtol, atol):
        """(value, rhs evaluations, accepted steps) at parameter row ``row`` with scipy ``method``."""
        from ..model import measure as ms

        p = self.point(row, rtol)
        if p is None:
            return math.nan, 0, 0
        m = self.m
        if isinstance(m, ms.FirstEvent):
            return self._first_event(p, method, rtol, atol)
        if isinstance(m, (ms.Crossing, ms.Period)):
            return self._crossing(p, method, rtol, atol)
        if isinstance(m, ms.StateAt):
            return self._state_at(p, method, rtol, atol)
        if isinstance(m, ms.Extremum):
            return self._extremum(p, method, rtol, atol)
        return self._floquet(p, method, rtol, atol)

    def _solve(self, p, t_end, method, rtol, atol, **kw):
        return self._integrate(p, self.f(p), t_end, self.y0(p), method, rtol, atol,
                               jac=self._jac_kw(p, method).get("jac"), **kw)

    def _first_event(self, p, method, rtol, atol):
        """One pass; where the measurement declares ``refine``, its factor f decides as in the engine:
        f <= 1 the value stands, f not finite NaN (ILL_CONDITIONED), else a second pass from the start
        at rtol / f, atol / f gives the value (both passes counted)."""
        value, nfev, steps = self._event_pass(p, method, rtol, atol)
        if "refine" not in self._fn or not math.isfinite(value):
            return value, nfev, steps
        f = self._fn["refine"](p, rtol, value)
        if f <= 1.0:
            return value, nfev, steps
        if not math.isfinite(f):
            return math.nan, nfev, steps
        value, nfev2, steps2 = self._event_pass(p, method, rtol / f, atol / f)
        return value, nfev + nfev2, steps + steps2

    def _event_pass(self, p, method, rtol, atol):
        m = self.m
        ev = self._fn["event"]
        t_max = self._fn["t_max"](p) if "t_max" in self._fn else float(m.t_max)

        def event(t, y):
            return ev(t, y, p)
        event.direction = -1.0 if m.direction == "down" else 1.0  # > 0 to <= 0, or the reverse
        event.terminal = m.n
        sol = self._solve(p, t_max, method, rtol, atol, events=event)
        times = sol.t_events[0]
        steps = sol.t.size - 1
        if sol.status < 0 or times.size < m.n:
            return math.nan, sol.nfev, steps
        t = float(times[m.n - 1]) - (float(times[m.since - 1]) if m.since else 0.0)
        return (float(self._fn["value"](p, t)) if "value" in self._fn else t), sol.nfev, steps

    def _crossing(self, p, method, rtol, atol):
        from ..model import measure as ms

        m = self.m
        i = self.model.states.index(m.state)
        count = m.n if isinstance(m, ms.Crossing) else 2

        def event(t, y):
            return y[i] - m.level
        event.direction = -1.0 if m.direction == "down" else 1.0
        event.terminal = count
        sol = self._solve(p, m.t_max, method, rtol, atol, events=event)
        times = sol.t_events[0]
        steps = sol.t.size - 1
        if sol.status < 0 or times.size < count:
            return math.nan, sol.nfev, steps
        value = times[count - 1] if isinstance(m, ms.Crossing) else times[1] - times[0]
        return float(value), sol.nfev, steps

    def _state_at(self, p, method, rtol, atol):
        m = self.m
        i = self.model.states.index(m.state)
        if m.t == 0.0:
            return float(self.y0(p)[i]), 0, 0
        sol = self._solve(p, m.t, method, rtol, atol)
        if sol.status != 0:
            return math.nan, sol.nfev, sol.t.size - 1
        return float(sol.y[i, -1]), sol.nfev, sol.t.size - 1

    def _extremum(self, p, method, rtol, atol):
        m = self.m
        rhs = self._rhs
        s = 1.0 if m.kind == "max" else -1.0
        d = np.empty(self.n)
        t0, t1 = self._window(p)
        if not (0.0 <= t0 < t1 < math.inf):
            return math.nan, 0, 0
        if isinstance(m.state, str):
            i = self.model.states.index(m.state)

            def of(t, y):
                return y[i]

            def turn(t, y):  # s * dy_i/dt through zero from + to -: a maximum of s * y_i
                rhs(t, y, p, d)
                return s * d[i]
        else:
            f = self._fn["of"]
            e = np.finfo(float).eps ** (1.0 / 3.0) * 1e-2 * (t1 - t0)  # a hundredth of the window as time scale

            def of(t, y):
                return f(t, y, p)

            def turn(t, y):  # the expression's rate along the flow, a central difference
                rhs(t, y, p, d)
                return s * (f(t + e, y + e * d, p) - f(t - e, y - e * d, p)) / (2.0 * e)
        turn.direction = -1.0
        sol = self._solve(p, t1, method, rtol, atol, events=turn, dense_output=True)
        if sol.status != 0:
            return math.nan, sol.nfev, sol.t.size - 1
        start = sol.sol(t0) if t0 > 0 else self.y0(p)
        candidates = [s * of(t1, sol.y[:, -1]), s * of(t0, start)]
        for t_e, y_e in zip(sol.t_events[0], sol.y_events[0]):
            if t0 <= t_e <= t1:
                candidates.append(s * of(t_e, y_e))
        return float(s * max(candidates)), sol.nfev, sol.t.size - 1

    def _floquet(self, p, method, rtol, atol):
        n = self.n
        T = float(getattr(self.model.forcing_period, "py_func", self.model.forcing_period)(p))
        if not (math.isfinite(T) and T > 0):
            return math.nan, 0, 0
        rhs, jac = self._rhs, self._jac
        J = np.empty((n, n))
        d0, d1 = np.empty(n), np.empty(n)
        eps = np.finfo(float).eps ** (1.0 / 3.0)

        def jacobian(t, y):
            if jac is not None:
                jac(t, y, p, J)
                return J
            for j in range(n):
                h = eps * max(1.0, abs(y[j]))
                yp, ym = y.copy(), y.copy()
                yp[j] += h
                ym[j] -= h
                rhs(t, yp, p, d1)
                rhs(t, ym, p, d0)
                J[:, j] = (d1 - d0) / (yp[j] - ym[j])
            return J

        def f(t, z):
            y = z[:n]
            dz = np.empty_like(z)
            rhs(t, y, p, d0)
            dz[:n] = d0
            dz[n:] = (jacobian(t, y) @ z[n:].reshape(n, n)).ravel()
            return dz
        y0 = self.y0(p)
        if "initial" in self._fn:  # the orbit's own start (Floquet's initial), not the model's initial state
            self._fn["initial"](p, y0)
        z0 = np.concatenate([y0, np.eye(n).ravel()])
        sol = self._integrate(p, f, T, z0, method, rtol, atol)
        if sol.status != 0:
            return math.nan, sol.nfev, sol.t.size - 1
        mono = sol.y[n:, -1].reshape(n, n)
        return float(np.abs(np.linalg.eigvals(mono)).max()), sol.nfev, sol.t.size - 1

    def reference(self, P):
        return np.array([self.value(r, "DOP853", REFERENCE_RTOL, REFERENCE_ATOL)[0] for r in P])


def default_output(model) -> str:
    """The first measured output this bench has a scipy version of."""
    from ..model import measure as ms

    for m in model.measurements:
        if isinstance(m, (ms.Crossing, ms.Period, ms.StateAt, ms.Extremum, ms.Floquet, ms.FirstEvent)):
            return m.name
    raise InputError(f"model {model.name!r} has no measurement this bench has a scipy version of")


def invariant_drift(model):
    """The drift of the quantity a model declares conserved (``OdeModel(invariant=Invariant(...))``):
    one integration from the model's ``initial(p, y0)`` at the point ``invariant.at`` through
    ``invariant.periods`` periods (continued from each end), by dop853 at each of ``invariant.rtols``
    (atol = 1e-2 rtol) and, where the model declares ``accel``, by the symplectic method at its
    ``symplectic_step(p, rtol)``; the model's own rhs and accel compiled as the engine's. Returns
    (names, relative errors [name, period], rhs evaluations over the whole run); None without an
    invariant. A point the model's classify or prepare refuses is an InputError (the declaration's
    ``at`` is wrong)."""
    from .. import status as st
    from ..ode import dop853, symplectic

    inv = model.invariant
    if inv is None:
        return None
    def compiled(func, what):
        return _compiled(model, func, what)
    n = len(model.states)
    row = []
    for q in model.params:
        v = inv.at.get(q.name, q.default)
        row.append(float(q.choices.index(v)) if (q.choices and isinstance(v, str)) else float(v))
    settings = [float(inv.at.get(x.name, x.default)) for x in model.settings]
    tail = len(model.internal) + 1 + 3 * n + n * n + 1
    explicit = dop853.make_solver(compiled(model.rhs, "rhs"))
    composed = (symplectic.make_solver(compiled(model.accel, "accel"), model.symplectic_order)
                if model.accel is not None else None)
    names, errors, costs = [], [], []
    for rtol in inv.rtols:
        p = np.array(row + settings + [0.0] * tail)
        for role in ("classify", "prepare"):
            f = getattr(model, role)
            code = None if f is None else (_plain(f)(p) if role == "classify" else _plain(f)(p, rtol))
            if code is not None and code != st.OK:
                raise InputError(f"model {model.name!r}: its invariant's point at = {inv.at!r} is refused by its "
                                 f"{role} (status {st.MEANINGS.get(int(code), code)}) at rtol {rtol:g}")
        T = float(_plain(inv.period)(p)) if callable(inv.period) else float(inv.period)
        y0 = np.empty(n)
        _plain(model.initial)(p, y0)
        e0 = _plain(inv.func)(y0, p)
        for name in ("dop853",) + (("symplectic",) if composed is not None else ()):
            err, cost = [], 0
            y, t = y0.copy(), 0.0
            q, v = y0[:n // 2].copy(), y0[n // 2:].copy()
            for k in inv.periods:  # continued from the previous end: one long integration
                t_end = k * T
                if name == "dop853":
                    _, _, nr = explicit(t, y, p, t_end, rtol, rtol * 1e-2, 0.0, 10**8, dop853.workspace(n))
                    state = y
                else:
                    steps = int(math.ceil((t_end - t) / float(_plain(model.symplectic_step)(p, rtol))))
                    _, _, nr = composed(t, q, v, p, t_end, steps, symplectic.workspace(n // 2))
                    state = np.concatenate([q, v])
                cost += nr
                t = t_end
                err.append(abs(_plain(inv.func)(state, p) - e0) / abs(e0))
            names.append(f"mechsweep {name}, rtol {rtol:g}")
            errors.append(err)
            costs.append(cost)
    return names, np.array(errors), np.array(costs)
