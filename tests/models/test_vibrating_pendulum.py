"""The worked example of docs/your-own-model.md: a pendulum on a vertically vibrating support
(sweeps/models/vibrating_pendulum.py), checked against Mathieu's characteristic values and Kapitza's
criterion, and its shipped scene run end to end. One model, one Floquet kernel for every test here.

Mapping to Mathieu's equation x'' + (a_M - 2 q cos 2 tau) x = 0: linearised about theta = 0 and
undamped, theta'' + (g/L - (a w^2/L) cos w t) theta = 0; with tau = w t / 2 (d/dt = (w/2) d/dtau)
    theta_tautau + (4 g / (L w^2) - (4 a / L) cos 2 tau) theta = 0,  a_M = 4 g / (L w^2), q = 2 a / L.
About theta = pi, sin(theta) = -(theta - pi) + ...: the same with the sign of the bracket flipped,
a_M = -4 g / (L w^2), q = -2 a / L (the sign of q does not change stability: tau -> tau + pi/2).
The forcing period 2 pi / w is tau-period pi, Mathieu's own.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import mathieu_a, mathieu_b

from mechsweep import status as st
from mechsweep.cli import main
from mechsweep.scene import load_scene

from tests.conftest import SWEEPS
from tests import evaluating

SCENE = SWEEPS / "vibrating_pendulum_stability.toml"
REF = f"{SWEEPS / 'models' / 'vibrating_pendulum.py'}:VIBRATING_PENDULUM"
G, L = 9.81, 0.25


def floquet(rows, rtol=1e-12, atol=1e-14):
    """max_multiplier at rows of (g, L, a, w, c, m, position index)."""
    scene = load_scene({"scene": {"name": "t", "model": REF, "outputs": ["max_multiplier"]},
                        "axes": {"a": [0.0, 0.01]}, "fixed": {"L": L, "w": 10.0, "position": "hanging"},
                        "solver": {"rtol": rtol, "atol": atol}})
    out, status, _, _ = evaluating.evaluate(scene.model, rows, ("max_multiplier",), scene.solver)
    assert (status == st.OK).all(), status
    return out["max_multiplier"]


def mathieu_point(a_m, q, inverted):
    """(a, w) of the support giving Mathieu's (a_M, q) at the hanging or inverted position."""
    w = math.sqrt(4.0 * G / (L * abs(a_m)))
    return (G, L, q * L / 2.0, w, 0.0, 1.0, 1.0 if inverted else 0.0)


def test_stability_boundaries_are_mathieus_characteristic_curves():
    """Just inside and just outside every boundary a_M = a_n(q), b_n(q) (relative step 1e-5):
    the stable side has max |multiplier| = 1 to the integration error, the unstable side is above it.
    Hanging: a_M > 0 (the tongues at w = 2 w0 / n); inverted: a_M < 0 (a_0 and, for larger q, b_1)."""
    rows, stable = [], []
    for q in (0.2, 0.5, 1.0, 1.5, 3.0):
        # q > 0: a_0 < b_1 < a_1 < b_2 < a_2; stable on a_0 < a_M < b_1, a_1 < a_M < b_2, a_2 < a_M < ...
        for edge, stable_above in ((mathieu_a(0, q), True), (mathieu_b(1, q), False), (mathieu_a(1, q), True),
                                   (mathieu_b(2, q), False), (mathieu_a(2, q), True)):
            for side in (-1.0, 1.0):
                a_m = edge * (1.0 + side * 1e-5)
                rows.append(mathieu_point(a_m, q, inverted=a_m < 0))
                stable.append((a_m > edge) == stable_above)
    stable = np.array(stable)
    inverted = np.array([r[6] == 1.0 for r in rows])
    assert stable[inverted].any() and (~stable[inverted]).any() and stable[~inverted].any() and (~stable[~inverted]).any()
    m = floquet(rows)
    assert np.abs(m[stable] - 1.0).max() < 1e-8, m[stable] - 1.0
    assert (m[~stable] - 1.0).min() > 1e-4, m[~stable] - 1.0


def test_kapitza_criterion_for_the_inverted_position_with_damping():
    """Kapitza: for small q the inverted pendulum is stable when (a w)^2 > 2 g L (a_0(q) ~ -q^2/2).
    A loose check at q = 0.08 (factor 0.7 / 1.4 either side), with damping c/m = 0.5 1/s: stable means
    every multiplier inside the unit circle, and there (a complex pair) |mu| = exp(-(c/m) T / 2),
    since the product of the multipliers is exp(-(c/m) T) (Liouville)."""
    a, c, m = 0.01, 0.5, 1.0
    rows = []
    for factor in (0.7, 1.4, 2.0):
        w = math.sqrt(factor * 2.0 * G * L) / a
        rows.append((G, L, a, w, c, m, 1.0))
    mu = floquet(rows)
    assert mu[0] > 1.1, mu  # below the criterion: falls over (measured 1.11 per period)
    T = 2.0 * math.pi / np.array([r[3] for r in rows[1:]])
    np.testing.assert_allclose(mu[1:], np.exp(-(c / m) * T / 2.0), rtol=1e-8)
    assert (mu[1:] < 1.0).all()


def test_shipped_scene_runs_and_agrees_with_mathieu(in_tmp):
    assert main(["run", str(SCENE), "-o", "vp.h5", "--no-progress", "--threads", "1"]) == 0
    import xarray as xr
    with xr.open_dataset(in_tmp / "vp.h5") as ds:
        assert (ds["status"].values == st.OK).all()
        assert ds["max_multiplier"].attrs["units"] == "1"
        m = ds["max_multiplier"].transpose("a", "w", "position").values
        a, w = np.meshgrid(ds["a"].values, ds["w"].values, indexing="ij")
        _check_stability_map(ds, m)
    q = 2.0 * a / L
    a_m = 4.0 * G / (L * w ** 2)
    # reference verdicts from Mathieu's curves, for points not within 1e-3 of a boundary
    hang_unstable = ((a_m > mathieu_b(1, q)) & (a_m < mathieu_a(1, q))) | ((a_m > mathieu_b(2, q)) & (a_m < mathieu_a(2, q)))
    inv_stable = -a_m > mathieu_a(0, q)
    near = np.zeros_like(a_m, dtype=bool)
    for edge in (mathieu_b(1, q), mathieu_a(1, q), mathieu_b(2, q), mathieu_a(2, q)):
        near |= np.abs(a_m - edge) < 1e-3 * np.abs(edge)
    near_inv = np.abs(-a_m - mathieu_a(0, q)) < 1e-3 * np.abs(mathieu_a(0, q)) + 1e-12
    for verdict, reference, skip in ((m[..., 0] > 1.0 + 1e-6, hang_unstable, near),
                                     (m[..., 1] <= 1.0 + 1e-6, inv_stable, near_inv)):
        assert (verdict == reference)[~skip].all()
    # the scene shows both phenomena: a parametric-resonance tongue and Kapitza stabilisation
    assert hang_unstable.any() and inv_stable.any() and (~inv_stable).any()


def _check_stability_map(ds, m):
    """The generic figure is chosen from the declared output kind, and draws the verdicts of the
    data (stable at max |multiplier| <= 1 + 1e-6), one panel per position, w on a log axis."""
    import matplotlib.pyplot as plt

    from mechsweep import figures

    assert ds["max_multiplier"].attrs["mechsweep_kind"] == "floquet_max"
    assert list(figures.available(ds)) == ["stability_map"]
    fig = figures.draw(ds, "stability_map")
    try:
        panels = [ax for ax in fig.axes if ax.get_visible() and ax.collections]
        assert [ax.get_title() for ax in panels] == ["position = hanging", "position = inverted"]
        for k, ax in enumerate(panels):
            assert ax.get_xscale() == "log" and ax.get_yscale() == "linear"
            shading = np.asarray(ax.collections[0].get_array()).reshape(m.shape[:2])
            np.testing.assert_array_equal(shading, (m[..., k] <= 1.0 + 1e-6).astype(float))
            assert len(ax.collections) >= 2  # the boundary contour
    finally:
        plt.close(fig)
