"""HDF5 datasets: netCDF4-flavoured HDF5 written with h5netcdf, read back by
``xarray.open_dataset(path, engine="h5netcdf")``.

A run saves its finished chunks in a journal (``journal.py``); ``assemble`` writes the dataset
from it, chunk by chunk (memory bounded by one chunk), into a temporary file that replaces the
output by one rename. A finished file is therefore never half overwritten.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import h5netcdf
import h5py
import numpy as np
import xarray as xr

from . import status as st
from .errors import StoreError  # noqa: F401  (raised by the runner, part of this module's API)
from .grid import plan_chunks
from .journal import Journal, partial_path  # noqa: F401  (partial_path: part of this module's API)
from .scene import Scene, load_scene_text

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


def assemble(journal: Journal, scene: Scene, lay: Layout, chunks, target, attrs: dict) -> dict[int, int]:
    """Write the dataset of a journal to ``target`` (a path or a file object): every variable
    defined, each journaled chunk written into its region, one chunk in memory at a time.
    Chunks not in the journal keep the fill values (NaN, status PENDING). The attribute
    ``wall_time_s`` is the sum of the journaled chunks' wall times. Returns the number of
    points per status code, counted as the chunks pass (PENDING for chunks not in the journal)."""
    with h5netcdf.File(target, "w") as f:
        _define(f, scene, lay, attrs)
    with h5py.File(target, "a") as f:
        names = list(lay.outputs) + ["status"] + (["n_steps", "n_rhs"] if lay.integrated else [])
        variables = {name: f[name] for name in names}
        wall_time = 0.0
        counts = Counts()
        for i in np.flatnonzero(journal.done_chunks()):
            chunk = chunks[int(i)]
            arrays, seconds = journal.read_chunk(int(i))
            wall_time += seconds
            counts.add(arrays["status"])
            shape = _region_shape(chunk.region, lay.shape)
            for name, var in variables.items():
                values = arrays[name]
                var[chunk.region + (slice(None),) * (values.ndim - 1)] = values.reshape(shape + values.shape[1:])
        f.attrs["wall_time_s"] = wall_time
    missing = int(np.prod(lay.shape, dtype=np.int64)) - counts.total
    if missing:
        counts.codes[st.PENDING] = counts.codes.get(st.PENDING, 0) + missing
    return dict(sorted(counts.codes.items()))


class Counts:
    """Points per status code, added up array by array."""

    def __init__(self):
        self.codes: dict[int, int] = {}
        self.total = 0

    def add(self, status: np.ndarray) -> None:
        codes, n = np.unique(np.asarray(status), return_counts=True)
        for c, k in zip(codes.tolist(), n.tolist()):
            self.codes[c] = self.codes.get(c, 0) + k
        self.total += int(np.asarray(status).size)


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


def _scalar(value) -> float:
    """An attribute as a float (h5netcdf may store scalars as 1-element arrays)."""
    return float(np.ravel(value)[0])


def _region_shape(region: tuple, shape: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(len(range(*s.indices(n))) for s, n in zip(region, shape))


def _define(f: h5netcdf.File, scene: Scene, lay: Layout, attrs: dict) -> None:
    f.dimensions = dict(zip(lay.dims, lay.shape))
    model = scene.model
    for axis in scene.axes:
        prm = model.param(axis.name)
        if prm.categorical:
            v = f.create_variable(axis.name, (axis.name,), dtype=h5py.string_dtype())
            v[:] = axis.array()
        else:  # written block by block: a range axis is never expanded at once
            v = f.create_variable(axis.name, (axis.name,), dtype="f8")
            for lo in range(0, axis.size, READ_BLOCK):
                hi = min(axis.size, lo + READ_BLOCK)
                v[lo:hi] = axis.array(lo, hi)
        _describe(v, prm.unit, prm.long_name, prm.symbol)
        v.attrs["spacing"] = axis.spacing
    for name, value in scene.fixed.items():
        prm = model.param(name)
        if prm.categorical:
            v = f.create_variable(name, (), dtype=h5py.string_dtype())
            v[()] = value
        else:
            v = f.create_variable(name, (), dtype="f8")
            v[()] = value
        _describe(v, prm.unit, prm.long_name, prm.symbol)
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
        _describe(v, out.unit, out.long_name, out.symbol)
        if out.integrated:
            v.attrs["integrated"] = 1
        if fixed_coords:
            v.attrs["coordinates"] = fixed_coords
    s = f.create_variable("status", lay.dims, dtype=st.DTYPE, fillvalue=st.PENDING, chunks=chunks,
                          **_compressed(lay.shape))
    del s.attrs["_FillValue"]  # keep int8 on reading (xarray would mask it to float)
    for k, val in st.cf_attrs().items():
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


def _compressed(shape: tuple[int, ...]) -> dict:
    """Status codes and step counts repeat a few values: gzip (level 1, fast) with byte shuffling
    shrinks them many times over. Float outputs are left raw: their mantissas do not compress."""
    return {"compression": "gzip", "compression_opts": 1, "shuffle": True} if _storage_chunks(shape) else {}


def _storage_chunks(shape: tuple[int, ...]):
    return True if shape and all(n > 0 for n in shape) else None


def _describe(var, unit: str, long_name: str, symbol: str) -> None:
    var.attrs["units"] = unit
    var.attrs["long_name"] = long_name
    if symbol:
        var.attrs["symbol"] = symbol


def open_dataset(path: str | Path, *, allow_partial: bool = False, lazy: bool | None = False) -> xr.Dataset:
    """Open a mechsweep dataset.

    ``lazy=False`` loads it into memory (the file is closed again); ``lazy=True`` reads values
    only when they are used (as dask arrays, one per storage chunk, when dask is installed);
    ``lazy=None`` loads datasets up to LOAD_LIMIT_BYTES and opens larger ones lazily.
    ``allow_partial`` opens an unfinished run (its missing chunks NaN, status pending) when the
    finished file does not exist yet; that view is always loaded.
    """
    path = Path(path)
    if not path.exists():
        part = partial_path(path)
        if allow_partial and part.exists():
            return _open_partial(part)
        if part.exists():
            raise FileNotFoundError(
                f"{path} does not exist, but an unfinished run left {part}; complete it with "
                "`mechsweep run SCENE --resume`, or open it with allow_partial=True"
            )
        raise FileNotFoundError(f"{path} does not exist")
    if lazy is None:
        lazy = path.stat().st_size > LOAD_LIMIT_BYTES
    if lazy:
        return xr.open_dataset(path, engine="h5netcdf", chunks={} if _have_dask() else None)
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        return ds.load()


def _open_partial(part: Path) -> xr.Dataset:
    """An unfinished run as a Dataset, assembled in memory from its journal."""
    import io

    journal = Journal.read(part)
    if journal.empty:
        raise FileNotFoundError(f"{part} holds no finished chunk yet")
    scene = load_scene_text(journal.meta["scene"], label=str(part / "run.json"))
    chunks = plan_chunks(scene.shape, journal.meta["chunk_target"])
    lay = layout(scene, len(chunks))
    buffer = io.BytesIO()
    assemble(journal, scene, lay, chunks, buffer, journal.meta["attrs"])
    buffer.seek(0)
    with xr.open_dataset(buffer, engine="h5netcdf") as ds:
        return ds.load()


def _have_dask() -> bool:
    try:
        import dask.array  # noqa: F401
    except ImportError:
        return False
    return True
