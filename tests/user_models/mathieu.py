"""Mathieu's equation x'' + (a - 2 q cos 2t) x = 0 (period pi) as a user model, for the Floquet
measurement (tests/test_model_layer.py): its stability boundaries are the characteristic-value
curves a = a_n(q), a = b_n(q) (scipy.special.mathieu_a / mathieu_b)."""
import math

from mechsweep.model import Floquet, OdeModel, Param


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -(p[0] - 2.0 * p[1] * math.cos(2.0 * t)) * y[0]


def initial(p, y0):
    y0[0] = 0.0
    y0[1] = 0.0


def period(p):
    return math.pi


MATHIEU = OdeModel(
    name="mathieu",
    description="Mathieu's equation x'' + (a - 2 q cos 2t) x = 0",
    params=(Param("a", "a", "1", "characteristic parameter"), Param("q", "q", "1", "forcing parameter")),
    states=("x", "v"),
    rhs=rhs,
    initial=initial,
    forcing_period=period,
    measurements=(Floquet("max_multiplier"),),
)
