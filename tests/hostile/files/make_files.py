"""Regenerate the foreign and damaged files of this folder: `python make_files.py` (here).

Each is something a user may hand to `mechsweep info` / `plot` / `run -o` by mistake; none is a
dataset mechsweep wrote, and every command must say so (exit 2), never crash or change it.
"""
from pathlib import Path

import h5py
import numpy as np
import xarray as xr

HERE = Path(__file__).resolve().parent
SIGNATURE = b"\x89HDF\r\n\x1a\n"


def run_like(path: Path, **drop) -> None:
    """A small dataset with the attributes and variables of a run (written without a run)."""
    ds = xr.Dataset({"period_exact": ("A", np.array([6.2, 6.1, 5.9])), "status": ("A", np.zeros(3, np.int8))},
                    coords={"A": [0.1, 0.5, 1.0]},
                    attrs={"title": "t", "model": "duffing", "outputs": "period_exact", "scene_canonical": "{}",
                           "scene": ""})
    for k in drop.get("attrs", ()):
        del ds.attrs[k]
    ds = ds.drop_vars(drop.get("variables", ()))
    ds.to_netcdf(path, engine="h5netcdf")


def main() -> None:
    rng = np.random.default_rng(12)
    (HERE / "text.h5").write_text("A = 0.1\nthis is a note, not a dataset\n")
    (HERE / "empty.h5").write_bytes(b"")
    (HERE / "random_bytes.h5").write_bytes(rng.integers(0, 256, 4096, dtype=np.uint8).tobytes())
    (HERE / "hdf5_signature_then_garbage.h5").write_bytes(
        SIGNATURE + rng.integers(0, 256, 4096, dtype=np.uint8).tobytes())
    (HERE / "png_image.h5").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(200))
    xr.Dataset({"x": ("a", np.arange(3.0))}).to_netcdf(HERE / "netcdf3_classic.nc", engine="scipy")
    xr.Dataset({"temperature": ("time", np.arange(5.0))}, attrs={"title": "weather"}).to_netcdf(
        HERE / "foreign_netcdf4.nc", engine="h5netcdf")
    with h5py.File(HERE / "plain_hdf5_groups.h5", "w") as f:
        f.create_group("g").create_dataset("d", data=np.arange(4))
    run_like(HERE / "run_without_status.h5", variables=["status"])
    run_like(HERE / "run_without_scene_canonical.h5", attrs=["scene_canonical"])
    xr.Dataset({"period_exact": ("x", np.array(["a", "b"])), "status": (("y", "z"), np.zeros((2, 2)))},
               attrs={"model": "nosuch", "outputs": "period_exact", "scene_canonical": "{}", "scene": "zz"}).to_netcdf(
        HERE / "lookalike_strings.h5", engine="h5netcdf")  # a run's attributes, not its layout
    run_like(HERE / "_whole.h5")
    data = (HERE / "_whole.h5").read_bytes()
    (HERE / "truncated_dataset.h5").write_bytes(data[: len(data) // 2])
    (HERE / "_whole.h5").unlink()


if __name__ == "__main__":
    main()
