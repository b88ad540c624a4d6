"""`python benchmarks/boundaries.py`: located boundaries against grid-and-contour, side by side.

The three Floquet stability boundaries of the pendulum auto-balancer along Omega (the lower one
near omega_xi, the one near omega_p, the upper one near omega_eta; omega_xi = 1, omega_eta =
1.5 rad/s, zeta = 0.02, A0 = m a, h = m a^2 x 1 rad/s, as tests/models/test_autobalancer.py) for
``values`` mass ratios 2 m / M from 0.0005 to 0.35 (log spaced; m = 0.5 kg fixed, M varies),
through the model's scene interface only (mechsweep.boundaries on ModelSpec.evaluate):

1. located: a coarse Omega grid (``grid`` values in [0.6, 4] rad/s, default 100) brackets every crossing of
   floquet_max = 1, refined to ``rtol`` in Omega (mechsweep.boundaries.locate); wall time of
   grid and refinement together, evaluations per located point;
2. grid and contour: floquet_max on finer Omega grids (``contour`` values each), crossings by
   linear interpolation between neighbouring grid values (what a contour line does); their error
   against the located boundaries measured on the mass ratios where both find as many crossings
   (where the window omega_xi < Omega < omega_p closes, a grid misses its two boundaries once
   they are closer than its spacing: those mass ratios are counted, not compared), its order p fitted (error ~ h^p) between the two
   finest grids, and the grid that ``rtol`` would need (and its time, from the measured time
   per point) extrapolated from it.

3. continuation: the boundaries located at the lightest pendulums followed in (Omega, M) (log M)
   by mechsweep.boundaries.continue_boundary, through folds, to where they end: two that end at
   the same point meet there (the window omega_xi < Omega < omega_p closes).

Both routes run in this process on the same threads, one after the other; the JIT compilation is
done before any timing.
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/NAME.py`: import from the repository's root, as -m does
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import math
import time

import numpy as np

from mechsweep import boundaries as bd
from mechsweep.boundaries import search
from mechsweep.scene import load_scene

OMEGA = (0.6, 4.0)
RATIO = (0.0005, 0.35)
M_PENDULUM = 0.5  # kg: 2 m = 1, so 2 m / M = 1 / M
# floquet_max's accuracy is taken as 100 solver rtol (boundaries.criterion_accuracy): 1e-10 here, so
# that the criterion does not limit the located boundaries above 1e-8 (the default rtol 5e-11 gives
# it 5e-9, which leaves many boundaries' brackets far wider than 1e-8)
SOLVER_RTOL, SOLVER_ATOL = 1e-12, 1e-14


def scene_dict(values: int, grid: int, rtol: float) -> dict:
    return {
        "scene": {"name": "bench-boundaries", "model": "autobalancer", "outputs": ["floquet_max"]},
        "axes": {"Omega": {"start": OMEGA[0], "stop": OMEGA[1], "num": grid},
                 "M": {"start": 2 * M_PENDULUM / RATIO[1], "stop": 2 * M_PENDULUM / RATIO[0], "num": values,
                       "spacing": "log"}},
        "fixed": {"m": M_PENDULUM, "a": 0.1, "I_B": M_PENDULUM * 0.01, "A0": M_PENDULUM * 0.1,
                  "h": M_PENDULUM * 0.01, "omega_xi": 1.0, "omega_eta": 1.5, "zeta_xi": 0.02, "zeta_eta": 0.02},
        "solver": {"rtol": SOLVER_RTOL, "atol": SOLVER_ATOL},
        "boundaries": {"along": "Omega", "criterion": "floquet_max", "level": 1.0, "rtol": rtol},
    }


def contour_crossings(x: np.ndarray, g: np.ndarray) -> list[np.ndarray]:
    """Per line (row of g), the crossings of 0 by linear interpolation between grid values."""
    out = []
    for row in g:
        i = np.nonzero((np.sign(row[:-1]) * np.sign(row[1:]) < 0))[0]
        out.append(x[i] - row[i] * (x[i + 1] - x[i]) / (row[i + 1] - row[i]))
    return out


def contour_error(located: np.ndarray, crossings: list[np.ndarray]) -> tuple[float, float, int, int, int]:
    """Compares, line by line, the contour crossings with the located boundaries. Returns the largest
    and the median relative error over the lines where both find the same number of crossings, the number of lines
    where they do not (a narrow window the contour grid or the bracketing grid cannot resolve), and
    the crossings the contour has more and fewer than the located boundaries on those lines."""
    errs, differ, more, fewer = [], 0, 0, 0
    for loc, cr in zip(located, crossings):
        loc = np.sort(loc[np.isfinite(loc)])
        if loc.size != cr.size:
            differ += 1
            more += max(0, cr.size - loc.size)
            fewer += max(0, loc.size - cr.size)
        elif loc.size:
            errs.extend(np.abs(np.sort(cr) - loc) / np.abs(loc))
    errs = np.array(errs) if errs else np.zeros(1)
    return float(errs.max()), float(np.median(errs)), differ, more, fewer


def _rows_at(rows: np.ndarray, ratios, m_col: int) -> np.ndarray:
    """Parameter rows like ``rows[0]`` at the mass ratios 2 m / M = ``ratios`` (M in column m_col)."""
    out = np.repeat(rows[:1], len(ratios), axis=0)
    out[:, m_col] = 2 * M_PENDULUM / np.asarray(ratios)
    return out


def main(values: int = 200, grid: int = 100, contour=(100, 200, 400), rtol: float = 1e-8,
         threads: int | None = None) -> dict:
    from mechsweep.execution.execute import threads as _threads

    scene = load_scene(scene_dict(values, grid, rtol))
    crit = bd.criterion_of(scene)
    rows, col, _ = bd.base_rows(scene, "Omega")
    ratio = 2 * M_PENDULUM / rows[:, [p.name for p in scene.model.params].index("M")]
    report = {}
    with _threads(threads):
        import numba

        n_threads = numba.get_num_threads()
        ev = search.Evaluator(scene, crit, rows, col)
        ev(np.zeros(2, dtype=np.int64), np.array([1.0, 1.3]))  # compile before timing
        t0 = time.perf_counter()
        res = bd.locate(scene, crit, rows, col, np.linspace(*OMEGA, grid), rtol=rtol)
        t_loc = time.perf_counter() - t0
        found = (res.bound == bd.PARAMETER) | (res.bound == bd.CRITERION)
        n_found = int(found.sum())
        per_line = found.sum(axis=1)
        evals = res.evaluations[found]
        width_rel = float(np.max(res.width[found] / np.abs(res.location[found])))
        report.update(located_s=t_loc, located=n_found, grid_points=values * grid, refine_points=res.points,
                      refine_calls=res.calls, evaluations_mean=float(evals.mean()), evaluations_max=int(evals.max()),
                      width_rel_max=width_rel, per_line=per_line,
                      bounds={bd.BOUND_MEANINGS[c]: int((res.bound == c).sum()) for c in (bd.PARAMETER, bd.CRITERION)})
        print(f"benchmarks/boundaries.py: auto-balancer floquet_max = 1 along Omega in [{OMEGA[0]}, {OMEGA[1]}] rad/s, "
              f"{values} mass ratios 2 m / M in [{RATIO[0]}, {RATIO[1]}] (log), {n_threads} thread(s), rtol {rtol:g}")
        print(f"  located: grid {grid} x {values} = {values * grid:,} points + refinement {res.points:,} points in "
              f"{res.calls} calls: {t_loc:.2f} s; {n_found} boundaries ({{k: n}} = "
              f"{ {int(k): int(v) for k, v in zip(*np.unique(per_line, return_counts=True))} } mass ratios with k "
              f"boundaries: the window "
              f"omega_xi < Omega < omega_p closes for heavy pendulums); "
              f"{evals.mean():.1f} evaluations per located point (max {evals.max()}); "
              f"bracket width <= {width_rel:.2g} |Omega|; bounds {report['bounds']}")
        located = np.where(found, res.location, np.nan)
        errors, worst, times = [], [], []
        for n in contour:
            x = np.linspace(*OMEGA, n)
            line = np.repeat(np.arange(values), n)
            t0 = time.perf_counter()
            g, _, _ = ev(line, np.tile(x, values))
            t = time.perf_counter() - t0
            err, med, differ, more, fewer = contour_error(located, contour_crossings(x, g.reshape(values, n)))
            errors.append(med)
            worst.append(err)
            times.append(t)
            print(f"  grid and contour: {n} x {values} = {n * values:,} points in {t:.2f} s "
                  f"({n * values / t:,.0f} points/s): error {med:.2e} (median), {err:.2e} (largest) relative where both find as many "
                  f"crossings; they differ on {differ} mass ratios (the contour has {more} more, {fewer} fewer: "
                  "a closing window one of the grids does not resolve)")
        h = (OMEGA[1] - OMEGA[0]) / (np.array(contour) - 1)
        p = math.log(errors[-2] / errors[-1]) / math.log(h[-2] / h[-1]) if errors[-1] > 0 and errors[-2] > 0 else 2.0
        target = max(rtol, width_rel)  # the precision the located boundaries reached
        # the grid on which the MEDIAN error reaches the target: a lower bound for the largest error
        need = (contour[-1] - 1) * (errors[-1] / target) ** (1 / p) + 1
        t_need = times[-1] * need / contour[-1]
        report.update(target=target, contour=list(contour), contour_s=times, contour_median_error=errors,
                      contour_max_error=worst, order=p, needed_grid=int(math.ceil(need)), needed_s=t_need)
        print(f"  the median contour error falls like h^{p:.2f}: for it to reach {target:.2g} a grid of at least "
              f"{int(math.ceil(need)):,} Omega values per mass ratio ({int(math.ceil(need)) * values:,} points) would "
              f"be needed, about {t_need:,.0f} s at the measured rate (the largest error, near the closing window, "
              f"falls more slowly); located: {t_loc:.2f} s")
        report["ratio"] = ratio
        # the boundaries' movement from the damped first approximation's roots P(Omega) = 0
        from scipy.optimize import brentq

        from tests.reference import autobalancer_kernels as ab  # the reference formula (numpy, vectorised)

        roots = np.array([brentq(lambda v: ab.receptance_sum(v, 1.0, 1.0, 2.25, 0.04, 0.06), lo_, hi_, xtol=1e-14)
                          for lo_, hi_ in ((0.9, 1.1), (1.2, 1.35), (1.4, 1.55))])
        probe = bd.locate(scene, crit, _rows_at(rows, [0.02, 0.0005], scene.model.param_names().index("M")), col,
                          np.linspace(*OMEGA, grid), rtol=rtol)
        report["movement"] = {}
        for k, r in enumerate((0.02, 0.0005)):
            if np.isfinite(probe.location[k]).sum() == 3:
                move = (probe.location[k] - roots) / roots
                report["movement"][r] = move
                print(f"  at 2 m / M = {r}: boundaries {np.array2string(probe.location[k], precision=8)} rad/s, moved "
                      f"{', '.join(f'{100 * v:.4f} %' for v in move)} from the first approximation's roots "
                      f"{np.array2string(roots, precision=8)} (brackets <= "
                      f"{np.nanmax(probe.width[k] / probe.location[k]):.2g})")
        # 3. continuation: the three boundaries followed in (Omega, M) from the lightest pendulums
        t0 = time.perf_counter()
        light = bd.locate(scene, crit, rows[-1:], col, np.linspace(*OMEGA, grid), rtol=1e-10)
        curves = [bd.continue_boundary(scene, crit, rows[-1], "Omega", "M", (x, 2 * M_PENDULUM / RATIO[0]))
                  for x in light.location[0] if np.isfinite(x)]
        t_cont = time.perf_counter() - t0
        report.update(continuation_s=t_cont, curves=curves)
        print(f"  continuation from 2 m / M = {RATIO[0]} (rtol 1e-10 start, Newton to 1e-10 of the chart): "
              f"{t_cont:.2f} s, {sum(c.evaluations for c in curves):,} points in {sum(c.calls for c in curves)} calls")
        for c in curves:
            end = c.points[-1]
            folds = "; ".join(f"turns back in {f[2]} at Omega = {f[0]:.6f}, 2 m / M = {2 * M_PENDULUM / f[1]:.6f}"
                              for f in c.folds) or "no fold"
            print(f"    from Omega = {c.points[0][0]:.6f}: {len(c.points)} points, {folds}; stops ({c.stop}) at "
                  f"Omega = {end[0]:.6f}, 2 m / M = {2 * M_PENDULUM / end[1]:.6f}")
        ends = [c.points[-1] for c in curves if c.stop == "step_too_small"]
        for i in range(len(ends)):
            for j in range(i + 1, len(ends)):
                if np.all(np.abs(ends[i] - ends[j]) <= 1e-4 * np.abs(ends[i])):
                    print(f"    boundaries {i} and {j} end at the same point: they meet at Omega = {ends[i][0]:.6f}, "
                          f"2 m / M = {2 * M_PENDULUM / ends[i][1]:.6f} (a corner of floquet_max, where the largest "
                          "multiplier changes: the window closes there)")
    return report


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/boundaries.py [--values N] [--grid N] [--contour N ...] [--rtol R] [--threads N]``."""
    from benchmarks import _cli
    from mechsweep.bench import arguments
    from mechsweep.errors import InputError

    p = _cli.parser("boundaries", "auto-balancer stability boundaries against 2 m / M: located vs grid-and-contour "
                                  "at the same precision")
    p.add_argument("--values", type=int, default=200, help="mass ratios 2 m / M in [0.0005, 0.35] (default 200)")
    p.add_argument("--grid", type=int, default=100, help="Omega values of the bracketing grid (default 100)")
    p.add_argument("--contour", type=int, nargs="+", default=[100, 200, 400], metavar="N",
                   help="Omega values of the contour grids (default 100 200 400)")
    p.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance in Omega (default 1e-8)")
    p.add_argument("--threads", type=int, default=None, help="numba threads (default: all cores)")

    def command(a) -> int:
        contour = [arguments.count("--contour", n, 3, 10**6) for n in a.contour]
        if len(contour) < 2:
            raise InputError("--contour needs at least two grid sizes (the error's order is fitted between the last two)")
        main(values=arguments.count("--values", a.values, 1, 10**5), grid=arguments.count("--grid", a.grid, 3, 10**6),
             contour=tuple(contour), rtol=arguments.tolerance("--rtol", a.rtol, 1e-15, 1e-2),
             threads=arguments.threads("--threads", a.threads))
        return 0

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
