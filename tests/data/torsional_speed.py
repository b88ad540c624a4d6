"""Points per CPU second of the torsional circuit's integrated outputs: ``NUMBA_NUM_THREADS=1
python tests/data/torsional_speed.py LABEL`` (11,520 points across both springs, the hump at
phi = 0 and the top, rtol 1e-10, best of 6 runs: the first compiles). Run alternately on two checkouts
(PYTHONPATH) to compare them side by side (docs/model-layer.md)."""
import itertools
import sys
import time

import numpy as np

from mechsweep.models import MODELS
from mechsweep.scene import Solver

spec = MODELS["torsional_circuit"]
rows = [(sp, l1, l2, s, 1.0, 1.0, 1.0, A) for sp, l1, l2, s, A in itertools.product(
    (0.0, 1.0), np.linspace(0.3, 2.0, 6), (0.0, 0.5), np.linspace(-0.5, 0.8, 8), np.linspace(0.05, 3.0, 60))]
P = np.array(rows)
n = len(P)
for wanted in (("period_exact_moment",), ("period", "period_exact_moment", "truncation_error", "period_exact")):
    best = 1e9
    for r in range(6):
        out = {k: np.full(n, np.nan) for k in wanted}
        status, ns, nr = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
        t = time.process_time()
        with np.errstate(all="ignore"):
            spec.evaluate(P, wanted, Solver.for_model(spec, rtol=1e-10, atol=1e-12), out, status, ns, nr)
        best = min(best, time.process_time() - t)
    print(sys.argv[1], len(wanted), n, f"{n / best / 1e3:.1f}k points/CPU-s")
