"""Cold-cache compile time of a model's route: ``MECHSWEEP_CACHE_DIR=<empty dir> python
tests/data/compile_time.py duffing dop853 [outputs...]`` prints the wall time of the first
evaluation of a 4-point scene (import excluded): everything numba compiles for it, from nothing.
Used to compare the built-in Duffing before and after it moved onto the model layer."""
import sys
import time

from mechsweep.chunks import Chunk
from mechsweep.execution.execute import evaluate_chunk
from mechsweep.scene import load_scene

model, method = sys.argv[1], sys.argv[2]
outputs = sys.argv[3:] or ["period", "period_exact", "period_error", "v_max", "a_max", "kv", "ka", "epsilon"]
scene = load_scene({"scene": {"name": "compile", "model": model, "outputs": outputs},
                    "axes": {"A": {"start": 0.1, "stop": 1.0, "num": 2}, "mu": {"start": 0.5, "stop": 2.0, "num": 2}},
                    "fixed": {"omega": 1.0}, "solver": {"method": method}})
t0 = time.perf_counter()
evaluate_chunk(scene, Chunk(0, 0, scene.n_points, ()))
print(f"{model} {method} {len(outputs)} outputs: first evaluation {time.perf_counter() - t0:.1f} s")
