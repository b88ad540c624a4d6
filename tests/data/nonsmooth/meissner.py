"""Meissner equation x'' + c x' + (delta + eps sign(cos t)) x = 0 (square-wave stiffness)."""
import math
from mechsweep.model import Floquet, OdeModel, Param

def rhs(t, y, p, dydt):
    delta, eps, c = p[0], p[1], p[2]
    ct = math.cos(t)
    s = 1.0 if ct > 0.0 else (-1.0 if ct < 0.0 else 0.0)
    dydt[0] = y[1]
    dydt[1] = -c * y[1] - (delta + eps * s) * y[0]

def jac(t, y, p, J):
    delta, eps, c = p[0], p[1], p[2]
    ct = math.cos(t)
    s = 1.0 if ct > 0.0 else (-1.0 if ct < 0.0 else 0.0)
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    J[1, 0] = -(delta + eps * s)
    J[1, 1] = -c

def initial(p, y0):
    y0[0] = 0.0
    y0[1] = 0.0

def forcing_period(p):
    return 2.0 * math.pi

_PARAMS = (
    Param("delta", "δ", "1", "mean stiffness (per unit mass, in units of the forcing frequency squared)", lo=-10.0, hi=10.0),
    Param("eps", "ε", "1", "square-wave stiffness modulation amplitude", lo=0.0, hi=5.0),
    Param("c", "c", "1", "viscous damping (per unit mass)", lo=0.0, required=False, default=0.0),
)

MEISSNER = OdeModel(
    name="meissner", description="Meissner equation: square-wave parametric excitation",
    params=_PARAMS, states=("x", "v"), rhs=rhs, initial=initial, forcing_period=forcing_period,
    measurements=(Floquet("mu"),),
)

MEISSNER_JAC = OdeModel(
    name="meissner_jac", description="Meissner equation with analytic jac",
    params=_PARAMS, states=("x", "v"), rhs=rhs, jac=jac, initial=initial, forcing_period=forcing_period,
    measurements=(Floquet("mu"),),
)

# The same equation with its switch times declared (sign(cos t) jumps at pi/2 and 3 pi/2): every step
# ends on them (model/switches.py), the located boundaries reach about rtol (docs/your-own-model.md).
MEISSNER_SW = OdeModel(
    name="meissner_sw", description="Meissner equation, switch times declared",
    params=_PARAMS, states=("x", "v"), rhs=rhs, initial=initial, forcing_period=forcing_period,
    switch_times=(0.5 * math.pi, 1.5 * math.pi), measurements=(Floquet("mu"),),
)

MEISSNER_JAC_SW = OdeModel(
    name="meissner_jac_sw", description="Meissner equation with analytic jac, switch times declared",
    params=_PARAMS, states=("x", "v"), rhs=rhs, jac=jac, initial=initial, forcing_period=forcing_period,
    switch_times=(0.5 * math.pi, 1.5 * math.pi), measurements=(Floquet("mu"),),
)
