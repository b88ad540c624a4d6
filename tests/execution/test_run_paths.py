"""The in-memory route (run(output=None)), the compile phase timed apart from the compute, and the
default output folder created by a run (issue 15 goal 2, issue 16 items 1 and 2)."""
import os
import time

import numpy as np
import pytest
import xarray as xr

import mechsweep
from mechsweep.execution import execute, runner
from mechsweep.cli import main
from mechsweep.errors import InputError

from tests.conftest import REPO

# what differs between two runs of a scene (their times), and between the routes: the in-memory
# route cuts the grid into as few chunks as memory allows when no progress bar is shown
# what differs between two runs of one scene: when (created, history begins with the time), how long, how chunked
# (the plan records the chunk cut too)
TIME_ATTRS = ("created", "history", "wall_time_s", "compile_time_s", "compute_time_s", "chunk_size", "n_chunks", "plan")


def _files(root):
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


def _without_times(ds):
    ds = ds.copy()
    for k in TIME_ATTRS:
        ds.attrs.pop(k, None)
    return ds


def test_in_memory_route_is_the_file_route_without_a_file(in_tmp, small_duffing):
    before = _files(in_tmp)
    mem = mechsweep.run(small_duffing, output=None)
    assert _files(in_tmp) == before, "output=None wrote something"
    stored = mechsweep.run(small_duffing, output="data/runs/s.h5")
    # bitwise the same values, names, dims, units, attributes (but the times of the run)
    xr.testing.assert_identical(_without_times(mem), _without_times(stored))
    for name in ("period", "kv", "status", "n_steps"):
        np.testing.assert_array_equal(mem[name].values, stored[name].values)
    assert mem["status"].dtype == stored["status"].dtype == np.int8


def test_in_memory_route_with_categorical_axis_and_extra_dims(in_tmp):
    from tests.models.test_linkage import GEO

    torsional = REPO / "sweeps" / "torsional_circuit_nomogram.toml"  # a categorical axis (spring)
    fourbar = {"scene": {"name": "fourbar", "model": "fourbar_balancing",  # curves over phi
                         "outputs": ["R_axis", "dM_max_axis", "M_static_phi", "dM_axis_phi"]},
               "axes": {"a4": [0.4, 0.42, 0.6]},
               "fixed": dict({k: v for k, v in GEO.items() if k != "a4"}, omega=20.0, branch="crossed")}
    for i, scene in enumerate((torsional, fourbar)):
        mem = mechsweep.run(scene, output=None)
        stored = mechsweep.run(scene, output=f"data/runs/{i}.h5")
        xr.testing.assert_identical(_without_times(mem), _without_times(stored))


@pytest.mark.parametrize("option", [{"resume": True}, {"restart": True}, {"overwrite": True}, {"load": True},
                                    {"scheduler": "tcp://127.0.0.1:8786"}])
def test_in_memory_route_refuses_file_options(in_tmp, small_duffing, option):
    with pytest.raises(InputError, match="output=None"):
        mechsweep.run(small_duffing, output=None, **option)


def _slow_compile(monkeypatch, offset=1000.0, sleep=0.0):
    """The first evaluation of a run (the compile phase) moves the run's clock on by ``offset`` s."""
    shift = [0.0]
    monkeypatch.setattr(execute, "_WARM", set())  # as in a fresh process: the compile phase runs
    real = execute.evaluate_rows
    calls = [0]

    def evaluate_rows(scene, P, *rest):
        calls[0] += 1
        if calls[0] == 1:
            shift[0] += offset
            time.sleep(sleep)
        return real(scene, P, *rest)

    monkeypatch.setattr(execute, "evaluate_rows", evaluate_rows)
    monkeypatch.setattr(execute, "clock", lambda: time.perf_counter() + shift[0])
    return calls


@pytest.mark.parametrize("output", [None, "data/runs/s.h5"])
def test_compile_time_stored_apart_from_compute_time(in_tmp, small_duffing, monkeypatch, output):
    calls = _slow_compile(monkeypatch)
    ds = mechsweep.run(small_duffing, output=output, progress=False)
    a = ds.attrs
    assert calls[0] >= 2  # the compile phase computed one point, the chunks the grid
    assert a["compile_time_s"] >= 1000.0  # the compile phase is counted as compile time ...
    assert 0.0 <= a["compute_time_s"] < 1000.0  # ... and not as compute time
    assert a["wall_time_s"] == pytest.approx(a["compile_time_s"] + a["compute_time_s"])


def test_compile_phase_shown_before_the_progress_bar(in_tmp, small_duffing, monkeypatch, capsys):
    monkeypatch.setattr(execute, "COMPILE_NOTE_AFTER", 0.05)
    _slow_compile(monkeypatch, offset=0.0, sleep=0.5)
    mechsweep.run(small_duffing, output="data/runs/s.h5", progress=True)
    err = capsys.readouterr().err
    note = err.find("compiling kernels for model duffing (first run; cached afterwards)")
    assert note >= 0, err
    assert "kernels compiled in" in err
    assert note < err.find("small:"), "the compile note comes before the progress bar"


def test_summary_of_a_resumed_dataset_without_times_apart(in_tmp, small_duffing):
    """A dataset written before compile and compute were stored apart reads as all compute."""
    import h5py

    mechsweep.run(small_duffing, output="data/runs/s.h5")
    with h5py.File("data/runs/s.h5", "a") as f:
        del f.attrs["compile_time_s"], f.attrs["compute_time_s"]
        f.attrs["wall_time_s"] = 2.5
    assert runner._times(in_tmp / "data/runs/s.h5") == (2.5, 0.0, 2.5)


SCENE = """\
[scene]
name = "fresh"
model = "duffing"
outputs = ["period_exact"]
[axes]
A = { start = 0.1, stop = 1.0, num = 5 }
[fixed]
omega = 1.0
mu = 1.0
"""


def test_run_outside_the_repository_creates_the_default_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "fresh.toml").write_text(SCENE)
    assert main(["run", "fresh.toml", "--no-progress"]) == 0
    out = capsys.readouterr().out
    target = tmp_path / "data" / "runs" / "fresh.h5"
    assert target.is_file()
    assert f"wrote {target.resolve()}:" in out  # where the file went, as an absolute path
    assert "compile" in out and "compute" in out


def test_refused_run_creates_no_default_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "fresh.toml").write_text(SCENE)
    assert main(["run", "fresh.toml", "--no-progress", "--threads", "999"]) == 2
    assert "threads" in capsys.readouterr().err
    assert not (tmp_path / "data").exists()


def test_default_folder_under_a_file_is_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "data").write_text("a file where the folder would go")
    (tmp_path / "fresh.toml").write_text(SCENE)
    assert main(["run", "fresh.toml", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "not a folder" in err and "Traceback" not in err
    assert (tmp_path / "data").read_text() == "a file where the folder would go"
    assert not os.path.isdir(tmp_path / "data")


def test_plot_point_and_output_folder_names(in_tmp, small_duffing, capsys):
    mechsweep.run(small_duffing, output="data/runs/d.h5")
    plot = ["plot", "data/runs/d.h5", "--kind", "amplitude_period", "--format", "svg"]
    assert main(plot) == 0
    full = in_tmp / "data/runs/d.svg"
    drawn = full.read_bytes()
    capsys.readouterr()
    # a one-point figure gets names of its own, the full grid's figure is left as it was
    assert main(plot + ["--point", "A=0.4,mu=2"]) == 0
    point = in_tmp / "data/runs/d_at_A0.4_mu2.0625.svg"
    assert f"wrote {point.relative_to(in_tmp)}" in capsys.readouterr().out
    assert point.is_file() and full.read_bytes() == drawn
    # -o an existing folder: the figures go into it under their default names
    (in_tmp / "figs").mkdir()
    assert main(["plot", "data/runs/d.h5", "-o", "figs"]) == 0, capsys.readouterr().err
    names = sorted(p.name for p in (in_tmp / "figs").iterdir())
    assert names == ["d_amplitude_period.png", "d_kinematic_coefficients.png"]
    assert main(["plot", "data/runs/d.h5", "-o", "nofolder/"]) == 2
    assert "nofolder/: the folder does not exist" in capsys.readouterr().err


def test_reading_a_dataset_imports_no_kernels(in_tmp, small_duffing):
    """`mechsweep plot` and open_dataset import neither numba nor the models (the package's names
    are imported when first used): a warm plot does not pay for them."""
    import subprocess
    import sys

    mechsweep.run(small_duffing, output="data/runs/s.h5")
    code = ("import sys, mechsweep; from mechsweep.cli import main; mechsweep.open_dataset('data/runs/s.h5'); "
            "assert main(['plot', 'data/runs/s.h5', '--list']) == 0; "
            "print(sorted(m for m in ('numba', 'mechsweep.models', 'mechsweep.execution.runner') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=in_tmp,
                         env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"
    assert mechsweep.run is runner.run and mechsweep.open_dataset is mechsweep.store.open_dataset


def test_file_route_returns_the_file_dataset_without_reading_it_back(in_tmp, small_duffing, monkeypatch):
    # run(output=path) keeps the dataset in memory as the file is written (store.assemble.MemorySink): what it
    # returns is the file's content, attributes and times included, and the file is not re-opened
    from mechsweep.store import journal

    returned = mechsweep.run(small_duffing, output="data/runs/h.h5")
    xr.testing.assert_identical(returned, mechsweep.open_dataset("data/runs/h.h5"))
    assert returned.attrs["compute_time_s"] > 0
    with monkeypatch.context() as m:
        m.setattr(runner, "open_dataset", lambda *a, **k: pytest.fail("the dataset was read back"))
        m.setattr(journal.Journal, "read_chunk",
                  lambda *a, **k: pytest.fail("a chunk of this run was read back from the journal"))
        again = mechsweep.run(small_duffing, output="data/runs/h.h5")
    xr.testing.assert_identical(again, mechsweep.open_dataset("data/runs/h.h5"))


def test_the_run_command_writes_its_file_without_importing_xarray(tmp_path):
    """`mechsweep run` defines and writes the HDF5 file with h5netcdf and h5py and returns no Dataset:
    xarray (and pandas under it, about 0.3 s of CPU in every warm run) is imported only where a Dataset
    is made (open_dataset, the in-memory route), not by the command."""
    import subprocess
    import sys

    scene = tmp_path / "s.toml"
    scene.write_text('[scene]\nname = "noxr"\nmodel = "duffing"\noutputs = ["period_exact"]\n'
                     '[axes]\nA = { start = 0.1, stop = 1.0, num = 4 }\n[fixed]\nmu = 1.0\nomega = 1.0\n')
    out = tmp_path / "s.h5"
    code = ("import sys\nfrom mechsweep.cli import main\n"
            f"rc = main(['run', {str(scene)!r}, '-o', {str(out)!r}, '--no-progress'])\n"
            "print(rc, sorted(m for m in ('xarray', 'pandas') if m in sys.modules))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip().splitlines()[-1] == "0 []"
    assert xr.open_dataset(out, engine="h5netcdf").attrs["xarray_version"] == xr.__version__


# ----------------------------------------------------------------------------- outputs among other runs' files
SCENE_TOML = """
[scene]
name = "paths"
model = "duffing"
outputs = ["period_exact"]
[axes]
A = { start = 0.1, stop = 1.0, num = 4 }
[fixed]
omega = 1.0
mu = 1.0
"""


def _tree(root):
    return sorted((str(p.relative_to(root)), p.is_symlink(), p.is_dir() and not p.is_symlink(),
                   p.read_bytes() if p.is_file() and not p.is_symlink() else None) for p in root.rglob("*"))


@pytest.mark.parametrize("output,said", [
    ("data/runs/other.h5.partial/x.h5", "is inside"),
    ("data/runs/other.h5.partial/chunks/x.h5", "is inside"),
    ("data/runs/other.h5.partial/run.json", "is inside"),
    ("data/runs/other.h5.partial.discard/x.h5", "is inside"),
    ("data/link/x.h5", "is inside"),  # a link to the journal folder
    ("data/runs/x.h5.partial", "is the one mechsweep gives the journal or the lock of another output"),
    ("data/runs/x.h5.partial.discard", "is the one mechsweep gives"),
    ("data/runs/.x.h5.lock", "is the one mechsweep gives"),
])
def test_an_output_in_a_journal_folder_or_named_as_a_journal_or_lock_is_refused(in_tmp, capsys, output, said):
    """A run of other.h5 removes its journal folder when it ends (and takes .other.h5.lock and
    other.h5.partial for its own): an output there is refused before anything is written."""
    runs = in_tmp / "data" / "runs"
    (runs / "other.h5.partial" / "chunks").mkdir(parents=True)
    (runs / "other.h5.partial.discard").mkdir()
    (in_tmp / "data" / "link").symlink_to(runs / "other.h5.partial")
    (in_tmp / "s.toml").write_text(SCENE_TOML)
    before = _tree(in_tmp)
    assert main(["run", "s.toml", "-o", output, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err, err
    if said == "is inside":
        assert "the journal folder of an unfinished run of" in err and "other.h5" in err, err
    with pytest.raises(mechsweep.StoreError, match=said):
        mechsweep.run(mechsweep.load_scene(in_tmp / "s.toml"), output=output, progress=False)
    assert _tree(in_tmp) == before


@pytest.mark.parametrize("what", ["a user's file", "a link"])
def test_a_lock_path_holding_something_else_is_refused_and_kept(in_tmp, capsys, what):
    """Taking the lock empties the lock file (it holds the run's process id) and releasing it removes
    it: a file there that is not a lock (or a link to one) is refused, not emptied."""
    lock = in_tmp / "data" / "runs" / ".out.h5.lock"
    mine = in_tmp / "mine.txt"
    mine.write_text("the user's data\n")
    if what == "a link":
        lock.symlink_to(mine)
    else:
        lock.write_text("the user's data\n")
    (in_tmp / "s.toml").write_text(SCENE_TOML)
    before = _tree(in_tmp)
    assert main(["run", "s.toml", "-o", "data/runs/out.h5", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert ".out.h5.lock (the run's lock)" in err and "move it away" in err, err
    assert _tree(in_tmp) == before


def test_a_lock_file_of_a_killed_run_is_taken_over(in_tmp, capsys):
    """A lock file a killed run left (its process id, or nothing) is a lock: the run goes on."""
    (in_tmp / "s.toml").write_text(SCENE_TOML)
    for content in ("12345", ""):
        (in_tmp / "data" / "runs" / ".out.h5.lock").write_text(content)
        assert main(["run", "s.toml", "-o", "data/runs/out.h5", "--no-progress"]) == 0, capsys.readouterr().err
        assert sorted(os.listdir(in_tmp / "data" / "runs")) == ["out.h5"]
