"""Where the solver settings stop working: ``python tests/data/solver_limits.py [SCENE ...] [num=N]
[atols=A,B,...] [rtols=R,...] [methods=M,...]``.

Every shipped scene with integrated outputs (default: sweeps/*.toml and sweeps/extreme/*.toml), its
axes cut to their two ends (``num=N``: N values), is computed with each method its outputs offer at
its own settings, then again with one tolerance moved at a time: ``atol`` down to 1e-300 and
``rtol`` down to 1e-15 (the scene's floor). Printed per scene and method: the statuses at its own
settings, the fewest and the most accepted steps one point takes (``max_steps`` below a point's
count turns it into status max_steps, flagged), and every point whose status changes when a
tolerance moves (e.g. ok -> nonfinite), with the largest atol at which one does.

The usable ranges scene.py refuses and warns outside of (``ATOL_FLOOR``, ``ATOL_WARN``,
``RADAU_MIN_RTOL``; docs/scenes.md, "Solver settings") are read from this table. The scene's floor of
atol is bypassed here (the Scene is changed after it was validated) to see what lies below it.
"""
from __future__ import annotations

import dataclasses
import sys
import tomllib
import warnings
from pathlib import Path

import numpy as np

import mechsweep
from mechsweep import status as st
from mechsweep.scene import load_scene_text

REPO = Path(__file__).resolve().parents[2]
ATOLS = (1e-100, 1e-120, 1e-140, 1e-150, 1e-155, 1e-160, 1e-170, 1e-200, 1e-250, 1e-300)
RTOLS = (1e-13, 1e-14, 3e-15, 1e-15)


def small(path: Path, num: int):
    """The scene of ``path`` with every axis cut to ``num`` values (its ends first), no storage."""
    data = tomllib.loads(path.read_text())
    for name, spec in data.get("axes", {}).items():
        if isinstance(spec, dict):
            spec["num"] = min(spec["num"], num)
        elif len(spec) > num:
            data["axes"][name] = [spec[0], spec[-1]] + spec[1:num - 1]
    data.pop("boundaries", None)
    data.pop("storage", None)
    from mechsweep.scene import to_toml

    return load_scene_text(to_toml(data), label=str(path), base=path.parent)


def statuses(scene) -> tuple[np.ndarray, np.ndarray]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = mechsweep.run(scene, output=None, progress=False)
    return ds["status"].values.ravel(), ds["n_steps"].values.ravel()


def changed(base: np.ndarray, now: np.ndarray) -> str:
    moved = base != now
    if not moved.any():
        return ""
    pairs = {}
    for a, b in zip(base[moved], now[moved]):
        key = f"{st.MEANINGS.get(int(a), a)} -> {st.MEANINGS.get(int(b), b)}"
        pairs[key] = pairs.get(key, 0) + 1
    return ", ".join(f"{k} {n}" for k, n in pairs.items())


def with_solver(scene, **kw):
    return dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, **kw))


def main(argv: list[str]) -> None:
    global ATOLS, RTOLS
    num, only = 2, None
    paths = []
    for a in argv:
        if a.startswith("num="):
            num = int(a[4:])
        elif a.startswith("atols="):
            ATOLS = tuple(float(x) for x in a[6:].split(","))
        elif a.startswith("rtols="):
            RTOLS = tuple(float(x) for x in a[6:].split(",") if x)
        elif a.startswith("methods="):
            only = a[8:].split(",")
        else:
            paths.append(Path(a).resolve())
    paths = paths or sorted((REPO / "sweeps").glob("*.toml")) + sorted((REPO / "sweeps" / "extreme").glob("*.toml"))
    for path in paths:
        scene = small(path, num)
        if scene.solver is None:
            continue
        spec = scene.model
        methods = spec.methods_for(spec.closure(scene.outputs)) if spec.methods_for else spec.methods
        for method in (m for m in methods if only is None or m in only):
            own = with_solver(scene, method=method)
            base, steps = statuses(own)
            print(f"{path.relative_to(REPO)} {method}: {base.size} points "
                  f"({changed(np.full_like(base, -99), base).replace('-99 -> ', '')}); rtol {own.solver.rtol:g}, "
                  f"atol {own.solver.atol:g}; steps of one point {int(steps.min())} to {int(steps.max())}", flush=True)
            first = None
            for atol in ATOLS:
                what = changed(base, statuses(with_solver(own, atol=atol))[0])
                if what:
                    first = first or atol
                    print(f"    atol {atol:g}: {what}", flush=True)
            for rtol in RTOLS:
                what = changed(base, statuses(with_solver(own, rtol=rtol))[0])
                if what:
                    print(f"    rtol {rtol:g}: {what}", flush=True)
            print(f"    largest atol that changes a status: {first if first else 'none of those tried'}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
