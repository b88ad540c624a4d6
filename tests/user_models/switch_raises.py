"""A user model for tests/engine/test_switch_times.py whose own code raises only on the switch-times route,
at points the load-time probe (k = 0, the default) does not reach: x'' + (1 + 0.5 sign(cos t)) x = 0
from x = 1, v = 0, switches at pi/2 and 3 pi/2. k = 1: the rhs raises past the switch at pi/2 (in
the piece where cos t < 0) and nowhere at t = 0; k = 2: switch_times raises. x_end on the one-point
kernel (engine/point.py), x_hist on the sampled trajectory (engine/trajectory.py)."""
import math

from mechsweep.model import History, OdeModel, Param, StateAt


def rhs(t, y, p, dydt):
    ct = math.cos(t)
    if ct < 0.0 and p[0] == 1.0:
        raise ValueError("no stiffness table for the negative piece")
    dydt[0] = y[1]
    dydt[1] = -(1.0 + (0.5 if ct > 0.0 else -0.5)) * y[0]


def initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


def forcing_period(p):
    return 2.0 * math.pi


def switch_times(p):
    if p[0] == 2.0:
        raise ValueError("switch times undefined for k = 2")
    return (0.5 * math.pi, 1.5 * math.pi)


RAISES = OdeModel(
    name="switch_raises", description="square-wave stiffness; rhs raises past a switch (k = 1), switch_times (k = 2)",
    params=(Param("k", "k", "1", "which part raises (0: none)", lo=0.0, hi=2.0, default=0.0),),
    states=("x", "v"), rhs=rhs, initial=initial, forcing_period=forcing_period, switch_times=switch_times,
    measurements=(StateAt("x_end", "x", t=4.0), History("x_hist", of="x", horizon=1.0, samples=3)))
