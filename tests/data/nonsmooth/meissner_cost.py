"""Meissner's largest Floquet multiplier with and without declared switch times: error against the
exact monodromy (meissner_ref.py) in units of rtol, accepted steps and rhs calls per point (n_rhs
counts the engine's finite-difference Jacobian too), for each method. The cost figures quoted in
docs/your-own-model.md ("A right-hand side that is not smooth") come from this script.

    python tests/data/nonsmooth/meissner_cost.py [--methods dop853 radau auto] [--rtols 1e-8 1e-10 1e-12]
"""
import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))
from meissner import MEISSNER, MEISSNER_SW  # noqa: E402
from meissner_ref import mu  # noqa: E402
from points import evaluate  # noqa: E402

POINTS = [(0.3, 0.2), (1.1, 0.3), (2.5, 0.6), (0.05, 0.6)]  # (delta, eps), undamped


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--methods", nargs="*", default=["dop853", "radau", "auto"])
    ap.add_argument("--rtols", nargs="*", type=float, default=[1e-8, 1e-10, 1e-12])
    a = ap.parse_args()
    P = np.array([(d, e, 0.0) for d, e in POINTS])
    ref = np.array([mu(d, e) for d, e in POINTS])
    for method in a.methods:
        for rtol in a.rtols:
            for model, attr in ((MEISSNER, "MEISSNER"), (MEISSNER_SW, "MEISSNER_SW")):
                spec = model.spec(origin=str(HERE / "meissner.py"), module="meissner", attr=attr)
                out, status, ns, nr = evaluate(spec, P, ["mu"], rtol=rtol, atol=rtol * 1e-2, method=method)
                err = np.abs(out["mu"] - ref) / ref / rtol
                print(f"{method:6s} rtol {rtol:g} {attr:12s} worst error {err.max():6.2f} rtol; steps "
                      f"{ns.min()}-{ns.max()}, rhs calls {nr.min()}-{nr.max()} per point; statuses {sorted(set(status))}",
                      flush=True)


if __name__ == "__main__":
    main()
