"""A measurement's own classify (where it applies) and a model's status_order (a point's status:
the most severe among its asked-for outputs'), on a user model with closed forms
(tests/user_models/severity.py)."""
import math
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.model import OdeModel, user
from tests.evaluating import evaluate

USER = Path(__file__).resolve().parents[1] / "user_models" / "severity.py"
# w, zeta, F, W: OK; F < 0 (amp does not apply); zeta = 0 (mu UNDECIDED) and F < 0;
# zeta = 2 (mu, x_hist do not apply) and F = 0 (amp_exact: NO_MOTION); zeta = 2 and F < 0
P = np.array([[1.0, 0.2, 1.0, 0.5], [1.0, 0.2, -1.0, 0.5], [1.0, 0.0, -1.0, 0.5], [1.0, 2.0, 0.0, 0.5],
              [1.0, 2.0, -1.0, 0.5]])


def _evaluate(name, wanted, P=P):
    out, status, ns, _ = evaluate(user.resolve(f"{USER}:{name}"), P, wanted, rtol=1e-10, atol=1e-12)
    return out, status, ns


ALL = ("mu", "mu_stable", "amp_exact", "amp_h1", "x_hist")


# The integrating tests compile a Floquet and two sampled kernels per model (about 75 s cold on the
# shared 2-core machine): slow. The default run keeps the declaration check.
@pytest.mark.slow
def test_status_order_gives_the_severer_problem_and_classify_skips_only_its_measurement():
    out, status, ns = _evaluate("SEVERITY", ALL)
    w, zeta, F, W = P.T
    T = 2 * np.pi / W
    # the values where each measurement applies, against the closed forms
    np.testing.assert_allclose(out["mu"][:3], np.exp(-zeta * w * T)[:3], rtol=1e-7)
    assert np.isnan(out["mu"][3:]).all() and np.isnan(out["mu_stable"][2])  # zeta >= 1; undecided
    np.testing.assert_allclose(out["amp_h1"][0], 1.0 / math.hypot(1 - 0.25, 0.2), rtol=1e-6)
    assert np.isnan(out["amp_h1"][[1, 2, 4]]).all()  # F < 0: amp does not apply
    assert out["amp_h1"][3] == 0.0  # F = 0 (from rest): amp applies, no motion (whatever mu's classify says)
    # x_hist keeps its values where amp is skipped (points 1, 2): the same as asked alone
    alone, st_alone, _ = _evaluate("SEVERITY", ("x_hist",))
    np.testing.assert_array_equal(out["x_hist"][:3], alone["x_hist"][:3])
    assert np.isfinite(out["x_hist"][:3]).all() and np.isnan(out["x_hist"][3:]).all()
    assert st_alone.tolist() == [st.OK, st.OK, st.OK, st.NOT_OSCILLATORY, st.NOT_OSCILLATORY]
    # a point with two problems gets the severer: SINGULAR (amp) over UNDECIDED (mu_stable) at
    # point 2, NOT_OSCILLATORY (mu, x_hist) over NO_MOTION (amp_exact) at point 3, SINGULAR over
    # NOT_OSCILLATORY at point 4
    assert status.tolist() == [st.OK, st.SINGULAR, st.SINGULAR, st.NOT_OSCILLATORY, st.SINGULAR]
    # without the order: the first failure in the kernel's order (closed forms, Floquet, sampled)
    out1, first, _ = _evaluate("FIRST", ALL)
    assert first.tolist() == [st.OK, st.SINGULAR, st.UNDECIDED, st.NO_MOTION, st.NOT_OSCILLATORY]
    for k in ALL:  # the values do not depend on the order
        np.testing.assert_array_equal(out1[k], out[k])


@pytest.mark.slow
def test_a_measurement_that_applies_nowhere_at_a_point_is_not_integrated_there():
    # x_hist alone at zeta = 2: skipped by its classify, no steps; the points it applies to integrate
    out, status, ns = _evaluate("SEVERITY", ("x_hist",))
    assert (ns[:3] > 0).all() and (ns[3:] == 0).all()
    # amp_h1 alone: asked-for outputs only: mu's NOT_OSCILLATORY does not count at point 4
    out, status, ns = _evaluate("SEVERITY", ("amp_h1",))
    assert status.tolist() == [st.OK, st.SINGULAR, st.SINGULAR, st.OK, st.SINGULAR]
    assert ns[3] > 0 and (ns[[1, 2, 4]] == 0).all()


def test_status_order_lists_status_codes():
    with pytest.raises(ValueError, match="status_order"):
        OdeModel(name="m", description="", params=(), states=("x",), rhs=lambda t, y, p, d: None,
                 initial=lambda p, y: None, status_order=(st.SINGULAR, 99))


@pytest.mark.slow  # two trajectory kernels (about 30 s cold)
def test_recheck_skips_points_locked_to_the_forcing_period():
    # zeta 0.3: the transient dies within the first half, the motion is T-periodic (locked); zeta
    # 0.002: it is still decaying at the end (not locked); neither settles (|x| stays above 1e-3)
    P = np.array([[1.0, 0.3, 1.0, 0.5], [1.0, 0.002, 1.0, 0.5]])
    ns = {}
    for name in ("LOCKED", "UNLOCKED"):
        out, status, ns[name] = _evaluate(name, ("kick",), P)
        assert status.tolist() == [st.UNDECIDED, st.UNDECIDED] and np.isnan(out["kick"]).all()  # neither verdict
    # LOCKED: the locked point is not integrated again (the test subtracts the phase's growth), the
    # other one is; UNLOCKED (no lock_rates): the phase grows by T each period, both are
    assert ns["UNLOCKED"][0] > 1.5 * ns["LOCKED"][0] and ns["UNLOCKED"][1] == ns["LOCKED"][1]
