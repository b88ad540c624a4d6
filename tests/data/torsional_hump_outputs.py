"""The torsional circuit across the hump of the spring's potential at phi = 0 (s0_over_r < 0,
96 points, where the exact-moment period's refine may run a second pass), by the methods given,
three cases (tight, loose, a step budget): ``python tests/data/torsional_hump_outputs.py record
FILE.npz METHOD...`` writes outputs, status, n_steps, n_rhs; ``... compare FILE.npz METHOD...``
reports whether the current code gives them bit for bit (docs/model-layer.md)."""
import itertools
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import record_reference as rr  # noqa: E402


def compute(methods) -> dict:
    from mechsweep.models import MODELS

    rows = [(sp, l1, 0.3, s, 1.0, 1.0, 1.0, A) for sp, l1, s, A in itertools.product(
        (0.0, 1.0), (0.5, 1.5), (-0.3, -0.05, -0.01), np.linspace(0.05, 3.1, 24))]
    P = np.array(rows)
    arrays = {}
    for method in methods:
        for tag, kw in (("t", dict(rtol=1e-10, atol=1e-12)), ("l", dict(rtol=1e-6, atol=1e-9)),
                        ("m", dict(rtol=1e-10, atol=1e-12, max_steps=400))):
            out, status, ns, nr = rr.evaluate_case(MODELS["torsional_circuit"], P,
                                                   ("period", "period_exact_moment"), dict(method=method, **kw))
            for k, v in {**out, "status": status, "n_steps": ns, "n_rhs": nr}.items():
                arrays[f"{method}{tag}/{k}"] = v
    return arrays


if __name__ == "__main__":
    mode, path, methods = sys.argv[1], sys.argv[2], sys.argv[3:]
    arrays = compute(methods)
    if mode == "record":
        np.savez(path, **arrays)
        print("recorded", len(arrays), "arrays")
    else:
        ref = np.load(path)
        bad = [k for k in arrays
               if not (ref[k].dtype == arrays[k].dtype and np.array_equal(ref[k], arrays[k], equal_nan=True))]
        print("compared", len(arrays), "arrays; different:", bad)
        sys.exit(1 if bad else 0)
