"""HDF5 datasets in netCDF-4's layout, written with h5py directly (``NetCDFWriter``: the objects and
attributes h5netcdf would define, with ``_NCProperties`` saying that mechsweep wrote them through h5py),
read back by ``xarray.open_dataset(path, engine="h5netcdf")``; netCDF-C (netCDF4-python, xarray's
netcdf4 engine) reads them as well.

A run saves its finished chunks in a journal (``journal.py``); ``assemble`` writes the dataset
from it, chunk by chunk (memory bounded by one chunk), into a temporary file that replaces the
output by one rename. A finished file is therefore never half overwritten.

HDF5 must never see a failed write: after one (disk full, file-size limit, I/O error) the library
is left with an open file it cannot flush, and it crashes the interpreter at exit (exit 139). So
``assemble`` hands HDF5 a file object (``_GuardedFile``) that does the writes itself: the first
failure is recorded, and what HDF5 writes after it is kept in memory (at most about one chunk:
the assembly stops at the next chunk), so the library closes its file normally. The file is then
removed and ``WriteFailed`` raised; the journal it was assembled from is untouched.
"""
from __future__ import annotations

import errno
import os
import stat
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

from . import cf
from . import status as st
from .errors import FileBusy, StoreError, WriteFailed, why_os_error  # noqa: F401  (StoreError: API)
from .grid import plan_chunks
from .journal import BadChunk, Journal, partial_path  # noqa: F401  (partial_path: this module's API)

if TYPE_CHECKING:  # not imported at run time: reading a dataset (plot, info) needs no model or numba
    import xarray as xr  # nor does writing one (`mechsweep run`) need xarray: imported where a Dataset is made

    from .scene import Scene

# Datasets up to this size are loaded into memory by open_dataset(lazy=None); larger ones are
# opened lazily, so that the memory a run or a plot needs stays bounded by a chunk, not the grid.
LOAD_LIMIT_BYTES = 256 * 2**20


@dataclass(frozen=True)
class Layout:
    """What goes into the file: names, dims and attributes, from the scene."""

    dims: tuple[str, ...]
    shape: tuple[int, ...]
    outputs: tuple[str, ...]
    integrated: bool
    n_chunks: int
    extra: dict  # output name -> tuple of (ExtraDim, coordinate values), for outputs with extra dims


def layout(scene: Scene, n_chunks: int) -> Layout:
    settings = scene.solver.settings if scene.solver is not None else {}
    extra = {}
    for name in scene.outputs:
        dims = scene.model.output(name).extra_dims
        if dims:
            extra[name] = tuple((d, np.asarray(d.values(settings), dtype=float)) for d in dims)
    return Layout(
        dims=tuple(a.name for a in scene.axes),
        shape=scene.shape,
        outputs=scene.outputs,
        integrated=scene.solver is not None,
        n_chunks=n_chunks,
        extra=extra,
    )


def assemble(journal: Journal, scene: Scene, lay: Layout, chunks: list, target, attrs: dict, *,
             stop=None, memory: "MemorySink | None" = None, early: "Early | None" = None
             ) -> tuple[list[BadChunk], dict[int, int]]:
    """Write the dataset of a journal to ``target`` (a path, or a file object for an in-memory
    view): every variable defined, each journaled chunk written into its region, one chunk in
    memory at a time. Chunks not in the journal keep the fill values (NaN, status PENDING), and so
    do chunk files that do not verify: they are returned (the file is still complete). The
    attributes ``compute_time_s`` (the sum of the written chunks' wall times), ``compile_time_s``
    (the compile phases the chunk files carry) and ``wall_time_s`` (their sum). Also returned: the
    number of points per status code, counted as the chunks pass (PENDING for chunks not written).

    To a path the file is written through ``_GuardedFile`` and synced; a failed write raises
    ``WriteFailed`` after the file is removed. ``stop()`` is asked between chunks: when true, the
    assembly ends, the file is removed and ``KeyboardInterrupt`` raised.

    ``memory``: the run's dataset in memory (``MemorySink``), filled with the chunks this process
    computed. Those chunks are taken from it instead of being read back from the journal, the others
    are read from the journal into it, and the file's variables are written from it whole; it ends up
    with the file's attributes, so that ``memory.dataset()`` is the dataset the file holds without
    opening it again.

    ``early``: the file ``target`` already defined and filled with the chunks of ``memory`` while they
    were computed (``Early``); only what is missing (chunks of the journal from before a resume,
    the times) is written into it. An ``early`` that cannot be used (a write of it failed, a chunk
    missed it, another target) is discarded and the file written from the start, as without it."""
    if not isinstance(target, (str, os.PathLike)):
        return _assemble(journal, scene, lay, chunks, target, attrs, lambda: False, memory)
    if early is not None and not early.usable(target, memory):
        early.discard()
        early = None
    if early is not None:
        guard = early.guard
    else:
        try:
            guard = _GuardedFile(target)
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
        _remove(target)
        raise
    guard.close()
    if guard.error is not None:
        _remove(target)
        raise WriteFailed(target, guard.error)
    if stop():
        _remove(target)
        raise KeyboardInterrupt
    return bad, counts


def _assemble(journal, scene, lay, chunks, target, attrs, stop, memory=None, early=None
              ) -> tuple[list[BadChunk], dict[int, int]]:
    if early is None:
        with NetCDFWriter(target) as f:
            _define(f, scene, lay, attrs)
    bad = []
    with (early.take() if early is not None else h5py.File(target, "a")) as f:
        names = _variables(lay)
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
            _write_region(variables, chunk.region, arrays, lay.shape)
        if memory is not None and not stopped:  # every variable at once (regions not computed: their fill values)
            if early is None:  # (with early: written chunk by chunk as they were computed)
                for name, var in variables.items():
                    var[...] = memory.store.variables[name].data
            counts.add(memory.store.variables["status"].data)
        times = time_attrs(compile_time, wall_time)
        f.attrs.update(times)
    if memory is not None:  # the attributes _define wrote, and the times
        memory.store.attrs = {**attrs, "n_chunks": lay.n_chunks, **times}
    missing = int(np.prod(lay.shape, dtype=np.int64)) - counts.total
    if missing:
        counts.codes[st.PENDING] = counts.codes.get(st.PENDING, 0) + missing
    return bad, dict(sorted(counts.codes.items()))


def _variables(lay: Layout) -> list[str]:
    """The variables a chunk fills."""
    return list(lay.outputs) + ["status"] + (["n_steps", "n_rhs"] if lay.integrated else [])


def _write_region(variables: dict, region: tuple, arrays: dict, shape: tuple[int, ...]) -> None:
    """One chunk's arrays (flat over its points) into ``region`` of the file's variables."""
    rshape = _region_shape(region, shape)
    for name, var in variables.items():
        values = arrays[name]
        var[region + (slice(None),) * (values.ndim - 1)] = values.reshape(rshape + values.shape[1:])


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
    """The dataset file of a run (with ``MemorySink``) written while its chunks are computed, in the
    writer thread: defined at the first chunk, each chunk written into its region after it is
    saved to the journal. It is the same temporary file the assembly writes (in the journal
    folder; renamed into place only when complete), so crash safety is unchanged: a kill leaves
    it half written in the journal folder, and the resumed run writes it anew from the journal.

    It is an optimisation only: the first write that fails (``_GuardedFile`` records it) or any
    other error discards it (closed, removed), and the assembly then writes the file from the
    start exactly as without it, meeting (and reporting) the same failure if it persists."""

    def __init__(self, path, scene: Scene, lay: Layout, attrs: dict):
        self.path = Path(path)
        self.scene, self.lay, self.attrs = scene, lay, attrs
        self.guard: _GuardedFile | None = None
        self.file: h5py.File | None = None
        self.variables: dict = {}
        self.written: set[int] = set()
        self.failed = False

    def _open(self) -> None:
        self.guard = _GuardedFile(self.path)
        names = _variables(self.lay)
        with NetCDFWriter(self.guard) as f:
            _define(f, self.scene, self.lay, self.attrs)
            cache = _early_cache(f.file, names)  # (from the storage chunks just made: no opening to read them)
        self.file = h5py.File(self.guard, "a", rdcc_nbytes=cache, rdcc_nslots=100_003, rdcc_w0=1.0)
        self.variables = {name: self.file[name] for name in names}

    def prepare(self, started=None) -> None:
        """Create and define the file before the first chunk arrives: the run calls it in the writer
        thread, idle while the first chunk is computed, so that the definition (``python
        benchmarks/duffing_breakdown.py`` times it) does not delay the first chunk's write and the second chunk's launch
        behind it. ``started``: an event set when
        the first chunk's kernel is about to run (waited for at most PREPARE_WAIT seconds), so that
        this Python work holds the GIL while the kernel has released it, not while the main
        thread prepares the launch. A failure discards the file, as in ``write``."""
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
                _write_region(self.variables, region, arrays, self.lay.shape)
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
            _remove(self.path)
            self.guard = None


class MemorySink:
    """A run's dataset in memory, defined as its file is (``memory_store``): the sink of the in-memory
    route (``run(output=None)``), and of a file run that returns its dataset loaded (beside the
    journal and the file). A chunk computed here is computed straight into its arrays (``views``:
    each variable's flat range of the chunk); ``save`` notes its wall and compile seconds in
    ``times`` (chunk index -> (wall, compile)) and copies only arrays computed elsewhere (a dask
    worker's, a chunk read back from the journal). ``assemble`` writes the file from it and gives it
    the file's attributes."""

    background = False  # nothing to write: the route saves its chunks in the computing thread

    def __init__(self, scene: Scene, lay: Layout, attrs: dict):
        self.store = memory_store(scene, lay, attrs)
        self.times: dict[int, tuple[float, float]] = {}
        n = int(np.prod(lay.shape, dtype=np.int64))
        self._flat = {}  # variable -> the array over the grid's flat points (a view, C order)
        for name in _variables(lay):
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
    """The dataset's time attributes: ``compile_time_s`` (JIT compilation, or loading the JIT
    cache, before the chunks), ``compute_time_s`` (the chunks: kernels and writes of the journal)
    and ``wall_time_s``, their sum (the run's time, as before they were stored apart)."""
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


READ_BLOCK = 2**18  # values per block when a variable is read or written in pieces (2 MiB of float64)


def _remove(path) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


class _GuardedFile:
    """A file for HDF5's ``fileobj`` driver that never reports a failed write to HDF5.

    Writes go to the disk with ``os.pwrite``. The first one that fails is kept in ``error``; from
    then on writes (and truncations) only go to an in-memory overlay that reads see, so HDF5 can
    finish and close its file as if nothing happened. The caller stops writing data once
    ``error`` is set, which bounds the overlay, then removes the file and reports the error."""

    def __init__(self, path):
        self.path = path
        self.fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o644)
        self.pos = 0
        self.error: OSError | None = None
        self.overlay: list[tuple[int, bytes]] = []  # (offset, data) written after the failure
        self.size: int | None = None  # the file's size as HDF5 sees it after the failure

    def seekable(self) -> bool:
        return True

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seek(self, offset: int, whence: int = 0) -> int:
        self.pos = offset if whence == 0 else self.pos + offset if whence == 1 else self._eof() + offset
        return self.pos

    def tell(self) -> int:
        return self.pos

    def _eof(self) -> int:
        real = os.fstat(self.fd).st_size
        if self.error is None:
            return real
        return max([real if self.size is None else self.size] + [o + len(d) for o, d in self.overlay])

    def readinto(self, buffer) -> int:
        view = memoryview(buffer).cast("B")
        n = len(view)
        data = os.pread(self.fd, n, self.pos)
        view[:len(data)] = data
        got = len(data)
        if self.error is not None:
            end = max(0, min(n, self._eof() - self.pos))
            view[got:end] = bytes(max(0, end - got))
            got = max(got, end)
            for offset, blob in self.overlay:  # later writes win
                lo, hi = max(offset, self.pos), min(offset + len(blob), self.pos + n)
                if lo < hi:
                    view[lo - self.pos:hi - self.pos] = blob[lo - offset:hi - offset]
        self.pos += got
        return got

    def read(self, n: int = -1) -> bytes:
        if n is None or n < 0:
            n = max(0, self._eof() - self.pos)
        buffer = bytearray(n)
        return bytes(buffer[:self.readinto(buffer)])

    def write(self, data) -> int:
        view = memoryview(data).cast("B")
        n = len(view)
        if self.error is None:
            done = 0
            try:
                while done < n:
                    done += os.pwrite(self.fd, view[done:], self.pos + done)
            except OSError as exc:
                self.error = exc
        if self.error is not None:
            self.overlay.append((self.pos, bytes(view)))
        self.pos += n
        return n

    def truncate(self, size: int | None = None) -> int:
        size = self.pos if size is None else size
        if self.error is None:
            try:
                os.ftruncate(self.fd, size)
                return size
            except OSError as exc:
                self.error = exc
        self.size = size
        self.overlay = [(o, d[:max(0, size - o)]) for o, d in self.overlay if o < size]
        return size

    def flush(self) -> None:
        pass

    def sync(self) -> None:
        try:
            os.fsync(self.fd)
        except OSError as exc:
            self.error = exc

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


def _scalar(value) -> float:
    """An attribute as a float (h5netcdf may store scalars as 1-element arrays)."""
    return float(np.ravel(value)[0])


def _region_shape(region: tuple, shape: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(len(range(*s.indices(n))) for s, n in zip(region, shape))


def _define(f: "NetCDFWriter | _MemoryFile", scene: Scene, lay: Layout, attrs: dict) -> None:
    f.dimensions = dict(zip(lay.dims, lay.shape))
    model = scene.model
    for axis in scene.axes:
        prm = model.param(axis.name)
        if prm.categorical:
            v = _string_variable(f, axis.name, (axis.name,), axis.array())
        else:  # written block by block: a range axis is never expanded at once
            v = f.create_variable(axis.name, (axis.name,), dtype="f8")
            for lo in range(0, axis.size, READ_BLOCK):
                hi = min(axis.size, lo + READ_BLOCK)
                v[lo:hi] = axis.array(lo, hi)
        _describe(v, prm.unit, prm.long_name, prm.symbol, prm.latex)
        v.attrs["spacing"] = axis.spacing
        if axis.spacing == "log":  # CF has no attribute for it: say it to a reader (docs: datasets)
            v.attrs["comment"] = cf.LOG_AXIS_COMMENT
    for name, value in scene.fixed.items():
        prm = model.param(name)
        if prm.categorical:
            v = _string_variable(f, name, (), np.array(value, dtype=object))
        else:
            v = f.create_variable(name, (), dtype="f8")
            v[()] = value
        _describe(v, prm.unit, prm.long_name, prm.symbol, prm.latex)
    for dims in lay.extra.values():
        for dim, values in dims:
            if dim.name not in f.dimensions:
                f.dimensions[dim.name] = len(values)
                v = f.create_variable(dim.name, (dim.name,), dtype="f8")
                v[:] = values
                _describe(v, dim.unit, dim.long_name, "")
    fixed_coords = " ".join(scene.fixed)
    chunks = _storage_chunks(lay.shape)
    for name in lay.outputs:
        out = model.output(name)
        extra = tuple(d.name for d, _ in lay.extra.get(name, ()))
        v = f.create_variable(name, lay.dims + extra, dtype="f8", fillvalue=np.nan,
                              chunks=_storage_chunks(lay.shape + tuple(len(x) for _, x in lay.extra.get(name, ()))))
        _describe(v, out.unit, out.long_name, out.symbol, out.latex)
        if out.integrated:
            v.attrs["integrated"] = 1
        if out.kind:
            v.attrs["mechsweep_kind"] = out.kind
        if fixed_coords:
            v.attrs["coordinates"] = fixed_coords
        v.attrs["ancillary_variables"] = "status"  # CF: the per-point status qualifies each value
    s = f.create_variable("status", lay.dims, dtype=st.DTYPE, fillvalue=st.PENDING, chunks=chunks,
                          **_compressed(lay.shape))
    del s.attrs["_FillValue"]  # keep int8 on reading (xarray would mask it to float)
    for k, val in st.cf_attrs(model.status_notes).items():
        s.attrs[k] = val
    if lay.integrated:
        for name, long_name in (("n_steps", "accepted integration steps"),
                                ("n_rhs", "right-hand-side evaluations")):
            c = f.create_variable(name, lay.dims, dtype="i8", fillvalue=0, chunks=chunks, **_compressed(lay.shape))
            del c.attrs["_FillValue"]
            _describe(c, "1", long_name, "")
    for k, val in attrs.items():
        f.attrs[k] = val
    f.attrs["n_chunks"] = lay.n_chunks


# ----------------------------------------------------------------------------- definition
# Attributes h5netcdf keeps for itself (a variable's attributes never use these names).
_NC_HIDDEN = frozenset(["REFERENCE_LIST", "CLASS", "DIMENSION_LIST", "NAME", "_Netcdf4Dimid", "_Netcdf4Coordinates",
                        "_nc3_strict", "_NCProperties"])


class _NetCDFAttrs:
    """A variable's (or the file's) attributes, stored as h5netcdf stores them: a non-string scalar
    as a one-element array (netCDF-4's convention), anything else as h5py stores it."""

    __slots__ = ("_attrs",)

    def __init__(self, attrs):
        self._attrs = attrs

    def __setitem__(self, key, value) -> None:
        if key in _NC_HIDDEN:
            raise AttributeError(f"cannot write attribute with reserved name {key!r}")
        dtype = value.dtype if hasattr(value, "dtype") else np.asarray(value).dtype
        if dtype == np.bool_:  # h5netcdf refuses it (not netCDF-4): so does this writer
            raise TypeError(f"attribute {key!r}: boolean values are not netCDF-4; store 0/1")
        if np.isscalar(value) and dtype.kind not in "SU":
            value = np.atleast_1d(value)
        self._attrs[key] = value

    def __delitem__(self, key) -> None:
        del self._attrs[key]


class _NetCDFVariable:
    __slots__ = ("ds", "attrs")

    def __init__(self, ds):
        self.ds = ds
        self.attrs = _NetCDFAttrs(ds.attrs)

    def __setitem__(self, key, value) -> None:
        self.ds[key] = value


def nc_properties() -> str:
    """The file's ``_NCProperties``: what wrote it, in netCDF-C's provenance format (``version=2``
    first, then ``key=value`` pairs separated by commas, ``\\``, ``=``, ``|`` and ``,`` escaped by a
    backslash): mechsweep through h5py on its HDF5 library. netCDF-C reads any keys there; h5netcdf
    writes its own name and version in the same place."""
    def escaped(text: str) -> str:
        return "".join("\\" + c if c in "\\=|," else c for c in text)

    from . import __version__

    pairs = (("mechsweep", __version__), ("h5py", h5py.__version__), ("hdf5", h5py.version.hdf5_version))
    return "version=2," + ",".join(f"{key}={escaped(value)}" for key, value in pairs)


class NetCDFWriter:
    """Defines a netCDF-4 file with h5py directly, as ``h5netcdf.File(target, "w")`` defines it for
    the calls ``_define`` makes (dimensions, each with its coordinate variable created next,
    variables with fixed sizes, attributes, ``del`` of an attribute): the same objects in the same
    creation order, the same dataset properties (shape, dtype, chunks, filters, fill value), the
    same attributes with their dtypes, shapes, values and order (netCDF-4's ``_Netcdf4Dimid`` and
    ``_Netcdf4Coordinates``), the same dimension-scale attachments. Only the provenance the file
    carries for netCDF-C (``_NCProperties``, :func:`nc_properties`) names mechsweep, h5py and HDF5,
    where h5netcdf names itself. tests/test_store_define.py walks a file of each shipped scene
    written both ways and compares all of it, and reads both with h5netcdf and with netCDF-C.
    Written with h5py because h5netcdf looks up the same h5py objects again and again while it defines
    a file (most of a small run's definition time: ``python benchmarks/duffing_breakdown.py``);
    this writes each once."""

    def __init__(self, target):
        self.file = h5py.File(target, "w", track_order=True)  # as h5netcdf opens a new file (h5py >= 3.7)
        self._dimensions: dict[str, int] = {}
        self._scales: dict = {}  # dimension -> its coordinate variable's dataset (the dimension scale)
        self.attrs = _NetCDFAttrs(self.file.attrs)

    @property
    def dimensions(self) -> dict:
        return self._dimensions

    @dimensions.setter
    def dimensions(self, value) -> None:
        for name, size in self._dimensions.items():
            if value.get(name, size) != size or name not in value:
                raise ValueError(f"cannot modify or drop the existing dimension {name!r}")
        self._dimensions.update(value)

    def create_variable(self, name, dims=(), dtype=None, fillvalue=None, chunks=None, **storage) -> _NetCDFVariable:
        dims = tuple(dims)
        shape = tuple(self._dimensions[d] for d in dims)
        chars = np.dtype(dtype) == np.dtype("S1") and len(dims) >= 1 and dims[-1] == name + STRLEN_SUFFIX
        coordinate = dims == (name,) or chars and dims == (name, name + STRLEN_SUFFIX)  # a string axis: 2-D scale
        if name in self._dimensions and not coordinate or 0 in shape or name in self.file:
            raise ValueError(f"variable {name!r} {dims}: not a layout this writer defines as h5netcdf does")
        if chars and dims[-1] not in self._scales:  # h5netcdf's placeholder of a dimension that is no variable
            self._placeholder(dims[-1])
        if fillvalue is not None:
            fillvalue = np.array(fillvalue).astype(dtype)
            if h5py.check_string_dtype(fillvalue.dtype) is not None:
                raise ValueError(f"variable {name!r}: a string fill value is not written by this writer")
        ds = self.file.create_dataset(name, shape, dtype=dtype, chunks=chunks, fillvalue=fillvalue, track_order=True,
                                      **storage)
        ids = {d: k for k, d in enumerate(self._dimensions)}  # netCDF dimension ids, in order of creation
        coords = np.array([ids[d] for d in dims], "int32")
        if coordinate:  # the dimension's scale (h5netcdf: the dimension's placeholder replaced by it)
            dimid = np.array(ids[name], np.int32)
            if dimid:  # id 0 is falsy: h5netcdf sets it again after _Netcdf4Coordinates, i.e. after it
                ds.attrs["_Netcdf4Dimid"] = dimid
            ds.make_scale(name)
            ds.attrs["_Netcdf4Coordinates"] = coords
            if not dimid:
                ds.attrs["_Netcdf4Dimid"] = dimid
            self._scales[name] = ds
        elif dims:
            for k, d in enumerate(dims):
                if d not in self._scales:
                    raise ValueError(f"variable {name!r}: dimension {d!r} has no coordinate variable yet")
                ds.dims[k].attach_scale(self._scales[d])
            ds.attrs["_Netcdf4Coordinates"] = coords
            ds.attrs["_Netcdf4Dimid"] = np.array(ids[dims[0]], np.int32)
        variable = _NetCDFVariable(ds)
        if fillvalue is not None:
            variable.attrs["_FillValue"] = ds.dtype.type(fillvalue)
        return variable

    def _placeholder(self, dim: str) -> None:
        """The dataset netCDF-4 keeps for a dimension without a coordinate variable (here: the
        characters of a string variable), as h5netcdf creates it when the dimension is defined."""
        n = self._dimensions[dim]
        ds = self.file.create_dataset(dim, (n,), dtype=">f4", track_order=True)
        ds.attrs["_Netcdf4Dimid"] = np.array(list(self._dimensions).index(dim), np.int32)
        ds.make_scale(b"This is a netCDF dimension but not a netCDF variable." + bytes(f"{n:10}", "ascii"))
        self._scales[dim] = ds

    def close(self) -> None:
        if self.file is None:
            return
        missing = [d for d in self._dimensions if d not in self._scales]
        try:
            if missing:  # (h5netcdf would leave a placeholder scale for it: not a layout _define makes)
                raise ValueError(f"dimension(s) {', '.join(missing)} without a coordinate variable")
            props = nc_properties()
            self.file.attrs["_NCProperties"] = np.array(props, dtype=h5py.string_dtype("ascii", len(props)))
        finally:
            self.file.close()
            self.file = None

    def __enter__(self) -> "NetCDFWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _compressed(shape: tuple[int, ...]) -> dict:
    """Status codes and step counts repeat a few values: gzip (level 1, fast) with byte shuffling
    shrinks them many times over. Float outputs are left raw: their mantissas do not compress."""
    return {"compression": "gzip", "compression_opts": 1, "shuffle": True} if _storage_chunks(shape) else {}


def _storage_chunks(shape: tuple[int, ...]):
    return True if shape and all(n > 0 for n in shape) else None


STRLEN_SUFFIX = "_strlen"  # the character dimension of a string variable: NAME_strlen


def _string_variable(f, name: str, dims: tuple[str, ...], values: np.ndarray):
    """A variable of strings (a categorical axis or fixed value). In a file: an array of characters
    over a dimension ``NAME_strlen`` with ``_Encoding = "utf-8"`` (CF's character arrays: CF-1.8 also
    allows netCDF-4 strings, but checkers and older netCDF tools do not read them); xarray decodes it
    to the strings, with the same dims. In memory (``_MemoryFile``): the strings themselves."""
    values = np.asarray(values, dtype=object)
    if isinstance(f, _MemoryFile):
        v = f.create_variable(name, dims, dtype=h5py.string_dtype())
        v[...] = values
        return v
    encoded = np.array([str(x).encode("utf-8") for x in values.ravel()], dtype=bytes)
    n = max(1, encoded.dtype.itemsize)
    strlen = name + STRLEN_SUFFIX
    f.dimensions[strlen] = n
    v = f.create_variable(name, dims + (strlen,), dtype="S1")
    v[...] = encoded.astype(f"S{n}").view("S1").reshape(values.shape + (n,))
    v.attrs["_Encoding"] = "utf-8"
    return v


def _describe(var, unit: str, long_name: str, symbol: str, latex: str = "") -> None:
    if unit and not _is_strings(var):  # a UDUNITS string; a measurement declared without one gets no units
        var.attrs["units"] = unit  # (CF: unknown), never ""; strings (categorical values) have none
    var.attrs["long_name"] = long_name
    if symbol:
        var.attrs["symbol"] = symbol
    if latex:  # the symbol in matplotlib mathtext: what figures label the variable with
        var.attrs["latex"] = latex


def _is_strings(var) -> bool:
    data = var.data if isinstance(var, _MemoryVariable) else var.ds if isinstance(var, _NetCDFVariable) else var
    return np.dtype(data.dtype).kind in "OSU"


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
RUN_ATTRS = ("scene_canonical", "model", "outputs")  # every dataset `mechsweep run` writes has them


def open_dataset(path: str | Path, *, allow_partial: bool = False, lazy: bool | None = False) -> xr.Dataset:
    """Open a dataset mechsweep wrote (``mechsweep run``, :func:`mechsweep.run`).

    Reading needs neither numba nor the models' kernels: it works wherever xarray and h5netcdf do.
    ``xarray.open_dataset(path, engine="h5netcdf")`` reads the same file; this function also
    checks that it is a mechsweep dataset and can open an unfinished run.

    Parameters
    ----------
    path : str or pathlib.Path
        The dataset's file.
    allow_partial : bool, optional
        Open an unfinished run (its missing chunks NaN, status ``pending``) when the finished file
        does not exist yet; that view is always loaded.
    lazy : bool or None, optional
        False (default): load it into memory (the file is closed again). True: read values only
        when they are used (as dask arrays, one per storage chunk, when dask is installed). None:
        load datasets up to ``LOAD_LIMIT_BYTES`` and open larger ones lazily.

    Returns
    -------
    xarray.Dataset
        The grid's dimensions and coordinates, the outputs, ``status`` (and ``n_steps``,
        ``n_rhs``), and the attributes the run wrote (the scene, solver settings, provenance).

    Raises
    ------
    FileNotFoundError
        No file at ``path`` (the message says when an unfinished run is there instead).
    StoreError
        The file is not a dataset mechsweep wrote (a folder, a device, an empty, text or damaged
        file, an HDF5 or netCDF file from elsewhere): the message says what it is not.
    """
    if "\0" in str(path):
        raise StoreError(f"dataset path {str(path)!r} contains a NUL character")
    path = Path(path)
    if not os.path.lexists(path):
        part = partial_path(path)
        if allow_partial and part.exists():
            return _open_partial(part)
        if part.exists():
            raise FileNotFoundError(
                f"{path} does not exist, but an unfinished run left {part}; complete it with "
                "`mechsweep run SCENE --resume`, or open it with allow_partial=True"
            )
        raise FileNotFoundError(f"{path} does not exist")
    check_dataset_file(path)
    if lazy is None:
        lazy = path.stat().st_size > LOAD_LIMIT_BYTES
    import xarray as xr  # here, not at the top: the command `mechsweep run` never needs it (0.3 s of CPU)

    try:
        if lazy:
            return current_names(xr.open_dataset(path, engine="h5netcdf", chunks={} if _have_dask() else None))
        with xr.open_dataset(path, engine="h5netcdf") as ds:
            return current_names(ds.load())
    except (OSError, ValueError, KeyError, TypeError, RuntimeError) as exc:
        raise StoreError(f"{path} is not a readable mechsweep dataset: {_first_line(exc)}") from None


def current_names(ds: xr.Dataset) -> xr.Dataset:
    """A dataset written before one of its model's parameters was renamed, with the current name:
    a variable named by a former name the declaration keeps (``Param.aliases``, e.g. the
    slider-crank's ``lambda``, now ``lam``: a Python keyword cannot be used in ``ds.sel``). Only
    a file with a name that is no identifier, or a keyword, looks the model up."""
    import keyword

    odd = [n for n in ds.variables if isinstance(n, str) and (keyword.iskeyword(n) or not n.isidentifier())]
    model = ds.attrs.get("model")
    if not odd or not isinstance(model, str):
        return ds
    from .models import MODELS  # (imports the built-in models: only for such an old file)

    spec = MODELS.get(model)
    renames = {a: n for a, n in (spec.aliases() if spec is not None else {}).items()
               if a in ds.variables and n not in ds.variables}
    if not renames:
        return ds
    ds = ds.rename(renames)
    for key in ("along", "continue_in"):  # a boundaries dataset names its axes
        if ds.attrs.get(key) in renames:
            ds.attrs[key] = renames[ds.attrs[key]]
    return ds


def check_dataset_file(path: str | Path) -> None:
    """Raise StoreError unless ``path`` is a regular HDF5 file that mechsweep wrote: a run's
    dataset (its scene, model and outputs attributes and a status variable) or a benchmark's
    (a ``mechsweep_kind`` attribute). Reads the file's header only, never blocks on a pipe."""
    path = Path(path)
    what = f"{path} is not a mechsweep dataset"
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise FileNotFoundError(f"{path} does not exist (a broken link)") from None
    except OSError as exc:
        raise StoreError(f"{what}: it cannot be read ({why_os_error(exc.errno, exc.strerror)})") from None
    if not stat.S_ISREG(mode):
        raise StoreError(f"{what}: it is {file_kind(mode)}, not a file")
    try:  # O_NONBLOCK: a path that became a pipe since the stat above does not block the open
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise StoreError(f"{what}: it cannot be read ({why_os_error(exc.errno, exc.strerror)})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise StoreError(f"{what}: it is {file_kind(info.st_mode)}, not a file")
        if held_for_writing(fd):
            raise FileBusy(path, lock_holder(info))
        head = os.read(fd, 8)
    except OSError as exc:
        raise StoreError(f"{what}: it cannot be read ({why_os_error(exc.errno, exc.strerror)})") from None
    finally:
        os.close(fd)
    if not head:
        raise StoreError(f"{what}: it is an empty file")
    if head != HDF5_SIGNATURE:
        kind = ("a netCDF-3 file" if head.startswith(b"CDF") else
                "a text file" if _looks_like_text(path) else "a file of another format")
        raise StoreError(f"{what}: it is {kind}, not HDF5 (it starts with {head[:8]!r})")
    try:
        with h5py.File(path, "r") as f:
            attrs = set(f.attrs)
            names = set(f.keys())
            outputs = _text(f.attrs.get("outputs", "")).split() if "outputs" in attrs else []
    except Exception as exc:  # h5py raises OSError, and others for damaged internals
        if is_lock_error(exc):  # another process took it for writing since the probe above
            raise FileBusy(path, lock_holder(path)) from None
        if isinstance(exc, OSError) and exc.errno in _SYSTEM_ERRORS:  # the system's refusal, not the file's bytes
            raise StoreError(f"{what}: it cannot be read ({why_os_error(exc.errno, exc.strerror)})") from None
        raise StoreError(f"{what}: it is an HDF5 file that cannot be read, damaged or truncated "
                         f"({_first_line(exc)})") from None
    if "mechsweep_kind" in attrs:
        return
    missing = [a for a in RUN_ATTRS if a not in attrs]
    if missing:
        raise StoreError(f"{what}: it is an HDF5/netCDF file without the attribute(s) {', '.join(missing)} "
                         "that `mechsweep run` writes")
    absent = [v for v in ["status", *outputs] if v not in names]
    if absent:
        raise StoreError(f"{what}: it lacks the variable(s) {', '.join(absent)} that a run writes")


# errnos with which the system refuses a read (the file's bytes are not at fault)
_SYSTEM_ERRORS = frozenset(getattr(errno, n) for n in ("EACCES", "EPERM", "ENOENT", "EMFILE", "ENFILE", "ENOMEM",
                                                        "EIO", "EISDIR", "ENOTDIR", "ELOOP") if hasattr(errno, n))


def is_lock_error(exc: BaseException) -> bool:
    """Whether ``exc`` (of h5py opening a file) says another process holds the file's HDF5 lock."""
    return isinstance(exc, BlockingIOError) or (isinstance(exc, OSError) and "unable to lock file" in str(exc))


def held_for_writing(fd: int) -> bool:
    """Whether another process holds an exclusive lock on the open file ``fd``: HDF5 takes one
    (flock) on a file it opens for writing. Probed with a shared lock that is released at once;
    False where file locks are not available (no fcntl: Windows)."""
    try:
        import fcntl
    except ImportError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:  # e.g. a file system without locks
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_UN)
    except OSError:
        pass
    return False


def lock_holder(file) -> int | None:
    """The process id holding a lock on ``file`` (a path or an os.stat_result), from /proc/locks
    (Linux); None when it cannot be told."""
    try:
        info = file if isinstance(file, os.stat_result) else os.stat(file)
        with open("/proc/locks") as f:
            lines = f.read(1 << 20).splitlines()
    except OSError:
        return None
    key = f"{os.major(info.st_dev):02x}:{os.minor(info.st_dev):02x}:{info.st_ino}"
    for line in lines:  # "1: FLOCK  ADVISORY  WRITE 19010 fe:00:1490980 0 EOF"
        parts = line.split()
        if key in parts and parts.index(key) >= 1:
            try:
                return int(parts[parts.index(key) - 1])
            except ValueError:
                return None
    return None


def is_run_dataset(ds: xr.Dataset) -> bool:
    """A dataset of `mechsweep run` (not a benchmark's)."""
    return all(a in ds.attrs for a in RUN_ATTRS) and "status" in ds


def _text(value) -> str:
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    return value if isinstance(value, str) else str(value)


def file_kind(mode: int) -> str:
    """What a file system entry of this st_mode is, for a message."""
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISREG, "a regular file")):
        if test(mode):
            return name
    return "not a regular file"


def _looks_like_text(path: Path) -> bool:
    with open(path, "rb") as f:
        block = f.read(4096)
    try:
        block.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(block) - 4:  # not just a character cut at the block's end
            return False
    return b"\0" not in block


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return (text[0][:200] if text else type(exc).__name__)


def _open_partial(part: Path) -> xr.Dataset:
    """An unfinished run as a Dataset, assembled in memory from its journal."""
    check_journal_files(part)
    try:
        return _assemble_partial(part)
    except (StoreError, FileNotFoundError):
        raise
    except Exception as exc:  # a journal someone edited or damaged: say so, no traceback
        raise StoreError(f"{part} is not a readable unfinished run ({type(exc).__name__}: {_first_line(exc)}); "
                         "start it over with --restart") from None


def check_journal_files(part: Path, contents: bool = True) -> None:
    """Raise StoreError if the journal folder ``part`` (when it exists) or, with ``contents``, what
    it holds is not of the kind a run makes: a folder, a file run.json that a run wrote (verified:
    its entries and, from journal format 3 on, its checksum), a folder chunks of files. A pipe or a
    device there would block or be replaced. Without ``contents`` (--restart, which discards what
    the folder holds) only the folder itself is checked. The message names what is damaged and
    that --restart discards the journal."""
    from .journal import RESTART

    if not os.path.lexists(part):
        return
    mode = os.lstat(part).st_mode
    if stat.S_ISREG(mode):  # an older version's one-file journal: Journal.read says so
        return
    if not stat.S_ISDIR(mode):
        kind = "a symbolic link" if stat.S_ISLNK(mode) else file_kind(mode)
        raise StoreError(f"{part} (the journal of unfinished runs) is {kind}, not a folder mechsweep made; "
                         "move it away")
    if not contents:
        return
    try:
        _check_journal_kinds(part)
    except OSError as exc:  # e.g. a folder that cannot be listed (permission denied)
        raise StoreError(f"{exc.filename or part} cannot be read ({exc.strerror}); the journal {part} cannot be "
                         f"resumed: {RESTART}") from None
    _check_run_json(part / "run.json")


def _check_journal_kinds(part: Path) -> None:
    from .journal import RESTART

    for name, want, test in (("run.json", "a file", stat.S_ISREG), ("chunks", "a folder", stat.S_ISDIR)):
        entry = part / name
        if os.path.lexists(entry) and not test(mode := os.lstat(entry).st_mode):
            kind = "a symbolic link" if stat.S_ISLNK(mode) else file_kind(mode)
            raise StoreError(f"{entry} is {kind}, not {want} as a run writes it; {RESTART}")
    for e in os.scandir(part):  # e.g. assembly.h5: a pipe there would block the run's last step
        if e.name not in ("run.json", "chunks") and not e.is_file(follow_symlinks=False):
            raise StoreError(f"{e.path} is {_lkind(e.path)}, not a file a run writes; {RESTART}")
    chunks = part / "chunks"
    n_chunk_files = 0
    if chunks.is_dir():
        for e in os.scandir(chunks):
            if not e.is_file(follow_symlinks=False):
                raise StoreError(f"{e.path} is not a chunk file a run writes (it is {_lkind(e.path)}): remove that "
                                 f"entry (--resume then computes its chunk again), or {RESTART}")
            n_chunk_files += e.name.endswith(".npz")
    has_meta = os.path.lexists(part / "run.json")
    if n_chunk_files and not has_meta:  # a run writes run.json before any chunk
        raise StoreError(f"{part / 'run.json'} is missing, and {n_chunk_files} chunk file(s) are in {chunks}: the "
                         f"journal is damaged; {RESTART}")
    if has_meta and not os.path.lexists(chunks):  # a run makes chunks/ before run.json
        raise StoreError(f"{chunks} is missing, and {part / 'run.json'} is there: the journal is damaged; {RESTART}")


def _lkind(path) -> str:
    mode = os.lstat(path).st_mode
    return "a symbolic link" if stat.S_ISLNK(mode) else file_kind(mode)




def _check_run_json(path: Path) -> None:
    """Refuse a journal's run.json that is not what a run writes (edited, damaged, foreign)."""
    import json

    from .journal import RESTART, meta_problem

    if not path.is_file():
        return
    try:
        meta = json.loads(path.read_bytes())
    except ValueError as exc:
        raise StoreError(f"{path} is unreadable ({_first_line(exc)}); {RESTART}") from None
    except OSError as exc:
        raise StoreError(f"{path} cannot be read ({exc.strerror}); {RESTART}") from None
    if (why := meta_problem(meta)) is not None:
        raise StoreError(f"{path} {why}; {RESTART}")


def _assemble_partial(part: Path) -> xr.Dataset:
    import io

    journal = Journal.read(part)
    if journal.empty:
        raise FileNotFoundError(f"{part} holds no finished chunk yet")
    attrs = journal.meta.get("attrs") if isinstance(journal.meta.get("attrs"), dict) else {}
    from .scene import load_scene_text

    scene = load_scene_text(journal.meta["scene"], label=str(part / "run.json"),
                            base=attrs.get("scene_folder") or None)
    chunks = plan_chunks(scene.shape, journal.meta["chunk_target"])
    lay = layout(scene, len(chunks))
    buffer = io.BytesIO()
    bad_chunks, _ = assemble(journal, scene, lay, chunks, buffer, journal.meta["attrs"])
    for bad in bad_chunks:
        print(f"mechsweep: {bad}; shown as pending, a --resume computes it again", file=sys.stderr)
    buffer.seek(0)
    import xarray as xr

    with xr.open_dataset(buffer, engine="h5netcdf") as ds:
        return ds.load()


def _have_dask() -> bool:
    try:
        import dask.array  # noqa: F401
    except ImportError:
        return False
    return True


# ----------------------------------------------------------------------------- in memory
class _MemoryVariable:
    """A variable of ``_MemoryFile``: a numpy array and its attributes."""

    def __init__(self, dims: tuple[str, ...], shape: tuple[int, ...], dtype, fillvalue):
        self.dims = tuple(dims)
        string = h5py.check_string_dtype(np.dtype(dtype)) is not None if dtype is not None else False
        self.data = np.empty(shape, dtype=object if string else dtype)
        if fillvalue is not None:
            self.data[...] = fillvalue
        elif not string:
            self.data[...] = 0
        self.attrs: dict = {} if fillvalue is None else {"_FillValue": fillvalue}

    def __setitem__(self, key, value) -> None:
        self.data[key] = value


class _MemoryFile:
    """Stands in for the h5netcdf file ``_define`` writes, so that the in-memory route describes its
    variables with the very code that describes a file's (names, dims, units, attributes)."""

    def __init__(self):
        self.dimensions: dict[str, int] = {}
        self.variables: dict[str, _MemoryVariable] = {}
        self.attrs: dict = {}

    def create_variable(self, name, dims, dtype=None, fillvalue=None, chunks=None, **_storage):
        v = _MemoryVariable(dims, tuple(self.dimensions[d] for d in dims), dtype, fillvalue)
        self.variables[name] = v
        return v

    def dataset(self) -> xr.Dataset:
        """The Dataset xarray would decode from the file (CF: ``coordinates`` attributes name
        coordinates, ``_FillValue`` goes to the encoding, dimension variables are indexes)."""
        coords = set(self.dimensions)
        for v in self.variables.values():
            coords.update(str(v.attrs.get("coordinates", "")).split())
        import xarray as xr

        data_vars, coord_vars = {}, {}
        for name, v in self.variables.items():
            attrs = {k: a for k, a in v.attrs.items() if k not in ("_FillValue", "coordinates")}
            var = xr.Variable(v.dims, v.data, attrs)
            (coord_vars if name in coords else data_vars)[name] = var
        return xr.Dataset(data_vars, coords=coord_vars, attrs=dict(self.attrs))


def memory_store(scene: Scene, lay: Layout, attrs: dict) -> _MemoryFile:
    """An in-memory store of a run's dataset, defined as ``assemble`` defines the file: outputs NaN,
    status PENDING until ``write_memory`` fills their regions."""
    f = _MemoryFile()
    _define(f, scene, lay, attrs)
    return f


def write_memory(f: _MemoryFile, region: tuple, arrays: dict, shape: tuple[int, ...]) -> None:
    """Write one chunk's arrays (flat over its points) into ``region`` of the grid, as ``_assemble``
    writes a chunk into the file."""
    rshape = _region_shape(region, shape)
    for name, values in arrays.items():
        f.variables[name][region + (slice(None),) * (values.ndim - 1)] = values.reshape(rshape + values.shape[1:])
