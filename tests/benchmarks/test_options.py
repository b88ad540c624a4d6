"""The developer benchmarks (``python benchmarks/NAME.py``) refuse a bad option, from the command
line and from Python, as mechsweep's commands do: exit 2, one line naming the option and what is
allowed, no traceback, nothing written, and nothing started."""
from __future__ import annotations

import importlib
import sys

import pytest

from ..test_hostile_scenes import snapshot, work  # noqa: F401 (fixture)

BENCH = [
    ("autobalancer", ["--sim-points", "0"], "sim_points = 0"),
    ("autobalancer", ["--scipy-points", "-1"], "scipy_points = -1"),
    ("autobalancer", ["--threads", "-2"], "threads = -2"),
    ("linkage", ["--designs", "-1"], "designs = -1"),
    ("linkage", ["--numpy-designs", "0"], "numpy_designs = 0"),
    ("linkage", ["--threads", "0"], "threads = 0"),
    ("cluster", ["--points", "-5"], "points = -5"),
    ("cluster", ["--workers", "0"], "workers = 0"),
    ("cluster", ["--chunk", "0"], "chunk = 0"),
    ("memory", ["--dir", "a_file"], "a_file is a file, not a folder"),
    ("memory", ["--dir", "no_such_folder"], "does not exist"),
    ("quickstart", ["--scene", "a_file"], "TOML syntax error"),
    ("quickstart", ["--scene", "data"], "is a directory, not a scene file"),
    ("quickstart", ["--scene", "nothing.toml"], "does not exist"),
]
TRIPWIRES = {"autobalancer": "_main", "linkage": "design_family", "cluster": "run", "memory": "_case", "quickstart": "_timed"}  # what each benchmark calls once its options are checked


def refused(capsys, name: str, argv, root, *fragments) -> str:
    """Run ``benchmarks/NAME.py``'s command line in-process: exit 2, the fragments, no traceback,
    no file touched."""
    before = snapshot(root)
    code = importlib.import_module(f"benchmarks.{name}").cli(argv)
    out, err = capsys.readouterr()
    assert code == 2, f"exit code {code}, stderr:\n{err}"
    assert "Traceback" not in out + err
    for piece in fragments:
        assert piece in err, f"{piece!r} missing from:\n{err}"
    assert len(err) < 4000, f"message of {len(err)} characters is not readable"
    assert snapshot(root) == before, "a file was created or changed"
    return err


@pytest.fixture
def no_bench_work(work, monkeypatch):  # noqa: F811 (the fixture it extends)
    """A benchmark that passed its argument checks would start computing: fail loudly instead."""
    import numba

    def tripwire(*args, **kwargs):
        raise AssertionError("the benchmark started despite a bad option")

    monkeypatch.setattr(numba, "set_num_threads", tripwire)
    for name, attr in TRIPWIRES.items():
        monkeypatch.setattr(importlib.import_module(f"benchmarks.{name}"), attr, tripwire)
    (work / "a_file").write_text("x")
    return work


@pytest.mark.parametrize("name, argv, said", BENCH, ids=[" ".join([n, *a]) for n, a, _ in BENCH])
def test_bench_options_out_of_range_are_refused(name, argv, said, no_bench_work, capsys):
    refused(capsys, name, argv, no_bench_work, said)


def test_bench_functions_refuse_bad_arguments_too():
    from benchmarks import autobalancer, linkage
    from mechsweep.errors import InputError

    with pytest.raises(InputError, match="sim_points = 2.5"):
        autobalancer.main(sim_points=2.5)
    with pytest.raises(InputError, match="designs = True"):
        linkage.main(designs=True)


def test_bench_cluster_without_dask_is_a_clear_error(work, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    refused(capsys, "cluster", ["--points", "1000"], work, "needs the optional packages dask and distributed")
