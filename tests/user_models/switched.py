"""A square-wave stiffness oscillator x'' + (delta + eps sign(cos t)) x = 0 from x = 1, v = 0: the
rhs jumps at t = pi/2 and 3 pi/2 of each period 2 pi. SWITCHED declares those switch times
(OdeModel(switch_times=...), model/switches.py), UNDECLARED is the same equation without them;
SWITCHED_JAC and UNDECLARED_JAC the same two with the exact Jacobian.
Its exact solution is a product of 2 x 2 closed-form matrices (tests/engine/test_switch_times.py)."""
import math

from mechsweep.model import Extremum, FirstEvent, Floquet, History, OdeModel, Param, StateAt


def rhs(t, y, p, dydt):
    ct = math.cos(t)
    s = 1.0 if ct > 0.0 else (-1.0 if ct < 0.0 else 0.0)
    dydt[0] = y[1]
    dydt[1] = -(p[0] + p[1] * s) * y[0]


def jac(t, y, p, J):  # exact (the Floquet references of tests/bench/test_workprecision_ode.py: no difference quotients)
    ct = math.cos(t)
    s = 1.0 if ct > 0.0 else (-1.0 if ct < 0.0 else 0.0)
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    J[1, 0] = -(p[0] + p[1] * s)
    J[1, 1] = 0.0


def initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


def forcing_period(p):
    return 2.0 * math.pi


def x_down(t, y, p):
    return y[0]


def switch_times(p):  # the same times as a function of p, moved by the parameter shift (0: the rhs's own)
    T = 2.0 * math.pi
    return (0.25 * T + p[2], 0.75 * T + p[2])


PARAMS = (Param("delta", "δ", "1", "mean stiffness", lo=0.0, hi=10.0),
          Param("eps", "ε", "1", "square-wave stiffness amplitude", lo=0.0, hi=5.0),
          Param("shift", "s", "1", "shift of SWITCHED_FN's declared switch times (0: where the rhs switches)",
                required=False, default=0.0))
MEASUREMENTS = (
    FirstEvent("t_zero", event=x_down, t_max=100.0),
    StateAt("x_end", "x", t=10.0),
    Extremum("x_max", "x", t0=5.0, t1=10.0, kind="max"),
    History("x_hist", of="x", horizon=2.0, samples=5),
    Floquet("mu"),
)
COMMON = dict(params=PARAMS, states=("x", "v"), rhs=rhs, initial=initial, forcing_period=forcing_period,
              measurements=MEASUREMENTS)

SWITCHED = OdeModel(name="switched", description="square-wave stiffness, switch times declared",
                    switch_times=(0.5 * math.pi, 1.5 * math.pi), **COMMON)
SWITCHED_FN = OdeModel(name="switched_fn", description="square-wave stiffness, switch times as a function",
                       switch_times=switch_times, **COMMON)
UNDECLARED = OdeModel(name="undeclared", description="square-wave stiffness, switch times not declared", **COMMON)
SWITCHED_JAC = OdeModel(name="switched_jac", description="SWITCHED with its Jacobian",
                        switch_times=(0.5 * math.pi, 1.5 * math.pi), jac=jac, **COMMON)
UNDECLARED_JAC = OdeModel(name="undeclared_jac", description="UNDECLARED with its Jacobian", jac=jac, **COMMON)
