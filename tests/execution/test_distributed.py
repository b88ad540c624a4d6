"""Runs on a dask.distributed cluster: the same dataset as a local run, bit for bit, and a worker
killed mid-run loses nothing and duplicates nothing."""
import _thread
import contextlib
import os
import re
import signal
import threading
import time

import numpy as np
import pytest

import mechsweep
from mechsweep.execution import cluster, runner
from mechsweep.errors import ClusterLost, InputError
from mechsweep.store.journal import partial_path
from mechsweep.execution.plan import make_plan

distributed = pytest.importorskip("distributed")

SCENE = {
    "scene": {"name": "dist", "model": "duffing", "outputs": ["period", "period_exact", "v_max"]},
    "axes": {"A": {"start": 0.01, "stop": 1.5, "num": 120},
             "mu": {"start": 1e-3, "stop": 1e3, "num": 100, "spacing": "log"}},
    "fixed": {"omega": 1.0},
    "storage": {"chunk_size": 400},
}
COMPARED = ("period", "period_exact", "v_max", "status", "n_steps", "n_rhs", "A", "mu")


@pytest.fixture(scope="module")
def local_cluster():
    # two worker processes of one task slot each (2-core CI machine); runs ask for one numba thread
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        yield c


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    where = tmp_path_factory.mktemp("local")
    return mechsweep.run(SCENE, output=where / "local.h5", progress=False, threads=2)


def assert_identical(ds, reference):
    for name in COMPARED:
        np.testing.assert_array_equal(ds[name].values, reference[name].values, err_msg=name)


def test_cluster_run_equals_local_run(in_tmp, local_cluster, reference):
    ds = mechsweep.run(SCENE, output="data/runs/dist.h5", progress=False, scheduler=local_cluster.scheduler_address,
                       threads=1)
    assert_identical(ds, reference)
    assert ds.attrs["execution"] == f"dask scheduler {local_cluster.scheduler_address}, 1 numba threads per worker"
    assert "threads" not in ds.attrs  # the client's thread count would say nothing about the workers
    assert reference.attrs["execution"] == "local, 2 threads"


def test_scene_execution_section_selects_the_cluster(in_tmp, local_cluster, reference):
    scene = {**SCENE, "execution": {"scheduler": local_cluster.scheduler_address}}
    ds = mechsweep.run(scene, output="data/runs/dist.h5", progress=False)
    assert ds.attrs["execution"].startswith("dask")
    assert_identical(ds, reference)


def test_a_worker_killed_mid_run_loses_and_duplicates_nothing(in_tmp, local_cluster, reference, monkeypatch):
    saved = []
    write = runner.Journal.write_chunk

    def counting(self, index, arrays, wall):
        saved.append(index)
        write(self, index, arrays, wall)

    monkeypatch.setattr(runner.Journal, "write_chunk", counting)
    with distributed.Client(local_cluster.scheduler_address) as client:
        victim = next(iter(client.run(os.getpid).values()))
    n_chunks = len(runner.plan_chunks(reference["status"].shape, 400))
    killed_at = []

    def kill_when_under_way():
        deadline = time.monotonic() + 60
        while len(saved) < 2 and time.monotonic() < deadline:
            time.sleep(0.002)
        killed_at.append(len(saved))
        os.kill(victim, signal.SIGKILL)

    killer = threading.Thread(target=kill_when_under_way)
    killer.start()
    ds = mechsweep.run(SCENE, output="data/runs/dist.h5", progress=False, scheduler=local_cluster.scheduler_address,
                       threads=1)
    killer.join()
    assert 2 <= killed_at[0] < n_chunks, "the worker was not killed while the run was under way"
    assert sorted(saved) == list(range(n_chunks)), "a chunk was lost or saved twice"
    assert_identical(ds, reference)
    assert not partial_path(in_tmp / "data/runs/dist.h5").exists()


def test_unreachable_scheduler_is_a_clear_error(in_tmp, monkeypatch):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 1)
    with pytest.raises(InputError, match="cannot reach the dask scheduler at 'tcp://127.0.0.1:9'"):
        mechsweep.run(SCENE, output="data/runs/none.h5", progress=False, scheduler="tcp://127.0.0.1:9")
    assert list((in_tmp / "data" / "runs").iterdir()) == []  # no dataset, and no journal left to refuse the next run


@pytest.mark.parametrize("address", ["", "tcp://a b", 3])
def test_bad_scheduler_address_is_refused_before_any_file(in_tmp, address):
    with pytest.raises(InputError, match="scheduler"):
        mechsweep.run(SCENE, output="data/runs/none.h5", progress=False, scheduler=address)
    assert list((in_tmp / "data" / "runs").iterdir()) == []


def _threads_after_a_chunk(plan, chunk, threads):
    import numba

    cluster.compute_chunk(plan, chunk, threads)
    return numba.get_num_threads()


def test_threads_apply_to_the_worker_task(local_cluster):
    scene = mechsweep.load_scene(SCENE)
    chunk = runner.plan_chunks(scene.shape, 400)[0]
    with distributed.Client(local_cluster.scheduler_address) as client:
        for threads, expected in ((1, 1), (10**6, None)):  # None: all of the worker's, and no more
            got = client.submit(_threads_after_a_chunk, make_plan(scene), chunk, threads, pure=False).result()
            most = client.submit(lambda: __import__("numba").config.NUMBA_NUM_THREADS, pure=False).result()
            assert got == (expected or most)


# ----------------------------------------------------------------------------- a lost cluster
@contextlib.contextmanager
def watchdog(seconds=60):
    """Interrupt the main thread (as Ctrl-C does) if the run waits longer than ``seconds``: a run
    that would wait forever fails the test instead of hanging it."""
    timer = threading.Timer(seconds, _thread.interrupt_main)
    timer.start()
    try:
        yield
    finally:
        timer.cancel()


def test_a_cluster_without_workers_stops_after_the_worker_timeout(in_tmp):
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as empty:
        address = empty.scheduler_address
        started = time.monotonic()
        with watchdog(), pytest.raises(ClusterLost, match=f"the dask scheduler at {re.escape(address)} has had no "
                                                          r"worker for 1 s \(\[execution\] worker_timeout\)"):
            mechsweep.run(SCENE, output="data/runs/dist.h5", progress=False, scheduler=address, threads=1,
                          worker_timeout=1)
        assert time.monotonic() - started < 30
    assert partial_path(in_tmp / "data/runs/dist.h5").is_dir(), "the journal is kept"


def _saving_counter(monkeypatch):
    saved = []
    write = runner.Journal.write_chunk

    def counting(self, index, arrays, wall):
        write(self, index, arrays, wall)
        saved.append(index)

    monkeypatch.setattr(runner.Journal, "write_chunk", counting)
    return saved


def _when_saved(saved, n, action):
    def run():
        deadline = time.monotonic() + 60
        while len(saved) < n and time.monotonic() < deadline:
            time.sleep(0.002)
        action()
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


@pytest.mark.parametrize("loss", ["workers", "scheduler"])
def test_a_lost_cluster_ends_with_a_message_and_the_run_resumes_identically(in_tmp, reference, monkeypatch, loss):
    """All workers gone (the run waits worker_timeout, then stops), or the scheduler closed (its
    tasks are cancelled: the run stops at once); either way the saved chunks are kept and a
    local --resume completes the dataset bit for bit."""
    saved = _saving_counter(monkeypatch)
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0")
    address = cluster.scheduler_address
    try:
        _when_saved(saved, 2, (lambda: cluster.scale(0)) if loss == "workers" else cluster.close)
        expected = "has had no worker for 1 s" if loss == "workers" else "lost the dask scheduler at"
        with watchdog(), pytest.raises(ClusterLost, match=re.escape(expected)) as caught:
            mechsweep.run(SCENE, output="data/runs/dist.h5", progress=False, scheduler=address, threads=1,
                          worker_timeout=1)
    finally:
        cluster.close()
    message = str(caught.value)
    assert address in message and "chunks in flight were not computed" in message
    assert "chunks saved in data/runs/dist.h5.partial); run again with --resume" in message
    assert len(saved) >= 2
    monkeypatch.undo()
    monkeypatch.chdir(in_tmp)  # undo() also undid in_tmp's chdir: resume this journal, not data/runs of the cwd
    ds = mechsweep.run(SCENE, output="data/runs/dist.h5", progress=False, resume=True, threads=2)
    assert_identical(ds, reference)


@pytest.mark.slow
def test_a_scheduler_killed_with_sigkill_ends_with_a_message(in_tmp, reference, monkeypatch):
    """A real `dask scheduler` process killed mid-run (the connection resets, the tasks are
    cancelled): a message naming it, the journal kept, no traceback; a local --resume completes it."""
    import json
    import subprocess
    import sys

    spec = in_tmp / "scheduler.json"
    scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--port", "0",
                                  "--no-dashboard", "--scheduler-file", str(spec)], stderr=subprocess.DEVNULL)
    worker = None
    try:
        deadline = time.monotonic() + 60
        while not spec.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.2)
        address = json.loads(spec.read_text())["address"]
        worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                                   "--no-nanny", "--no-dashboard"], stderr=subprocess.DEVNULL)
        saved = _saving_counter(monkeypatch)
        _when_saved(saved, 2, scheduler.kill)
        with watchdog(), pytest.raises(ClusterLost, match=f"lost the dask scheduler at {re.escape(address)}") as caught:
            mechsweep.run(SCENE, output="data/runs/dist.h5", progress=False, scheduler=address, threads=1,
                          worker_timeout=5)
    finally:
        scheduler.kill()
        if worker is not None:
            worker.kill()
    assert "run again with --resume" in str(caught.value)
    monkeypatch.undo()
    monkeypatch.chdir(in_tmp)  # undo() also undid in_tmp's chdir: resume this journal, not data/runs of the cwd
    ds = mechsweep.run(SCENE, output="data/runs/dist.h5", progress=False, resume=True, threads=2)
    assert_identical(ds, reference)
