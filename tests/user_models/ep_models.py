"""The model tests/model/test_model_layer_api.py registers as an entry point (a module of its own:
the file-path door uses api_models.py). x'' + w^2 x = 0 from x = 1: x(1) = cos(w)."""
from mechsweep.model import OdeModel, Param, StateAt


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * p[0] * y[0]


def initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


OSC = OdeModel(
    name="ep_oscillator", description="x'' + w^2 x = 0 from x = 1",
    params=(Param("w", "w", "rad/s", "natural frequency", lo=0.0, lo_open=True, default=1.0),),
    states=("x", "v"), rhs=rhs, initial=initial,
    measurements=(StateAt("x_at_1", "x", t=1.0, unit="m"),))
