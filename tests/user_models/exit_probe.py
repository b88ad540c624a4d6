"""A model whose classify calls sys.exit when it is run in plain Python at the probe point (the
engine runs it once when the model is loaded; tests/model/test_model_exits.py)."""
import sys

from mechsweep.model import OdeModel, Param, StateAt


def rhs(t, y, p, dydt):
    dydt[0] = -p[0] * y[0]


def initial(p, y0):
    y0[0] = 1.0


def classify(p):
    if p[0] > 0.5:
        sys.exit(0)
    return 0


M = OdeModel(name="decay_exit_probe", description="y' = -k y", states=("y",), rhs=rhs, initial=initial,
             params=(Param("k", "k", "s-1", "rate", lo=0.0, required=False, default=1.0),),
             classify=classify, measurements=(StateAt("y1", "y", t=1.0),))
