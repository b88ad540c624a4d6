import numpy as np
import pytest
import scipy.special as sp
from hypothesis import given, settings
from hypothesis import strategies as hs

from mechsweep.special import ellipk


@pytest.mark.parametrize("m", [-1e12, -1e6, -50.0, -1.0, -1e-9, 0.0, 1e-9, 0.3, 0.5, 0.9, 1 - 1e-6, 1 - 1e-14])
def test_ellipk_matches_scipy(m):
    assert ellipk(m) == pytest.approx(sp.ellipk(m), rel=4e-15)


@settings(max_examples=300, deadline=None)
@given(hs.floats(min_value=-1e8, max_value=0.999999, allow_nan=False))
def test_ellipk_property_against_scipy(m):
    assert abs(ellipk(m) - sp.ellipk(m)) <= 1e-14 * sp.ellipk(m)


def test_ellipk_edges():
    assert ellipk(1.0) == np.inf
    assert np.isnan(ellipk(1.5))
    assert np.isnan(ellipk(np.nan))
    assert ellipk(0.0) == pytest.approx(np.pi / 2, rel=0, abs=1e-16)


def test_jitted_equals_python():
    for m in (-3.0, 0.25, 0.75):
        assert ellipk(m) == pytest.approx(ellipk.py_func(m), rel=1e-15)
