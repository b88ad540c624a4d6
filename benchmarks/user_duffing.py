"""`python benchmarks/user_duffing.py`: the Duffing oscillator declared as a user model (on the model
layer, as a user would write it in a file) against the built-in Duffing, on the same grid, the same
tolerances and threads, in one run.

Like with like: the user model ``DUFFING`` declares what the built-in integrates, the scaled
equation x = phi / A, tau = w t (w^2 = omega^2 + |mu| A^2): x'' = -a x - b x^3 from x = 1 at rest,
a ``prepare`` writing a, b and w per point, and the first zero of x (a quarter period, a
``FirstEvent``) turned into T = 4 tau_q / w. The built-in adds the saddle formulation near the soft
separatrix and the ill-conditioning test (irrelevant on this hard-spring grid). Both are timed on the
whole grid in memory (best of 3, compiled first); both periods are compared with the elliptic closed
form (matched accuracy: the same scaled equation at the same tolerances). ``DUFFING_UNSCALED``
integrates phi'' = -omega^2 phi - mu phi^3 from phi = A in its own units (a ``Crossing``), for
information: its tolerances mean something else (its error and steps are printed beside it, with
the point where each model's error is largest: docs/your-own-model.md, "Accuracy of your own
model", reads them).
The target: the user model reaches at least 90 % of the built-in points/s (a model of one's own
must not pay for going through the model layer).
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/NAME.py`: import from the repository's root, as -m does
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import math
import time

import numpy as np

from mechsweep.model import Crossing, FirstEvent, OdeModel, Param

TARGET = 0.90

PARAMS = (Param("omega", "ω", "rad/s", "linear natural frequency", lo=0.0, lo_open=True),
          Param("mu", "μ", "1/(rad^2 s^2)", "cubic stiffness coefficient (>0 hard, <0 soft)"),
          Param("A", "A", "rad", "amplitude, phi(0) = A, phi'(0) = 0", lo=0.0, lo_open=True))


# ---- scaled, as the built-in: p = (omega, mu, A | a, b, w)
def prepare(p, rtol):
    w2 = p[0] * p[0] + abs(p[1]) * p[2] * p[2]
    p[3] = p[0] * p[0] / w2
    p[4] = p[1] * p[2] * p[2] / w2
    p[5] = math.sqrt(w2)
    return 0  # status OK


def scaled_initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


def scaled_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[3] * y[0] - p[4] * y[0] * y[0] * y[0]


def x_event(t, y, p):
    return y[0]


def period_from_quarter(p, tau_q):
    return 4.0 * tau_q / p[5]


DUFFING = OdeModel(
    name="duffing_user",
    description="phi'' + omega^2 phi + mu phi^3 = 0 from phi = A at rest, declared on the model layer (scaled)",
    params=PARAMS,
    internal=("a", "b", "w"),
    states=("x", "dx"),
    prepare=prepare,
    rhs=scaled_rhs,
    initial=scaled_initial,
    measurements=(FirstEvent("period", x_event, t_max=200.0 * math.pi, value=period_from_quarter, symbol="T",
                             unit="s", long_name="period: 4 times the first zero of x = phi / A"),),
)
REFERENCE = "benchmarks.user_duffing:DUFFING"  # how a scene names it (the "package.module:NAME" door)


# ---- unscaled: phi(t) itself
def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -(p[0] * p[0] + p[1] * y[0] * y[0]) * y[0]


def initial(p, y0):
    y0[0] = p[2]
    y0[1] = 0.0


DUFFING_UNSCALED = OdeModel(
    name="duffing_user_unscaled",
    description="phi'' + omega^2 phi + mu phi^3 = 0 from phi = A at rest, declared on the model layer (in phi, t)",
    params=PARAMS,
    states=("phi", "dphi"),
    rhs=rhs,
    initial=initial,
    measurements=(Crossing("t_quarter", "phi", level=0.0, direction="down", n=1, t_max=100.0, unit="s",
                           long_name="time of the first zero of phi: a quarter period"),),
)
REFERENCE_UNSCALED = "benchmarks.user_duffing:DUFFING_UNSCALED"


def main(points: int = 200_000, threads: int | None = None, rtol: float | None = None,
         atol: float | None = None) -> dict:
    import numba

    from mechsweep import status as st
    from mechsweep.chunks import Chunk
    from mechsweep.grid import parameter_matrix
    from mechsweep.models import duffing
    from mechsweep.execution.execute import evaluate_chunk, threads as _threads
    from mechsweep.scene import SOLVER_LIMITS, Solver, load_scene
    from mechsweep.bench import arguments
    from mechsweep.bench.duffing import grid_scene

    points = arguments.count("points", points)
    threads = arguments.threads("threads", threads)
    rtol = arguments.tolerance("rtol", Solver.rtol if rtol is None else rtol, *SOLVER_LIMITS["rtol"])
    atol = arguments.tolerance("atol", Solver.atol if atol is None else atol, *SOLVER_LIMITS["atol"])
    builtin = grid_scene(points, rtol, atol, ("period",))
    user = {**builtin, "scene": {"name": "bench-duffing-user", "model": REFERENCE, "outputs": ["period"]}}
    unscaled = {**builtin, "scene": {"name": "bench-duffing-user-unscaled", "model": REFERENCE_UNSCALED,
                                     "outputs": ["t_quarter"]}}
    scenes = {"built-in": load_scene(builtin), "user model": load_scene(user),
              "user, unscaled": load_scene(unscaled)}
    P = parameter_matrix(scenes["built-in"], 0, scenes["built-in"].n_points)
    exact = np.array([duffing.period_closed_form.py_func(o * o, m, a) for o, m, a in P])
    rows = {}
    with _threads(threads):
        n_threads = numba.get_num_threads()
        for label, scene in scenes.items():
            t0 = time.perf_counter()
            evaluate_chunk(scene, Chunk(0, 0, 4, ()))
            rows[label] = {"compile_or_cache_load_s": time.perf_counter() - t0, "best_s": math.inf}
        for _ in range(3):  # interleaved: a disturbance of the machine hits every model alike
            for label, scene in scenes.items():
                t0 = time.perf_counter()
                cols, status, n_steps, _ = evaluate_chunk(scene, Chunk(0, 0, scene.n_points, ()))
                rows[label]["best_s"] = min(rows[label]["best_s"], time.perf_counter() - t0)
                period = cols["period"] if "period" in cols else 4.0 * cols["t_quarter"]
                error = np.abs(period - exact) / exact
                worst = int(np.nanargmax(error))
                rows[label].update(max_rel_error=float(error[worst]), max_rel_error_at=tuple(map(float, P[worst])),
                                   mean_steps=float(n_steps.mean()), ok_fraction=float((status == st.OK).mean()))
    for row in rows.values():
        row["points_per_s"] = P.shape[0] / row.pop("best_s")
    ratio = rows["user model"]["points_per_s"] / rows["built-in"]["points_per_s"]
    result = {"points": int(P.shape[0]), "threads": n_threads, "rtol": rtol, "atol": atol, **{
        f"{label}_{k}": v for label, row in rows.items() for k, v in row.items()}, "ratio": ratio,
        "ratio_unscaled": rows["user, unscaled"]["points_per_s"] / rows["built-in"]["points_per_s"]}
    print(f"benchmarks/user_duffing.py: Duffing declared as a user model ({REFERENCE}, the built-in's scaled "
          f"equation) against the built-in, DOP853, rtol={rtol:g}, atol={atol:g}, {n_threads} threads, "
          f"{P.shape[0]} points")
    for label, row in rows.items():
        omega, mu, a = row["max_rel_error_at"]
        print(f"  {label:14s}: {row['points_per_s']:>12,.0f} points/s, {row['mean_steps']:.1f} steps/point, "
              f"max relative period error {row['max_rel_error']:.2e} ({row['max_rel_error'] / rtol:.2f} rtol, at "
              f"A = {a:.3g}, mu = {mu:.3g}, epsilon = {mu * a * a / (omega * omega):.3g}), "
              f"{row['ok_fraction'] * 100:.1f}% ok (first call, compile or cache load: "
              f"{row['compile_or_cache_load_s']:.1f} s)")
    print(f"  user model / built-in: {ratio:.2f} (target: at least {TARGET:.2f}); "
          f"unscaled user model / built-in: {result['ratio_unscaled']:.2f} (for information)")
    return result


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/user_duffing.py [--points N] [--threads N] [--rtol R] [--atol A]``."""
    from benchmarks import _cli

    p = _cli.parser("user_duffing", "the Duffing oscillator declared as a user model against the built-in kernel: "
                                    "points/s and period error, side by side")
    p.add_argument("--points", type=int, default=200_000, help="grid points (default 200000)")
    p.add_argument("--threads", type=int, default=None, help="numba threads (default: all cores)")
    p.add_argument("--rtol", type=float, default=None, help="default: the solver default")
    p.add_argument("--atol", type=float, default=None, help="default: the solver default")

    def command(a) -> int:
        main(points=a.points, threads=a.threads, rtol=a.rtol, atol=a.atol)
        return 0

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
