"""Start-up of the quickstart commands (issue 15 goal 3): what a warm `mechsweep plot` imports."""
import os
import subprocess
import sys

import mechsweep


def test_plot_does_not_import_dask_and_leaves_xarray_as_it_was(in_tmp, small_duffing):
    """xarray imports dask.array (and with it scipy.fft, 0.4-1 s) to ask whether each new variable is a
    dask array; `mechsweep plot` draws loaded datasets and tells xarray not to ask while it runs
    (commands/plot.py, no_dask_probe), then puts xarray's own probe back: a dask array made afterwards in the same
    process is still one to xarray. Nor dask at all: xarray also imports dask.base (0.05-0.2 s) to ask
    whether each index it makes while opening the dataset is a dask collection. The command's process
    (main() with sys.argv) freezes its start-up's objects for the garbage collector and turns it back on."""
    mechsweep.run(small_duffing, output="data/runs/s.h5")
    code = ("import os, sys; from matplotlib.figure import Figure; save = Figure.savefig\n"
            "def savefig(self, *a, **k): open('pids', 'a').write(f'{os.getpid()}\\n'); return save(self, *a, **k)\n"
            "Figure.savefig = savefig; from mechsweep.cli import main; import gc\n"
            "sys.argv = ['mechsweep', 'plot', 'data/runs/s.h5']; assert main() == 0\n"
            "print(os.getpid(), gc.isenabled(), gc.get_freeze_count() > 0); "
            "from xarray.namedarray import pycompat, utils; "
            "print(sorted(m for m in ('dask', 'dask.array', 'scipy', 'numba') if m in sys.modules), "
            "'dask' in pycompat._cached_duck_array_modules, utils.is_dask_collection.__module__); "
            "import dask.array as da, xarray as xr; print(xr.DataArray(da.zeros(4, chunks=2)).chunks)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=in_tmp,
                         env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-2:] == ["[] False xarray.namedarray.utils", "((2, 2),)"]
    assert sorted(p.name for p in (in_tmp / "data/runs").glob("*.png")) == ["s_amplitude_period.png",
                                                                            "s_kinematic_coefficients.png"]
    # the two figures were drawn side by side: one here, one in a forked process (figures/jobs.py, side_by_side)
    here, collector, frozen = out.stdout.strip().splitlines()[-3].split()
    assert (collector, frozen) == ("True", "True")  # the start-up's objects frozen, the collector on (commands.started)
    pids = (in_tmp / "pids").read_text().split()
    assert len(pids) == 2 and here in pids and len(set(pids)) == 2


def test_plot_process_ends_at_once_once_its_atexit_handlers_ran(in_tmp, small_duffing):
    """The `mechsweep` program (python -m mechsweep, the console script: cli.script) ends the process of
    `plot` as soon as the command is done and the atexit handlers have run (commands.leave): the
    interpreter is not taken apart (an object still alive at the end is never finalized), and the
    output and the exit code are the command's, also for an error. Other commands exit as usual."""
    mechsweep.run(small_duffing, output="data/runs/s.h5")
    code = ("import atexit, runpy, sys\n"
            "class Alive:\n    def __del__(self): print('taken apart', flush=True)\n"
            "alive = Alive(); atexit.register(print, 'atexit ran')\n"
            "sys.argv = ['mechsweep'] + sys.argv[1:]; runpy.run_module('mechsweep', run_name='__main__')\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    for args, returncode, last in ((["plot", "data/runs/s.h5"], 0, "atexit ran"),
                                   (["plot", "data/runs/missing.h5"], 2, "atexit ran"),
                                   (["info", "data/runs/s.h5"], 0, "taken apart")):
        out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=in_tmp, env=env)
        assert out.returncode == returncode, out.stderr
        lines = out.stdout.strip().splitlines()
        assert lines[-1] == last and "atexit ran" in lines and ("taken apart" in lines) == (args[0] != "plot")
        if returncode == 0 and args[0] == "plot":
            assert lines[:-1] == [f"wrote data/runs/s_{k}.png" for k in ("amplitude_period", "kinematic_coefficients")]
        if returncode == 2:
            assert "missing.h5 does not exist" in out.stderr and "Traceback" not in out.stderr


def test_side_by_side_runs_jobs_in_forked_processes_and_raises_what_they_raised(tmp_path):
    """figures.jobs.side_by_side (`mechsweep plot`'s figures on two cores): the first job here, the others in
    forked children; an exception of a child is raised here with its type; an exception here is raised
    only after the children have finished (a sibling's figure is not cut off half written)."""
    import time

    import pytest

    from mechsweep.figures.jobs import side_by_side as _side_by_side

    def mark(name, delay=0.0, fail=None):
        def job():
            time.sleep(delay)
            (tmp_path / name).write_text(str(os.getpid()))
            if fail is not None:
                raise fail
        return job

    _side_by_side([mark("a"), mark("b"), mark("c")])
    pids = [(tmp_path / n).read_text() for n in "abc"]
    assert pids[0] == str(os.getpid()) and len(set(pids)) == 3
    with pytest.raises(KeyError, match="from a child"):
        _side_by_side([mark("d"), mark("e", fail=KeyError("from a child"))])
    with pytest.raises(ValueError, match="here"):
        _side_by_side([mark("f", fail=ValueError("here")), mark("g", delay=0.5)])
    assert (tmp_path / "g").read_text() != str(os.getpid())
