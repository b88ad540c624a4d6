"""One dataset route for every run (execution/runner.py): scene -> plan -> chunks -> compute -> a sink. The CLI,
``compute``, ``run(output=path)`` and ``run(output=None)`` differ only in their sink; a dataset a run
returns is the memory its chunks were computed into (no copy), beside the journal and the file."""
import numpy as np
import pytest
import xarray as xr

import mechsweep
from mechsweep.execution import execute, runner
from mechsweep.cli import main


@pytest.fixture
def routes(monkeypatch):
    """The sinks of the runs that go through runner._route, in order."""
    seen, real = [], runner._route

    def route(plan, todo, sink, **kw):
        seen.append((type(sink).__name__, getattr(sink, "memory", sink) is not None, plan.n_points, len(todo)))
        return real(plan, todo, sink, **kw)

    monkeypatch.setattr(runner, "_route", route)
    return seen


def test_every_front_end_takes_the_one_route(in_tmp, small_duffing, routes):
    (in_tmp / "s.toml").write_text('[scene]\nname = "small"\nmodel = "duffing"\noutputs = ["period"]\n'
                                   '[axes]\nA = { start = 0.1, stop = 1.0, num = 7 }\n[fixed]\nmu = 1.0\nomega = 2.0\n'
                                   '[storage]\nchunk_size = 3\n')
    mechsweep.run(small_duffing, output=None)
    mechsweep.run(small_duffing, output="data/runs/a.h5", progress=False)
    runner.compute(small_duffing, output="data/runs/b.h5", progress=False)
    assert main(["run", "s.toml", "-o", "data/runs/c.h5", "--no-progress"]) == 0
    assert routes == [("MemorySink", True, 63, 7),  # in memory (the scene sets its chunk size)
                      ("_FileSink", True, 63, 7),  # the journal, the file, and the dataset it returns
                      ("_FileSink", False, 63, 7),  # the journal and the file only (memory bounded by a chunk)
                      ("_FileSink", False, 7, 3)]


@pytest.mark.parametrize("output", [None, "data/runs/r.h5"])
def test_a_returned_dataset_holds_the_arrays_its_chunks_were_computed_into(in_tmp, small_duffing, monkeypatch,
                                                                         output):
    """Each chunk's outputs, status and step counts are computed straight into the dataset the run
    returns (views of its variables): not copied into it afterwards, and not read back from the file."""
    given, real = [], execute.evaluate_chunk

    def evaluate_chunk(plan, chunk, params=None, out=None, launching=None):
        given.append(out)
        return real(plan, chunk, params, out, launching)

    monkeypatch.setattr(execute, "evaluate_chunk", evaluate_chunk)
    ds = mechsweep.run(small_duffing, output=output, progress=False)
    assert given and all(out is not None for out in given)
    for out in given:
        assert set(out) == {"period", "period_exact", "period_error", "kv", "epsilon", "status", "n_steps", "n_rhs"}
        for name, array in out.items():
            assert np.shares_memory(array, ds[name].values), name
    if output is not None:
        xr.testing.assert_identical(ds, mechsweep.open_dataset(output))


def test_a_run_to_a_file_without_a_returned_dataset_holds_no_grid_in_memory(in_tmp, small_duffing, monkeypatch):
    """``compute`` (the CLI's route): each chunk in arrays of its own, memory bounded by the chunk."""
    given, real = [], execute.evaluate_chunk
    monkeypatch.setattr(execute, "evaluate_chunk",
                        lambda plan, chunk, params=None, out=None, launching=None:
                        given.append(out) or real(plan, chunk, params, out, launching))
    runner.compute(small_duffing, output="data/runs/c.h5", progress=False)
    assert given and all(out is None for out in given)


def test_the_public_compute_stays_the_function():
    """The module that computes chunks (execute.py) is not named after the public ``mechsweep.compute``:
    a submodule of that name would replace the function on the package once imported."""
    import mechsweep.execution.execute  # noqa: F401  (imported, as every run imports it)

    assert mechsweep.compute is runner.compute and callable(mechsweep.compute)



@pytest.mark.parametrize("output", [None, "data/runs/w.h5"])
def test_each_chunk_is_written_once_into_each_place_that_keeps_it(in_tmp, small_duffing, monkeypatch, output):
    """``run(output=path)`` keeps each chunk in three places, each written once: the journal (a crash
    loses no saved chunk; ``--resume``), the dataset's file (written while the next chunk computes)
    and the dataset it returns (the memory the chunk was computed into: nothing copied, nothing read
    back). ``run(output=None)`` keeps it in memory only."""
    import collections

    from mechsweep.store import assemble, journal

    written = collections.Counter()

    def counting(owner, name, key):
        real = getattr(owner, name)

        def wrapper(*args, **kwargs):
            written[key(*args)] += 1
            return real(*args, **kwargs)
        monkeypatch.setattr(owner, name, wrapper)

    counting(journal.Journal, "write_chunk", lambda self, index, *a: ("journal", index))
    counting(assemble, "write_region", lambda variables, region, *a: ("file", str(region)))
    counting(journal.Journal, "read_chunk", lambda self, index, *a: ("read back", index))
    real_save = assemble.MemorySink.save

    def save(self, chunk, arrays, seconds):
        views = self.views(chunk)
        if not all(np.shares_memory(arrays[name], views[name]) for name in views):
            written[("memory copy", chunk.index)] += 1
        return real_save(self, chunk, arrays, seconds)

    monkeypatch.setattr(assemble.MemorySink, "save", save)
    ds = mechsweep.run(small_duffing, output=output, progress=False)
    n_chunks = int(ds.attrs["n_chunks"])
    assert n_chunks > 1
    if output is None:
        assert written == {}
    else:
        assert sorted(kind for kind, _ in written) == ["file"] * n_chunks + ["journal"] * n_chunks
        assert set(written.values()) == {1}, written  # each chunk once into the journal, once into the file
