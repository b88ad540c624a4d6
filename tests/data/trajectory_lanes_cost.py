"""What the sampled-trajectory lanes cost and gain (model/trajectory.py, USE_LANES / LANES_FROM_POINTS):
``python tests/data/trajectory_lanes_cost.py [cold|speed|both] [points] [model]``.

cold: each route (lanes, one trajectory at a time) in a new process with an empty numba cache
folder (MECHSWEEP_CACHE_DIR in a temporary folder): the CPU and wall time of a first evaluation of
4 points (horizon 20 revolutions: the compile dominates); their difference is the lanes' extra
cold compile. speed: warm caches (the default cache folder), ``points`` points (default 256,
Omega 6..60, horizon 300 revolutions, rtol 1e-8, as tests/data/autobalancer_layer_speed.py),
alternating the routes in one process, points per second. model: autobalancer (stable_sim and
residual_amplitude, no re-integration) or forced (tests/user_models/forced.py FORCED, amp and
x_hist, 200 periods, four forcing frequencies), or forced_distinct (every point its own forcing
frequency; ``--groups-of-one``: lanes for groups of one point too, trajectory.LANE_GROUP_MIN = 1)."""
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
        P = np.column_stack([np.full(n, 1.0), np.full(n, 0.1), np.linspace(0.5, 2.0, n), W])
        return spec, P, ("amp", "x_hist"), dict(method="dop853", rtol=1e-8, atol=1e-10,
                                                horizon_periods=20.0 if short else 200.0)
    sys.path.insert(0, str(HERE))
    import record_autobalancer as rec

    spec = MODELS["autobalancer"]
    P = np.repeat(rec.design_points()[2][None, :], n, axis=0)
    P[:, 0] = np.linspace(6.0, 60.0, n)
    return spec, P, ("stable_sim", "residual_amplitude"), dict(
        method="dop853", rtol=1e-8, atol=1e-10, horizon_revolutions=20.0 if short else 300.0,
        reproducibility_factor=0.0)


def evaluate(spec, P, wanted, kw, lanes: bool):
    from mechsweep.model import trajectory
    trajectory.USE_LANES = lanes
    sys.path.insert(0, str(HERE))
    import points
    return points.evaluate(spec, P, wanted, **kw)


def child(route: str, model: str) -> None:
    from mechsweep.model import trajectory

    trajectory.LANE_GROUP_MIN = 1  # the 4 points' lanes compiled whatever their periods
    spec, P, wanted, kw = problem(model, 4, True)
    c0, w0 = time.process_time(), time.perf_counter()
    evaluate(spec, P, wanted, kw, route == "lanes")
    print(json.dumps({"route": route, "cpu": time.process_time() - c0, "wall": time.perf_counter() - w0}))


def cold(model: str) -> None:
    res = {}
    for route in ("one", "lanes"):
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, MECHSWEEP_CACHE_DIR=tmp)
            out = subprocess.run([sys.executable, __file__, "child", route, model], env=env, capture_output=True,
                                 text=True, check=True).stdout
            res[route] = json.loads(out.strip().splitlines()[-1])
            print(f"cold {model} {route}: {res[route]['cpu']:.1f} s CPU, {res[route]['wall']:.1f} s wall", flush=True)
    print(f"cold {model}: the lanes' extra compile {res['lanes']['cpu'] - res['one']['cpu']:.1f} s CPU, "
          f"{res['lanes']['wall'] - res['one']['wall']:.1f} s wall")


def speed(model: str, n: int, rounds: int = 3) -> None:
    from mechsweep.model import trajectory

    if model == "forced_distinct" and "--groups-of-one" in sys.argv:  # lanes even for a period of one point
        trajectory.LANE_GROUP_MIN = 1
    spec, P, wanted, kw = problem(model, n, False)
    ref = evaluate(spec, P, wanted, kw, False)
    lan = evaluate(spec, P, wanted, kw, True)
    same = all(np.array_equal(a[k], b[k], equal_nan=True) for a, b in [(ref[0], lan[0])] for k in wanted)
    same = same and all(np.array_equal(a, b) for a, b in zip(ref[1:], lan[1:]))
    for r in range(rounds):
        t = []
        for lanes in (False, True):
            t0 = time.perf_counter()
            evaluate(spec, P, wanted, kw, lanes)
            t.append(time.perf_counter() - t0)
        print(f"speed {model} {n} points: one trajectory {n / t[0]:.1f} points/s, lanes {n / t[1]:.1f} points/s "
              f"(x{t[0] / t[1]:.2f}); bitwise the same {same}", flush=True)


if __name__ == "__main__":
    if sys.argv[1:2] == ["child"]:
        child(sys.argv[2], sys.argv[3])
        sys.exit(0)
    args = [a for a in sys.argv if not a.startswith("--")]
    what = args[1] if len(args) > 1 else "both"
    n = int(args[2]) if len(args) > 2 else 256
    model = args[3] if len(args) > 3 else "autobalancer"
    if what in ("cold", "both"):
        cold(model)
    if what in ("speed", "both"):
        speed(model, n)
