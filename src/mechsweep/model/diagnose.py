"""Why a point has status USER_ERROR: replay the model's own functions at that point in plain
Python. The compiled guards only flag the point (numba keeps no exception object in a parallel
loop); the replay runs what happens first at the point, in order: classify, prepare, initial, the
right-hand side and Jacobian at t = 0, the forcing period, each measurement's horizon and its
event at t = 0, and the closed forms that need no measurement. A model with switch times
(model/switches.py) is replayed on the route its solvers take: the forcing period and its
``switch_times(p)`` before the first rhs call (what every solver's ``switch_check`` calls), then the
rhs and Jacobian at t = 0 and at the start of each segment of the first forcing period (just after
each switch, at the time the solvers pass there), with the initial state (the state at the switch is
not integrated here). The first exception gives its type, message, and the file and line in the
model's code. Code reached only later in the integration (at t > 0 elsewhere, in a refinement, or
in a formula of measured values) is not replayed: the answer then says so. A ClosedFormModel's
``compute`` is replayed whole at the design (:func:`explain_closed`).

Plain Python raises on float arithmetic the compiled kernel does by IEEE rules (numba's
``error_model="numpy"``): ``1.0 / 0.0``, ``math.sqrt(-1.0)``, ``math.exp(1000.0)`` give inf or NaN
there, not an exception. Such an error is not the point's USER_ERROR, so the replay passes over it
(:func:`_ieee`) and names what raised after it."""
from __future__ import annotations

import math
import traceback

import numpy as np

from .switches import SIDE

SCRATCH = 64  # zero slots beyond the declared ones: a function that reads past them gets zeros


def _py(func):
    """The plain Python function behind a numba dispatcher (or the function itself)."""
    return getattr(func, "py_func", func)


def _where(exc: BaseException) -> str:
    """'file, line N, in name' of the innermost frame of the traceback."""
    frames = traceback.extract_tb(exc.__traceback__)
    if not frames:
        return "unknown place"
    f = frames[-1]
    return f"{f.filename}, line {f.lineno}, in {f.name}"


def _ieee(exc: BaseException) -> bool:
    """Whether ``exc`` is plain Python's float error (a division by zero, a math domain or range
    error) that the compiled code turns into inf or NaN, not an exception the model's code raises
    itself (a ``raise`` statement)."""
    frames = traceback.extract_tb(exc.__traceback__)
    if frames and (frames[-1].line or "").lstrip().startswith("raise"):
        return False
    if isinstance(exc, (ZeroDivisionError, OverflowError)):
        return True
    text = str(exc)  # math's messages: "math domain error"; from Python 3.14 "expected a positive input, ..."
    return isinstance(exc, ValueError) and (text == "math domain error"
                                            or (text.startswith("expected a ") and " input" in text))


def _switches(model, p) -> tuple:
    """The switch times of the first forcing period at ``p`` the solvers would step onto, or () where
    the kernel's check refuses them (INFEASIBLE: no switch is reached) or their code raises (the
    replay calls it first and reports that)."""
    try:
        T = float(_py(model.forcing_period)(p))
        sw = model.switch_times
        times = [float(x) for x in (_py(sw)(p) if callable(sw) else sw)]
    except Exception:  # noqa: BLE001 - reported by the replay's own call
        return ()
    ok = (math.isfinite(T) and T > 0.0 and times and all(math.isfinite(x) and 0.0 <= x < T for x in times)
          and all(a < b for a, b in zip(times, times[1:])))
    return tuple(x for x in times if x > 0.0) if ok else ()  # a switch at 0 is the start: not moved


def _calls(model, p, y0, rtol):
    """(what, thunk) in the order the kernel meets them."""
    n = len(model.states)
    dydt, J = np.zeros(n), np.zeros((n, n))
    out = []
    if model.classify is not None:
        out.append(("classify", lambda: _py(model.classify)(p)))
    if model.prepare is not None:
        out.append(("prepare", lambda: _py(model.prepare)(p, rtol)))
    out.append(("initial", lambda: _py(model.initial)(p, y0)))
    switched = getattr(model, "switch_times", None) is not None
    if switched:  # every solver checks the switch times before its first rhs call (switches.switch_check)
        out.append(("forcing_period", lambda: _py(model.forcing_period)(p)))
        if callable(model.switch_times):
            out.append(("switch_times", lambda: _py(model.switch_times)(p)))
    out.append(("rhs at t = 0", lambda: _py(model.rhs)(0.0, y0, p, dydt)))
    if model.jac is not None:
        out.append(("jac at t = 0", lambda: _py(model.jac)(0.0, y0, p, J)))
    if switched:
        for b in _switches(model, p):
            t = b + SIDE * abs(b)  # where the solvers evaluate the segment that starts at the switch b
            out.append((f"rhs just after the switch at t = {b:g} (t = {t!r}, with the initial state)",
                        lambda t=t: _py(model.rhs)(t, y0, p, dydt)))
            if model.jac is not None:
                out.append((f"jac just after the switch at t = {b:g} (t = {t!r}, with the initial state)",
                            lambda t=t: _py(model.jac)(t, y0, p, J)))
    elif model.forcing_period is not None:
        out.append(("forcing_period", lambda: _py(model.forcing_period)(p)))
    for m in model.measurements:
        roles = dict(getattr(m, "functions", lambda: ())())
        if "t_max" in roles:
            out.append((f"{m.name}: t_max", lambda f=roles["t_max"]: _py(f)(p)))
        if "event" in roles:
            out.append((f"{m.name}: event at t = 0", lambda f=roles["event"]: _py(f)(0.0, y0, p)))
    for c in model.closed_forms:
        if not c.needs:
            out.append((f"closed form {c.name}", lambda f=c.func: _py(f)(p)))
    return out


def point_text(params, row) -> str:
    """'k = 3, spring = tanh': a point's parameters as a scene gives them (a categorical one by the
    name of its choice, not the index the kernel receives)."""
    parts = []
    for q, v in zip(params, row):
        v = float(v)
        choices = getattr(q, "choices", ())
        if choices and v.is_integer() and 0 <= int(v) < len(choices):
            parts.append(f"{q.name} = {choices[int(v)]}")
        else:
            parts.append(f"{q.name} = {v:g}")
    return ", ".join(parts)


def explain_closed(model, row: np.ndarray, want: np.ndarray, slot: np.ndarray, n_curves: int, n: int,
                   data: tuple) -> str:
    """One line: what a ClosedFormModel's ``compute`` raised at the design ``row``, replayed in plain
    Python with the run's arguments (``want``, ``slot``, ``n_curves`` wanted curves of ``n`` values,
    the shared ``data``; the scratch rows zero, where the kernel leaves the previous design's
    values), or that it raised nothing there."""
    func = _py(model.compute)
    scratch = np.zeros((model.scratch, n))
    args = (np.array(row, dtype=np.float64), np.array(want, dtype=np.bool_), np.full(len(model.scalars), np.nan),
            np.full((n_curves, n), np.nan), np.array(slot, dtype=np.int64), scratch)
    try:
        with np.errstate(all="ignore"):
            code = func(*args, *[np.array(a) for a in data])
    except Exception as e:  # noqa: BLE001 - the user's exception is the answer
        if _ieee(e):
            return (f"compute raised {type(e).__name__}: {e} ({_where(e)}) in plain Python, where the compiled "
                    "code gives inf or NaN and goes on: what raised there comes later in compute")
        return f"compute raised {type(e).__name__}: {e} ({_where(e)})"
    if code is None:
        return "compute returned None (expected a status code)"
    return (f"no exception in plain Python at this design (compute returned {code!r}; replayed with its scratch "
            "zeroed, where the kernel leaves the previous design's values)")


def explain(model, row: np.ndarray, settings: np.ndarray, rtol: float) -> str:
    """One line: the first exception the model's functions raise at the point (parameters ``row``,
    settings values ``settings``), or that none does before the integration starts."""
    n_p, n_s = len(model.params), len(settings)
    p = np.zeros(n_p + n_s + len(model.internal) + SCRATCH)
    p[:n_p] = row
    p[n_p:n_p + n_s] = settings
    y0 = np.zeros(len(model.states))
    passed = ""  # the first float error passed over (inf or NaN in the kernel), said if nothing else raised
    for what, call in _calls(model, p, y0, rtol):
        try:
            with np.errstate(all="ignore"):
                call()
        except Exception as e:  # noqa: BLE001 - the user's exception is the answer
            if not _ieee(e):
                return f"{what} raised {type(e).__name__}: {e} ({_where(e)})"
            passed = passed or (f" ({what} raised {type(e).__name__}: {e} ({_where(e)}) in plain Python, "
                                "inf or NaN in the compiled code, not an exception)")
    return ("no exception in plain Python up to the start of the integration: it raised later (at t > 0, "
            "in a refinement or in a formula of measured values)" + passed)
