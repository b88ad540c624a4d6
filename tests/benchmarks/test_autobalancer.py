"""benchmarks/autobalancer.py: the auto-balancer's Floquet chart and simulation speed against scipy."""
import pytest


@pytest.mark.slow
def test_benchmark_runs_and_compares_the_same_steps():
    """`python benchmarks/autobalancer.py` on a tiny sample: the lanes and the one-at-a-time kernel take
    the same steps, and both beat scipy on the same trajectories (timings themselves: not asserted)."""
    from benchmarks import autobalancer as bench

    r = bench.main(n_omega=2, n_ratio=2, sim_points=4, scipy_points=1, threads=1)
    assert r["one_at_a_time_same_steps"] and r["auto_same_steps_elsewhere"]
    assert r["ours_steps_same_trajectories"][0] == pytest.approx(r["scipy_mean_steps"], rel=0.5)
    assert r["max_residual_difference_m"] < 1e-9  # both scipy routes: Python rhs and the model's compiled rhs
    assert r["scipy_jitted_rhs_steps_per_s"] > 0
    nb = r["numbalsoda"]  # the strongest competitor, when installed: the same trajectories, none failed
    if nb is not None:
        assert nb["failed"] == 0 and nb["max_residual_difference_m"] < 1e-9
        assert nb["one_thread"]["ratio"] > 0 and nb["all_threads"]["ratio"] > 0
