"""Runner and store: dataset layout, leave-out, resume, atomic replace, reproducibility."""
import copy
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import xarray as xr

import mechsweep
from mechsweep.execution import checks, execute, runner
from mechsweep import status as st
from mechsweep.errors import StoreError
from mechsweep.store.journal import partial_path

from tests.conftest import REPO
from tests.data.interrupt import interrupted_after


def test_dataset_layout(in_tmp, small_duffing):
    ds = mechsweep.run(small_duffing, output="data/runs/s.h5")
    assert list(ds.dims) == ["A", "mu"]
    assert ds["A"].attrs["units"] == "rad" and ds["mu"].attrs["long_name"]
    assert float(ds["omega"]) == 2.0 and ds["omega"].attrs["units"] == "rad s-1"
    assert set(ds.data_vars) == {"period", "period_exact", "period_error", "kv", "epsilon", "status",
                                 "n_steps", "n_rhs"}
    for name in ("period", "kv"):
        assert ds[name].attrs["units"] and ds[name].attrs["long_name"]
    assert ds["status"].dtype == np.int8
    assert "ok" in ds["status"].attrs["flag_meanings"].split()
    for key in ("scene", "mechsweep_version", "numba_version", "numpy_version", "solver_rtol", "wall_time_s",
                "created"):
        assert key in ds.attrs, key
    # readable by plain xarray
    with xr.open_dataset("data/runs/s.h5", engine="h5netcdf") as raw:
        np.testing.assert_array_equal(raw["period"].values, ds["period"].values)
    ok = ds["status"].values == st.OK
    for name in ("period", "period_exact", "kv", "epsilon"):
        assert np.isfinite(ds[name].values[ok]).all()
        assert np.isnan(ds[name].values[~ok]).all()


def test_only_requested_outputs_are_stored(in_tmp, small_duffing):
    small_duffing["scene"]["outputs"] = ["period_error"]
    ds = mechsweep.run(small_duffing, output="data/runs/e.h5")
    assert set(ds.data_vars) == {"period_error", "status", "n_steps", "n_rhs"}


def test_algebraic_scene_never_compiles_an_integrator(in_tmp):
    """Run in a fresh interpreter: no integrating kernel may have a compiled signature."""
    code = textwrap.dedent("""
        import gc
        import sys
        import mechsweep
        from numba.core.dispatcher import Dispatcher
        from mechsweep.engine import kernels as mc
        ds = mechsweep.run({"scene": {"name": "alg", "model": "duffing", "outputs": ["period_exact", "kv"]},
                            "axes": {"A": [0.1, 0.5]}, "fixed": {"omega": 1.0, "mu": 2.0}},
                           output="data/runs/alg.h5")
        assert "n_steps" not in ds and "solver_rtol" not in ds.attrs
        assert mc._KERNELS, "the kernel should have run"
        # any integrator, shared trajectory or model equation compiled in this process
        compiled = [d.py_func.__qualname__ for d in gc.get_objects() if isinstance(d, Dispatcher) and d.signatures
                     and (d.py_func.__module__.startswith(("mechsweep.ode", "mechsweep.engine.shared"))
                          or d.py_func.__qualname__.split("__")[0] in ("rhs", "jac", "accel"))]
        print("COMPILED", compiled)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=in_tmp)
    assert out.returncode == 0, out.stderr
    assert "COMPILED []" in out.stdout


def test_interrupted_run_resumes_to_identical_dataset(in_tmp, small_duffing):
    reference = mechsweep.run(small_duffing, output="data/runs/ref.h5")
    with interrupted_after(3), pytest.raises(mechsweep.RunInterrupted, match="--resume"):
        mechsweep.run(small_duffing, output="data/runs/r.h5")
    part = partial_path("data/runs/r.h5")
    assert part.exists() and not (in_tmp / "data/runs/r.h5").exists()
    partial = mechsweep.open_dataset("data/runs/r.h5", allow_partial=True)
    assert (partial["status"].values == st.PENDING).any()
    with pytest.raises(StoreError, match="--resume"):
        mechsweep.run(small_duffing, output="data/runs/r.h5")  # neither resume nor restart
    done = mechsweep.run(small_duffing, output="data/runs/r.h5", resume=True)
    assert not part.exists()
    history = done.attrs["history"].splitlines()  # the run that began it, then the one that finished it
    assert len(history) == 2 and "resume=True" in history[1] and "resume" not in history[0]
    assert len(reference.attrs["history"].splitlines()) == 1
    for name in ("period", "period_exact", "kv", "epsilon", "status", "n_steps", "n_rhs"):
        np.testing.assert_array_equal(done[name].values, reference[name].values, err_msg=name)


@pytest.mark.parametrize("during", [1, 3])
def test_a_signal_during_a_chunk_stops_the_run_once_that_chunk_is_saved(in_tmp, small_duffing, monkeypatch, during):
    """Ctrl-C (here SIGINT sent to this process) while chunk ``during`` computes: the kernel cannot be
    stopped, so the chunk finishes; it is saved before the run stops (it was thrown away: a docs-only
    trial's one-chunk grid said "0 of 1 chunks saved" 20 s after Ctrl-C). Chunks after it are not
    computed; resume completes the dataset."""
    import os
    import signal

    from mechsweep.store.journal import Journal

    real, calls = execute.evaluate_chunk, [0]

    def signalled(*args):
        calls[0] += 1
        if calls[0] == during:
            os.kill(os.getpid(), signal.SIGINT)  # handled in this thread during the real chunk below
        return real(*args)

    monkeypatch.setattr(execute, "evaluate_chunk", signalled)
    with pytest.raises(mechsweep.RunInterrupted, match=f"{during} of 7 chunks saved"):
        mechsweep.run(small_duffing, output="data/runs/s.h5", progress=False)
    assert calls[0] == during
    assert Journal.read(partial_path("data/runs/s.h5")).done_chunks().sum() == during
    monkeypatch.setattr(execute, "evaluate_chunk", real)
    done = mechsweep.run(small_duffing, output="data/runs/s.h5", resume=True, progress=False)
    assert (done["status"].values != st.PENDING).all()


def test_failed_run_leaves_finished_dataset_untouched(in_tmp, small_duffing):
    first = mechsweep.run(small_duffing, output="data/runs/keep.h5")
    before = (in_tmp / "data/runs/keep.h5").read_bytes()
    changed = copy.deepcopy(small_duffing)
    changed["fixed"]["omega"] = 3.0
    with pytest.raises(StoreError, match="different scene") as refused:  # it would replace another scene's run
        mechsweep.run(changed, output="data/runs/keep.h5")
    assert "a different scene (fixed.omega: 2.0 in the stored run, 3.0 now); use --overwrite" in str(refused.value)
    with interrupted_after(1), pytest.raises(mechsweep.RunInterrupted):
        mechsweep.run(changed, output="data/runs/keep.h5", overwrite=True)
    assert (in_tmp / "data/runs/keep.h5").read_bytes() == before
    np.testing.assert_array_equal(mechsweep.open_dataset("data/runs/keep.h5")["period"], first["period"])


def test_resume_with_a_different_scene_is_refused(in_tmp, small_duffing):
    with interrupted_after(1), pytest.raises(mechsweep.RunInterrupted):
        mechsweep.run(small_duffing, output="data/runs/x.h5")
    other = copy.deepcopy(small_duffing)
    other["fixed"]["omega"] = 3.0
    with pytest.raises(StoreError, match="different scene"):
        mechsweep.run(other, output="data/runs/x.h5", resume=True)
    tighter = copy.deepcopy(other)
    tighter["solver"]["rtol"] = 1e-11
    with pytest.raises(StoreError) as refused:  # the message names each key that differs, with both values
        mechsweep.run(tighter, output="data/runs/x.h5", resume=True)
    assert ("started from a different scene (fixed.omega: 2.0 when the run began, 3.0 now; solver.rtol: 1e-10 "
            "when the run began, 1e-11 now); resume it") in str(refused.value), refused.value
    ds = mechsweep.run(other, output="data/runs/x.h5", restart=True)
    assert float(ds["omega"]) == 3.0


def test_results_do_not_depend_on_threads_or_chunks(in_tmp, small_duffing):
    a = mechsweep.run(small_duffing, output="data/runs/a.h5", threads=1)
    other = copy.deepcopy(small_duffing)
    other["storage"]["chunk_size"] = 7
    b = mechsweep.run(other, output="data/runs/b.h5", threads=2)
    for name in ("period", "kv", "status", "n_steps"):
        np.testing.assert_array_equal(a[name].values, b[name].values)


def test_bad_output_paths(in_tmp, small_duffing):
    with pytest.raises(StoreError, match="is a directory"):
        mechsweep.run(small_duffing, output="data")
    with pytest.raises(StoreError, match="does not exist"):
        mechsweep.run(small_duffing, output="no/such/folder/x.h5")
    assert not (in_tmp / "no").exists()


def test_torsional_nomogram_scene_small(in_tmp):
    scene = mechsweep.load_scene(REPO / "sweeps" / "torsional_circuit_nomogram.toml")
    ds = mechsweep.run(scene, output="data/runs/t.h5")
    assert list(ds.dims) == ["spring", "s0_over_r", "lambda2"]
    assert list(ds["spring"].values) == ["tension", "compression"]
    ok = ds["status"].values == st.OK
    assert ok.mean() > 0.8
    assert set(np.unique(ds["hardness"].values[ok])) <= {-1.0, 0.0, 1.0}


def test_a_second_writer_is_refused_and_touches_nothing(in_tmp, small_duffing):
    """While one process holds a run's lock, another run on the same output (plain, --resume or
    --restart) is refused with the holder's pid, and the unfinished run's journal is left as it was."""
    with interrupted_after(1), pytest.raises(mechsweep.RunInterrupted):
        mechsweep.run(small_duffing, output="data/runs/busy.h5")
    part = partial_path("data/runs/busy.h5")
    saved = sorted(p.name for p in (part / "chunks").iterdir())
    code = ("import time; from mechsweep.store.journal import RunLock; RunLock('data/runs/busy.h5').acquire(); "
            "print('locked', flush=True); time.sleep(60)")
    holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        for flags in ({}, {"resume": True}, {"restart": True}):
            with pytest.raises(StoreError, match=f"another mechsweep run \\(process {holder.pid}\\)"):
                mechsweep.run(small_duffing, output="data/runs/busy.h5", **flags)
        assert sorted(p.name for p in (part / "chunks").iterdir()) == saved
    finally:
        holder.kill()
        holder.wait()
    # the holder died without releasing: the kernel dropped its lock, the run resumes
    assert mechsweep.run(small_duffing, output="data/runs/busy.h5", resume=True)["status"].size == 63


def test_progress_bar_shows_points_and_rate(in_tmp, small_duffing, capsys):
    mechsweep.run(small_duffing, output="data/runs/p.h5", progress=True)
    err = capsys.readouterr().err
    assert "63/63" in err and "pt/s" in err


def test_size_estimate_is_the_file_size(in_tmp, small_duffing):
    """The disk refusal compares bytes_per_point x points with the free space: that product must
    bound the data actually written (plus HDF5 metadata, coordinates and attributes), and be tight
    for the float outputs, which are stored raw."""
    scene = mechsweep.load_scene(small_duffing)
    mechsweep.run(scene, output="data/runs/size.h5", progress=False)
    data = checks.bytes_per_point(scene) * scene.n_points
    floats = 8 * len(scene.outputs) * scene.n_points
    actual = (in_tmp / "data" / "runs" / "size.h5").stat().st_size
    assert floats <= actual <= data + 200_000


def test_big_datasets_open_lazily_with_dask_chunks(in_tmp, small_duffing, monkeypatch):
    from mechsweep.store import read as store_read

    loaded = mechsweep.run(small_duffing, output="data/runs/lazy.h5", progress=False)
    assert loaded["period"].chunks is None  # small: in memory
    monkeypatch.setattr(store_read, "LOAD_LIMIT_BYTES", 0)  # now every file counts as big
    with mechsweep.open_dataset("data/runs/lazy.h5", lazy=None) as lazy:
        assert lazy["period"].chunks is not None, "not opened lazily as dask arrays"
        for name in ("period", "status", "n_steps"):
            np.testing.assert_array_equal(lazy[name].values, loaded[name].values)
    ran = mechsweep.run(small_duffing, output="data/runs/lazy.h5", resume=True, load=False)
    assert ran["period"].chunks is not None
    ran.close()


@pytest.mark.parametrize("fail_at", [1, 3])
def test_a_failure_after_the_checks_leaves_no_blocking_journal(in_tmp, small_duffing, monkeypatch, fail_at):
    """An exception inside the run after the scene's checks passed (a bug: here chunk fail_at
    raises): with no chunk saved the journal is removed, so the next run starts without --restart;
    with chunks saved it is kept and the exception says how to go on."""
    calls = []
    real = execute.evaluate_chunk

    def failing(scene, chunk, *rest):
        calls.append(chunk)
        if len(calls) == fail_at:
            raise RuntimeError("bug in a chunk")
        return real(scene, chunk, *rest)

    monkeypatch.setattr(execute, "evaluate_chunk", failing)
    with pytest.raises(RuntimeError, match="bug in a chunk") as info:
        runner.compute(small_duffing, output="data/runs/s.h5", progress=False)
    notes = "".join(getattr(info.value, "__notes__", []))
    part = partial_path(in_tmp / "data/runs/s.h5")
    if fail_at == 1:
        assert not part.exists() and not notes
        assert sorted(p.name for p in (in_tmp / "data/runs").iterdir()) == []
    else:
        assert part.exists() and "run again with --resume" in notes and "--restart" in notes
    monkeypatch.setattr(execute, "evaluate_chunk", real)
    if fail_at == 1:  # nothing blocks the next run
        runner.compute(small_duffing, output="data/runs/s.h5", progress=False)
    else:
        runner.compute(small_duffing, output="data/runs/s.h5", progress=False, resume=True)
    assert (in_tmp / "data/runs/s.h5").exists() and not part.exists()
