"""RMS, a sampled-trajectory measurement (model/sampled.py), against the closed form of a forced damped
oscillator on every route: one trajectory at a time by each method, the SIMD lanes, a dask cluster."""
import math
from pathlib import Path

import numpy as np
import pytest

import mechsweep
from mechsweep import status as st
from mechsweep.errors import InputError
from mechsweep.engine import sampling as trajectory
from mechsweep.model import RMS, user

from tests.evaluating import evaluate

USER = Path(__file__).resolve().parents[1] / "user_models" / "rms.py"

WANTED = ("x_rms", "v_rms", "x_rel")
# below, near and above resonance (settled within 200 periods); F < 0; zeta = 0: x_rel's classify skips it
P = np.array([[1.0, 0.1, 1.0, 0.5], [1.0, 0.05, 2.0, 0.97], [2.0, 0.3, 1.0, 5.0], [1.5, 0.2, -0.5, 1.5],
              [1.0, 0.0, 1.0, 0.5]])


@pytest.fixture(scope="module")
def model():
    return user.resolve(f"{USER}:FORCED_RMS")


def _amplitude(w, zeta, F, W):
    return np.abs(F) / np.hypot(w * w - W * W, 2 * zeta * w * W)


@pytest.mark.parametrize("method", ["dop853", pytest.param("radau", marks=pytest.mark.slow),
                                    pytest.param("auto", marks=pytest.mark.slow)])
def test_rms_of_a_forced_damped_oscillator_is_its_amplitude_over_sqrt2(model, method, monkeypatch):
    monkeypatch.setattr(trajectory, "USE_LANES", False)  # one trajectory at a time (the lanes: below)
    out, status, ns, nr = evaluate(model, P, WANTED, method=method, rtol=1e-10, atol=1e-12, max_steps=10**7)
    A = _amplitude(*P[:4].T)
    assert status[:4].tolist() == [st.OK] * 4 and (ns > 0).all() and (nr > ns).all()
    # the trapezoid rule over whole periods is exact for the squared sinusoid (64 and 32 samples a period)
    np.testing.assert_allclose(out["x_rms"][:4], A / math.sqrt(2.0), rtol=2e-7)
    np.testing.assert_allclose(out["v_rms"][:4], A * P[:4, 3] / math.sqrt(2.0), rtol=2e-7)
    np.testing.assert_allclose(out["x_rel"][:4], A / math.sqrt(2.0) / P[:4, 2], rtol=2e-7)  # value(p, x): x / F
    # zeta = 0: x_rel does not apply (its classify), the undamped beat's RMS is still measured
    assert status[4] == st.INFEASIBLE and math.isnan(out["x_rel"][4]) and math.isfinite(out["x_rms"][4])


def test_rms_in_lanes_is_the_one_trajectory_route_bitwise(model, monkeypatch):
    """dop853 in SIMD lanes (the engine's lane form of the rhs) and one trajectory at a time: the same
    values, status, n_steps and n_rhs, bitwise; the lanes were taken (a forcing period shared by 16
    points: LANE_GROUP_MIN)."""
    rows = np.repeat(P, 4, axis=0)
    rows[:, 0] *= np.tile([1.0, 1.1, 1.2, 1.3], P.shape[0])  # 20 points, one forcing period each 4
    rows[:, 3] = 0.9  # one forcing period: one lane group
    calls = []
    run_lanes = trajectory._run_lanes
    monkeypatch.setattr(trajectory, "_run_lanes", lambda *a, **k: calls.append(1) or run_lanes(*a, **k))
    got = []
    for use in (False, True):
        monkeypatch.setattr(trajectory, "USE_LANES", use)
        got.append(evaluate(model, rows, WANTED, method="dop853", rtol=1e-9, atol=1e-12))
    assert calls == [1]
    (one, s1, n1, r1), (lan, s2, n2, r2) = got
    assert (s1 == s2).all() and (n1 == n2).all() and (r1 == r2).all()
    for name in WANTED:
        assert np.array_equal(one[name], lan[name], equal_nan=True), name


def test_lanes_on_several_threads_use_the_kernel_pool_with_the_same_results(model, monkeypatch):
    """The lane queues of a forcing period run on the calling thread and the kernel pool's threads
    (engine/point.py, as the one-trajectory kernel), not on a thread pool started per forcing period:
    no pool is made on 3 threads (2 queues on each of 2 periods), and the results are bitwise those
    of 1 thread."""
    import concurrent.futures

    import numba

    from mechsweep.engine import point

    rows = np.repeat(P[:4], 10, axis=0)
    rows[:, 0] *= np.tile(np.linspace(1.0, 1.3, 10), 4)
    rows[:, 3] = np.repeat([0.9, 1.1], 20)  # two forcing periods of 20 points: two queues each
    monkeypatch.setattr(trajectory, "USE_LANES", True)
    point._pool()  # the kernel pool, made once per process
    made = []

    class Counted(concurrent.futures.ThreadPoolExecutor):
        def __init__(self, *a, **k):
            made.append(1)
            super().__init__(*a, **k)

    monkeypatch.setattr(concurrent.futures, "ThreadPoolExecutor", Counted)
    got = []
    for threads in (1, 3):
        monkeypatch.setattr(numba, "get_num_threads", lambda: threads)
        got.append(evaluate(model, rows, WANTED, method="dop853", rtol=1e-9, atol=1e-12))
    assert made == []
    (one, s1, n1, r1), (three, s3, n3, r3) = got
    assert (s1 == st.OK).all() and (s1 == s3).all() and (n1 == n3).all() and (r1 == r3).all()
    for name in WANTED:
        assert np.array_equal(one[name], three[name]), name


def test_rms_declaration_is_checked(model):
    for bad, match in ((dict(window=0.0), "window"), (dict(window=1.5), "window"),
                       (dict(samples_per_period=1), "samples_per_period"), (dict(of="z"), "state 'z'")):
        kw = dict(name="r", of="x") | bad
        with pytest.raises(ValueError, match=match):
            RMS(**kw).validate(("x", "v"))
    assert [o.name for o in RMS("r", "x").outputs()] == ["r"]


def test_rms_scene_runs_on_a_dask_cluster_as_locally(in_tmp):
    """The dataset of a scene asking for RMS outputs, computed on a dask cluster (two worker processes)
    and locally: bitwise the same values and statuses."""
    distributed = pytest.importorskip("distributed")
    scene = {"scene": {"name": "rms", "model": f"{USER}:FORCED_RMS", "outputs": list(WANTED)},
             "axes": {"W": {"start": 0.5, "stop": 2.0, "num": 6}, "zeta": [0.1, 0.3]},
             "fixed": {"w": 1.0, "F": 1.0}, "solver": {"rtol": 1e-9, "atol": 1e-12},
             "storage": {"chunk_size": 4}}
    local = mechsweep.run(scene, output="data/runs/local.h5", progress=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        remote = mechsweep.run(scene, output="data/runs/dask.h5", progress=False, scheduler=c.scheduler_address)
    for name in WANTED + ("status", "n_steps", "n_rhs"):
        np.testing.assert_array_equal(remote[name].values, local[name].values, err_msg=name)
    assert (local["status"].values == st.OK).all()
    A = _amplitude(1.0, local["zeta"].values[None, :], 1.0, local["W"].values[:, None])
    np.testing.assert_allclose(local["x_rms"].values, A / math.sqrt(2.0), rtol=1e-6)


def test_a_bad_rms_in_a_scene_is_refused(in_tmp):
    with pytest.raises(InputError, match="horizon_periods"):
        mechsweep.run({"scene": {"name": "rms", "model": f"{USER}:FORCED_RMS", "outputs": ["x_rms"]},
                       "axes": {"W": [1.0]}, "fixed": {"w": 1.0, "zeta": 0.1, "F": 1.0},
                       "solver": {"horizon_periods": 0.0}}, output=None)
