"""HDF5 datasets: netCDF4-flavoured HDF5 written with h5netcdf, read back by
``xarray.open_dataset(path, engine="h5netcdf")``.

A run saves its finished chunks in a journal (``journal.py``); ``assemble`` writes the dataset
from it, chunk by chunk (memory bounded by one chunk), into a temporary file that replaces the
output by one rename. A finished file is therefore never half overwritten.
"""
from __future__ import annotations

import os
import stat
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


def assemble(journal: Journal, scene: Scene, lay: Layout, chunks: list, target, attrs: dict) -> None:
    """Write the dataset of a journal to ``target`` (a path or a file object): every variable
    defined, each journaled chunk written into its region, one chunk in memory at a time.
    Chunks not in the journal keep the fill values (NaN, status PENDING). The attribute
    ``wall_time_s`` is the sum of the journaled chunks' wall times."""
    with h5netcdf.File(target, "w") as f:
        _define(f, scene, lay, attrs)
    with h5py.File(target, "a") as f:
        names = list(lay.outputs) + ["status"] + (["n_steps", "n_rhs"] if lay.integrated else [])
        variables = {name: f[name] for name in names}
        wall_time = 0.0
        for i in np.flatnonzero(journal.done_chunks()):
            chunk = chunks[int(i)]
            arrays, seconds = journal.read_chunk(int(i))
            wall_time += seconds
            shape = _region_shape(chunk.region, lay.shape)
            for name, var in variables.items():
                values = arrays[name]
                var[chunk.region + (slice(None),) * (values.ndim - 1)] = values.reshape(shape + values.shape[1:])
        f.attrs["wall_time_s"] = wall_time


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


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
RUN_ATTRS = ("scene_canonical", "model", "outputs")  # every dataset `mechsweep run` writes has them


def open_dataset(path: str | Path, *, allow_partial: bool = False, lazy: bool | None = False) -> xr.Dataset:
    """Open a mechsweep dataset.

    ``lazy=False`` loads it into memory (the file is closed again); ``lazy=True`` reads values
    only when they are used (as dask arrays, one per storage chunk, when dask is installed);
    ``lazy=None`` loads datasets up to LOAD_LIMIT_BYTES and opens larger ones lazily.
    ``allow_partial`` opens an unfinished run (its missing chunks NaN, status pending) when the
    finished file does not exist yet; that view is always loaded.

    Anything that is not a dataset mechsweep wrote (a folder, a device, an empty, text or damaged
    file, an HDF5 or netCDF file from elsewhere) raises StoreError saying what the file is not.
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
    try:
        if lazy:
            return xr.open_dataset(path, engine="h5netcdf", chunks={} if _have_dask() else None)
        with xr.open_dataset(path, engine="h5netcdf") as ds:
            return ds.load()
    except (OSError, ValueError, KeyError, TypeError, RuntimeError) as exc:
        raise StoreError(f"{path} is not a readable mechsweep dataset: {_first_line(exc)}") from None


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
        raise StoreError(f"{what}: it cannot be read ({exc.strerror})") from None
    if not stat.S_ISREG(mode):
        raise StoreError(f"{what}: it is {file_kind(mode)}, not a file")
    try:
        with open(path, "rb") as f:
            head = f.read(8)
    except OSError as exc:
        raise StoreError(f"{what}: it cannot be read ({exc.strerror})") from None
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
    it holds is not of the kind a run makes: a folder, a file run.json, a folder chunks of files.
    A pipe or a device there would block or be replaced."""
    if not os.path.lexists(part):
        return
    if part.is_file():  # an older version's one-file journal: Journal.read says so
        return
    if not part.is_dir():
        raise StoreError(f"{part} (the journal of unfinished runs) is {file_kind(part.stat().st_mode)}, "
                         "not a folder mechsweep made; move it away")
    for name, want, test in (("run.json", "a file", stat.S_ISREG), ("chunks", "a folder", stat.S_ISDIR)):
        entry = part / name
        if os.path.lexists(entry) and not test(entry.stat().st_mode):
            raise StoreError(f"{entry} is {file_kind(entry.stat().st_mode)}, not {want} as a run writes it; "
                             "start over with --restart")
    for e in os.scandir(part):  # e.g. assembly.h5: a pipe there would block the run's last step
        if e.name not in ("run.json", "chunks") and not e.is_file(follow_symlinks=False):
            raise StoreError(f"{e.path} is {file_kind(os.lstat(e.path).st_mode)}, not a file a run writes; "
                             "start over with --restart")
    _check_run_json(part / "run.json")
    chunks = part / "chunks"
    if chunks.is_dir():
        for e in os.scandir(chunks):
            if not e.is_file(follow_symlinks=False):
                raise StoreError(f"{e.path} is not a chunk file a run writes; start over with --restart")


RUN_JSON_KEYS = {"scene_canonical": str, "scene": str, "chunk_target": int, "n_chunks": int, "attrs": dict}


def _check_run_json(path: Path) -> None:
    """Refuse a journal's run.json that is not what a run writes (edited, damaged, foreign)."""
    import json

    from .journal import FORMAT

    if not path.is_file():
        return
    try:
        meta = json.loads(path.read_bytes())
    except ValueError as exc:
        raise StoreError(f"{path} is unreadable ({_first_line(exc)}); start over with --restart") from None
    if not isinstance(meta, dict):
        raise StoreError(f"{path} is not a run's journal (a JSON {type(meta).__name__}, not an object); "
                         "start over with --restart")
    if meta.get("format") != FORMAT:
        return  # another version's journal: Journal.read says so
    bad = [k for k, kind in RUN_JSON_KEYS.items() if not isinstance(meta.get(k), kind) or isinstance(meta.get(k), bool)]
    if bad or meta["n_chunks"] < 1 or meta["chunk_target"] < 1:
        raise StoreError(f"{path} is damaged (entries {', '.join(bad) or 'n_chunks, chunk_target'} missing or of the "
                         "wrong kind); start over with --restart")


def _assemble_partial(part: Path) -> xr.Dataset:
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
