"""`python benchmarks/startup.py`: the fixed costs of a run, its cold start, and its cost per point.

Each figure is printed with its target beside it (the project's start-up and cost targets), as the median of
``repeats`` (>= 3) measurements and their spread (min .. max):

- warm ``mechsweep.run`` of 10^3 and 10^4 Duffing points (integrated period, DOP853, rtol 1e-10),
  in memory (``output=None``; targets 10 ms and 25 ms) and to a file (no target: the file route
  adds the journal, its fsyncs, and the HDF5 assembly; the returned dataset is the one held in memory, not re-opened), interleaved with
  the kernel alone on the same grid (one call, no run around it: the difference is the run's fixed
  cost, which is what a busy machine does not blur);
- the quickstart (``mechsweep run sweeps/quickstart.toml`` then ``mechsweep plot``) in fresh
  processes, cold (an empty JIT cache folder of its own for each repetition; target 8 s) and
  warm (target 2.5 s); the run's own compile and compute times are read from its dataset;
- the cost per point of ``mechsweep.compute`` to a file from 10^4 to 10^6 integrated points
  (--full: to 10^7 integrated and 10^6 .. 10^8 closed-form points; beyond 10^7 points, an axis's
  most, the grid is 10^4 x 10^4), warm, and the peak resident memory of the command
  ``mechsweep run`` on the same grid (a fresh process, interpreter included; benchmarks/memory.py
  explains the measurement);
- ``--only routes``: the cold compile of the quickstart's kernels by route (SIMD lanes, one point at
  a time) in fresh processes with an empty JIT cache each, alternated, and both warm kernels' points/s
  side by side: what engine/kernels.py's LANES_FROM_POINTS and LANES_AFTER_POINTS are set from; likewise the sampled-trajectory
  kernel (one trajectory at a time, sweeps/autobalancer_residual.toml) and the closed-form kernel
  (sweeps/fourbar_pareto.toml), each warm in the process that compiled it (``--routes`` picks some);
- ``--only compile``: the scene's cold compile by function (numba's compile events in a fresh process with
  an empty JIT cache; each function's own time split into LLVM's work and numba's own) and by phase (numba's
  typing, lowering, IR inlining; LLVM's parsing, passes, linking, machine code), ``repeats`` times.
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/NAME.py`: import from the repository's root, as -m does
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import json
import os
import statistics
import subprocess
import tempfile
import time

from benchmarks import memory

TARGET_WARM_MS = {10**3: 10.0, 10**4: 25.0}
TARGET_COLD_S = 8.0
TARGET_WARM_S = 2.5
RTOL, ATOL = 1e-10, 1e-12


def shape_of(n: int) -> tuple[int, ...]:
    """The grid of ``n`` points: one axis (mu) up to 10^7 points (an axis's most), beyond that
    10^4 values of A by n / 10^4 of mu."""
    return (n,) if n <= 10**7 else (10**4, n // 10**4)


def duffing(n: int, output: str = "period") -> dict:
    """A Duffing scene of ``n`` points (one axis, mu, up to 10^7 points), the bench's standard small grid."""
    data = memory.scene(shape_of(n), output)
    data["scene"]["name"] = "bench-startup"
    data["solver"].update(rtol=RTOL, atol=ATOL)
    return data


def _spread(values: list[float], unit: str, scale: float = 1.0, fmt: str = ".1f") -> str:
    v = [x * scale for x in values]
    return f"{statistics.median(v):{fmt}} {unit} ({min(v):{fmt}} .. {max(v):{fmt}}, {len(v)} runs)"


def _verdict(value: float, target: float) -> str:
    return "met" if value <= target else "NOT met"


def warm_small(repeats: int, folder: Path) -> dict:
    """Seconds of warm runs of 10^3 and 10^4 points, in memory and to a file: {(n, route): [s]}."""
    import mechsweep
    from mechsweep.grid import ParameterMatrix
    from mechsweep.execution.execute import evaluate_rows
    from mechsweep.scene import load_scene

    out = {}
    for n in TARGET_WARM_MS:
        scene = load_scene(duffing(n))
        path = folder / f"warm{n}.h5"
        mechsweep.run(scene, output=None)  # compile or load the kernels first
        mechsweep.run(scene, output=path, progress=False)
        P = ParameterMatrix(scene)(0, n)
        times = {"kernel": [], "memory": [], "file": []}
        for _ in range(repeats):  # interleaved: a burst of load on the machine hits all three alike
            for route in times:
                t0 = time.perf_counter()
                if route == "kernel":
                    evaluate_rows(scene, P)
                elif route == "memory":
                    mechsweep.run(scene, output=None)
                else:
                    mechsweep.run(scene, output=path, progress=False)
                times[route].append(time.perf_counter() - t0)
        for route, v in times.items():
            out[n, route] = v
    return out


def _command(args: list[str], env: dict, cwd: Path) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of ``mechsweep ARGS`` in a fresh process. The CPU time (user +
    system of the child) is less blurred than the wall time when other processes share the cores."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "mechsweep.cli", *args], env=env, cwd=cwd, capture_output=True,
                          text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"mechsweep {' '.join(args)} failed:\n{proc.stderr[-2000:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def quickstart(scene: Path, repeats: int, folder: Path) -> dict:
    """Cold and warm quickstart (run + plot) in fresh processes:
    {label: [(run s, plot s, compile s, run CPU s, plot CPU s)]}."""
    import h5py

    result = {"cold": [], "warm": []}
    out = folder / "quickstart.h5"
    for label in ("cold", "warm"):
        for i in range(repeats):
            cache = folder / (f"cache-cold-{i}" if label == "cold" else "cache-cold-0")  # warm: filled by cold 0
            env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(cache))
            run_s, run_cpu = _command(["run", str(scene), "-o", str(out), "--no-progress", "--overwrite"], env, folder)
            plot_s, plot_cpu = _command(["plot", str(out)], env, folder)
            with h5py.File(out, "r") as f:
                compile_s = float(f.attrs.get("compile_time_s", float("nan")))
            result[label].append((run_s, plot_s, compile_s, run_cpu, plot_cpu))
    return result


def warm_start(scene: Path, repeats: int, folder: Path, against: str | None = None) -> dict:
    """The warm quickstart as a user runs it (``mechsweep run SCENE`` then ``mechsweep plot`` of its
    dataset, two fresh processes, JIT cache filled), ``repeats`` times, split by process: {label:
    [(run wall, run CPU, plot wall, plot CPU, load average before the run)]}. ``against``: the ``src``
    folder of other sources (e.g. another checkout's), run alternately with this package's, each in
    its own processes (``PYTHONPATH``). The JIT cache is the environment's (``MECHSWEEP_CACHE_DIR``, else
    the default), filled by one unmeasured run and plot of each; the children write Python's bytecode
    to a folder of their own (``PYTHONPYCACHEPREFIX``, also under ``PYTHONDONTWRITEBYTECODE``), so
    neither set of sources is compiled from source in a measured process (an installed package has its
    bytecode)."""
    import mechsweep

    sources = {"this": Path(mechsweep.__file__).resolve().parents[1]}
    if against is not None:
        sources["against"] = Path(against).resolve()
    base = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    base["PYTHONPYCACHEPREFIX"] = str(folder / "pycache")
    result = {label: [] for label in sources}
    envs = {label: dict(base, PYTHONPATH=str(src)) for label, src in sources.items()}
    outs = {label: folder / label / "quickstart.h5" for label in sources}
    for label in sources:
        outs[label].parent.mkdir(parents=True, exist_ok=True)
    run_args = {label: ["run", str(scene), "-o", str(out), "--no-progress", "--overwrite"] for label, out in outs.items()}
    for label in sources:  # fill the JIT cache and the bytecode
        _command(run_args[label], envs[label], folder)
        _command(["plot", str(outs[label])], envs[label], folder)
    for _ in range(repeats):
        for label in sources:  # alternated: a burst of load hits both alike
            load = os.getloadavg()[0]
            run_s, run_cpu = _command(run_args[label], envs[label], folder)
            plot_s, plot_cpu = _command(["plot", str(outs[label])], envs[label], folder)
            result[label].append((run_s, run_cpu, plot_s, plot_cpu, load))
    phases = {}
    for label in sources:  # where the time goes, by phase, in one more fresh process of each kind
        phases[label] = {}
        for kind, code, args in (("run", RUN_CHILD, [str(scene), str(folder / label / "phases.h5")]),
                                 ("plot", PLOT_CHILD, [str(outs[label]), str(folder / label / "phases")])):
            proc = subprocess.run([sys.executable, "-c", code, *args], env=envs[label], cwd=folder,
                                  capture_output=True, text=True)
            if proc.returncode != 0:
                raise RuntimeError(f"{kind} phases failed:\n{proc.stderr[-2000:]}")
            phases[label][kind] = json.loads(proc.stdout.strip().splitlines()[-1])
    return {"sources": {k: str(v) for k, v in sources.items()}, "phases": phases, **result}


def scaling(sizes: list[tuple[int, str]], repeats: int, folder: Path) -> list[dict]:
    """Warm cost per point of ``compute`` to a file, and the peak RSS of the command on the same grid."""
    from mechsweep.execution.runner import compute
    from mechsweep.scene import load_scene

    rows = []
    for n, output in sizes:
        scene = load_scene(duffing(n, output))
        path = folder / f"scale{n}.h5"
        compute(load_scene(duffing(1000, output)), output=folder / "w.h5", progress=False, overwrite=True)
        times, cpu = [], []
        for _ in range(repeats if n <= 10**6 else 1):
            t0, c0 = time.perf_counter(), time.process_time()
            compute(scene, output=path, progress=False, overwrite=True)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        path.unlink()
        command = memory._case("command", output, shape_of(n), folder)
        rows.append({"points": n, "output": output, "seconds": times, "cpu_seconds": cpu,
                     "peak_rss": command["peak_rss"], "disk": command["disk"], "command_s": command["process_s"]})
    return rows


LINEAR_WITHIN = 1.15  # CPU per point of the two largest grids of an output: "linear" if within 15 %


def _scaling_verdict(rows: list[dict]) -> None:
    """Goal 5 against its target: CPU per point of the two largest grids of each output (linear:
    about 1), and the command's peak memory against the dataset's size and a chunk's estimate."""
    from mechsweep.grid import chunk_target
    from mechsweep.execution.checks import CHUNK_MEMORY_FACTOR, bytes_per_point
    from mechsweep.scene import load_scene

    for output in dict.fromkeys(r["output"] for r in rows):
        mine = sorted((r for r in rows if r["output"] == output), key=lambda r: r["points"])
        if len(mine) < 2:
            continue
        a, b = mine[-2], mine[-1]
        per_a, per_b = (statistics.median(r["cpu_seconds"]) / r["points"] for r in (a, b))
        ratio = per_b / per_a
        print(f"    goal 5, {output}: CPU per point at {b['points']:,} points / at {a['points']:,} = {ratio:.2f} "
              f"(target: linear, within {LINEAR_WITHIN:g}): {_verdict(ratio, LINEAR_WITHIN)}")
    small, big = min(rows, key=lambda r: r["peak_rss"]), max(rows, key=lambda r: r["disk"])
    scene = load_scene(duffing(big["points"], big["output"]))
    chunk = CHUNK_MEMORY_FACTOR * bytes_per_point(scene) * min(chunk_target(scene), scene.n_points)
    print(f"    goal 5, memory: command peak RSS {small['peak_rss'] / 2**20:.0f} .. "
          f"{max(r['peak_rss'] for r in rows) / 2**20:.0f} MiB from {min(r['points'] for r in rows):,} to "
          f"{max(r['points'] for r in rows):,} points; the largest dataset {big['disk'] / 2**20:.0f} MiB, a chunk's "
          f"estimate (checks.CHUNK_MEMORY_FACTOR x its outputs) {chunk / 2**20:.1f} MiB (target: within chunk + "
          "interpreter, i.e. not growing with the grid)")


COMPILE_CHILD = """
import json, sys, time  # CPU time of the compiling thread: less blurred by other processes than wall
from numba.core import codegen, event
rows, stack = [], []
class Listener(event.Listener):
    def on_start(self, ev):
        stack.append([time.thread_time(), 0.0, 0.0, 0.0])  # start, nested compiles, own LLVM: finalize, function passes
    def on_end(self, ev):
        d = ev.data["dispatcher"]
        start, nested, fin, fpass = stack.pop()
        took = time.thread_time() - start
        if stack:
            stack[-1][1] += took
        rows.append((took, took - nested, d.py_func.__module__,
                     d.py_func.__module__.split(".")[-1] + "." + d.py_func.__qualname__.split(".<locals>.")[-1],
                     fin, fpass))
event.register("numba:compile", Listener())
def timed(name, slot):  # LLVM's share of the innermost compile: a library's finalize (linking its callees'
    original = getattr(codegen.CPUCodeLibrary, name)  # modules, the module passes, machine code), function passes
    def wrapper(self, *a, **k):
        t = time.thread_time()
        try:
            return original(self, *a, **k)
        finally:
            if stack:
                stack[-1][slot] += time.thread_time() - t
    setattr(codegen.CPUCodeLibrary, name, wrapper)
timed("finalize", 2)
timed("_optimize_functions", 3)
phases, open_phases = {}, []  # the same compile by phase: each phase's time without the phases nested in it
def phase(owner, name, label):
    original = getattr(owner, name)
    def wrapper(*a, **k):
        open_phases.append([label, time.thread_time(), 0.0])
        try:
            return original(*a, **k)
        finally:
            label_, start, nested = open_phases.pop()
            took = time.thread_time() - start
            phases[label_] = phases.get(label_, 0.0) + took - nested
            if open_phases:
                open_phases[-1][2] += took
    setattr(owner, name, wrapper)
import llvmlite.binding as ll
from numba.core import caching, dispatcher, lowering, typed_passes, untyped_passes
for owner, names, label in (
        (dispatcher.Dispatcher, ("compile",), "numba: the rest (bytecode to IR, IR passes, dispatch, cache lookups)"),
        (untyped_passes.InlineInlinables, ("run_pass",), "numba: IR inlining (inline='always': the callee's IR made, copied)"),
        (typed_passes.BaseTypeInference, ("run_pass",), "numba: type inference"),
        (lowering.BaseLower, ("lower",), "numba: lowering to LLVM IR"),
        (lowering.BaseLower, ("create_cpython_wrapper", "create_cfunc_wrapper"), "numba: CPython wrappers"),
        (caching.Cache, ("save_overload",), "numba: disk cache writes"),
        (codegen.CPUCodeLibrary, ("add_ir_module",), "LLVM: parse numba's IR text"),
        (codegen.CPUCodeLibrary, ("_optimize_functions",), "LLVM: function passes"),
        (ll.ModuleRef, ("link_in",), "LLVM: link the callees' modules"),
        (codegen.CPUCodeLibrary, ("_optimize_final_module",), "LLVM: module passes (the linked module)"),
        (codegen.CPUCodeLibrary, ("_finalize_final_module",), "LLVM: machine code (the linked module)")):
    for name in names:
        phase(owner, name, label)
import mechsweep
c0 = time.thread_time()
ds = mechsweep.run(sys.argv[1], output=sys.argv[2], progress=False)  # the dataset the plot breakdown draws
print(json.dumps({"rows": sorted(rows, reverse=True), "compile_time_s": ds.attrs["compile_time_s"], "phases": phases,
                  "run_cpu": time.thread_time() - c0}))
"""


_LAP = """
import json, sys, time
t0 = time.perf_counter()
phases = []
def lap(name):
    global t0
    t = time.perf_counter()
    phases.append((name, t - t0))
    t0 = t
"""  # the phases of a child process, timed as they end


PLOT_CHILD = _LAP + """
from mechsweep.commands.plot import no_dask_probe as _no_dask_probe
import matplotlib.figure, xarray
lap("import matplotlib, xarray")
from mechsweep import figures
from mechsweep.store import open_dataset
lap("import mechsweep.figures, store")
save = getattr(figures, "savefig", None)  # how `plot` writes a figure (older sources: matplotlib's savefig)
with _no_dask_probe():
    ds = open_dataset(sys.argv[1])
    lap("open the dataset")
    plan = {name: fn for name, _, fn, _ in figures._plan(ds)}
    for kind in figures.available(ds):
        fig = plan[kind](ds).figure
        lap(f"draw {kind}")
        if save is not None:
            save(fig, f"{sys.argv[2]}_{kind}.png", format="png", dpi=150)
        else:
            fig.savefig(f"{sys.argv[2]}_{kind}.png", dpi=150)
        lap(f"savefig {kind} (layout, render, PNG)")
print(json.dumps(phases))
"""


RUN_CHILD = _LAP + """
import os
import numpy
lap("import numpy")
import numba
lap("import numba")
from mechsweep import cli
lap("import mechsweep.cli")
from mechsweep import scene
from mechsweep.execution import execute, runner
lap("import mechsweep.scene, runner (the models)")
s = scene.load_scene(sys.argv[1])
lap("load the scene")
from mechsweep.grid import ParameterMatrix
execute.evaluate_rows(s, ParameterMatrix(s)(0, 1))
lap("first kernel call (numba's target, the cached kernel)")
runner.compute(s, output=sys.argv[2], progress=False, overwrite=True)
lap("compute to the file")
phases.append(("scipy.linalg imported", "scipy.linalg" in sys.modules))
print(__import__("json").dumps(phases))
"""


WARM_LOAD_CHILD = """
import cProfile, json, pstats, sys, time
import mechsweep
from mechsweep.grid import ParameterMatrix
from mechsweep.execution.execute import evaluate_rows
scene = mechsweep.load_scene(sys.argv[1])
P = ParameterMatrix(scene)(0, 1)
profile = cProfile.Profile()
t0 = time.perf_counter()
profile.runcall(evaluate_rows, scene, P)
total = time.perf_counter() - t0
stats = pstats.Stats(profile).stats
def cumulative(name):
    return sum(v[3] for k, v in stats.items() if k[2] == name)
print(json.dumps({"total": total, "registries": cumulative("load_additional_registries"),
                  "blas": cumulative("ensure_blas")}))
"""


INTEGRATOR_CHILD = """
import hashlib, json, time
import numpy as np
from mechsweep._jit import jit
from mechsweep.ode import dop853
@jit
def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * y[0] - p[1] * y[0] ** 3
@jit
def event(t, y, p):
    return y[0]
solve = dop853.make_event_solver(rhs, event)
@jit
def quarters(A, out, work):
    y = np.empty(2)
    p = np.array([1.0, 2.0])
    for i in range(A.size):
        y[0] = A[i]
        y[1] = 0.0
        out[i] = solve(0.0, y, p, 100.0, 1e-10, 1e-12, 0.0, 100000, work)[1]
A = np.linspace(0.05, 2.0, 20000)
out = np.empty_like(A)
work = dop853.workspace(2)
t = time.process_time()
quarters(A[:2], out[:2], work)
compile_cpu = time.process_time() - t
runs = []
for _ in range(5):  # CPU time (one thread): less blurred by other processes than wall time
    t = time.process_time()
    quarters(A, out, work)
    runs.append(time.process_time() - t)
print(json.dumps({"compile_cpu": compile_cpu, "run": min(runs), "roots": hashlib.sha256(out.tobytes()).hexdigest()[:16]}))
"""


ROUTE_CHILD = """
import json, sys, time
import mechsweep
from mechsweep.engine import kernels as mc, sampling
from mechsweep.grid import ParameterMatrix
from mechsweep.execution.execute import evaluate_rows
mode, warm = sys.argv[2], int(sys.argv[3])
mc.USE_LANES = {"lanes": True, "one": False}.get(mode, mc.USE_LANES)
if mode == "auto":
    mc.USE_LANES = None
sampling.USE_LANES = False  # the sampled-trajectory route: one trajectory at a time
scene = mechsweep.load_scene(sys.argv[1])
P = ParameterMatrix(scene)(0, scene.n_points)
c0, t0 = time.process_time(), time.perf_counter()
evaluate_rows(scene, P[:1])  # the compile (the run's warm-up point)
compile_cpu, compile_wall = time.process_time() - c0, time.perf_counter() - t0
lane_kernels = sum(isinstance(k, mc._Recorded) for k in mc._KERNELS.values())
runs = []
if warm:  # the warm kernel on every (scene.n_points / warm)-th row: (points, wall s, CPU s) per repetition
    rows = P[::max(1, scene.n_points // warm)]
    for _ in range(3):
        c0, t0 = time.process_time(), time.perf_counter()
        evaluate_rows(scene, rows)
        runs.append((rows.shape[0], time.perf_counter() - t0, time.process_time() - c0))
print(json.dumps({"compile_cpu": compile_cpu, "compile_wall": compile_wall, "kernels": len(mc._KERNELS),
                  "lane_kernels": lane_kernels, "warm": runs}))
"""
ROOT = Path(__file__).resolve().parents[1]
# the routes measured on scenes of their own: {mode: (scene, rows of the warm measurement)}
OTHER_ROUTES = {"trajectory": (ROOT / "sweeps" / "autobalancer_residual.toml", 120),
                "closed": (ROOT / "sweeps" / "fourbar_pareto.toml", 20_000)}
ROUTES = ("lanes", "one") + tuple(OTHER_ROUTES)


def route_compile(scene: Path, repeats: int, folder: Path, modes=("lanes", "one")) -> dict:
    """Cold compile of ``scene``'s kernels (its first point, as the run's warm-up) in fresh processes with
    an empty JIT cache each, by route: "lanes" (engine.kernels.USE_LANES True), "one" (one point at a time),
    "trajectory" and "closed" (OTHER_ROUTES' scenes, then their warm kernels in the same process),
    alternated ``repeats`` times: {mode: [{compile_cpu, compile_wall, kernels, lane_kernels, warm}]}."""
    out = {m: [] for m in modes}
    for i in range(repeats):
        for mode in modes:
            env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(folder / f"cache-route-{mode}-{i}"))
            path, warm = OTHER_ROUTES.get(mode, (scene, 0))
            proc = subprocess.run([sys.executable, "-c", ROUTE_CHILD, str(path), mode, str(warm)], env=env,
                                  capture_output=True, text=True)
            if proc.returncode != 0:
                raise RuntimeError(f"route compile failed:\n{proc.stderr[-2000:]}")
            out[mode].append(json.loads(proc.stdout.strip().splitlines()[-1]))
    return out


def route_speed(n: int, repeats: int) -> dict:
    """Warm points per second of the Duffing period kernel (DOP853, rtol 1e-10) on ``n`` points, the lane
    kernel and the one-point kernel alternated in this process: {mode: [(wall s, CPU s)]}."""
    from mechsweep.grid import ParameterMatrix
    from mechsweep.engine import kernels as mc
    from mechsweep.execution.execute import evaluate_rows
    from mechsweep.scene import load_scene

    scene = load_scene(duffing(n))
    P = ParameterMatrix(scene)(0, n)
    saved = mc.USE_LANES
    out = {"lanes": [], "one": []}
    try:
        for mode in out:  # compile or load both first
            mc.USE_LANES = mode == "lanes"
            evaluate_rows(scene, P[:1])
        for _ in range(repeats):
            for mode in out:
                mc.USE_LANES = mode == "lanes"
                t0, c0 = time.perf_counter(), time.process_time()
                evaluate_rows(scene, P)
                out[mode].append((time.perf_counter() - t0, time.process_time() - c0))
    finally:
        mc.USE_LANES = saved
    return out


def integrator_compile(repeats: int) -> list[dict]:
    """The one-point DOP853 event solver of a Duffing rhs (quarter periods of 20000 amplitudes) in
    fresh processes with caching off: CPU seconds of its compile and of the best of 5 runs, and a hash of
    the roots (to compare code versions bitwise: run this child with another PYTHONPATH)."""
    env = dict(os.environ, MECHSWEEP_NO_CACHE="1")
    rows = []
    for _ in range(repeats):
        proc = subprocess.run([sys.executable, "-c", INTEGRATOR_CHILD], env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"integrator compile failed:\n{proc.stderr[-2000:]}")
        rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    return rows

def compile_child(scene: Path, folder: Path, i: int = 0) -> dict:
    """COMPILE_CHILD on ``scene`` in a fresh process with an empty JIT cache of its own (repetition ``i``;
    its sources: PYTHONPATH)."""
    env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(folder / f"cache-compile-{i}"))
    proc = subprocess.run([sys.executable, "-c", COMPILE_CHILD, str(scene), str(folder / "compile.h5")], env=env,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"compile breakdown failed:\n{proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def compile_table(result: dict, top: int = 15) -> None:
    """Print COMPILE_CHILD's result: every function numba compiled, the longest first, with its own time
    (without the compiles nested in it) split into LLVM (its libraries' finalize: linking the callees'
    modules, the module passes, machine code; and the function passes) and numba's Python (typing,
    lowering, the parfor passes, wrappers, the cache), and the totals."""
    rows = result["rows"]
    print(f"  cold compile: {result['compile_time_s']:.2f} s wall (the run's compile phase), {len(rows)} functions "
          f"compiled; CPU s of the compiling thread, the longest {top}: with callees / own = LLVM finalize + LLVM "
          "function passes + numba")
    for took, own, _, name, fin, fpass in rows[:top]:
        print(f"    {took:7.2f} / {own:5.2f} = {fin:5.2f} + {fpass:5.2f} + {own - fin - fpass:5.2f}  {name}")
    own, fin, fpass = (sum(r[i] for r in rows) for i in (1, 4, 5))
    print(f"    all functions: own {own:.2f} = LLVM finalize {fin:.2f} + LLVM function passes {fpass:.2f} + numba "
          f"{own - fin - fpass:.2f}")
    phases = result.get("phases")
    if phases:
        print(f"    by phase (CPU s of the run's thread, each without the phases nested in it; the run {result['run_cpu']:.2f}):")
        for label, seconds in sorted(phases.items(), key=lambda kv: -kv[1]):
            print(f"      {seconds:6.2f}  {label}")
        print(f"      {result['run_cpu'] - sum(phases.values()):6.2f}  the run outside numba's compiles (scene, plan, "
              "binding, first cache lookups, the points)")


def breakdown(scene: Path, folder: Path, repeats: int) -> None:
    """Where the time goes: the file route's fixed costs by function (10^3 points, warm), chunk
    launches (10^4 points in 1 or 20 calls), the compile of ``scene`` by function (numba's
    compile events, in a fresh process with an empty JIT cache; times include what each calls) and by
    module (each function's own time, without the compiles nested in it), the warm compile phase,
    and a warm plot of the scene's dataset by phase (imports, opening, drawing, saving)."""
    import collections
    import functools

    import numpy as np

    import mechsweep
    from mechsweep.execution import execute, runner
    from mechsweep.store import assemble, journal, write
    from mechsweep.grid import ParameterMatrix
    from mechsweep.scene import load_scene

    spent = collections.defaultdict(float)

    def timed(owner, name, label):
        original = getattr(owner, name)

        @functools.wraps(original)
        def wrapper(*a, **k):
            t0 = time.perf_counter()
            try:
                return original(*a, **k)
            finally:
                spent[label] += time.perf_counter() - t0
        return original, wrapper

    patches = [(runner, n, n) for n in ("check_existing", "_save_chunks", "_finish", "open_dataset", "drop")]
    patches += [(execute, "warm_up", "warm_up")]
    patches += [(write, "define", "store.define"), (assemble, "define", "store.define"), (journal.Journal, "create", "Journal.create"),
                (journal.Journal, "write_chunk", "Journal.write_chunk")]
    small = load_scene(duffing(10**3))
    path = folder / "breakdown.h5"
    mechsweep.run(small, output=path, progress=False)
    originals = []
    for owner, name, label in patches:
        original, wrapper = timed(owner, name, label)
        originals.append((owner, name, original))
        setattr(owner, name, wrapper)
    try:
        t0 = time.perf_counter()
        for _ in range(repeats):
            mechsweep.run(small, output=path, progress=False)
        total = (time.perf_counter() - t0) / repeats
    finally:
        for owner, name, original in originals:
            setattr(owner, name, original)
    print(f"  file route, 10^3 points, warm: {total * 1e3:.1f} ms a run (mean of {repeats}); inside it, ms a run "
          "(nested: _finish holds store.define, _save_chunks holds Journal.write_chunk):")
    for label, seconds in sorted(spent.items(), key=lambda kv: -kv[1]):
        print(f"    {label:<22} {seconds / repeats * 1e3:8.1f}")
    big = load_scene(duffing(10**4))
    P = ParameterMatrix(big)(0, 10**4)
    execute.evaluate_rows(big, P)
    launches = {1: [], 20: []}
    for _ in range(repeats):
        for k in launches:
            t0 = time.perf_counter()
            for part in np.array_split(np.arange(10**4), k):
                execute.evaluate_rows(big, P[part[0]:part[-1] + 1])
            launches[k].append(time.perf_counter() - t0)
    print("  10^4 points in 1 kernel call: " + _spread(launches[1], "ms", 1e3) + "; in 20 calls: "
          + _spread(launches[20], "ms", 1e3))
    env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(folder / "cache-breakdown"))
    out = folder / "breakdown-quickstart.h5"
    proc = subprocess.run([sys.executable, "-c", COMPILE_CHILD, str(scene), str(out)], env=env, capture_output=True,
                          text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"compile breakdown failed:\n{proc.stderr[-2000:]}")
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    compile_table(result)
    by_module = collections.defaultdict(float)
    for _, own, module, *_ in result["rows"]:
        by_module["generated kernel module" if ".mechsweep_gen_" in "." + module else module] += own
    print("  the same compile by module (s, each function without the compiles nested in it; numba's own "
          "implementations under numba.*):")
    for module, seconds in sorted(by_module.items(), key=lambda kv: -kv[1])[:12]:
        print(f"    {seconds:7.2f}  {module}")
    proc = subprocess.run([sys.executable, "-c", WARM_LOAD_CHILD, str(scene)], env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"warm load breakdown failed:\n{proc.stderr[-2000:]}")
    w = json.loads(proc.stdout.strip().splitlines()[-1])
    print(f"  warm compile phase of {scene.name} (JIT cache filled, fresh process, first one-point call, under "
          f"cProfile): {w['total']:.2f} s, of which numba's target initialisation (load_additional_registries) "
          f"{w['registries']:.2f} s, within it numba's BLAS check importing scipy.linalg (ensure_blas) {w['blas']:.2f} s")
    proc = subprocess.run([sys.executable, "-c", PLOT_CHILD, str(out), str(folder / "breakdown-plot")], env=env,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"plot breakdown failed:\n{proc.stderr[-2000:]}")
    phases = json.loads(proc.stdout.strip().splitlines()[-1])
    print(f"  warm plot of {scene.name}'s dataset in a fresh process (as `mechsweep plot`), s: "
          + "; ".join(f"{name} {seconds:.2f}" for name, seconds in phases))
    rows = integrator_compile(repeats)
    print("  one-point DOP853 event solver of a Duffing rhs (fresh processes, no cache): compile "
          + _spread([r["compile_cpu"] for r in rows], "s CPU", fmt=".2f") + "; 20000 quarter periods "
          + _spread([r["run"] for r in rows], "ms CPU", 1e3) + f"; roots {rows[0]['roots']}")


def main(full: bool = False, repeats: int = 3, scene: str = "sweeps/quickstart.toml",
         parts: tuple[str, ...] = ("warm", "quickstart", "scaling"), against: str | None = None,
         routes: tuple[str, ...] = ROUTES) -> dict:
    """Measure and print ``parts``: "warm", "quickstart", "scaling" (the default), "breakdown"
    (where the time goes; see :func:`breakdown`), "routes" (:func:`route_compile`, :func:`route_speed`;
    ``routes``: which of ROUTES),
    "compile" (the scene's cold compile by function, ``repeats`` fresh processes: :func:`compile_table`),
    "warmstart" (the warm quickstart by process, alternated with the sources ``against`` when given:
    :func:`warm_start`)."""
    from mechsweep.bench import arguments

    repeats = arguments.count("--repeats", repeats, 3, 100)
    scene_path = Path(scene).resolve()
    if against is not None and not (Path(against) / "mechsweep" / "__init__.py").is_file():
        raise arguments.InputError(f"--against {against}: no mechsweep package in it; give the src folder of a "
                               "checkout, e.g. /path/to/checkout/src")
    if against is not None and "warmstart" not in parts:
        raise arguments.InputError("--against applies to --only warmstart only")
    if parts and set(parts) & {"quickstart", "breakdown", "routes", "compile", "warmstart"}:
        if not scene_path.is_file():
            raise arguments.InputError(f"--scene {scene} does not exist (run from the repository root, or give its path)")
        from mechsweep.scene import load_scene

        load_scene(scene_path)  # an invalid scene is refused here, not as a failed child process
    import numba

    report = {}
    print(f"benchmarks/startup.py: {numba.get_num_threads()} threads, median of {repeats} runs (min .. max)")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if "warm" in parts:
            warm = warm_small(repeats, tmp)
            report["warm"] = {f"{n}_{route}": v for (n, route), v in warm.items()}
            print(f"  warm mechsweep.run, Duffing period (DOP853, rtol {RTOL:g}):")
            for (n, route), v in warm.items():
                med = statistics.median(v) * 1e3
                target = {"memory": f"target <= {TARGET_WARM_MS[n]:g} ms: {_verdict(med, TARGET_WARM_MS[n])}",
                          "file": "no target (journal, fsyncs, HDF5 assembly)",
                          "kernel": "reference: the model's kernel on the whole grid in one call"}[route]
                where = {"memory": "in memory (output=None)", "file": "to a file", "kernel": "kernel alone"}[route]
                print(f"    {n:>6,} points {where:<24} {_spread(v, 'ms', 1e3):<34} {target}", flush=True)
        if "quickstart" in parts:
            q = quickstart(scene_path, repeats, tmp)
            report["quickstart"] = q
            print(f"  quickstart ({scene}) run + plot in fresh processes:")
            for label, target, what in (("cold", TARGET_COLD_S, "empty JIT cache"),
                                        ("warm", TARGET_WARM_S, "JIT cache filled")):
                rows = q[label]
                totals = [r[0] + r[1] for r in rows]
                med = statistics.median(totals)
                print(f"    {label} ({what:<15}) total {_spread(totals, 's', fmt='.2f'):<30} target <= {target:g} s: "
                      f"{_verdict(med, target)}", flush=True)
                print(f"      run {_spread([r[0] for r in rows], 's', fmt='.2f')}, of which compile "
                      f"{_spread([r[2] for r in rows], 's', fmt='.2f')}; plot "
                      f"{_spread([r[1] for r in rows], 's', fmt='.2f')}")
                print(f"      CPU time (user + system; less blurred by other processes): run "
                      f"{_spread([r[3] for r in rows], 's', fmt='.2f')}; plot "
                      f"{_spread([r[4] for r in rows], 's', fmt='.2f')}; total {_spread([r[3] + r[4] for r in rows], 's', fmt='.2f')}")
        if "warmstart" in parts:
            w = warm_start(scene_path, repeats, tmp, against)
            report["warmstart"] = w
            print(f"  warm quickstart ({scene}): `mechsweep run` then `mechsweep plot`, fresh processes, JIT cache "
                  "filled, wall and CPU (user + system) by process" + (", alternated with --against" if against else "")
                  + ":")
            for label, src in w["sources"].items():
                rows = w[label]
                totals = [r[0] + r[2] for r in rows]
                print(f"    {label} ({src}): total {_spread(totals, 's', fmt='.2f')}, target <= {TARGET_WARM_S:g} s: "
                      f"{_verdict(statistics.median(totals), TARGET_WARM_S)}")
                print(f"      run  wall {_spread([r[0] for r in rows], 's', fmt='.2f')}, CPU "
                      f"{_spread([r[1] for r in rows], 's', fmt='.2f')}")
                print(f"      plot wall {_spread([r[2] for r in rows], 's', fmt='.2f')}, CPU "
                      f"{_spread([r[3] for r in rows], 's', fmt='.2f')}")
                print(f"      total CPU {_spread([r[1] + r[3] for r in rows], 's', fmt='.2f')}; load average (1 min) "
                      f"before each run {min(r[4] for r in rows):.2f} .. {max(r[4] for r in rows):.2f}", flush=True)
                for kind, phases in w["phases"][label].items():
                    print(f"      {kind} by phase (one more process, wall s): " + "; ".join(
                        f"{name} {value:.3f}" if isinstance(value, float) else f"{name}: {value}"
                        for name, value in phases))
        if "scaling" in parts:
            sizes = [(10**4, "period"), (10**5, "period"), (10**6, "period")]
            if full:
                sizes += [(10**7, "period"), (10**6, "period_exact"), (10**7, "period_exact"), (10**8, "period_exact")]
            print("  cost per point of mechsweep.compute to a file (warm; wall, and CPU of this process: the "
                  "figure a shared machine disturbs least), peak RSS of the command `mechsweep run` (fresh process, "
                  "interpreter included); target: linear in points (per point flat from 10^5 on), peak within "
                  "chunk + interpreter:")
            rows = report["scaling"] = []
            for size in sizes:  # printed as measured: a failure at 10^8 keeps the smaller sizes' figures
                r = scaling([size], repeats, tmp)[0]
                rows.append(r)
                first = next(x for x in rows if x["output"] == r["output"])  # the smallest grid of this output
                base = statistics.median(first["seconds"]) / first["points"]
                per = [s / r["points"] * 1e6 for s in r["seconds"]]
                per_cpu = statistics.median(r["cpu_seconds"]) / r["points"] * 1e6
                ratio = statistics.median(r["seconds"]) / r["points"] / base
                print(f"    {r['points']:>11,} {r['output']:<13} {_spread(per, 'us/point', fmt='.3f'):<40} "
                      f"CPU {per_cpu:.3f} us/point; x{ratio:.2f} of {first['points']:,}'s per point; command peak RSS "
                      f"{r['peak_rss'] / 2**20:.0f} MiB (dataset {r['disk'] / 2**20:.1f} MiB, command "
                      f"{r['command_s']:.1f} s)", flush=True)
            _scaling_verdict(rows)
        if "routes" in parts:
            comp = route_compile(scene_path, repeats, tmp, tuple(m for m in ROUTES if m in routes))
            report["routes"] = comp
            print(f"  cold compile by route (fresh processes, empty JIT cache each, alternated; CPU and wall seconds "
                  f"of the first point; lanes, one: {scene_path.name}):")
            for mode, rows in comp.items():
                where = f" ({OTHER_ROUTES[mode][0].name})" if mode in OTHER_ROUTES else ""
                kernels = "" if where else f"; kernels {rows[0]['kernels']}, in lanes {rows[0]['lane_kernels']}"
                print(f"    {mode + where:<40} CPU {_spread([r['compile_cpu'] for r in rows], 's', fmt='.2f'):<30} "
                      f"wall {_spread([r['compile_wall'] for r in rows], 's', fmt='.2f')}{kernels}")
            for mode, rows in comp.items():
                if mode in OTHER_ROUTES:
                    runs = [run for r in rows for run in r["warm"]]
                    print(f"    {mode} warm, {runs[0][0]:,} points, 3 runs in each of those processes: "
                          f"{_spread([n / w for n, w, _ in runs], 'points/s', fmt=',.0f')}, "
                          f"{_spread([n / c for n, _, c in runs], 'points per CPU s', fmt=',.0f')}")
            if {"lanes", "one"} <= set(comp):  # their warm speed side by side, and the crossover
                n = 10**5
                speed = route_speed(n, repeats)
                report["route_speed"] = speed
                print(f"  warm kernels, Duffing period, {n:,} points, alternated in one process:")
                for mode, rows in speed.items():
                    print(f"    {mode:<5} {_spread([n / r[0] for r in rows], 'points/s', fmt=',.0f'):<44} "
                          f"{_spread([n / r[1] for r in rows], 'points per CPU s', fmt=',.0f')}")
                extra = statistics.median(r["compile_cpu"] for r in comp["lanes"]) - statistics.median(
                    r["compile_cpu"] for r in comp["one"])
                saved = (statistics.median(r[1] for r in speed["one"])
                         - statistics.median(r[1] for r in speed["lanes"])) / n
                whole = statistics.median(r["compile_cpu"] for r in comp["lanes"])
                report["crossover"] = extra / saved if saved > 0 else float("inf")
                report["crossover_whole"] = whole / saved if saved > 0 else float("inf")
                print(f"  the lanes' extra compile ({extra:.1f} CPU s) is repaid at {report['crossover']:.3g} points "
                      f"(CPU s saved per point {saved * 1e6:.3f} us): engine/kernels.py's LANES_FROM_POINTS")
                print(f"  their whole compile ({whole:.1f} CPU s, once the one-point kernel is compiled) at "
                      f"{report['crossover_whole']:.3g} points: engine/kernels.py's LANES_AFTER_POINTS")
        if "compile" in parts:
            for i in range(repeats):
                compile_table(compile_child(scene_path, tmp, i), top=60)
        if "breakdown" in parts:
            print("  where the time goes:")
            breakdown(scene_path, tmp, repeats)
    return report


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/startup.py [--full] [--repeats N] [--scene S] [--only PART ...] [--against SRC]``."""
    from benchmarks import _cli

    p = _cli.parser("startup", "fixed costs and cold start against their targets: warm runs of 10^3 and 10^4 points "
                               "(in memory and to a file), quickstart run + plot cold and warm, cost per point "
                               "10^4 .. 10^6 (--full: 10^7, 10^8 closed form) with the command's peak memory")
    p.add_argument("--full", action="store_true", help="scale to 10^7 integrated and 10^8 closed-form points (minutes)")
    p.add_argument("--repeats", type=int, default=3, help="measurements per figure, at least 3 (default 3)")
    p.add_argument("--scene", default="sweeps/quickstart.toml",
                   help="the quickstart scene (default sweeps/quickstart.toml)")
    p.add_argument("--only", choices=("warm", "quickstart", "scaling", "breakdown", "routes", "compile", "warmstart"),
                   nargs="+", default=None,
                   help="measure only these parts (default: warm quickstart scaling; breakdown: where the time "
                        "goes, by function: the file route's fixed costs, chunk launches, a cold compile; routes: "
                        "the cold compile and warm speed of the lane and one-point kernels; compile: the scene's cold "
                        "compile by function, LLVM against numba's own work, in --repeats fresh processes; "
                        "warmstart: the warm quickstart by process, run and plot)")
    p.add_argument("--against", metavar="SRC", default=None,
                   help="with --only warmstart: alternate with the sources in SRC (another checkout's src folder)")
    p.add_argument("--routes", choices=ROUTES, nargs="+", default=ROUTES,
                   help="with --only routes: these routes only (default: all; lanes and one also give their warm "
                        "speed and crossover)")

    def command(a) -> int:
        main(full=a.full, repeats=a.repeats, scene=a.scene,
             parts=tuple(a.only) if a.only else ("warm", "quickstart", "scaling"), against=a.against,
             routes=tuple(a.routes))
        return 0

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
