"""The grid of a scene: flat point index <-> axis values, and its cut into chunks.

Points are numbered in C order over the axes (the last axis varies fastest). A chunk
is a contiguous range of flat indices that is also a hyperslab of the N-d grid
(leading indices fixed, a slice of one axis, all of the following axes), so each
finished chunk is written to the HDF5 file as one rectangular block.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import Scene


@dataclass(frozen=True)
class Chunk:
    index: int
    start: int  # first flat point
    stop: int  # one past the last flat point
    region: tuple  # tuple of slices into the N-d grid

    @property
    def size(self) -> int:
        return self.stop - self.start


def plan_chunks(shape: tuple[int, ...], target: int) -> list[Chunk]:
    """Cut a grid of ``shape`` into hyperslab chunks of about ``target`` points (never more)."""
    if not shape:
        return [Chunk(0, 0, 1, ())]
    target = max(1, int(target))
    # the split axis j: the first axis whose trailing block (one index of j, all after) fits
    trailing = [int(np.prod(shape[k + 1 :], dtype=np.int64)) for k in range(len(shape))]
    j = next((k for k in range(len(shape)) if trailing[k] <= target), len(shape) - 1)
    step = max(1, target // trailing[j])
    lead_shape = shape[:j]
    chunks = []
    flat = 0
    for lead in np.ndindex(*lead_shape) if lead_shape else [()]:
        for s in range(0, shape[j], step):
            e = min(shape[j], s + step)
            region = tuple(slice(i, i + 1) for i in lead) + (slice(s, e),) + (slice(None),) * (len(shape) - j - 1)
            size = (e - s) * trailing[j]
            chunks.append(Chunk(len(chunks), flat, flat + size, region))
            flat += size
    return chunks


CHUNK_VALUES = 2**22  # float64 values of one chunk's outputs (32 MiB), whatever their extra dims


def default_chunk_target(scene: Scene) -> int:
    """Points per chunk: a few seconds of work, many chunks for the progress bar and resume,
    and at most CHUNK_VALUES output values (a 360-position curve counts 360 per point)."""
    if scene.storage.chunk_size:
        return scene.storage.chunk_size
    per_chunk = 8192 if scene.solver is not None else 262_144
    settings = scene.solver.settings if scene.solver is not None else {}
    values_per_point = sum(
        int(np.prod([len(d.values(settings)) for d in scene.model.output(name).extra_dims], dtype=np.int64))
        for name in scene.computed_outputs
    )
    per_chunk = min(per_chunk, max(1, CHUNK_VALUES // max(1, values_per_point)))
    return int(min(per_chunk, max(min(256, per_chunk), scene.n_points // 20)))


class ParameterMatrix:
    """Builds the float64 [n, n_params] parameter rows of any flat range of a scene's grid.

    Axis values are encoded (choices -> indices) once, not per chunk."""

    def __init__(self, scene: Scene):
        self.shape = scene.shape
        self.columns = []  # per parameter: ("axis", k, encoded values) or ("const", value)
        axis_pos = {a.name: k for k, a in enumerate(scene.axes)}
        for prm in scene.model.params:
            if prm.name in axis_pos:
                k = axis_pos[prm.name]
                self.columns.append(("axis", k, np.array([prm.encode(v) for v in scene.axes[k].values])))
            elif prm.name in scene.fixed:
                self.columns.append(("const", prm.encode(scene.fixed[prm.name])))
            else:
                self.columns.append(("const", prm.default))

    def __call__(self, start: int, stop: int) -> np.ndarray:
        P = np.empty((stop - start, len(self.columns)))
        idx = np.unravel_index(np.arange(start, stop, dtype=np.int64), self.shape) if self.shape else ()
        for col, spec in enumerate(self.columns):
            P[:, col] = spec[2][idx[spec[1]]] if spec[0] == "axis" else spec[1]
        return P


def parameter_matrix(scene: Scene, start: int, stop: int) -> np.ndarray:
    """float64 [stop - start, n_params] in the model's declared parameter order."""
    return ParameterMatrix(scene)(start, stop)
