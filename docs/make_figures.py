"""Regenerate every committed figure: run each shipped scene, then draw its figures; then the
work-precision reports of the integrated models (tolerance ladder) and of the linkage models
(crank-position ladder).

    python docs/make_figures.py               # all scenes in sweeps/ and every work-precision report
    python docs/make_figures.py quickstart    # only scenes whose file name contains 'quickstart'
    python docs/make_figures.py workprecision # only the work-precision reports
    python docs/make_figures.py workprecision_fourbar_balancing  # only that model's report

A scene with a [boundaries] section also gets its located boundaries (`mechsweep boundaries`,
DATA.boundaries.h5 beside the dataset), drawn over the charts that show them.

Datasets go to data/runs/ and data/bench/ (git-ignored), figures to docs/figures/ (committed).
"""
from __future__ import annotations

import sys
from pathlib import Path

import mechsweep
from mechsweep import figures

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "figures"


def main(filters: list[str]) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for path in sorted((ROOT / "sweeps").glob("*.toml")):
        if filters and not any(f in path.stem for f in filters):
            continue
        scene = mechsweep.load_scene(path)
        ds = mechsweep.run(scene, output=ROOT / scene.storage.path, restart=True, progress=False)
        bds = None
        if scene.boundaries is not None:
            from mechsweep.boundaries import run_boundaries

            where, bds = run_boundaries(scene, data=ROOT / scene.storage.path)
            print(f"{path.name} -> {where.relative_to(ROOT)}: {bds.attrs['located']} boundaries located")
        for written in figures.save(ds, OUT / f"{path.stem}.png", boundaries=bds):
            print(f"{path.name} -> {written.relative_to(ROOT)}")
    from mechsweep.bench import workprecision

    for model in workprecision.all_cases():
        if filters and "workprecision" not in filters and f"workprecision_{model}" not in filters:
            continue
        ds = workprecision.main(model, out_dir=ROOT / "data" / "bench")
        for written in figures.save(ds, OUT / f"workprecision_{model}.png"):
            print(f"workprecision {model} -> {written.relative_to(ROOT)}")


if __name__ == "__main__":
    main(sys.argv[1:])
