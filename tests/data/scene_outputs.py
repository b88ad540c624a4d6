"""Whole shipped scenes of a model, every method: ``python tests/data/scene_outputs.py record DIR``
writes each scene's outputs, status, n_steps and n_rhs (in memory, no HDF5) to DIR; ``... compare
DIR`` computes them again with the current code and reports whether every array is bitwise equal;
an optional third argument keeps only the scenes whose file name starts with it (e.g. torsional).
Used once to check that moving the built-in Duffing and torsional circuit onto the model layer
changed no value of sweeps/duffing_*.toml and sweeps/torsional_circuit_*.toml (too slow for a test).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
SCENES = sorted(REPO.glob("sweeps/duffing_*.toml")) + sorted(REPO.glob("sweeps/torsional_circuit_*.toml"))
METHODS = ("dop853", "radau", "symplectic", "auto")


def compute(path: Path, method: str) -> dict:
    import tomllib

    from mechsweep.chunks import Chunk
    from mechsweep.execution.execute import evaluate_chunk
    from mechsweep.scene import load_scene

    raw = tomllib.loads(path.read_text())
    raw.setdefault("solver", {})["method"] = method
    raw.pop("storage", None)
    scene = load_scene(raw)
    cols, status, n_steps, n_rhs = evaluate_chunk(scene, Chunk(0, 0, scene.n_points, ()))
    return {**cols, "status": status, "n_steps": n_steps, "n_rhs": n_rhs}


def main(mode: str, folder: str, prefix: str = "") -> int:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    bad = 0
    for path in [s for s in SCENES if s.name.startswith(prefix)]:
        for method in METHODS:
            arrays = compute(path, method)
            f = folder / f"{path.stem}-{method}.npz"
            if mode == "record":
                np.savez_compressed(f, **arrays)
                print("recorded", f.name, len(arrays), "arrays")
                continue
            ref = np.load(f)
            same = set(ref.files) == set(arrays) and all(
                np.array_equal(ref[k], arrays[k], equal_nan=True) and ref[k].dtype == arrays[k].dtype
                for k in ref.files)
            bad += not same
            print(f"{path.stem} {method}: {'bitwise identical' if same else 'DIFFERENT'} "
                  f"({len(ref.files)} arrays, {arrays['status'].size} points)")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:4]))
