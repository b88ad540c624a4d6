"""A measured experiment, not the model: the auto-balancer's closed-form outputs (theta, balanceable,
m_k, omega_p, stable_first_approx, P_approx, stable_damped_approx) declared as the layer's
``ClosedForm``s with their ``classify`` (theta: NOT_BALANCEABLE without a balanced state; P_approx:
SINGULAR at an undamped resonance) and the model's ``classify`` (INFEASIBLE), the formulas written
per point as in models/autobalancer.py (there vectorised), against the hand-written model's
reference values (tests/data/autobalancer_reference.npz, every point of the design grid):
``python tests/data/autobalancer_closed_on_layer.py``. What it shows is in docs/model-layer.md.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numba
import numpy as np

from mechsweep import status as st
from mechsweep.model import ClosedForm, OdeModel
from mechsweep.models import autobalancer as ab

IX = {name: j for j, name in enumerate(ab.PARAM_NAMES)}
I_Omega, I_M, I_m, I_a, I_IB, I_A0 = (IX[k] for k in ("Omega", "M", "m", "a", "I_B", "A0"))
I_omega_xi, I_c_xi, I_b_xi, I_zeta_xi = (IX[k] for k in ("omega_xi", "c_xi", "b_xi", "zeta_xi"))
I_omega_eta, I_c_eta, I_b_eta, I_zeta_eta = (IX[k] for k in ("omega_eta", "c_eta", "b_eta", "zeta_eta"))
I_A1, I_l3, I_l4, I_m4, I_S4, I_m5, I_S_k = (IX[k] for k in ("A1", "l3", "l4", "m4", "S4", "m5", "S_k"))
IB_SLACK = ab.IB_SLACK


@numba.njit
def _axis(om, c, b, zeta, M):
    """(omega, c, b) of one platform axis from either parametrisation (autobalancer.platform)."""
    if math.isnan(om):
        om = math.sqrt(c / M)
    if math.isnan(c):
        c = M * om * om
    if math.isnan(b):
        b = 2.0 * zeta * M * om
    return om, c, b


@numba.njit
def _xi(p):
    return _axis(p[I_omega_xi], p[I_c_xi], p[I_b_xi], p[I_zeta_xi], p[I_M])


@numba.njit
def _eta(p):
    return _axis(p[I_omega_eta], p[I_c_eta], p[I_b_eta], p[I_zeta_eta], p[I_M])


def classify(p):
    """INFEASIBLE outside the physical domain (autobalancer.evaluate's ``feasible``)."""
    M, m, a, IB, A1, l3, l4 = p[I_M], p[I_m], p[I_a], p[I_IB], p[I_A1], p[I_l3], p[I_l4]
    wx, cx, bx = _xi(p)
    wy, cy, by = _eta(p)
    lengths = not math.isnan(l3) and not math.isnan(l4)
    ok = IB >= m * a * a * (1.0 - IB_SLACK) and M > 2.0 * m
    ok = ok and math.isfinite(wx) and math.isfinite(wy) and math.isfinite(bx) and math.isfinite(by)
    ok = ok and (not lengths or l3 < l4) and (A1 == 0.0 or lengths)
    return st.OK if ok else st.INFEASIBLE


def theta(p):
    two_ma = 2.0 * p[I_m] * p[I_a]
    return math.acos(min(1.0, max(-1.0, -p[I_A0] / two_ma)))  # eq. (8); has a balance: A0 <= 2 m a


def theta_classify(p):
    return st.OK if p[I_A0] <= 2.0 * p[I_m] * p[I_a] and p[I_A1] == 0.0 else st.NOT_BALANCEABLE


def balanceable(p):
    return 1.0 if p[I_A0] <= 2.0 * p[I_m] * p[I_a] and p[I_A1] == 0.0 else 0.0


def m_k(p):  # eq. (6)
    return (p[I_m4] * p[I_S4] + p[I_m5] * p[I_l4]) / p[I_S_k]


def omega_p(p):
    wx = _xi(p)[0]
    wy = _eta(p)[0]
    return math.sqrt(0.5 * (wx * wx + wy * wy))


def stable_first_approx(p):
    wx = _xi(p)[0]
    wy = _eta(p)[0]
    Om = p[I_Omega]
    lo, hi = min(wx, wy), max(wx, wy)
    wp = math.sqrt(0.5 * (wx * wx + wy * wy))
    return 1.0 if (lo < Om and Om < wp) or Om > hi else 0.0


@numba.njit
def _receptance(p):
    """P(Omega) = Re(H_xi + H_eta) (autobalancer.receptance_sum)."""
    Om, M = p[I_Omega], p[I_M]
    _, cx, bx = _xi(p)
    _, cy, by = _eta(p)
    total = 0.0
    d = cx - M * Om ** 2
    total = total + _div(d, d * d + (bx * Om) ** 2)
    d = cy - M * Om ** 2
    total = total + _div(d, d * d + (by * Om) ** 2)
    return total


@numba.njit
def _div(x, y):
    """x / y with IEEE results for y = 0 (numpy's: +-inf, or NaN for 0 / 0); numba raises there."""
    if y != 0.0:
        return x / y
    if x == 0.0 or math.isnan(x):
        return math.nan
    return math.copysign(math.inf, x) * math.copysign(1.0, y)


def P_approx(p):
    return _receptance(p)


def P_classify(p):
    return st.OK if math.isfinite(_receptance(p)) else st.SINGULAR


def stable_damped_approx(p, P):
    if math.isnan(P):
        return math.nan
    return 1.0 if P < 0.0 else 0.0


def _rhs(t, y, p, dydt):  # no measurement integrates: the closed forms only
    dydt[0] = 0.0


def _initial(p, y0):
    y0[0] = 0.0


MODEL = OdeModel(
    name="autobalancer_closed_layer", description="the auto-balancer's closed forms on the layer (experiment)",
    params=ab.SPEC.params, states=("z",), rhs=_rhs, initial=_initial, classify=classify,
    closed_forms=(
        ClosedForm("theta", theta, classify=theta_classify),
        ClosedForm("balanceable", balanceable),
        ClosedForm("m_k", m_k),
        ClosedForm("omega_p", omega_p),
        ClosedForm("stable_first_approx", stable_first_approx),
        ClosedForm("P_approx", P_approx, classify=P_classify),
        ClosedForm("stable_damped_approx", stable_damped_approx, needs=("P_approx",)),
    ))

NAMES = ("theta", "balanceable", "m_k", "omega_p", "stable_first_approx", "P_approx", "stable_damped_approx")


def compare():
    """{output: (bitwise equal points incl. NaN, points)} on every point of the design grid, each
    output asked for alone, against the reference run with every output; and "status": for each
    output alone, the points whose status is INFEASIBLE / NOT_BALANCEABLE / SINGULAR on the layer
    against where the reference's values say it must be (list of mismatching point counts)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import record_autobalancer as rec
    from mechsweep.model import load
    from mechsweep.scene import Solver

    spec = load.resolve(f"{Path(__file__).resolve()}:MODEL")
    ref = np.load(rec.FILE)
    P = rec.design_points()
    n = P.shape[0]
    slv = Solver.for_model(spec, rtol=1e-8, atol=1e-10)
    result = {}
    for name in NAMES:
        out = {k: np.full(n, np.nan) for k in spec.output(name).needs + (name,)}
        status, ns, nr = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
        wanted = tuple(out)
        with np.errstate(all="ignore"):
            spec.evaluate(P, wanted, slv, out, status, ns, nr)
        e = ref[f"grid-dop853-all/{name}"]
        same = np.array([np.array_equal(a, b, equal_nan=True) for a, b in zip(out[name], e)])
        # the hand-written model asked for the same outputs: its statuses
        old = {k: np.full(n, np.nan) for k in wanted}
        ostatus = np.zeros(n, np.int8)
        with np.errstate(all="ignore"):
            ab.SPEC.evaluate(P, wanted, Solver.for_model(ab.SPEC, rtol=1e-8, atol=1e-10), old, ostatus,
                             np.zeros(n, np.int64), np.zeros(n, np.int64))
        result[name] = (int(same.sum()), n, status, int((status == ostatus).sum()))
    return result


def main():
    for name, (same, n, status, same_status) in compare().items():
        codes = {int(c): int((status == c).sum()) for c in np.unique(status)}
        print(f"{name:22s}: bitwise {same}/{n}; status as the hand-written model's at {same_status}/{n}; "
              f"statuses {codes}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
