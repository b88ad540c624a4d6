"""`mechsweep bench duffing`: the amplitude-period sweep against scipy solve_ivp, measured now.

Both sides integrate the same scaled Duffing equation x'' = -a x - b x^3 from x = 1, x' = 0 to
the first zero of x (a quarter period) with DOP853 at the same rtol/atol, on the same grid
points; scipy runs on a random sample of them (it is ~1000x slower). Errors are against the
elliptic closed form. mechsweep runs on all numba threads, scipy on one core, as each is used.
"""
from __future__ import annotations

import math
import os
import tempfile
import time

import numpy as np

from .. import status as st
from ..grid import Chunk
from ..models import duffing
from ..runner import _threads, evaluate_chunk, run
from ..scene import Solver, load_scene


def grid_scene(points: int, rtol: float, atol: float, outputs=("period",)) -> dict:
    n_a = max(2, int(round(math.sqrt(points * 100 / 61))))
    n_mu = max(2, int(round(points / n_a)))
    return {
        "scene": {"name": "bench-duffing", "model": "duffing", "outputs": list(outputs)},
        "axes": {"A": {"start": 0.01, "stop": 1.0, "num": n_a},
                 "mu": {"start": 1e-3, "stop": 1e3, "num": n_mu, "spacing": "log"}},
        "fixed": {"omega": 1.0},
        "solver": {"method": "dop853", "rtol": rtol, "atol": atol},
    }


def _whole_grid(scene) -> Chunk:
    return Chunk(0, 0, scene.n_points, ())


def time_kernel(scene, repeats: int = 3) -> tuple[float, dict]:
    """Best of ``repeats`` wall times of evaluating the whole grid in memory (compiled already)."""
    best, result = math.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = evaluate_chunk(scene, _whole_grid(scene))
        best = min(best, time.perf_counter() - t0)
    return best, result


def scipy_periods(omega, mu, A, rtol, atol):
    """Same scaled problem, same tolerances, scipy's DOP853 with a terminal event."""
    from scipy.integrate import solve_ivp

    T = np.full(omega.size, np.nan)
    steps = np.zeros(omega.size, dtype=np.int64)
    for i in range(omega.size):
        w2 = omega[i] ** 2 + abs(mu[i]) * A[i] ** 2
        a, b = omega[i] ** 2 / w2, mu[i] * A[i] ** 2 / w2

        def rhs(t, y, a=a, b=b):
            return [y[1], -a * y[0] - b * y[0] ** 3]

        def crossing(t, y):
            return y[0]

        crossing.terminal = True
        crossing.direction = -1
        sol = solve_ivp(rhs, (0.0, 200 * math.pi), [1.0, 0.0], method="DOP853", rtol=rtol, atol=atol,
                        events=crossing)
        if sol.status == 1:
            T[i] = 4.0 * sol.t_events[0][0] / math.sqrt(w2)
        steps[i] = sol.t.size - 1
    return T, steps


def main(points: int = 200_000, scipy_points: int = 200, threads: int | None = None,
         rtol: float = Solver.rtol, atol: float = Solver.atol, seed: int = 0) -> dict:
    import numba

    from ..scene import SOLVER_LIMITS
    from . import _args

    points = _args.count("points", points)
    scipy_points = _args.count("scipy_points", scipy_points, 1, points)
    threads = _args.threads("threads", threads)
    rtol = _args.tolerance("rtol", rtol, *SOLVER_LIMITS["rtol"])
    atol = _args.tolerance("atol", atol, *SOLVER_LIMITS["atol"])
    scene = load_scene(grid_scene(points, rtol, atol))
    stored = ("period", "period_exact", "period_error", "v_max", "a_max")
    with _threads(threads):
        n_threads = numba.get_num_threads()
        t0 = time.perf_counter()
        evaluate_chunk(load_scene(grid_scene(4, rtol, atol, stored)), Chunk(0, 0, 4, ()))
        compile_s = time.perf_counter() - t0  # every kernel the timed runs use, compiled or loaded
        kernel_s, (cols, status, n_steps, _) = time_kernel(scene)
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            run(grid_scene(points, rtol, atol, stored), output=os.path.join(tmp, "bench.h5"), progress=False)
            run_s = time.perf_counter() - t0
        with _threads(1):
            one_core_s, _ = time_kernel(scene, repeats=2)

    from ..grid import parameter_matrix

    P = parameter_matrix(scene, 0, scene.n_points)
    exact = np.array([duffing.period_closed_form.py_func(o * o, m, a) for o, m, a in P])
    ours_err = np.abs(cols["period"] - exact) / exact
    rng = np.random.default_rng(seed)
    sample = np.sort(rng.choice(scene.n_points, size=min(scipy_points, scene.n_points), replace=False))
    t0 = time.perf_counter()
    T_sp, steps_sp = scipy_periods(P[sample, 0], P[sample, 1], P[sample, 2], rtol, atol)
    scipy_s = time.perf_counter() - t0
    scipy_err = np.abs(T_sp - exact[sample]) / exact[sample]

    ours_rate = scene.n_points / kernel_s
    scipy_rate = sample.size / scipy_s
    result = {
        "points": scene.n_points,
        "threads": n_threads,
        "compile_or_cache_load_s": compile_s,
        "kernel_points_per_s": ours_rate,
        "kernel_points_per_s_one_thread": scene.n_points / one_core_s,
        "run_to_hdf5_points_per_s": scene.n_points / run_s,
        "scipy_points": int(sample.size),
        "scipy_points_per_s": scipy_rate,
        "ratio_vs_scipy": ours_rate / scipy_rate,
        "ratio_vs_scipy_one_thread": (scene.n_points / one_core_s) / scipy_rate,
        "ours_max_rel_error": float(np.nanmax(ours_err)),
        "scipy_max_rel_error": float(np.nanmax(scipy_err)),
        "ours_mean_steps": float(n_steps.mean()),
        "scipy_mean_steps": float(steps_sp.mean()),
        "ok_fraction": float((status == st.OK).mean()),
    }
    _print(result, rtol, atol)
    return result


def _print(r: dict, rtol: float, atol: float) -> None:
    print(f"mechsweep bench duffing: quarter-period integration of the Duffing oscillator, DOP853, "
          f"rtol={rtol:g}, atol={atol:g}")
    print(f"  grid: A in [0.01, 1] x mu in [1e-3, 1e3] (log), omega = 1: {r['points']} points; "
          f"{r['ok_fraction'] * 100:.1f}% ok")
    print(f"  first call (JIT compile or cache load): {r['compile_or_cache_load_s']:.2f} s")
    print(f"  mechsweep kernel   : {r['kernel_points_per_s']:>12,.0f} points/s on {r['threads']} threads "
          f"({r['kernel_points_per_s_one_thread']:,.0f} on 1 thread); {r['ours_mean_steps']:.1f} steps/point")
    print(f"  mechsweep run->HDF5: {r['run_to_hdf5_points_per_s']:>12,.0f} points/s (5 outputs, file written)")
    print(f"  scipy solve_ivp    : {r['scipy_points_per_s']:>12,.1f} points/s on 1 core "
          f"({r['scipy_points']} sampled points); {r['scipy_mean_steps']:.1f} steps/point")
    print(f"  ratio mechsweep / scipy: {r['ratio_vs_scipy']:,.0f}x "
          f"({r['ratio_vs_scipy_one_thread']:,.0f}x thread for core)")
    print(f"  max relative period error vs closed form: mechsweep {r['ours_max_rel_error']:.2e}, "
          f"scipy {r['scipy_max_rel_error']:.2e}")
