"""The model layer's second equations and refined measurements: a FirstEvent may integrate a
System of its own (rhs, initial, jac, prepare) instead of the model's, a FirstEvent's refine runs a
second pass at a tightened tolerance, and a ClosedForm's classify gives NaN and a status where the
formula does not apply. The built-in torsional circuit is declared with them
(tests/model/test_model_layer_builtin.py compares it bit for bit with the hand-written kernels)."""
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.model import user
from tests.evaluating import evaluate

USER = Path(__file__).resolve().parents[1] / "user_models" / "layer_systems.py"


def _evaluate(P, wanted, **solver):
    return evaluate(user.resolve(f"{USER}:SYSTEMS"), P, wanted, **solver)


# The two integrating tests compile two kernels each (~13 s cold on the shared 2-core machine): slow.
# The default run covers the same generated code through the built-in torsional circuit
# (tests/models/test_torsional_circuit.py: two Systems, and the refined pass near the hump at phi = 0).
@pytest.mark.slow
@pytest.mark.parametrize("method", ["dop853", "radau"])
def test_a_measurement_integrates_its_own_system_with_its_own_prepare(method):
    P = np.array([[1.0, 0.5, 1.0], [2.0, 0.3, 1.0], [6.0, 0.5, 1.0]])
    out, status, ns, _ = _evaluate(P, ("period", "half"), method=method, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(out["period"], 2 * np.pi / P[:, 0], rtol=1e-8)
    np.testing.assert_allclose(out["half"][:2], np.pi / P[:2, 0], rtol=1e-8)  # the System's equation
    # the System's prepare refuses w > 5: only its measurement is NaN, with that status
    assert np.isnan(out["half"][2]) and status.tolist() == [st.OK, st.OK, st.INFEASIBLE]
    _, _, ns_period, _ = _evaluate(P, ("period",), method=method, rtol=1e-10, atol=1e-12)
    assert (ns[:2] > ns_period[:2]).all() and ns[2] == ns_period[2]  # both integrations counted


@pytest.mark.slow
def test_refine_integrates_again_at_the_tightened_tolerance():
    # powers of two: rtol / factor is exact, the second pass's tolerance is that of a plain run
    P = np.array([[1.0, 0.5, 1.0], [1.0, 0.5, 2.0 ** 13], [1.0, 0.5, np.inf], [1.0, 0.5, 0.5]])
    out, status, ns, nr = _evaluate(P, ("refined", "period"), rtol=2.0 ** -20, atol=2.0 ** -30)
    first = ns[0] // 2  # "period" and "refined" take the same steps at factor <= 1
    assert out["refined"][0] == out["period"][0] and ns[0] == 2 * first and ns[3] == ns[0]
    # factor 2^13: a second pass at rtol 2^-33 from the start, both passes counted, much closer
    tight, _, ns_tight, _ = _evaluate(P[:1], ("refined",), rtol=2.0 ** -33, atol=2.0 ** -43)
    assert out["refined"][1] == tight["refined"][0]
    assert ns[1] == ns[0] + ns_tight[0]
    assert abs(out["refined"][1] - 2 * np.pi) < 1e-3 * abs(out["refined"][0] - 2 * np.pi)
    # not finite: ILL_CONDITIONED, no value; the other measurement keeps its value
    assert status.tolist() == [st.OK, st.OK, st.ILL_CONDITIONED, st.OK]
    assert np.isnan(out["refined"][2]) and out["period"][2] == out["period"][0]
    # no step budget left for the second pass: MAX_STEPS
    out, status, ns, _ = _evaluate(P[1:2], ("refined",), rtol=2.0 ** -20, atol=2.0 ** -30, max_steps=first)
    assert status[0] == st.MAX_STEPS and np.isnan(out["refined"][0]) and ns[0] == first


def test_a_closed_forms_classify_gives_nan_and_its_status():
    P = np.array([[1.0, 0.5, 1.0], [1.0, -0.25, 1.0]])
    out, status, _, _ = _evaluate(P, ("inverse",))
    assert out["inverse"][0] == 2.0 and np.isnan(out["inverse"][1])
    assert status.tolist() == [st.OK, st.NO_MOTION]
