"""A user model with RMS measurements (tests/test_model_layer_rms.py), written as a user would.

x'' + 2 zeta w x' + w^2 x = F cos(W t) from rest; the steady motion is x = A cos(W t - phi),
A = F / sqrt((w^2 - W^2)^2 + (2 zeta w W)^2): its RMS is A / sqrt(2), the velocity's A W / sqrt(2).
"""
import math

from mechsweep import status as st
from mechsweep.model import RMS, OdeModel, Param, Setting


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = p[2] * math.cos(p[3] * t) - 2.0 * p[1] * p[0] * y[1] - p[0] * p[0] * y[0]


def initial(p, y0):
    y0[0] = 0.0
    y0[1] = 0.0


def period(p):
    return 2.0 * math.pi / p[3]


def speed(t, y, p):
    return y[1]


def per_force(p, x):  # the RMS relative to the forcing amplitude
    return x / p[2]


def damped(p):  # where the steady motion is reached within the horizon
    return st.OK if p[1] > 0.0 else st.INFEASIBLE


FORCED_RMS = OdeModel(
    name="forced_rms",
    description="x'' + 2 zeta w x' + w^2 x = F cos(W t) from rest: RMS of the steady motion",
    params=(Param("w", "w", "rad/s", "natural frequency", lo=0.0, lo_open=True),
            Param("zeta", "zeta", "1", "damping ratio", lo=0.0),
            Param("F", "F", "m/s^2", "forcing amplitude"),
            Param("W", "W", "rad/s", "forcing frequency", lo=0.0, lo_open=True)),
    states=("x", "v"),
    rhs=rhs,
    initial=initial,
    forcing_period=period,
    settings=(Setting("horizon_periods", 200.0, "1", "simulated forcing periods", 1.0, 1e5),),
    measurements=(
        RMS("x_rms", "x", horizon="horizon_periods", window=0.1, unit="m"),
        RMS("v_rms", speed, horizon="horizon_periods", window=0.1, samples_per_period=32, unit="m/s"),
        RMS("x_rel", "x", horizon="horizon_periods", window=0.05, value=per_force, unit="s^2", classify=damped),
    ),
)
