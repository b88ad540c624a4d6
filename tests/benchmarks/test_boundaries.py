"""benchmarks/boundaries.py: located boundaries against grid-and-contour, and their continuation."""
import numpy as np


def test_bench_boundaries_small(capsys):
    from benchmarks import boundaries as bench

    assert bench.cli(["--contour", "100"]) == 2
    assert "--contour needs at least two" in capsys.readouterr().err
    assert bench.cli(["--values", "0"]) == 2

    r = bench.main(values=2, grid=100, contour=(50, 400), threads=1)
    out = capsys.readouterr().out
    assert "located: grid 100 x 2" in out and out.count("grid and contour:") == 2
    assert r["per_line"].tolist() == [1, 3]  # 2 m / M = 0.35: the window has closed; 0.0005: all three
    assert r["contour_median_error"][1] < r["contour_median_error"][0] / 4 and r["needed_grid"] > 400
    # continued from 2 m / M = 0.0005, the lower and the omega_p boundary end at one point: the window
    # omega_xi < Omega < omega_p closes there (2 m / M = 0.0578, Omega = 1.2896 rad/s, measured); the
    # upper one turns back in Omega and leaves the chart at 2 m / M = 0.35
    np.testing.assert_allclose(r["movement"][0.02], [0.12443, 0.00363, 0.18658], atol=2e-5)  # README's 12, 0.4, 19 %
    lower, mid, upper = r["curves"]
    assert lower.stop == mid.stop == "step_too_small" and upper.stop == "edge"
    np.testing.assert_allclose(lower.points[-1], mid.points[-1], rtol=1e-5)
    assert 0.05 < 1.0 / lower.points[-1][1] < 0.065 and len(upper.folds) == 1
