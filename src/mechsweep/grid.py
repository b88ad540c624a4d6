"""The grid of a scene: flat point index <-> axis values, and how many points a chunk holds.

Points are numbered in C order over the axes (the last axis varies fastest); the chunks
themselves (hyperslabs of the grid) are cut by ``mechsweep.chunks``.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .chunks import MAX_CHUNKS, ChunkPlan, least_target

if TYPE_CHECKING:  # not imported at run time: reading a dataset (plot, info) needs no model or numba
    from .scene import Scene


def chunk_target(scene: Scene, many: bool = True) -> int:
    """Points per chunk of a run: ``default_chunk_target``, raised when it would cut the grid into
    more than MAX_CHUNKS chunks (a [storage] chunk_size that does so is refused when the scene is
    loaded). ``many=False``: without the at-least-20-chunks rule (no progress bar to feed)."""
    target = default_chunk_target(scene, many)
    if len(ChunkPlan(scene.shape, target)) > MAX_CHUNKS:
        target = max(target, least_target(scene.shape))
    return target


INTEGRATED_CHUNK = 65536  # points of a default chunk of integrated outputs (about 40 ms of Duffing periods on 2 cores)
CHUNK_VALUES = 2**22  # float64 values of one chunk's outputs (32 MiB), whatever their extra dims


def default_chunk_target(scene: Scene, many: bool = True) -> int:
    """Points per chunk: many chunks for the progress bar and resume, and at most CHUNK_VALUES
    output values (a 360-position curve counts 360 per point). ``many=False`` (no progress bar):
    not cut into at least 20 chunks. Each chunk costs a kernel launch (whose lanes idle at its end,
    a barrier for the threads), a journal file with its fsyncs and some Python: 8192-point chunks
    spent 15-20 % of a 2*10^5-point run's CPU on them, 32768-point chunks still 5 % of a
    10^6-point run's (docs/performance-duffing.md, `python benchmarks/duffing_breakdown.py`)."""
    if scene.storage.chunk_size:
        return scene.storage.chunk_size
    per_chunk = INTEGRATED_CHUNK if scene.solver is not None else 262_144
    settings = scene.solver.settings if scene.solver is not None else {}
    values_per_point = sum(
        int(np.prod([len(d.values(settings)) for d in scene.model.output(name).extra_dims], dtype=np.int64))
        for name in scene.computed_outputs
    )
    per_chunk = min(per_chunk, max(1, CHUNK_VALUES // max(1, values_per_point)))
    if not many:
        return int(per_chunk)
    # at least 20 chunks, but not below SMALLEST_CHUNK points: a grid of 10^3-10^4 points computes in
    # milliseconds, and 20 chunks of it cost more (launches, journal files, fsyncs) than the points
    least = SMALLEST_CHUNK[scene.solver is not None]
    return int(min(per_chunk, max(min(least, per_chunk), scene.n_points // 20)))


# The smallest default chunk (closed form, integrated), unless the memory cap or the grid is smaller.
SMALLEST_CHUNK = {False: 8192, True: 2048}


class ParameterMatrix:
    """Builds the float64 [n, n_params] parameter rows of any flat range of a scene's grid.

    List axes are encoded (choices -> indices) once; a range axis gives, per chunk, only the
    stretch of values the chunk covers, so memory is bounded by the chunk, whatever the axes."""

    def __init__(self, scene: Scene):
        self.shape = scene.shape
        self.columns = []  # per parameter: ("axis", k, encoded values or the range Axis) or ("const", value)
        axis_pos = {a.name: k for k, a in enumerate(scene.axes)}
        for prm in scene.model.params:
            if prm.name in axis_pos:
                k = axis_pos[prm.name]
                axis = scene.axes[k]
                values = (np.array([prm.encode(v) for v in axis.items], dtype=float) if axis.spacing == "list"
                          else axis)
                self.columns.append(("axis", k, values))
            elif prm.name in scene.fixed:
                self.columns.append(("const", prm.encode(scene.fixed[prm.name])))
            else:
                self.columns.append(("const", prm.default))

    def __call__(self, start: int, stop: int) -> np.ndarray:
        P = np.empty((stop - start, len(self.columns)))
        slab = self._hyperslab(start, stop)
        if slab is not None:  # a chunk of the plan: each axis's values broadcast, no index arrays
            self._fill_slab(P, *slab)
            return P
        idx = np.unravel_index(np.arange(start, stop, dtype=np.int64), self.shape) if self.shape else ()
        for col, spec in enumerate(self.columns):
            if spec[0] == "const":
                P[:, col] = spec[1]
            elif isinstance(spec[2], np.ndarray):
                P[:, col] = spec[2][idx[spec[1]]]
            elif stop > start:  # a range axis: the values this stretch of points uses
                i = idx[spec[1]]
                lo, hi = int(i.min()), int(i.max()) + 1
                P[:, col] = spec[2].array(lo, hi)[i - lo]
        return P

    def _hyperslab(self, start: int, stop: int):
        """(j, lead, s, m) when the flat range [start, stop) is a hyperslab as ChunkPlan cuts them:
        the axes before j at the indices ``lead``, indices s to s + m - 1 of axis j, all of the axes
        after it; None when it is not one (e.g. a range that wraps over an axis)."""
        shape = self.shape
        if not shape or stop <= start:
            return None
        for j in range(len(shape)):  # the coarsest cut first
            block = math.prod(shape[j + 1:])
            if start % block or stop % block:
                continue
            s, m = (start // block) % shape[j], (stop - start) // block
            if s + m <= shape[j]:
                lead = np.unravel_index(start // (block * shape[j]), shape[:j]) if j else ()
                return j, tuple(int(x) for x in lead), s, m
        return None

    def _fill_slab(self, P: np.ndarray, j: int, lead: tuple, s: int, m: int) -> None:
        """P's rows for the hyperslab (j, lead, s, m): each column computed from the same stretch of
        its axis as the general route (``array(lo, hi)`` with the same lo, hi: the same floats),
        broadcast over the slab instead of gathered through index arrays."""
        region = (m,) + tuple(self.shape[j + 1:])
        for col, spec in enumerate(self.columns):
            if spec[0] == "const":
                P[:, col] = spec[1]
                continue
            k = spec[1]
            if k < j:
                lo, hi = lead[k], lead[k] + 1
            elif k == j:
                lo, hi = s, s + m
            else:
                lo, hi = 0, self.shape[k]
            values = spec[2][lo:hi] if isinstance(spec[2], np.ndarray) else spec[2].array(lo, hi)
            if k < j:
                P[:, col] = values[0]
                continue
            view = [1] * len(region)
            view[k - j] = hi - lo
            target = P[:, col].reshape(region)  # a view: a strided column takes any C-order shape
            if not np.may_share_memory(target, P):  # (never; were it a copy, the rows would not be set)
                raise AssertionError("the column view of the parameter rows was copied")
            target[...] = values.reshape(view)


def parameter_matrix(scene: Scene, start: int, stop: int) -> np.ndarray:
    """float64 [stop - start, n_params] in the model's declared parameter order."""
    return ParameterMatrix(scene)(start, stop)
