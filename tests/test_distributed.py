"""Runs on a dask.distributed cluster: the same dataset as a local run, bit for bit, and a worker
killed mid-run loses nothing and duplicates nothing."""
import os
import signal
import threading
import time

import numpy as np
import pytest

import mechsweep
from mechsweep import cluster, runner
from mechsweep.errors import InputError
from mechsweep.journal import partial_path

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
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as c:
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


def _threads_after_a_chunk(text, chunk, threads):
    import numba

    cluster.compute_chunk(text, chunk, threads)
    return numba.get_num_threads()


def test_threads_apply_to_the_worker_task(local_cluster):
    scene = mechsweep.load_scene(SCENE)
    chunk = runner.plan_chunks(scene.shape, 400)[0]
    with distributed.Client(local_cluster.scheduler_address) as client:
        for threads, expected in ((1, 1), (10**6, None)):  # None: all of the worker's, and no more
            got = client.submit(_threads_after_a_chunk, scene.text, chunk, threads, pure=False).result()
            most = client.submit(lambda: __import__("numba").config.NUMBA_NUM_THREADS, pure=False).result()
            assert got == (expected or most)
