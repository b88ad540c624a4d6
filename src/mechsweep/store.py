"""HDF5 datasets: a sweep is written chunk by chunk to ``<path>.partial`` and renamed to
``<path>`` only when every chunk is in. A finished file is therefore never half
overwritten, and an interrupted run leaves a partial file that ``--resume`` completes.

The file is netCDF4-flavoured HDF5 written with h5netcdf and read back by
``xarray.open_dataset(path, engine="h5netcdf")``. Which chunks are done is kept in
the group ``/mechsweep_progress`` (not part of the Dataset xarray shows).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import h5netcdf
import h5py
import numpy as np
import xarray as xr

from . import status as st
from .errors import InputError
from .scene import Scene

PROGRESS = "mechsweep_progress"


class StoreError(InputError):
    """A problem with the output file (exists, locked, from another scene, unwritable)."""


def partial_path(path: str | Path) -> Path:
    return Path(str(path) + ".partial")


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


class PartialFile:
    """An open ``.partial`` file being filled chunk by chunk.

    The file is defined with h5netcdf (netCDF dimensions and attributes) and then filled
    through plain h5py datasets, looked up once (h5netcdf's per-write lookups cost more
    than the write itself).
    """

    def __init__(self, handle: h5py.File, path: Path, lay: Layout):
        self.f = handle
        self.path = path
        self.layout = lay
        names = list(lay.outputs) + ["status"] + (["n_steps", "n_rhs"] if lay.integrated else [])
        self.vars = {name: handle[name] for name in names}
        self.done = handle[PROGRESS]["chunk_done"]

    # -- creation and reopening ------------------------------------------------
    @classmethod
    def create(cls, path: Path, scene: Scene, lay: Layout, attrs: dict) -> "PartialFile":
        if path.exists():
            _open(path, "a").close()  # refuse (locked) before truncating another run's file
        try:
            with h5netcdf.File(path, "w") as f:
                _define(f, scene, lay, attrs)
        except BaseException:
            path.unlink(missing_ok=True)
            raise
        return cls(_open(path, "a"), path, lay)

    @classmethod
    def reopen(cls, path: Path, scene: Scene, lay: Layout) -> "PartialFile":
        f = _open(path, "a")
        try:
            stored = f.attrs.get("scene_canonical")
            if stored != scene.canonical():
                raise StoreError(
                    f"{path} was started from a different scene (model, outputs, axes, fixed values or "
                    "solver settings differ); resume it with the scene it was started with, or start "
                    "over with --restart"
                )
            if int(_scalar(f.attrs.get("n_chunks", -1))) != lay.n_chunks:
                raise StoreError(f"{path} was cut into {_scalar(f.attrs.get('n_chunks'))} chunks, this run into "
                                 f"{lay.n_chunks}; use the same storage.chunk_size, or --restart")
        except BaseException:
            f.close()
            raise
        return cls(f, path, lay)

    # -- progress ------------------------------------------------------------------
    def done_chunks(self) -> np.ndarray:
        return np.asarray(self.done[:], dtype=bool)

    def write_chunk(self, chunk, columns: dict[str, np.ndarray], status, n_steps=None, n_rhs=None) -> None:
        shape = _region_shape(chunk.region, self.layout.shape)
        for name, values in columns.items():
            n_extra = values.ndim - 1
            self.vars[name][chunk.region + (slice(None),) * n_extra] = values.reshape(shape + values.shape[1:])
        self.vars["status"][chunk.region] = status.reshape(shape)
        if self.layout.integrated:
            self.vars["n_steps"][chunk.region] = n_steps.reshape(shape)
            self.vars["n_rhs"][chunk.region] = n_rhs.reshape(shape)
        # mark done only after the data: a crash in between recomputes the chunk
        self.f.flush()
        self.done[chunk.index] = 1
        self.f.flush()

    def add_wall_time(self, seconds: float) -> None:
        self.f.attrs["wall_time_s"] = _scalar(self.f.attrs.get("wall_time_s", 0.0)) + float(seconds)
        self.f.flush()

    def set_attrs(self, **attrs) -> None:
        for k, v in attrs.items():
            self.f.attrs[k] = v

    def close(self) -> None:
        self.f.close()

    def finish(self, final: Path) -> None:
        """Close and move into place atomically (same directory, os.replace)."""
        self.f.close()
        os.replace(self.path, final)


def _open(path: Path, mode: str) -> h5py.File:
    try:
        return h5py.File(path, mode)
    except BlockingIOError:
        raise StoreError(f"{path} is being written by another mechsweep run (the file is locked); "
                         "wait for it to finish or stop it first") from None
    except OSError as exc:
        msg = str(exc)
        if "lock" in msg.lower():
            raise StoreError(f"{path} is being written by another mechsweep run (the file is locked); "
                             "wait for it to finish or stop it first") from None
        raise StoreError(f"cannot open {path} for writing: {msg}") from None


def discard_partial(path: Path) -> None:
    """Delete an unfinished run's file, unless another run is writing it right now."""
    if path.exists():
        _open(path, "a").close()  # raises StoreError when another process holds the file
        path.unlink()


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
            v[:] = np.array(axis.values, dtype=object)
        else:
            v = f.create_variable(axis.name, (axis.name,), dtype="f8")
            v[:] = np.array(axis.values)
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
    s = f.create_variable("status", lay.dims, dtype=st.DTYPE, fillvalue=st.PENDING, chunks=chunks)
    del s.attrs["_FillValue"]  # keep int8 on reading (xarray would mask it to float)
    for k, val in st.cf_attrs().items():
        s.attrs[k] = val
    if lay.integrated:
        for name, long_name in (("n_steps", "accepted integration steps"),
                                ("n_rhs", "right-hand-side evaluations")):
            c = f.create_variable(name, lay.dims, dtype="i8", fillvalue=0, chunks=chunks)
            del c.attrs["_FillValue"]
            _describe(c, "1", long_name, "")
    g = f.create_group(PROGRESS)
    g.dimensions = {"chunk": lay.n_chunks}
    d = g.create_variable("chunk_done", ("chunk",), dtype="i1", fillvalue=0)
    del d.attrs["_FillValue"]
    for k, val in attrs.items():
        f.attrs[k] = val
    f.attrs["n_chunks"] = lay.n_chunks


def _storage_chunks(shape: tuple[int, ...]):
    return True if shape and all(n > 0 for n in shape) else None


def _describe(var, unit: str, long_name: str, symbol: str) -> None:
    var.attrs["units"] = unit
    var.attrs["long_name"] = long_name
    if symbol:
        var.attrs["symbol"] = symbol


def open_dataset(path: str | Path, *, allow_partial: bool = False) -> xr.Dataset:
    """Load a mechsweep dataset into memory (the file is closed again)."""
    path = Path(path)
    if not path.exists():
        part = partial_path(path)
        if allow_partial and part.exists():
            path = part
        elif part.exists():
            raise FileNotFoundError(
                f"{path} does not exist, but an unfinished run left {part}; complete it with "
                "`mechsweep run SCENE --resume`, or open it with allow_partial=True"
            )
        else:
            raise FileNotFoundError(f"{path} does not exist")
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        return ds.load()
