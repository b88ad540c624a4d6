"""`python benchmarks/cluster.py`: throughput of one scene run locally and on a dask cluster of
1 ... W worker processes on this machine, in the same run, and whether the datasets are identical.

Every configuration runs the same Duffing amplitude-period scene (integrated periods) into its own
file. Local runs use 1 and all numba threads. Cluster runs start a LocalCluster of w worker
processes with one task slot each, running the kernels on one numba thread (``threads=1``),
warm it up (each worker loads the JIT cache once) and then time `mechsweep.run(...,
scheduler=...)`: wall time from the call to the finished dataset, journal and assembly included,
and the CPU time this process spent per chunk (on dask: the client, the LocalCluster's scheduler
and the journal writer, i.e. the cost of a task outside the workers).
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/NAME.py`: import from the repository's root, as -m does
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import os
import resource
import tempfile
import time

import numpy as np

from mechsweep.execution.runner import run
from mechsweep.bench.duffing import grid_scene

COMPARED = ("period", "status", "n_steps", "n_rhs")


def _cpu_s() -> float:
    """CPU seconds of this process so far (all its threads: kernels, writer, dask client/scheduler)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _timed_run(scene: dict, out: Path, **kw) -> tuple[float, float, object]:
    t0, c0 = time.perf_counter(), _cpu_s()
    ds = run(scene, output=out, progress=False, restart=True, **kw)
    return time.perf_counter() - t0, _cpu_s() - c0, ds


def _same(a, b) -> bool:
    return all(np.array_equal(a[k].values, b[k].values, equal_nan=True) for k in COMPARED)


def main(points: int = 400_000, workers: int | None = None, chunk: int = 8192) -> list[dict]:
    from mechsweep.bench import arguments
    from mechsweep.errors import InputError

    try:
        from distributed import LocalCluster
    except ImportError:
        raise InputError("this benchmark needs the optional packages dask and distributed: "
                         "pip install \"mechsweep[distributed]\"") from None

    points = arguments.count("points", points)
    workers = arguments.count("workers", workers, 1, 256) if workers is not None else os.cpu_count() or 1
    chunk = arguments.count("chunk", chunk, 1, 2**31)
    scene = grid_scene(points, 5e-11, 1e-12)
    scene["storage"] = {"chunk_size": chunk}
    warm = grid_scene(2_000, 5e-11, 1e-12)
    warm["storage"] = {"chunk_size": 100}  # 20 tasks: every worker gets some and loads the JIT cache
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        run(warm, output=tmp / "warm.h5", progress=False)  # JIT compile or load here first
        reference = None
        for threads in sorted({1, os.cpu_count() or 1}):
            seconds, cpu, ds = _timed_run(scene, tmp / f"local{threads}.h5", threads=threads)
            reference = ds if reference is None else reference
            rows.append({"where": f"local, {threads} numba thread(s)", "seconds": seconds, "cpu": cpu,
                         "same": _same(ds, reference)})
        for w in range(1, workers + 1):
            with LocalCluster(n_workers=w, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
                address = cluster.scheduler_address
                run(warm, output=tmp / "warm.h5", progress=False, restart=True, scheduler=address, threads=1)
                seconds, cpu, ds = _timed_run(scene, tmp / f"dask{w}.h5", scheduler=address, threads=1)
            rows.append({"where": f"dask, {w} worker(s) x 1 thread", "seconds": seconds, "cpu": cpu,
                         "same": _same(ds, reference)})
    n = reference["status"].size
    n_chunks = -(-n // chunk)
    base = rows[0]["seconds"]
    print(f"benchmarks/cluster.py: Duffing periods, {n:,} points in chunks of {chunk}, this machine "
          f"({os.cpu_count()} cores); time includes the journal and the dataset assembly")
    print(f"  {'configuration':<34} {'wall s':>8} {'points/s':>12} {'vs local 1 thread':>18} "
          f"{'this process CPU ms/chunk':>26}  identical to local")
    for r in rows:
        r["points_per_s"] = n / r["seconds"]
        print(f"  {r['where']:<34} {r['seconds']:8.2f} {r['points_per_s']:12,.0f} {base / r['seconds']:17.2f}x "
              f"{1e3 * r['cpu'] / n_chunks:26.1f}  {'yes' if r['same'] else 'NO'}")
    print("  (this process: kernels when local; on dask the client, the scheduler and the journal writer)")
    return rows


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/cluster.py [--points N] [--workers W] [--chunk N]``."""
    from benchmarks import _cli

    p = _cli.parser("cluster", "throughput locally and on a dask LocalCluster of 1..W workers; identical datasets")
    p.add_argument("--points", type=int, default=400_000, help="Duffing grid points (default 400000)")
    p.add_argument("--workers", type=int, default=None, help="up to this many worker processes (default: cores)")
    p.add_argument("--chunk", type=int, default=8192, help="points per chunk, i.e. per task (default 8192)")

    def command(a) -> int:
        main(points=a.points, workers=a.workers, chunk=a.chunk)
        return 0

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
