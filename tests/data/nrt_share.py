"""How much of a kernel's time goes to numba's reference counting (NRT_incref / NRT_decref, atomic
``lock incq/decq``): ``python tests/data/nrt_share.py SCENE|duffing [key=value ...]`` (Linux, needs
``perf``). Run it with ``MECHSWEEP_NO_CACHE=1``: functions loaded from numba's disk cache have no
names to map (their samples then show as bare addresses).

The scene's whole grid is computed once (compiled, and every route it takes warmed up: lanes, the
one-trajectory kernel), then ``perf record`` is attached to this process while the grid is computed
again and again for ``secs`` seconds; a perf map (/tmp/perf-PID.map) names the compiled functions and
numba's NRT functions. Printed: the kernel's rate, the share of the samples in JIT code and libm
(the kernels) and, of those, in NRT_incref/NRT_decref, and the hottest functions.

Keys: ``lanes=0|1`` (model/compile.USE_LANES: the one-point kernel or the lanes), ``tlanes=0|1``
(model/trajectory.USE_LANES), ``threads=N`` (default 1), ``secs=S`` (default 8), ``shrink=AXIS:N,...``
(fewer values on an axis), ``outputs=a,b`` (other outputs), ``points=N`` (the ``duffing`` grid of
``mechsweep bench duffing``, rtol 1e-10, atol 1e-12). SCENE ``meissner``: the Meissner equation with its
switch times declared (tests/data/nonsmooth/meissner.py), Floquet, 1,600 points. Numbers from it: docs/performance.md,
"Reference counting in the kernels".
"""
import gc
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numba
from numba.core.registry import CPUDispatcher
from numba.core.runtime import nrt

from mechsweep.bench.duffing import grid_scene
from mechsweep.chunks import Chunk
from mechsweep.engine import kernels as model_compile
from mechsweep.engine import sampling as trajectory
from mechsweep.execution.execute import evaluate_chunk
from mechsweep.scene import load_scene


def _whole_grid(scene) -> Chunk:
    return Chunk(0, 0, scene.n_points, ())


MEISSNER = {  # switches (model/switches.py): the Meissner equation with its switch times declared, Floquet
    "scene": {"name": "nrt-meissner", "model": str(Path(__file__).resolve().parent / "nonsmooth" / "meissner.py")
              + ":MEISSNER_SW", "outputs": ["mu"]},
    "axes": {"delta": {"start": 0.1, "stop": 3.0, "num": 40}, "eps": {"start": 0.0, "stop": 2.0, "num": 40}},
    "fixed": {"c": 0.05},
    "solver": {"rtol": 1e-8, "atol": 1e-10},
}


def scene_dict(source: str, args: dict) -> dict:
    if source == "duffing":
        return grid_scene(int(args.get("points", 100_000)), 1e-10, 1e-12)
    if source == "meissner":
        return MEISSNER
    d = tomllib.loads(open(source).read())
    d.pop("boundaries", None)
    d.pop("storage", None)
    for kv in filter(None, args.get("shrink", "").split(",")):
        axis, n = kv.split(":")
        ax = d["axes"][axis]
        if isinstance(ax, dict):
            ax["num"] = int(n)
        else:
            d["axes"][axis] = ax[:int(n)]
    if "outputs" in args:
        d["scene"]["outputs"] = args["outputs"].split(",")
    return d


def perf_map() -> dict[int, str]:
    """Address -> name of every compiled function in this process, and of numba's NRT functions."""
    syms = {}
    libraries = [cres.library for o in gc.get_objects() if isinstance(o, CPUDispatcher) for cres in o.overloads.values()]
    libraries.append(nrt.rtsys._library)
    for lib in libraries:
        try:
            names = [f.name for f in lib._final_module.functions if not f.is_declaration]
        except Exception:
            continue
        for name in names:
            try:
                address = lib.get_pointer_to_function(name)
            except Exception:
                continue
            if address:
                syms[address] = ("NRT::" if lib is nrt.rtsys._library else "") + name
    addresses = sorted(syms)
    with open(f"/tmp/perf-{os.getpid()}.map", "w") as f:
        for i, a in enumerate(addresses):
            size = min((addresses[i + 1] - a) if i + 1 < len(addresses) else 65536, 1 << 20)
            f.write(f"{a:x} {size:x} {syms[a][:150]}\n")
    return syms


def shares(data: str) -> tuple[float, float, list]:
    """(% of samples in JIT code and libm, % of those in NRT_incref/decref, hottest (%, name))."""
    report = subprocess.run(["perf", "report", "-i", data, "--no-children", "--sort", "dso,sym"],
                            capture_output=True, text=True).stdout
    kernel = refcount = 0.0
    rows = []
    for line in report.splitlines():
        m = re.match(r"\s*([\d.]+)%\s+(\S+(?: tid \d+)?)\s+\[.\]\s+(.*)", line)
        if not m:
            continue
        share, dso, sym = float(m.group(1)), m.group(2), m.group(3)
        if dso.startswith("[JIT]") or "libm" in dso:
            kernel += share
            rows.append((share, sym))
        if sym.startswith("NRT::NRT_incref") or sym.startswith("NRT::NRT_decref"):
            refcount += share
    return kernel, 100.0 * refcount / max(kernel, 1e-300), rows


def main(argv):
    source, args = argv[0], dict(a.split("=", 1) for a in argv[1:])
    model_compile.USE_LANES = {"0": False, "1": True}.get(args.get("lanes", ""))
    trajectory.USE_LANES = {"0": False, "1": True}.get(args.get("tlanes", ""))
    numba.set_num_threads(int(args.get("threads", "1")))
    d = scene_dict(source, args)
    if source not in ("duffing", "meissner"):
        os.chdir(os.path.dirname(os.path.abspath(source)))
    scene = load_scene(d)
    evaluate_chunk(scene, _whole_grid(scene))  # compiles, and warms every route the grid takes
    perf_map()
    data = os.path.join(tempfile.mkdtemp(prefix="nrt-share-"), "perf.data")
    rec = subprocess.Popen(["perf", "record", "-q", "-F", "2000", "-o", data, "-p", str(os.getpid())])
    time.sleep(0.5)
    best, end, rounds = float("inf"), time.perf_counter() + float(args.get("secs", "8")), 0
    while rounds < 2 or time.perf_counter() < end:
        t = time.perf_counter()
        evaluate_chunk(scene, _whole_grid(scene))
        best = min(best, time.perf_counter() - t)
        rounds += 1
    rec.send_signal(signal.SIGINT)
    rec.wait()
    kernel, refcount, rows = shares(data)
    print(f"{scene.n_points} points, {numba.get_num_threads()} thread(s): best {scene.n_points / best:,.0f} points/s "
          f"({rounds} rounds)")
    print(f"samples in JIT code and libm: {kernel:.1f} %; of those in NRT_incref/decref: {refcount:.2f} %")
    for share, sym in rows[:12]:
        print(f"  {share:6.2f} % {sym[:120]}")


if __name__ == "__main__":
    main(sys.argv[1:])
