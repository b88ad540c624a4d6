"""Mathieu's equation x'' + (a - 2 q cos 2t) x = 0 (period pi) as a user model, for the Floquet
measurement (tests/model/test_model_layer.py): its stability boundaries are the characteristic-value
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


def damped_variational(t, Phi, p, dPhi):
    """The variational system about the known orbit x = 0 (the equation is linear: it is the
    equation itself), on each column of Phi (column-major, 2 x 2)."""
    k = p[0] - 2.0 * p[1] * math.cos(2.0 * t)
    for c in range(2):
        dPhi[2 * c] = Phi[2 * c + 1]
        dPhi[2 * c + 1] = -p[2] * Phi[2 * c + 1] - k * Phi[2 * c]


def damped_variational_jac(t, Phi, p, J):
    """Its 4 x 4 Jacobian: the 2 x 2 Jacobian of the equation on the diagonal, twice."""
    J[:, :] = 0.0
    for c in range(2):
        J[2 * c, 2 * c + 1] = 1.0
        J[2 * c + 1, 2 * c] = -(p[0] - 2.0 * p[1] * math.cos(2.0 * t))
        J[2 * c + 1, 2 * c + 1] = -p[2]


# the damped Mathieu equation with its variational system given: Floquet integrates the 4 equations
# of Phi alone (MATHIEU_VAR_FD: without its Jacobian, radau differentiates it)
MATHIEU_VAR = OdeModel(
    name="mathieu_variational", description="damped Mathieu equation, Floquet on its own variational system",
    params=MATHIEU_JAC.params, states=("x", "v"), rhs=damped_rhs, initial=initial, forcing_period=period,
    jac=damped_jac,
    measurements=(Floquet("max_multiplier", variational=damped_variational, variational_jac=damped_variational_jac),),
)
MATHIEU_VAR_FD = OdeModel(
    name="mathieu_variational_fd", description="damped Mathieu equation, Floquet on its own variational system "
    "(no Jacobian of it)",
    params=MATHIEU_JAC.params, states=("x", "v"), rhs=damped_rhs, initial=initial, forcing_period=period,
    jac=damped_jac, measurements=(Floquet("max_multiplier", variational=damped_variational),),
)
