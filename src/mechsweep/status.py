"""Per-point status codes.

Kernels return or write these integers; Python decides what they mean. A point
whose status is not ``OK`` has NaN in every output that could not be computed;
a point with status ``OK`` never has a NaN or inf output (tests check this).
"""
from __future__ import annotations

import numpy as np

PENDING = -1  # not computed yet (only seen in an unfinished file)
OK = 0
MAX_STEPS = 1  # integration hit the step budget
STEP_UNDERFLOW = 2  # step size fell below round-off of t
NONFINITE = 3  # NaN or inf appeared in the state or an output
INFEASIBLE = 4  # parameters outside the model's physical domain at this point
SINGULAR = 5  # a formula is singular here (e.g. D0 -> 0)
NOT_OSCILLATORY = 6  # the motion is not an oscillation about phi = 0 (decided by each model for its outputs)
NO_MOTION = 7  # amplitude A = 0: period-based ratios are undefined
NO_EVENT = 8  # an event (period crossing, settling) did not happen within the horizon
NOT_BALANCEABLE = 9  # no balanced state (A0 > 2 m a or A1 != 0): balanced-state outputs are NaN
UNDECIDED = 10  # stability undecided (simulation inconclusive, or |multiplier| within margin of 1)
STIFF = 11  # the explicit method detected stiffness and no implicit method was allowed to take over
ILL_CONDITIONED = 12  # the output is too sensitive here to reach the tolerance in double precision
NOT_REPRODUCIBLE = 13  # the value moved by more than its tolerance when integrated again at a tighter one
USER_ERROR = 14  # the model's own code (a user model's function) raised at this point

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
}

DESCRIPTIONS: dict[int, str] = {
    PENDING: "not computed yet (the run was interrupted; use --resume)",
    OK: "all requested outputs computed",
    MAX_STEPS: "the integrator used its whole step budget (solver.max_steps)",
    STEP_UNDERFLOW: "the step size fell below the round-off of t (stiff or singular)",
    NONFINITE: "NaN or inf appeared in the state or an output",
    INFEASIBLE: "parameters outside the model's physical domain at this point",
    SINGULAR: "a formula of the model is singular at this point",
    NOT_OSCILLATORY: "the motion is not an oscillation about phi = 0: the two-term model at or beyond its soft separatrix, or the exact spring moment never brings the lever back (each model decides for its own outputs; period_exact_moment is still given when only the two-term model fails)",
    NO_MOTION: "amplitude A = 0: there is no motion, ratios to A are undefined",
    NO_EVENT: "an event the output needs (a period crossing, settling) did not happen within the horizon",
    NOT_BALANCEABLE: "no balanced state exists (A0 > 2 m a, A0 = 0 or A1 != 0): balanced-state outputs are NaN",
    UNDECIDED: "stability could not be decided: the simulation neither settled nor diverged within the horizon, or floquet_max is within solver.floquet_margin of 1",
    ILL_CONDITIONED: "the output is too sensitive here to reach solver.rtol in double precision: its condition number with respect to the inputs times round-off exceeds rtol (the Duffing period below 1 + epsilon = 6.8e-7 at the default rtol, the exact-moment period next to a hump of the spring's potential); the closed form, where there is one, is still given",
    STIFF: "the problem is stiff at this point and the explicit method stopped (use method = \"auto\" or \"radau\")",
    NOT_REPRODUCIBLE: "integrated again at a tighter tolerance, an output moved by more than the tolerance it "
                      "claims (or the second integration failed): the value is stored but its trailing digits "
                      "are not meaningful (chaotic or transient-dominated motion)",
    USER_ERROR: "the model's own code raised at this point (an exception in a function of a model declared on "
                "the model layer, inside the compiled kernel; its message is lost): its outputs are NaN",
}

DTYPE = np.int8


def cf_attrs() -> dict:
    """CF flag attributes for the ``status`` variable."""
    codes = sorted(MEANINGS)
    return {
        "long_name": "status of the grid point",
        "flag_values": np.array(codes, dtype=DTYPE),
        "flag_meanings": " ".join(MEANINGS[c] for c in codes),
        "comment": "; ".join(f"{MEANINGS[c]}: {DESCRIPTIONS[c]}" for c in codes),
    }
