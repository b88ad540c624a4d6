import math

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


# ----------------------------------------------------------------------------- sincos
mpmath = pytest.importorskip("mpmath")
from mechsweep.special import sincos  # noqa: E402


def ulp_error(value, x, func):
    """|value - func(x)| in units of the last place of the exact result (mpmath, 60 digits)."""
    with mpmath.workdps(60):
        exact = func(mpmath.mpf(x))
        ulp = np.spacing(abs(float(exact)))
        return float(abs(mpmath.mpf(value) - exact)) / ulp


def sample_arguments():
    rng = np.random.default_rng(7)
    near_quadrants = (np.pi / 2) * np.arange(-2000, 2000) + 0.0  # worst cases of the reduction
    return np.concatenate([rng.uniform(-np.pi, np.pi, 400), rng.uniform(-2e3, 2e3, 400),
                           rng.uniform(-1e6, 1e6, 300), near_quadrants[::7],
                           np.nextafter(near_quadrants[::31], np.inf), np.geomspace(1e-300, 1.0, 50)])


def test_sincos_within_one_ulp_of_the_exact_values():
    """fdlibm's kernels promise < 1 ulp; measured here against 60-digit mpmath values."""
    worst = 0.0
    for x in sample_arguments():
        s, c = sincos(x)
        worst = max(worst, ulp_error(s, x, mpmath.sin), ulp_error(c, x, mpmath.cos))
    assert worst < 1.0


@settings(max_examples=500, deadline=None)
@given(hs.floats(min_value=-1e6, max_value=1e6, allow_nan=False))
def test_sincos_property_close_to_libm(x):
    s, c = sincos(x)
    assert abs(s - np.sin(x)) <= 2 * np.spacing(abs(np.sin(x)))
    assert abs(c - np.cos(x)) <= 2 * np.spacing(abs(np.cos(x)))
    assert s * s + c * c == pytest.approx(1.0, abs=4e-16)


def test_sincos_outside_the_reduction_range_and_non_finite():
    for x in (1e6 * 1.5, -3e15, 1e300):  # libm takes over beyond 1e6
        assert sincos(x) == (np.sin(x), np.cos(x))
    for x in (np.inf, -np.inf, np.nan):
        s, c = sincos(x)
        assert np.isnan(s) and np.isnan(c)
    assert sincos(0.0) == (0.0, 1.0)
    assert np.copysign(1.0, sincos(-0.0)[0]) == -1.0  # sign of zero kept, as libm


def test_sincos_jitted_equals_python():
    for x in sample_arguments()[::10]:
        assert sincos(x) == sincos.py_func(x)


# ----------------------------------------------------------------------------- the branch-free forms
from mechsweep._jit import jit  # noqa: E402
from mechsweep.special import ieee_sqrt, sincos_reduced  # noqa: E402


def test_sincos_reduced_is_sincos_inside_the_reduction_range():
    """The lane right-hand side uses sincos_reduced; the one-trajectory one sincos: the same floats."""
    xs = np.concatenate([sample_arguments(), [-0.0, 0.0, 1e6, -1e6]])
    for x in xs:
        s, c = sincos_reduced(x)
        assert (s, c) == sincos(x)
        assert np.copysign(1.0, s) == np.copysign(1.0, sincos(x)[0])
    assert all(np.isnan(v) for v in sincos_reduced(np.nan))


@jit
def _sqrt_both(x):
    return ieee_sqrt(x), math.sqrt(x)


def test_ieee_sqrt_is_libm_sqrt():
    rng = np.random.default_rng(3)
    for x in np.concatenate([rng.uniform(0, 2, 200), np.geomspace(1e-310, 1e300, 200), [0.0, -0.0, np.inf]]):
        a, b = _sqrt_both(x)
        assert a == b and np.copysign(1.0, a) == np.copysign(1.0, b)
    assert np.isnan(_sqrt_both(-1.0)[0]) and np.isnan(_sqrt_both(np.nan)[0])
