"""Engine features models rely on: model settings, cross-parameter checks, outputs with extra dims."""
import numpy as np
import pytest

import mechsweep
from mechsweep import models, status as st
from mechsweep.model.spec import ExtraDim, ModelSpec, Output, Param, Setting
from mechsweep.scene import SceneError, load_scene


def _evaluate(P, wanted, solver, out, status, n_steps, n_rhs):
    t = np.linspace(0.0, 1.0, solver.settings["samples"])
    if "ramp" in wanted:
        out["ramp"][:] = P[:, 0:1] * t[None, :]
    if "total" in wanted:
        out["total"][:] = np.where(np.isnan(P[:, 1]), P[:, 0], P[:, 0] + P[:, 1])
    status[P[:, 0] < 0] = st.INFEASIBLE
    n_steps += 1


def _check(given):
    if "k" in given and "k_alt" in given:
        return ["fixed.k_alt: give k or k_alt, not both"]
    if "k" not in given and "k_alt" not in given:
        return ["fixed.k: give k or k_alt"]
    return []


TOY = ModelSpec(
    name="toy", description="test model", source="tests",
    params=(Param("k", "k", "N", "gain", required=False, default=np.nan),
            Param("k_alt", "k'", "N", "other gain", required=False, default=np.nan)),
    outputs=(Output("ramp", "r", "N", "ramp", integrated=True,
                    extra_dims=(ExtraDim("sample", "s", "sample time",
                                         lambda s: np.linspace(0.0, 1.0, s["samples"])),)),
             Output("total", "T", "N", "total")),
    evaluate=_evaluate,
    settings=(Setting("samples", 5, "1", "samples per ramp", 2, 1000, integer=True),),
    check=_check,
)


@pytest.fixture
def toy(monkeypatch):
    monkeypatch.setitem(models.MODELS, "toy", TOY)
    monkeypatch.setattr(mechsweep.scene.sections, "MODELS", models.MODELS)


def scene(**solver):
    return {"scene": {"name": "toy", "model": "toy", "outputs": ["ramp", "total"]},
            "axes": {"k": [1.0, 2.0, -1.0]}, "solver": solver}


def test_extra_dims_are_stored_with_their_coordinate(toy, in_tmp):
    ds = mechsweep.run(scene(samples=4), output="data/runs/toy.h5")
    assert ds["ramp"].dims == ("k", "sample")
    np.testing.assert_allclose(ds["sample"].values, np.linspace(0, 1, 4))
    assert ds["sample"].attrs["units"] == "s"
    np.testing.assert_allclose(ds["ramp"].sel(k=2.0).values, 2.0 * np.linspace(0, 1, 4))
    assert ds["status"].values.tolist() == [st.OK, st.OK, st.INFEASIBLE]
    assert ds.attrs["solver_samples"] == 4


def test_model_settings_are_validated(toy):
    with pytest.raises(SceneError, match=r"solver.samples: 1 is outside the allowed range \[2, 1000\]"):
        load_scene(scene(samples=1))
    with pytest.raises(SceneError, match="solver.sampels.*did you mean 'samples'"):
        load_scene(scene(sampels=3))
    assert load_scene(scene()).solver.settings["samples"] == 5


def test_cross_parameter_check(toy):
    both = scene()
    both["fixed"] = {"k_alt": 1.0}
    with pytest.raises(SceneError, match="give k or k_alt, not both"):
        load_scene(both)
    neither = scene()
    neither["axes"] = {}
    neither["fixed"] = {}
    with pytest.raises(SceneError, match="give k or k_alt"):
        load_scene(neither)


def test_duffing_horizon_setting_reaches_the_dataset(in_tmp, small_duffing):
    small_duffing["solver"]["t_max_periods"] = 50.0
    ds = mechsweep.run(small_duffing, output="data/runs/h.h5")
    assert ds.attrs["solver_t_max_periods"] == 50.0


def test_chunks_shrink_with_extra_dimensions(toy):
    from mechsweep.grid import CHUNK_VALUES, default_chunk_target

    big = scene(samples=1000)
    big["axes"] = {"k": {"start": 1.0, "stop": 2.0, "num": 100_000}}
    target = default_chunk_target(load_scene(big))
    assert target * 1000 <= CHUNK_VALUES  # a chunk's curves stay within the memory budget
    small = scene(samples=2)
    small["axes"] = {"k": {"start": 1.0, "stop": 2.0, "num": 100_000}}
    # two values per point: the cap does not bind, the usual n / 20 (here 5000) does
    assert default_chunk_target(load_scene(small)) == 100_000 // 20 > target
