"""Side by side in one process: the auto-balancer's simulated outputs (stable_sim,
residual_amplitude) by the hand-written kernels (DOP853 lanes) and by the layer's sampled
trajectory (tests/data/autobalancer_on_layer.py: one trajectory at a time), the same points, warm
caches, alternating: ``python tests/data/autobalancer_layer_speed.py [points] [sim|both] [on_layer|declaration]
[rounds] [cpu]`` (sim: stable_sim alone; declaration: tests/data/autobalancer_declaration.py, the whole
model with its status rules; rounds: alternating pairs, default 3; cpu: points per CPU second of the process instead of wall-clock; the median ratio is printed)."""
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import record_autobalancer as rec  # noqa: E402

from mechsweep.model import load  # noqa: E402
from mechsweep.models import MODELS  # noqa: E402
from mechsweep.scene import Solver  # noqa: E402

old = MODELS["autobalancer"]
which = sys.argv[3] if len(sys.argv) > 3 else "on_layer"
new = load.resolve(f"{HERE / f'autobalancer_{which}.py'}:MODEL")
rounds = int(sys.argv[4]) if len(sys.argv) > 4 else 3
CPU = "cpu" in sys.argv[5:]  # points per CPU second of the process (less disturbed by other jobs)
n = int(sys.argv[1]) if len(sys.argv) > 1 else 256
P = np.repeat(rec.design_points()[2][None, :], n, axis=0)
P[:, 0] = np.linspace(6.0, 60.0, n)  # Omega
kw = dict(method="dop853", rtol=1e-8, atol=1e-10, horizon_revolutions=300.0, reproducibility_factor=0.0)


def run(spec, wanted):
    slv = Solver.for_model(spec, **kw)
    out = {k: np.full(n, np.nan) for k in wanted}
    status, ns, nr = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
    t = time.process_time() if CPU else time.perf_counter()
    spec.evaluate(P, wanted, slv, out, status, ns, nr)
    return (time.process_time() if CPU else time.perf_counter()) - t, ns.sum(), out


OLD, NEW = (("stable_sim",), ("sim",)) if sys.argv[2:3] == ["sim"] else (("stable_sim", "residual_amplitude"),
                                                                         ("sim", "residual"))
if which == "declaration":  # the declaration keeps the old output names
    NEW = OLD
run(old, OLD)
run(new, NEW)
ratios = []
for r in range(rounds):
    to, so, oo = run(old, OLD)
    tn, sn, on = run(new, NEW)
    print(f"run {r}: old {n / to:8.1f} points/s, layer {n / tn:8.1f} points/s, ratio {to / tn:.3f}; steps {so} {sn}; "
          f"same values {np.array_equal(oo['stable_sim'], on[NEW[0]], equal_nan=True)}")
    ratios.append(to / tn)
print(f"median ratio layer/old {np.median(ratios):.3f} over {rounds} rounds")
