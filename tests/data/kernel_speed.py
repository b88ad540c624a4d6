"""Points/s of `mechsweep bench duffing`'s kernel measurement alone (its grid, period only, best of
``repeats`` whole-grid evaluations in memory after a compile call): ``python tests/data/kernel_speed.py
[points] [repeats] [threads]``. Prints wall-clock points/s and points per CPU second of the process
(less disturbed by other processes on a shared machine). Run it alternately with two source trees
(PYTHONPATH) to compare them side by side; the full bench also times scipy and an HDF5 run."""
import math
import sys
import time

from mechsweep.bench.duffing import grid_scene
from mechsweep.chunks import Chunk
from mechsweep.execution.execute import evaluate_chunk, threads as _threads
from mechsweep.scene import Solver, load_scene

points = int(sys.argv[1]) if len(sys.argv) > 1 else 200_000
repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 5
threads = int(sys.argv[3]) if len(sys.argv) > 3 else None
scene = load_scene(grid_scene(points, Solver.rtol, Solver.atol))
whole = Chunk(0, 0, scene.n_points, ())
wall = cpu = math.inf
with _threads(threads):
    evaluate_chunk(scene, Chunk(0, 0, 4, ()))
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        evaluate_chunk(scene, whole)
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
print(f"{scene.n_points / wall:,.0f} points/s wall, {scene.n_points / cpu:,.0f} points per CPU second")
