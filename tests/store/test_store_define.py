"""store.write.NetCDFWriter defines a run's file as h5netcdf does: every object, property and attribute the
same (walked with h5py) but the provenance stamp ``_NCProperties``, which says truthfully that
mechsweep wrote the file through h5py; xarray reads identical Datasets with its h5netcdf and netcdf4
(netCDF-C) engines. Cheap: definitions only, no kernel."""
from __future__ import annotations

import io
import math
import tomllib

import h5netcdf
import h5py
import numpy as np
import pytest
import xarray as xr

import mechsweep
from mechsweep.bench.duffing import grid_scene
from mechsweep.execution.plan import make_plan
from mechsweep.execution.provenance import provenance
from mechsweep.scene import load_scene
from mechsweep.store.write import NetCDFWriter, define as _define, layout, nc_properties

from tests.conftest import SMALL_DUFFING, SWEEPS



def _shrunk(path):
    """A shipped scene with each range axis cut to 3 values (the layout is the same; the test is cheaper)."""
    spec = tomllib.loads(path.read_text())
    for axis in spec.get("axes", {}).values():
        if isinstance(axis, dict) and axis.get("num", 0) > 3:
            axis["num"] = 3
    spec["scene"]["name"] = path.stem
    model = spec["scene"]["model"]
    if ".py:" in model:  # a model file beside the scene
        spec["scene"]["model"] = str(path.parent / model)
    return spec


SCENES = [_shrunk(p) for p in sorted(SWEEPS.glob("*.toml"))] + [SMALL_DUFFING, grid_scene(2000, 1e-10, 1e-12)]


def _value(f, key, value):
    """An attribute's value, comparable: references (dimension scales) by the names they point to."""
    if key == "DIMENSION_LIST":
        return [[f[ref].name for ref in row] for row in value]
    if key == "REFERENCE_LIST":
        return [(f[ref].name, int(k)) for ref, k in value]
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes() if value.dtype != object else value.tolist())
    if isinstance(value, float) and math.isnan(value):
        return "nan"
    return (type(value).__name__, value)


def _attrs(f, obj):
    """Name, stored type (HDF5's, with string details), shape and value of each attribute, in order."""
    out = []
    for key in obj.attrs:
        aid = obj.attrs.get_id(key)
        out.append((key, aid.dtype.str, h5py.check_string_dtype(aid.dtype), aid.get_type().get_class(), aid.shape,
                    _value(f, key, obj.attrs[key])))
    return out


def walk(source) -> list:
    """Everything of a file that a reader can see, in the file's own order."""
    out = []
    with h5py.File(source, "r") as f:
        fcpl = f.id.get_create_plist()
        root = f["/"].id.get_create_plist()
        out.append(("file", f.libver, f.userblock_size, fcpl.get_sizes(), fcpl.get_version(),
                    fcpl.get_file_space_strategy(), fcpl.get_attr_phase_change(), fcpl.get_obj_track_times(),
                    root.get_link_creation_order(), root.get_attr_creation_order(), root.get_attr_phase_change(),
                    list(f.keys()), _attrs(f, f)))

        def visit(name, obj):
            if not isinstance(obj, h5py.Dataset):
                out.append((name, "group", _attrs(f, obj)))
                return
            d = obj.id.get_create_plist()
            fill = obj.fillvalue
            data = obj[()] if obj.ndim <= 1 else None  # (the grid's variables hold their fill values)
            out.append((name, obj.shape, obj.maxshape, obj.dtype.str, h5py.check_string_dtype(obj.dtype),
                        obj.id.get_type().get_class(), obj.chunks, obj.compression, obj.compression_opts,
                        obj.shuffle, obj.fletcher32, obj.scaleoffset,
                        "nan" if isinstance(fill, float) and math.isnan(fill) else repr(fill),
                        d.get_fill_time(), d.get_alloc_time(), d.get_layout(), d.get_attr_creation_order(),
                        d.get_attr_phase_change(), d.get_obj_track_times(),
                        d.get_nfilters(), [d.get_filter(k) for k in range(d.get_nfilters())],
                        obj.is_scale, [[s.name for s in dim.values()] for dim in obj.dims],
                        [dim.label for dim in obj.dims], _attrs(f, obj),
                        None if data is None else np.asarray(data).tobytes() if obj.dtype != object else np.asarray(data).tolist()))

        f.visititems(visit)
    return out


def _define_both(spec):
    scene = load_scene(spec)
    plan = make_plan(scene)
    lay, attrs = layout(scene, len(plan.chunks)), provenance(plan)
    theirs, ours = io.BytesIO(), io.BytesIO()
    with h5netcdf.File(theirs, "w") as f:
        _define(f, scene, lay, attrs)
    with NetCDFWriter(ours) as f:
        _define(f, scene, lay, attrs)
    return theirs, ours


# The h5netcdf release whose files NetCDFWriter was written to match object for object. Another
# release may lay its files out otherwise (attribute order, hidden attributes): then only what a
# reader gets is compared (xarray's Datasets and encodings, below), not the HDF5 objects.
MATCHED_H5NETCDF = (1, 8)


def _stamp(walked):
    """The walk without the value of the file's _NCProperties (h5netcdf's names h5netcdf, ours mechsweep;
    its length is the string type's), and that attribute's kind: the same in both files."""
    head, *rest = walked
    attrs = head[-1]
    (k,) = [k for k, a in enumerate(attrs) if a[0] == "_NCProperties"]
    key, dtype, string, cls, shape, value = attrs[k]
    kind = (k, key, dtype[:2], string.encoding, string.length is not None, cls, shape)
    text = value[-1].decode("ascii") if isinstance(value[-1], bytes) else value[-1]
    return [head[:-1] + ([*attrs[:k], *attrs[k + 1:]],), *rest], kind, text


@pytest.mark.parametrize("spec", SCENES, ids=lambda s: s["scene"]["name"])
def test_the_file_is_the_one_h5netcdf_writes_but_says_who_wrote_it(spec):
    theirs, ours = _define_both(spec)
    theirs.seek(0)
    ours.seek(0)
    a, their_kind, their_text = _stamp(walk(theirs))
    b, our_kind, our_text = _stamp(walk(ours))
    assert their_text.startswith("version=2,h5netcdf=")
    assert our_text == nc_properties() == (f"version=2,mechsweep={mechsweep.__version__},h5py={h5py.__version__},"
                                           f"hdf5={h5py.version.hdf5_version}")
    assert our_kind == their_kind  # a scalar fixed-length ASCII string, where h5netcdf puts it
    if tuple(int(x) for x in h5netcdf.__version__.split(".")[:2]) == MATCHED_H5NETCDF:
        assert len(a) == len(b)
        for x, y in zip(a, b):
            assert x == y
    theirs.seek(0)
    ours.seek(0)
    with xr.open_dataset(theirs, engine="h5netcdf") as x, xr.open_dataset(ours, engine="h5netcdf") as y:
        assert x.load().identical(y.load())
        def encoding(ds):  # (but "source": which BytesIO it was read from; repr: NaN == NaN)
            return {k: {e: repr(w) for e, w in v.encoding.items() if e != "source"} for k, v in ds.variables.items()}

        assert encoding(x) == encoding(y)


@pytest.mark.parametrize("spec", SCENES, ids=lambda s: s["scene"]["name"])
def test_netcdf_c_reads_the_file_as_h5netcdf_does(spec, tmp_path):
    """netCDF-C (netCDF4-python, xarray's netcdf4 engine) takes the file for a netCDF-4 file and reads
    the Dataset h5netcdf reads; the stamp is in netCDF-C's provenance format (version=2 first, then
    key=value pairs: netCDF-C ignores a stamp it cannot parse, so this is checked here)."""
    netCDF4 = pytest.importorskip("netCDF4")
    _, ours = _define_both(spec)
    path = tmp_path / "defined.nc"
    path.write_bytes(ours.getvalue())
    with netCDF4.Dataset(path) as nc:
        assert (nc.data_model, nc.disk_format) == ("NETCDF4", "HDF5")
        stamp = nc.getncattr("_NCProperties")
    version, *pairs = stamp.split(",")
    assert version == "version=2" and all(len(p.split("=")) == 2 and all(p.split("=")) for p in pairs), stamp
    assert [p.split("=")[0] for p in pairs] == ["mechsweep", "h5py", "hdf5"]
    with xr.open_dataset(path, engine="h5netcdf") as x, xr.open_dataset(path, engine="netcdf4") as y:
        assert x.load().identical(y.load())


def test_the_walk_sees_a_difference():
    """The comparison above is not blind: one attribute out of order, or one fill value, is seen."""
    theirs, _ = _define_both(SMALL_DUFFING)
    theirs.seek(0)
    before = walk(theirs)
    with h5py.File(theirs, "r+") as f:
        f["mu"].attrs["_Netcdf4Dimid"] = f["mu"].attrs["_Netcdf4Dimid"]  # re-created: moves to the end
    theirs.seek(0)
    assert walk(theirs) != before
