"""Writing a dataset: what goes into the file (``Layout``), its definition (``define``: dimensions,
coordinates, variables and attributes, the same code for a file and for a dataset in memory), the
netCDF-4 layout written with h5py (``NetCDFWriter``) and the file object that keeps a failed write
away from HDF5 (``GuardedFile``)."""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import h5py
import numpy as np

from .. import cf
from .. import status as st

if TYPE_CHECKING:  # not imported at run time: writing a dataset (`mechsweep run`) needs no xarray
    import xarray as xr

    from ..scene import Scene


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


def chunk_variables(lay: Layout) -> list[str]:
    """The variables a chunk fills."""
    return list(lay.outputs) + ["status"] + (["n_steps", "n_rhs"] if lay.integrated else [])


def write_region(variables: dict, region: tuple, arrays: dict, shape: tuple[int, ...]) -> None:
    """One chunk's arrays (flat over its points) into ``region`` of the file's variables."""
    rshape = _region_shape(region, shape)
    for name, var in variables.items():
        values = arrays[name]
        var[region + (slice(None),) * (values.ndim - 1)] = values.reshape(rshape + values.shape[1:])


READ_BLOCK = 2**18  # values per block when a variable is read or written in pieces (2 MiB of float64)


def remove_file(path) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


class GuardedFile:
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


def _region_shape(region: tuple, shape: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(len(range(*s.indices(n))) for s, n in zip(region, shape))


def define(f: "NetCDFWriter | _MemoryFile", scene: Scene, lay: Layout, attrs: dict) -> None:
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

    from .. import __version__

    pairs = (("mechsweep", __version__), ("h5py", h5py.__version__), ("hdf5", h5py.version.hdf5_version))
    return "version=2," + ",".join(f"{key}={escaped(value)}" for key, value in pairs)


class NetCDFWriter:
    """Defines a netCDF-4 file with h5py directly, as ``h5netcdf.File(target, "w")`` defines it for
    the calls ``define`` makes: the same objects in the same order, with the same properties,
    attributes and dimension scales; only ``_NCProperties`` (:func:`nc_properties`) names mechsweep,
    h5py and HDF5 where h5netcdf names itself (tests/store/test_store_define.py compares both ways
    for each shipped scene, and reads both with h5netcdf and netCDF-C). Why: h5netcdf looks up the
    same h5py objects again and again while it defines a file (most of a small run's definition
    time, ``python benchmarks/duffing_breakdown.py``); this writes each once."""

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
            if missing:  # (h5netcdf would leave a placeholder scale for it: not a layout define makes)
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
    """Stands in for the h5netcdf file ``define`` writes, so that the in-memory route describes its
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
    define(f, scene, lay, attrs)
    return f


def write_memory(f: _MemoryFile, region: tuple, arrays: dict, shape: tuple[int, ...]) -> None:
    """Write one chunk's arrays into ``region`` of the grid, as ``write_region`` writes the file's."""
    write_region({name: f.variables[name] for name in arrays}, region, arrays, shape)
