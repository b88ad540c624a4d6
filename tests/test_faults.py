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
from mechsweep import cli, journal, runner
from mechsweep.journal import Journal, partial_path
from mechsweep.errors import InputError
from mechsweep.scene import Execution

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

    def save(ds, path, **kwargs):
        raise OSError(code, os.strerror(code), str(path))

    monkeypatch.setattr(figures, "save", save)
    monkeypatch.setattr(cli, "_can_fork", lambda: False)
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
    from mechsweep import cli, journal, runner
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
    real = runner.evaluate_chunk
    monkeypatch.setattr(runner, "evaluate_chunk", lambda scene, chunk, *r: computed.append(chunk.index) or
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
    real = runner.evaluate_chunk
    monkeypatch.setattr(runner, "evaluate_chunk", lambda scene, chunk, *r: computed.append(chunk.index) or
                        real(scene, chunk, *r))
    resume_and_compare(scene_file.parent, reference)
    assert sorted(computed) == [5, 6, 7]


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
    from mechsweep import cli, journal
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
    child = subprocess.run([sys.executable, "signaller.py", sig, site, "run", "faults.toml", "-o", OUT,
                            "--no-progress", "--threads", "1"], cwd=scene_file.parent, capture_output=True, text=True)
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
