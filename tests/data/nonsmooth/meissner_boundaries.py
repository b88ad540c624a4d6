"""The Meissner equation x'' + (delta + eps sign(cos t)) x = 0 (meissner.py, a user model with a
non-smooth rhs): its Floquet boundaries located by `mechsweep boundaries` against the exact ones
(meissner_ref.py: the monodromy as a product of three 2x2 closed-form matrices, |trace| = 2 by
brentq). The numbers quoted in docs/your-own-model.md ("A right-hand side that is not smooth") and
docs/boundaries.md come from this script (first measured by a docs-only trial, 2026-11-24).

    python tests/data/nonsmooth/meissner_boundaries.py [RTOL ...] [--accuracy A] [--model MEISSNER_JAC]
                                                       [--switch-times]

For each solver rtol (default 1e-8 1e-10 1e-12): eps in (0.1, 0.3, 0.6) x 141 delta in [-0.5, 3],
boundaries along delta at the same rtol; prints the worst relative error of the located boundaries and
how many exact ones were not found. ``--switch-times``: the same model with its switch times
declared (meissner.py's MEISSNER_SW / MEISSNER_JAC_SW: OdeModel(switch_times=(pi/2, 3 pi/2))).
"""
import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from meissner_ref import boundaries  # noqa: E402

SCENE = """[scene]
name = "meissner"
model = "{model_file}:{model}"
outputs = ["mu"]

[axes]
eps = [0.1, 0.3, 0.6]
delta = {{ start = -0.5, stop = 3.0, num = 141 }}

[fixed]
c = 0.0

[solver]
rtol = {rtol}
atol = {atol}

[storage]
path = "{data}"

[boundaries]
along = "delta"
criterion = "mu"
level = 1.0
rtol = {rtol}
{accuracy}"""


def compare(path):
    b = xr.open_dataset(path, engine="h5netcdf")
    worst, missing = 0.0, 0
    for e in b.eps.values:
        ref = boundaries(float(e), -0.5, 3.0)
        got = b.boundary.sel(eps=e).values
        found = set()
        for g, bound in zip(got, b.boundary_bound.sel(eps=e).values):
            if bound < 0 or not np.isfinite(g):
                continue
            r = min(ref, key=lambda x: abs(x - g))
            found.add(r)
            worst = max(worst, abs(g - r) / max(abs(r), 1e-300))
        missing += len(set(ref) - found)
    return worst, missing


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("rtols", nargs="*", type=float, default=[1e-8, 1e-10, 1e-12])
    ap.add_argument("--accuracy", type=float, default=None, help="[boundaries] criterion_accuracy (default: none)")
    ap.add_argument("--model", default="MEISSNER")
    ap.add_argument("--switch-times", action="store_true", help="the model with its switch times declared (MODEL_SW)")
    a = ap.parse_args()
    if a.switch_times:
        a.model += "_SW"
    with tempfile.TemporaryDirectory() as tmp:
        for rtol in a.rtols:
            scene = Path(tmp) / f"m_{rtol:g}.toml"
            data = Path(tmp) / f"m_{rtol:g}.h5"
            scene.write_text(SCENE.format(model_file=HERE / "meissner.py", model=a.model, rtol=rtol, atol=rtol * 1e-2,
                                          data=data, accuracy=f"criterion_accuracy = {a.accuracy}" if a.accuracy else ""))
            subprocess.run([sys.executable, "-m", "mechsweep", "boundaries", str(scene), "--no-progress",
                            "--threads", "1"], check=True, capture_output=True)
            worst, missing = compare(data.with_name(data.stem + ".boundaries.h5"))
            print(f"{a.model} rtol {rtol:g}, criterion_accuracy {a.accuracy or 'default'}: worst relative error "
                  f"{worst:.1e}; exact boundaries not found: {missing}", flush=True)


if __name__ == "__main__":
    main()
