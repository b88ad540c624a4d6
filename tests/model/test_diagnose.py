"""The replay that explains a USER_ERROR point (model/diagnose.py) in plain Python: a float error
that the compiled code turns into inf or NaN (a division by zero, a math domain or range error) is
not what raised in the kernel, so the replay names the exception raised after it. Nothing is
compiled here."""
import math
from pathlib import Path

import numpy as np

from mechsweep import status as st
from mechsweep.model import ClosedForm, ClosedFormModel, FirstEvent, OdeModel, Output, Param
from mechsweep.model.diagnose import explain, explain_closed

HERE = Path(__file__).resolve()


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -y[0] + math.sqrt(2.0 - p[0]) * 0.0  # NaN for W > 2 in the kernel, ValueError in Python


def initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


def event(t, y, p):
    return y[0] + 1.0 / (p[0] - 3.0)  # inf at W = 3 in the kernel, ZeroDivisionError in Python


def refuses(p):
    if p[0] > 2.0:
        raise ValueError("W above 2 refused")
    return 1.0


MODEL = OdeModel(
    name="ieee_replay", description="replay test",
    params=(Param("W", "W", "rad s-1", "frequency", lo=0.0, lo_open=True),),
    states=("x", "v"), rhs=rhs, initial=initial,
    measurements=(FirstEvent("t_event", event, t_max=10.0, unit="s", long_name="event time"),),
    closed_forms=(ClosedForm("c", refuses, "c", "1", "refuses W > 2"),),
)


def line_of(words):
    """The line of this file that raises ValueError(words)."""
    return 1 + next(j for j, x in enumerate(HERE.read_text().splitlines()) if f'raise ValueError("{words}")' in x)


def test_a_float_error_in_plain_python_is_passed_over_and_the_raise_after_it_named():
    why = explain(MODEL, np.array([3.0]), np.zeros(0), 1e-8)
    assert why == (f"closed form c raised ValueError: W above 2 refused ({HERE}, line "
                   f"{line_of('W above 2 refused')}, in refuses)"), why


def test_with_nothing_else_raising_the_replay_says_so_and_names_the_float_error():
    plain = OdeModel(name="ieee_plain", description="replay test", params=MODEL.params, states=("x", "v"),
                     rhs=rhs, initial=initial,
                     measurements=(FirstEvent("t_event", event, t_max=10.0, unit="s", long_name="event time"),))
    why = explain(plain, np.array([3.0]), np.zeros(0), 1e-8)
    assert why.startswith("no exception in plain Python up to the start of the integration"), why
    assert "(rhs at t = 0 raised ValueError: math domain error" in why and "not an exception)" in why, why
    assert explain(plain, np.array([1.0]), np.zeros(0), 1e-8).endswith("in a formula of measured values)")


def compute(p, want, row, curves, slot, scratch):
    row[0] = math.log(p[0] - 1.0)  # -inf at W = 1 in the kernel, ValueError in Python
    if p[0] < 1.5:
        raise ValueError("W below 1.5 refused")
    return st.OK


CLOSED = ClosedFormModel(name="ieee_closed", description="replay test",
                         params=(Param("W", "W", "1", "ratio", lo=0.0, lo_open=True, default=2.0),),
                         outputs=(Output("y", "y", "1", "log"),), compute=compute)


def test_a_closed_form_models_float_error_is_said_to_be_no_exception_in_the_kernel():
    why = explain_closed(CLOSED, np.array([1.0]), np.array([True]), np.zeros(0, dtype=np.int64), 0, 1, ())
    assert why.startswith("compute raised ValueError: math domain error") and "compiled code gives inf or NaN" in why
    why = explain_closed(CLOSED, np.array([1.2]), np.array([True]), np.zeros(0, dtype=np.int64), 0, 1, ())
    assert why == (f"compute raised ValueError: W below 1.5 refused ({HERE}, line "
                   f"{line_of('W below 1.5 refused')}, in compute)"), why
