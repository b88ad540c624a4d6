"""Cost of a closed-form user model (docs/model-layer.md, "Closed-form models"): the cam follower of
cam.py. Prints the time of a first process with an empty numba cache (scene loading with its
probe and compile of compute, then the kernel's compile and one small evaluation), of a second
process (everything from the disk cache), and designs/s on one thread (best of 5, 200,000
designs, 101 samples each), with and without the two curves.

    PYTHONPATH=src python tests/user_models/cam_cost.py
"""
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CAM = Path(__file__).resolve().parent / "cam.py"
CHILD = """
import json, sys, time
t0 = time.perf_counter()
import numpy as np
from mechsweep.scene import load_scene
t1 = time.perf_counter()
scene = load_scene({"scene": {"name": "c", "model": sys.argv[1], "outputs": ["a_max", "s_u"]},
                    "axes": {"beta": [1.0, 2.0]}, "fixed": {"h": 0.02, "omega": 30.0}})
t2 = time.perf_counter()
P = np.array([[0.02, 1.0, 30.0, 0.0, 0.05, 0.5236]])
out = {"a_max": np.full(1, np.nan), "s_u": np.full((1, 101), np.nan)}
scene.model.evaluate(P, ("a_max", "s_u"), None, out, np.zeros(1, np.int8), None, None)
t3 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "load_scene": t2 - t1, "first_evaluate": t3 - t2}))
"""


def processes():
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, MECHSWEEP_CACHE_DIR=cache)
        runs = []
        for _ in range(2):
            res = subprocess.run([sys.executable, "-c", CHILD, f"{CAM}:CAM"], capture_output=True, text=True,
                                 env=env, check=True)
            runs.append(json.loads(res.stdout.strip().splitlines()[-1]))
    return runs


def throughput(n=200_000, repeats=5):
    import numba

    from mechsweep.scene import load_scene
    from mechsweep import status as st

    scene = load_scene({"scene": {"name": "c", "model": f"{CAM}:CAM", "outputs": ["a_max"]},
                        "axes": {"beta": [1.0, 2.0]}, "fixed": {"h": 0.02, "omega": 30.0}})
    rng = np.random.default_rng(0)
    P = np.column_stack([np.full(n, 0.02), rng.uniform(1.0, 2.0, n), np.full(n, 30.0), rng.integers(0, 2, n),
                         np.full(n, 0.05), np.full(n, 0.5236)])
    res = {}
    numba.set_num_threads(1)
    for label, wanted in (("scalars", ("v_max", "a_max", "pressure_angle_max")),
                          ("scalars_and_curves", ("v_max", "a_max", "pressure_angle_max", "s_u", "a_u"))):
        out = {k: np.full((n, 101) if k.endswith("_u") else n, np.nan) for k in wanted}
        status = np.zeros(n, st.DTYPE)
        scene.model.evaluate(P[:10], wanted, None, {k: v[:10] for k, v in out.items()}, status[:10], None, None)
        best = min(_timed(lambda: scene.model.evaluate(P, wanted, None, out, status, None, None))
                   for _ in range(repeats))
        res[label] = n / best
    return res


def _timed(fn):
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


if __name__ == "__main__":
    first, second = processes()
    print(f"first process (empty cache): import {first['import']:.2f} s, load_scene (probe + compile of compute) "
          f"{first['load_scene']:.2f} s, first evaluate (kernel compile) {first['first_evaluate']:.2f} s")
    print(f"second process (disk cache): import {second['import']:.2f} s, load_scene {second['load_scene']:.2f} s, "
          f"first evaluate {second['first_evaluate']:.2f} s")
    for label, v in throughput().items():
        print(f"one thread, {label}: {v:,.0f} designs/s ({v * 101 / 1e6:.1f} M samples/s)")
