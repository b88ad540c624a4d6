"""Faults a run must survive with its journal kept and a clear message (issue 12, items 13-17):
a failed write at every stage that writes (disk full, file-size limit, quota, I/O error), damaged
chunk files, contradictory flags, SIGTERM/SIGINT at any moment. After each, the run resumes to a
dataset bitwise identical to an uninterrupted run."""
import errno
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import mechsweep
from mechsweep import cli
from mechsweep.execution import execute, runner
from mechsweep.store import journal
from mechsweep.store.journal import Journal, partial_path
from mechsweep.errors import InputError
from mechsweep.scene import Execution

from .conftest import ctrl_c_as_from_a_terminal
from .data.interrupt import interrupted_after

SCENE = """
[scene]
name = "faults"
model = "duffing"
outputs = ["period", "period_exact", "v_max"]
[axes]
A = { start = 0.01, stop = 1.0, num = 40 }
mu = { start = 1e-3, stop = 1e3, num = 20, spacing = "log" }
[fixed]
omega = 1.0
[storage]
chunk_size = 100
"""
N_CHUNKS = 8
COMPARED = ("period", "period_exact", "v_max", "status", "n_steps", "n_rhs", "A", "mu")
OUT = "data/runs/f.h5"


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    where = tmp_path_factory.mktemp("ref")
    (where / "faults.toml").write_text(SCENE)
    mechsweep.run(mechsweep.load_scene(where / "faults.toml"), output=where / "ref.h5", progress=False)
    return where / "ref.h5"


@pytest.fixture
def scene_file(in_tmp):
    (in_tmp / "faults.toml").write_text(SCENE)
    return in_tmp / "faults.toml"


def resume_and_compare(folder, reference):
    """Complete the run with --resume and compare it with the uninterrupted one, bit for bit."""
    done = mechsweep.run(mechsweep.load_scene(folder / "faults.toml"), output=folder / OUT, resume=True,
                         progress=False)
    ref = mechsweep.open_dataset(reference)
    for name in COMPARED:
        np.testing.assert_array_equal(done[name].values, ref[name].values, err_msg=name)
    left = sorted(p.name for p in (folder / OUT).parent.iterdir())
    assert left == ["f.h5"], f"journal, lock or temporary files left: {left}"


def journal_files(folder):
    """The journal's files (names), after checking that every chunk file in it verifies."""
    part = partial_path(folder / OUT)
    if not part.exists():
        return None
    j = Journal.read(part)
    done = j.done_chunks()
    for i in np.flatnonzero(done):
        j.read_chunk(int(i))  # raises BadChunk if it does not verify
    return sorted(str(p.relative_to(part)) for p in part.rglob("*"))


def main(*argv):
    return cli.main(list(argv))


# ----------------------------------------------------------------------------- failed writes
def failing(monkeypatch, owner, name, code, *, nth=1, when=lambda *a, **k: True):
    """``owner.name`` raises OSError(code) on its nth call for which ``when`` holds."""
    original = getattr(owner, name)
    seen = [0]

    def wrapper(*args, **kwargs):
        if when(*args, **kwargs):
            seen[0] += 1
            if seen[0] == nth:
                raise OSError(code, os.strerror(code))
        return original(*args, **kwargs)

    monkeypatch.setattr(owner, name, wrapper)
    return seen


def _fd_name(fd) -> str:
    try:
        return os.readlink(f"/proc/self/fd/{fd}")
    except OSError:
        return ""


# Each stage at which a run writes: what to break, and how many chunks the journal holds after it.
STAGES = {
    "lock": (lambda mp, code: failing(mp, os, "write", code, when=lambda fd, data: data == str(os.getpid()).encode()),
             None),
    "run.json": (lambda mp, code: failing(mp, journal, "_write_atomic", code, when=lambda p, d: p.name == "run.json"),
                 None),
    "chunk": (lambda mp, code: failing(mp, np, "savez", code, nth=3), 2),
    "chunk-sync": (lambda mp, code: failing(mp, os, "fsync", code, nth=4, when=lambda fd: ".npz" in _fd_name(fd)),
                   3),
    "assembly": (lambda mp, code: failing(mp, os, "pwrite", code, nth=6), N_CHUNKS),
    "assembly-sync": (lambda mp, code: failing(mp, os, "fsync", code,
                                               when=lambda fd: _fd_name(fd).endswith("assembly.h5")), N_CHUNKS),
    "rename": (lambda mp, code: failing(mp, os, "replace", code,
                                        when=lambda src, dst: str(src).endswith("assembly.h5")), N_CHUNKS),
}
REASONS = {errno.ENOSPC: "disk full", errno.EFBIG: "file size limit", errno.EDQUOT: "disk quota exceeded",
           errno.EIO: "I/O error"}
CASES = [(stage, errno.ENOSPC) for stage in STAGES] + [
    (stage, code) for stage in ("chunk", "assembly") for code in (errno.EFBIG, errno.EDQUOT, errno.EIO)]


@pytest.mark.parametrize("stage,code", CASES, ids=[f"{s}-{errno.errorcode[c]}" for s, c in CASES])
def test_a_failed_write_at_every_stage_keeps_the_journal_and_resumes_identically(
        scene_file, reference, monkeypatch, capsys, stage, code):
    break_it, chunks_kept = STAGES[stage]
    with monkeypatch.context() as mp:
        seen = break_it(mp, code)
        status = main("run", str(scene_file), "-o", OUT, "--no-progress", "--threads", "1")
    assert seen[0] >= 1, f"the {stage} write was never reached"
    err = capsys.readouterr().err
    assert status == 2, err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    # a lack of room says how much the run needs; an I/O error is no lack of room: it says to check the disk
    assert REASONS[code] in err and ("MiB" in err) == (code != errno.EIO), err
    assert code != errno.EIO or "check it" in err, err
    files = journal_files(scene_file.parent)
    if chunks_kept is None:  # nothing computed yet: no journal, and nothing else left either
        assert files is None and "no chunk was saved" in err, err
        assert list((scene_file.parent / OUT).parent.iterdir()) == []
    else:
        assert f"journal kept ({chunks_kept} of {N_CHUNKS} chunks saved in {partial_path(OUT)})" in err, err
        assert "run again with --resume" in err, err
        assert sum(name.endswith(".npz") for name in files) == chunks_kept
        assert set(files) - {"chunks", "run.json"} == {f for f in files if f.startswith("chunks/") and
                                                       f.endswith(".npz")}, f"more than chunks in the journal: {files}"
        assert not (scene_file.parent / OUT).exists()
    resume_and_compare(scene_file.parent, reference)


# Writes refused for a cause that is no lack of room: each message names it, says what to do, and
# says nothing of space needed; the journal is kept and the run resumes identically.
CAUSES = {
    errno.EACCES: ["permission denied (EACCES)", "permission to write in", "was taken away during the run"],
    errno.EPERM: ["operation not permitted (EPERM)", "no longer permitted"],
    errno.EROFS: ["read-only file system (EROFS)", "became read-only during the run"],
    errno.EISDIR: ["it is a directory (EISDIR)", "became a directory during the run"],
    errno.ENOTDIR: ["a part of the path is not a folder (ENOTDIR)", "replaced by a file during the run"],
}


@pytest.mark.parametrize("code", sorted(CAUSES), ids=[errno.errorcode[c] for c in sorted(CAUSES)])
def test_a_write_refused_for_another_cause_than_room_names_it(scene_file, reference, monkeypatch, capsys, code):
    with monkeypatch.context() as mp:
        STAGES["chunk"][0](mp, code)
        status = main("run", str(scene_file), "-o", OUT, "--no-progress", "--threads", "1")
    err = capsys.readouterr().err
    assert status == 2 and "Traceback" not in err, err
    for piece in CAUSES[code]:
        assert piece in err, err
    assert "MiB" not in err and "disk full" not in err, err
    assert f"journal kept (2 of {N_CHUNKS} chunks saved in {partial_path(OUT)})" in err, err
    resume_and_compare(scene_file.parent, reference)


def test_no_inode_left_is_not_called_a_full_disk(scene_file, reference, monkeypatch, capsys):
    """ENOSPC with space to spare: the file system is out of inodes (files). Its statvfs is
    replaced by one of a disk with 3 free inodes of 1000 and 10 GB free."""
    real = os.statvfs

    def few_inodes(path):
        v = real(path)
        return os.statvfs_result((v.f_bsize, 4096, 2_500_000, 2_500_000, 2_500_000, 1000, 3, 3, v.f_flag,
                                  v.f_namemax))

    with monkeypatch.context() as mp:
        STAGES["chunk"][0](mp, errno.ENOSPC)
        mp.setattr(os, "statvfs", few_inodes)
        status = main("run", str(scene_file), "-o", OUT, "--no-progress", "--threads", "1")
    err = capsys.readouterr().err
    assert status == 2 and "Traceback" not in err, err
    assert "out of inodes (file entries), not of space" in err and "3 of 1000 inodes free" in err, err
    assert f"about {N_CHUNKS - 2 + 1} more files" in err and "disk full" not in err, err
    assert f"journal kept (2 of {N_CHUNKS} chunks saved" in err, err
    resume_and_compare(scene_file.parent, reference)


def test_a_really_inode_starved_disk_says_so(tmp_path):
    """A real tmpfs with 12 inodes (needs root): the run's files take them all before its chunks are
    saved; the message names the inodes, not the 1 MiB the run needs."""
    mount = tmp_path / "disk"
    mount.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    made = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16m,nr_inodes=12", "tmpfs", str(mount)],
                          capture_output=True, text=True)
    if made.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {made.stderr.strip()}")
    try:
        (mount / "faults.toml").write_text(SCENE)
        (mount / "data" / "runs").mkdir(parents=True)
        child = subprocess.run([sys.executable, "-m", "mechsweep", "run", "faults.toml", "-o", OUT, "--no-progress",
                                "--threads", "1"], cwd=mount, capture_output=True, text=True)
        assert child.returncode == 2, child.stderr[-2000:]
        assert "out of inodes (file entries), not of space" in child.stderr, child.stderr
        assert "disk full" not in child.stderr and "Traceback" not in child.stderr, child.stderr
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)


@pytest.mark.parametrize("removed", ["output folder", "journal folder"])
def test_a_folder_removed_during_the_run_is_named(scene_file, monkeypatch, capsys, removed):
    """Removing the output folder (or the journal) while chunks are written: ENOENT, not a lack of
    room; the chunks went with the folder."""
    import shutil

    write, seen = journal.Journal.write_chunk, [0]
    gone = (scene_file.parent / OUT).parent if removed == "output folder" else partial_path(scene_file.parent / OUT)

    def write_chunk(self, *args):
        seen[0] += 1
        if seen[0] == 3:
            shutil.rmtree(gone)
        return write(self, *args)

    monkeypatch.setattr(journal.Journal, "write_chunk", write_chunk)
    status = main("run", str(scene_file), "-o", OUT, "--no-progress", "--threads", "1")
    err = capsys.readouterr().err
    assert status == 2 and "Traceback" not in err, err
    name = "data/runs" if removed == "output folder" else str(partial_path(OUT))
    assert f"the {removed} {name} was removed during the run" in err and "(ENOENT)" in err, err
    assert "MiB" not in err and "lost: run again, from the start" in err, err


# ----------------------------------------------------------------------------- a dataset another process writes
HOLDER = textwrap.dedent("""
    import sys, time, h5py
    f = h5py.File(sys.argv[1], "a")  # HDF5 locks the file for this process (flock)
    print("open", flush=True)
    time.sleep(120)
""")


@pytest.fixture
def held_dataset(scene_file, reference):
    """OUT, a dataset of the scene, held open for writing by another process (its pid)."""
    import shutil

    target = scene_file.parent / OUT
    shutil.copy(reference, target)
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(target)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "open"
        yield target, holder.pid
    finally:
        holder.kill()
        holder.wait()


@pytest.mark.parametrize("argv", [("run", "faults.toml"), ("run", "faults.toml", "--overwrite"),
                                  ("run", "faults.toml", "--resume"), ("info",), ("plot",)])
def test_a_dataset_another_process_holds_is_named_so_and_never_replaced(held_dataset, capsys, argv):
    """It used to be called "damaged or truncated ... use --overwrite", and --overwrite lost the
    other process's data. Whatever the flags, it is left alone and the holder is named."""
    target, pid = held_dataset
    before = os.stat(target)
    command = [*argv, "-o", OUT, "--no-progress"] if argv[0] == "run" else [*argv, OUT]
    assert main(*command) == 2
    err = capsys.readouterr().err
    assert f"{OUT} is held open for writing by process {pid} (its HDF5 file lock)" in err, err
    assert "damaged" not in err and "use --overwrite" not in err and "Traceback" not in err, err
    after = os.stat(target)
    assert (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns), "the file was replaced"


# ----------------------------------------------------------------------------- figures that cannot be written
@pytest.fixture
def small_dataset(scene_file, reference):
    import shutil

    shutil.copy(reference, scene_file.parent / OUT)
    return OUT


def test_plot_into_a_missing_folder_names_the_folder(small_dataset, capsys):
    assert main("plot", small_dataset, "-o", "nope/f.png") == 2
    err = capsys.readouterr().err
    assert "the folder nope does not exist; create it first (mkdir -p nope)" in err, err
    assert "damaged" not in err and "Traceback" not in err, err


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EACCES, errno.EROFS, errno.EDQUOT],
                         ids=lambda c: errno.errorcode[c])
def test_a_figure_write_that_fails_names_its_cause(small_dataset, monkeypatch, capsys, code):
    from mechsweep import figures
    from mechsweep.figures import jobs

    def save(ds, path, **kwargs):
        raise OSError(code, os.strerror(code), str(path))

    monkeypatch.setattr(figures, "save", save)
    monkeypatch.setattr(jobs, "can_fork", lambda: False)
    assert main("plot", small_dataset, "-o", "fig.png") == 2
    err = capsys.readouterr().err
    assert "cannot write the figure fig.png" in err and f"({errno.errorcode[code]})" in err, err
    assert "damaged" not in err and "Traceback" not in err, err
    assert os.path.exists(small_dataset)


def test_plot_into_a_read_only_folder_is_refused_before_drawing(small_dataset, capsys):
    folder = os.path.join(os.path.dirname(small_dataset), "ro")
    os.mkdir(folder)
    os.chmod(folder, 0o555)
    try:
        assert main("plot", small_dataset, "-o", os.path.join(folder, "f.png")) == 2
    finally:
        os.chmod(folder, 0o755)
    err = capsys.readouterr().err
    assert f"cannot write into {folder} (permission denied)" in err and "damaged" not in err, err


def test_a_file_size_limit_below_the_dataset_is_refused_before_any_file(scene_file, monkeypatch, capsys):
    import resource

    monkeypatch.setattr(resource, "getrlimit", lambda which: (10_000, 10_000) if which == resource.RLIMIT_FSIZE
                        else (resource.RLIM_INFINITY, resource.RLIM_INFINITY))
    assert main("run", str(scene_file), "-o", OUT, "--no-progress") == 2
    err = capsys.readouterr().err
    assert "file size limit reached (ulimit -f)" in err and "the limit is 0.00954 MiB" in err, err
    assert list((scene_file.parent / OUT).parent.iterdir()) == []


CHILD = textwrap.dedent("""
    import os, resource, sys
    limit = int(os.environ.get("FSIZE_LIMIT", "0"))
    if limit:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    from mechsweep import cli
    from mechsweep.execution import runner
    from mechsweep.store import journal
    fill = os.environ.get("FILL")
    if fill:  # fill the disk of the output at one moment: 'chunk' after 2 chunks, 'assembly' just before it
        def filler(leave):
            with open(os.environ["FILLER"], "wb") as f:
                try:
                    while True:
                        f.write(b"\\0" * 65536)
                        f.flush()
                except OSError:
                    pass
            size = os.path.getsize(os.environ["FILLER"])
            os.truncate(os.environ["FILLER"], max(0, size - leave))
        if fill == "chunk":
            write, seen = journal.Journal.write_chunk, [0]
            def write_chunk(self, *a):
                write(self, *a)
                seen[0] += 1
                if seen[0] == 2:
                    filler(0)
            journal.Journal.write_chunk = write_chunk
        else:
            check = runner.check_free_space
            def check_free_space(scene, tmp):
                filler(int(os.environ["LEAVE"]))
                check(scene, tmp)
            runner.check_free_space = check_free_space
    sys.exit(cli.main(sys.argv[1:]))
""")


def run_child(folder, env=(), *argv):
    (folder / "child.py").write_text(CHILD)
    return subprocess.run([sys.executable, "child.py", *argv], cwd=folder, capture_output=True, text=True,
                          env={**os.environ, **dict(env)})


def test_a_file_size_limit_hit_during_the_assembly_is_a_message_not_a_segfault(scene_file, reference):
    """The case of the issue: RLIMIT_FSIZE between the size of the float outputs (checked before
    the run) and the file's size; HDF5 used to crash the process at exit (139)."""
    least = 8 * 3 * 40 * 20
    size = reference.stat().st_size
    limit = least + (size - least) // 2
    assert least < limit < size
    child = run_child(scene_file.parent, {"FSIZE_LIMIT": str(limit)}, "run", "faults.toml", "-o", OUT,
                      "--no-progress", "--threads", "1")
    assert child.returncode == 2, f"exit {child.returncode}: {child.stderr[-2000:]}"
    assert "Traceback" not in child.stderr and "Exception ignored" not in child.stderr, child.stderr
    assert "file size limit reached (ulimit -f)" in child.stderr, child.stderr
    assert f"journal kept ({N_CHUNKS} of {N_CHUNKS} chunks saved" in child.stderr, child.stderr
    assert "assembly.h5" not in journal_files(scene_file.parent)
    resume_and_compare(scene_file.parent, reference)


@pytest.fixture
def small_disk(tmp_path):
    """A 1 MiB tmpfs (needs root; skipped where mounting is not allowed)."""
    mount = tmp_path / "disk"
    mount.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    made = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mount)], capture_output=True,
                          text=True)
    if made.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {made.stderr.strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)


@pytest.mark.parametrize("when", [pytest.param("chunk", marks=pytest.mark.slow), "assembly"])
def test_a_really_full_disk_keeps_the_journal_and_resumes_identically(small_disk, reference, when):
    """A real ENOSPC from the kernel: the disk is filled after two chunks, or just before the
    assembly leaving less room than the dataset needs (more than its float outputs)."""
    (small_disk / "faults.toml").write_text(SCENE)
    (small_disk / "data" / "runs").mkdir(parents=True)
    least = 8 * 3 * 40 * 20
    leave = least + (reference.stat().st_size - least) // 2
    env = {"FILL": when, "FILLER": str(small_disk / "filler"), "LEAVE": str(leave),
           "MECHSWEEP_CACHE_DIR": os.environ.get("MECHSWEEP_CACHE_DIR", "")}
    child = run_child(small_disk, {k: v for k, v in env.items() if v}, "run", "faults.toml", "-o", OUT,
                      "--no-progress", "--threads", "1")
    assert child.returncode == 2, f"exit {child.returncode}: {child.stderr[-2000:]}"
    assert "Traceback" not in child.stderr and "disk full" in child.stderr, child.stderr
    kept = 2 if when == "chunk" else N_CHUNKS
    assert f"journal kept ({kept} of {N_CHUNKS} chunks saved" in child.stderr, child.stderr
    files = journal_files(small_disk)
    assert sum(f.endswith(".npz") for f in files) == kept and "assembly.h5" not in files
    (small_disk / "filler").unlink()
    (small_disk / "child.py").unlink()
    resume_and_compare(small_disk, reference)


# ----------------------------------------------------------------------------- damaged chunk files
def interrupted_run(scene_file, after=5):
    """A run stopped (Ctrl-C) after ``after`` chunks were saved."""
    with interrupted_after(after), pytest.raises(mechsweep.RunInterrupted):
        mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, progress=False)
    return sorted((partial_path(scene_file.parent / OUT) / "chunks").glob("*.npz"))


def damage(path, how):
    data = path.read_bytes()
    if how == "truncated":
        path.write_bytes(data[:len(data) // 2])
    elif how == "empty":
        path.write_bytes(b"")
    else:  # one byte changed in the middle: same size, only the checksum tells
        i = len(data) // 2
        path.write_bytes(data[:i] + bytes([data[i] ^ 0xFF]) + data[i + 1:])


@pytest.mark.parametrize("how", ["truncated", "empty", "flipped"])
def test_a_damaged_chunk_file_is_recomputed_and_the_others_kept(scene_file, reference, monkeypatch, capsys, how):
    files = interrupted_run(scene_file, after=5)
    assert len(files) == 5
    damage(files[2], how)
    capsys.readouterr()
    computed = []
    real = execute.evaluate_chunk
    monkeypatch.setattr(execute, "evaluate_chunk", lambda scene, chunk, *r: computed.append(chunk.index) or
                        real(scene, chunk, *r))
    resume_and_compare(scene_file.parent, reference)
    assert sorted(computed) == [2, 5, 6, 7], "only the damaged chunk and the missing ones are computed"
    err = capsys.readouterr().err
    assert f"chunk file {files[2].name}" in err and "removed, it is computed again" in err, err


def test_info_on_a_journal_with_a_damaged_chunk_shows_it_pending_without_traceback(scene_file, capsys):
    files = interrupted_run(scene_file, after=5)
    damage(files[1], "flipped")
    capsys.readouterr()
    assert main("info", OUT) == 0
    out, err = capsys.readouterr()
    assert "damaged" in err and files[1].name in err and "Traceback" not in err, err
    assert "pending 400 (50%)" in out, out  # chunks 1 (damaged), 5, 6 and 7, of 100 points each
    assert files[1].exists(), "info must not change the journal"
    (partial_path(scene_file.parent / OUT) / "run.json").write_text("{ not json")
    assert main("info", OUT) == 2
    assert "run.json is unreadable" in capsys.readouterr().err


def test_a_journal_of_an_older_version_without_checksums_is_still_resumed(scene_file, reference, monkeypatch):
    """Journal format 1: chunk files named NNNNNNN.npz; they count when numpy can read them."""
    import json

    files = interrupted_run(scene_file, after=5)
    files[0].rename(files[0].with_name(files[0].name.split("-")[0] + ".npz"))
    meta = partial_path(scene_file.parent / OUT) / "run.json"
    meta.write_text(json.dumps({**json.loads(meta.read_text()), "format": 1}))
    computed = []
    real = execute.evaluate_chunk
    monkeypatch.setattr(execute, "evaluate_chunk", lambda scene, chunk, *r: computed.append(chunk.index) or
                        real(scene, chunk, *r))
    resume_and_compare(scene_file.parent, reference)
    assert sorted(computed) == [5, 6, 7]


def _as_an_older_version(monkeypatch):
    """Runs write no dependency record (model/sources.py), as versions before it did."""
    from mechsweep.model import sources

    monkeypatch.setattr(sources.Record, "attrs", lambda self, base=None: {})


def test_a_journal_without_a_dependency_record_is_refused_and_restart_starts_over(scene_file, reference,
                                                                                  monkeypatch, capsys):
    """What its chunks were computed from cannot be checked (an older mechsweep wrote it): refused,
    nothing touched; --restart starts over."""
    import json

    from mechsweep import _jit

    with monkeypatch.context() as mp:
        _as_an_older_version(mp)
        interrupted_run(scene_file, after=3)
    before = journal_files(scene_file.parent)
    capsys.readouterr()
    assert main("run", str(scene_file), "-o", OUT, "--resume") == 2
    err = capsys.readouterr().err
    assert "which did not record the sources its results depend on" in err and "start over with --restart" in err, err
    assert "Traceback" not in err
    assert journal_files(scene_file.parent) == before
    assert main("run", str(scene_file), "-o", OUT, "--restart", "--no-progress") == 0
    done, ref = mechsweep.open_dataset(scene_file.parent / OUT), mechsweep.open_dataset(reference)
    for name in COMPARED:
        np.testing.assert_array_equal(done[name].values, ref[name].values, err_msg=name)
    assert json.loads(done.attrs["dependencies"])["mechsweep_sources"] == _jit.package_hash()


def test_resume_of_a_finished_dataset_without_a_dependency_record_finds_it_finished(scene_file, monkeypatch, capsys):
    """Nothing is computed, so nothing can be mixed: taken as it is (exit 0, the file unchanged)."""
    with monkeypatch.context() as mp:
        _as_an_older_version(mp)
        assert main("run", str(scene_file), "-o", OUT, "--no-progress") == 0
    out = scene_file.parent / OUT
    assert "dependencies" not in mechsweep.open_dataset(out).attrs
    before = out.read_bytes()
    assert main("run", str(scene_file), "-o", OUT, "--resume", "--no-progress") == 0
    assert out.read_bytes() == before


# ----------------------------------------------------------------------------- flags
def test_resume_and_restart_together_are_refused_and_touch_nothing(scene_file, capsys):
    interrupted_run(scene_file, after=3)
    before = journal_files(scene_file.parent)
    capsys.readouterr()
    assert main("run", str(scene_file), "-o", OUT, "--resume", "--restart") == 2
    err = capsys.readouterr().err
    assert "--resume --restart" in err and "choose one" in err and "Traceback" not in err, err
    assert journal_files(scene_file.parent) == before
    with pytest.raises(InputError, match="choose one"):
        mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, resume=True, restart=True)


@pytest.mark.parametrize("value", [0, -1, 10**6, float("nan"), "60", True])
def test_worker_timeout_is_validated(scene_file, capsys, value):
    scene = mechsweep.load_scene(scene_file)
    with pytest.raises(InputError, match=r"worker timeout .* is not allowed; expected a number of "
                                                   r"seconds in \[1, 86400\]"):
        mechsweep.run(scene, output=OUT, worker_timeout=value)
    text = SCENE + f"[execution]\nworker_timeout = {value!r}\n".replace("True", "true")
    (scene_file.parent / "bad.toml").write_text(text.replace("'", '"'))
    assert main("run", "bad.toml", "-o", OUT) == 2
    assert "execution.worker_timeout" in capsys.readouterr().err
    assert list((scene_file.parent / OUT).parent.iterdir()) == []


def test_worker_timeout_default_and_scene_key():
    assert Execution().worker_timeout == 120.0
    scene = mechsweep.load_scene(SCENE_DICT | {"execution": {"worker_timeout": 5}})
    assert scene.execution.worker_timeout == 5.0


SCENE_DICT = {"scene": {"name": "faults", "model": "duffing", "outputs": ["period"]},
              "axes": {"A": {"start": 0.1, "stop": 1.0, "num": 3}}, "fixed": {"omega": 1.0, "mu": 1.0}}


# ----------------------------------------------------------------------------- signals
SIGNALLER = textwrap.dedent("""
    import os, signal, sys
    from mechsweep import cli
    from mechsweep.store import journal
    sig, site = getattr(signal, sys.argv[1]), sys.argv[2]
    if site == "computing":  # after the second chunk is saved (in the writer thread, the third computing)
        write, seen = journal.Journal.write_chunk, [0]
        def write_chunk(self, *a):
            write(self, *a)
            seen[0] += 1
            if seen[0] == 2:
                os.kill(os.getpid(), sig)
        journal.Journal.write_chunk = write_chunk
    else:  # while the dataset is assembled, with the third chunk
        read, seen = journal.Journal.read_chunk, [0]
        def read_chunk(self, i):
            seen[0] += 1
            if seen[0] == 3:
                os.kill(os.getpid(), sig)
            return read(self, i)
        journal.Journal.read_chunk = read_chunk
    sys.exit(cli.main(sys.argv[3:]))
""")
SIGNAL_CASES = [("SIGTERM", "computing"), ("SIGTERM", "assembling"), ("SIGINT", "assembling")]


@pytest.mark.parametrize("sig,site", SIGNAL_CASES, ids=[f"{s}-{w}" for s, w in SIGNAL_CASES])
def test_sigterm_and_sigint_keep_the_journal_with_a_message(scene_file, reference, sig, site):
    (scene_file.parent / "signaller.py").write_text(SIGNALLER)
    with ctrl_c_as_from_a_terminal():
        child = subprocess.run([sys.executable, "signaller.py", sig, site, "run", "faults.toml", "-o", OUT,
                                "--no-progress", "--threads", "1"], cwd=scene_file.parent, capture_output=True,
                               text=True)
    expected = 128 + getattr(signal, sig)
    assert child.returncode == expected, f"exit {child.returncode}: {child.stderr[-2000:]}"
    assert f"interrupted ({sig})" in child.stderr and "run again with --resume" in child.stderr, child.stderr
    assert "Traceback" not in child.stderr and "Exception ignored" not in child.stderr, child.stderr
    files = journal_files(scene_file.parent)
    assert "assembly.h5" not in files and not any(f.endswith(".tmp") for f in files), files
    # computing: the signal comes as chunk 2 is saved, while chunk 3 computes; chunk 3 is saved before
    # the run stops (a launch cannot be stopped), chunk 4 is not started
    assert sum(f.endswith(".npz") for f in files) == (N_CHUNKS if site == "assembling" else 3)
    (scene_file.parent / "signaller.py").unlink()
    resume_and_compare(scene_file.parent, reference)


def test_a_run_started_ignoring_sigint_is_not_stopped_by_it(scene_file, reference):
    """A script's background job (`mechsweep run ... &`: a non-interactive shell starts it with SIGINT
    ignored) keeps ignoring SIGINT, as Python does: a Ctrl-C meant for the job in the foreground
    neither stops the run nor loses anything; the dataset is the uninterrupted run's."""
    (scene_file.parent / "signaller.py").write_text(SIGNALLER)
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)  # inherited by the child, as from such a shell
    try:
        child = subprocess.run([sys.executable, "signaller.py", "SIGINT", "computing", "run", "faults.toml", "-o",
                                OUT, "--no-progress", "--threads", "1"], cwd=scene_file.parent, capture_output=True,
                               text=True)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert child.returncode == 0 and "interrupted" not in child.stderr, f"exit {child.returncode}: {child.stderr}"
    done, ref = mechsweep.open_dataset(scene_file.parent / OUT), mechsweep.open_dataset(reference)
    for name in COMPARED:
        np.testing.assert_array_equal(done[name].values, ref[name].values, err_msg=name)


# ----------------------------------------------------------------------------- damaged journals
def tree(folder):
    """What a folder holds, entry by entry, links not followed: kind, and the bytes of a file or
    the target of a link (pipes and devices are never opened)."""
    import stat

    state = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            path = os.path.join(root, name)
            mode = os.lstat(path).st_mode
            key = os.path.relpath(path, folder)
            if stat.S_ISLNK(mode):
                state[key] = ("link", os.readlink(path))
            elif stat.S_ISREG(mode):
                with open(path, "rb") as f:
                    state[key] = ("file", f.read())
            else:
                state[key] = ("folder" if stat.S_ISDIR(mode) else "special", stat.S_IFMT(mode))
    return state


def _edit_meta(**changes):
    """Damage run.json: each key set to a value, or removed (value ``...``); its checksum is kept."""
    import json

    def edit(part, user):
        meta = json.loads((part / "run.json").read_text())
        for key, value in changes.items():
            if value is ...:
                meta.pop(key, None)
            else:
                meta[key] = value
        (part / "run.json").write_text(json.dumps(meta))
    return edit


def _replace(name, how):
    """Replace journal entry ``name`` ('run.json', 'chunks', 'assembly.h5', or 'chunk' for the second
    chunk file) by a folder, a pipe, a link to /dev/zero or to the user's folder or file, or nothing."""
    import shutil

    def edit(part, user):
        path = part / name if name != "chunk" else sorted((part / "chunks").iterdir())[1]
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif os.path.lexists(path):
            path.unlink()
        if how == "folder":
            path.mkdir()
        elif how == "fifo":
            os.mkfifo(path)
        elif how == "file":
            path.write_text("x")
        elif how == "dev-zero":
            path.symlink_to("/dev/zero")
        elif how == "link-to-user-folder":
            path.symlink_to(user / "folder")
        elif how == "link-to-user-file":
            path.symlink_to(user / "notes.txt")
        elif how == "device":  # /dev/null's numbers (making a device node needs root)
            import stat

            try:
                os.mknod(path, stat.S_IFCHR | 0o600, os.makedev(1, 3))
            except PermissionError:
                pytest.skip("making a device node needs root")
    return edit


def _bytes(data):
    def edit(part, user):
        meta = part / "run.json"
        meta.write_bytes(data(meta.read_bytes()))
    return edit


# A damaged journal (3 of 8 chunks saved), and what --resume must name. --restart discards any of them.
DAMAGED = {
    "run.json-garbage": (_bytes(lambda b: b"\x00\xff{garbage"), "run.json is unreadable"),
    "run.json-truncated": (_bytes(lambda b: b[:len(b) // 2]), "run.json is unreadable"),
    "run.json-empty": (_bytes(lambda b: b""), "run.json is unreadable"),
    "run.json-list": (_bytes(lambda b: b"[1, 2]"), "run.json is not a run's journal"),
    "run.json-folder": (_replace("run.json", "folder"), "run.json is a directory"),
    "run.json-fifo": (_replace("run.json", "fifo"), "run.json is a named pipe"),
    "run.json-dev-zero": (_replace("run.json", "dev-zero"), "run.json is a symbolic link"),
    "run.json-link-to-user-file": (_replace("run.json", "link-to-user-file"), "run.json is a symbolic link"),
    "run.json-device": (_replace("run.json", "device"), "run.json is a character device"),
    "chunk-device": (_replace("chunk", "device"), "(it is a character device)"),
    "run.json-missing": (_replace("run.json", None), "run.json is missing, and 3 chunk file(s)"),
    "format-missing": (_edit_meta(format=...), "entry format missing"),
    "format-text": (_edit_meta(format="3"), "entry format missing or of the wrong kind"),
    "format-true": (_edit_meta(format=True), "entry format missing or of the wrong kind"),
    "format-future": (_edit_meta(format=99), "another mechsweep version (journal format 99"),
    "scene_canonical-missing": (_edit_meta(scene_canonical=...), "entries scene_canonical missing"),
    "scene_canonical-number": (_edit_meta(scene_canonical=1), "entries scene_canonical missing"),
    "scene-list": (_edit_meta(scene=["x"]), "entries scene missing"),
    "n_chunks-text": (_edit_meta(n_chunks="8"), "entries n_chunks missing"),
    "n_chunks-float": (_edit_meta(n_chunks=8.0), "entries n_chunks missing"),
    "n_chunks-zero": (_edit_meta(n_chunks=0), "n_chunks = 0"),
    "n_chunks-huge": (_edit_meta(n_chunks=10**15), "n_chunks = 1000000000000000"),
    "chunk_target-negative": (_edit_meta(chunk_target=-5), "chunk_target = -5"),
    "chunk_target-null": (_edit_meta(chunk_target=None), "entries chunk_target missing"),
    "attrs-missing": (_edit_meta(attrs=...), "entries attrs missing"),
    "attrs-list": (_edit_meta(attrs=[]), "entries attrs missing"),
    "attrs-empty": (_edit_meta(attrs={}), "does not match its checksum"),
    "run_id-missing": (_edit_meta(run_id=...), "has no run id"),
    "checksum-missing": (_edit_meta(checksum=...), "has no checksum"),
    "checksum-number": (_edit_meta(checksum=0), "has no checksum"),
    "chunks-missing": (_replace("chunks", None), "chunks is missing"),
    "chunks-file": (_replace("chunks", "file"), "chunks is a regular file"),
    "chunks-link-to-user-folder": (_replace("chunks", "link-to-user-folder"), "chunks is a symbolic link"),
    "chunk-folder": (_replace("chunk", "folder"), "is not a chunk file a run writes (it is a directory)"),
    "chunk-dev-zero": (_replace("chunk", "dev-zero"), "is not a chunk file a run writes (it is a symbolic link)"),
    "chunk-fifo": (_replace("chunk", "fifo"), "is not a chunk file a run writes (it is a named pipe"),
    "chunk-link-to-user-file": (_replace("chunk", "link-to-user-file"), "(it is a symbolic link)"),
    "assembly-fifo": (_replace("assembly.h5", "fifo"), "assembly.h5 is a named pipe (FIFO), not a file"),
    "assembly-link-to-user-file": (_replace("assembly.h5", "link-to-user-file"), "assembly.h5 is a symbolic link"),
}


@pytest.fixture
def user_files(tmp_path):
    """Files of the user's elsewhere, that links in a damaged journal point to: never touched."""
    user = tmp_path / "user"
    (user / "folder").mkdir(parents=True)
    (user / "folder" / "data.txt").write_text("the user's data\n")
    (user / "notes.txt").write_text("the user's notes\n")
    return user


@pytest.mark.parametrize("damage_it", sorted(DAMAGED))
def test_a_damaged_journal_is_named_by_resume_and_discarded_by_restart(
        scene_file, reference, user_files, capsys, damage_it):
    """Whatever is wrong with a journal's own files (run.json unreadable, an entry of it missing or of
    the wrong kind or range, a folder, pipe or link in place of a file), --resume says what and that
    --restart discards it, and changes nothing; --restart then starts over (every time) and never
    touches what a link in the journal points to."""
    edit, said = DAMAGED[damage_it]
    interrupted_run(scene_file, after=3)
    part = partial_path(scene_file.parent / OUT)
    edit(part, user_files)
    before, users = tree(part), tree(user_files)
    capsys.readouterr()
    assert main("run", str(scene_file), "-o", OUT, "--no-progress", "--resume") == 2
    err = capsys.readouterr().err
    assert said in err and "--restart discards the journal" in err and "Traceback" not in err, err
    assert err.count("\n") == 1, err
    assert tree(part) == before, "a refused resume changed the journal"
    assert main("run", str(scene_file), "-o", OUT, "--no-progress", "--restart") == 0, capsys.readouterr().err
    assert tree(user_files) == users, "--restart touched what a link in the journal points to"
    resume_and_compare(scene_file.parent, reference)  # (finished: --resume only checks it)
    ref, done = mechsweep.open_dataset(reference), mechsweep.open_dataset(scene_file.parent / OUT)
    for name in COMPARED:
        np.testing.assert_array_equal(done[name].values, ref[name].values, err_msg=name)


# Entries a run does not write, put into its journal folder (and the entry to move away after):
# never deleted, by --restart or otherwise.
FOREIGN = {
    "notes.txt": (lambda part: (part / "notes.txt").write_text("the user's notes\n"), "notes.txt"),
    "chunks/README": (lambda part: (part / "chunks" / "README").write_text("mine\n"), "chunks/README"),
    "backup": (lambda part: ((part / "backup").mkdir(), (part / "backup" / "a.npz").write_bytes(b"x")), "backup"),
    "run.json.bak": (lambda part: (part / "run.json.bak").write_bytes((part / "run.json").read_bytes()),
                     "run.json.bak"),
    "mine.txt": (lambda part: ((part / "run.json").unlink(), (part / "run.json").mkdir(),  # in a folder run.json
                               (part / "run.json" / "mine.txt").write_text("x")), "run.json"),
}


@pytest.mark.parametrize("what", sorted(FOREIGN))
def test_resume_and_restart_never_delete_files_a_run_did_not_write(scene_file, reference, capsys, what):
    """A journal folder holding a user's file: a run would remove it with the journal (at its end, or
    with --restart). Every run of that output is refused, naming it, and nothing changes; once it is
    moved away, --restart starts over."""
    make, entry = FOREIGN[what]
    interrupted_run(scene_file, after=3)
    part = partial_path(scene_file.parent / OUT)
    make(part)
    before = tree(part)
    capsys.readouterr()
    for flags in (["--resume"], ["--restart"], [], ["--overwrite"]):
        assert main("run", str(scene_file), "-o", OUT, "--no-progress", *flags) == 2
        err = capsys.readouterr().err
        assert "which a run does not write" in err and "never deletes files it did not write" in err, (flags, err)
        assert what in err and "Traceback" not in err, err
        assert tree(part) == before, f"{flags} changed the journal"
    with pytest.raises(mechsweep.StoreError, match="which a run does not write"):
        mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, restart=True, progress=False)
    assert tree(part) == before
    (part / entry).rename(scene_file.parent / "kept")
    assert main("run", str(scene_file), "-o", OUT, "--no-progress", "--restart") == 0, capsys.readouterr().err
    resume_and_compare(scene_file.parent, reference)


def test_a_file_put_into_the_journal_during_a_run_is_kept_when_the_run_ends(scene_file, reference, monkeypatch,
                                                                             capsys):
    """The journal is removed when the dataset is in place: only what the run wrote; a user's file
    put there meanwhile stays (with a message), and the next run of that output says so."""
    part = partial_path(scene_file.parent / OUT)
    write, seen = journal.Journal.write_chunk, [0]

    def write_chunk(self, *args):
        write(self, *args)
        seen[0] += 1
        if seen[0] == 2:
            (part / "notes.txt").write_text("the user's notes\n")

    monkeypatch.setattr(journal.Journal, "write_chunk", write_chunk)
    assert main("run", str(scene_file), "-o", OUT, "--no-progress") == 0
    err = capsys.readouterr().err
    assert "notes.txt" in err and "left as they are" in err, err
    assert sorted(p.name for p in part.iterdir()) == ["notes.txt"]
    assert (part / "notes.txt").read_text() == "the user's notes\n"
    ref, done = mechsweep.open_dataset(reference), mechsweep.open_dataset(scene_file.parent / OUT)
    for name in COMPARED:
        np.testing.assert_array_equal(done[name].values, ref[name].values, err_msg=name)
    assert main("run", str(scene_file), "-o", OUT, "--no-progress") == 2
    assert "notes.txt, which a run does not write" in capsys.readouterr().err


def test_info_on_a_damaged_journal_names_the_damage(scene_file, capsys):
    interrupted_run(scene_file, after=3)
    _edit_meta(n_chunks="8")(partial_path(scene_file.parent / OUT), None)
    capsys.readouterr()
    assert main("info", OUT) == 2
    err = capsys.readouterr().err
    assert "run.json is damaged (entries n_chunks" in err and "--restart discards" in err and "Traceback" not in err


# ----------------------------------------------------------------------------- tampering
def _meta(part):
    import json

    return json.loads((part / "run.json").read_text())


def _write_meta(part, meta):
    import json

    (part / "run.json").write_text(json.dumps(meta, indent=1))


@pytest.mark.parametrize("key,value", [("model", "pendulum"), ("solver_rtol", 1.0), ("solver_method", "radau"),
                                       ("outputs", "period"), ("title", "another"), ("mechsweep_version", "9.9")])
def test_an_edited_run_json_attribute_is_refused_not_put_into_the_dataset(scene_file, reference, capsys, key, value):
    """run.json's attributes become the dataset's: an edited one (here with its checksum left as it
    was) is refused by --resume; --restart then starts over."""
    interrupted_run(scene_file, after=3)
    part = partial_path(scene_file.parent / OUT)
    meta = _meta(part)
    meta["attrs"][key] = value
    _write_meta(part, meta)
    capsys.readouterr()
    assert main("run", str(scene_file), "-o", OUT, "--no-progress", "--resume") == 2
    err = capsys.readouterr().err
    assert "run.json does not match its checksum" in err and "--restart discards" in err, err
    assert main("run", str(scene_file), "-o", OUT, "--no-progress", "--restart") == 0
    assert mechsweep.open_dataset(scene_file.parent / OUT).attrs[key] != value


@pytest.mark.parametrize("key,value", [("model", "pendulum"), ("solver_rtol", 1.0), ("solver_atol", 1e-3),
                                       ("outputs", "period v_max"), ("solver_extra", 1)])
def test_an_edited_attribute_under_a_recomputed_checksum_is_refused(scene_file, capsys, key, value):
    """The checksum is no signature (anyone can compute it): the attributes the scene determines
    (model, outputs, solver settings) are also compared with the scene being resumed, naming the one
    that differs. This is what guards a journal of format 2, which has no checksum."""
    from mechsweep.store.journal import meta_checksum

    interrupted_run(scene_file, after=3)
    part = partial_path(scene_file.parent / OUT)
    meta = _meta(part)
    meta["attrs"][key] = value
    meta["checksum"] = meta_checksum(meta)
    _write_meta(part, meta)
    capsys.readouterr()
    assert main("run", str(scene_file), "-o", OUT, "--no-progress", "--resume") == 2
    err = capsys.readouterr().err
    assert f"gives the dataset the attribute {key} = {value!r}" in err and "the journal was edited" in err, err


def as_format_2(part):
    """Turn a journal into one the previous version wrote (format 2): no run id, no checksum, chunk
    names with the CRC-32 of the file's bytes only."""
    import zlib

    meta = _meta(part)
    del meta["run_id"], meta["checksum"]
    meta["format"] = 2
    _write_meta(part, meta)
    for f in (part / "chunks").glob("*.npz"):
        data = f.read_bytes()
        f.rename(f.with_name(f"{f.name[:7]}-{len(data)}-{zlib.crc32(data):08x}.npz"))


def test_a_journal_of_the_previous_format_is_resumed_and_its_attributes_checked(scene_file, reference, monkeypatch,
                                                                                capsys):
    """A journal written before run.json had a checksum (format 2) is resumed, computing only its
    missing chunks, bitwise as an uninterrupted run; its attributes are compared with the scene."""
    interrupted_run(scene_file, after=3)
    part = partial_path(scene_file.parent / OUT)
    as_format_2(part)
    meta = _meta(part)
    _write_meta(part, {**meta, "attrs": {**meta["attrs"], "solver_rtol": 1.0}})
    capsys.readouterr()
    assert main("run", str(scene_file), "-o", OUT, "--no-progress", "--resume") == 2
    assert "attribute solver_rtol = 1.0" in capsys.readouterr().err
    _write_meta(part, meta)
    computed = []
    real = execute.evaluate_chunk
    monkeypatch.setattr(execute, "evaluate_chunk", lambda scene, chunk, *r: computed.append(chunk.index) or
                        real(scene, chunk, *r))
    resume_and_compare(scene_file.parent, reference)
    assert sorted(computed) == [3, 4, 5, 6, 7]


def _chunk_files(part):
    return sorted((part / "chunks").glob("*.npz"))


def _crc_name(index, data):
    """A chunk file's name as one who knows the previous format's rule would make it."""
    import zlib

    return f"{index:07d}-{len(data)}-{zlib.crc32(data):08x}.npz"


def _renamed(part, other):
    """The bytes of chunk 1 under the name of chunk 3 (missing), its size and CRC-32 matching."""
    f = _chunk_files(part)[1]
    data = f.read_bytes()
    (part / "chunks" / _crc_name(3, data)).write_bytes(data)
    return [3]


def _renamed_keeping_name(part, other):
    f = _chunk_files(part)[1]
    f.rename(f.with_name("0000003" + f.name[7:]))
    return [1, 3]


def _swapped(part, other):
    a, b = _chunk_files(part)[0], _chunk_files(part)[2]
    a.rename(part / "swap")
    b.rename(b.with_name("0000000" + b.name[7:]))
    (part / "swap").rename(a.with_name("0000002" + a.name[7:]))
    return [0, 2]


def _swapped_renamed(part, other):
    a, b = _chunk_files(part)[0], _chunk_files(part)[2]
    da, db = a.read_bytes(), b.read_bytes()
    a.unlink(), b.unlink()
    (part / "chunks" / _crc_name(0, db)).write_bytes(db)
    (part / "chunks" / _crc_name(2, da)).write_bytes(da)
    return [0, 2]


def _from_another_run(part, other):
    """Chunk 0 of another run of the same shape (another scene: omega = 2) in place of this run's."""
    mine, theirs = _chunk_files(part)[0], _chunk_files(other)[0]
    mine.unlink()
    (part / "chunks" / theirs.name).write_bytes(theirs.read_bytes())
    return [0]


def _edited_values(part, other):
    """One value of chunk 2 changed, the file renamed with its new size and CRC-32."""
    import io

    f = _chunk_files(part)[2]
    with np.load(f) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["period"] = arrays["period"].copy()
    arrays["period"][5] *= 1.5
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    f.unlink()
    (part / "chunks" / _crc_name(2, buffer.getvalue())).write_bytes(buffer.getvalue())
    return [2]


TAMPERED = {"renamed": _renamed, "renamed-keeping-its-name": _renamed_keeping_name, "swapped": _swapped,
            "swapped-renamed": _swapped_renamed, "from-another-run": _from_another_run,
            "edited-values": _edited_values}


@pytest.mark.parametrize("how", sorted(TAMPERED))
def test_a_chunk_file_moved_swapped_edited_or_from_another_run_is_computed_again(
        scene_file, reference, monkeypatch, capsys, how):
    """A chunk file's name carries a CRC-32 of the run's id, its index and its bytes: the bytes of
    another chunk, of another run's chunk, or edited values do not verify under any name the
    previous rule (size and CRC-32 of the bytes) gives them. Each is reported, removed and computed
    again; the dataset is bitwise an uninterrupted run's."""
    other = scene_file.parent / "other"
    other.mkdir()
    (other / "faults.toml").write_text(SCENE.replace("omega = 1.0", "omega = 2.0"))
    with interrupted_after(3), pytest.raises(mechsweep.RunInterrupted):
        mechsweep.run(mechsweep.load_scene(other / "faults.toml"), output=other / "o.h5", progress=False)
    interrupted_run(scene_file, after=3)
    part = partial_path(scene_file.parent / OUT)
    again = TAMPERED[how](part, partial_path(other / "o.h5"))
    (part / "swap").unlink(missing_ok=True)
    computed = []
    real = execute.evaluate_chunk
    monkeypatch.setattr(execute, "evaluate_chunk", lambda scene, chunk, *r: computed.append(chunk.index) or
                        real(scene, chunk, *r))
    capsys.readouterr()
    resume_and_compare(scene_file.parent, reference)
    assert set(again) <= set(computed), f"chunks {again} were taken as they were: computed {computed}"
    err = capsys.readouterr().err
    assert "not this run's chunk of this index" in err and "removed, it is computed again" in err, err


# ----------------------------------------------------------------------------- the output path, at the end
def _other_dataset(folder):
    """A finished dataset of another scene (omega = 2), to be put at the output path."""
    (folder / "other.toml").write_text(SCENE.replace("omega = 1.0", "omega = 2.0"))
    mechsweep.run(mechsweep.load_scene(folder / "other.toml"), output=folder / "other.h5", progress=False)
    return (folder / "other.h5").read_bytes()


def _appear(kind, target, folder):
    """Put a ``kind`` at ``target`` (the run's output path), as a user or another program would."""
    if kind == "text file":
        target.write_text("the user's notes\n")
    elif kind == "empty file":
        target.write_bytes(b"")
    elif kind == "link":
        (folder / "mine.txt").write_text("the user's file\n")
        target.symlink_to(folder / "mine.txt")
    elif kind == "folder":
        target.mkdir()
        (target / "mine.txt").write_text("x")
    elif kind == "fifo":
        os.mkfifo(target)
    elif kind == "dataset of another scene":
        target.write_bytes((folder / "other.h5").read_bytes())


APPEARING = ["text file", "empty file", "link", "folder", "fifo", "dataset of another scene"]


def _appearing_during_the_run(monkeypatch, kind, target, folder):
    write, seen = journal.Journal.write_chunk, [0]

    def write_chunk(self, *args):
        write(self, *args)
        seen[0] += 1
        if seen[0] == 2:
            _appear(kind, target, folder)

    monkeypatch.setattr(journal.Journal, "write_chunk", write_chunk)


@pytest.mark.parametrize("route", ["cli", "python"])
@pytest.mark.parametrize("kind", APPEARING)
def test_a_file_that_appears_at_the_output_path_during_the_run_is_never_replaced(
        scene_file, reference, monkeypatch, capsys, kind, route):
    """What is at the output path is checked when the run starts, and again right before the
    dataset is renamed into place: something that came meanwhile is left as it is, the run stops
    with its journal complete, and once it is moved away --resume only assembles the dataset."""
    folder = scene_file.parent
    target = folder / OUT
    _other_dataset(folder)
    with monkeypatch.context() as mp:
        _appearing_during_the_run(mp, kind, target, folder)
        if route == "cli":
            assert main("run", str(scene_file), "-o", OUT, "--no-progress") == 2
            err = capsys.readouterr().err
        else:
            with pytest.raises(mechsweep.StoreError) as exc:
                mechsweep.run(mechsweep.load_scene(scene_file), output=OUT, progress=False)
            err = str(exc.value)
    assert f"{OUT} appeared while the run computed" in err and "it was left as it is" in err, err
    assert "Traceback" not in err
    after = tree(folder / "data" / "runs")
    assert after[os.path.basename(OUT)][0] == {"link": "link", "folder": "folder", "fifo": "special"}.get(kind, "file")
    if kind == "dataset of another scene":
        assert target.read_bytes() == (folder / "other.h5").read_bytes()
    elif kind == "text file":
        assert target.read_text() == "the user's notes\n"
    elif kind == "link":
        assert os.readlink(target) == str(folder / "mine.txt") and target.read_text() == "the user's file\n"
    elif kind == "folder":
        assert os.listdir(target) == ["mine.txt"]
    files = journal_files(folder)
    assert sum(f.endswith(".npz") for f in files) == N_CHUNKS and "assembly.h5" not in files, files
    if target.is_dir() and not target.is_symlink():
        (target / "mine.txt").unlink()
        target.rmdir()
    else:
        target.unlink()
    computed = []
    real = execute.evaluate_chunk
    monkeypatch.setattr(execute, "evaluate_chunk", lambda scene, chunk, *r: computed.append(chunk.index) or
                        real(scene, chunk, *r))
    resume_and_compare(folder, reference)
    assert computed == []


def test_a_dataset_of_the_same_scene_that_appears_is_replaced(scene_file, reference, monkeypatch):
    """A dataset of the same scene holds the same values: the run replaces it (as a re-run would)."""
    folder = scene_file.parent
    target = folder / OUT
    with monkeypatch.context() as mp:
        write, seen = journal.Journal.write_chunk, [0]

        def write_chunk(self, *args):
            write(self, *args)
            seen[0] += 1
            if seen[0] == 2:
                target.write_bytes(reference.read_bytes())

        mp.setattr(journal.Journal, "write_chunk", write_chunk)
        assert main("run", str(scene_file), "-o", OUT, "--no-progress") == 0
    assert sorted(p.name for p in target.parent.iterdir()) == ["f.h5"]


def test_overwrite_covers_only_the_file_the_run_started_with(scene_file, monkeypatch, capsys):
    """--overwrite replaces the file that was at the output path when the run was checked; a file
    put there in its place while the run computed is another one: it is kept."""
    folder = scene_file.parent
    target = folder / OUT
    target.write_bytes(_other_dataset(folder))
    with monkeypatch.context() as mp:
        write, seen = journal.Journal.write_chunk, [0]

        def write_chunk(self, *args):
            write(self, *args)
            seen[0] += 1
            if seen[0] == 2:
                target.unlink()
                target.write_bytes((folder / "other.h5").read_bytes())  # the same bytes, another file

        mp.setattr(journal.Journal, "write_chunk", write_chunk)
        assert main("run", str(scene_file), "-o", OUT, "--no-progress", "--overwrite") == 2
    assert "changed while the run computed (a dataset of a different scene)" in capsys.readouterr().err
    assert target.read_bytes() == (folder / "other.h5").read_bytes()


APPEARER = textwrap.dedent("""
    import os, sys
    from mechsweep import cli
    from mechsweep.store import journal
    write, seen = journal.Journal.write_chunk, [0]
    def write_chunk(self, *a):
        write(self, *a)
        seen[0] += 1
        if seen[0] == 2:
            with open(sys.argv[1], "w") as f:
                f.write("the user's notes\\n")
    journal.Journal.write_chunk = write_chunk
    sys.exit(cli.main(sys.argv[2:]))
""")


def test_the_command_keeps_a_file_that_appears_at_its_output_path(scene_file, reference):
    """The same from the command in a process of its own: exit 2, one line, the file kept."""
    (scene_file.parent / "appearer.py").write_text(APPEARER)
    child = subprocess.run([sys.executable, "appearer.py", OUT, "run", "faults.toml", "-o", OUT, "--no-progress",
                            "--threads", "1"], cwd=scene_file.parent, capture_output=True, text=True)
    assert child.returncode == 2, child.stderr[-2000:]
    assert child.stderr.count("\n") == 1 and "appeared while the run computed (not a mechsweep dataset: it is a " \
        "text file" in child.stderr, child.stderr
    assert (scene_file.parent / OUT).read_text() == "the user's notes\n"
    (scene_file.parent / OUT).unlink()
    (scene_file.parent / "appearer.py").unlink()
    resume_and_compare(scene_file.parent, reference)


def _denied(monkeypatch, where):
    """Reading ``where`` fails with EACCES, as for another user (the tests may run as root, which
    reads anything). Only the calls made with that path."""
    import pathlib

    def guard(name, real):
        def call(path, *a, **k):
            if isinstance(path, (str, os.PathLike)) and os.fspath(path).endswith(where):
                raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fspath(path))
            return real(path, *a, **k)
        return call

    monkeypatch.setattr(os, "scandir", guard("scandir", os.scandir))
    monkeypatch.setattr(os, "listdir", guard("listdir", os.listdir))
    real_read = pathlib.Path.read_bytes
    monkeypatch.setattr(pathlib.Path, "read_bytes", lambda self: guard("read", lambda p: real_read(self))(self))


def test_permission_denied_entries_are_named_and_never_removed_blind(scene_file, reference, monkeypatch, capsys):
    """run.json that cannot be read: --resume says so, --restart discards it (removing a file needs no
    right to read it). A chunks folder that cannot be listed: what it holds is not known, so no run
    removes it; every run says to give it back its permissions."""
    interrupted_run(scene_file, after=3)
    part = partial_path(scene_file.parent / OUT)
    before = tree(part)
    capsys.readouterr()
    with monkeypatch.context() as mp:
        _denied(mp, "run.json")
        assert main("run", str(scene_file), "-o", OUT, "--no-progress", "--resume") == 2
        err = capsys.readouterr().err
        assert "run.json cannot be read (Permission denied)" in err and "--restart discards" in err, err
    assert tree(part) == before
    with monkeypatch.context() as mp:
        _denied(mp, "chunks")
        for flags in (["--resume"], ["--restart"]):
            assert main("run", str(scene_file), "-o", OUT, "--no-progress", *flags) == 2
            err = capsys.readouterr().err
            assert "chunks (Permission denied) cannot be listed" in err and "chmod u+rwx" in err, err
            assert "Traceback" not in err
    assert tree(part) == before
    with monkeypatch.context() as mp:
        _denied(mp, "run.json")
        assert main("run", str(scene_file), "-o", OUT, "--no-progress", "--restart") == 0, capsys.readouterr().err
    resume_and_compare(scene_file.parent, reference)


def test_a_file_at_the_journal_path_that_is_not_an_unfinished_run_is_kept(scene_file, capsys):
    """An older version kept an unfinished run in one HDF5 file PATH.partial, which --restart removes;
    a file there that is not HDF5 is not such a run: it is refused, and kept."""
    part = partial_path(scene_file.parent / OUT)
    part.write_text("the user's notes\n")
    for flags in (["--restart"], ["--resume"], []):
        assert main("run", str(scene_file), "-o", OUT, "--no-progress", *flags) == 2
        assert "is a file that is not an unfinished run" in capsys.readouterr().err
    assert part.read_text() == "the user's notes\n"
