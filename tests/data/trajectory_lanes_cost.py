"""What the sampled-trajectory lanes cost and gain (engine/sampling.py, USE_LANES / LANES_FROM_POINTS):
``python tests/data/trajectory_lanes_cost.py [cold|speed|both] [points] [model] [--rounds=N]``.

cold: each route (lanes, one trajectory at a time) in a new process with an empty numba cache
folder (MECHSWEEP_CACHE_DIR in a temporary folder): the CPU and wall time of a first evaluation of
4 points (short horizon: the compile dominates); their difference is the lanes' extra cold compile.
speed: warm caches (the default cache folder), ``points`` points (default 256), alternating the
routes in one process: points per second and CPU seconds per point (every thread's, process time).
both: cold then speed, and the crossover, the run size from which the lanes' extra cold compile
(CPU s) is repaid by their CPU saved per point (the median of the rounds: what LANES_FROM_POINTS
is set from). ``--rounds=N``: N rounds of each (default 1 cold, 3 speed).

model: residual (sweeps/autobalancer_residual.toml: its outputs, solver settings with its
re-integration, the first ``points`` points of its grid), autobalancer (stable_sim and
residual_amplitude, Omega 6..60, horizon 300 revolutions, rtol 1e-8, no re-integration, as
tests/data/autobalancer_layer_speed.py), forced (tests/user_models/forced.py FORCED, amp and
x_hist, 200 periods, four forcing frequencies; ``--per-period=N``: N points a forcing frequency, of
five damping ratios 0.05 .. 1), rms (tests/user_models/rms.py, its RMS outputs,
four forcing frequencies) or forced_distinct (every point its own forcing frequency;
``--groups-of-one``: lanes for groups of one point too, trajectory.LANE_GROUP_MIN = 1)."""
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def problem(model: str, n: int, short: bool):
    from mechsweep.model import user
    from mechsweep.models import MODELS

    if model.startswith("forced"):
        spec = user.resolve(f"{HERE.parent / 'user_models' / 'forced.py'}:FORCED")
        # four forcing frequencies (four lane groups), the amplitude varied within each; forced_distinct:
        # every point its own frequency (its own period: too few points for lanes)
        W = np.repeat(np.linspace(0.3, 3.0, 4), -(-n // 4))[:n] if model == "forced" else np.linspace(0.3, 3.0, n)
        zeta = np.full(n, 0.1)
        per = next((int(a.split("=")[1]) for a in sys.argv if a.startswith("--per-period=")), 0)
        if per:  # a sweep of the forcing frequency: `per` points a period, of five damping ratios
            W = np.repeat(np.linspace(0.3, 3.0, -(-n // per)), per)[:n]
            zeta = np.resize([0.05, 0.1, 0.2, 0.5, 1.0], n)
        P = np.column_stack([np.full(n, 1.0), zeta, np.linspace(0.5, 2.0, n), W])
        return spec, P, ("amp", "x_hist"), dict(method="dop853", rtol=1e-8, atol=1e-10,
                                                horizon_periods=20.0 if short else 200.0)
    if model == "rms":
        spec = user.resolve(f"{HERE.parent / 'user_models' / 'rms.py'}:FORCED_RMS")
        W = np.repeat(np.linspace(0.3, 3.0, 4), -(-n // 4))[:n]
        P = np.column_stack([np.full(n, 1.0), np.full(n, 0.1), np.linspace(0.5, 2.0, n), W])
        return spec, P, tuple(o.name for o in spec.outputs), dict(method="dop853", rtol=1e-8, atol=1e-10,
                                                                  **({"horizon_periods": 20.0} if short else {}))
    if model == "residual":
        import mechsweep
        from mechsweep.grid import parameter_matrix

        scene = mechsweep.load_scene(HERE.parents[1] / "sweeps" / "autobalancer_residual.toml")
        P = parameter_matrix(scene, 0, scene.n_points)
        P = P[np.arange(n) % P.shape[0]]
        kw = dict(scene.solver.settings, method=scene.solver.method, rtol=scene.solver.rtol, atol=scene.solver.atol)
        if short:
            kw["horizon_revolutions"] = 20.0
        return scene.model, P, tuple(scene.outputs), kw
    sys.path.insert(0, str(HERE))
    import record_autobalancer as rec

    spec = MODELS["autobalancer"]
    P = np.repeat(rec.design_points()[2][None, :], n, axis=0)
    P[:, 0] = np.linspace(6.0, 60.0, n)
    return spec, P, ("stable_sim", "residual_amplitude"), dict(
        method="dop853", rtol=1e-8, atol=1e-10, horizon_revolutions=20.0 if short else 300.0,
        reproducibility_factor=0.0)


def evaluate(spec, P, wanted, kw, lanes: bool):
    from mechsweep.engine import sampling as trajectory
    trajectory.USE_LANES = lanes
    sys.path.insert(0, str(HERE))
    import points
    return points.evaluate(spec, P, wanted, **kw)


def child(route: str, model: str) -> None:
    from mechsweep.engine import sampling as trajectory

    trajectory.LANE_GROUP_MIN = 1  # the 4 points' lanes compiled whatever their periods
    spec, P, wanted, kw = problem(model, 4, True)
    c0, w0 = time.process_time(), time.perf_counter()
    evaluate(spec, P, wanted, kw, route == "lanes")
    print(json.dumps({"route": route, "cpu": time.process_time() - c0, "wall": time.perf_counter() - w0}))


def cold(model: str) -> float:
    """The lanes' extra cold compile in CPU seconds (printed with each route's CPU and wall time)."""
    res = {}
    for route in ("one", "lanes"):
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, MECHSWEEP_CACHE_DIR=tmp)
            out = subprocess.run([sys.executable, __file__, "child", route, model], env=env, capture_output=True,
                                 text=True, check=True).stdout
            res[route] = json.loads(out.strip().splitlines()[-1])
            print(f"cold {model} {route}: {res[route]['cpu']:.1f} s CPU, {res[route]['wall']:.1f} s wall", flush=True)
    print(f"cold {model}: the lanes' extra compile {res['lanes']['cpu'] - res['one']['cpu']:.1f} s CPU, "
          f"{res['lanes']['wall'] - res['one']['wall']:.1f} s wall", flush=True)
    return res["lanes"]["cpu"] - res["one"]["cpu"]


def speed(model: str, n: int, rounds: int = 3) -> float:
    """The lanes' CPU seconds saved per point, warm (the median of the rounds)."""
    from mechsweep.engine import sampling as trajectory

    if model == "forced_distinct" and "--groups-of-one" in sys.argv:  # lanes even for a period of one point
        trajectory.LANE_GROUP_MIN = 1
    spec, P, wanted, kw = problem(model, n, False)
    ref = evaluate(spec, P, wanted, kw, False)
    lan = evaluate(spec, P, wanted, kw, True)
    same = all(np.array_equal(a[k], b[k], equal_nan=True) for a, b in [(ref[0], lan[0])] for k in wanted)
    same = same and all(np.array_equal(a, b) for a, b in zip(ref[1:], lan[1:]))
    saved = []
    for r in range(rounds):
        t, c = [], []
        for lanes in (False, True):
            c0, t0 = time.process_time(), time.perf_counter()
            evaluate(spec, P, wanted, kw, lanes)
            t.append(time.perf_counter() - t0)
            c.append(time.process_time() - c0)
        saved.append((c[0] - c[1]) / n)
        print(f"speed {model} {n} points: one trajectory {n / t[0]:.1f} points/s ({c[0] / n * 1e3:.2f} ms CPU a "
              f"point), lanes {n / t[1]:.1f} points/s ({c[1] / n * 1e3:.2f} ms CPU a point) (x{t[0] / t[1]:.2f}); "
              f"bitwise the same {same}", flush=True)
    return float(np.median(saved))


if __name__ == "__main__":
    if sys.argv[1:2] == ["child"]:
        child(sys.argv[2], sys.argv[3])
        sys.exit(0)
    args = [a for a in sys.argv if not a.startswith("--")]
    what = args[1] if len(args) > 1 else "both"
    n = int(args[2]) if len(args) > 2 else 256
    model = args[3] if len(args) > 3 else "autobalancer"
    rounds = next((int(a.split("=")[1]) for a in sys.argv if a.startswith("--rounds=")), None)
    extra = [cold(model) for _ in range(rounds or 1)] if what in ("cold", "both") else []
    saved = speed(model, n, rounds or 3) if what in ("speed", "both") else None
    if extra and saved is not None:
        x = float(np.median(extra))
        print(f"crossover {model}: the lanes' extra cold compile {x:.1f} s CPU (median of {len(extra)}) / "
              f"{saved * 1e3:.2f} ms CPU saved a point = {x / saved:.0f} points" if saved > 0 else
              f"crossover {model}: the lanes save no CPU warm ({saved * 1e3:.2f} ms a point): never", flush=True)
