"""Memory bounded by the chunk for any grid shape: range axes are never expanded, the stored scene
stays small, the chunk plan is O(1), the chunk count is capped, the command counts statuses
without opening the dataset (issue 12, items 18-20). RSS figures are in `python benchmarks/memory.py`;
these tests assert structure only."""
import copy
import json
import random
import re
import tracemalloc

import numpy as np
import pytest
import xarray as xr

import mechsweep
from mechsweep import grid, scene as scene_mod
from mechsweep.store import read as store_read, write as store_write
from mechsweep.execution import execute, runner
from mechsweep.scene import sections as scene_sections
from mechsweep.cli import main
from mechsweep.chunks import MAX_CHUNKS, Chunk, ChunkPlan, least_target, plan_chunks
from mechsweep.grid import ParameterMatrix, chunk_target
from mechsweep.scene import Axis, SceneError, load_scene


def duffing(axes, outputs=("period_exact",), fixed=None, **storage):
    data = {"scene": {"name": "mem", "model": "duffing", "outputs": list(outputs)},
            "axes": axes,
            "fixed": {k: v for k, v in {"omega": 1.0, "A": 0.5}.items() if k not in axes} if fixed is None else fixed}
    if storage:
        data["storage"] = storage
    return data


LONG = {"mu": {"start": 1e-3, "stop": 1e3, "num": 10**7, "spacing": "log"}}
MANY = {"A": {"start": 0.01, "stop": 1.0, "num": 1000}, "mu": {"start": -0.5, "stop": 50.0, "num": 10**4},
        "omega": [0.5, 1.0, 2.0]}


# ----------------------------------------------------------------------------- item 18: the scene
@pytest.mark.parametrize("axes, fixed", [(LONG, None), (MANY, {})])
def test_canonical_form_is_small_for_any_grid(axes, fixed):
    s = load_scene(duffing(axes, fixed=fixed))
    assert s.n_points >= 10**7
    text = s.canonical()
    assert len(text) < 10_000, len(text)
    described = dict(json.loads(text)["axes"])
    assert described["mu"]["num"] == s.shape[list(described).index("mu")]
    if "omega" in described:
        assert described["omega"] == [0.5, 1.0, 2.0]  # a list stays what the user wrote


def test_canonical_form_equal_scenes_equal_any_change_differs(tmp_path):
    base = duffing({"A": {"start": 0.1, "stop": 1.0, "num": 5},
                    "mu": {"start": 1e-3, "stop": 1e3, "num": 7, "spacing": "log"}})
    ref = load_scene(base).canonical()
    toml = tmp_path / "s.toml"
    toml.write_text(scene_mod.to_toml(base).replace("start = 0.1,", "start = 0.10000,").replace("num = 5", "num = 5"))
    assert load_scene(toml).canonical() == ref  # the same scene written otherwise
    same = copy.deepcopy(base)
    same["axes"]["A"]["spacing"] = "linear"  # the default, spelled out
    assert load_scene(same).canonical() == ref
    changes = [("axes", "A", "start", 0.2), ("axes", "A", "stop", 0.9), ("axes", "A", "num", 6),
               ("axes", "mu", "spacing", "linear"), ("axes", "mu", "stop", 1e2), ("fixed", "omega", None, 2.0)]
    seen = {ref}
    for section, name, key, value in changes:
        other = copy.deepcopy(base)
        if key is None:
            other[section][name] = value
        else:
            other[section][name][key] = value
        text = load_scene(other).canonical()
        assert text not in seen, (section, name, key)
        seen.add(text)
    assert json.loads(ref)["axes"][0] == ["A", {"start": 0.1, "stop": 1.0, "num": 5, "spacing": "linear"}]


def test_older_expanded_canonical_form_still_matches():
    """Journals and datasets of earlier versions wrote range axes value by value."""
    s = load_scene(duffing({"A": {"start": 0.1, "stop": 1.0, "num": 4}, "mu": [1.0, 2.0]}))
    old = json.loads(s.canonical())
    old["axes"][0][1] = list(np.linspace(0.1, 1.0, 4))
    assert s.same_as(json.dumps(old, sort_keys=True))
    old["axes"][0][1][2] += 1e-15
    assert not s.same_as(json.dumps(old, sort_keys=True))
    assert not s.same_as("{}") and not s.same_as(None)


def test_range_axis_values_are_numpys_bit_for_bit_in_any_stretch():
    rng = random.Random(12)
    for _ in range(400):
        num = rng.choice([1, 2, 3, 61, rng.randint(1, 3000)])
        if rng.random() < 0.5:
            start, stop, spacing = 10 ** rng.uniform(-200, 200), 10 ** rng.uniform(-200, 200), "log"
            ref = np.geomspace(start, stop, num)
        else:
            start, stop, spacing = rng.uniform(-1e6, 1e6), rng.uniform(-1e6, 1e6), "linear"
            ref = np.linspace(start, stop, num)
        axis = Axis.of_range("x", start, stop, num, spacing)
        lo = rng.randint(0, num)
        hi = rng.randint(lo, num)
        assert np.array_equal(axis.array(lo, hi), ref[lo:hi]), (start, stop, num, spacing, lo, hi)
        assert axis.array()[0] == start and (num == 1 or axis.array()[-1] == stop)


def test_values_repeating_at_float_precision_are_found_without_expanding(monkeypatch):
    spans = []
    real = Axis.array
    monkeypatch.setattr(Axis, "array", lambda self, lo=0, hi=None: spans.append(
        (hi if hi is not None else self.size) - lo) or real(self, lo, hi))
    monkeypatch.setattr(scene_sections, "_BLOCK", 1000)
    with pytest.raises(SceneError, match="repeat at float precision"):
        load_scene(duffing({"mu": {"start": 1.0, "stop": 1.0 + 2e-12, "num": 50_000}}))
    assert spans and max(spans) <= 1000
    spans.clear()
    load_scene(duffing(LONG))
    load_scene(duffing({"mu": {"start": -1.0, "stop": 1.0, "num": 10**7}}))
    assert not spans  # a sensible range is decided from its step alone


@pytest.mark.parametrize("axes, fixed", [(LONG, None), (MANY, {})])
def test_chunk_parameters_use_only_the_stretch_of_the_chunk(monkeypatch, axes, fixed):
    s = load_scene(duffing(axes, fixed=fixed))
    spans = []
    real = Axis.array
    monkeypatch.setattr(Axis, "array", lambda self, lo=0, hi=None: spans.append(
        (hi if hi is not None else self.size) - lo) or real(self, lo, hi))
    plan = plan_chunks(s.shape, 4096)
    params = ParameterMatrix(s)
    for chunk in (plan[0], plan[len(plan) // 2], plan[-1]):
        P = params(chunk.start, chunk.stop)
        idx = np.unravel_index(np.arange(chunk.start, chunk.stop), s.shape)
        for k, axis in enumerate(s.axes):
            col = [p.name for p in s.model.params].index(axis.name)
            if axis.spacing != "list":
                assert np.array_equal(P[:, col], real(axis)[idx[k]] if axis.size <= 10**4 else
                                      real(axis, int(idx[k].min()), int(idx[k].max()) + 1)[idx[k] - idx[k].min()])
    assert spans and max(spans) <= 4096


def test_run_never_expands_a_long_axis(in_tmp, monkeypatch):
    """The whole run path (scene, journal, provenance, chunk parameters, coordinates, assembly)
    asks a range axis for at most a chunk or a write block of values at a time."""
    spans = []
    real = Axis.array
    monkeypatch.setattr(Axis, "array", lambda self, lo=0, hi=None: spans.append(
        (hi if hi is not None else self.size) - lo) or real(self, lo, hi))
    monkeypatch.setattr(store_write, "READ_BLOCK", 5000)
    data = duffing({"mu": {"start": 1e-3, "stop": 1e3, "num": 120_000, "spacing": "log"}}, chunk_size=20_000)
    summary = runner.compute(data, output="data/runs/long.h5", progress=False)
    assert summary.status == {0: 120_000}
    assert spans and max(spans) <= 20_000
    with xr.open_dataset("data/runs/long.h5", engine="h5netcdf") as ds:
        np.testing.assert_array_equal(ds["mu"].values, np.geomspace(1e-3, 1e3, 120_000))
        assert len(ds.attrs["scene_canonical"]) < 1000


# ----------------------------------------------------------------------------- item 19: the plan
def _reference_plan(shape, target):
    """The list the plan was built as before: every chunk made in order."""
    trailing = [int(np.prod(shape[k + 1:], dtype=np.int64)) for k in range(len(shape))]
    j = next(k for k in range(len(shape)) if trailing[k] <= target)
    step, chunks, flat = max(1, target // trailing[j]), [], 0
    for lead in np.ndindex(*shape[:j]) if shape[:j] else [()]:
        for s in range(0, shape[j], step):
            e = min(shape[j], s + step)
            region = tuple(slice(i, i + 1) for i in lead) + (slice(s, e),) + (slice(None),) * (len(shape) - j - 1)
            chunks.append(Chunk(len(chunks), flat, flat + (e - s) * trailing[j], region))
            flat += (e - s) * trailing[j]
    return chunks


def test_chunk_plan_is_made_on_demand_and_equals_the_listed_plan():
    rng = random.Random(19)
    for _ in range(200):
        shape = tuple(rng.randint(1, 6) for _ in range(rng.randint(1, 4)))
        target = rng.randint(1, 50)
        plan = plan_chunks(shape, target)
        assert list(plan) == _reference_plan(shape, target), (shape, target)
        assert plan.max_size == max(c.size for c in plan)
        counts = [len(ChunkPlan(shape, t)) for t in range(1, int(np.prod(shape)) + 2)]
        assert counts == sorted(counts, reverse=True)  # what least_target's bisection relies on
    tracemalloc.start()
    try:
        huge = plan_chunks((10**5,), 1)  # 10^5 chunks: made only when asked for
        last = huge[-1]
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(huge) == 10**5 and last == Chunk(10**5 - 1, 10**5 - 1, 10**5, (slice(10**5 - 1, 10**5),))
    assert peak < 100_000, peak
    assert len(plan_chunks((2**20, 2**20), 1)) == 2**40


def test_too_many_chunks_refused_with_the_numbers(in_tmp, capsys):
    data = duffing({"mu": {"start": 1.0, "stop": 2.0, "num": 20_000}}, chunk_size=1)
    with pytest.raises(SceneError) as err:
        load_scene(data)
    message = str(err.value)
    for piece in ("storage.chunk_size", "20,000 chunks", f"at most {MAX_CHUNKS:,}", "chunk_size >= 2"):
        assert piece in message, message
    assert len(plan_chunks((20_000,), least_target((20_000,)))) <= MAX_CHUNKS
    (in_tmp / "s.toml").write_text(scene_mod.to_toml(data))
    assert main(["run", "s.toml", "--no-progress"]) == 2
    assert "20,000 chunks" in capsys.readouterr().err
    assert not any((in_tmp / "data" / "runs").iterdir())


def test_default_chunks_are_raised_to_the_cap():
    s = load_scene(duffing({"A": {"start": 0.01, "stop": 1.0, "num": 10**4},
                            "mu": {"start": 1e-3, "stop": 1e3, "num": 10**5}}, outputs=("period",)))
    assert len(plan_chunks(s.shape, grid.default_chunk_target(s))) > MAX_CHUNKS
    target = chunk_target(s)
    assert len(plan_chunks(s.shape, target)) <= MAX_CHUNKS < len(plan_chunks(s.shape, target - 1))


def test_small_grids_are_few_chunks_and_large_ones_get_big_chunks():
    # each chunk is a launch, a journal file with fsyncs and Python: a grid of 10^3 integrated points
    # is one chunk, 10^4 a handful, and a large grid's chunks are 65536 points (issue 15)
    def n_chunks(n, outputs):
        s = load_scene(duffing({"mu": {"start": 1e-3, "stop": 1e3, "num": n, "spacing": "log"}}, outputs=outputs,
                               fixed={"A": 0.5, "omega": 1.0}))
        return len(plan_chunks(s.shape, chunk_target(s))), chunk_target(s)

    assert n_chunks(1000, ("period",)) == (1, 2048)
    assert n_chunks(10_000, ("period",)) == (5, 2048)
    assert n_chunks(10_000, ("period_exact",)) == (2, 8192)
    assert n_chunks(100_000, ("period",)) == (20, 5000)  # at least 20 chunks above that
    assert n_chunks(10**7, ("period",))[1] == 65536


# ----------------------------------------------------------------------------- item 20: the command
MIXED = duffing({"A": {"start": 0.1, "stop": 3.0, "num": 9}, "mu": {"start": -0.9, "stop": 2.0, "num": 11}},
                fixed={"omega": 1.0}, chunk_size=20)


def _counts(path):
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        codes, n = np.unique(ds["status"].values, return_counts=True)
    return {mechsweep.status.MEANINGS[int(c)]: int(k) for c, k in zip(codes, n)}


def test_command_counts_statuses_without_opening_the_dataset(in_tmp, capsys, monkeypatch):
    (in_tmp / "s.toml").write_text(scene_mod.to_toml(MIXED))

    def refuse(*args, **kwargs):
        raise AssertionError("the command opened the dataset")
    with monkeypatch.context() as mp:
        mp.setattr(store_read, "open_dataset", refuse)
        mp.setattr(runner, "open_dataset", refuse)
        mp.setattr(xr, "open_dataset", refuse)
        assert main(["run", "s.toml", "-o", "data/runs/m.h5", "--no-progress"]) == 0
    out = capsys.readouterr().out
    printed = eval(re.search(r"status (\{.*?\})", out).group(1))  # noqa: S307 (our own dict repr)
    assert printed == _counts("data/runs/m.h5") and len(printed) > 1, printed
    assert "{'A': 9, 'mu': 11}" in out


def test_counts_of_a_resumed_run_include_the_journaled_chunks(in_tmp, monkeypatch):
    real, calls = execute.evaluate_chunk, {"n": 0}

    def flaky(*args):
        calls["n"] += 1
        if calls["n"] > 2:
            raise KeyboardInterrupt
        return real(*args)
    with monkeypatch.context() as mp:
        mp.setattr(execute, "evaluate_chunk", flaky)
        with pytest.raises(runner.RunInterrupted):
            runner.compute(MIXED, output="data/runs/r.h5", progress=False)
    summary = runner.compute(MIXED, output="data/runs/r.h5", resume=True, progress=False)
    assert summary.status_names() == _counts("data/runs/r.h5")
    assert sum(summary.status.values()) == 99 and summary.sizes == {"A": 9, "mu": 11}
    again = runner.compute(MIXED, output="data/runs/r.h5", resume=True, progress=False)  # already finished
    assert again.status == summary.status
