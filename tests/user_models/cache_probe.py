"""Run a user model in this (fresh) process and print what numba compiled (used by
tests/test_model_layer.py): cache misses of the kernel (its binding's entry point) and of the user's functions.
argv[2] (optional): the outputs, comma-separated (default: period)."""
import json
import sys

import numpy as np

from mechsweep.scene import load_scene
from mechsweep.engine import kernels as mc
from mechsweep.model import load

outputs = sys.argv[2].split(",") if len(sys.argv) > 2 else ["period"]
scene = load_scene({"scene": {"name": "probe", "model": sys.argv[1], "outputs": outputs},
                    "axes": {"w": {"start": 1.0, "stop": 2.0, "num": 3}}, "fixed": {"A": 0.5}})
P = np.array([[1.0, 0.5], [2.0, 0.5]])
out = {name: np.full(2, np.nan) for name in outputs}
status, ns, nr = np.zeros(2, np.int8), np.zeros(2, np.int64), np.zeros(2, np.int64)
scene.model.evaluate(P, tuple(outputs), scene.solver, out, status, ns, nr)
dispatchers = (list(mc._KERNELS.values()) + list(load._JITTED.values())
               + [h[1] for h in load._HELPERS.values() if isinstance(h, tuple)])  # the user's helpers, recompiled
print(json.dumps({outputs[0]: out[outputs[0]].tolist(),
                  "misses": sum(sum(d.stats.cache_misses.values()) for d in dispatchers),
                  "hits": sum(sum(d.stats.cache_hits.values()) for d in dispatchers),
                  "n": len(dispatchers)}))
