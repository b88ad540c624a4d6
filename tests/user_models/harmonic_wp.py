"""A user model that declares its own work-precision report (tests/bench/test_workprecision_ode.py), as a
user would: x'' + w^2 x = 0 from x = A, x' = 0, its period measured by integration and its exact
value 2 pi / w given as a ClosedForm, which the report uses as its reference; the scene is named
relative to this file."""
import math

from mechsweep.model import ClosedForm, OdeModel, Param, Period, WorkPrecision


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * p[0] * y[0]


def initial(p, y0):
    y0[0] = p[1]
    y0[1] = 0.0


def period_exact(p):
    return 2.0 * math.pi / p[0]


HARMONIC = OdeModel(
    name="harmonic_wp",
    description="x'' + w^2 x = 0 released from rest at x = A",
    params=(Param("w", "w", "rad/s", "natural frequency", lo=0.0, lo_open=True),
            Param("A", "A", "m", "amplitude", lo=0.0, lo_open=True)),
    states=("x", "v"),
    rhs=rhs,
    initial=initial,
    measurements=(Period("period", "x", t_max=100.0),),
    closed_forms=(ClosedForm("period_exact", period_exact, "T_exact", "s", "period 2 pi / w"),),
    workprecision=WorkPrecision(scene="harmonic_wp.toml", output="period", reference="period_exact"),
)
