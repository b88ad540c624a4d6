"""`python benchmarks/period_error.py`: the tolerance ladder's errors, hard and soft springs apart
(docs/numerics.md quotes them: rtol 1e-6 for nomograms read by eye, the defaults)."""
import numpy as np

from benchmarks import period_error as pe


def test_rtol_1e6_keeps_hard_springs_below_3_5e7_and_soft_ones_reach_ten_times_more():
    """At rtol 1e-6 (atol 1e-8) the hard springs' period error stays below 3.5e-7 and the soft
    springs' reaches 7.6e-6 (near epsilon = -0.65): a bound quoted for the hard-spring scene does not
    hold for soft springs, so the bench prints both."""
    assert (1e-6, 1e-8) in pe.LADDER
    eps = pe.epsilon_scan(2000, 2000)  # a coarser scan than the bench's 40,001 values
    r = pe.worst_error(eps, 1e-6, 1e-8)
    assert r["max_error_hard"] < 3.6e-7 and 7.0e-6 < r["max_error_soft"] < 8.0e-6, r
    assert r["max_error"] == max(r["max_error_hard"], r["max_error_soft"]) and r["not_ok"] == 0
    # the defaults: 5.64e-11 at worst, soft springs; hard springs 1.72e-11
    d = pe.worst_error(eps, 5e-11, 1e-12)
    assert d["max_error_soft"] < 5.7e-11 and d["max_error_hard"] < 1.8e-11, d
    assert np.isclose(d["max_error"], d["max_error_soft"])


def test_symplectic_step_keeps_the_period_error_below_a_tenth_of_rtol_over_every_epsilon():
    """models/duffing.py's symplectic_step promises the period error below rtol over epsilon in
    [-0.99, 1e4]; the bench measures it over that scan (at most 0.098 rtol from 1e-6 to 1e-12)."""
    eps = pe.epsilon_scan(2000, 2000)
    for rtol, atol in pe.SYMPLECTIC_LADDER[:2]:
        r = pe.worst_error(eps, rtol, atol, "symplectic")
        assert r["not_ok"] == 0 and r["max_error"] < 0.1 * rtol, r
