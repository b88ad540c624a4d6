"""The cut of a grid into chunks: contiguous ranges of flat point indices (C order over the
axes, the last axis varying fastest) that are also hyperslabs of the N-d grid (leading indices
fixed, a slice of one axis, all of the following axes), so each finished chunk is written to the
HDF5 file as one rectangular block.

Only shapes and counts: checking a scene's [storage] chunk_size and planning a run's chunks both
read it, and it reads neither.
"""
from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Chunk:
    index: int
    start: int  # first flat point
    stop: int  # one past the last flat point
    region: tuple  # tuple of slices into the N-d grid

    @property
    def size(self) -> int:
        return self.stop - self.start


class ChunkPlan(Sequence):
    """The chunks of a grid of ``shape`` cut into hyperslabs of about ``target`` points (never
    more): the first axis whose trailing block (one index of it, all axes after) fits is sliced
    into steps, the axes before it are walked one index at a time. Chunks are made on demand
    from their index, so the plan takes O(1) memory and time, whatever their number."""

    def __init__(self, shape: tuple[int, ...], target: int):
        self.shape = tuple(int(n) for n in shape)
        self.target = max(1, int(target))
        if not self.shape:
            self._n = 1
            return
        trailing = [math.prod(self.shape[k + 1:]) for k in range(len(self.shape))]
        self._j = j = next(k for k in range(len(self.shape)) if trailing[k] <= self.target)
        self._trailing = trailing[j]
        self._step = max(1, self.target // trailing[j])
        self._per_lead = -(-self.shape[j] // self._step)
        self._n = math.prod(self.shape[:j]) * self._per_lead

    def __len__(self) -> int:
        return self._n

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(self._n))]
        i = operator.index(i)
        if i < 0:
            i += self._n
        if not 0 <= i < self._n:
            raise IndexError(f"chunk {i} of a plan of {self._n}")
        if not self.shape:
            return Chunk(0, 0, 1, ())
        j, step, trailing = self._j, self._step, self._trailing
        lead_flat, k = divmod(i, self._per_lead)
        s, e = k * step, min(self.shape[j], (k + 1) * step)
        lead = []
        rest = lead_flat
        for n in reversed(self.shape[:j]):
            rest, idx = divmod(rest, n)
            lead.append(idx)
        region = (tuple(slice(x, x + 1) for x in reversed(lead)) + (slice(s, e),)
                  + (slice(None),) * (len(self.shape) - j - 1))
        start = (lead_flat * self.shape[j] + s) * trailing
        return Chunk(i, start, start + (e - s) * trailing, region)

    @property
    def max_size(self) -> int:
        """Points of the largest chunk."""
        return min(self._step, self.shape[self._j]) * self._trailing if self.shape else 1


def plan_chunks(shape: tuple[int, ...], target: int) -> ChunkPlan:
    """Cut a grid of ``shape`` into hyperslab chunks of about ``target`` points (never more)."""
    return ChunkPlan(shape, target)


# A run keeps one file per chunk (written and synced) and one flag per chunk; beyond this count
# the per-chunk costs dominate (about 10,000 synced files a minute) and the chunks are raised.
MAX_CHUNKS = 10_000


def least_target(shape: tuple[int, ...], max_chunks: int = MAX_CHUNKS) -> int:
    """The smallest chunk target whose plan has at most ``max_chunks`` chunks (the count never
    grows with the target: a bisection over O(1) plans)."""
    lo, hi = 1, max(1, math.prod(shape))
    while lo < hi:
        mid = (lo + hi) // 2
        if len(ChunkPlan(shape, mid)) <= max_chunks:
            hi = mid
        else:
            lo = mid + 1
    return lo
