"""`python benchmarks/linkage.py`: four-bar residual sweep, mechsweep against vectorised numpy, same run.

The computation (per design, 360 crank positions phi_i = 2 pi i / 360, constant crank speed):
closed-form four-bar kinematics (positions, velocities, accelerations), counterweights for
complete shaking-force balancing (method 1), the shaking moment M(phi) that balancing leaves,
the RMS-optimal axis of the crank counterweight from the 2x2 normal equations (method 2), the
residual dM(phi), its RMS and maximum and the efficiency R against static balancing: the outputs
M_rms_static, M_max_static, axis_x, axis_y, dM_rms_axis, dM_max_axis, R_axis of the model
``fourbar_balancing``. numpy does exactly that on [designs, 360] arrays (blocks of 64 designs, its fastest size here;
the same closed forms, formula (1) for the axis as the kernel uses at constant speed, no Python
loop over positions); the two must agree to round-off (checked).

Designs: a random family of Grashof crank-rockers (coupler, rocker and frame lengths, coupler
mass, centre and inertia varied). mechsweep runs on ``threads`` numba threads (default: all,
2 on the reference machine), numpy on one core as numpy elementwise code does.
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/NAME.py`: import from the repository's root, as -m does
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import math
import time

import numpy as np

from mechsweep import status as st
from mechsweep.models import _linkage as L
from mechsweep.models import fourbar_balancing as fb
from mechsweep.models._linkage_reference import FOURBAR_OUTPUTS as OUTPUTS, numpy_fourbar  # the numpy side
from mechsweep.execution.execute import threads as _threads


def design_family(n: int, seed: int = 0) -> np.ndarray:
    """[n, params] rows of a random family of Grashof crank-rockers (all OK)."""
    rng = np.random.default_rng(seed)
    P = np.empty((n, len(L.FOURBAR_PARAMS)))
    base = dict(a1=0.1, a2=0.35, a3=0.3, a4=0.4, branch=0.0, m1=1.0, r1=0.03, theta1=0.0, I1=1e-3,
                m2=2.0, r2=0.175, theta2=0.0, I2=0.02, m3=1.5, r3=0.15, theta3=0.0, I3=0.011,
                omega=20.0, delta=0.0, g=0.0, M_load=0.0, cw1_mr=0.0, cw1_angle=0.0, r_cw1=0.1,
                cw3_mr=0.0, cw3_angle=0.0, r_cw3=0.3)
    for k, v in base.items():
        P[:, L.FOURBAR_PARAMS.index(k)] = v
    col = L.FOURBAR_PARAMS.index
    P[:, col("a2")] = rng.uniform(0.30, 0.45, n)
    P[:, col("a3")] = rng.uniform(0.25, 0.40, n)
    P[:, col("a4")] = rng.uniform(0.35, 0.45, n)
    P[:, col("m2")] = rng.uniform(1.0, 3.0, n)
    P[:, col("r2")] = P[:, col("a2")] * rng.uniform(0.3, 0.7, n)
    P[:, col("theta2")] = rng.uniform(-0.3, 0.3, n)
    P[:, col("I2")] = P[:, col("m2")] * P[:, col("a2")] ** 2 / 12
    P[:, col("branch")] = rng.integers(0, 2, n)
    return P


def mechsweep_residuals(P: np.ndarray) -> tuple[dict, np.ndarray]:
    n = P.shape[0]
    out = {k: np.full(n, np.nan) for k in OUTPUTS}
    status = np.zeros(n, dtype=st.DTYPE)
    fb.evaluate(P, OUTPUTS, None, out, status, None, None)
    return out, status


def _best(fn, repeats):
    best, result = math.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result


def main(designs: int = 200_000, numpy_designs: int = 20_000, threads: int | None = 2,
         repeats: int = 3, seed: int = 0) -> dict:
    """Measure designs/s of mechsweep (``threads`` numba threads) and of numpy (one core) on the
    four-bar residual sweep, print them and the ratio, and return them as a dict."""
    import os

    import numba

    from mechsweep.bench import arguments

    designs = arguments.count("designs", designs)
    numpy_designs = arguments.count("numpy_designs", numpy_designs, 1, designs)
    repeats = arguments.count("repeats", repeats, 1, 1000)
    if threads is not None:
        threads = min(arguments.count("threads", threads, 1, 10**6), numba.config.NUMBA_NUM_THREADS)
    load_before = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    P = design_family(designs, seed)
    with _threads(threads):
        n_threads = numba.get_num_threads()
        t0 = time.perf_counter()
        mechsweep_residuals(P[:8])
        compile_s = time.perf_counter() - t0  # JIT compile or cache load
        ours_s, (ours, status) = _best(lambda: mechsweep_residuals(P), repeats)
        with _threads(1):
            one_s, _ = _best(lambda: mechsweep_residuals(P[:numpy_designs * 2]), repeats)
    Pn = P[:numpy_designs]
    numpy_s, ref = _best(lambda: numpy_fourbar(Pn), repeats)
    worst = 0.0
    for k in OUTPUTS:
        a, b = ours[k][:numpy_designs], ref[k]
        worst = max(worst, float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300 + np.abs(b).max() * 1e-12))))
    r = {
        "designs": designs,
        "positions_per_design": L.N_POSITIONS,
        "threads": n_threads,
        "compile_or_cache_load_s": compile_s,
        "designs_per_s": designs / ours_s,
        "designs_per_s_one_thread": 2 * numpy_designs / one_s,
        "numpy_designs": numpy_designs,
        "numpy_designs_per_s": numpy_designs / numpy_s,
        "ratio": (designs / ours_s) / (numpy_designs / numpy_s),
        "ratio_one_thread": (2 * numpy_designs / one_s) / (numpy_designs / numpy_s),
        "max_rel_difference": worst,
        "ok_fraction": float((status == st.OK).mean()),
        "load_average_before": load_before,  # other work on the machine lowers the thread speed-up
    }
    r["positions_per_s"] = r["designs_per_s"] * L.N_POSITIONS
    _print(r)
    return r


def _print(r: dict) -> None:
    print("benchmarks/linkage.py: four-bar residual sweep (kinematics, complete force balancing, "
          f"RMS-optimal counterweight axis, residual RMS/max, efficiency), {r['positions_per_design']} "
          "positions per design")
    print(f"  designs: {r['designs']:,} random Grashof crank-rockers; {r['ok_fraction'] * 100:.1f}% ok; "
          f"first call (JIT compile or cache load) {r['compile_or_cache_load_s']:.2f} s")
    print(f"  mechsweep: {r['designs_per_s']:>12,.0f} designs/s on {r['threads']} threads "
          f"({r['positions_per_s'] / 1e6:.1f} M positions/s); {r['designs_per_s_one_thread']:,.0f} on 1 thread")
    print(f"  numpy    : {r['numpy_designs_per_s']:>12,.0f} designs/s on 1 core ({r['numpy_designs']:,} designs, "
          "blocks of 64 x 360)")
    print(f"  ratio mechsweep / numpy: {r['ratio']:.1f}x ({r['ratio_one_thread']:.1f}x thread for core); "
          f"max relative difference {r['max_rel_difference']:.1e}")
    print(f"  (load average before the run: {r['load_average_before']:.2f}; other processes on the cores "
          "lower the speed-up of the threads)")


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/linkage.py [--designs N] [--numpy-designs N] [--threads N]``."""
    import numba

    from benchmarks import _cli

    p = _cli.parser("linkage", "four-bar residual sweep (360 positions/design): designs/s vs vectorised numpy")
    p.add_argument("--designs", type=int, default=200_000, help="designs for mechsweep (default 200000)")
    p.add_argument("--numpy-designs", type=int, default=20_000, help="designs for numpy (default 20000)")
    p.add_argument("--threads", type=int, default=None, help="numba threads (default: all cores)")

    def command(a) -> int:
        main(designs=a.designs, numpy_designs=a.numpy_designs,
             threads=numba.config.NUMBA_NUM_THREADS if a.threads is None else a.threads)
        return 0

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
