"""Fingerprints of the data every figure draws, from every shipped scene at reduced size.

The figures of each scene in sweeps/ (cut down by :func:`reduce_scene`) are drawn and the arrays on
them (line and marker coordinates, colour-mesh values, contour paths: what ``_style.lines_data``
reads off the figure, never pixels) are summarised per array as (size, finite count, sum, sum of
|values|). tests/figures/test_figure_data.py recomputes them and compares with the stored JSON to a
relative tolerance, so a change in what any figure draws (or in the numbers under it) is seen, but
not a last-ulp difference.

    python tests/data/figure_fingerprints.py     # rewrite tests/data/figure_fingerprints.json

Regenerate it only after checking that the change is intended (and regenerate docs/figures with
docs/make_figures.py in the same commit).
"""
from __future__ import annotations

import copy
import json
import sys
import tomllib
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
STORE = Path(__file__).with_suffix(".json")
AXIS_POINTS = 6  # a linspace/logspace axis keeps at most this many values
LIST_VALUES = 4  # a list axis keeps at most this many (evenly picked, first and last included)
# solver settings that keep a scene cheap (applied when the scene has the key): the simulated
# auto-balancer outputs over fewer revolutions (their values change, their figures do not)
SOLVER = {"horizon_revolutions": 30}


def reduce_scene(data: dict) -> dict:
    """The scene (parsed TOML) with every axis cut to a few values; nothing else changed but the
    SOLVER keys above and the storage path (the caller sets it)."""
    data = copy.deepcopy(data)
    for name, axis in data.get("axes", {}).items():
        if isinstance(axis, dict) and "num" in axis:
            axis["num"] = min(int(axis["num"]), AXIS_POINTS)
        elif isinstance(axis, list) and len(axis) > LIST_VALUES:
            pick = np.unique(np.linspace(0, len(axis) - 1, LIST_VALUES).round().astype(int))
            data["axes"][name] = [axis[i] for i in pick]
    for key, value in SOLVER.items():
        if key in data.get("solver", {}):
            data["solver"][key] = value
    data.pop("boundaries", None)
    return data


def summary(arrays) -> list[list[float]]:
    out = []
    for a in arrays:
        a = np.asarray(a, dtype=float).ravel()
        fin = a[np.isfinite(a)]
        out.append([int(a.size), int(fin.size), float(fin.sum()), float(np.abs(fin).sum())])
    return out


def reduced_datasets(workdir: Path) -> dict:
    """{scene stem: dataset} of every shipped scene, run cut down by :func:`reduce_scene`."""
    import mechsweep
    from mechsweep.scene import load_scene_text, to_toml

    result = {}
    for path in sorted((REPO / "sweeps").glob("*.toml")):
        data = reduce_scene(tomllib.loads(path.read_text()))
        data.setdefault("storage", {})["path"] = str(workdir / f"{path.stem}.h5")
        scene = load_scene_text(to_toml(data), label=path.name, base=path.parent)  # model paths: beside the scene
        result[path.stem] = mechsweep.run(scene, output=workdir / f"{path.stem}.h5", progress=False)
    return result


def drawn_figures(datasets: dict) -> dict:
    """{scene stem: {figure name: Figure}}: every figure drawn by default for each dataset."""
    from mechsweep import figures

    return {stem: {kind: figures.draw(ds, kind) for kind in figures.available(ds)} for stem, ds in datasets.items()}


def fingerprints(workdir: Path, drawn: dict | None = None) -> dict:
    """{scene stem: {figure name: summary of its arrays}} for every shipped scene (``drawn``: the
    figures of :func:`drawn_figures`, drawn here when not given)."""
    from mechsweep.figures._style import lines_data

    drawn = drawn if drawn is not None else drawn_figures(reduced_datasets(workdir))
    return {stem: {kind: summary(lines_data(fig)) for kind, fig in figs.items()} for stem, figs in drawn.items()}


def compare(got: dict, want: dict, rtol: float = 1e-6) -> list[str]:
    """The differences, one line each (empty: the same to rtol)."""
    bad = []
    for scene in sorted(set(got) | set(want)):
        g, w = got.get(scene), want.get(scene)
        if g is None or w is None:
            bad.append(f"{scene}: {'not drawn now' if g is None else 'no stored fingerprint'}")
            continue
        if set(g) != set(w):
            bad.append(f"{scene}: figures {sorted(g)} now, {sorted(w)} stored")
        for kind in sorted(set(g) & set(w)):
            if len(g[kind]) != len(w[kind]):
                bad.append(f"{scene} {kind}: {len(g[kind])} arrays drawn now, {len(w[kind])} stored")
                continue
            for i, (a, b) in enumerate(zip(g[kind], w[kind])):
                if a[:2] != b[:2]:
                    bad.append(f"{scene} {kind} array {i}: size/finite {a[:2]} now, {b[:2]} stored")
                elif not (np.isclose(a[3], b[3], rtol=rtol, atol=0)
                          and abs(a[2] - b[2]) <= rtol * max(b[3], abs(b[2]))):
                    bad.append(f"{scene} {kind} array {i}: sum {a[2]:.10g} / sum|x| {a[3]:.10g} now, "
                               f"{b[2]:.10g} / {b[3]:.10g} stored")
    return bad


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        fp = fingerprints(Path(tmp))
    STORE.write_text(json.dumps(fp, indent=1, sort_keys=True) + "\n")
    print(f"wrote {STORE.relative_to(REPO)}: {sum(len(v) for v in fp.values())} figures of {len(fp)} scenes",
          file=sys.stderr)
