"""`[execution] lanes` in a scene: the public switch of the kernels' route where SIMD lanes apply
("auto", "always", "never"; before it, only the internal mechsweep.engine.kernels.USE_LANES). The
results are bitwise the same by either route, so the key is validated but not part of the scene's
identity (a run resumes whatever it says)."""
import sys
from pathlib import Path

import numpy as np
import pytest

import mechsweep
from mechsweep.cli import main
from mechsweep.engine import kernels as mc
from mechsweep.execution.plan import choose_route, make_plan
from mechsweep.scene import SceneError, load_scene

# the Duffing kernels tests/engine/test_model_lanes.py compiles (lanes and one point): nothing new to compile
SCENE = {"scene": {"name": "lanes", "model": "duffing", "outputs": ["period", "period_exact", "period_error"]},
         "axes": {"A": {"start": 0.05, "stop": 2.0, "num": 7}, "mu": {"start": -0.5, "stop": 100.0, "num": 6}},
         "fixed": {"omega": 1.0}}


def _lane_kernels():
    """The kernels' binding modules loaded in this process that integrate in lanes (as test_model_lanes)."""
    return {name for name in mc._KERNELS if "rhs_lanes" in Path(sys.modules[name].__file__).read_text()}


def _run(lanes, monkeypatch):
    monkeypatch.setattr(mc, "_KERNELS", {})  # every kernel fetched anew (from the disk cache): those used are listed
    monkeypatch.setattr(mc, "_BY_OBJECTS", {})
    ds = mechsweep.run({**SCENE, "execution": {"lanes": lanes}}, output=None)
    return ds, _lane_kernels()


def test_lanes_always_and_never_give_bitwise_the_same_dataset(monkeypatch):
    monkeypatch.setattr(mc, "USE_LANES", None)
    always, used_always = _run("always", monkeypatch)
    never, used_never = _run("never", monkeypatch)
    assert used_always and not used_never  # the key chose the route: a 42-point run is far below LANES_FROM_POINTS
    assert set(always.data_vars) == set(never.data_vars) == {"period", "period_exact", "period_error", "status",
                                                             "n_steps", "n_rhs"}
    for name in always.data_vars:
        assert np.array_equal(always[name].values, never[name].values, equal_nan=True), name
    assert (always.status == 0).sum() > 20  # points that integrated, not only statuses
    auto, _ = _run("auto", monkeypatch)
    for name in always.data_vars:
        assert np.array_equal(auto[name].values, never[name].values, equal_nan=True), name


def test_the_scene_key_decides_before_the_module_switch(monkeypatch):
    """USE_LANES (the benches' and tests' switch) only decides when the scene says "auto"."""
    monkeypatch.setattr(mc, "USE_LANES", True)
    _, used = _run("never", monkeypatch)
    assert not used
    # the run's plan (plan.choose_route), for every kernel family: the sampled trajectories' route too
    large = {"forced": True, "from_points": 1, "recorded": True}  # everything says lanes but the scene
    assert choose_route(10**9, large, load_scene({**SCENE, "execution": {"lanes": "never"}}).execution.use_lanes()) \
        == "point"
    small = {"forced": False, "from_points": 10**9, "recorded": False}
    assert choose_route(0, small, load_scene({**SCENE, "execution": {"lanes": "always"}}).execution.use_lanes()) \
        == "lanes"
    assert choose_route(10, large, load_scene(SCENE).execution.use_lanes()) == "lanes"  # "auto": the module switch
    assert make_plan(load_scene({**SCENE, "execution": {"lanes": "never"}})).routes == {"kernel": "point"}


@pytest.mark.parametrize("value", ["yes", True, 1, "Always", ["always"]])
def test_a_bad_lanes_value_is_refused_naming_the_key_and_the_choices(value):
    with pytest.raises(SceneError) as err:
        load_scene({**SCENE, "execution": {"lanes": value}})
    text = str(err.value)
    assert "execution.lanes" in text and "'auto', 'always', 'never'" in text, text


def test_lanes_is_not_part_of_the_scenes_identity_and_is_checked_by_the_cli(tmp_path, capsys):
    a = load_scene({**SCENE, "execution": {"lanes": "always"}})
    b = load_scene(SCENE)
    assert a.execution.lanes == "always" and b.execution.lanes == "auto"
    assert a.canonical() == b.canonical()
    bad = tmp_path / "bad.toml"
    bad.write_text('[scene]\nname = "x"\nmodel = "duffing"\noutputs = ["period_exact"]\n'
                   '[axes]\nA = [0.1, 0.2]\n[fixed]\nmu = 1.0\nomega = 1.0\n[execution]\nlanes = "sometimes"\n')
    assert main(["check", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "execution.lanes" in err and "'sometimes'" in err, err
