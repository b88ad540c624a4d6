"""benchmarks/linkage.py: the four-bar residual sweep against vectorised numpy."""
import numpy as np

from mechsweep import status as st


def test_bench_numpy_reference_is_the_same_computation(capsys):
    from benchmarks import linkage as bench

    P = bench.design_family(200, seed=4)
    ours, status = bench.mechsweep_residuals(P)
    ref = bench.numpy_fourbar(P, block=64)
    assert (status == st.OK).all()
    for k in bench.OUTPUTS:
        np.testing.assert_allclose(ours[k], ref[k], rtol=1e-11, atol=1e-11 * np.abs(ref[k]).max())
    r = bench.main(designs=256, numpy_designs=64, repeats=1)
    assert r["max_rel_difference"] < 1e-11 and r["ratio"] > 0
    assert "ratio mechsweep / numpy" in capsys.readouterr().out
