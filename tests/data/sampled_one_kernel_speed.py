"""Side by side in one process: the auto-balancer's simulated outputs by the model's one
sampled-trajectory kernel (every sampled measurement, the asked-for ones chosen at run time) and by
a kernel compiled for the asked-for measurements alone (``trajectory.evaluate(per_subset=True)``,
the kernel as it was before), the same points, warm caches, alternating:
``python tests/data/sampled_one_kernel_speed.py [points] [rounds] [lanes|one]`` (lanes: the
model's DOP853 lanes, as it runs; one: one trajectory at a time). Prints each round's points/s
and the median ratio one-kernel/subset-kernel (> 1: the one kernel is faster)."""
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import record_autobalancer as rec  # noqa: E402

from mechsweep.engine import sampling as trajectory  # noqa: E402
from mechsweep.models import autobalancer as ab  # noqa: E402
from mechsweep.scene import Solver  # noqa: E402

n = int(sys.argv[1]) if len(sys.argv) > 1 else 256
rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 5
lanes = (sys.argv[3] if len(sys.argv) > 3 else "lanes") == "lanes"
P = np.repeat(rec.design_points()[2][None, :], n, axis=0)
P[:, 0] = np.linspace(6.0, 60.0, n)  # Omega
WANTED = ("stable_sim", "residual_amplitude")
slv = Solver.for_model(ab.SPEC, method="dop853", rtol=1e-8, atol=1e-10, horizon_revolutions=300.0,
                       reproducibility_factor=0.0)
chosen = tuple(m for m in ab.MODEL.measurements if m.name in WANTED)


def run(per_subset):
    out = {k: np.full(n, np.nan) for k in WANTED}
    status, ns, nr = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
    t = time.perf_counter()
    trajectory.evaluate(ab.MODEL, chosen, P, WANTED, slv, out, status, ns, nr, lanes=lanes, per_subset=per_subset)
    return time.perf_counter() - t, ns.sum(), out, status


run(False)
run(True)
ratios = []
for r in range(rounds):
    ts, ss, os_, sts = run(True)
    to, so, oo, sto = run(False)
    same = all(np.array_equal(oo[k], os_[k], equal_nan=True) for k in WANTED) and np.array_equal(sto, sts)
    print(f"run {r}: subset kernel {n / ts:8.1f} points/s, one kernel {n / to:8.1f} points/s, ratio {ts / to:.3f}; "
          f"steps {ss} {so}; same values and statuses {same}", flush=True)
    ratios.append(ts / to)
print(f"median ratio one-kernel/subset-kernel {np.median(ratios):.3f} over {rounds} rounds")
