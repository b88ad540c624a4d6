"""The plan of a run (plan.py): made once, before any chunk, from the scene and mechsweep's own cache
record; stored with the run; pickled as it is to a dask worker; the route of its kernels chosen by
one rule from the run's size and the record, never from the rows of a call."""
import numpy as np
import pytest

from mechsweep import plan as planning, runner
from mechsweep.grid import ParameterMatrix
from mechsweep.model import compile as mc
from mechsweep.scene import load_scene


@pytest.mark.parametrize("facts,points,route", [
    ({"forced": None, "from_points": 100, "recorded": False}, 99, "point"),  # small, nothing compiled
    ({"forced": None, "from_points": 100, "recorded": False}, 100, "lanes"),  # large enough to repay the compile
    ({"forced": None, "from_points": 100, "recorded": True}, 1, "lanes"),  # compiled already: nothing to repay
    ({"forced": False, "from_points": 100, "recorded": True}, 10**9, "point"),  # the engine's override
    ({"forced": True, "from_points": 100, "recorded": False}, 1, "lanes"),
])
def test_one_rule_chooses_the_route(facts, points, route):
    assert planning.choose_route(points, facts) == route
    assert planning.choose_route(points, facts, True) == "lanes"  # the scene's [execution] lanes first
    assert planning.choose_route(points, facts, False) == "point"


def test_the_record_of_a_compiled_lane_kernel_is_mechsweeps_own(tmp_path, monkeypatch):
    """A file next to the kernel's module in the cache folder, written once the kernel has run; a later
    process reads it (no numba internals); a record of another CPU does not count."""
    monkeypatch.setattr(mc._jit, "cache_dir", str(tmp_path))
    monkeypatch.setattr(mc, "_RECORDED", set())
    name = "mechsweep_gen_test_record"
    assert not mc.lanes_recorded(name)
    mc.record_compiled(name)
    assert mc.lanes_recorded(name)
    assert [p.name for p in (tmp_path / "models").iterdir()] == [f"{name}.{mc._cpu_tag()}.compiled"]
    monkeypatch.setattr(mc, "_RECORDED", set())  # as in a new process: the file says it
    assert mc.lanes_recorded(name)
    monkeypatch.setattr(mc, "_CPU", ["another-cpu"])
    assert not mc.lanes_recorded(name)


def test_the_runs_size_chooses_the_route_and_the_record_keeps_it(small_duffing, monkeypatch):
    """The run's size, not the rows of a call, chooses the lanes: the warm-up's single row compiles the lane
    kernel of a run of LANES_FROM_POINTS points; once compiled, its record makes a small run take the
    lanes too (the same values either way)."""
    scene = load_scene(small_duffing)
    monkeypatch.setattr(mc, "USE_LANES", None)
    monkeypatch.setattr(mc, "_RECORDED", set())
    monkeypatch.setattr(mc, "lanes_recorded", lambda name: name in mc._RECORDED)  # as with an empty cache folder
    small = planning.make_plan(scene)
    assert small.routes == {"kernel": "point"}
    monkeypatch.setattr(mc, "LANES_FROM_POINTS", scene.n_points)
    large = planning.make_plan(scene)
    assert large.routes == {"kernel": "lanes"}
    monkeypatch.setattr(mc, "_KERNELS", {})
    monkeypatch.setattr(mc, "_BY_OBJECTS", {})
    runner.evaluate_rows(scene, ParameterMatrix(scene)(0, 1))  # the warm-up's one row
    (lane,) = [name for name, k in mc._KERNELS.items() if isinstance(k, mc._Recorded)]
    assert lane in mc._RECORDED
    monkeypatch.setattr(mc, "LANES_FROM_POINTS", 10**12)
    again = planning.make_plan(scene)
    assert again.routes == {"kernel": "lanes"}  # recorded: nothing left to repay
    P = ParameterMatrix(scene)(0, scene.n_points)
    lanes = runner.evaluate_rows(scene, P)
    monkeypatch.setattr(mc, "USE_LANES", False)  # one point at a time
    for a, b in zip(lanes[1:], runner.evaluate_rows(scene, P)[1:]):
        assert np.array_equal(a, b)
