"""Mathieu's equation x'' + (a - 2 q cos 2t) x = 0 (period pi) as a user model, for the Floquet
measurement (tests/test_model_layer.py): its stability boundaries are the characteristic-value
curves a = a_n(q), a = b_n(q) (scipy.special.mathieu_a / mathieu_b)."""
import math

from mechsweep.model import ClosedForm, Floquet, OdeModel, Param


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


def damped_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[2] * y[1] - (p[0] - 2.0 * p[1] * math.cos(2.0 * t)) * y[0]


def damped_jac(t, y, p, J):
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    J[1, 0] = -(p[0] - 2.0 * p[1] * math.cos(2.0 * t))
    J[1, 1] = -p[2]


# x'' + c x' + (a - 2 q cos 2t) x = 0 with its analytic Jacobian: the product of the two multipliers
# is exp(-c pi) (Liouville), so inside a stability region both have modulus exp(-c pi / 2).
MATHIEU_JAC = OdeModel(
    name="mathieu_damped",
    description="damped Mathieu equation x'' + c x' + (a - 2 q cos 2t) x = 0, analytic Jacobian",
    params=(Param("a", "a", "1", "characteristic parameter"), Param("q", "q", "1", "forcing parameter"),
            Param("c", "c", "1", "damping", lo=0.0)),
    states=("x", "v"),
    rhs=damped_rhs,
    initial=initial,
    forcing_period=period,
    jac=damped_jac,
    measurements=(Floquet("max_multiplier"),),
)


def twice(p, x):
    return 2.0 * x


# the damped Mathieu equation with closed forms reading the Floquet measurement's kind and angle
# (outputs besides its first: the kernel's further values)
MATHIEU_CF = OdeModel(
    name="mathieu_closed_forms",
    description="damped Mathieu equation; closed forms of the critical multiplier's kind and angle",
    params=MATHIEU_JAC.params, states=("x", "v"), rhs=damped_rhs, initial=initial, forcing_period=period,
    jac=damped_jac, measurements=(Floquet("max_multiplier"),),
    closed_forms=(ClosedForm("angle2", twice, "2 arg", "rad", "twice the angle", needs=("max_multiplier_angle",)),
                  ClosedForm("kind2", twice, "2 kind", "1", "twice the kind", needs=("max_multiplier_kind",))),
)
