"""`run()` writes its dataset's file while the chunks are computed (store.assemble.Early):
the file it places is the one the chunk-by-chunk assembly writes (every variable bitwise), and a
failed write of it changes nothing a run promises: a passing failure is repaired by the assembly,
a lasting one is reported with the journal kept, and the run resumes to the same dataset."""
import errno
import os

import h5py
import numpy as np
import pytest

import mechsweep
from mechsweep.execution import execute, runner
from mechsweep.store.journal import partial_path

from tests.data.interrupt import interrupted_after
from tests.test_faults import SCENE as FAULTS_SCENE

SCENE = FAULTS_SCENE.replace('name = "faults"', 'name = "early"')  # the fault tests' small grid: 8 chunks of 100
N_CHUNKS = 8
OUT = "data/runs/e.h5"


@pytest.fixture
def scene_file(in_tmp):
    (in_tmp / "early.toml").write_text(SCENE)
    return in_tmp / "early.toml"


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The dataset as `compute` (the command's route) assembles it from the journal at the end."""
    where = tmp_path_factory.mktemp("ref")
    (where / "early.toml").write_text(SCENE)
    runner.compute(mechsweep.load_scene(where / "early.toml"), output=where / "ref.h5", progress=False)
    return where / "ref.h5"


def assert_same_file(path, reference):
    """Every variable bitwise, with its dtype, storage chunks, filters and attributes; the file's
    attributes but the times."""
    with h5py.File(path, "r") as a, h5py.File(reference, "r") as b:
        assert sorted(a) == sorted(b)
        for name in b:
            x, y = a[name], b[name]
            assert x.dtype == y.dtype and x.shape == y.shape, name
            assert (x.chunks, x.compression, x.shuffle) == (y.chunks, y.compression, y.shuffle), name
            if x.dtype.kind == "O":
                assert list(np.ravel(x[()])) == list(np.ravel(y[()])), name
            else:
                assert np.ravel(x[()]).tobytes() == np.ravel(y[()]).tobytes(), name
            ignore = {"DIMENSION_LIST", "REFERENCE_LIST"}
            assert ({k: str(v) for k, v in x.attrs.items() if k not in ignore}
                    == {k: str(v) for k, v in y.attrs.items() if k not in ignore}), name
        times = {"created", "history", "wall_time_s", "compile_time_s", "compute_time_s"}
        assert [k for k in a.attrs if k not in times] == [k for k in b.attrs if k not in times]
        for k in b.attrs:
            if k not in times:
                assert str(a.attrs[k]) == str(b.attrs[k]), k


def assert_no_leftovers(folder):
    assert sorted(p.name for p in (folder / OUT).parent.iterdir()) == ["e.h5"], "journal, lock or temporary files left"


def test_run_writes_its_file_while_the_chunks_are_computed(scene_file, reference, monkeypatch):
    seen, real = [], execute.evaluate_chunk

    def watching(scene, chunk, *rest):
        seen.append((partial_path(scene_file.parent / OUT) / "assembly.h5").exists())
        return real(scene, chunk, *rest)

    monkeypatch.setattr(execute, "evaluate_chunk", watching)
    ds = mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, progress=False)
    assert len(seen) == N_CHUNKS
    # the third chunk is computed after the first one was saved and written into the file (the file
    # itself may be there from the first chunk on: it is defined while that chunk is computed)
    assert all(seen[2:]), seen
    assert_same_file(scene_file.parent / OUT, reference)
    assert_no_leftovers(scene_file.parent)
    back = mechsweep.open_dataset(scene_file.parent / OUT)
    for name in ("period", "period_exact", "v_max", "status", "n_steps", "n_rhs"):
        np.testing.assert_array_equal(ds[name].values, back[name].values, err_msg=name)


def test_the_file_is_defined_while_the_first_chunk_is_computed(scene_file, reference, monkeypatch):
    """store.assemble.Early.prepare runs in the writer thread as soon as the first chunk's kernel is launched,
    not after that chunk is saved: the first chunk waits here until the file appears."""
    import time

    seen, real = [], execute.evaluate_chunk
    path = partial_path(scene_file.parent / OUT) / "assembly.h5"

    def waiting(scene, chunk, *rest):
        if chunk.index == 0:
            deadline = time.monotonic() + 10.0
            while not path.exists() and time.monotonic() < deadline:
                time.sleep(0.005)
            seen.append(path.exists())
        return real(scene, chunk, *rest)

    monkeypatch.setattr(execute, "evaluate_chunk", waiting)
    mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, progress=False)
    assert seen == [True]
    assert_same_file(scene_file.parent / OUT, reference)
    assert_no_leftovers(scene_file.parent)


def _fd_name(fd) -> str:
    try:
        return os.readlink(f"/proc/self/fd/{fd}")
    except OSError:
        return ""


def failing_file_writes(monkeypatch, first: int, last: int):
    """os.pwrite to the journal's assembly.h5 fails (disk full) on its calls first..last."""
    real, calls = os.pwrite, [0]

    def pwrite(fd, data, offset):
        if _fd_name(fd).endswith("assembly.h5"):
            calls[0] += 1
            if first <= calls[0] <= last:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(fd, data, offset)

    monkeypatch.setattr(os, "pwrite", pwrite)
    return calls


def test_a_passing_write_failure_of_the_early_file_is_repaired_by_the_assembly(scene_file, reference, monkeypatch):
    calls = failing_file_writes(monkeypatch, 6, 6)
    mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, progress=False)
    assert calls[0] > 6
    assert_same_file(scene_file.parent / OUT, reference)
    assert_no_leftovers(scene_file.parent)


def test_a_lasting_write_failure_of_the_early_file_keeps_the_journal_and_resumes(scene_file, reference,
                                                                                 monkeypatch):
    with monkeypatch.context() as mp:
        failing_file_writes(mp, 6, 10**9)
        with pytest.raises(runner.OutOfSpace, match=f"journal kept \\({N_CHUNKS} of {N_CHUNKS} chunks saved"):
            mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, progress=False)
    part = partial_path(scene_file.parent / OUT)
    assert sorted(p.name for p in part.iterdir()) == ["chunks", "run.json"], "a half-written file was left"
    mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, resume=True, progress=False)
    assert_same_file(scene_file.parent / OUT, reference)
    assert_no_leftovers(scene_file.parent)


def test_an_interrupted_run_leaves_no_half_written_file_and_resumes(scene_file, reference):
    with interrupted_after(4):
        with pytest.raises(mechsweep.RunInterrupted):
            mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, progress=False)
    part = partial_path(scene_file.parent / OUT)
    assert sorted(p.name for p in part.iterdir()) == ["chunks", "run.json"], "a half-written file was left"
    assert len(list((part / "chunks").iterdir())) == 4
    mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, resume=True, progress=False)
    assert_same_file(scene_file.parent / OUT, reference)
    assert_no_leftovers(scene_file.parent)


LINE = """
[scene]
name = "line"
model = "duffing"
outputs = ["period"]
[axes]
mu = { start = 1e-3, stop = 1e3, num = 100000, spacing = "log" }
[fixed]
A = 0.5
omega = 1.0
"""


def test_without_a_progress_bar_a_grid_is_cut_in_few_large_chunks_and_resumes_with_its_own_cut(in_tmp):
    """Without a bar, 100,000 integrated points are 2 chunks of 65536 (with one: 20 of 5000, the
    least 20 chunks of a bar); a run interrupted so is resumed with its journal's cut, bar or not."""
    (in_tmp / "line.toml").write_text(LINE)
    scene = mechsweep.load_scene(in_tmp / "line.toml")
    from mechsweep.chunks import plan_chunks
    from mechsweep.grid import chunk_target

    assert (chunk_target(scene), len(plan_chunks(scene.shape, chunk_target(scene)))) == (5000, 20)
    with interrupted_after(1):
        with pytest.raises(mechsweep.RunInterrupted, match="1 of 2 chunks saved"):
            mechsweep.run(scene, output="data/runs/line.h5", progress=False)
    done = mechsweep.run(scene, output="data/runs/line.h5", resume=True, progress=True)
    assert done.attrs["n_chunks"] == 2 and done.attrs["chunk_size"] == 65536
    whole = mechsweep.run(scene, output=None)
    np.testing.assert_array_equal(done["period"].values, whole["period"].values)
