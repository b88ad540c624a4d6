"""User models for tests/test_model_lanes.py: right-hand sides the lane rewrite (engine/lane_rhs.py)
covers (math calls, `from math import`, module constants, a negative constant under a power, the
time t, a branch, a loop over range, helper functions called as statements) and ones it must leave
to the one-point route (a call to a helper function inside an expression, a helper with a while
loop, an early return)."""
import math
from math import cos

import numba

from mechsweep.model import Crossing, FirstEvent, OdeModel, Param

K = 2  # slot of the damping, a module constant the rewrite writes in as its value
NEG = -1.0  # (NEG) ** 2 must stay +1 after the rewrite


def initial(p, y0):
    y0[0] = p[1]
    y0[1] = 0.0


def forced_rhs(t, y, p, dydt):
    """A damped, forced pendulum: theta'' = -sin theta - c theta' + f cos(t) (+ a branch and a loop)."""
    dydt[0] = y[1]
    acc = -math.sin(y[0]) - p[K] * y[1] + p[3] * cos(t) * NEG ** 2
    if y[0] > 3.0:
        acc = acc - 0.0 * y[0]
    for j in range(1):
        acc += 0.0 * j
    dydt[1] = acc


def down(t, y, p):
    return y[0]


@numba.njit
def helper(x):
    return -math.sin(x)


def helper_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = helper(y[0]) - p[K] * y[1] + p[3] * cos(t)


PARAMS = (Param("w", "w", "1", "unused frequency", lo=0.0, lo_open=True),
          Param("A", "A", "rad", "release angle"),
          Param("c", "c", "1", "damping", lo=0.0),
          Param("f", "f", "1", "forcing amplitude"))

FORCED = OdeModel(name="lanes_forced", description="damped forced pendulum", params=PARAMS, states=("theta", "omega"),
                  rhs=forced_rhs, initial=initial,
                  measurements=(FirstEvent("t_down", down, t_max=30.0),
                                Crossing("t_cross", "theta", level=0.25, direction="down", n=1, t_max=30.0)))
HELPER = OdeModel(name="lanes_helper", description="FORCED with a helper call in its rhs", params=PARAMS,
                  states=("theta", "omega"), rhs=helper_rhs, initial=initial,
                  measurements=(FirstEvent("t_down", down, t_max=30.0),))


# An rhs that calls a plain module-level function on a slice of p, which calls another returning a
# tuple: the rewrite inlines both (their arguments bound in order, the slice offset added to the
# indices), as the auto-balancer's rhs -> scaled_rhs -> accelerations.
OFF = 1


def inline_rhs(t, y, p, dydt):
    scaled(t, y, p[OFF:OFF + 3], dydt)


@numba.njit
def scaled(t, z, q, dz):  # q = (A, c, f)
    """z'' = -sin z - c z' + f cos t"""
    dz[0] = z[1]
    acc, s = accel(t, z[0], z[1], q)
    dz[1] = acc + 0.0 * s


@numba.njit
def accel(t, x, v, q):
    s = math.sin(x)
    return -s - q[1] * v + q[2] * cos(t), s


def looping(x):
    while x > 1.0:
        x -= 1.0
    return x


def uncovered_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    a = looping(y[0])
    dydt[1] = -a


def recursive(x, k):
    y = x
    if k > 0:
        y = recursive(x, k - 1)
    return y


def recursive_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    a = recursive(y[0], 2)
    dydt[1] = -a


def tail(x, k):
    return tail(x, k - 1)


def tail_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    a = tail(y[0], 2)
    dydt[1] = -a
