"""A linear oscillator x'' = -w^2 x declared with every feature of the model layer's engine side
(tests/model/test_model_layer_builtin.py): a setting and internal slots in p, classify and prepare, a
FirstEvent with a point-dependent event and a value transform, closed forms with needs, and the
separable form (accel) for the symplectic method; no jac (radau uses the engine's Jacobian).
p = (w, A | horizon | w_scaled, sign)."""
import math

from mechsweep.model import ClosedForm, FirstEvent, OdeModel, Param, Setting

NO_MOTION, INFEASIBLE, OK = 7, 4, 0


def classify(p):
    return NO_MOTION if p[1] == 0.0 else OK


def prepare(p, rtol):
    if p[0] > 5.0:  # refused for the test: measurements NaN, closed forms kept
        return INFEASIBLE
    p[3] = p[0]
    p[4] = 1.0 if p[1] > 0.0 else -1.0  # the event follows the sign of the release
    return OK


def initial(p, y0):
    y0[0] = p[1]
    y0[1] = 0.0


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[3] * p[3] * y[0]


def accel(t, q, p, a):
    a[0] = -p[3] * p[3] * q[0]


def step(p, rtol):
    return 2.0 * math.pi / p[3] / math.ceil(3.0 * rtol ** (-1.0 / 8.0))


def event(t, y, p):
    return p[4] * y[0]


def horizon(p):
    return p[2] / p[3]


def period_from_quarter(p, t):
    return 4.0 * t


def period_exact(p):
    return 2.0 * math.pi / p[0]


def error(p, T, T_exact):
    return abs(T - T_exact) / T_exact


LINEAR = OdeModel(
    name="layer_linear",
    description="x'' = -w^2 x from x = A at rest",
    params=(Param("w", "w", "rad/s", "angular frequency", lo=0.0, lo_open=True),
            Param("A", "A", "1", "release")),
    settings=(Setting("horizon", 100.0, "1", "horizon in units of 1 / w", 1e-3, 1e6),),
    internal=("w_scaled", "sign"),
    states=("x", "v"),
    classify=classify,
    prepare=prepare,
    rhs=rhs,
    initial=initial,
    accel=accel,
    symplectic_step=step,
    measurements=(FirstEvent("period", event, t_max=horizon, value=period_from_quarter, symbol="T", unit="s"),),
    closed_forms=(ClosedForm("period_exact", period_exact, "T_exact", "s"),
                  ClosedForm("period_error", error, "err", "1", needs=("period", "period_exact"))),
)


def raising_closed_form(p):
    if p[0] > 2.0:
        raise ValueError("w too large for this formula")
    return 1.0 / p[0]


def raising_event(t, y, p):
    if p[0] > 3.0:
        raise ValueError("w too large for this event")
    return p[4] * y[0]


RAISING = OdeModel(
    name="layer_raising",
    description="LINEAR whose closed form raises for w > 2 and whose event raises for w > 3",
    params=LINEAR.params, settings=LINEAR.settings, internal=LINEAR.internal, states=LINEAR.states,
    prepare=prepare, rhs=rhs, initial=initial,
    measurements=(FirstEvent("period", raising_event, t_max=horizon, value=period_from_quarter),),
    closed_forms=(ClosedForm("inverse", raising_closed_form),),
)
