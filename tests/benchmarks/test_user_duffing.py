"""The user-model Duffing of `python benchmarks/user_duffing.py`: declared on the model layer and named by
its module path, it gives the periods of the built-in model (same points, closed form), and the
bench reports both rates and their ratio (timings are printed, never asserted)."""
import numpy as np

from benchmarks import user_duffing


def test_user_duffing_periods_match_the_closed_form_and_the_built_in(capsys):
    r = user_duffing.main(points=60, threads=1, rtol=1e-10, atol=1e-12)
    assert r["points"] >= 60
    for label in ("built-in", "user model"):
        assert r[f"{label}_ok_fraction"] == 1.0
        assert r[f"{label}_max_rel_error"] < 1e-8
        assert r[f"{label}_points_per_s"] > 0
    assert np.isclose(r["ratio"], r["user model_points_per_s"] / r["built-in_points_per_s"])
    out = capsys.readouterr().out
    assert "user model / built-in" in out and user_duffing.REFERENCE in out
    # where each model's error is largest (docs/your-own-model.md reads it): a point of the grid, in rtol units
    omega, mu, a = r["user, unscaled_max_rel_error_at"]
    assert omega == 1.0 and 0.01 <= a <= 1.0 and 1e-3 <= mu <= 1e3
    assert f"{r['user, unscaled_max_rel_error'] / 1e-10:.2f} rtol, at A = {a:.3g}" in out


def test_bench_user_model_refuses_bad_options(capsys):
    assert user_duffing.cli(["--points", "-5"]) == 2
    assert "points" in capsys.readouterr().err
