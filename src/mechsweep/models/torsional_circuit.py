"""Spatial torsional oscillating circuit: rocking lever + out-of-plane spring -> Duffing equation.

Source: Klyuchkovskyi, "Synthesis of motion laws of the rocking link of spatial torsional
oscillating circuits"; formulas (4)-(7) as checked in ../shared/physics.md section 1.

Nondimensional form used by the kernels (s = S0 / R = s0_over_r, sigma = +1 tension,
-1 compression):
    D0    = 1 + lambda1^2 + lambda2^2 - 2 sigma lambda1          (= (L(0)/R)^2)
    chi   = omega^2 I / (R^2 c) = lambda1 s / sqrt(D0)                         (5), (7)
    xi    = mu I / (R^2 c) = lambda1 (3 lambda1 - s (D0 + 3 sigma lambda1) / sqrt(D0)) / (6 D0)  (4), (6)
    exact moment  M_b / (c R^2) = sigma lambda1 sin(phi) (1 - (sqrt(D0) - sigma s) / l(phi)),
                  l(phi)^2 = 1 + lambda1^2 + lambda2^2 - 2 sigma lambda1 cos(phi)     [beyond]
(D0 + 3 sigma lambda1 is the source's lambda2^2 + lambda1^2 + 1 +/- lambda1.)
Without R, c, I the time unit is sqrt(I / (R^2 c)); outputs with dimensional units need them.
"""
from __future__ import annotations

import math

import numpy as np

from .. import status as st
from .._jit import call_with_literal, jit, jit_noalloc, literally, pjit, prange
from ..ode import METHOD_CODES, dop853, radau, symplectic
from . import _duffing_scaled as duf
from . import duffing
from ._spec import ModelSpec, Output, Param

OUTPUTS = ("chi", "xi", "omega2", "mu", "hardness") + duf.OUTPUTS + ("period_exact_moment", "truncation_error")
K_CHI, K_XI, K_OMEGA2, K_MU, K_HARD = range(5)
OFF = 5  # Duffing outputs occupy columns OFF .. OFF + 7 in the same order as duffing.OUTPUTS
K_EXACT_MOMENT = OFF + len(duf.OUTPUTS)
K_TRUNC = K_EXACT_MOMENT + 1

SINGULAR_D0 = 1e-12  # (L(0)/R)^2 below this: spring of zero length at rest, formulas singular

BLOCK = 16


@jit
def spring_sign(spring_code):
    return 1.0 if spring_code == 0.0 else -1.0  # choices: 0 tension, 1 compression


@jit
def coefficients(sigma, lam1, lam2, s):
    """(status, chi, xi, D0). Formulas (4)-(7) in nondimensional form."""
    D0 = rest_length_squared(sigma, lam1, lam2)
    if D0 <= SINGULAR_D0:
        return st.SINGULAR, math.nan, math.nan, D0
    r = math.sqrt(D0)
    if r - sigma * s <= 0.0:
        return st.INFEASIBLE, math.nan, math.nan, D0  # free length L0 = R (sqrt(D0) - sigma s) <= 0
    chi = lam1 * s / r
    xi = lam1 * (3.0 * lam1 - s * (D0 + 3.0 * sigma * lam1) / r) / (6.0 * D0)
    return st.OK, chi, xi, D0


@jit_noalloc
def rest_length_squared(sigma, lam1, lam2):
    """D0 = (L(0)/R)^2 = 1 + lambda1^2 + lambda2^2 - 2 sigma lambda1, written as a sum of squares:
    the expanded form cancels as D0 -> 0 (lambda1 -> 1, lambda2 -> 0 with tension) and lost
    five digits of chi at D0 ~ 1e-12 (sweeps/extreme/torsional_d0_limit.toml)."""
    d = 1.0 - sigma * lam1
    return d * d + lam2 * lam2


@jit_noalloc
def spring_length(phi, sigma, lam1, D0):
    """l(phi) = L(phi)/R: l^2 = 1 + lambda1^2 + lambda2^2 - 2 sigma lambda1 cos(phi)
    = D0 + 4 sigma lambda1 sin^2(phi / 2), the second form free of cancellation near phi = 0."""
    h = math.sin(0.5 * phi)
    return math.sqrt(D0 + 4.0 * sigma * lam1 * h * h)


@jit_noalloc
def exact_moment(phi, sigma, lam1, D0, L0):
    """M_b / (c R^2) from the spring energy; D0 = rest_length_squared, L0 = free length / R."""
    return sigma * lam1 * math.sin(phi) * (1.0 - L0 / spring_length(phi, sigma, lam1, D0))


@jit
def _exact_rhs(t, y, p, dydt):
    # x = phi / A, tau = w t:  x'' = -coef * m(A x);  p = (sigma, lambda1, D0, L0, A, coef)
    dydt[0] = y[1]
    dydt[1] = -p[5] * exact_moment(p[4] * y[0], p[0], p[1], p[2], p[3])


@jit
def _phi_event(t, y, p):
    # p[6] = level of phi = 0 in the scaled coordinate, p[7] = +1 (y falls to it) or -1 (y rises to it)
    return p[7] * (y[0] - p[6])


@jit_noalloc
def exact_moment_slope(phi, sigma, lam1, D0, L0):
    """d/dphi of exact_moment: sigma lam1 (cos phi (1 - L0 / l) + sigma lam1 L0 sin^2 phi / l^3)."""
    length = spring_length(phi, sigma, lam1, D0)
    sin_phi = math.sin(phi)
    return sigma * lam1 * (math.cos(phi) * (1.0 - L0 / length)
                           + sigma * lam1 * L0 * sin_phi * sin_phi / (length * length * length))


@jit_noalloc
def _exact_jac(t, y, p, J):
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    J[1, 0] = -p[5] * p[4] * exact_moment_slope(p[4] * y[0], p[0], p[1], p[2], p[3])
    J[1, 1] = 0.0


@jit_noalloc
def _exact_accel(t, q, p, a):
    a[0] = -p[5] * exact_moment(p[4] * q[0], p[0], p[1], p[2], p[3])


@jit_noalloc
def _q_event(t, q, v, p):
    return p[7] * (q[0] - p[6])


exact_quarter_period_solver = dop853.make_event_solver(_exact_rhs, _phi_event)
exact_quarter_period_stiffness_test = dop853.make_event_solver(_exact_rhs, _phi_event, stiffness_test=True)
exact_quarter_period_radau = radau.make_event_solver(_exact_rhs, _exact_jac, _phi_event)
exact_quarter_period_symplectic = symplectic.make_event_solver(_exact_accel, _q_event, duf.SYMPLECTIC_ORDER)


# as duffing.quarter_period, for the exact spring moment
exact_quarter_period = duf.make_quarter_period(
    "exact_quarter_period", exact_quarter_period_solver, exact_quarter_period_stiffness_test,
    exact_quarter_period_radau, exact_quarter_period_symplectic)


N_P = 8  # parameters of the scaled exact-moment equation: (sigma', lambda1, D, L0, scale, coef, level, direction)
PI_LO = 1.2246467991473532e-16  # pi - math.pi: pi = math.pi + PI_LO to twice double precision
# Tightened tolerances below this are not tried: the point is ILL_CONDITIONED (as the old Duffing floor)
RTOL_FLOOR = 5e-14


@jit_noalloc
def integrate_exact_period(method, sigma, lam1, lam2, s, k, chi, xi, A, rtol, atol, max_steps, t_max_periods, y, p,
                           work, rwork, swork, q, v):
    """Period with the exact spring moment (k = R^2 c / I). Returns (status, T, n_steps, n_rhs).

    Whether the lever oscillates about phi = 0 is decided by the exact moment's potential alone
    (exact_classify), never by the two-term model: the cubic's soft separatrix is an artefact of
    the truncation (a stretched tension spring, for instance, always brings the lever back).

    The potential V = (l - L0)^2 / 2 has its humps at phi = pi (where the spring is stretched, or
    compressed, beyond its free length there) and, when chi < 0, at phi = 0; near them the period
    diverges logarithmically and, as for the Duffing separatrix, errors are amplified:
    - released near the top (A > pi / 2): integrated in theta = pi - phi, theta(0) = (pi - A)
      formed to twice double precision, so that the tolerance is relative to the distance from the
      top (in phi / A the error grew as pi - A shrank: 4e5 rtol at pi - A = 1e-8, measured);
      what is left is the sensitivity to A itself, d ln T / d ln A = 4 A / (lambda_pi (pi - A) T);
    - swinging over the hump at 0 with a small energy excess dE = V(A) - V(0): the energy error of
      the integration (of order rtol V(A)) is amplified by at most V(A) |d T / d E| / T, which is
      2 V(A) / (lambda_0 T dE) for dE -> 0, so the tolerance is tightened by that bound
      and a second pass is run (untightened: 5e4 rtol at A / A* - 1 = 1e-8; tightened: within
      0.33 rtol from 1e-1 to 1e-8, measured against quadrature); where the tightened
      tolerance would be below RTOL_FLOOR, or the inputs' round-off alone moves T by more than rtol
      (condition number with respect to A, lambda1, lambda2, s0_over_r times round-off), the point is
      ILL_CONDITIONED."""
    D0 = rest_length_squared(sigma, lam1, lam2)
    L0 = math.sqrt(D0) - sigma * s
    code = exact_classify(sigma, lam1, D0, L0, A)
    if code != st.OK:
        return code, math.nan, 0, 0
    # time scale of the scaled equation: as the two-term model's, with |chi| (chi < 0 is allowed
    # here: the lever may swing over the hump at phi = 0); |chi| + |xi| A^2 > 0 for every feasible A > 0
    w2 = k * (abs(chi) + abs(xi) * A * A)
    p[1] = lam1
    p[3] = L0
    top = A > 0.5 * math.pi
    theta0 = (math.pi - A) + PI_LO  # pi - A; math.pi - A is exact for A >= pi / 2 (Sterbenz)
    if top:
        # theta'' = -k m(theta; -sigma, D_pi): the same moment with sigma -> -sigma, D0 -> D_pi
        d = 1.0 + sigma * lam1
        p[0] = -sigma
        p[2] = d * d + lam2 * lam2
        p[4] = theta0
        p[5] = k / (w2 * theta0)
        p[6] = math.pi / theta0
        p[7] = -1.0
    else:
        p[0] = sigma
        p[2] = D0
        p[4] = A
        p[5] = k / (w2 * A)
        p[6] = 0.0
        p[7] = 1.0
    t_max = t_max_periods * 2.0 * math.pi
    y[0] = 1.0
    y[1] = 0.0
    # NO_EVENT now means the lever does come back, later than the horizon: raise t_max_periods
    code, tau_q, ns, nr = exact_quarter_period(method, y, p, t_max, rtol, atol, max_steps, work, rwork, swork, q, v)
    if code != st.OK:
        return code, math.nan, ns, nr
    T = 4.0 * tau_q / math.sqrt(w2)
    # sensitivity to the inputs near either hump, and the integration's amplification at the hump at 0
    lam_pi2 = k * sigma * lam1 * (1.0 - L0 / spring_length(math.pi, sigma, lam1, D0))
    kappa = 0.0
    if lam_pi2 > 0.0:  # phi = pi is a hump of V
        kappa = 4.0 * A / (math.sqrt(lam_pi2) * theta0 * T)
    amp = 1.0
    if chi < 0.0:  # phi = 0 is a hump of V
        lam0 = math.sqrt(-k * chi)
        lA = spring_length(A, sigma, lam1, D0)
        r = math.sqrt(D0)
        sA = math.sin(0.5 * A)
        dl = 4.0 * sigma * lam1 * sA * sA / (lA + r)  # l(A) - l(0), no cancellation
        F = dl + 2.0 * sigma * s  # l(A) + l(0) - 2 L0 (the lever passes 0 iff F dl > 0)
        dE = 0.5 * dl * F  # V(A) - V(0) > 0
        # |d T / d E| / T from the time spent over the hump, t = asinh(lam0 phi_w / sqrt(2 k dE)) / lam0
        # (4 such crossings per period), phi_w = the well's bottom, l(phi_w) = L0: 2 / (lam0 dE) for
        # dE -> 0, the ballistic value for a vanishing hump (lam0 -> 0, s0_over_r -> 0-)
        h = (L0 * L0 - D0) / (4.0 * sigma * lam1)  # sin^2(phi_w / 2)
        phi_w = 2.0 * math.asin(math.sqrt(h)) if 0.0 < h < 1.0 else A
        phi_w = min(phi_w, A)
        gain = 2.0 * phi_w / (T * dE * math.sqrt(2.0 * k * dE + lam0 * lam0 * phi_w * phi_w))
        vA = lA - L0
        amp = max(1.0, gain * 0.5 * vA * vA)  # relative energy error rtol V(A) -> relative period error
        # d F / d ln p for p = A, lambda1, lambda2, s0_over_r
        dD1 = -2.0 * sigma * (1.0 - sigma * lam1)
        sens = (abs(A * sigma * lam1 * math.sin(A) / lA)
                + abs(lam1 * ((dD1 + 4.0 * sigma * sA * sA) / (2.0 * lA) - dD1 / (2.0 * r)))
                + abs(lam2 * (lam2 / lA - lam2 / r)) + abs(2.0 * s))
        kappa = max(kappa, gain * abs(dE) * sens / abs(F))
    if not kappa * duf.UNIT_ROUNDOFF <= rtol:  # NaN-safe
        return st.ILL_CONDITIONED, math.nan, ns, nr
    if not amp <= 1.0:
        if not rtol / amp >= RTOL_FLOOR:
            return st.ILL_CONDITIONED, math.nan, ns, nr
        if ns >= max_steps:
            return st.MAX_STEPS, math.nan, ns, nr
        y[0] = 1.0
        y[1] = 0.0
        # the second pass gets what is left of the step budget: one output, one budget
        code, tau_q, ns2, nr2 = exact_quarter_period(method, y, p, t_max, rtol / amp, atol / amp, max_steps - ns,
                                                     work, rwork, swork, q, v)
        ns += ns2
        nr += nr2
        if code != st.OK:
            return code, math.nan, ns, nr
        T = 4.0 * tau_q / math.sqrt(w2)
    return st.OK, T, ns, nr


@jit_noalloc
def exact_classify(sigma, lam1, D0, L0, A):
    """Status of the exact-moment motion released at rest from phi = A: NO_MOTION for A = 0,
    NOT_OSCILLATORY unless the lever passes through phi = 0 (_returns_through_zero), else OK.
    The two-term model's classification plays no part."""
    if A == 0.0:
        return st.NO_MOTION
    if not _returns_through_zero(sigma, lam1, D0, L0, A):
        return st.NOT_OSCILLATORY
    return st.OK


@jit_noalloc
def _returns_through_zero(sigma, lam1, D0, L0, A):
    """Energy: released at rest from A, the lever reaches phi = 0 iff the spring energy there is
    lower than at A, (l(0) - L0)^2 < (l(A) - L0)^2; l is monotonic on [0, pi] and the energy
    (l - L0)^2 / 2 is convex in l, so on [0, A] it is highest at an end and has no other hump in
    between. Then, the moment being odd, the motion is symmetric and swings to -A: an oscillation
    about phi = 0 whatever the two-term model says. Otherwise the lever stays in a well away from 0
    (or creeps to 0 forever)."""
    return abs(math.sqrt(D0) - L0) < abs(spring_length(A, sigma, lam1, D0) - L0)


@jit
def _point_coefficients(P, i):
    """(status, sigma, lam1, lam2, s, k, chi, xi, A) of row i; k = R^2 c / I."""
    sigma = spring_sign(P[i, 0])
    lam1, lam2, s = P[i, 1], P[i, 2], P[i, 3]
    k = P[i, 4] * P[i, 4] * P[i, 5] / P[i, 6]
    code, chi, xi, _ = coefficients(sigma, lam1, lam2, s)
    return code, sigma, lam1, lam2, s, k, chi, xi, P[i, 7]


@pjit
def algebraic_kernel(P, want, want_duffing, table, status):
    for i in prange(P.shape[0]):
        code, sigma, lam1, lam2, s, k, chi, xi, A = _point_coefficients(P, i)
        if code != st.OK:
            status[i] = code
            continue
        row = table[i]
        row[K_CHI] = chi
        row[K_XI] = xi
        if want[K_OMEGA2]:
            row[K_OMEGA2] = k * chi
        if want[K_MU]:
            row[K_MU] = k * xi
        if want[K_HARD]:
            row[K_HARD] = 1.0 if xi > 0.0 else (-1.0 if xi < 0.0 else 0.0)
        if want_duffing:
            code = duf.classify(k * chi, k * xi, A)
            if code != st.OK:
                status[i] = code
                continue
            duf.fill_closed_forms(k * chi, k * xi, A, want[OFF:K_EXACT_MOMENT], row[OFF:K_EXACT_MOMENT])


@jit_noalloc
def cubic_sensitivities(sigma, lam1, lam2, s, D0):
    """(k_omega2, k_q) of duffing.period_condition for this model's inputs: the sums over
    lambda1, lambda2, s0_over_r (and A for mu A^2) of |d ln chi / d ln p| and |d ln xi / d ln p|,
    from the formulas (4)-(7) differentiated by hand. R, c, I scale omega^2 and mu alike (time
    scale only): they move ln T by exactly -1/2 d ln(R^2 c / I) and are left out."""
    r = math.sqrt(D0)
    dD1 = -2.0 * sigma * (1.0 - sigma * lam1)  # d D0 / d lambda1
    dD2 = 2.0 * lam2  # d D0 / d lambda2
    k_omega2 = abs(1.0 - 0.5 * lam1 * dD1 / D0) + 0.5 * lam2 * abs(dD2) / D0 + 1.0
    G = D0 + 3.0 * sigma * lam1
    B = 3.0 * lam1 - s * G / r  # xi = lambda1 B / (6 D0)
    dGr = (D0 - 3.0 * sigma * lam1) / (2.0 * r * D0)  # d (G / r) / d D0
    dB1 = 3.0 - s * (dGr * dD1 + 3.0 * sigma / r)
    dB2 = -s * dGr * dD2
    k_q = (abs(1.0 + lam1 * (dB1 / B - dD1 / D0)) + abs(lam2 * (dB2 / B - dD2 / D0)) + abs(s * G / (r * B))
           + 2.0)
    return k_omega2, k_q


@pjit
def integrated_kernel(method, P, want_period, want_exact, rtol, atol, max_steps, t_max_periods, table, status, n_steps,
                      n_rhs):
    """The two-term period (want_period) and the exact-moment period (want_exact) of each point.
    Each is decided by its own model: a point whose two-term model is past its separatrix still gets
    period_exact_moment when the exact moment oscillates (its status stays not_oscillatory, which
    the algebraic stage or the two-term classification set, because the two-term outputs are NaN)."""
    literally(method)  # one cached kernel per method
    n = P.shape[0]
    n_blocks = (n + BLOCK - 1) // BLOCK
    for b in prange(n_blocks):
        work, rwork, swork, y, _, q, v = duf.workspaces()
        p = np.empty(N_P)
        for i in range(b, n, n_blocks):  # strided: prange splits blocks statically, and cost varies along the grid
            code, sigma, lam1, lam2, s, k, chi, xi, A = _point_coefficients(P, i)
            if code != st.OK:
                status[i] = code  # no coefficients, no motion of either model
                continue
            final = status[i]  # the algebraic stage's verdict on the two-term outputs (or OK)
            if want_period:
                code = duf.classify(k * chi, k * xi, A)
                if code == st.OK:
                    k_omega2, k_q = cubic_sensitivities(sigma, lam1, lam2, s, rest_length_squared(sigma, lam1, lam2))
                    code, T, ns, nr = duf.integrate_period(
                        method, k * chi, k * xi, A, rtol, atol, max_steps, t_max_periods, y, p, work, rwork, swork,
                        q, v, k_omega2, k_q,
                    )
                    n_steps[i] += ns
                    n_rhs[i] += nr
                    table[i, OFF + duf.K_PERIOD] = T
                if final == st.OK:
                    final = code
            if want_exact:
                code, T, ns, nr = integrate_exact_period(
                    method, sigma, lam1, lam2, s, k, chi, xi, A, rtol, atol, max_steps, t_max_periods, y, p, work,
                    rwork, swork, q, v,
                )
                n_steps[i] += ns
                n_rhs[i] += nr
                table[i, K_EXACT_MOMENT] = T
                if final == st.OK:
                    final = code
            status[i] = final


def evaluate(P, wanted, solver, out, status, n_steps, n_rhs):
    table = np.full((P.shape[0], len(OUTPUTS)), np.nan)
    want = np.array([name in wanted for name in OUTPUTS])
    want_duffing_closed = bool(want[OFF:K_EXACT_MOMENT].any())
    # chi, xi are the base of everything: the algebraic stage always runs (it is cheap).
    algebraic_kernel(P, want, want_duffing_closed, table, status)
    want_period = bool(want[OFF + duf.K_PERIOD])
    want_exact = bool(want[K_EXACT_MOMENT])
    if want_period or want_exact:
        call_with_literal(
            integrated_kernel, METHOD_CODES[solver.method], P, want_period, want_exact, solver.rtol, solver.atol,
            solver.max_steps, solver.settings["t_max_periods"], table, status, n_steps, n_rhs,
        )
    if want[OFF + duf.K_PERIOD_ERROR]:
        table[:, OFF + duf.K_PERIOD_ERROR] = duf.relative_error(
            table[:, OFF + duf.K_PERIOD], table[:, OFF + duf.K_PERIOD_EXACT]
        )
    if want[K_TRUNC]:
        table[:, K_TRUNC] = duf.relative_error(table[:, OFF + duf.K_PERIOD_EXACT], table[:, K_EXACT_MOMENT])
    for name in wanted:
        out[name][:] = table[:, OUTPUTS.index(name)]


_DIMENSIONAL = ("R", "c", "I")


def _duffing_output(o: Output) -> Output:
    """Re-declare a Duffing output for this model: needs A, and R, c, I when it has a unit."""
    needs_params = ("A",) + (_DIMENSIONAL if o.unit != "1" else ())
    return Output(o.name, o.symbol, o.unit, o.long_name, o.integrated, o.needs, needs_params)


SPEC = ModelSpec(
    name="torsional_circuit",
    description="Rocking lever with an out-of-plane spring: Duffing coefficients, nomograms, amplitude-period",
    source="Klyuchkovskyi, torsional oscillating circuits, formulas (4)-(7); physics.md section 1",
    params=(
        Param("spring", "", "", "spring kind", choices=("tension", "compression")),
        Param("lambda1", "λ1", "1", "frame point offset in the lever plane / R", lo=0.0, lo_open=True),
        Param("lambda2", "λ2", "1", "frame point offset along the axis / R", lo=0.0),
        Param("s0_over_r", "S0/R", "1", "mounting deformation of the spring / R"),
        Param("R", "R", "m", "lever radius of the spring attachment", lo=0.0, lo_open=True,
              required=False, default=1.0),
        Param("c", "c", "N/m", "spring stiffness", lo=0.0, lo_open=True, required=False, default=1.0),
        Param("I", "I", "kg m^2", "moment of inertia of the lever", lo=0.0, lo_open=True,
              required=False, default=1.0),
        Param("A", "A", "rad", "amplitude, phi(0) = A, phi'(0) = 0", lo=0.0, hi=math.pi,
              required=False, default=math.nan),
    ),
    outputs=(
        Output("chi", "χ = ω² I / (R² c)", "1", "linear stiffness coefficient chi"),
        Output("xi", "ξ = μ I / (R² c)", "1", "cubic stiffness coefficient xi"),
        Output("omega2", "ω²", "1/s^2", "squared linear natural frequency", needs_params=_DIMENSIONAL),
        Output("mu", "μ", "1/(rad^2 s^2)", "cubic stiffness coefficient mu", needs_params=_DIMENSIONAL),
        Output("hardness", "sign ξ", "1", "characteristic: +1 hard, 0 linear, -1 soft"),
    )
    + tuple(_duffing_output(o) for o in duffing.SPEC.outputs)
    + (
        Output("period_exact_moment", "T_M", "s", "period with the exact spring moment",
               integrated=True, needs_params=("A",) + _DIMENSIONAL),
        Output("truncation_error", "|T_exact - T_M| / T_M", "1",
               "relative period error of the two-term (Duffing) model against the exact moment",
               needs=("period_exact", "period_exact_moment"), needs_params=("A",)),
    ),
    evaluate=evaluate,
    settings=(duf.T_MAX_PERIODS,),
    methods=duffing.SPEC.methods,
    statuses=(st.INFEASIBLE, st.SINGULAR, st.NOT_OSCILLATORY, st.NO_MOTION, *st.INTEGRATION_FAILURES),
    status_notes={
        st.INFEASIBLE: "spring free length <= 0, or omega^2 <= 0 for the two-term outputs",
        st.SINGULAR: "D0 = (L(0)/R)^2 <= 1e-12: a spring of zero length at rest",
        st.NOT_OSCILLATORY: "the two-term model at or beyond its soft separatrix, or the exact spring moment never "
                            "brings the lever back through phi = 0 (period_exact_moment is still given when only "
                            "the two-term model fails)",
        st.NO_MOTION: "A = 0: no motion, ratios to A undefined",
        st.ILL_CONDITIONED: "the two-term period next to its separatrix, or the exact-moment period next to a hump "
                            "of the spring's potential",
    },
)
