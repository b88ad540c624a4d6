"""Per-point status codes.

Kernels return or write these integers; Python decides what they mean. A point
whose status is not ``OK`` has NaN in every output that could not be computed;
a point with status ``OK`` never has a NaN or inf output (tests check this).
"""
from __future__ import annotations

import json

import numpy as np

PENDING = -1  # not computed yet (only seen in an unfinished file)
OK = 0
MAX_STEPS = 1  # integration hit the step budget
STEP_UNDERFLOW = 2  # step size fell below round-off of t
NONFINITE = 3  # NaN or inf appeared in the state or an output
INFEASIBLE = 4  # parameters outside the model's physical domain at this point
SINGULAR = 5  # a formula is singular here
NOT_OSCILLATORY = 6  # the motion is not the oscillation an output measures (each model decides for its outputs)
NO_MOTION = 7  # zero amplitude: outputs relative to the amplitude are undefined
NO_EVENT = 8  # an event (a crossing, settling) did not happen within the horizon
NOT_BALANCEABLE = 9  # no balanced state: balanced-state outputs are NaN
UNDECIDED = 10  # stability undecided (simulation inconclusive, or |multiplier| within margin of 1)
STIFF = 11  # dop853 spent its step budget at the stability limit (its stiffness test on its last steps)
ILL_CONDITIONED = 12  # the output is too sensitive here to reach the tolerance in double precision
NOT_REPRODUCIBLE = 13  # the value moved by more than its tolerance when integrated again at a tighter one
USER_ERROR = 14  # the model's own code (a user model's function) raised at this point
OUT_OF_RANGE = 15  # a quantity the outputs are computed from over- or underflows double precision here
LAST = OUT_OF_RANGE  # the largest code: a kernel's code outside OK..LAST is stored as USER_ERROR (runner)

# what an integration (or a tolerance it cannot reach) can end with, for models to declare
INTEGRATION_FAILURES = (MAX_STEPS, STEP_UNDERFLOW, NONFINITE, NO_EVENT, STIFF, ILL_CONDITIONED)

MEANINGS: dict[int, str] = {
    PENDING: "pending",
    OK: "ok",
    MAX_STEPS: "max_steps",
    STEP_UNDERFLOW: "step_underflow",
    NONFINITE: "nonfinite",
    INFEASIBLE: "infeasible",
    SINGULAR: "singular",
    NOT_OSCILLATORY: "not_oscillatory",
    NO_MOTION: "no_motion",
    NO_EVENT: "no_event",
    NOT_BALANCEABLE: "not_balanceable",
    UNDECIDED: "undecided",
    STIFF: "stiff",
    ILL_CONDITIONED: "ill_conditioned",
    NOT_REPRODUCIBLE: "not_reproducible",
    USER_ERROR: "user_error",
    OUT_OF_RANGE: "out_of_range",
}

DESCRIPTIONS: dict[int, str] = {
    PENDING: "not computed yet (the run was interrupted; use --resume)",
    OK: "all requested outputs computed",
    MAX_STEPS: "the integrator used its whole step budget (solver.max_steps)",
    STEP_UNDERFLOW: "the step size fell below the round-off of t (the equations or the solution are singular or "
                    "not smooth there)",
    NONFINITE: "NaN or inf appeared in the state or an output",
    INFEASIBLE: "parameters outside the model's physical domain at this point",
    SINGULAR: "a formula of the model is singular at this point",
    NOT_OSCILLATORY: "the motion is not the oscillation an output measures (each model decides for its own "
                     "outputs; an output that does not need that oscillation may still be given)",
    NO_MOTION: "the amplitude is zero: there is no motion, outputs relative to the amplitude are undefined",
    NO_EVENT: "an event an output needs (a crossing, settling) did not happen within the horizon",
    NOT_BALANCEABLE: "no balanced state exists: balanced-state outputs are NaN",
    UNDECIDED: "stability could not be decided: a simulation neither settled nor diverged within the horizon, "
               "or the largest Floquet multiplier modulus is within solver.floquet_margin of 1",
    ILL_CONDITIONED: "the output is too sensitive here to reach solver.rtol in double precision: its condition "
                     "number with respect to the inputs times round-off exceeds rtol; a closed form, where there "
                     "is one, is still given",
    STIFF: "the problem is stiff at this point: dop853 spent its step budget (solver.max_steps) with its step held "
           "at the stability limit, as Hairer's stiffness test found on its last steps (use method = \"auto\" or "
           "\"radau\" where the outputs offer them)",
    NOT_REPRODUCIBLE: "integrated again at a tighter tolerance, an output moved by more than the tolerance it "
                      "claims (or the second integration failed): the value is stored but its trailing digits "
                      "are not meaningful (chaotic or transient-dominated motion)",
    USER_ERROR: "the model's own code raised at this point (an exception in a function of a model declared on "
                "the model layer, inside the compiled kernel), or returned a status code that is none of these: "
                "its outputs are NaN; the run replays the first such point in plain Python and warns "
                "(UserModelWarning) with the exception's message, its file and line, and the point",
    OUT_OF_RANGE: "the inputs are of such magnitudes that a quantity the outputs are computed from would "
                  "overflow or underflow double precision (beyond about 1e308 or below about 1e-308): the "
                  "outputs it affects are NaN (each model's notes say where)",
}

DTYPE = np.int8


def cf_attrs(notes=()) -> dict:
    """CF flag attributes for the ``status`` variable. ``notes``: a model's (code, text) pairs
    (``ModelSpec.status_notes``), kept as the attribute ``status_notes`` (JSON, by meaning)."""
    codes = sorted(MEANINGS)
    attrs = {
        "standard_name": "status_flag",  # CF: the status of the variables naming it in ancillary_variables
        "long_name": "status of the grid point",
        "flag_values": np.array(codes, dtype=DTYPE),
        "flag_meanings": " ".join(MEANINGS[c] for c in codes),
        "comment": "; ".join(f"{MEANINGS[c]}: {DESCRIPTIONS[c]}" for c in codes),
    }
    if notes:
        attrs["status_notes"] = json.dumps({MEANINGS.get(int(c), str(c)): str(t) for c, t in notes})
    return attrs


def stored_notes(status_attrs) -> dict[str, str]:
    """A dataset's status notes {meaning: text} from its ``status`` variable's attributes ({} for a
    dataset written before models declared notes, or an unreadable attribute)."""
    try:
        notes = json.loads(status_attrs.get("status_notes", "{}"))
    except (TypeError, ValueError):
        return {}
    return {str(k): str(v) for k, v in notes.items()} if isinstance(notes, dict) else {}


def ranks(order) -> np.ndarray:
    """rank[code] for a model's ``status_order`` (most severe first): a listed status its position,
    a status not listed -1 (above every listed one: an unexpected problem is shown, not hidden),
    OK last."""
    rank = np.full(max(MEANINGS) + 1, -1, dtype=np.int64)
    for r, code in enumerate(order):
        rank[int(code)] = r
    rank[OK] = len(order)
    return rank


def worse(current, new, order):
    """Element-wise the more severe of two status arrays in ``order`` (see ``ranks``); equal ranks keep
    ``current``. Without an order: ``current`` where it is not OK, else ``new`` (first failure wins)."""
    new = np.broadcast_to(np.asarray(new, dtype=current.dtype), current.shape)
    if not order:
        return np.where(current == OK, new, current)
    rank = ranks(order)
    return np.where(rank[new] < rank[current], new, current)


def mark_not_reproducible(status, moved, order) -> None:
    """NOT_REPRODUCIBLE where ``moved``: ranked by the model's status order, else above the statuses
    that leave a value NaN for a reason (NO_EVENT, UNDECIDED) and OK, below integration failures."""
    if order:
        status[:] = worse(status, np.where(moved, NOT_REPRODUCIBLE, OK), order)
    else:
        soft = (status == OK) | (status == NO_EVENT) | (status == UNDECIDED)
        status[:] = np.where(moved & soft, NOT_REPRODUCIBLE, status)
