"""The example image of docs/your-own-model.md, "Figures": the generic heatmap and nomogram drawn by
hand (``ax=``) from the worked example's dataset.

    python docs/generic_figures_example.py   # runs sweeps/vibrating_pendulum_stability.toml if needed

Writes docs/figures/generic_figures_example.png. The dataset goes to data/runs/ (git-ignored).
"""
from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure

import mechsweep
from mechsweep.figures import generic

ROOT = Path(__file__).resolve().parents[1]


def main() -> Path:
    scene = mechsweep.load_scene(ROOT / "sweeps" / "vibrating_pendulum_stability.toml")
    ds = mechsweep.run(scene, output=ROOT / scene.storage.path, progress=False)  # resumes / reuses a finished run
    fig = Figure(figsize=(13.0, 4.8), layout="constrained")
    left, right = fig.subplots(1, 2)
    # the largest |Floquet multiplier| of the inverted pendulum over w (log-spaced axis) and a
    generic.heatmap(ds, "max_multiplier", x="w", y="a", at={"position": "inverted"}, ax=left)
    left.set_title('generic.heatmap(ds, "max_multiplier", x="w", y="a",\nat={"position": "inverted"}, ax=left)',
                   fontsize=9, family="monospace")
    # the same output against w, one curve per fifth value of a (five curves: a legend)
    generic.nomogram(ds.isel(a=slice(0, None, 5)), "max_multiplier", x="w", family="a",
                     at={"position": "inverted"}, ax=right)
    right.set_title('generic.nomogram(ds.isel(a=slice(0, None, 5)), "max_multiplier",\nx="w", family="a", '
                    'at={"position": "inverted"}, ax=right)', fontsize=9, family="monospace")
    out = ROOT / "docs" / "figures" / "generic_figures_example.png"
    fig.savefig(out, dpi=110)
    return out


if __name__ == "__main__":
    print(main().relative_to(ROOT))
