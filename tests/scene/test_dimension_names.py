"""Every dimension of a dataset is a Python identifier, so that ``ds.sel(name=...)`` works: the
slider-crank's crank-to-rod ratio is ``lam`` (``lambda`` is a keyword). A scene may still say
``lambda`` (the declaration keeps it as a former name), and a dataset written with a ``lambda``
axis opens, is described and drawn with ``lam``."""
from __future__ import annotations

import keyword
import tomllib

import numpy as np
import pytest
import xarray as xr

import mechsweep
from mechsweep.cli import main
from mechsweep.scene import SceneError, load_scene

from tests.conftest import SWEEPS

SLIDER = tomllib.loads((SWEEPS / "slidercrank_partial.toml").read_text())


def small(axes):
    data = {**SLIDER, "axes": axes}
    data.pop("storage", None)
    return data


def test_every_shipped_scene_has_identifier_dimensions():
    for path in sorted(SWEEPS.glob("*.toml")):
        scene = load_scene(path)
        for name in [a.name for a in scene.axes] + list(scene.fixed):
            assert name.isidentifier() and not keyword.iskeyword(name), (path.name, name)


def test_the_slider_crank_ratio_is_lam_and_lambda_still_works_in_a_scene(tmp_path):
    new = load_scene(small({"k": [0.0, 0.5], "lam": [0.2, 0.4]}))
    old = load_scene(small({"k": [0.0, 0.5], "lambda": [0.2, 0.4]}))
    assert [a.name for a in new.axes] == [a.name for a in old.axes] == ["k", "lam"]
    assert new.canonical() == old.canonical()
    fixed = load_scene(small({"k": [0.0, 0.5]}) | {"fixed": {**SLIDER["fixed"], "lambda": 0.3}})
    assert fixed.fixed["lam"] == 0.3
    with pytest.raises(SceneError, match="lambda is the former name of lam, which is given too"):
        load_scene(small({"k": [0.0, 0.5], "lam": [0.2], "lambda": [0.4]}))
    ds = mechsweep.run(old, output=tmp_path / "s.h5", progress=False)
    assert "lam" in ds.dims and "lambda" not in ds.variables
    assert float(ds.sel(lam=0.4)["F_max"].sel(k=0.5)) == float(ds["F_max"].values[1, 1])
    # a stored form written with the former name (a journal or dataset of an older version) is this scene
    assert new.same_as(new.canonical().replace('"lam"', '"lambda"'))


def test_a_dataset_written_with_lambda_opens_describes_and_plots_with_lam(tmp_path, capsys):
    mechsweep.run(small({"k": {"start": 0.0, "stop": 1.0, "num": 5}, "lam": [0.2, 0.4]}),
                  output=tmp_path / "new.h5", progress=False)
    with xr.open_dataset(tmp_path / "new.h5", engine="h5netcdf") as ds:
        old = ds.load().rename({"lam": "lambda"})  # the layout of a file written before the rename
    old.to_netcdf(tmp_path / "old.h5", engine="h5netcdf")
    with xr.open_dataset(tmp_path / "old.h5", engine="h5netcdf") as raw:
        assert "lambda" in raw.dims
    ds = mechsweep.open_dataset(tmp_path / "old.h5")
    assert "lam" in ds.dims and "lambda" not in ds.variables
    np.testing.assert_array_equal(ds.sel(lam=0.2)["F_max"].values, old.sel({"lambda": 0.2})["F_max"].values)
    assert main(["info", str(tmp_path / "old.h5")]) == 0
    assert "lam " in capsys.readouterr().out
    assert main(["plot", str(tmp_path / "old.h5"), "-o", str(tmp_path / "old.png")]) == 0
    assert list(tmp_path.glob("old*.png"))


def test_the_balancing_api_takes_the_former_name_too():
    from mechsweep import balancing

    fixed = {k: v for k, v in SLIDER["fixed"].items()}
    a, _ = balancing.evaluate("slidercrank_balancing", ["F_max"], k=0.5, lam=0.3, **fixed)
    b, _ = balancing.evaluate("slidercrank_balancing", ["F_max"], k=0.5, **{"lambda": 0.3}, **fixed)
    assert a["F_max"] == b["F_max"]
    with pytest.raises(ValueError, match="former name of lam"):
        balancing.evaluate("slidercrank_balancing", ["F_max"], k=0.5, lam=0.3, **{"lambda": 0.3}, **fixed)
