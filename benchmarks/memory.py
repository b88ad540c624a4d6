"""`python benchmarks/memory.py`: peak resident memory of a run against the size of its dataset.

Each case runs in a fresh process (JIT cache loaded, not compiled: a warm-up process runs first)
and reports that process's peak resident set size (``ru_maxrss``, which includes the interpreter,
numba, numpy, xarray and h5py themselves) next to the dataset's size on disk. Two paths:

- ``run``: ``mechsweep.run(scene, load=False)`` in the process (it opens the result lazily, which
  reads the axes' coordinates: 8 bytes per axis value, about twice that with xarray's index);
- ``command``: the command ``mechsweep run SCENE -o PATH`` (``python -m mechsweep.cli``), started
  from a wrapper process that reads the command's peak with ``getrusage(RUSAGE_CHILDREN)`` (its
  only child). The command prints the status counts without opening the dataset.

The memory target is peak RSS <= dataset size + 300 MiB; the stronger property shown is
that the peak does not grow with the grid, whatever its shape (one long axis, several short ones):
the column "over 10^3" is the peak minus that of the same path on a 1,000-point grid.

Cases: Duffing closed-form periods (algebraic, ``period_exact``) and integrated periods
(``period``, DOP853), grids given by their shape (axes A, mu, omega in that order of use).
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/NAME.py`: import from the repository's root, as -m does
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import json
import math
import subprocess
import tempfile
import textwrap
import time

MiB = 2**20
ALLOWANCE = 300 * MiB

RUN_CHILD = textwrap.dedent("""
    import json, resource, sys, time
    import mechsweep
    scene, path = json.loads(sys.argv[1]), sys.argv[2]
    t0 = time.perf_counter()
    ds = mechsweep.run(scene, output=path, progress=False, load=False)
    seconds = time.perf_counter() - t0
    ds.close()
    print(json.dumps({"peak_rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
                      "seconds": seconds}))
""")

# The wrapper's only child is the command, so RUSAGE_CHILDREN is the command's own peak.
COMMAND_WRAPPER = textwrap.dedent("""
    import json, resource, subprocess, sys, time
    t0 = time.perf_counter()
    proc = subprocess.run(sys.argv[1:], capture_output=True, text=True)
    print(json.dumps({"peak_rss": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024,
                      "seconds": time.perf_counter() - t0, "returncode": proc.returncode,
                      "stdout": proc.stdout[-1000:], "stderr": proc.stderr[-2000:]}))
""")

# (path, output, shape)
FULL = (
    ("run", "period_exact", (10**3,)),
    ("run", "period_exact", (10**3, 10**3)),
    ("run", "period_exact", (10**4, 10**3)),
    ("run", "period_exact", (10**7,)),
    ("run", "period_exact", (100, 10**3, 100)),
    ("run", "period_exact", (10**4, 10**4)),
    ("run", "period", (10**3,)),
    ("run", "period", (10**3, 10**3)),
    ("run", "period", (10**4, 10**3)),
    ("command", "period_exact", (10**3,)),
    ("command", "period_exact", (10**4, 10**3)),
    ("command", "period_exact", (10**7,)),
)
QUICK = (
    ("run", "period_exact", (10**3,)),
    ("run", "period_exact", (10**3, 10**2)),
    ("run", "period_exact", (10**5,)),
    ("run", "period", (10**3,)),
    ("run", "period", (10**2, 10**2)),
    ("command", "period_exact", (10**3,)),
    ("command", "period_exact", (10**3, 10**2)),
    ("command", "period_exact", (10**5,)),
)


def scene(shape, output: str) -> dict:
    """A Duffing scene whose grid has ``shape``: axes A (linear), mu (log), omega (linear), in
    that order, as many as ``shape`` has entries (one axis: mu alone)."""
    shape = tuple(int(n) for n in shape)
    ranges = {"A": {"start": 0.01, "stop": 1.0}, "mu": {"start": 1e-3, "stop": 1e3, "spacing": "log"},
              "omega": {"start": 0.5, "stop": 2.0}}
    names = ("mu",) if len(shape) == 1 else ("A", "mu", "omega")[: len(shape)]
    axes = {name: {**ranges[name], "num": n} for name, n in zip(names, shape)}
    fixed = {k: v for k, v in {"A": 0.5, "omega": 1.0}.items() if k not in axes}
    return {
        "scene": {"name": "bench-memory", "model": "duffing", "outputs": [output]},
        "axes": axes,
        "fixed": fixed,
        "solver": {"method": "dop853", "rtol": 5e-11, "atol": 1e-12},
    }


def _case(how: str, output: str, shape: tuple, folder: Path) -> dict:
    name = f"{how}_{output}_{'x'.join(map(str, shape))}"
    path = folder / f"{name}.h5"
    t0 = time.perf_counter()
    if how == "run":
        argv = [sys.executable, "-c", RUN_CHILD, json.dumps(scene(shape, output)), str(path)]
    else:
        from mechsweep.scene import to_toml

        toml = folder / f"{name}.toml"
        toml.write_text(to_toml(scene(shape, output)))
        argv = [sys.executable, "-c", COMMAND_WRAPPER, sys.executable, "-m", "mechsweep.cli", "run", str(toml),
                "-o", str(path), "--no-progress"]
    proc = subprocess.run(argv, capture_output=True, text=True)
    result = json.loads(proc.stdout.strip().splitlines()[-1]) if proc.returncode == 0 and proc.stdout.strip() else {}
    if proc.returncode != 0 or result.get("returncode", 0) != 0:
        raise RuntimeError(f"memory case {name} failed:\n{(proc.stderr or result.get('stderr', ''))[-2000:]}")
    result.update(how=how, output=output, shape=shape, points=math.prod(shape), disk=path.stat().st_size,
                  process_s=time.perf_counter() - t0)
    path.unlink()
    return result


def main(quick: bool = False, folder: str | None = None) -> list[dict]:
    from mechsweep.bench import arguments

    if folder is not None:
        path = arguments.folder("dir", folder)
        if not path.is_dir():
            raise arguments.InputError(f"dir = {str(folder)!r} does not exist; create it first")
    cases = QUICK if quick else FULL
    rows = []
    base = {}
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        tmp = Path(tmp)
        _case("run", "period", (1000,), tmp)  # warm-up: compile or load the kernels once
        _case("run", "period_exact", (1000,), tmp)
        print(f"benchmarks/memory.py: peak resident memory of a run in a fresh process (interpreter and "
              f"libraries included) against the dataset on disk; criterion: peak <= disk + "
              f"{ALLOWANCE // MiB} MiB; 'over 10^3': peak minus that of the same path at 1,000 points")
        print(f"  {'path':<8} {'output':<13} {'grid':>15} {'points':>12} {'run s':>7} {'disk MiB':>9} "
              f"{'peak RSS MiB':>13} {'over 10^3':>10}  criterion")
        for how, output, shape in cases:
            r = _case(how, output, shape, tmp)
            if r["points"] == 1000:
                base.setdefault((how, output), r["peak_rss"])
            r["over_base"] = r["peak_rss"] - base.get((how, output), r["peak_rss"])
            r["ok"] = r["peak_rss"] <= r["disk"] + ALLOWANCE
            rows.append(r)
            grid = " x ".join(_power(n) for n in shape)
            print(f"  {how:<8} {output:<13} {grid:>15} {r['points']:>12,} {r['seconds']:7.1f} "
                  f"{r['disk'] / MiB:9.1f} {r['peak_rss'] / MiB:13.1f} {r['over_base'] / MiB:10.1f}  "
                  f"{'met' if r['ok'] else 'NOT met'}", flush=True)
    return rows


def _power(n: int) -> str:
    k = round(math.log10(n)) if n > 0 else 0
    return f"10^{k}" if 10**k == n and k > 1 else str(n)


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/memory.py [--quick] [--dir DIR]``: exit 1 when a case misses its target."""
    from benchmarks import _cli

    p = _cli.parser("memory", "peak resident memory of runs up to 10^8 points (one long axis, several short ones; "
                              "mechsweep.run and the `mechsweep run` command) against their dataset size")
    p.add_argument("--quick", action="store_true", help="small grids only (10^4 ... 10^6 points)")
    p.add_argument("--dir", default=None, help="folder for the temporary datasets (default: the system's temp)")

    def command(a) -> int:
        rows = main(quick=a.quick, folder=a.dir)
        return 0 if all(r["ok"] for r in rows) else 1

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
