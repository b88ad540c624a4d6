"""Side by side in one process: the auto-balancer's simulated outputs (stable_sim,
residual_amplitude) by the hand-written kernels (tests/reference/autobalancer_kernels.py, the reference
kept for this: DOP853 lanes) and by the model, the layer declaration (models/autobalancer.py: the
layer's sampled trajectory in DOP853 lanes, with its status rules), the same points, warm caches,
alternating: ``python tests/data/autobalancer_layer_speed.py [points] [sim|both] [rounds] [cpu]``
(sim: stable_sim alone; floquet: floquet_max on the points of ``python benchmarks/autobalancer.py``'s
chart, at the solver's default tolerances, as that bench times it; rounds: alternating pairs, default 3; cpu: points per CPU second of the
process instead of wall-clock; the median ratio is printed)."""
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parents[1])]  # record_autobalancer beside it; the repository root
import record_autobalancer as rec  # noqa: E402

from mechsweep.models import MODELS  # noqa: E402
from mechsweep.scene import Solver  # noqa: E402
from tests.reference import autobalancer_kernels as K  # noqa: E402

old = K.SPEC
new = MODELS["autobalancer"]
rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 3
CPU = "cpu" in sys.argv[4:]  # points per CPU second of the process (less disturbed by other jobs)
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


OLD = ("stable_sim",) if sys.argv[2:3] == ["sim"] else ("stable_sim", "residual_amplitude")
if sys.argv[2:3] == ["floquet"]:
    from benchmarks.autobalancer import chart_parameters
    side = max(2, int(round(n ** 0.5)))
    P = chart_parameters(side, side)
    n = P.shape[0]
    kw = {}
    OLD = ("floquet_max",)
NEW = OLD
run(old, OLD)
run(new, NEW)
ratios = []
for r in range(rounds):
    to, so, oo = run(old, OLD)
    tn, sn, on = run(new, NEW)
    print(f"run {r}: old {n / to:8.1f} points/s, layer {n / tn:8.1f} points/s, ratio {to / tn:.3f}; steps {so} {sn}; "
          f"same values {np.array_equal(oo[OLD[0]], on[NEW[0]], equal_nan=True)}")
    ratios.append(to / tn)
print(f"median ratio layer/old {np.median(ratios):.3f} over {rounds} rounds")
