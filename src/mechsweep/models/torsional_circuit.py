"""Spatial torsional oscillating circuit: rocking lever + out-of-plane spring -> Duffing equation.

Over 700 lines on purpose: a model is one module, its declarations and per-point functions beside
the source formulas they implement.

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
from ._scaling import exponent, normal, product_in_range, quotient_in_range, times_pow2
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
def coefficients_in_range(sigma, lam1, s, D0):
    """Every product and quotient of chi and xi (coefficients) is a normal number or an exact 0 from a
    zero factor: False for geometries beyond about 1e150 R (D0 overflows at lambda1 = 1e200, where chi
    would be 0 and xi NaN) or products below about 1e-308 (s0_over_r = 1e-310; lambda1 = 1e-200, where
    xi ~ 3 lambda1^2 / (6 D0) underflows to 0): chi, xi and the two-term outputs are then OUT_OF_RANGE.
    A cancellation to 0 or to a tiny difference (xi = 0: linear) is not a range problem and passes."""
    r = math.sqrt(D0)
    G = D0 + 3.0 * sigma * lam1
    B = 3.0 * lam1 - s * G / r
    return (normal(D0) and normal(6.0 * D0) and normal(3.0 * lam1) and product_in_range(lam1, s)
            and quotient_in_range(lam1 * s, r) and product_in_range(s, G) and quotient_in_range(s * G, r)
            and product_in_range(lam1, B) and quotient_in_range(lam1 * B, 6.0 * D0))


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
def stretch(phi, sigma, lam1, D0, r):
    """(l(phi) - r, l(phi)) without cancellation, r = sqrt(D0) the formulation's l at 0:
    l - r = 4 sigma lambda1 sin^2(phi / 2) / (l + r)."""
    h = math.sin(0.5 * phi)
    d = 4.0 * sigma * lam1 * h * h
    length = math.sqrt(D0 + d)
    return d / (length + r), length


@jit_noalloc
def exact_moment_stretch(phi, sigma, lam1, D0, r, gap, L0):
    """exact_moment with 1 - L0 / l written as (l - L0) / l, l - L0 = (l - r) + gap (stretch; gap =
    r - L0 given without cancellation): the plain form loses the digits of l - L0 where it is small
    against L0 (a mounting deformation s0_over_r -> 0 at small amplitudes; u L0 / |l - L0| relative)."""
    dl, length = stretch(phi, sigma, lam1, D0, r)
    return sigma * lam1 * math.sin(phi) * ((dl + gap) / length)


@jit_noalloc
def exact_moment_stretch_slope(phi, sigma, lam1, D0, r, gap, L0):
    """d/dphi of exact_moment_stretch (exact_moment_slope with 1 - L0 / l from stretch)."""
    dl, length = stretch(phi, sigma, lam1, D0, r)
    sin_phi = math.sin(phi)
    return sigma * lam1 * (math.cos(phi) * ((dl + gap) / length)
                           + sigma * lam1 * L0 * sin_phi * sin_phi / (length * length * length))


@jit_noalloc
def exact_classify(sigma, lam1, D0, gap, A):
    """Status of the exact-moment motion released at rest from phi = A: NO_MOTION for A = 0,
    NOT_OSCILLATORY unless the lever passes through phi = 0 (_returns_through_zero), else OK.
    The two-term model's classification plays no part."""
    if A == 0.0:
        return st.NO_MOTION
    if not _returns_through_zero(sigma, lam1, D0, gap, A):
        return st.NOT_OSCILLATORY
    return st.OK


@jit_noalloc
def _returns_through_zero(sigma, lam1, D0, gap, A):
    """Energy: released at rest from A, the lever reaches phi = 0 iff the spring energy there is
    lower than at A, (l(0) - L0)^2 < (l(A) - L0)^2; l is monotonic on [0, pi] and the energy
    (l - L0)^2 / 2 is convex in l, so on [0, A] it is highest at an end and has no other hump in
    between. Then, the moment being odd, the motion is symmetric and swings to -A: an oscillation
    about phi = 0 whatever the two-term model says. Otherwise the lever stays in a well away from 0
    (or creeps to 0 forever). gap = l(0) - L0 = sigma s0_over_r and dl = l(A) - l(0) (stretch) are
    free of cancellation, and the energy difference is decided by signs, so a tiny mounting
    deformation at a tiny amplitude, or a stroke far shorter than the deformation, is decided right."""
    dl, _ = stretch(A, sigma, lam1, D0, math.sqrt(D0))
    # V(A) - V(0) = dl (dl + 2 gap) / 2 > 0, by signs (dl far below gap is not lost to rounding)
    e = dl + 2.0 * gap
    return (dl > 0.0 and e > 0.0) or (dl < 0.0 and e < 0.0)


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
# system's (sigma', lambda1, D, L0, scale, coef, level, direction, w, sqrt D, gap, form, step). Each
# system's prepare writes its own slots just before its measurement.
SPRING, LAM1, LAM2, S0R, RR, CC, II, AMP, T_MAX = range(9)
IA, IB, IC, ILEVEL, IDIR, IW = range(9, 15)
ES, EL1, ED, EL0, ESCALE, ECOEF, ELEVEL, EDIR, EW, ER, EGAP, EFORM, ESTEP = range(15, 28)
PI_LO = 1.2246467991473532e-16  # pi - math.pi: pi = math.pi + PI_LO to twice double precision
# Tightened tolerances below this are not tried: the point is ILL_CONDITIONED
RTOL_FLOOR = 5e-14
# Time unit of the exact system: the two-term model's w^2 = k (|chi| + |xi| A^2) where it is within this
# factor (both ways) of the exact moment's own w_e^2 = k exact_time_scale (any unit within it serves, and
# sweeps/torsional_circuit_truncation.toml keeps its bits: its largest ratio is 9.2, measured by
# tests/test_torsional_circuit.py::test_exact_time_unit_is_the_two_term_one_where_they_agree); w_e^2
# beyond it (next to D0 -> 0, xi ~ 1 / (2 D0) while the moment saturates like sin(phi): there the
# two-term unit is far too fast, and a horizon of 100 of its periods would end before the first
# quarter period)
SCALE_BAND = 16.0
# The exact moment as (l - L0) / l (exact_moment_stretch) where the plain 1 - L0 / l could lose more
# than this factor of round-off: |L0| > STRETCH_FORM max(|l(0) - L0|, |l(A) - L0|)
# (s0_over_r -> 0 at small amplitudes; the shipped scenes stay below 20 and keep their bits)
STRETCH_FORM = 64.0
# the exact system's lengths and mounting deformation below 2^600 (its rhs forms l^3), its force
# scale above 2^-900 (below, moments along the stroke would be subnormal)
EXACT_BIG = 2.0 ** 600
EXACT_TINY = 2.0 ** -900


@jit_noalloc
def stiffness_split(p):
    """(kk, ek): k = R^2 c / I = kk 2^ek exactly, ek even: (k, 0) where R^2 c / I is safely normal,
    else kk in [1, 4): no overflow for any R, c, I, and the bits of R * R * c / I wherever that is a
    normal number (models/_scaling.py)."""
    R2 = p[RR] * p[RR]
    R2c = R2 * p[CC]
    k = R2c / p[II]
    if 2.0 ** -400 <= min(R2, R2c, k) and max(R2, R2c, k) <= 2.0 ** 400:
        return k, 0  # R^2 c / I as written (no libm call where it is safely normal)
    fR, eR = math.frexp(p[RR])
    fc, ec = math.frexp(p[CC])
    fI, eI = math.frexp(p[II])
    kk = fR * fR * fc / fI  # in (1/8, 2)
    e = 2 * eR + ec - eI
    t = 1 - exponent(kk)  # kk 2^t in [1, 2)
    if (e - t) % 2 != 0:
        t += 1
    return math.ldexp(kk, t), e - t


@jit
def point_coefficients(p):
    """(status, sigma, lam1, lam2, s, kk, ek, chi, xi, A) of a point; k = R^2 c / I = kk 2^ek
    (stiffness_split). status: SINGULAR or INFEASIBLE where formulas (4)-(7) give no coefficients,
    OUT_OF_RANGE where chi or xi cannot be formed in double precision (coefficients_in_range)."""
    sigma = spring_sign(p[SPRING])
    lam1, lam2, s = p[LAM1], p[LAM2], p[S0R]
    kk, ek = stiffness_split(p)
    code, chi, xi, D0 = coefficients(sigma, lam1, lam2, s)
    if code == st.OK and not (coefficients_in_range(sigma, lam1, s, D0) and product_in_range(kk, chi)
                              and product_in_range(kk, xi)):
        code = st.OUT_OF_RANGE
    return code, sigma, lam1, lam2, s, kk, ek, chi, xi, p[AMP]


def model_classify(p):
    """SINGULAR or INFEASIBLE where formulas (4)-(7) give no coefficients: every output NaN."""
    code = point_coefficients(p)[0]
    return st.OK if code == st.OUT_OF_RANGE else code


def coefficients_classify(p):
    """OUT_OF_RANGE where chi or xi cannot be formed in double precision: the coefficients and the
    two-term outputs are NaN, the exact-moment period is still given (it has its own range)."""
    return point_coefficients(p)[0]


@jit
def two_term_point(p):
    """The two-term model's point (omega^2 = k chi, mu = k xi, A) rescaled by powers of two
    (duffing.rescaled): (status, omega2', mu', A', i, j), status the coefficients' or duffing's."""
    code, _, _, _, _, kk, ek, chi, xi, A = point_coefficients(p)
    o2, mu, a, i, j = duffing.rescaled(kk * chi, ek, kk * xi, ek, A)
    if code == st.OK:
        code = duffing.classify_scaled(chi, o2, mu, a)
    return code, o2, mu, a, i, j


def two_term_classify(p):
    """The two-term (Duffing) model's status (duffing.classify_scaled of omega^2 = k chi, mu = k xi)."""
    return two_term_point(p)[0]


# ---- closed forms: the coefficients, and the Duffing closed forms of the two-term model, evaluated on
# the rescaled point as duffing's (bitwise the plain formulas in the usual range)
def chi_of(p):
    return point_coefficients(p)[7]


def xi_of(p):
    return point_coefficients(p)[8]


def omega2_of(p):
    _, _, _, _, _, kk, ek, chi, xi, A = point_coefficients(p)
    return times_pow2(kk * chi, ek)


def mu_of(p):
    _, _, _, _, _, kk, ek, chi, xi, A = point_coefficients(p)
    return times_pow2(kk * xi, ek)


def hardness_of(p):
    xi = point_coefficients(p)[8]
    return 1.0 if xi > 0.0 else (-1.0 if xi < 0.0 else 0.0)


def period_exact(p):
    _, omega2, mu, A, i, _ = two_term_point(p)
    return times_pow2(duffing.period_plain(omega2, mu, A), i)


def v_max(p):
    _, omega2, mu, A, i, j = two_term_point(p)
    return times_pow2(duffing.v_max_plain(omega2, mu, A), -(i + j))


def a_max(p):
    _, omega2, mu, A, i, j = two_term_point(p)
    return times_pow2(duffing.a_max_plain(omega2, mu, A), -(2 * i + j))


def kv(p, vmax, T):
    _, omega2, mu, A, _, _ = two_term_point(p)
    return duffing.v_max_plain(omega2, mu, A) * duffing.period_plain(omega2, mu, A) / A  # 2 pi when linear


def ka(p, amax, T):
    _, omega2, mu, A, _, _ = two_term_point(p)
    T = duffing.period_plain(omega2, mu, A)
    return duffing.a_max_plain(omega2, mu, A) * T * T / A  # 4 pi^2 for the linear oscillator


def epsilon(p):
    _, _, _, _, _, kk, ek, chi, xi, A = point_coefficients(p)
    return duffing.epsilon_split(kk * chi, ek, kk * xi, ek, A)


def relative_error(p, value, reference):
    return duffing.relative_difference(value, reference)


# ---- the two-term system: duffing's scaled equation (plain or saddle formulation) in slots IA..IW
def two_term_prepare(p, rtol):
    """The two-term model's status, then, as duffing.prepare, ILL_CONDITIONED where the period's
    condition number (with this model's sensitivities, cubic_sensitivities) times round-off exceeds
    rtol, OUT_OF_RANGE where w is beyond the normal range; else the scaled equation's coefficients,
    the event and w."""
    _, sigma, lam1, lam2, s, kk, ek, chi, xi, A = point_coefficients(p)
    code, omega2, mu, A, i, _ = two_term_point(p)
    if code != st.OK:
        return code
    k_omega2, k_q = cubic_sensitivities(sigma, lam1, lam2, s, rest_length_squared(sigma, lam1, lam2))
    if not duffing.period_condition(omega2, mu, A, k_omega2, k_q) * duffing.UNIT_ROUNDOFF <= rtol:  # NaN-safe
        return st.ILL_CONDITIONED
    if not duffing.scale_into(omega2, mu, A, i, p, IA):
        return st.OUT_OF_RANGE
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


# ---- the exact system: the scaled exact-moment equation in slots ES..EFORM
@jit_noalloc
def exact_time_scale(sigma, lam1, D0, gap, A):
    """w_e^2 / k = (v_max / A)^2 / k of the exact moment released at rest from A (gap = l(0) - L0 =
    sigma s0_over_r): 2 dV / A^2, dV = V(A) - min V over [0, A] from the energy V = (l - L0)^2 / 2,
    without cancellation: V(A) - V(0) = dl (dl + 2 gap) / 2, dl = l(A) - l(0); V(A) where the well's
    bottom l = L0 lies inside the stroke. The quarter period is at least A / v_max: the scaled
    equation's period is at least 4 in this unit, whatever the spring (it grows only near a hump)."""
    dl, _ = stretch(A, sigma, lam1, D0, math.sqrt(D0))
    vA = dl + gap  # l(A) - L0
    if gap * vA < 0.0:
        dV = 0.5 * vA * vA
    else:
        dV = 0.5 * dl * (dl + 2.0 * gap)
    return 2.0 * dV / (A * A)


@jit_noalloc
def exact_in_range(lam1, D0, s, A):
    """The exact system's inputs leave room in double precision's range: the squared spring length and
    the mounting deformation below EXACT_BIG, A^2 and the spring's stretch over the stroke normal
    (below A ~ 1e-154 sin^2(A / 2) underflows and the lever would look as if it never left phi = 0).
    The force scale is checked once the motion is known to oscillate (exact_prepare)."""
    h = math.sin(0.5 * A)
    return D0 + 4.0 * lam1 <= EXACT_BIG and abs(s) <= EXACT_BIG and normal(A * A) and normal(4.0 * lam1 * h * h)


def exact_prepare(p, rtol):
    """Whether the lever oscillates about phi = 0 is decided by the exact moment's potential alone
    (exact_classify), never by the two-term model; then the scaled equation, in phi / A, or, released
    near the top (A > pi / 2), in theta = pi - phi (see exact_refine), with the time unit of
    exact_time_scale where the two-term model's is off by more than SCALE_BAND, and the moment in
    the form free of cancellation where the plain one would lose digits (STRETCH_FORM).
    OUT_OF_RANGE where the exact system's quantities leave double precision's range (exact_in_range)."""
    _, sigma, lam1, lam2, s, kk, ek, chi, xi, A = point_coefficients(p)
    D0 = rest_length_squared(sigma, lam1, lam2)
    r = math.sqrt(D0)
    gap = sigma * s  # l(0) - L0
    L0 = r - gap
    if A == 0.0:
        return st.NO_MOTION
    if not exact_in_range(lam1, D0, s, A):
        return st.OUT_OF_RANGE
    code = exact_classify(sigma, lam1, D0, gap, A)
    if code != st.OK:
        return code
    scale = exact_time_scale(sigma, lam1, D0, gap, A)
    if not (EXACT_TINY <= scale * A and scale <= EXACT_BIG):  # the force scale: moments along the stroke normal
        return st.OUT_OF_RANGE
    # time scale of the scaled equation: the two-term model's (|chi| + |xi| A^2 > 0 for every feasible
    # A > 0; chi < 0 is allowed here: the lever may swing over the hump at phi = 0) unless it is off
    X2 = abs(chi) + abs(xi) * A * A
    X = X2
    if not (X <= SCALE_BAND * scale and scale <= SCALE_BAND * X):  # NaN-safe: NaN coefficients take scale
        X = scale
    # symplectic steps: no coarser than in the two-term unit where that is faster. Its |xi| A^2 is the
    # curvature of the moment at phi = 0, which sees what the exact unit does not: next to D0 -> 0 the
    # moment turns over within |phi| ~ sqrt(D0 / lambda1), a feature a fixed step must resolve (in the
    # exact unit alone the period was 2e-7 off at rtol 1e-10, D0 = 9e-12, A = 1e-3; measured by
    # tests/test_torsional_circuit.py::test_exact_moment_period_of_every_method_next_to_a_zero_rest_length)
    step = math.sqrt(X / X2)
    p[ESTEP] = step if step < 1.0 else 1.0  # NaN (coefficients out of range): 1
    w2 = kk * X  # w^2 / 2^ek
    w = times_pow2(math.sqrt(w2), ek // 2)
    if not normal(w):
        return st.OUT_OF_RANGE
    dl, _ = stretch(A, sigma, lam1, D0, r)
    p[EFORM] = 1.0 if abs(L0) > STRETCH_FORM * max(abs(gap), abs(dl + gap)) else 0.0
    p[EL1] = lam1
    p[EL0] = L0
    theta0 = (math.pi - A) + PI_LO  # pi - A; math.pi - A is exact for A >= pi / 2 (Sterbenz)
    if A > 0.5 * math.pi:
        # theta'' = -k m(theta; -sigma, D_pi): the same moment with sigma -> -sigma, D0 -> D_pi
        d = 1.0 + sigma * lam1
        p[ES] = -sigma
        p[ED] = d * d + lam2 * lam2
        r_pi = math.sqrt(p[ED])
        p[ER] = r_pi
        p[EGAP] = 4.0 * sigma * lam1 / (r_pi + r) + gap  # l(pi) - L0: l(pi)^2 - l(0)^2 = 4 sigma lambda1
        p[ESCALE] = theta0
        p[ECOEF] = kk / (w2 * theta0)
        p[ELEVEL] = math.pi / theta0
        p[EDIR] = -1.0
    else:
        p[ES] = sigma
        p[ED] = D0
        p[ER] = r
        p[EGAP] = gap
        p[ESCALE] = A
        p[ECOEF] = kk / (w2 * A)
        p[ELEVEL] = 0.0
        p[EDIR] = 1.0
    p[EW] = w
    return st.OK


def exact_rhs(t, y, p, dydt):
    # x = phi / A (or theta / theta0), tau = w t:  x'' = -coef * m(scale x)
    dydt[0] = y[1]
    if p[EFORM] != 0.0:
        dydt[1] = -p[ECOEF] * exact_moment_stretch(p[ESCALE] * y[0], p[ES], p[EL1], p[ED], p[ER], p[EGAP], p[EL0])
    else:
        dydt[1] = -p[ECOEF] * exact_moment(p[ESCALE] * y[0], p[ES], p[EL1], p[ED], p[EL0])


def exact_jac(t, y, p, J):
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    if p[EFORM] != 0.0:
        J[1, 0] = -p[ECOEF] * p[ESCALE] * exact_moment_stretch_slope(p[ESCALE] * y[0], p[ES], p[EL1], p[ED], p[ER],
                                                                     p[EGAP], p[EL0])
    else:
        J[1, 0] = -p[ECOEF] * p[ESCALE] * exact_moment_slope(p[ESCALE] * y[0], p[ES], p[EL1], p[ED], p[EL0])
    J[1, 1] = 0.0


def exact_accel(t, q, p, a):
    if p[EFORM] != 0.0:
        a[0] = -p[ECOEF] * exact_moment_stretch(p[ESCALE] * q[0], p[ES], p[EL1], p[ED], p[ER], p[EGAP], p[EL0])
    else:
        a[0] = -p[ECOEF] * exact_moment(p[ESCALE] * q[0], p[ES], p[EL1], p[ED], p[EL0])


def exact_step_for(p, rtol):
    return duffing.symplectic_step(rtol) * p[ESTEP]


def exact_event(t, y, p):
    # level of phi = 0 in the scaled coordinate; +1: y falls to it, -1: y rises to it
    return p[EDIR] * (y[0] - p[ELEVEL])


def exact_period(p, tau_q):
    return 4.0 * tau_q / p[EW]


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
    _, sigma, lam1, lam2, s, k, ek, chi, xi, A = point_coefficients(p)
    T = times_pow2(T, ek // 2)  # with k = kk 2^ek: T in units of 2^(-ek/2) s, k the mantissa kk (exact)
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
EXACT = System(rhs=exact_rhs, initial=at_rest_at_one, jac=exact_jac, accel=exact_accel,
               symplectic_step=exact_step_for, prepare=exact_prepare)

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
              "exact_direction", "exact_w", "exact_sqrt_D", "exact_gap", "exact_form", "exact_step"),
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
                   classify=coefficients_classify, latex=r"$\chi = \omega^2 I/(R^2 c)$"),
        ClosedForm("xi", xi_of, "ξ = μ I / (R² c)", "1", "cubic stiffness coefficient, nondimensional",
                   classify=coefficients_classify, latex=r"$\xi = \mu I/(R^2 c)$"),
        ClosedForm("omega2", omega2_of, "ω²", "s-2", "squared linear natural frequency",
                   needs_params=_DIMENSIONAL, classify=coefficients_classify, latex=r"$\omega^2$"),
        ClosedForm("mu", mu_of, "μ", "rad-2 s-2", "cubic stiffness coefficient of the Duffing equation",
                   needs_params=_DIMENSIONAL, classify=coefficients_classify, latex=r"$\mu$"),
        ClosedForm("hardness", hardness_of, "sign ξ", "1", "characteristic: +1 hard, 0 linear, -1 soft",
                   classify=coefficients_classify, latex=r"$\mathrm{sign}\,\xi$"),
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
    statuses=(st.INFEASIBLE, st.SINGULAR, st.NOT_OSCILLATORY, st.NO_MOTION, st.OUT_OF_RANGE,
              *st.INTEGRATION_FAILURES),
    status_notes={
        st.INFEASIBLE: "spring free length <= 0, or omega^2 <= 0 for the two-term outputs",
        st.SINGULAR: "D0 = (L(0)/R)^2 <= 1e-12: a spring of zero length at rest",
        st.NOT_OSCILLATORY: "the two-term model at or beyond its soft separatrix, or the exact spring moment never "
                            "brings the lever back through phi = 0 (period_exact_moment is still given when only "
                            "the two-term model fails)",
        st.NO_MOTION: "A = 0: no motion, ratios to A undefined",
        st.ILL_CONDITIONED: "the two-term period next to its separatrix, or the exact-moment period next to a hump "
                            "of the spring's potential",
        st.OUT_OF_RANGE: "chi or xi would over- or underflow (lambda1, lambda2 or |s0_over_r| beyond about 1e150, "
                         "or products below about 1e-308, e.g. s0_over_r = 1e-310): the coefficients and two-term "
                         "outputs are NaN; or the exact system's would (lengths beyond 2^600, A below about 1e-154, "
                         "a force scale below 2^-900): period_exact_moment is NaN; or a period beyond about "
                         "1e308 s or below 1e-308 s",
    },
    # bench workprecision: the exact-moment period against scipy DOP853 at rtol 1e-13 on the System's own rhs
    workprecision=WorkPrecision(scene="sweeps/torsional_circuit_truncation.toml", output="period_exact_moment"),
)

SPEC = MODEL.spec(module=__name__, attr="MODEL")
evaluate = SPEC.evaluate
