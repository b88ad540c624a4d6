"""A run killed with SIGKILL at any moment resumes to a dataset identical to an uninterrupted run.

Two kinds of kill: at a random moment of the computation (after k chunks were saved), and at each
step where the run changes files on disk (the child process kills itself right there, so the
test hits moments too short to aim at from outside: mid-way through a chunk file, between a
rename and the folder sync, while the dataset is assembled, between placing the dataset and
dropping the journal)."""
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import mechsweep
from mechsweep.store.journal import partial_path

SCENE = """
[scene]
name = "kill"
model = "duffing"
outputs = ["period", "period_exact", "v_max"]
[axes]
A = {{ start = 0.01, stop = 1.0, num = {n_a} }}
mu = {{ start = 1e-3, stop = 1e3, num = {n_mu}, spacing = "log" }}
[fixed]
omega = 1.0
[storage]
chunk_size = {chunk}
"""
COMPARED = ("period", "period_exact", "v_max", "status", "n_steps", "n_rhs", "A", "mu")


def chunks_done(part) -> int:
    try:
        return sum(1 for p in (part / "chunks").iterdir() if p.suffix == ".npz")
    except FileNotFoundError:  # not created yet
        return -1


def cli(*args, cwd):
    return [sys.executable, "-m", "mechsweep.cli", *args], dict(cwd=cwd)


def assert_identical(out, reference):
    done = mechsweep.open_dataset(out)
    for name in COMPARED:
        np.testing.assert_array_equal(done[name].values, reference[name].values, err_msg=name)
    assert done.attrs["scene_canonical"] == reference.attrs["scene_canonical"]


def assert_no_leftovers(folder, out):
    assert sorted(p.name for p in folder.iterdir()) == [out.name], "journal, lock or temporary files left"


@pytest.fixture(scope="module")
def long_reference(tmp_path_factory):
    where = tmp_path_factory.mktemp("long")
    (where / "kill.toml").write_text(SCENE.format(n_a=600, n_mu=200, chunk=2000))
    return mechsweep.run(mechsweep.load_scene(where / "kill.toml"), output=where / "ref.h5", progress=False)


@pytest.mark.parametrize("kill_after", [1, 7])
def test_sigkill_during_the_computation_then_resume_is_identical(in_tmp, long_reference, kill_after):
    (in_tmp / "kill.toml").write_text(SCENE.format(n_a=600, n_mu=200, chunk=2000))
    out = in_tmp / "data" / "runs" / "k.h5"
    part = partial_path(out)
    argv, kw = cli("run", "kill.toml", "-o", str(out), "--no-progress", "--threads", "1", cwd=in_tmp)
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, **kw)
    deadline = time.monotonic() + 120
    while chunks_done(part) < kill_after and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert part.exists() and not out.exists(), "the run finished before it could be killed"
    mechsweep.run(mechsweep.load_scene(in_tmp / "kill.toml"), output=out, resume=True, progress=False)
    assert_identical(out, long_reference)
    assert_no_leftovers(out.parent, out)


# The child runs the scene with one function wrapped so that the process kills itself with
# SIGKILL on the n-th call that matches: `before` kills before the call, otherwise just after it.
KILLER = textwrap.dedent("""
    import os, signal, sys
    import numpy as np, shutil
    import mechsweep
    from mechsweep import store
    from mechsweep.execution import runner
    from mechsweep.store import journal

    site, n = sys.argv[1], int(sys.argv[2])
    seen = [0]

    def killing(owner, name, before=False, when=lambda *a: True):
        original = getattr(owner, name)
        def wrapper(*args, **kwargs):
            if when(*args):
                seen[0] += 1
                if seen[0] == n and before:
                    os.kill(os.getpid(), signal.SIGKILL)
            result = original(*args, **kwargs)
            if when(*args) and seen[0] == n and not before:
                os.kill(os.getpid(), signal.SIGKILL)
            return result
        setattr(owner, name, wrapper)

    if site == "journal-created":  # the folder exists, run.json does not
        killing(journal, "_write_atomic", before=True)
    elif site == "mid-chunk-file":  # a chunk's temporary file written, not synced nor renamed
        def fd_name(fd):
            try:
                return os.readlink(f"/proc/self/fd/{fd}")
            except OSError:
                return ""
        killing(os, "fsync", before=True, when=lambda fd: fd_name(fd).endswith(".npz.tmp"))
    elif site == "chunk-renamed":  # a chunk file renamed, the folder not synced
        killing(journal, "_sync_dir", before=True, when=lambda folder: folder.name == "chunks")
    elif site == "assembling":  # the dataset half written in the journal folder, chunk by chunk (compute, as the CLI)
        killing(journal.Journal, "read_chunk")
    elif site == "assembling-held":  # the same for run(), which writes its file while the chunks are computed
        import h5py
        stored = ("period", "period_exact", "v_max", "status", "n_steps", "n_rhs")
        killing(h5py.Dataset, "__setitem__", when=lambda ds, *a: ds.name.strip("/") in stored)
    elif site == "dataset-placed":  # the dataset in place, the journal not dropped yet
        killing(runner, "drop", before=True, when=lambda final: (final.parent / final.name).exists())
    elif site == "journal-dropping":  # the journal renamed away, not yet deleted
        killing(shutil, "rmtree", before=True, when=lambda p, **k: str(p).endswith(".discard") and os.path.exists(p))
    route = runner.compute if site == "assembling" else mechsweep.run  # run() reads no chunk back
    route(mechsweep.load_scene("kill.toml"), output=sys.argv[3], progress=False)
    print("finished without being killed")
""")

SITES = [("journal-created", 1), ("mid-chunk-file", 1), ("mid-chunk-file", 3), ("chunk-renamed", 2),
         ("assembling", 3), ("assembling-held", 3), ("assembling-held", 12),
         ("dataset-placed", 1), ("journal-dropping", 1)]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    where = tmp_path_factory.mktemp("ref")
    (where / "kill.toml").write_text(SCENE.format(n_a=40, n_mu=20, chunk=100))
    return mechsweep.run(mechsweep.load_scene(where / "kill.toml"), output=where / "ref.h5", progress=False)


@pytest.mark.parametrize("site,n", SITES, ids=[f"{s}-{n}" for s, n in SITES])
def test_sigkill_at_every_file_step_then_resume_is_identical(in_tmp, reference, site, n):
    (in_tmp / "kill.toml").write_text(SCENE.format(n_a=40, n_mu=20, chunk=100))
    (in_tmp / "killer.py").write_text(KILLER)
    out = in_tmp / "data" / "runs" / "k.h5"
    child = subprocess.run([sys.executable, "killer.py", site, str(n), str(out)], cwd=in_tmp,
                           capture_output=True, text=True)
    assert child.returncode == -signal.SIGKILL, f"not killed at {site}: {child.stdout}{child.stderr}"
    resumed = mechsweep.run(mechsweep.load_scene(in_tmp / "kill.toml"), output=out, resume=True, progress=False)
    assert_identical(out, reference)
    assert resumed.attrs["scene_canonical"] == reference.attrs["scene_canonical"]
    assert_no_leftovers(out.parent, out)


def test_a_second_run_on_the_same_output_is_refused_while_the_first_writes(in_tmp, long_reference):
    (in_tmp / "kill.toml").write_text(SCENE.format(n_a=600, n_mu=200, chunk=2000))
    out = in_tmp / "data" / "runs" / "k.h5"
    argv, kw = cli("run", "kill.toml", "-o", str(out), "--no-progress", "--threads", "1", cwd=in_tmp)
    first = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, **kw)
    try:
        deadline = time.monotonic() + 120
        while chunks_done(partial_path(out)) < 1 and first.poll() is None and time.monotonic() < deadline:
            time.sleep(0.005)
        assert first.poll() is None, "the first run ended before the second could start"
        for flags in ({}, {"resume": True}, {"restart": True}):
            with pytest.raises(mechsweep.StoreError, match=f"being written by another mechsweep run "
                                                           f"\\(process {first.pid}\\)"):
                mechsweep.run(mechsweep.load_scene(in_tmp / "kill.toml"), output=out, progress=False, **flags)
        assert first.poll() is None, "the refused runs disturbed the first"
    finally:
        first.kill()
        first.wait()


# The child runs the scene with --restart and kills itself with SIGKILL on the n-th removal of a file
# (the discarded journal half deleted).
RESTARTER = textwrap.dedent("""
    import os, signal, sys
    from mechsweep import cli
    real, seen = os.unlink, [0]
    def unlink(*args, **kwargs):
        seen[0] += 1
        if seen[0] == int(sys.argv[1]):
            os.kill(os.getpid(), signal.SIGKILL)
        return real(*args, **kwargs)
    os.unlink = unlink
    sys.exit(cli.main(sys.argv[2:]))
""")


@pytest.mark.parametrize("damage", ["garbage", "links"])
@pytest.mark.parametrize("n", [1, 3])
def test_sigkill_while_restart_discards_a_damaged_journal_then_restart_is_identical(in_tmp, reference, damage, n):
    """--restart on a damaged journal, killed while it deletes it: a second --restart completes the
    run, identical to an uninterrupted one, and what a link in the journal pointed to is untouched."""
    from .data.interrupt import interrupted_after

    (in_tmp / "kill.toml").write_text(SCENE.format(n_a=40, n_mu=20, chunk=100))
    out = in_tmp / "data" / "runs" / "k.h5"
    with interrupted_after(4), pytest.raises(mechsweep.RunInterrupted):
        mechsweep.run(mechsweep.load_scene(in_tmp / "kill.toml"), output=out, progress=False)
    part = partial_path(out)
    user = in_tmp / "user"
    user.mkdir()
    (user / "data.txt").write_text("the user's data\n")
    if damage == "garbage":
        (part / "run.json").write_bytes(b"\x00garbage")
    else:  # run.json a link to the user's file, a chunk file a link to /dev/zero
        (part / "run.json").unlink()
        (part / "run.json").symlink_to(user / "data.txt")
        chunk = sorted((part / "chunks").iterdir())[1]
        chunk.unlink()
        chunk.symlink_to("/dev/zero")
    (in_tmp / "restarter.py").write_text(RESTARTER)
    child = subprocess.run([sys.executable, "restarter.py", str(n), "run", "kill.toml", "-o", str(out),
                            "--no-progress", "--restart", "--threads", "1"], cwd=in_tmp, capture_output=True, text=True)
    assert child.returncode == -signal.SIGKILL, f"not killed: {child.stdout}{child.stderr}"
    assert os.path.lexists(partial_path(out)) or os.path.lexists(str(part) + ".discard")
    mechsweep.run(mechsweep.load_scene(in_tmp / "kill.toml"), output=out, restart=True, progress=False)
    assert_identical(out, reference)
    assert_no_leftovers(out.parent, out)
    assert sorted(os.listdir(user)) == ["data.txt"] and (user / "data.txt").read_text() == "the user's data\n"
