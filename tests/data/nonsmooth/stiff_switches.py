"""With `auto`, Hairer's stiffness count restarts at each declared switch (model/switches.py: every
segment is a new call of the solver). Does a stiff model with many switches then stay on dop853 where
radau would be cheaper? A first-order lag driven by a square wave, y' = -lam (y - sign(sin 2 pi N t)),
z' = y, N = 20 (40 switches per period 1, segments of 0.025), with its exact Jacobian, History of z
over 3 periods, rtol 1e-6: accepted steps and rhs calls per point by dop853, radau and auto, with and
without the switch times declared. Where a segment holds fewer than the 15 stability-limited steps
the test needs, dop853 takes fewer than 15 steps per segment and radau, restarted at each switch as
well, is not cheaper; where it holds more, auto switches within the first segments. The sentence on
it in docs/your-own-model.md ("Switch times", cost) comes from this script.

    python tests/data/nonsmooth/stiff_switches.py
"""
import math
import sys
from pathlib import Path

import numpy as np

from mechsweep.model import History, OdeModel, Param

HERE = Path(__file__).resolve().parent
N = 20


def rhs(t, y, p, dydt):
    s = 1.0 if math.sin(2.0 * math.pi * N * t) >= 0.0 else -1.0
    dydt[0] = -p[0] * (y[0] - s)
    dydt[1] = y[0]


def jac(t, y, p, J):
    J[0, 0] = -p[0]
    J[0, 1] = 0.0
    J[1, 0] = 1.0
    J[1, 1] = 0.0


def initial(p, y0):
    y0[0] = 0.0
    y0[1] = 0.0


def forcing_period(p):
    return 1.0


COMMON = dict(params=(Param("lam", "λ", "1", "rate of the lag", lo=0.0, lo_open=True),), states=("y", "z"),
              rhs=rhs, jac=jac, initial=initial, forcing_period=forcing_period,
              measurements=(History("z_hist", of="z", horizon=3.0, samples=4),))
LAG_SW = OdeModel(name="lag_sw", description="square-wave lag, switch times declared",
                  switch_times=tuple(k / (2.0 * N) for k in range(2 * N)), **COMMON)
LAG = OdeModel(name="lag", description="square-wave lag, switch times not declared", **COMMON)


def main():
    sys.path.insert(0, str(HERE.parent))
    sys.path.insert(0, str(HERE))
    import stiff_switches as me  # the models from their module (a kernel imports them by module path)
    from points import evaluate

    lams = [1e2, 1e3, 3e3, 1e4, 1e5]
    P = np.array([[x] for x in lams])
    print("lam * segment length:", [x / (2 * N) for x in lams])
    for model, attr in ((me.LAG_SW, "LAG_SW"), (me.LAG, "LAG")):
        spec = model.spec(origin=str(Path(__file__).resolve()), module="stiff_switches", attr=attr)
        for method in ("dop853", "radau", "auto"):
            out, status, ns, nr = evaluate(spec, P, ["z_hist"], rtol=1e-6, atol=1e-9, method=method, max_steps=10**7)
            print(f"{attr:7s} {method:6s} statuses {sorted(set(status.tolist()))} steps {ns.tolist()} "
                  f"rhs calls {nr.tolist()}", flush=True)


if __name__ == "__main__":
    main()
