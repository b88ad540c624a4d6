"""The plan of a run (plan.py): made once, before any chunk, from the scene and mechsweep's own cache
record; stored with the run; pickled as it is to a dask worker; the route of its kernels chosen by
one rule from the run's size and the record, never from the rows of a call."""
import json
import pickle

import numpy as np
import pytest

import mechsweep
from mechsweep.execution import execute, plan as planning
from mechsweep.store.journal import Journal, partial_path
from mechsweep.engine import kernels as mc
from mechsweep.scene import load_scene


@pytest.mark.parametrize("facts,points,route", [
    ({"forced": None, "from_points": 100, "recorded": False}, 99, "point"),  # small, nothing compiled
    ({"forced": None, "from_points": 100, "recorded": False}, 100, "lanes"),  # large enough to repay the compile
    ({"forced": None, "from_points": 100, "recorded": True}, 1, "lanes"),  # compiled already: nothing to repay
    ({"forced": False, "from_points": 100, "recorded": True}, 10**9, "point"),  # the engine's override
    ({"forced": True, "from_points": 100, "recorded": False}, 1, "lanes"),
    # small runs that add up: this run and those computed one at a time before it repay the whole compile
    ({"forced": None, "from_points": 100, "recorded": False, "tallied": 150, "after_points": 200}, 49, "point"),
    ({"forced": None, "from_points": 100, "recorded": False, "tallied": 150, "after_points": 200}, 50, "lanes"),
    ({"forced": None, "from_points": 100, "recorded": False, "tallied": 10**9}, 1, "point"),  # no after_points
    ({"forced": False, "from_points": 100, "recorded": False, "tallied": 10**9, "after_points": 1}, 1, "point"),
])
def test_one_rule_chooses_the_route(facts, points, route):
    assert planning.choose_route(points, facts) == route
    assert planning.choose_route(points, facts, True) == "lanes"  # the scene's [execution] lanes first
    assert planning.choose_route(points, facts, False) == "point"


def test_the_plan_says_what_is_computed_and_how(small_duffing):
    scene = load_scene(small_duffing)
    plan = planning.make_plan(scene, 10)
    assert plan.outputs == ("period", "period_exact", "period_error", "kv", "epsilon")
    assert set(plan.computed) == set(scene.computed_outputs)
    assert plan.measurements == ("period",)  # the one integration behind every output
    assert {"period_exact", "period_error", "kv", "epsilon"} <= set(plan.closed_forms)  # (and what they need)
    assert dict(plan.solver)["rtol"] == 1e-10 and dict(plan.solver)["method"] == "dop853"
    assert set(plan.routes) == {"kernel"}  # the period's first-event kernel has a lane route
    assert (plan.n_points, plan.chunk_target, len(plan.chunks)) == (63, 10, 7)  # one row of A each
    text = json.loads(plan.text())
    assert text["chunks"] == {"target": 10, "count": 7, "largest": 9} and text["points"] == 63
    assert text["route"] == plan.routes and text["measurements"] == ["period"]
    assert planning.make_plan(scene, 10).text() == plan.text()  # stable


def test_a_plan_pickles_without_its_scene_and_a_worker_computes_the_same_from_it(small_duffing):
    """A dask worker gets the plan as it is (cluster.compute_chunk): the scene loaded again from its text,
    the route and the cut unchanged, the same values bitwise."""
    scene = load_scene(small_duffing)
    plan = planning.make_plan(scene, 10)
    data = pickle.dumps(plan)
    assert b"OdeModel" not in data and b"ModelSpec" not in data  # no model objects travel
    planning._loaded.cache_clear()
    sent = pickle.loads(data)
    assert sent == plan and sent.route == plan.route and sent.text() == plan.text()
    assert sent.scene is not scene and sent.scene.canonical() == scene.canonical()
    chunk = plan.chunks[3]
    for a, b in zip(execute.evaluate_chunk(plan, chunk)[1:], execute.evaluate_chunk(sent, chunk)[1:]):
        assert np.array_equal(a, b)


def test_the_plan_is_stored_in_the_journal_and_the_dataset(in_tmp, small_duffing):
    from tests.data.interrupt import interrupted_after

    with interrupted_after(2), pytest.raises(mechsweep.RunInterrupted):
        mechsweep.run(small_duffing, output="data/runs/p.h5", progress=False)
    stored = Journal.read(partial_path(in_tmp / "data/runs/p.h5")).meta["attrs"]["plan"]
    ds = mechsweep.run(small_duffing, output="data/runs/p.h5", progress=False, resume=True)
    assert json.loads(ds.attrs["plan"]) == json.loads(stored)
    assert mechsweep.open_dataset("data/runs/p.h5").attrs["plan"] == ds.attrs["plan"]
    assert json.loads(mechsweep.run(small_duffing, output=None, progress=True).attrs["plan"])["outputs"] == \
        json.loads(stored)["outputs"]


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


def test_the_tally_of_points_computed_one_at_a_time_is_mechsweeps_own(tmp_path, monkeypatch):
    """Kept in the process, then added to a file next to the kernel's module in the cache folder (at
    the process's exit); a tally of another CPU does not count, an unreadable one counts nothing; with
    caching off the tally stays this process's."""
    monkeypatch.setattr(mc._jit, "cache_dir", str(tmp_path))
    monkeypatch.setattr(mc, "_TALLY", {})
    monkeypatch.setattr(mc, "_FLUSH_AT_EXIT", [mc.write_tallies])  # registered already: not again
    name = "mechsweep_gen_test_tally"
    assert mc.points_tallied(name) == 0
    mc.tally_points(name, 40)
    mc.tally_points(name, 2)
    assert mc.points_tallied(name) == 42 and not list(tmp_path.rglob("*.points"))  # no file write per run
    mc.write_tallies()
    path = tmp_path / "models" / f"{name}.{mc._cpu_tag()}.points"
    assert path.read_text() == "42" and [p.name for p in path.parent.iterdir()] == [path.name]
    assert mc.points_tallied(name) == 42 and mc._TALLY == {}
    mc.tally_points(name, 8)  # as another process: the file's and its own
    mc.write_tallies()
    assert path.read_text() == "50"
    path.write_text("fifty")
    assert mc.points_tallied(name) == 0
    monkeypatch.setattr(mc, "_CPU", ["another-cpu"])
    assert mc.points_tallied(name) == 0
    monkeypatch.setattr(mc._jit, "cache_dir", None)
    mc.tally_points(name, 7)
    mc.write_tallies()
    assert mc.points_tallied(name) == 7 and mc._TALLY == {name: 7}


def _tally_after_a_process(folder, body: str) -> str:
    """The tally file of 't' after a Python process with the cache folder ``folder`` has tallied 5 points
    of it and then run ``body``."""
    import subprocess
    import sys
    code = ("import os, sys; from mechsweep.engine import kernels as mc; mc._jit.cache_dir = {d!r}; "
            "mc.tally_points('t', 5)\n{body}\nprint(mc._tally_path('t'))").format(d=str(folder), body=body)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    return open(out.strip()).read()


def test_the_tally_is_written_when_the_process_exits(tmp_path):
    assert _tally_after_a_process(tmp_path, "") == "5"


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="os.fork")
def test_a_forked_child_does_not_write_its_parents_tally_again(tmp_path):
    body = "pid = os.fork()\nif pid == 0: sys.exit(0)\nos.waitpid(pid, 0)"
    assert _tally_after_a_process(tmp_path, body) == "5"  # the parent's 5 points, once


def test_small_runs_that_add_up_lead_to_the_lanes(in_tmp, small_duffing, monkeypatch):
    """A run on the one-point route adds its points to the lane kernel's tally (a run on the lanes does
    not); the next plan takes the lanes once the tally and its own points reach LANES_AFTER_POINTS."""
    tallies = {}
    monkeypatch.setattr(mc, "points_tallied", lambda name: tallies.get(name, 0))
    monkeypatch.setattr(mc, "tally_points", lambda name, n: tallies.__setitem__(name, tallies.get(name, 0) + n))
    monkeypatch.setattr(mc, "lanes_recorded", lambda name: False)  # as with an empty cache folder
    monkeypatch.setattr(mc, "USE_LANES", None)
    scene = load_scene(small_duffing)
    monkeypatch.setattr(mc, "LANES_AFTER_POINTS", 2 * scene.n_points)
    first = planning.make_plan(scene)
    (record,) = [r for family, r in first.records if family == "kernel"]
    assert first.routes == {"kernel": "point"} and not tallies
    mechsweep.run(small_duffing, output="data/runs/t.h5", progress=False)
    assert tallies == {record: scene.n_points}
    assert planning.make_plan(scene).routes == {"kernel": "lanes"}  # 2 runs' points: the whole compile repaid
    planning.tally(planning.make_plan(scene), 10**6)
    assert tallies == {record: scene.n_points}  # the lanes' own points are not the one-point route's cost


def test_the_runs_size_chooses_the_route_and_the_record_keeps_it(small_duffing, monkeypatch):
    """The run's size, not the rows of a call, chooses the lanes: the warm-up's single row compiles the lane
    kernel of a run of LANES_FROM_POINTS points; once compiled, its record makes a small run take the
    lanes too (the same values either way)."""
    scene = load_scene(small_duffing)
    monkeypatch.setattr(mc, "USE_LANES", None)
    monkeypatch.setattr(mc, "_RECORDED", set())
    monkeypatch.setattr(mc, "lanes_recorded", lambda name: name in mc._RECORDED)  # as with an empty cache folder
    monkeypatch.setattr(mc, "points_tallied", lambda name: 0)
    small = planning.make_plan(scene)
    assert small.routes == {"kernel": "point"}
    monkeypatch.setattr(mc, "LANES_FROM_POINTS", scene.n_points)
    large = planning.make_plan(scene)
    assert large.routes == {"kernel": "lanes"}
    monkeypatch.setattr(mc, "_KERNELS", {})
    monkeypatch.setattr(mc, "_BY_OBJECTS", {})
    execute.evaluate_rows(large, large.params(0, 1))
    (lane,) = [name for name, k in mc._KERNELS.items() if isinstance(k, mc._Recorded)]
    assert lane in mc._RECORDED
    monkeypatch.setattr(mc, "LANES_FROM_POINTS", 10**12)
    again = planning.make_plan(scene)
    assert again.routes == {"kernel": "lanes"}  # recorded: nothing left to repay
    P = again.params(0, scene.n_points)
    for a, b in zip(execute.evaluate_rows(again, P)[1:], execute.evaluate_rows(small, P)[1:]):
        assert np.array_equal(a, b)
