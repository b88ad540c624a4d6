"""`python benchmarks/duffing_breakdown.py`: where the time of a `mechsweep.run` goes, step by step,
against its kernel alone.

The bench grid of `mechsweep bench duffing` (the amplitude-period sweep, DOP853) is run to an HDF5
file ``repeats`` times with the steps of the run (scene, journal, parameter rows, kernel, writer,
assembly, ...) timed, wall and thread CPU, and each kernel launch's threads accounted (on a CPU,
waiting for one, asleep at the launch's end), beside the kernel alone on the same grid and outputs
in one call.
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/NAME.py`: import from the repository's root, as -m does
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import os
import tempfile
import time

from mechsweep.bench.duffing import grid_scene
from mechsweep.chunks import Chunk
from mechsweep.engine import kernels as model_compile
from mechsweep.execution.execute import evaluate_chunk, threads as _threads
from mechsweep.execution.runner import run
from mechsweep.scene import Solver, load_scene


def _whole_grid(scene) -> Chunk:
    return Chunk(0, 0, scene.n_points, ())


def _timed(f):
    """(wall s, process CPU s, result) of f()."""
    t0, c0 = time.perf_counter(), time.process_time()
    result = f()
    return time.perf_counter() - t0, time.process_time() - c0, result


# The steps of `mechsweep.run` timed by `breakdown` (owner, attribute, label): each is wrapped for the
# measured runs only, its wall and thread CPU time added up per call (a step inside another is
# counted in both). The writer thread's steps run while the main thread computes the next chunk.
_STEPS = (
    ("execution.runner", "load_scene", "scene: load and validate"),
    ("execution.runner", "check_existing", "checks: existing files, journal"),
    ("store.journal:Journal", "create", "journal: create (run.json, fsyncs)"),
    ("store.assemble:MemorySink", "__init__", "dataset in memory: define"),
    ("grid:ParameterMatrix", "__call__", "per chunk: parameter rows"),
    ("execution.execute", "evaluate_rows", "per chunk: kernel + status/NONFINITE"),
    ("store.journal:Journal", "write_chunk", "writer: journal chunk file + fsyncs"),
    ("store.assemble:MemorySink", "save", "writer: chunk into the dataset in memory"),
    ("store.assemble:Early", "prepare", "writer: define the HDF5 file (early)"),
    ("store.assemble:Early", "write", "writer: chunk into the HDF5 file (early)"),
    ("store.write", "define", "HDF5/memory: define (store.write.define)"),
    ("store.assemble", "define", "HDF5/memory: define (store.write.define)"),
    ("execution.runner", "_save_chunks", "all chunks (main thread, wall)"),
    ("execution.runner", "_finish", "end: assembly, fsync, rename, drop journal"),
    ("store.assemble", "_assemble", "end: assembly (HDF5 writes, close)"),
    ("execution.runner", "drop", "end: drop the journal"),
    ("execution.runner", "_times", "end: read the times back"),
)


def _schedstat() -> dict:
    """Per thread of this process (Linux: /proc/self/task/*/schedstat): (ns on a CPU, ns waiting in
    the run queue for a CPU). Empty where the kernel does not provide it."""
    out = {}
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f"/proc/self/task/{tid}/schedstat") as f:
                on, waiting = f.read().split()[:2]
            out[int(tid)] = (int(on), int(waiting))
        except (OSError, ValueError):
            pass
    return out


def _launch_account(acc: dict, f):
    """A wrapper of the model's ``evaluate`` ``f`` (one chunk's kernel launch, inside execute.evaluate_rows)
    that adds up, per launch, the on-CPU, run-queue wait and asleep time of the calling thread and of
    the kernel's other threads (those that ran during it, the run's writer thread excepted): asleep
    is the launch's wall time that a thread neither ran nor waited for a CPU, i.e. a thread that ran
    out of work waiting at the end of the launch for the slowest (or, for the caller, for the GIL).
    Also the run's thread's time between two launches (the Python of the chunk boundary)."""
    import threading

    def accounted(*a, **k):
        me = threading.get_native_id()
        s0, t0 = _schedstat(), time.perf_counter_ns()
        try:
            return f(*a, **k)
        finally:
            s1, wall = _schedstat(), time.perf_counter_ns() - t0
            writers = {t.native_id for t in threading.enumerate() if t.name.startswith("mechsweep-writer")}
            e = acc.setdefault("launches", {"n": 0, "wall": 0, "caller": [0, 0, 0], "others": [0, 0, 0],
                                            "threads": 0, "first": t0, "last": t0, "between": 0})
            if e["n"]:
                e["between"] += t0 - e["last"]  # the run's thread between two chunks' launches
            e["n"] += 1
            e["wall"] += wall
            e["last"] = t0 + wall
            others = 0
            for tid, (on1, w1) in s1.items():
                if tid not in s0 or tid in writers:
                    continue
                on, waiting = on1 - s0[tid][0], w1 - s0[tid][1]
                if tid != me and on <= 0:
                    continue  # a thread that did not take part (asleep throughout)
                key = "caller" if tid == me else "others"
                others += tid != me
                for j, v in enumerate((on, waiting, wall - on - waiting)):
                    e[key][j] += v
            e["threads"] = max(e["threads"], 1 + others)

    return accounted


def _owner(path: str):
    import importlib

    module, _, cls = path.partition(":")  # "package.module:Class" or "package.module"
    obj = importlib.import_module(f"mechsweep.{module}")
    return getattr(obj, cls, None) if cls else obj  # None: a step this version does not have


def breakdown(points: int = 200_000, threads: int | None = None, rtol: float = Solver.rtol,
              atol: float = Solver.atol, repeats: int = 3, outputs=("period", "period_exact", "period_error",
                                                                     "v_max", "a_max"),
              lanes: bool | None = True) -> list[dict]:
    """`mechsweep.run` of the bench grid to an HDF5 file, ``repeats`` times, with its steps timed
    (wall and CPU of the thread that runs them) and its kernel launches accounted per thread (on a
    CPU, waiting for one, asleep: ``_launch_account``), beside the kernel alone on the same grid and
    outputs in one call. ``lanes``: the kernel route (engine.kernels.USE_LANES; True, the lane
    kernel of goal 1, by default). Prints a table per run; returns the timings."""
    import functools
    import numba

    from mechsweep.bench import arguments

    points = arguments.count("points", points)
    repeats = arguments.count("repeats", repeats, 1, 100)
    threads = arguments.threads("threads", threads)
    scene = load_scene(grid_scene(points, rtol, atol, outputs))
    n = scene.n_points
    acc: dict = {}
    saved = []
    for path, name, label in _STEPS:
        owner = _owner(path)
        if owner is None or not hasattr(owner, name):  # a step this version does not have
            continue
        f = getattr(owner, name)

        def timed(*a, _f=f, _label=label, **k):
            t0, c0 = time.perf_counter(), time.thread_time()
            try:
                return _f(*a, **k)
            finally:
                e = acc.setdefault(_label, [0.0, 0.0, 0])
                e[0] += time.perf_counter() - t0
                e[1] += time.thread_time() - c0
                e[2] += 1

        saved.append((owner, name, f))
        setattr(owner, name, functools.wraps(f)(timed))
    use_lanes = model_compile.USE_LANES
    model_compile.USE_LANES = lanes  # the lane kernel (goal 1's), also where the run alone would not take it
    # the run's scenes share this scene's model object (the registry's): its evaluate, the kernel
    # launch of each chunk, is accounted per thread (a frozen dataclass: set around its own __setattr__)
    plain = scene.model.evaluate
    object.__setattr__(scene.model, "evaluate", _launch_account(acc, plain))
    results = []
    try:
        with _threads(threads), tempfile.TemporaryDirectory() as tmp:
            n_threads = numba.get_num_threads()
            evaluate_chunk(scene, Chunk(0, 0, 4, ()))
            run(grid_scene(1000, rtol, atol, outputs), output=os.path.join(tmp, "warm.h5"), progress=False)
            for k in range(repeats):
                kw, kc, _ = _timed(lambda: evaluate_chunk(scene, _whole_grid(scene)))
                acc.clear()
                path = os.path.join(tmp, f"run{k}.h5")
                began = time.perf_counter_ns()
                wall, cpu, _ = _timed(lambda: run(grid_scene(points, rtol, atol, outputs), output=path,
                                                  progress=False))
                ended = began + int(wall * 1e9)
                if "launches" in acc:  # the serial start and end of the run, around its launches
                    e = acc["launches"]
                    e["before"], e["after"] = e["first"] - began, ended - e["last"]
                os.unlink(path)
                launches = acc.pop("launches", None)
                results.append({"points": n, "threads": n_threads, "kernel_wall_s": kw, "kernel_cpu_s": kc,
                                "run_wall_s": wall, "run_cpu_s": cpu, "load": os.getloadavg()[0],
                                "steps": {label: tuple(v) for label, v in acc.items()}, "launches": launches})
    finally:
        model_compile.USE_LANES = use_lanes
        object.__setattr__(scene.model, "evaluate", plain)
        for owner, name, f in reversed(saved):
            setattr(owner, name, f)
    for r in results:
        print(f"mechsweep.run breakdown: {r['points']:,} points, outputs {', '.join(outputs)}, rtol {rtol:g}, "
              f"{r['threads']} threads, load average {r['load']:.2f}")
        print(f"  kernel alone (one call, same outputs): {r['kernel_wall_s'] * 1e3:8.1f} ms wall, "
              f"{r['kernel_cpu_s'] * 1e3:8.1f} ms process CPU, {n / r['kernel_wall_s']:,.0f} points/s")
        print(f"  mechsweep.run -> HDF5               : {r['run_wall_s'] * 1e3:8.1f} ms wall, "
              f"{r['run_cpu_s'] * 1e3:8.1f} ms process CPU, {n / r['run_wall_s']:,.0f} points/s "
              f"(run / kernel: {r['kernel_wall_s'] / r['run_wall_s']:.2f} wall, "
              f"{r['kernel_cpu_s'] / r['run_cpu_s']:.2f} CPU)")
        for label, (w, c, calls) in r["steps"].items():
            print(f"    {label:45s} {calls:4d} calls {w * 1e3:8.1f} ms wall {c * 1e3:8.1f} ms thread CPU")
        e = r["launches"]
        if e and e["n"]:
            print(f"    kernel launches ({e['n']}, {e['wall'] / 1e6:.1f} ms wall in all; per thread: on a CPU / "
                  "waiting for a CPU / asleep):")
            for key, label in (("caller", "the run's thread"),
                               ("others", f"the kernel's other threads ({e['threads'] - 1})")):
                on, waiting, asleep = (v / 1e6 for v in e[key])
                print(f"      {label:50s} {on:8.1f} / {waiting:8.1f} / {asleep:8.1f} ms")
            print(f"    before the first launch {e['before'] / 1e6:.1f} ms, between launches {e['between'] / 1e6:.1f} ms, "
                  f"after the last {e['after'] / 1e6:.1f} ms (wall, the run's thread)")
    return results


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/duffing_breakdown.py [--points N] [--threads N] [--rtol R] [--atol A] [--repeats N]
    [--outputs NAMES]``."""
    from benchmarks import _cli

    p = _cli.parser("duffing_breakdown", "time the steps of mechsweep.run (planning, journal, kernel, HDF5, ...) "
                                         "against the kernel (the lane kernel), with each kernel launch's threads "
                                         "accounted (on a CPU, waiting for one, asleep at the launch's end), "
                                         "--repeats times")
    p.add_argument("--points", type=int, default=200_000, help="grid points (default 200000)")
    p.add_argument("--threads", type=int, default=None, help="numba threads (default: all cores)")
    p.add_argument("--rtol", type=float, default=None, help="default: the solver default")
    p.add_argument("--atol", type=float, default=None, help="default: the solver default")
    p.add_argument("--repeats", type=int, default=3, help="runs timed (default 3)")
    p.add_argument("--outputs", default=None,
                   help="the outputs the run stores, comma-separated (default: period, period_exact, period_error, "
                        "v_max, a_max)")

    def command(a) -> int:
        outputs = {} if a.outputs is None else {"outputs": tuple(o.strip() for o in a.outputs.split(","))}
        breakdown(points=a.points, threads=a.threads, repeats=a.repeats,
                  rtol=Solver.rtol if a.rtol is None else a.rtol, atol=Solver.atol if a.atol is None else a.atol,
                  **outputs)
        return 0

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
