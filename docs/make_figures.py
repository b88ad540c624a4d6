"""Regenerate every committed figure: run each shipped scene, then draw its figures; then the
work-precision reports of the integrated models (tolerance ladder) and of the linkage models
(crank-position ladder); then the generic-figures example of docs/your-own-model.md and the
picture of docs/architecture.md.

    python docs/make_figures.py               # all scenes in sweeps/ and every work-precision report
    python docs/make_figures.py quickstart    # only scenes whose file name contains 'quickstart'
    python docs/make_figures.py workprecision # only the work-precision reports
    python docs/make_figures.py workprecision_fourbar_balancing  # only that model's report
    python docs/make_figures.py architecture  # only the picture of docs/architecture.md (no scene run)
    python docs/make_figures.py --reuse       # redraw from the datasets already in data/ (a run that
                                              # finished is reused, the boundaries and reports are read back)

A scene with a [boundaries] section also gets its located boundaries (`mechsweep boundaries`,
DATA.boundaries.h5 beside the dataset), drawn over the charts that show them.

Datasets go to data/runs/ and data/bench/ (git-ignored), figures to docs/figures/ (committed).

Every figure written is recorded in docs/figures/MANIFEST.json with a hash of the code that draws
it (the figure modules, see ``mechsweep.figures.source_files``), of the file declaring the scene's
model (units and names label the figure) and of its scene file, and the hash of the PNG itself:
tests/figures/test_figure_data.py fails when a committed figure is older than the
code or scene it comes from, or was written without its manifest entry.
"""
from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import mechsweep
from mechsweep import figures

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "figures"
MANIFEST = OUT / "MANIFEST.json"


def code_hash(files) -> str:
    """sha256 over each file's path (relative to the repository) and bytes, in the given order."""
    h = hashlib.sha256()
    for rel in files:
        h.update(rel.encode() + b"\0" + (ROOT / rel).read_bytes() + b"\0")
    return h.hexdigest()


def entry(png: Path, sources, scene=None) -> dict:
    """The manifest entry of one written figure."""
    files = sorted({str(Path(f).resolve().relative_to(ROOT)) for f in sources})
    if scene is not None and Path(scene).resolve().is_relative_to(ROOT):
        files.append(str(Path(scene).resolve().relative_to(ROOT)))
    return {"files": files, "code_sha256": code_hash(files), "png_sha256": hashlib.sha256(png.read_bytes()).hexdigest()}


def model_file(scene, scene_path: Path) -> Path | None:
    """The file declaring the scene's model (its units and names label the figures): a user model
    file ("models/x.py:NAME", beside the scene) or the built-in module holding the declaration."""
    import tomllib

    key = str(tomllib.loads(scene_path.read_text())["scene"]["model"])
    if ".py:" in key:
        f = (scene_path.parent / key.split(":")[0]).resolve()
        return f if f.is_file() else None
    for name, module in list(sys.modules.items()):
        if name.startswith("mechsweep.models.") and any(v is scene.model for v in vars(module).values()):
            return Path(module.__file__).resolve()
    return None


def _record(manifest: dict, png: Path, sources, scene=None) -> None:
    manifest[png.name] = entry(png, sources, scene)
    print(f"-> {png.relative_to(ROOT)}")


def main(filters: list[str], reuse: bool = False) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    manifest = json.loads(MANIFEST.read_text()) if MANIFEST.is_file() else {}
    for path in sorted((ROOT / "sweeps").glob("*.toml")):
        if filters and not any(f in path.stem for f in filters):
            continue
        scene = mechsweep.load_scene(path)
        stored = ROOT / scene.storage.path
        ds = (mechsweep.open_dataset(stored) if reuse and stored.is_file()
              else mechsweep.run(scene, output=stored, restart=True, overwrite=True, progress=False))
        bds = None
        if scene.boundaries is not None and reuse and figures.sibling_boundaries(ROOT / scene.storage.path):
            bds = mechsweep.open_dataset(figures.sibling_boundaries(ROOT / scene.storage.path))
        elif scene.boundaries is not None:
            from mechsweep.boundaries import run_boundaries

            where, bds = run_boundaries(scene, data=ROOT / scene.storage.path)
            print(f"{path.name} -> {where.relative_to(ROOT)}: {bds.attrs['located']} boundaries located")
        kinds = list(figures.available(ds))
        for kind, written in zip(kinds, figures.save(ds, OUT / f"{path.stem}.png", boundaries=bds)):
            model = model_file(scene, path)
            _record(manifest, written, figures.source_files(ds, kind, boundaries=bds) + ([model] if model else []),
                    path)
    import xarray as xr

    from mechsweep.bench import workprecision

    for model in workprecision.all_cases():
        if filters and "workprecision" not in filters and f"workprecision_{model}" not in filters:
            continue
        stored = ROOT / "data" / "bench" / f"workprecision_{model}.h5"
        ds = (xr.open_dataset(stored, engine="h5netcdf").load() if reuse and stored.is_file()
              else workprecision.main(model, out_dir=ROOT / "data" / "bench"))
        scene = ROOT / str(ds.attrs.get("scene", ""))
        for kind, written in zip(list(figures.available(ds)), figures.save(ds, OUT / f"workprecision_{model}.png")):
            _record(manifest, written, figures.source_files(ds, kind), scene if scene.is_file() else None)
    if not filters or any(f in "generic_figures_example" for f in filters):
        sys.path.insert(0, str(ROOT / "docs"))
        import generic_figures_example

        here = Path(figures.__file__).parent
        _record(manifest, generic_figures_example.main(),
                [ROOT / "docs" / "generic_figures_example.py", here / "generic.py", here / "_style.py",
                 ROOT / "sweeps" / "models" / "vibrating_pendulum.py"],
                ROOT / "sweeps" / "vibrating_pendulum_stability.toml")
    if not filters or any(f in "architecture" for f in filters):  # docs/architecture.md's picture
        sys.path.insert(0, str(ROOT / "docs"))
        import make_architecture_figure

        _record(manifest, make_architecture_figure.main(), [ROOT / "docs" / "make_architecture_figure.py"])
    MANIFEST.write_text(json.dumps(dict(sorted(manifest.items())), indent=1) + "\n")
    print(f"-> {MANIFEST.relative_to(ROOT)}")


if __name__ == "__main__":
    main([a for a in sys.argv[1:] if a != "--reuse"], reuse="--reuse" in sys.argv[1:])
