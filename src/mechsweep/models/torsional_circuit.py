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

Declared on the model layer (mechsweep.model): two equations are integrated per point, each by a
FirstEvent with its own System (rhs, initial state, prepare): the two-term (Duffing) equation for
`period` and the exact spring moment for `period_exact_moment`; the latter's `refine` runs a second
pass at a tightened tolerance next to the hump of the potential at phi = 0. The Duffing closed forms
are ClosedForms whose `classify` is the two-term model's. No chunk loop, no method switch.
"""
from __future__ import annotations

import math

from .. import status as st
from .._jit import jit, jit_noalloc
from ..model.measure import ClosedForm, FirstEvent, System
from ..model.ode import OdeModel
from ..model.workprecision import WorkPrecision
from . import duffing
from ..model.spec import Param

SINGULAR_D0 = 1e-12  # (L(0)/R)^2 below this: spring of zero length at rest, formulas singular


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


@jit_noalloc
def exact_moment_slope(phi, sigma, lam1, D0, L0):
    """d/dphi of exact_moment: sigma lam1 (cos phi (1 - L0 / l) + sigma lam1 L0 sin^2 phi / l^3)."""
    length = spring_length(phi, sigma, lam1, D0)
    sin_phi = math.sin(phi)
    return sigma * lam1 * (math.cos(phi) * (1.0 - L0 / length)
                           + sigma * lam1 * L0 * sin_phi * sin_phi / (length * length * length))


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



# --------------------------------------------------------------------------- the declaration
# p = (spring, lambda1, lambda2, s0_over_r, R, c, I, A | t_max_periods | internal slots).
# Internal slots: the two-term system's (a, b, c, level, direction, w) as duffing's, then the exact
# system's (sigma', lambda1, D, L0, scale, coef, level, direction, w2). Each system's prepare writes
# its own slots just before its measurement.
SPRING, LAM1, LAM2, S0R, RR, CC, II, AMP, T_MAX = range(9)
IA, IB, IC, ILEVEL, IDIR, IW = range(9, 15)
ES, EL1, ED, EL0, ESCALE, ECOEF, ELEVEL, EDIR, EW2 = range(15, 24)
PI_LO = 1.2246467991473532e-16  # pi - math.pi: pi = math.pi + PI_LO to twice double precision
# Tightened tolerances below this are not tried: the point is ILL_CONDITIONED (as the old Duffing floor)
RTOL_FLOOR = 5e-14


@jit
def point_coefficients(p):
    """(status, sigma, lam1, lam2, s, k, chi, xi, A) of a point; k = R^2 c / I."""
    sigma = spring_sign(p[SPRING])
    lam1, lam2, s = p[LAM1], p[LAM2], p[S0R]
    k = p[RR] * p[RR] * p[CC] / p[II]
    code, chi, xi, _ = coefficients(sigma, lam1, lam2, s)
    return code, sigma, lam1, lam2, s, k, chi, xi, p[AMP]


def model_classify(p):
    """SINGULAR or INFEASIBLE where formulas (4)-(7) give no coefficients: every output NaN."""
    return point_coefficients(p)[0]


def two_term_classify(p):
    """The two-term (Duffing) model's status (duffing.classify of omega^2 = k chi, mu = k xi)."""
    _, _, _, _, _, k, chi, xi, A = point_coefficients(p)
    return duffing.classify(k * chi, k * xi, A)


# ---- closed forms: the coefficients, and the Duffing closed forms of the two-term model
def chi_of(p):
    return point_coefficients(p)[6]


def xi_of(p):
    return point_coefficients(p)[7]


def omega2_of(p):
    _, _, _, _, _, k, chi, xi, A = point_coefficients(p)
    return k * chi


def mu_of(p):
    _, _, _, _, _, k, chi, xi, A = point_coefficients(p)
    return k * xi


def hardness_of(p):
    xi = point_coefficients(p)[7]
    return 1.0 if xi > 0.0 else (-1.0 if xi < 0.0 else 0.0)


def period_exact(p):
    _, _, _, _, _, k, chi, xi, A = point_coefficients(p)
    return duffing.period_closed_form(k * chi, k * xi, A)


def v_max(p):
    _, _, _, _, _, k, chi, xi, A = point_coefficients(p)
    return duffing.v_max_closed_form(k * chi, k * xi, A)


def a_max(p):
    _, _, _, _, _, k, chi, xi, A = point_coefficients(p)
    return duffing.a_max_closed_form(k * chi, k * xi, A)


def kv(p, vmax, T):
    return vmax * T / p[AMP]  # 2 pi for the linear oscillator


def ka(p, amax, T):
    return amax * T * T / p[AMP]  # 4 pi^2 for the linear oscillator


def epsilon(p):
    _, _, _, _, _, k, chi, xi, A = point_coefficients(p)
    mu = k * xi
    return mu * A * A / (k * chi)


def relative_error(p, value, reference):
    return abs(value - reference) / abs(reference)


# ---- the two-term system: duffing's scaled equation (plain or saddle formulation) in slots IA..IW
def two_term_prepare(p, rtol):
    """The two-term model's status, then, as duffing.prepare, ILL_CONDITIONED where the period's
    condition number (with this model's sensitivities, cubic_sensitivities) times round-off exceeds
    rtol; else the scaled equation's coefficients, the event and w."""
    _, sigma, lam1, lam2, s, k, chi, xi, A = point_coefficients(p)
    omega2 = k * chi
    mu = k * xi
    code = duffing.classify(omega2, mu, A)
    if code != st.OK:
        return code
    k_omega2, k_q = cubic_sensitivities(sigma, lam1, lam2, s, rest_length_squared(sigma, lam1, lam2))
    if not duffing.period_condition(omega2, mu, A, k_omega2, k_q) * duffing.UNIT_ROUNDOFF <= rtol:  # NaN-safe
        return st.ILL_CONDITIONED
    duffing.scale_into(omega2, mu, A, p, IA)
    return st.OK


def at_rest_at_one(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


def two_term_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[IA] * y[0] - p[IB] * y[0] * y[0] * y[0] - p[IC] * y[0] * y[0]


def two_term_jac(t, y, p, J):
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    J[1, 0] = -p[IA] - 3.0 * p[IB] * y[0] * y[0] - 2.0 * p[IC] * y[0]
    J[1, 1] = 0.0


def two_term_accel(t, q, p, a):
    a[0] = -p[IA] * q[0] - p[IB] * q[0] * q[0] * q[0] - p[IC] * q[0] * q[0]


def step_for(p, rtol):
    return duffing.symplectic_step(rtol)


def two_term_event(t, y, p):
    return p[IDIR] * (y[0] - p[ILEVEL])


def horizon(p):
    return p[T_MAX] * 2.0 * math.pi


def two_term_period(p, tau_q):
    return 4.0 * tau_q / p[IW]


# ---- the exact system: the scaled exact-moment equation in slots ES..EW2
def exact_prepare(p, rtol):
    """Whether the lever oscillates about phi = 0 is decided by the exact moment's potential alone
    (exact_classify), never by the two-term model; then the scaled equation, in phi / A, or, released
    near the top (A > pi / 2), in theta = pi - phi (see exact_refine)."""
    _, sigma, lam1, lam2, s, k, chi, xi, A = point_coefficients(p)
    D0 = rest_length_squared(sigma, lam1, lam2)
    L0 = math.sqrt(D0) - sigma * s
    code = exact_classify(sigma, lam1, D0, L0, A)
    if code != st.OK:
        return code
    # time scale of the scaled equation: as the two-term model's, with |chi| (chi < 0 is allowed
    # here: the lever may swing over the hump at phi = 0); |chi| + |xi| A^2 > 0 for every feasible A > 0
    w2 = k * (abs(chi) + abs(xi) * A * A)
    p[EL1] = lam1
    p[EL0] = L0
    theta0 = (math.pi - A) + PI_LO  # pi - A; math.pi - A is exact for A >= pi / 2 (Sterbenz)
    if A > 0.5 * math.pi:
        # theta'' = -k m(theta; -sigma, D_pi): the same moment with sigma -> -sigma, D0 -> D_pi
        d = 1.0 + sigma * lam1
        p[ES] = -sigma
        p[ED] = d * d + lam2 * lam2
        p[ESCALE] = theta0
        p[ECOEF] = k / (w2 * theta0)
        p[ELEVEL] = math.pi / theta0
        p[EDIR] = -1.0
    else:
        p[ES] = sigma
        p[ED] = D0
        p[ESCALE] = A
        p[ECOEF] = k / (w2 * A)
        p[ELEVEL] = 0.0
        p[EDIR] = 1.0
    p[EW2] = w2
    return st.OK


def exact_rhs(t, y, p, dydt):
    # x = phi / A (or theta / theta0), tau = w t:  x'' = -coef * m(scale x)
    dydt[0] = y[1]
    dydt[1] = -p[ECOEF] * exact_moment(p[ESCALE] * y[0], p[ES], p[EL1], p[ED], p[EL0])


def exact_jac(t, y, p, J):
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    J[1, 0] = -p[ECOEF] * p[ESCALE] * exact_moment_slope(p[ESCALE] * y[0], p[ES], p[EL1], p[ED], p[EL0])
    J[1, 1] = 0.0


def exact_accel(t, q, p, a):
    a[0] = -p[ECOEF] * exact_moment(p[ESCALE] * q[0], p[ES], p[EL1], p[ED], p[EL0])


def exact_event(t, y, p):
    # level of phi = 0 in the scaled coordinate; +1: y falls to it, -1: y rises to it
    return p[EDIR] * (y[0] - p[ELEVEL])


def exact_period(p, tau_q):
    return 4.0 * tau_q / math.sqrt(p[EW2])


def exact_refine(p, rtol, T):
    """The refine bound of the exact-moment period T (k = R^2 c / I): math.inf where the point is
    ILL_CONDITIONED, else the factor the tolerance is tightened by (1: none).

    Whether the lever oscillates about phi = 0 is decided by the exact moment's potential alone
    (exact_classify), never by the two-term model: the cubic's soft separatrix is an artefact of
    the truncation (a stretched tension spring, for instance, always brings the lever back).

    The potential V = (l - L0)^2 / 2 has its humps at phi = pi (where the spring is stretched, or
    compressed, beyond its free length there) and, when chi < 0, at phi = 0; near them the period
    diverges logarithmically and, as for the Duffing separatrix, errors are amplified:
    - released near the top (A > pi / 2): integrated in theta = pi - phi, theta(0) = (pi - A)
      formed to twice double precision, so that the tolerance is relative to the distance from the
      top (in phi / A the error grows without bound as pi - A shrinks);
      what is left is the sensitivity to A itself, d ln T / d ln A = 4 A / (lambda_pi (pi - A) T);
    - swinging over the hump at 0 with a small energy excess dE = V(A) - V(0): the energy error of
      the integration (of order rtol V(A)) is amplified by at most V(A) |d T / d E| / T, which is
      2 V(A) / (lambda_0 T dE) for dE -> 0, so the tolerance is tightened by that bound
      and a second pass is run (within rtol of 30-digit quadrature from A / A* - 1 = 1e-1 to 1e-8,
      tests/test_torsional_circuit.py); where the tightened
      tolerance would be below RTOL_FLOOR, or the inputs' round-off alone moves T by more than rtol
      (condition number with respect to A, lambda1, lambda2, s0_over_r times round-off), the point is
      ILL_CONDITIONED.
    """
    _, sigma, lam1, lam2, s, k, chi, xi, A = point_coefficients(p)
    D0 = rest_length_squared(sigma, lam1, lam2)
    L0 = math.sqrt(D0) - sigma * s
    theta0 = (math.pi - A) + PI_LO
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
    if not kappa * duffing.UNIT_ROUNDOFF <= rtol:  # NaN-safe
        return math.inf
    if not amp <= 1.0:
        if not rtol / amp >= RTOL_FLOOR:
            return math.inf
        return amp
    return 1.0


_DIMENSIONAL = ("R", "c", "I")
_DUF = {o.name: o for o in duffing.SPEC.outputs}


def _duffing_closed(name, func, needs=(), output_needs=None):
    """A Duffing closed form of the two-term model: duffing's output, needing A (and R, c, I when it
    has a unit), NaN with the two-term status where the two-term model does not oscillate."""
    o = _DUF[name]
    return ClosedForm(name, func, o.symbol, o.unit, o.long_name, needs=needs, output_needs=output_needs,
                      classify=two_term_classify, needs_params=("A",) + (_DIMENSIONAL if o.unit != "1" else ()),
                      latex=o.latex)


TWO_TERM = System(rhs=two_term_rhs, initial=at_rest_at_one, jac=two_term_jac, accel=two_term_accel,
                  symplectic_step=step_for, prepare=two_term_prepare)
EXACT = System(rhs=exact_rhs, initial=at_rest_at_one, jac=exact_jac, accel=exact_accel, symplectic_step=step_for,
               prepare=exact_prepare)

MODEL = OdeModel(
    name="torsional_circuit",
    description="Rocking lever with an out-of-plane spring: Duffing coefficients, nomograms, amplitude-period",
    source="Klyuchkovskyi, torsional oscillating circuits, formulas (4)-(7); physics.md section 1",
    references=(
        'Klyuchkovskyi, "Synthesis of motion laws of the rocking link of spatial torsional oscillating circuits" '
        "(printing-machine automata)",
        "mechsweep docs/physics.md section 1: the checks and corrections made to the source",
    ),
    params=(
        Param("spring", "", "1", "spring kind", choices=("tension", "compression")),
        Param("lambda1", "λ1", "1", "frame-point offset in the lever plane, in lever radii R", lo=0.0, lo_open=True,
              latex=r"$\lambda_1$"),
        Param("lambda2", "λ2", "1", "frame-point offset along the axis, in lever radii R", lo=0.0,
              latex=r"$\lambda_2$"),
        Param("s0_over_r", "S0/R", "1", "mounting deformation of the spring, in lever radii R", latex="$S_0/R$"),
        Param("R", "R", "m", "lever radius of the spring attachment", lo=0.0, lo_open=True,
              required=False, default=1.0, latex="$R$"),
        Param("c", "c", "N m-1", "spring stiffness", lo=0.0, lo_open=True, required=False, default=1.0,
              latex="$c$"),
        Param("I", "I", "kg m2", "moment of inertia of the lever", lo=0.0, lo_open=True,
              required=False, default=1.0, latex="$I$"),
        Param("A", "A", "rad", "amplitude, released at rest from φ = A", lo=0.0, hi=math.pi,
              required=False, default=math.nan, latex="$A$"),
    ),
    settings=(duffing.T_MAX_PERIODS,),
    internal=("a", "b", "c", "level", "direction", "w",
              "exact_sigma", "exact_lambda1", "exact_D", "exact_L0", "exact_scale", "exact_coef", "exact_level",
              "exact_direction", "exact_w2"),
    states=("x", "dx"),
    classify=model_classify,
    initial=at_rest_at_one,
    rhs=two_term_rhs,
    jac=two_term_jac,
    accel=two_term_accel,
    symplectic_step=step_for,
    symplectic_order=duffing.SYMPLECTIC_ORDER,
    measurements=(
        FirstEvent("period", two_term_event, t_max=horizon, value=two_term_period, symbol=_DUF["period"].symbol,
                   unit=_DUF["period"].unit, long_name=_DUF["period"].long_name, system=TWO_TERM,
                   needs_params=("A",) + _DIMENSIONAL, latex=_DUF["period"].latex),
        FirstEvent("period_exact_moment", exact_event, t_max=horizon, value=exact_period, symbol="T_M", unit="s",
                   long_name="period with the exact spring moment", system=EXACT, refine=exact_refine,
                   needs_params=("A",) + _DIMENSIONAL, latex="$T_M$"),
    ),
    closed_forms=(
        ClosedForm("chi", chi_of, "χ = ω² I / (R² c)", "1", "linear stiffness coefficient, nondimensional",
                   latex=r"$\chi = \omega^2 I/(R^2 c)$"),
        ClosedForm("xi", xi_of, "ξ = μ I / (R² c)", "1", "cubic stiffness coefficient, nondimensional",
                   latex=r"$\xi = \mu I/(R^2 c)$"),
        ClosedForm("omega2", omega2_of, "ω²", "s-2", "squared linear natural frequency",
                   needs_params=_DIMENSIONAL, latex=r"$\omega^2$"),
        ClosedForm("mu", mu_of, "μ", "rad-2 s-2", "cubic stiffness coefficient of the Duffing equation",
                   needs_params=_DIMENSIONAL, latex=r"$\mu$"),
        ClosedForm("hardness", hardness_of, "sign ξ", "1", "characteristic: +1 hard, 0 linear, -1 soft",
                   latex=r"$\mathrm{sign}\,\xi$"),
        _duffing_closed("period_exact", period_exact),
        ClosedForm("period_error", relative_error, _DUF["period_error"].symbol, "1", _DUF["period_error"].long_name,
                   needs=("period", "period_exact"), needs_params=("A",), latex=_DUF["period_error"].latex),
        _duffing_closed("v_max", v_max),
        _duffing_closed("a_max", a_max),
        _duffing_closed("kv", kv, needs=("v_max", "period_exact"), output_needs=()),
        _duffing_closed("ka", ka, needs=("a_max", "period_exact"), output_needs=()),
        _duffing_closed("epsilon", epsilon),
        ClosedForm("truncation_error", relative_error, "|T_exact - T_M| / T_M", "1",
                   "relative period error of the two-term (Duffing) model against the exact moment",
                   needs=("period_exact", "period_exact_moment"), needs_params=("A",),
                   latex=r"$|T_\mathrm{exact} - T_M|/T_M$"),
    ),
    output_order=("chi", "xi", "omega2", "mu", "hardness", "period", "period_exact", "period_error", "v_max",
                  "a_max", "kv", "ka", "epsilon", "period_exact_moment", "truncation_error"),
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
    # bench workprecision: the exact-moment period against scipy DOP853 at rtol 1e-13 on the System's own rhs
    workprecision=WorkPrecision(scene="sweeps/torsional_circuit_truncation.toml", output="period_exact_moment"),
)

SPEC = MODEL.spec(module=__name__, attr="MODEL")
evaluate = SPEC.evaluate
