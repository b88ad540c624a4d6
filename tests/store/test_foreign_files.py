"""Foreign, damaged and odd files handed to mechsweep (issue 12, items 5-9 and 11).

Every command that opens a dataset (info, plot, run --resume, run onto an existing output, the
Python open_dataset) goes through one validating opener: a file that is not a dataset mechsweep
wrote is refused with one line saying what it is not, exit 2, and nothing is created or changed.
Outputs, locks and journals that are not regular files and folders are refused the same way, and
so are benchmark options out of range. Only test_run_onto_existing_datasets computes (a 3-point
closed-form grid); the others never reach the engine (the tripwire of test_hostile_scenes).
"""
from __future__ import annotations

import os
import shutil
import socket
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import mechsweep
from mechsweep import StoreError
from mechsweep.execution import checks, execute, runner
from mechsweep.cli import main

from tests.test_hostile_scenes import VALID, existing_dataset, refused, snapshot, work  # noqa: F401 (fixture)

FILES = Path(__file__).resolve().parents[1] / "hostile" / "files"

# file of tests/hostile/files -> what the message must say the file is
FOREIGN = {
    "text.h5": "a text file, not HDF5",
    "empty.h5": "an empty file",
    "random_bytes.h5": "a file of another format, not HDF5",
    "png_image.h5": "a file of another format, not HDF5",
    "hdf5_signature_then_garbage.h5": "an HDF5 file that cannot be read, damaged or truncated",
    "truncated_dataset.h5": "truncated file",
    "netcdf3_classic.nc": "a netCDF-3 file",
    "foreign_netcdf4.nc": "without the attribute(s) scene_canonical, model, outputs",
    "plain_hdf5_groups.h5": "without the attribute(s)",
    "run_without_status.h5": "lacks the variable(s) status",
    "run_without_scene_canonical.h5": "without the attribute(s) scene_canonical",
}


LOOKALIKE = "lookalike_strings.h5"  # a run's attributes and variables, not their layout


def test_every_foreign_file_has_an_expectation():
    assert {p.name for p in FILES.iterdir() if p.suffix in (".h5", ".nc")} == set(FOREIGN) | {LOOKALIKE}


def test_lookalike_dataset_is_refused_not_a_traceback(work, capsys):
    path = _copy(LOOKALIKE, work)
    refused(capsys, ["info", path], work, "is not laid out as a mechsweep dataset")
    refused(capsys, ["plot", path, "--point", "x=1"], work, "give a value for y, z too")
    refused(capsys, ["plot", path, "-o", "fig.png"], work, "no figure fits this dataset")


def _copy(name: str, work: Path) -> str:
    shutil.copy(FILES / name, work / name)
    return name


@pytest.mark.parametrize("name", sorted(FOREIGN))
def test_foreign_file_is_refused_by_every_reader(name, work, capsys):
    path = _copy(name, work)
    said = [f"{name} is not a mechsweep dataset", FOREIGN[name]]
    refused(capsys, ["info", path], work, *said)
    refused(capsys, ["plot", path], work, *said)
    refused(capsys, ["plot", path, "--list"], work, *said)
    refused(capsys, ["plot", path, "--point", "A=0.5", "-o", "fig.png"], work, *said)
    with pytest.raises(StoreError, match="is not a mechsweep dataset"):
        mechsweep.open_dataset(path)
    with pytest.raises(StoreError, match="is not a mechsweep dataset"):
        mechsweep.open_dataset(path, lazy=True)


@pytest.mark.parametrize("name", sorted(set(FOREIGN) - {"empty.h5"}))
def test_run_onto_a_foreign_file_is_refused(name, work, capsys):
    """run -o / run --resume onto a file mechsweep did not write (an empty file may be replaced);
    the engine's tripwire proves no work starts. A non-HDF5 file is refused by its header."""
    (work / "valid.toml").write_text(VALID)
    path = _copy(name, work)
    hdf5 = (FILES / name).read_bytes().startswith(b"\x89HDF")
    said = ["--overwrite"] if hdf5 else ["exists and is not an HDF5 dataset"]
    refused(capsys, ["run", "valid.toml", "-o", path], work, name, *said)
    refused(capsys, ["run", "valid.toml", "-o", path, "--resume"], work, name, *said)
    refused(capsys, ["run", "valid.toml", "-o", path, "--restart"], work, name, *said)


def _fifo(work: Path) -> str:
    os.mkfifo(work / "pipe.h5")
    return "pipe.h5"


def _socket(work: Path) -> str:
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(work / "sock.h5"))
    s.close()
    return "sock.h5"


def _folder(work: Path) -> str:
    (work / "folder.h5").mkdir()
    return "folder.h5"


def _broken_link(work: Path) -> str:
    (work / "link.h5").symlink_to(work / "nowhere.h5")
    return "link.h5"


NOT_FILES = {"fifo": (_fifo, "a named pipe (FIFO)"), "socket": (_socket, "a socket"),
             "folder": (_folder, "a directory"), "device": (lambda w: os.devnull, "a character device")}


@pytest.mark.parametrize("kind", sorted(NOT_FILES))
def test_readers_refuse_what_is_not_a_file(kind, work, capsys):
    make, said = NOT_FILES[kind]
    path = make(work)
    refused(capsys, ["info", path], work, "is not a mechsweep dataset", said)
    refused(capsys, ["plot", path], work, "is not a mechsweep dataset", said)
    with pytest.raises(StoreError, match=said.replace("(", r"\(").replace(")", r"\)")):
        mechsweep.open_dataset(path)


def test_nul_in_a_dataset_path_is_refused():
    with pytest.raises(StoreError, match="NUL character"):
        mechsweep.open_dataset("data/a\0b.h5")


def test_broken_link_is_a_missing_dataset(work, capsys):
    path = _broken_link(work)
    refused(capsys, ["info", path], work, "link.h5 does not exist")


# ----------------------------------------------------------------------------- item 8: outputs
@pytest.mark.parametrize("kind", ["fifo", "socket", "device", "broken_link"])
def test_run_refuses_an_output_that_is_not_a_regular_file(kind, work, capsys):
    (work / "valid.toml").write_text(VALID)
    path = {"fifo": _fifo, "socket": _socket, "device": lambda w: os.devnull, "broken_link": _broken_link}[kind](work)
    for flags in ([], ["--resume"], ["--restart"], ["--overwrite"]):
        refused(capsys, ["run", "valid.toml", "-o", path, "--no-progress", *flags], work,
                f"output path {path} is", "not a regular file")


WRONG_KIND = {
    "lock_folder": ".out.h5.lock (the run's lock) is a directory, not a file",
    "lock_fifo": ".out.h5.lock (the run's lock) is a named pipe (FIFO), not a file",
    "journal_fifo": "out.h5.partial (the journal of unfinished runs) is a named pipe (FIFO), not a folder",
    "journal_file_run_json_fifo": "run.json is a named pipe (FIFO), not a file",
    "journal_chunks_file": "chunks is a regular file, not a folder",
    "journal_chunk_fifo": "0000000.npz is not a chunk file",
    "discard_file": "out.h5.partial.discard (the run's journal being deleted) is a regular file, not a folder",
    "journal_assembly_fifo": "assembly.h5 is a named pipe (FIFO), not a file a run writes",
    "run_json_list": "run.json is not a run's journal (a JSON list",
    "run_json_not_json": "run.json is unreadable",
    "run_json_missing_keys": "run.json is damaged (entries scene_canonical, scene, chunk_target, n_chunks, attrs",
    "run_json_zero_chunks": "run.json is damaged",
}


@pytest.mark.parametrize("what", sorted(WRONG_KIND))
def test_run_refuses_lock_and_journal_paths_of_the_wrong_kind(what, work, capsys):
    (work / "valid.toml").write_text(VALID)
    out = work / "data" / "runs" / "out.h5"
    part = work / "data" / "runs" / "out.h5.partial"
    lock = work / "data" / "runs" / ".out.h5.lock"
    if what == "lock_folder":
        lock.mkdir()
    elif what == "lock_fifo":
        os.mkfifo(lock)
    elif what == "journal_fifo":
        os.mkfifo(part)
    elif what == "discard_file":
        (work / "data" / "runs" / "out.h5.partial.discard").write_text("x")
    else:
        (part / "chunks").mkdir(parents=True)
        if what == "journal_file_run_json_fifo":
            os.mkfifo(part / "run.json")  # reading it would block forever
        elif what.startswith("run_json"):
            zero = '{"format": 1, "scene_canonical": "", "scene": "", "chunk_target": 0, "n_chunks": 0, "attrs": {}}'
            (part / "run.json").write_text({"run_json_list": "[1, 2]", "run_json_not_json": "{not json",
                                            "run_json_missing_keys": '{"format": 1}',
                                            "run_json_zero_chunks": zero}[what])
        elif what == "journal_assembly_fifo":
            os.mkfifo(part / "assembly.h5")  # the run's last step would block writing into it
        elif what == "journal_chunks_file":
            (part / "chunks").rmdir()
            (part / "chunks").write_text("x")
        else:
            (part / "run.json").write_text("{}")
            os.mkfifo(part / "chunks" / "0000000.npz")
    flags = [] if what.startswith(("lock", "discard")) else ["--resume"]
    refused(capsys, ["run", "valid.toml", "-o", str(out), "--no-progress", *flags], work, WRONG_KIND[what])
    if what.startswith(("journal_", "run_json")):
        refused(capsys, ["info", str(out)], work, WRONG_KIND[what])  # the unfinished-run view too


# ----------------------------------------------------------------------------- item 9: scheduler
def test_unreachable_scheduler_leaves_nothing_behind(work, capsys, monkeypatch):
    pytest.importorskip("distributed")
    from mechsweep.execution import cluster

    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 1)
    (work / "valid.toml").write_text(VALID)
    refused(capsys, ["run", "valid.toml", "--no-progress", "--scheduler", "tcp://127.0.0.1:9"], work,
            "cannot reach the dask scheduler at 'tcp://127.0.0.1:9'")


@pytest.mark.parametrize("address, said", [
    ("foo://x:1", "unknown address scheme 'foo'"),
    ("tcp://127.0.0.1:99999", "port 99999"),
    ("tcp://host", "missing port number"),
    ("tcp://[::1", "invalid address"),
    ("inproc://x", "cannot reach the dask scheduler"),
])
def test_scheduler_addresses_dask_cannot_use_are_refused_before_any_file(address, said, work, capsys):
    pytest.importorskip("distributed")
    (work / "valid.toml").write_text(VALID)
    refused(capsys, ["run", "valid.toml", "--no-progress", "--scheduler", address], work, said)


def test_a_failed_connection_prints_one_line(in_tmp):
    """distributed's clean-up of a Client that failed to start waited 40 s at exit and printed a
    traceback ("Exception ignored in Client.__del__") after the error line."""
    pytest.importorskip("distributed")
    import subprocess

    (in_tmp / "valid.toml").write_text(VALID)
    proc = subprocess.run([sys.executable, "-m", "mechsweep.cli", "run", "valid.toml", "--no-progress",
                           "--scheduler", "inproc://x"], capture_output=True, text=True, cwd=in_tmp, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "cannot reach the dask scheduler" in proc.stderr, proc.stderr
    assert list((in_tmp / "data" / "runs").iterdir()) == []


# ----------------------------------------------------------------------------- item 7: replacing datasets
OTHER = VALID.replace("mu = 1.0", "mu = 2.0")


def test_run_onto_existing_datasets(in_tmp, capsys):
    """A run replaces a dataset of the same scene (idempotent), refuses one of another scene or a
    foreign file unless --overwrite; a refused run leaves the file byte for byte."""
    (in_tmp / "a.toml").write_text(VALID)
    (in_tmp / "b.toml").write_text(OTHER)
    out = in_tmp / "data" / "runs" / "hostile.h5"
    assert main(["run", "a.toml", "--no-progress", "--threads", "1"]) == 0
    assert main(["run", "a.toml", "--no-progress", "--threads", "1"]) == 0  # the same scene again
    kept = out.read_bytes()
    capsys.readouterr()
    for flags in ([], ["--restart"], ["--resume"]):
        assert main(["run", "b.toml", "--no-progress", *flags]) == 2
        err = capsys.readouterr().err
        assert "holds a finished run of a different scene" in err and "--overwrite" in err, err
        assert "Traceback" not in err
        assert out.read_bytes() == kept
        assert sorted(p.name for p in out.parent.iterdir()) == ["hostile.h5"]
    assert main(["run", "b.toml", "--no-progress", "--overwrite", "--threads", "1"]) == 0
    assert float(mechsweep.open_dataset(out)["mu"]) == 2.0
    # the API: the same refusal, and overwrite=True
    with pytest.raises(StoreError, match="different scene"):
        mechsweep.run("a.toml", progress=False)
    assert float(mechsweep.run("a.toml", progress=False, overwrite=True)["mu"]) == 1.0
    # a foreign HDF5 file at the output: refused, then replaced with --overwrite
    shutil.copy(FILES / "foreign_netcdf4.nc", out)
    assert main(["run", "a.toml", "--no-progress"]) == 2
    assert "is not a mechsweep dataset" in capsys.readouterr().err
    assert out.read_bytes() == (FILES / "foreign_netcdf4.nc").read_bytes()
    assert main(["run", "a.toml", "--no-progress", "--overwrite", "--threads", "1"]) == 0
    assert mechsweep.open_dataset(out).attrs["model"] == "duffing"


def test_damaged_data_is_refused_however_the_dataset_is_opened(work, capsys, monkeypatch):
    """Header and attributes intact, one compressed storage chunk overwritten: loading fails, and so
    does reading it lazily (datasets above LOAD_LIMIT_BYTES) while info summarises it."""
    import h5py
    import xarray as xr

    from mechsweep.store import read as store_read

    n = 5000
    xr.Dataset({"period_exact": ("A", np.linspace(1, 2, n)), "status": ("A", np.zeros(n, np.int8))},
               coords={"A": np.linspace(0, 1, n)},
               attrs={"model": "duffing", "outputs": "period_exact", "scene_canonical": "{}", "scene": ""}
               ).to_netcdf(work / "z.h5", engine="h5netcdf",
                           encoding={v: {"zlib": True, "chunksizes": (1000,)} for v in ("period_exact", "status")})
    with h5py.File(work / "z.h5") as f:
        offset = f["period_exact"].id.get_chunk_info(1).byte_offset
    data = bytearray((work / "z.h5").read_bytes())
    data[offset:offset + 50] = b"\xff" * 50
    (work / "z.h5").write_bytes(bytes(data))
    refused(capsys, ["info", "z.h5"], work, "z.h5 is not a readable mechsweep dataset", "filter returned failure")
    refused(capsys, ["plot", "z.h5"], work, "z.h5 is not a readable mechsweep dataset")
    monkeypatch.setattr(store_read, "LOAD_LIMIT_BYTES", 0)  # info opens it lazily
    refused(capsys, ["info", "z.h5"], work, "z.h5 cannot be read, it is damaged", "filter returned failure")


def test_benchmark_dataset_is_not_a_run(work, capsys):
    import xarray as xr

    xr.Dataset({"error": ("rtol", np.ones(2))}, coords={"rtol": [1e-6, 1e-8]},
               attrs={"mechsweep_kind": "workprecision"}).to_netcdf(work / "wp.h5", engine="h5netcdf")
    (work / "valid.toml").write_text(VALID)
    refused(capsys, ["info", "wp.h5"], work, "wp.h5 is a mechsweep benchmark dataset (workprecision), not a run")
    refused(capsys, ["run", "valid.toml", "-o", "wp.h5"], work, "benchmark dataset, not a run", "--overwrite")


def test_run_help_documents_overwrite(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--overwrite" in text and "a dataset of a different scene" in text


def test_same_scene_is_recognised_through_its_stored_text():
    """A dataset whose stored canonical form differs in spelling (e.g. an older version's) but
    whose stored scene text is the same scene counts as the same scene."""
    scene = mechsweep.scene.load_scene_text(VALID)
    attrs = {"scene_canonical": "an older spelling", "scene": VALID}
    assert checks.same_scene(attrs, scene)
    assert not checks.same_scene({**attrs, "scene": OTHER}, scene)
    assert not checks.same_scene({"scene_canonical": "x", "scene": "not toml ["}, scene)


# ----------------------------------------------------------------------------- plot: figure path, --point
def test_plot_refuses_to_overwrite_its_dataset(work, capsys):
    existing_dataset(work / "X.png")  # a dataset named like a figure
    refused(capsys, ["plot", "X.png", "--kind", "curve_period_exact"], work, "X.png is the dataset X.png itself")
    refused(capsys, ["plot", "X.png"], work, "is the dataset")
    existing_dataset(work / "d.h5")
    os.link(work / "d.h5", work / "hard.png")
    (work / "soft.png").symlink_to(work / "d.h5")
    refused(capsys, ["plot", "d.h5", "-o", "hard.png"], work, "is the dataset d.h5 itself")
    refused(capsys, ["plot", "d.h5", "-o", "soft.png"], work, "is the dataset d.h5 itself")
    existing_dataset(work / "other.png")
    refused(capsys, ["plot", "d.h5", "-o", "other.png"], work, "other.png is an HDF5 file")
    (work / "fig_dir.png").mkdir()
    refused(capsys, ["plot", "d.h5", "-o", "fig_dir.png"], work, "is not a regular file")


@pytest.mark.parametrize("point, said", [
    ("A=nan", "A = nan is not a finite number"),
    ("A=inf", "A = inf is not a finite number"),
    ("A=-inf", "is not a finite number"),
    ("A=100", "A = 100 is outside the grid (0.1 .. 1)"),
    ("A=-1e300", "is outside the grid"),
    ("A=1.26", "is outside the grid"),  # beyond the last value by more than half the last step
])
def test_plot_point_outside_the_grid_is_refused(point, said, work, capsys):
    existing_dataset(work / "d.h5")
    refused(capsys, ["plot", "d.h5", "--point", point, "--list"], work, said)


def test_plot_point_within_half_a_step_is_the_nearest(work, capsys):
    existing_dataset(work / "d.h5")  # A = 0.1, 0.5, 1.0
    for point in ("A=1.24", "A=-0.09", "A=0.7"):
        assert main(["plot", "d.h5", "--point", point, "--list"]) == 0, capsys.readouterr().err


# ----------------------------------------------------------------------------- item 11: bench and API
BENCH = [
    (["duffing", "--points", "-5"], "points = -5"),
    (["duffing", "--points", "0"], "points = 0"),
    (["duffing", "--scipy-points", "0"], "scipy_points = 0"),
    (["duffing", "--threads", "0"], "threads = 0"),
    (["duffing", "--threads", "100000"], "threads = 100000"),
    (["duffing", "--rtol", "0"], "rtol = 0.0"),
    (["duffing", "--rtol", "nan"], "rtol = nan"),
    (["duffing", "--atol", "-1"], "atol = -1.0"),
    (["workprecision", "duffing", "--points", "0"], "points = 0"),
    (["workprecision", "duffing", "--scipy-points", "-2"], "scipy_points = -2"),
    (["workprecision", "duffing", "--repeats", "0"], "repeats = 0"),
    (["workprecision", "duffing", "--rtol", "5"], "rtol = 5.0"),
    (["workprecision", "duffing", "--rtol", "1e-8", "inf"], "rtol = inf"),
    (["workprecision", "nosuchmodel"], "no work-precision case for model 'nosuchmodel'"),
    (["workprecision", "fourbar_balancing", "--positions", "2"], "need at least 4 crank positions"),
    (["workprecision", "fourbar_balancing", "--positions", "12", "-3"], "positions = -3"),
    (["workprecision", "fourbar_balancing", "--points", "-1"], "points = -1"),
    (["workprecision", "fourbar_balancing", "--repeats", "0"], "repeats = 0"),
    (["workprecision", "duffing", "--out", "a_file"], "a_file is a file, not a folder"),
    (["workprecision", "duffing", "--out", "a_file/sub"], "a_file is a file, not a folder"),
]


@pytest.fixture
def no_bench_work(work, monkeypatch):
    """A benchmark that passed its argument checks would start computing: fail loudly instead."""
    import numba

    def tripwire(*args, **kwargs):
        raise AssertionError("the benchmark started despite a bad option")

    from mechsweep.bench import duffing, workprecision, workprecision_linkage

    monkeypatch.setattr(numba, "set_num_threads", tripwire)
    for mod in (duffing, workprecision, workprecision_linkage):
        monkeypatch.setattr(mod, "load_scene", tripwire)
    (work / "a_file").write_text("x")
    return work


@pytest.mark.parametrize("argv, said", BENCH, ids=[" ".join(a) for a, _ in BENCH])
def test_bench_options_out_of_range_are_refused(argv, said, no_bench_work, capsys):
    refused(capsys, ["bench", *argv], no_bench_work, said)


def test_bench_functions_refuse_bad_arguments_too():
    from mechsweep.bench import duffing
    from mechsweep.errors import InputError

    with pytest.raises(InputError, match="points = -5"):
        duffing.main(points=np.int64(-5))
    from mechsweep.bench import workprecision, workprecision_linkage

    with pytest.raises(InputError, match="rtol = 'x'"):
        workprecision.main("duffing", ladder="x")
    with pytest.raises(InputError, match="need at least 4 crank positions"):
        workprecision_linkage.main("fourbar_balancing", positions=np.int64(3))
    with pytest.raises(InputError, match="no linkage work-precision case"):
        workprecision_linkage.main(["fourbar_balancing"])


def test_api_takes_numpy_numbers(small_duffing):
    """np.float64 / np.int64 / np.bool_-free numpy scalars and arrays are numbers, like in TOML."""
    s = small_duffing
    s["axes"] = {"A": {"start": np.float64(0.1), "stop": np.float32(1.0), "num": np.int64(4)},
                 "mu": np.array([0.5, 2.0])}
    s["fixed"] = {"omega": np.int64(2)}
    s["solver"] = {"rtol": np.float64(1e-9), "max_steps": np.int32(1000), "t_max_periods": np.int64(3)}
    s["storage"] = {"chunk_size": np.uint16(10)}
    scene = mechsweep.load_scene(s)
    assert scene.shape == (4, 2) and scene.fixed["omega"] == 2.0
    assert scene.solver.max_steps == 1000 and scene.storage.chunk_size == 10
    assert mechsweep.scene.load_scene_text(scene.text).canonical() == scene.canonical()
    omega = mechsweep.MODELS["duffing"].param("omega")
    assert omega.problem(np.float32(2.0)) is None and omega.problem(np.int64(2)) is None
    assert "is not a number" in omega.problem(np.bool_(True))
    horizon = mechsweep.MODELS["autobalancer"].settings[1]
    assert horizon.problem(np.int16(300)) is None


@pytest.mark.parametrize("threads", [1.0, np.float64(1.0), "1", True])
def test_api_thread_count_must_be_a_whole_number(threads, in_tmp, small_duffing):
    with pytest.raises(mechsweep.errors.InputError, match="threads = .* is not allowed; expected a whole number"):
        mechsweep.run(small_duffing, output="data/runs/t.h5", threads=threads)
    assert list((in_tmp / "data" / "runs").iterdir()) == []


def test_extreme_parameters_give_no_numpy_warnings():
    """Overflowing closed forms at extreme (valid) parameters give a status, not warnings on stderr."""
    from mechsweep.chunks import plan_chunks

    scene = mechsweep.load_scene({
        "scene": {"name": "x", "model": "autobalancer", "outputs": ["P_approx", "omega_p", "stable_first_approx"]},
        "axes": {"Omega": [1e200, 1e300]},
        "fixed": {"M": 1e-300, "m": 1e300, "a": 0.1, "I_B": 1e300, "A0": 0.1, "h": 0.02, "omega_xi": 1e300,
                  "omega_eta": 30.0, "zeta_xi": 0.05, "zeta_eta": 0.05}})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, status, _, _ = execute.evaluate_chunk(scene, plan_chunks(scene.shape, 10)[0])
    assert (status != 0).all()
