"""A user model for tests/model/test_model_layer_api.py, written as a user would (outside the package):
x'' + w^2 x = 0 from x = 1, x' = 0, so x(1) = cos(w). Its rhs raises for w > 2.5, a branch the
scene-load probe (w = 1, the default) does not reach. One cheap measurement: one small kernel."""
from mechsweep.model import OdeModel, Param, StateAt


def rhs(t, y, p, dydt):
    if p[0] > 2.5:
        raise ValueError("w too large for this model")
    dydt[0] = y[1]
    dydt[1] = -p[0] * p[0] * y[0]


def initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


OSC = OdeModel(
    name="api_oscillator", description="x'' + w^2 x = 0 from x = 1; rhs raises for w > 2.5",
    params=(Param("w", "w", "rad/s", "natural frequency", lo=0.0, lo_open=True, default=1.0),),
    states=("x", "v"), rhs=rhs, initial=initial,
    measurements=(StateAt("x_at_1", "x", t=1.0, unit="m"),))
