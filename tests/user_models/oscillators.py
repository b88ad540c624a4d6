"""User models for tests/model/test_model_layer.py, written as a user would (outside the package).

x'' + w^2 x = 0 from x = A, x' = 0: x = A cos(w t), period 2 pi / w, max x' = A w.
theta'' + (g / L) sin(theta) = 0 from theta = A: period 4 K(sin^2(A/2)) sqrt(L/g); its energy
omega^2 / 2 + (g / L)(1 - cos theta) is declared conserved (an Invariant: bench workprecision's drift).
"""
import dataclasses
import math

from mechsweep.model import Crossing, Extremum, Invariant, OdeModel, Param, Period, Recheck, StateAt


def linear_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * p[0] * y[0]


def linear_initial(p, y0):
    y0[0] = p[1]
    y0[1] = 0.0


LINEAR = OdeModel(
    name="linear_oscillator",
    description="x'' + w^2 x = 0 released from rest at x = A",
    params=(Param("w", "w", "rad/s", "natural frequency", lo=0.0, lo_open=True),
            Param("A", "A", "m", "amplitude", lo=0.0, lo_open=True)),
    states=("x", "v"),
    rhs=linear_rhs,
    initial=linear_initial,
    measurements=(
        Period("period", "x", t_max=100.0),
        Period("period_short", "x", t_max=1.0),
        StateAt("x_at_2", "x", t=2.0, unit="m"),
        Extremum("v_max", "v", t0=0.0, t1=10.0, kind="max", unit="m/s"),
        Extremum("x_min", "x", t0=0.3, t1=0.9, kind="min", unit="m"),
        Crossing("t_up2", "x", level=0.0, direction="up", n=2),  # 7 T / 4
        Crossing("t_half_down", "x", level=0.35, direction="down", n=1),  # x = A/2 first at w t = pi/3
    ),
)


def pendulum_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -(p[0] / p[1]) * math.sin(y[0])


def pendulum_initial(p, y0):
    y0[0] = p[2]
    y0[1] = 0.0


def pendulum_energy(y, p):
    return 0.5 * y[1] * y[1] + (p[0] / p[1]) * (1.0 - math.cos(y[0]))


def small_swing_period(p):
    return 2.0 * math.pi * math.sqrt(p[1] / p[0])


PENDULUM = OdeModel(
    name="pendulum",
    description="undamped pendulum theta'' + (g/L) sin theta = 0 released from rest at theta = A",
    params=(Param("g", "g", "m/s^2", "gravity", lo=0.0, lo_open=True),
            Param("L", "L", "m", "length", lo=0.0, lo_open=True),
            Param("A", "A", "rad", "amplitude", lo=0.0, hi=math.pi, lo_open=True, hi_open=True)),
    states=("theta", "omega"),
    rhs=pendulum_rhs,
    initial=pendulum_initial,
    measurements=(Period("period", "theta", t_max=200.0),),
    invariant=Invariant(pendulum_energy, at={"g": 9.81, "L": 0.5, "A": 1.0}, period=small_swing_period,
                        periods=(1, 10, 100), rtols=(1e-6,)),
)


# the same pendulum with the generic conditioning test: every measurement integrated again at rtol / 100
# (the same name: the re-check needs no kernel of its own, so the tests share PENDULUM's compiled one)
PENDULUM_CHECKED = dataclasses.replace(PENDULUM, recheck=Recheck(every_measurement=True))
