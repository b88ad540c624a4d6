"""A linear oscillator x'' = -w^2 x from x = A, x' = 0 (x = A cos(w t), v = -A w sin(w t)) for the
measurements of expressions, n-th roots and windows that are functions of p
(tests/model/test_model_layer_measure.py). No jac: radau differentiates the rhs itself."""
import math

import numba

from mechsweep.model import ClosedForm, Extremum, FirstEvent, Floquet, OdeModel, Param

SINGULAR, OK = 5, 0


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * p[0] * y[0]


def initial(p, y0):
    y0[0] = p[1]
    y0[1] = 0.0


def accel(t, q, p, a):
    a[0] = -p[0] * p[0] * q[0]


def step(p, rtol):
    return 2.0 * math.pi / p[0] / math.ceil(3.0 * rtol ** (-1.0 / 8.0))


def mixed(t, y, p):  # x + v / w = A sqrt(2) cos(w t + pi / 4): a combination of the states
    return y[0] + y[1] / p[0]


def kinetic(t, y, p):  # v^2 / 2 = (A w)^2 sin^2(w t) / 2
    return 0.5 * y[1] * y[1]


def power(t, y, p):  # x v = -(A^2 w / 2) sin(2 w t)
    return y[0] * y[1]


def kinetic_rate(t, y, p):  # d/dt (v^2 / 2) = v v' = -w^2 x v: from > 0 to <= 0 at every maximum of v^2
    return -p[0] * p[0] * y[0] * y[1]


def early_from(p):
    return 0.1 / p[0]


def early_to(p):
    return 0.5 / p[0]


def late_from(p):  # w t = pi / 4
    return 0.25 * math.pi / p[0]


def late_to(p):  # w t = pi
    return math.pi / p[0]


def one_over_w(p):  # a window [1 / w, 1]: empty where w <= 1
    return 1.0 / p[0]


@numba.njit  # numba's default error model: 1 / 0 would raise ZeroDivisionError here
def _inverse(x):
    return 1.0 / x


def detuning(p):  # 1 / (w - 1): infinite at w = 1
    return _inverse(p[0] - 1.0)


def detuning_classify(p):
    return OK if math.isfinite(_inverse(p[0] - 1.0)) else SINGULAR


MODEL = OdeModel(
    name="linear_more",
    description="x'' + w^2 x = 0 released from rest at x = A",
    params=(Param("w", "w", "rad s-1", "natural frequency", lo=0.0, lo_open=True),
            Param("A", "A", "m", "amplitude", lo=0.0, lo_open=True)),
    states=("x", "v"), rhs=rhs, initial=initial, accel=accel, symplectic_step=step,
    measurements=(
        FirstEvent("down3", mixed, t_max=100.0, n=3),  # w t + pi/4 = pi/2 + 4 pi
        FirstEvent("up1", mixed, t_max=100.0, direction="up"),  # w t + pi/4 = 3 pi / 2
        FirstEvent("up2", mixed, t_max=100.0, n=2, direction="up"),  # w t + pi/4 = 3 pi / 2 + 2 pi
        FirstEvent("down3_short", mixed, t_max=10.0, n=3),  # beyond t_max where w < 17 pi / 40
        FirstEvent("period_up", mixed, t_max=100.0, n=2, direction="up", since=1),  # 2 pi / w
        FirstEvent("two_periods", kinetic_rate, t_max=100.0, n=4, since=2),  # v^2 peaks: 2 x (pi / w)
        Extremum("ke_max", kinetic, 0.0, 10.0, unit="J kg-1"),
        Extremum("power_early", power, early_from, early_to),  # an end of the window: w t = 0.1
        Extremum("power_late", power, late_from, late_to),  # interior: 2 w t = 3 pi / 2
        Extremum("x_min_late", "x", late_from, late_to, kind="min"),  # -A at w t = pi (the end)
        Extremum("bad_window", "x", one_over_w, 1.0),
    ),
    closed_forms=(ClosedForm("detuning", detuning, classify=detuning_classify),
                  ClosedForm("detuning_raw", detuning)),
)


def counted_rhs(t, y, p, dydt):  # the same oscillator, counting its own calls in the internal slot p[2]
    p[2] += 1.0
    dydt[0] = y[1]
    dydt[1] = -p[0] * p[0] * y[0]


def x_event(t, y, p):
    return y[0]


def period(p):  # Floquet over one free period: both multipliers on the unit circle
    return 2.0 * math.pi / p[0]


def calls(p, t):  # computed after the measurement: the rhs calls of this point's integration
    return p[2]


COUNTED = OdeModel(
    name="linear_counted",
    description="x'' + w^2 x = 0 released from rest at x = A; the rhs counts its calls",
    params=MODEL.params, states=("x", "v"), rhs=counted_rhs, initial=initial, internal=("calls",),
    forcing_period=period,
    measurements=(FirstEvent("t_zero", x_event, t_max=100.0),  # w t = pi / 2
                  Floquet("mult"),
                  Extremum("v_max", "v", 0.1, 10.0)),  # A w, interior turning points (roots of -w^2 x)
    closed_forms=(ClosedForm("rhs_calls", calls, needs=("t_zero",)),
                  ClosedForm("rhs_calls_floquet", calls, needs=("mult",)),
                  ClosedForm("rhs_calls_extremum", calls, needs=("v_max",))),
)
