"""Kernel binding modules under concurrent first use (dask's threaded scheduler runs chunks of
one scene in several threads, each asking for the scene's kernel at once)."""
from __future__ import annotations

import sys
import threading
import time
import uuid

from mechsweep.engine import binding
from mechsweep.engine import kernels as mc


def test_threads_asking_for_one_generated_module_share_one_import():
    name = "mechsweep_gen_test_" + uuid.uuid4().hex[:12]

    def slow():  # a slow import: the threads overlap
        time.sleep(0.2)
        return binding.Entries()

    got, errors = [], []
    start = threading.Barrier(4)

    def load():
        try:
            start.wait()
            got.append(binding.bind(name, "a test", {}, slow))
        except Exception as e:  # noqa: BLE001 - any failure is the finding
            errors.append(e)

    threads = [threading.Thread(target=load) for _ in range(4)]
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        (binding.folder() / f"{name}.py").unlink(missing_ok=True)
        sys.modules.pop(name, None)
        binding._LOADED.pop(name, None)
    assert not errors
    assert len(got) == 4 and all(k is got[0] for k in got)  # one module, imported once
    assert not list(binding.folder().glob(f"{name}*.tmp"))


def test_kernel_for_the_same_objects_reads_no_model_source_again(monkeypatch):
    """Every chunk of a run asks for its kernel: after the first time, the same model and
    measurement objects get it without reading and hashing the model's files; a kernel dropped
    from the cache is looked up (and read) again."""
    from pathlib import Path

    from mechsweep.model import load, user

    path = Path(__file__).parents[1] / "user_models" / "api_models.py"
    user.resolve(f"{path}:OSC")  # imports the file as the engine does; kernel_for takes its OdeModel
    osc = sys.modules[next(n for n, m in sys.modules.items()
                           if getattr(m, "__file__", None) == str(path))].OSC
    chosen = osc.measurements
    first = mc.kernel_for(osc, chosen)
    reads = []
    real = load.module_source
    monkeypatch.setattr(load, "module_source", lambda *a: reads.append(a) or real(*a))
    assert mc.kernel_for(osc, chosen) is first and not reads
    monkeypatch.setattr(mc, "_KERNELS", {})
    assert mc.kernel_for(osc, chosen) is not None and reads


def test_one_point_kernel_is_serial_code_split_over_python_threads(monkeypatch, small_duffing):
    """The one-point kernel is compiled as serial code (numba's parallel compile of a prange cost about
    2.3 s of the quickstart's cold compile) and engine/point.py's Threaded runs it on numba.get_num_threads() Python
    threads, each a stride of the points: the results are bitwise the same for any split (1 or 3 threads,
    the latter uneven over 63 points)."""
    import numba
    import numpy as np

    from mechsweep.grid import ParameterMatrix
    from mechsweep.execution.execute import evaluate_rows
    from mechsweep.scene import load_scene

    monkeypatch.setattr(mc, "USE_LANES", False)
    scene = load_scene(small_duffing)
    P = ParameterMatrix(scene)(0, scene.n_points)
    got = []
    for threads in (1, 3):
        monkeypatch.setattr(numba, "get_num_threads", lambda: threads)
        got.append(evaluate_rows(scene, P))
    (one, s1, a1, b1), (three, s3, a3, b3) = got
    assert (s1 == s3).all() and (a1 == a3).all() and (b1 == b3).all() and (a1 > 0).any()
    for name in one:
        assert np.array_equal(one[name], three[name], equal_nan=True), name
    kernels = [k for k in mc._KERNELS.values() if isinstance(k, mc.Threaded)]
    assert kernels and not any(k.targetoptions.get("parallel") for k in kernels)


def test_sampled_trajectory_and_closed_form_kernels_are_serial_code_split_over_python_threads(monkeypatch):
    """The sampled-trajectory kernel (engine/trajectory.py, one trajectory at a time) and a closed-form
    model's kernel (engine/closed.py) are compiled as serial code that engine/point.py's Threaded runs
    on numba.get_num_threads() Python threads (numba's parallel compile of a prange spared): the results
    are bitwise the same for 1 and 3 threads (the latter uneven: 29 points in strides; 150 designs in
    blocks of 64)."""
    from pathlib import Path

    import numba
    import numpy as np

    from mechsweep.engine import sampling
    from mechsweep.model import closed, user
    from tests.evaluating import evaluate

    models = Path(__file__).parents[1] / "user_models"
    forced, cam = user.resolve(f"{models / 'forced.py'}:FORCED"), user.resolve(f"{models / 'cam.py'}:CAM")
    monkeypatch.setattr(sampling, "USE_LANES", False)
    n = 29
    P_forced = np.column_stack([np.full(n, 1.0), np.full(n, 0.1), np.linspace(0.5, 2.0, n),
                                np.linspace(0.3, 3.0, n)])
    n = 150
    P_cam = np.column_stack([np.full(n, 0.02), np.linspace(0.5, 3.0, n), np.full(n, 30.0), np.arange(n) % 2,
                             np.full(n, 0.04), np.full(n, np.pi / 6)])
    got = []
    for threads in (1, 3):
        monkeypatch.setattr(numba, "get_num_threads", lambda: threads)
        got.append((evaluate(forced, P_forced, ("amp", "x_hist"), method="dop853", rtol=1e-8, atol=1e-10,
                             horizon_periods=20.0),
                    evaluate(cam, P_cam, ("a_max", "a_u"))))
    for (one, s1, a1, b1), (three, s3, a3, b3) in zip(*got):
        assert (s1 == s3).all() and (a1 == a3).all() and (b1 == b3).all()
        for name in one:
            assert np.isfinite(one[name]).any() and np.array_equal(one[name], three[name], equal_nan=True), name
    assert (got[0][0][2] > 0).all()  # every trajectory integrated
    kernels = [k.kernel for k in sampling._KERNELS.values()] + [k.entry for k in closed._KERNELS.values()]
    assert kernels and all(isinstance(k, mc.Threaded) and not k.targetoptions.get("parallel") for k in kernels)
