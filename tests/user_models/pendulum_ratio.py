"""The pendulum of oscillators.py with a closed form of its integrated period: T / T0, the period
over the small-swing period 2 pi sqrt(L / g) (tests/boundaries/test_boundaries.py locates where it crosses a
level: a criterion only as accurate as the integration)."""
import math

from mechsweep.model import ClosedForm, OdeModel, Param, Period


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -(p[0] / p[1]) * math.sin(y[0])


def initial(p, y0):
    y0[0] = p[2]
    y0[1] = 0.0


def ratio(p, T):
    return T / (2.0 * math.pi * math.sqrt(p[1] / p[0]))


PENDULUM_RATIO = OdeModel(
    name="pendulum_ratio",
    description="undamped pendulum released from rest at theta = A, its period over the small-swing period",
    params=(Param("g", "g", "m/s^2", "gravity", lo=0.0, lo_open=True),
            Param("L", "L", "m", "length", lo=0.0, lo_open=True),
            Param("A", "A", "rad", "amplitude", lo=0.0, hi=math.pi, lo_open=True, hi_open=True)),
    states=("theta", "omega"), rhs=rhs, initial=initial,
    measurements=(Period("period", "theta", t_max=200.0),),
    closed_forms=(ClosedForm("ratio", ratio, "T/T_0", "1", "period over the small-swing period", needs=("period",)),),
)
