"""Floquet with the model's own variational system about a known orbit (``Floquet(...,
variational=f, variational_jac=g)``): the engine integrates the n*n equations of Phi alone. On the
damped Mathieu equation (orbit x = 0, tests/user_models/mathieu.py) it gives the integrating route's
multipliers; a bad ``variational`` is refused with a clear error."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.errors import InputError
from mechsweep.scene import load_scene
from tests import evaluating

HERE = Path(__file__).resolve().parents[1]
MATHIEU_FILE = HERE / "user_models" / "mathieu.py"
FLOQUET = ("max_multiplier", "max_multiplier_stable", "max_multiplier_kind", "max_multiplier_angle")
# (a, q, c): unstable +1 and -1 (damped a little), inside the first region damped, q = 0 (closed form)
ROWS = np.array([(-0.5, 0.5, 0.05), (1.0, 1.0, 0.1), (3.0, 2.0, 0.0), (0.3, 0.5, 0.2), (2.0, 0.0, 0.2)])


def evaluate(name, P, method="dop853", rtol=1e-12, atol=1e-14):
    scene = load_scene({"scene": {"name": "t", "model": f"{MATHIEU_FILE}:{name}", "outputs": list(FLOQUET)},
                        "axes": {"a": {"start": 0.0, "stop": 1.0, "num": 2}}, "fixed": {"q": 1.0, "c": 0.0},
                        "solver": {"rtol": rtol, "atol": atol, "method": method}})
    return evaluating.evaluate(scene.model, P, FLOQUET, scene.solver)


def _same(a, b):
    np.testing.assert_allclose(a["max_multiplier"], b["max_multiplier"], rtol=1e-9)
    np.testing.assert_array_equal(a["max_multiplier_kind"], b["max_multiplier_kind"])
    np.testing.assert_array_equal(a["max_multiplier_stable"], b["max_multiplier_stable"])
    np.testing.assert_allclose(a["max_multiplier_angle"], b["max_multiplier_angle"], rtol=1e-9, atol=1e-12)


def test_variational_route_gives_the_integrating_routes_multipliers():
    var, s_var, ns_var, nr_var = evaluate("MATHIEU_VAR", ROWS)
    full, s_full, _, nr_full = evaluate("MATHIEU_JAC", ROWS)
    np.testing.assert_array_equal(s_var, s_full)
    assert s_var.tolist() == [st.OK, st.OK, st.UNDECIDED, st.OK, st.OK]  # undamped, stable: |mu| = 1
    _same(var, full)
    assert var["max_multiplier_kind"][:2].tolist() == [1.0, -1.0] and (var["max_multiplier"][:2] > 1.1).all()
    # q = 0: x'' + c x' + a x = 0, multipliers exp(pi (-c/2 +- i w)): modulus exp(-c pi / 2)
    assert var["max_multiplier"][4] == pytest.approx(math.exp(-0.2 * math.pi / 2), rel=1e-10)


@pytest.mark.slow
@pytest.mark.parametrize("model", ["MATHIEU_VAR", "MATHIEU_VAR_FD"])
def test_variational_route_by_radau_with_and_without_its_jacobian(model):
    """radau on the variational system, its Jacobian given or differentiated by the engine (exact up
    to round-off: the system is linear), against radau on the integrating route."""
    var, s_var, _, nr_var = evaluate(model, ROWS, "radau", rtol=1e-10, atol=1e-12)
    full, s_full, _, _ = evaluate("MATHIEU_JAC", ROWS, "radau", rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(s_var, s_full)
    np.testing.assert_allclose(var["max_multiplier"], full["max_multiplier"], rtol=1e-8)
    np.testing.assert_array_equal(var["max_multiplier_kind"], full["max_multiplier_kind"])
    if model == "MATHIEU_VAR_FD":  # each Jacobian costs 2 n*n = 8 further calls of variational
        given, _, _, nr_given = evaluate("MATHIEU_VAR", ROWS, "radau", rtol=1e-10, atol=1e-12)
        assert (nr_var > nr_given).all() and ((nr_var - nr_given) % 8 == 0).all()


HEAD = ("import math\nimport fractions\nfrom mechsweep.model import Floquet, OdeModel, Param\n\n\n"
        "def initial(p, y0):\n    y0[0] = 0.0\n    y0[1] = 0.0\n\n\n"
        "def rhs(t, y, p, dydt):\n    dydt[0] = y[1]\n    dydt[1] = -p[0] * y[0]\n\n\n"
        "def period(p):\n    return math.pi\n\n\n"
        "def var(t, Phi, p, dPhi):\n")  # line 19: the body under test
TAIL = ('\n\nM = OdeModel(name="v", description="d", params=(Param("a", "a", "1", "a"),), states=("x", "v"), '
        'rhs=rhs, initial=initial, forcing_period=period, measurements=(Floquet("mu", {floquet}),))\n')
GOOD = "    for c in range(2):\n        dPhi[2 * c] = Phi[2 * c + 1]\n        dPhi[2 * c + 1] = -p[0] * Phi[2 * c]"


@pytest.mark.parametrize("body, floquet, expected", [
    (GOOD, "variational=3", "mu: variational must be a function variational(t, Phi, p, dPhi)"),
    (GOOD, "variational_jac=var", "mu: variational_jac is the Jacobian of variational; give variational="),
    (GOOD, "variational=var, variational_jac='g'", "mu: variational_jac must be a function"),
    ("    dPhi[:] = float(fractions.Fraction(1, 2))", "variational=var", "numba cannot compile mu.variational"),
    ("    dPhi[4] = 0.0", "variational=var", "mu.variational indexes beyond its arrays"),
    ("    dPhi[0] = Phi[1]\n    dPhi[1] = -p[0] * Phi[0]", "variational=var",
     "mu.variational did not write dPhi[2] (it must write all 4 components"),
])
def test_a_bad_variational_is_refused_clearly(tmp_path, body, floquet, expected):
    path = tmp_path / "badvar.py"
    path.write_text(HEAD + body + TAIL.format(floquet=floquet))
    with pytest.raises(InputError) as info:
        load_scene({"scene": {"name": "t", "model": f"{path}:M", "outputs": ["mu"]},
                    "axes": {"a": {"start": 0.5, "stop": 1.0, "num": 2}}})
    assert expected in str(info.value) and str(path) in str(info.value), str(info.value)
