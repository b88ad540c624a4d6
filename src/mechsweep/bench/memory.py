"""`mechsweep bench memory`: peak resident memory of a run against the size of its dataset.

Each case runs `mechsweep.run` in a fresh process (JIT cache loaded, not compiled: a warm-up
process runs first) and reports that process's peak resident set size (``ru_maxrss``, which
includes the interpreter, numba, numpy, xarray and h5py themselves) next to the dataset's size
on disk. The criterion of issue 6 is peak RSS <= dataset size + 300 MiB; the stronger property
shown is that the peak does not grow with the grid (memory is bounded by the chunk size).

Cases: Duffing closed-form periods (algebraic, ``period_exact``) and integrated periods
(``period``, DOP853) over grids of growing size. The returned dataset is not loaded (``load=False``):
what is measured is the run.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

MiB = 2**20
ALLOWANCE = 300 * MiB

CHILD = textwrap.dedent("""
    import json, resource, sys, time
    import mechsweep
    from mechsweep.bench.duffing import grid_scene
    points, output, path = int(sys.argv[1]), sys.argv[2], sys.argv[3]
    scene = grid_scene(points, 5e-11, 1e-12, outputs=(output,))
    t0 = time.perf_counter()
    ds = mechsweep.run(scene, output=path, progress=False, load=False)
    seconds = time.perf_counter() - t0
    shape = dict(ds.sizes)
    ds.close()
    print(json.dumps({"peak_rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
                      "seconds": seconds, "shape": shape}))
""")

FULL = (("period_exact", (10**6, 10**7, 10**8)), ("period", (10**5, 10**6, 10**7)))
QUICK = (("period_exact", (10**5, 10**6)), ("period", (10**4, 10**5)))


def _case(output: str, points: int, folder: Path) -> dict:
    path = folder / f"{output}_{points}.h5"
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", CHILD, str(points), output, str(path)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"memory case {output} x {points} failed:\n{proc.stderr[-2000:]}")
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    result.update(output=output, points=points, disk=path.stat().st_size,
                  process_s=time.perf_counter() - t0)
    path.unlink()
    return result


def main(quick: bool = False, folder: str | None = None) -> list[dict]:
    from . import _args

    if folder is not None:
        path = _args.folder("dir", folder)
        if not path.is_dir():
            raise _args.InputError(f"dir = {str(folder)!r} does not exist; create it first")
    cases = QUICK if quick else FULL
    rows = []
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        tmp = Path(tmp)
        _case("period", 1000, tmp)  # warm-up: compile or load the kernels once
        print(f"mechsweep bench memory: peak resident memory of `mechsweep.run` in a fresh process "
              f"(interpreter and libraries included) against the dataset on disk; criterion: peak <= disk + "
              f"{ALLOWANCE // MiB} MiB")
        print(f"  {'output':<13} {'points':>12} {'run s':>8} {'disk MiB':>10} {'peak RSS MiB':>13} "
              f"{'RSS - disk MiB':>15}  criterion")
        for output, sizes in cases:
            for points in sizes:
                r = _case(output, points, tmp)
                r["ok"] = r["peak_rss"] <= r["disk"] + ALLOWANCE
                rows.append(r)
                print(f"  {output:<13} {points:>12,} {r['seconds']:8.1f} {r['disk'] / MiB:10.1f} "
                      f"{r['peak_rss'] / MiB:13.1f} {(r['peak_rss'] - r['disk']) / MiB:15.1f}  "
                      f"{'met' if r['ok'] else 'NOT met'}", flush=True)
    return rows
