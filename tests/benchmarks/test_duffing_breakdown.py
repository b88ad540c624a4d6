"""benchmarks/duffing_breakdown.py: the steps of a run timed, and put back as they were."""
import os

import pytest

from mechsweep.execution import execute, runner


def test_bench_breakdown_times_the_steps_of_a_run_and_unwraps_them(in_tmp, capsys):
    from benchmarks import duffing_breakdown as bench
    from mechsweep import grid
    from mechsweep.store import assemble
    from mechsweep.store import journal
    from mechsweep.model import compile as model_compile
    from mechsweep.models import MODELS

    before = (execute.evaluate_rows, runner.load_scene, journal.Journal.write_chunk, assemble.Early.write,
              grid.ParameterMatrix.__call__, MODELS["duffing"].evaluate)

    lanes = model_compile.USE_LANES
    (r,) = bench.breakdown(points=3000, threads=1, repeats=1, lanes=lanes)  # (no extra kernel compiled)
    assert model_compile.USE_LANES is lanes
    assert (execute.evaluate_rows, runner.load_scene, journal.Journal.write_chunk, assemble.Early.write,
            grid.ParameterMatrix.__call__, MODELS["duffing"].evaluate) == before
    steps = r["steps"]
    n_chunks = steps["per chunk: kernel + status/NONFINITE"][2]
    assert n_chunks >= 1
    for label in ("per chunk: parameter rows", "writer: journal chunk file + fsyncs",
                  "writer: chunk into the HDF5 file (early)"):
        assert steps[label][2] == n_chunks, label
    assert steps["end: assembly, fsync, rename, drop journal"][2] == 1
    assert 0 < r["kernel_wall_s"] and 0 < r["run_wall_s"]
    if os.path.exists("/proc/self/task"):  # each launch's threads accounted (on a CPU, waiting, asleep)
        launches = r["launches"]
        assert launches["n"] == n_chunks and launches["caller"][0] > 0 and launches["threads"] == 1
    assert "mechsweep.run breakdown: 3,010 points" in capsys.readouterr().out


def test_the_breakdowns_outputs_are_chosen_on_its_command_line(monkeypatch):
    """--outputs chooses the outputs the timed run stores; `mechsweep bench duffing` (the comparison
    with the other solvers) has no such option."""
    from benchmarks import duffing_breakdown as bench
    from mechsweep.cli import main

    seen = []
    monkeypatch.setattr(bench, "breakdown", lambda **kw: seen.append(kw["outputs"]))
    assert bench.cli(["--points", "3000", "--threads", "1", "--repeats", "1", "--outputs", "period, v_max"]) == 0
    assert seen == [("period", "v_max")]
    with pytest.raises(SystemExit) as refused:
        main(["bench", "duffing", "--outputs", "period"])
    assert refused.value.code == 2
