"""grid.ParameterMatrix builds a chunk's rows by broadcasting each axis's values over the hyperslab:
bitwise the rows of the general route (index arrays), for every chunk of several cuts and any range."""
from __future__ import annotations

import numpy as np
import pytest

from mechsweep.chunks import plan_chunks
from mechsweep.grid import ParameterMatrix
from mechsweep.scene import load_scene

from tests.store.test_store_define import SWEEPS, _shrunk

A = {"start": 0.01, "stop": 1.0, "num": 7}
MU = {"start": 1e-3, "stop": 1e3, "num": 11, "spacing": "log"}
OMEGA = [0.5, 1.0, 2.0]


def _duffing(axes):
    return {"scene": {"name": "rows", "model": "duffing", "outputs": ["period_exact"]}, "axes": axes,
            "fixed": {k: v for k, v in {"A": 0.5, "mu": 1.0, "omega": 1.0}.items() if k not in axes}}


SCENES = [_duffing({"mu": MU}), _duffing({"A": A, "mu": MU}), _duffing({"omega": OMEGA, "A": A, "mu": MU}),
          _duffing({"A": A, "omega": OMEGA, "mu": MU}), _shrunk(SWEEPS / "torsional_circuit_nomogram.toml")]


def _general(pm: ParameterMatrix, start: int, stop: int) -> np.ndarray:
    pm._hyperslab = lambda a, b: None  # (this instance only) the route through index arrays
    try:
        return pm(start, stop)
    finally:
        del pm._hyperslab


@pytest.mark.parametrize("spec", SCENES, ids=lambda s: "-".join(s["axes"]) if "axes" in s else "scene")
def test_chunk_rows_are_those_of_the_general_route(spec):
    scene = load_scene(spec)
    pm = ParameterMatrix(scene)
    n = scene.n_points
    ranges = [(c.start, c.stop) for target in (1, 2, 5, 11, 30, n) for c in plan_chunks(scene.shape, target)]
    rng = np.random.default_rng(1)
    ranges += [tuple(sorted(rng.integers(0, n + 1, 2))) for _ in range(40)]
    fast = 0
    for start, stop in ranges:
        if stop <= start:
            continue
        fast += pm._hyperslab(start, stop) is not None
        got, want = pm(start, stop), _general(pm, start, stop)
        assert got.shape == want.shape and got.tobytes() == want.tobytes(), (start, stop)
    assert fast >= len(ranges) // 2  # every chunk of a plan took the broadcast route
