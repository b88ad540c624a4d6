"""A run's dataset made from its chunks: ``assemble`` writes it from the journal (chunk by chunk,
memory bounded by one chunk) into a temporary file that replaces the output by one rename;
``MemorySink`` holds it in memory (the in-memory route, and the dataset ``run(output=path)``
returns); ``Early`` writes the file while the chunks are computed. Also the points per status."""
from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

from .. import status as st
from ..errors import WriteFailed
from .journal import BadChunk, Journal
from .write import (READ_BLOCK, GuardedFile, Layout, NetCDFWriter, chunk_variables, define, memory_store,
                    remove_file, write_memory, write_region)

if TYPE_CHECKING:
    import xarray as xr

    from ..scene import Scene


def assemble(journal: Journal, scene: Scene, lay: Layout, chunks: list, target, attrs: dict, *,
             stop=None, memory: "MemorySink | None" = None, early: "Early | None" = None
             ) -> tuple[list[BadChunk], dict[int, int]]:
    """Write the dataset of a journal to ``target`` (a path, or a file object for an in-memory
    view), one chunk in memory at a time. Chunks not in the journal keep the fill values (NaN,
    status PENDING), and so do chunk files that do not verify: they are returned. Also returned:
    the points per status code. The time attributes are the sums the chunk files carry.

    To a path the file is written through ``GuardedFile`` and synced; a failed write raises
    ``WriteFailed`` after the file is removed. ``stop()`` is asked between chunks: when true, the
    file is removed and ``KeyboardInterrupt`` raised.

    ``memory`` (a MemorySink): the chunks this process computed are taken from it, not read back;
    the others are read from the journal into it; it ends with the file's attributes, so that
    ``memory.dataset()`` is the dataset the file holds. ``early``: the file already filled with
    ``memory``'s chunks while they were computed; only what is missing is written into it. An
    ``early`` that cannot be used is discarded and the file written from the start."""
    if not isinstance(target, (str, os.PathLike)):
        return _assemble(journal, scene, lay, chunks, target, attrs, lambda: False, memory)
    if early is not None and not early.usable(target, memory):
        early.discard()
        early = None
    if early is not None:
        guard = early.guard
    else:
        try:
            guard = GuardedFile(target)
        except OSError as exc:  # e.g. no inode left
            raise WriteFailed(target, exc) from None
    stop = stop or (lambda: False)
    try:
        bad, counts = _assemble(journal, scene, lay, chunks, guard, attrs,
                                lambda: guard.error is not None or stop(), memory, early)
        if guard.error is None:
            guard.sync()
    except BaseException:
        guard.close()
        remove_file(target)
        raise
    guard.close()
    if guard.error is not None:
        remove_file(target)
        raise WriteFailed(target, guard.error)
    if stop():
        remove_file(target)
        raise KeyboardInterrupt
    return bad, counts


def _assemble(journal, scene, lay, chunks, target, attrs, stop, memory=None, early=None
              ) -> tuple[list[BadChunk], dict[int, int]]:
    if early is None:
        with NetCDFWriter(target) as f:
            define(f, scene, lay, attrs)
    bad = []
    with (early.take() if early is not None else h5py.File(target, "a")) as f:
        names = chunk_variables(lay)
        variables = {name: f[name] for name in names}
        wall_time = compile_time = 0.0
        counts = Counts()
        stopped = False
        for i in np.flatnonzero(journal.done_chunks()):
            if stop():
                stopped = True
                break
            chunk = chunks[int(i)]
            if memory is not None and int(i) in memory.times:  # computed by this process: in memory already
                seconds, compiled = memory.times[int(i)]
                wall_time += seconds
                compile_time += compiled
                continue
            try:
                arrays, seconds = journal.read_chunk(int(i))
            except BadChunk as exc:
                bad.append(exc)
                continue
            wall_time += seconds
            compile_time += float(arrays.pop(COMPILE_KEY, 0.0))
            if memory is not None:
                write_memory(memory.store, chunk.region, arrays, lay.shape)
                if early is None:
                    continue
            if memory is None:
                counts.add(arrays["status"])
            write_region(variables, chunk.region, arrays, lay.shape)
        if memory is not None and not stopped:  # every variable at once (regions not computed: their fill values)
            if early is None:  # (with early: written chunk by chunk as they were computed)
                for name, var in variables.items():
                    var[...] = memory.store.variables[name].data
            counts.add(memory.store.variables["status"].data)
        times = time_attrs(compile_time, wall_time)
        f.attrs.update(times)
    if memory is not None:  # the attributes define wrote, and the times
        memory.store.attrs = {**attrs, "n_chunks": lay.n_chunks, **times}
    missing = int(np.prod(lay.shape, dtype=np.int64)) - counts.total
    if missing:
        counts.codes[st.PENDING] = counts.codes.get(st.PENDING, 0) + missing
    return bad, dict(sorted(counts.codes.items()))


def _early_cache(f: h5py.File, names: list[str]) -> int:
    """Bytes of HDF5's chunk cache (per variable) for the early-written file: a chunk of the run is
    a band of rows, which seldom ends at an HDF5 storage chunk's edge; a cache of three bands of
    storage chunks holds the partly written ones until the next chunks of the run complete them
    (completed ones are evicted first, ``rdcc_w0=1``, so their compression is spread over the
    run), instead of HDF5 compressing, evicting and reading them back. The values stored are the
    same either way."""
    band = 0
    for name in names:
        var = f[name]
        if var.chunks:
            band = max(band, var.chunks[0] * int(np.prod(var.shape[1:], dtype=np.int64)) * var.dtype.itemsize)
    return max(2**20, 3 * band)


PREPARE_WAIT = 5.0  # seconds Early.prepare waits for the first chunk's launch (then it defines the file anyway)


class Early:
    """The dataset file of a run (with ``MemorySink``) written in the writer thread while its chunks
    are computed, each chunk after it is saved to the journal. It is the temporary file the
    assembly writes (in the journal folder, renamed into place only when complete), so crash safety
    is unchanged: a resumed run writes it anew from the journal. An optimisation only: any failure
    discards it, and the assembly writes the file from the start as without it."""

    def __init__(self, path, scene: Scene, lay: Layout, attrs: dict):
        self.path = Path(path)
        self.scene, self.lay, self.attrs = scene, lay, attrs
        self.guard: GuardedFile | None = None
        self.file: h5py.File | None = None
        self.variables: dict = {}
        self.written: set[int] = set()
        self.failed = False

    def _open(self) -> None:
        self.guard = GuardedFile(self.path)
        names = chunk_variables(self.lay)
        with NetCDFWriter(self.guard) as f:
            define(f, self.scene, self.lay, self.attrs)
            cache = _early_cache(f.file, names)  # (from the storage chunks just made: no opening to read them)
        self.file = h5py.File(self.guard, "a", rdcc_nbytes=cache, rdcc_nslots=100_003, rdcc_w0=1.0)
        self.variables = {name: self.file[name] for name in names}

    def prepare(self, started=None) -> None:
        """Create and define the file in the writer thread while the first chunk computes, so that
        the definition does not delay the first write. ``started``: set when the first chunk's kernel
        is about to run (waited for at most PREPARE_WAIT seconds), so that this Python work holds
        the GIL while the kernel has released it. A failure discards the file, as in ``write``."""
        if started is not None:
            started.wait(PREPARE_WAIT)
        if self.failed or self.file is not None:
            return
        try:
            self._open()
        except Exception:
            self.discard()

    def write(self, index: int, region: tuple, arrays: dict) -> None:
        """Write one saved chunk (COMPILE_KEY and other extra keys are ignored)."""
        if self.failed:
            return
        try:
            if self.file is None:
                self._open()
            if self.guard.error is None:
                write_region(self.variables, region, arrays, self.lay.shape)
            if self.guard.error is None:
                # what HDF5 has written of the file so far goes to the disk now, in this thread while
                # the next chunk computes, instead of all at the run's final sync, after the last launch
                self.guard.sync()
            if self.guard.error is not None:
                self.discard()
                return
            self.written.add(index)
        except Exception:  # e.g. OSError opening the file: the assembly writes it from the start
            self.discard()

    def usable(self, target, memory: "MemorySink | None") -> bool:
        """Whether the assembly of ``target`` can go on in this file: nothing failed and every
        chunk ``memory`` has from this process is in it."""
        return (not self.failed and self.file is not None and self.guard.error is None and memory is not None
                and Path(target) == self.path and set(memory.times) <= self.written)

    def take(self) -> h5py.File:
        """The open file, handed to the assembly (which closes it)."""
        f, self.file = self.file, None
        return f

    def discard(self) -> None:
        """Close and remove the file; nothing more is written to it."""
        self.failed = True
        try:
            if self.file is not None:
                self.file.close()
        except Exception:
            pass
        self.file = None
        if self.guard is not None:
            self.guard.close()
            remove_file(self.path)
            self.guard = None


class MemorySink:
    """A run's dataset in memory, defined as its file is (``memory_store``): the sink of
    ``run(output=None)``, and of a file run that returns its dataset. A chunk computed here is
    computed straight into its arrays (``views``); ``save`` notes its seconds in ``times`` (chunk
    index -> (wall, compile)) and copies only arrays computed elsewhere."""

    background = False  # nothing to write: the route saves its chunks in the computing thread

    def __init__(self, scene: Scene, lay: Layout, attrs: dict):
        self.store = memory_store(scene, lay, attrs)
        self.times: dict[int, tuple[float, float]] = {}
        n = int(np.prod(lay.shape, dtype=np.int64))
        self._flat = {}  # variable -> the array over the grid's flat points (a view, C order)
        for name in chunk_variables(lay):
            data = self.store.variables[name].data
            flat = data.reshape((n,) + data.shape[len(lay.shape):])
            if _address(flat) != _address(data):
                raise AssertionError(f"the flat view of {name} is a copy")
            self._flat[name] = flat

    def views(self, chunk) -> dict:
        """The arrays a chunk is computed into: each variable's stretch of the chunk's flat points (a
        chunk is a contiguous range of them, grid.py)."""
        return {name: flat[chunk.start:chunk.stop] for name, flat in self._flat.items()}

    def save(self, chunk, arrays: dict, seconds: float) -> None:
        """A computed chunk: its arrays (and COMPILE_KEY, the compile phase it carries), its wall time."""
        for name, flat in self._flat.items():
            values, into = arrays[name], flat[chunk.start:chunk.stop]
            if _address(values) != _address(into):  # (computed into ``views``: nothing to copy)
                into[...] = values.reshape(into.shape)
        self.times[chunk.index] = (float(seconds), float(arrays.get(COMPILE_KEY, 0.0)))

    def dataset(self) -> xr.Dataset:
        return self.store.dataset()


def _address(a: np.ndarray) -> int:
    """Where an array's data begins in memory."""
    return a.__array_interface__["data"][0]


# The key under which a chunk file of the journal carries the compile phase that preceded it.
COMPILE_KEY = "__compile_time_s"


def time_attrs(compile_s: float, compute_s: float) -> dict:
    """The dataset's time attributes: ``compile_time_s`` (before the chunks), ``compute_time_s`` (the
    chunks: kernels and journal writes) and ``wall_time_s``, their sum."""
    return {"compile_time_s": float(compile_s), "compute_time_s": float(compute_s),
            "wall_time_s": float(compile_s) + float(compute_s)}


class Counts:
    """Points per status code, added up array by array."""

    def __init__(self):
        self.codes: dict[int, int] = {}
        self.total = 0

    def add(self, status: np.ndarray) -> None:
        status = np.asarray(status)
        if status.dtype == np.int8:  # the status variable: a histogram, not np.unique's sort (7x faster)
            hist = np.bincount(status.ravel().astype(np.int16) + 128, minlength=256)
            codes = np.flatnonzero(hist)
            codes, n = codes - 128, hist[codes]
        else:
            codes, n = np.unique(status, return_counts=True)
        for c, k in zip(codes.tolist(), n.tolist()):
            self.codes[c] = self.codes.get(c, 0) + k
        self.total += int(status.size)


def status_counts(path: str | Path) -> dict[int, int]:
    """Points per status code of a stored dataset, read block by block (memory of one block,
    whatever the grid)."""
    counts = Counts()
    with h5py.File(path, "r") as f:
        var = f["status"]
        if var.ndim == 0:
            counts.add(var[()])
        else:
            rows = max(1, READ_BLOCK // max(1, int(np.prod(var.shape[1:], dtype=np.int64))))
            for lo in range(0, var.shape[0], rows):
                counts.add(var[lo:lo + rows])
    return dict(sorted(counts.codes.items()))
