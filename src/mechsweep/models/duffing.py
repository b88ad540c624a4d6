"""Undamped Duffing oscillator phi'' + omega^2 phi + mu phi^3 = 0, phi(0) = A, phi'(0) = 0,
declared on the model layer (mechsweep.model): the engine composes its chunk kernel for the
scene's method and outputs (engine/kernels.py), as for any user model.

Source: Klyuchkovskyi, torsional oscillating circuits, equation (3); closed forms from
../shared/physics.md section 1 (amplitude-period relation and kinematic invariants).

Numerics: the period is integrated on the scaled equation x = phi / A, tau = w t with
w^2 = omega^2 + |mu| A^2, so that rtol/atol mean the same thing for A = 1e-8 rad and for
A = 10 rad:  x'' = -a x - b x^3,  a = omega^2 / w^2,  b = mu A^2 / w^2,  |a| + |b| = 1.
By symmetry of the motion the first zero of x is a quarter period: T = 4 tau_q / w.
Within 2e-3 of the soft separatrix the same quarter period is integrated in coordinates centred on
the saddle, and points whose period is too sensitive to the inputs for rtol are ILL_CONDITIONED
(see prepare). All of this is the declaration's ``prepare`` (per point: the scaling, the
formulation, the conditioning test), ``rhs``/``jac``/``accel`` (the scaled equation), the event
and the value T = 4 tau_q / w; the closed forms are ClosedForm outputs.
"""
from __future__ import annotations

import math

from .. import status as st
from .._jit import jit, jit_noalloc
from ..model.measure import ClosedForm, FirstEvent
from ..model.ode import Invariant, OdeModel
from ..model.workprecision import WorkPrecision
from ..special import ellipk
from ._scaling import exponent, normal, times_pow2
from ..model.spec import Param, Setting

# Integration horizon of the period event, in linearised periods 2 pi / w (w^2 = omega^2 + |mu| A^2):
# near the soft separatrix T grows like log(1 / distance), so 100 is reached only ~e^-200 from it.
T_MAX_PERIODS = Setting("t_max_periods", 100.0, "1", "integration horizon in linearised periods", 1e-3, 1e9)

# sum over the inputs (omega, mu, A) of |d ln omega^2 / d ln p| and |d ln(mu A^2) / d ln p|
K_OMEGA2 = 2.0
K_Q = 3.0

# method "symplectic": McLachlan's 8th-order composition with ceil(SYMPLECTIC_C rtol^(-1/8)) fixed
# steps per linearised period 2 pi of the scaled equation
SYMPLECTIC_ORDER = 8
SYMPLECTIC_C = 3.0


# --------------------------------------------------------------------------- closed forms
# Every closed form and the integrated period are evaluated on a copy of the point rescaled by powers
# of two (rescaled): the formulas are homogeneous, so the scaled values are O(1), nothing overflows or
# underflows where the result is representable (at mu = 1e308, A = 1 the plain 2 (omega^2 + mu A^2)
# overflows and the plain period is 18 % off), and in the usual range the results are bitwise those of
# the plain formulas (there they are the plain formulas: PLAIN_LO, PLAIN_HI; models/_scaling.py).
# Symmetries: time t -> t / 2^i (omega^2 -> 4^i omega^2, mu -> 4^i mu, T -> T / 2^i, v -> 2^i v,
# a -> 4^i a) and amplitude phi -> 2^j phi (A -> 2^j A, mu -> mu / 4^j, v -> 2^j v, a -> 2^j a);
# kv, ka and epsilon are invariant.
PLAIN_LO, PLAIN_HI = 2.0 ** -400, 2.0 ** 400  # omega^2, A^2, |mu| A^2 within these: the plain formulas


@jit_noalloc
def rescaled(o2, eo2, mu, emu, A):
    """(omega2', mu', A', i, j): the point omega^2 = o2 2^eo2, mu = mu 2^emu, A (a caller whose omega^2
    or mu would overflow passes them so) as omega2' = 4^i omega^2, mu' = 4^(i-j) mu, A' = 2^j A, exact,
    with A' in [1/2, 1) and the larger of omega2', |mu'| A'^2 in [1/16, 2): the smaller one may
    underflow, where it is negligible (below 2^-1000 of the other). T = 2^i T', v = v' / 2^(i+j),
    a = a' / 2^(2i+j)."""
    if eo2 == 0 and emu == 0 and PLAIN_LO <= o2 <= PLAIN_HI and PLAIN_LO <= A * A <= PLAIN_HI and (
            mu == 0.0 or PLAIN_LO <= abs(mu * A * A) <= PLAIN_HI):
        return o2, mu, A, 0, 0  # every intermediate of the formulas stays normal: no scaling (no libm call)
    j = -exponent(A)
    e = exponent(o2) + eo2
    if mu != 0.0 and mu == mu:
        e = max(e, exponent(mu) + emu - 2 * j)
    i = -(e >> 1)
    return math.ldexp(o2, eo2 + 2 * i), math.ldexp(mu, emu + 2 * i - 2 * j), math.ldexp(A, j), i, j


@jit_noalloc
def omega_split(omega):
    """(o2, eo2) with omega^2 = o2 2^eo2: omega * omega and 0 where that is safely normal, else
    o2 = f^2 for omega = f 2^e (no overflow for any omega)."""
    if 2.0 ** -200 <= abs(omega) <= 2.0 ** 200:
        return omega * omega, 0
    f, e = math.frexp(omega)
    return f * f, 2 * e


@jit_noalloc
def classify_scaled(sign, omega2, mu, A):
    """The status of a Duffing point before any computation, from the rescaled point (omega2, mu, A);
    sign: a number of the sign of omega^2 (omega2 itself may underflow to 0 next to a large mu A^2)."""
    if A == 0.0:
        return st.NO_MOTION
    if not sign > 0.0:
        return st.INFEASIBLE  # no stable equilibrium at phi = 0 to oscillate about
    if not omega2 + mu * A * A > 0.0:
        return st.NOT_OSCILLATORY  # at or beyond the soft separatrix |mu| A^2 = omega^2
    return st.OK


@jit_noalloc
def period_plain(omega2, mu, A):
    """T = 4 K(m) / sqrt(omega^2 + mu A^2), m = mu A^2 / (2 (omega^2 + mu A^2)), as written (on a
    rescaled point: period_closed_form)."""
    s = omega2 + mu * A * A
    return 4.0 * ellipk(mu * A * A / (2.0 * s)) / math.sqrt(s)


@jit_noalloc
def v_max_plain(omega2, mu, A):
    """Energy: v_max^2 = omega^2 A^2 + mu A^4 / 2 (velocity at phi = 0), both signs of mu."""
    return A * math.sqrt(omega2 + 0.5 * mu * A * A)


@jit_noalloc
def a_max_plain(omega2, mu, A):
    """max |phi''| over the stroke; for omega^2/3 < |mu| A^2 < omega^2 (soft) it lies inside."""
    if mu >= 0.0 or 3.0 * (-mu) * A * A <= omega2:
        return A * (omega2 + mu * A * A)
    return 2.0 * omega2 * math.sqrt(omega2) / (3.0 * math.sqrt(-3.0 * mu))


@jit_noalloc
def epsilon_split(o2, eo2, mu, emu, A):
    """epsilon = mu A^2 / omega^2 of the point omega^2 = o2 2^eo2, mu = mu 2^emu, A: the plain
    quotient of the mantissas times the power of two (correctly rounded also beyond the normal range)."""
    if eo2 == 0 and emu == 0 and PLAIN_LO <= o2 <= PLAIN_HI and PLAIN_LO <= A * A <= PLAIN_HI and (
            mu == 0.0 or PLAIN_LO <= abs(mu * A * A) <= PLAIN_HI):
        return mu * A * A / o2  # as written, where every intermediate is safely normal
    fm, em = math.frexp(mu)
    fA, eA = math.frexp(A)
    fo, eo = math.frexp(o2)
    return math.ldexp(fm * fA * fA / fo, em + emu + 2 * eA - eo - eo2)


@jit
def period_closed_form(omega2, mu, A):
    """T = 4 K(m) / sqrt(omega^2 + mu A^2), m = mu A^2 / (2 (omega^2 + mu A^2)).

    One formula for both signs of mu (K accepts m < 0). physics.md section 1. Evaluated on the
    point rescaled by powers of two (no overflow of omega^2 + mu A^2 for any representable T)."""
    w2, m, a, i, _ = rescaled(omega2, 0, mu, 0, A)
    return times_pow2(period_plain(w2, m, a), i)


@jit
def v_max_closed_form(omega2, mu, A):
    """Energy: v_max^2 = omega^2 A^2 + mu A^4 / 2 (velocity at phi = 0), both signs of mu."""
    w2, m, a, i, j = rescaled(omega2, 0, mu, 0, A)
    return times_pow2(v_max_plain(w2, m, a), -(i + j))


@jit
def a_max_closed_form(omega2, mu, A):
    """max |phi''| over the stroke; for omega^2/3 < |mu| A^2 < omega^2 (soft) it lies inside."""
    w2, m, a, i, j = rescaled(omega2, 0, mu, 0, A)
    return times_pow2(a_max_plain(w2, m, a), -(2 * i + j))


# Near the soft separatrix (delta = (omega^2 + mu A^2) / w^2 -> 0) the motion starts next to the
# saddle x_s = sqrt(a / -b) = 1 + O(delta) and lingers there for a time ~ log(1 / delta). In x = phi/A
# the distance to the saddle, u = x_s - x ~ delta / 2, is carried as a difference of two numbers
# near 1: every local error (rtol |x|) and every rounding of x is an error of u of relative size
# rtol / delta, and the period's error grows like (2e-3 / delta)^0.85 times rtol (measured; tightening
# rtol by that fitted factor misses points by up to 2.85x). Below SADDLE_DELTA the
# period is therefore integrated in saddle coordinates z = (x_s - x) / u0, u0 = x_s - 1:
#     z'' = 2 a z + 3 b x_s u0 z^2 - b u0^2 z^3,  z(0) = 1, z'(0) = 0,  event z = x_s / u0 (x = 0),
# exact (a x_s + b x_s^3 = 0 is used analytically, no constant term is left to cancel); u0 and x_s
# are formed from delta without cancellation, so the tolerance is relative to the distance from the
# saddle and the integration error does not grow as delta -> 0.
# What cannot be helped is the data: s = omega^2 + mu A^2 is a difference, and its inputs are known
# to a unit of round-off u at best. The condition number of the period with respect to the inputs,
# kappa = sum_p |d ln T / d ln p|, follows from d ln T = -S (omega^2/s) d ln omega^2
# + (S omega^2/s - 1/2) d ln(mu A^2), S = -d ln T / d ln s at fixed mu A^2 (period_log_sensitivity);
# it grows like 1 / ((1 + epsilon) ln(1 / (1 + epsilon))). Where kappa u > rtol, a perturbation of the
# inputs by one unit of round-off moves the period by more than rtol: no double-precision computation
# from these inputs can promise rtol, and the point is ILL_CONDITIONED (the closed form is still
# given; it carries the same sensitivity). The test depends on rtol, not on a fixed distance.
SADDLE_DELTA = 2e-3
UNIT_ROUNDOFF = 2.0 ** -53


@jit_noalloc
def period_log_sensitivity(m):
    """S = -d ln T / d ln s of T = 4 K(m) / sqrt(s), m = mu A^2 / (2 s), s = omega^2 + mu A^2, for
    m <= 0 (soft springs): S = E(m') / (2 K(m')) with m' = m / (m - 1) in [0, 1) (Jacobi's imaginary
    modulus transformation), from the AGM: E / K = 1 - sum_n 2^(n-1) c_n^2, c_0^2 = m'. 1/2 for the
    linear spring, ~1 / (2 ln(4 sqrt(1 - m))) towards the separatrix (m -> -inf)."""
    b = 1.0 / math.sqrt(1.0 - m)  # sqrt(1 - m'), free of the rounding of m' near 1
    a = 1.0
    acc = 0.5 * (1.0 - b * b)  # 2^-1 c_0^2
    pw = 0.5
    for _ in range(64):
        c = 0.5 * (a - b)
        pw *= 2.0
        acc += pw * c * c
        if abs(a - b) <= 2.220446049250313e-16 * a:
            break
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return 0.5 * (1.0 - acc)


@jit_noalloc
def period_condition(omega2, mu, A, k_omega2, k_q):
    """Condition number kappa of the period with respect to the model's inputs p, bounded by
    S (omega^2/s) k_omega2 + |S omega^2/s - 1/2| k_q, where k_omega2 = sum_p |d ln omega^2 / d ln p|
    and k_q = sum_p |d ln(mu A^2) / d ln p| (duffing: 2 and 3). Soft springs only (0 for mu >= 0:
    there s >= omega^2 and kappa stays of order k_omega2 + k_q; no separatrix to approach)."""
    if mu >= 0.0:
        return 0.0
    q = mu * A * A
    s = omega2 + q
    f = period_log_sensitivity(q / (2.0 * s)) * omega2 / s
    return f * k_omega2 + abs(f - 0.5) * k_q


@jit_noalloc
def symplectic_step(rtol):
    """Fixed step (scaled time) of the symplectic method for a tolerance: SYMPLECTIC_STEPS(rtol)
    steps per linearised period 2 pi, calibrated so that the period error stays below rtol over
    epsilon in [-0.99, 1e4] (measured by `python benchmarks/period_error.py`: at most 0.1 rtol from rtol
    1e-6 to 1e-12)."""
    return 2.0 * math.pi / math.ceil(SYMPLECTIC_C * rtol ** (-1.0 / SYMPLECTIC_ORDER))


# --------------------------------------------------------------------------- the declaration
# p = (omega, mu, A | t_max_periods | a, b, c, level, direction, w): parameters, the setting, and the
# internal slots prepare writes. One scaled oscillator serves both formulations (see prepare):
#   y'' = -(a y + b y^3 + c y^2),  event  direction (y - level) from > 0 to <= 0.
# The plain formulation is x = phi / A with (a, b, c, level, direction) = (omega^2/w^2, mu A^2/w^2,
# 0, 0, 1): x'' = -a x - b x^3, event x = 0 (the quadratic term and the level are exact zeros, so
# its results are those of the two-term rhs). The saddle formulation near the soft separatrix has
# c != 0, level = x_s / u0, direction = -1.
OMEGA, MU, AMP, T_MAX = 0, 1, 2, 3
IA, IB, IC, ILEVEL, IDIR, IW = 4, 5, 6, 7, 8, 9


@jit_noalloc
def point(p):
    """The point rescaled by powers of two (rescaled): (omega2', mu', A', i, j), and omega^2's
    mantissa o2 (its sign decides INFEASIBLE)."""
    o2, eo2 = omega_split(p[OMEGA])
    omega2, mu, A, i, j = rescaled(o2, eo2, p[MU], 0, p[AMP])
    return o2, omega2, mu, A, i, j


def duffing_classify(p):
    o2, omega2, mu, A, _, _ = point(p)
    return classify_scaled(o2, omega2, mu, A)


def prepare(p, rtol):
    """Per point: ILL_CONDITIONED where the period's condition number times round-off exceeds rtol
    (the closed forms are still given); OUT_OF_RANGE where the linearised frequency w itself is
    beyond double precision's normal range (the period then is too: below about 1e-308 s or
    above 1e308 s); else the scaled equation's coefficients, the event and w."""
    _, omega2, mu, A, i, _ = point(p)
    if not period_condition(omega2, mu, A, K_OMEGA2, K_Q) * UNIT_ROUNDOFF <= rtol:  # NaN-safe: a NaN bound flags
        return st.ILL_CONDITIONED
    if not scale_into(omega2, mu, A, i, p, IA):
        return st.OUT_OF_RANGE
    return st.OK


@jit_noalloc
def scale_into(omega2, mu, A, i, p, ia):
    """The scaled equation's (a, b, c, level, direction, w) into p[ia:ia + 6] for a point rescaled by
    powers of two (rescaled: omega2, mu, A and the time exponent i; a, b, c, level and direction are
    invariant, w = sqrt(omega^2 + |mu| A^2) is scaled back): the plain formulation, or the
    saddle-centred one within SADDLE_DELTA of the soft separatrix (shared with torsional_circuit's
    two-term system, whose slots start elsewhere). False where w is not a normal number."""
    muA2 = mu * A * A
    w2 = omega2 + abs(muA2)
    delta = (omega2 + muA2) / w2
    if mu < 0.0 and delta < SADDLE_DELTA:
        bneg = -muA2 / w2  # -b > 0
        xs = math.sqrt(1.0 + delta / bneg)  # saddle, x_s^2 = a / -b with a = delta - b
        u0 = delta / (bneg * (xs + 1.0))  # x_s - 1
        p[ia] = -2.0 * (delta + bneg)
        p[ia + 1] = -bneg * u0 * u0
        p[ia + 2] = 3.0 * bneg * xs * u0
        p[ia + 3] = xs / u0
        p[ia + 4] = -1.0
    else:
        p[ia] = omega2 / w2
        p[ia + 1] = muA2 / w2
        p[ia + 2] = 0.0
        p[ia + 3] = 0.0
        p[ia + 4] = 1.0
    w = times_pow2(math.sqrt(w2), -i)
    p[ia + 5] = w
    return normal(w)


def initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[IA] * y[0] - p[IB] * y[0] * y[0] * y[0] - p[IC] * y[0] * y[0]


def jac(t, y, p, J):
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    J[1, 0] = -p[IA] - 3.0 * p[IB] * y[0] * y[0] - 2.0 * p[IC] * y[0]
    J[1, 1] = 0.0


def accel(t, q, p, a):
    a[0] = -p[IA] * q[0] - p[IB] * q[0] * q[0] * q[0] - p[IC] * q[0] * q[0]


def step_for(p, rtol):
    return symplectic_step(rtol)


def quarter_event(t, y, p):
    return p[IDIR] * (y[0] - p[ILEVEL])


def horizon(p):
    return p[T_MAX] * 2.0 * math.pi


def period_from_quarter(p, tau_q):
    return 4.0 * tau_q / p[IW]


def period_exact(p):
    _, omega2, mu, A, i, _ = point(p)
    return times_pow2(period_plain(omega2, mu, A), i)


def v_max(p):
    _, omega2, mu, A, i, j = point(p)
    return times_pow2(v_max_plain(omega2, mu, A), -(i + j))


def a_max(p):
    _, omega2, mu, A, i, j = point(p)
    return times_pow2(a_max_plain(omega2, mu, A), -(2 * i + j))


def kv(p, vmax, T):
    """v_max T / A, on the rescaled point (invariant; v_max or T may be beyond the range)."""
    _, omega2, mu, A, _, _ = point(p)
    return v_max_plain(omega2, mu, A) * period_plain(omega2, mu, A) / A  # 2 pi for the linear oscillator


def ka(p, amax, T):
    """a_max T^2 / A, on the rescaled point (invariant)."""
    _, omega2, mu, A, _, _ = point(p)
    T = period_plain(omega2, mu, A)
    return a_max_plain(omega2, mu, A) * T * T / A  # 4 pi^2 for the linear oscillator


def epsilon(p):
    o2, eo2 = omega_split(p[OMEGA])
    return epsilon_split(o2, eo2, p[MU], 0, p[AMP])


def relative_error(p, value, reference):
    return relative_difference(value, reference)


@jit_noalloc
def relative_difference(value, reference):
    """|value - reference| / |reference|, both scaled by the power of two of reference first (exact):
    the difference of two periods near 1e-300 would be subnormal and lose its digits."""
    if PLAIN_LO <= abs(reference) <= PLAIN_HI and abs(value) <= PLAIN_HI:
        return abs(value - reference) / abs(reference)  # as written, where nothing leaves the normal range
    e = exponent(reference)
    r = math.ldexp(reference, -e)
    return abs(math.ldexp(value, -e) - r) / abs(r)


def energy(y, p):
    """The scaled equation's energy y'^2 / 2 + a y^2 / 2 + b y^4 / 4 + c y^3 / 3 (either
    formulation): conserved along every trajectory (the oscillator is undamped)."""
    x, v = y[0], y[1]
    return 0.5 * v * v + 0.5 * p[IA] * x * x + 0.25 * p[IB] * x**4 + p[IC] * x**3 / 3.0


def scaled_period(p):
    """The period in the scaled equation's own time: T w."""
    return period_exact(p) * p[IW]


MODEL = OdeModel(
    name="duffing",
    description="Undamped Duffing oscillator phi'' + omega^2 phi + mu phi^3 = 0 released from rest at phi = A",
    source="Klyuchkovskyi, torsional oscillating circuits, eq. (3); physics.md section 1",
    references=(
        'Klyuchkovskyi, "Synthesis of motion laws of the rocking link of spatial torsional oscillating circuits" '
        "(printing-machine automata)",
        "mechsweep docs/physics.md section 1: the checks and corrections made to the source",
    ),
    params=(
        Param("omega", "ω", "rad s-1", "linear natural frequency", lo=0.0, lo_open=True, latex=r"$\omega$"),
        Param("mu", "μ", "rad-2 s-2", "cubic stiffness coefficient (> 0 hard, < 0 soft)", latex=r"$\mu$"),
        Param("A", "A", "rad", "amplitude, released at rest from φ = A", lo=0.0, latex="$A$"),
    ),
    settings=(T_MAX_PERIODS,),
    internal=("a", "b", "c", "level", "direction", "w"),
    states=("x", "dx"),
    classify=duffing_classify,
    prepare=prepare,
    initial=initial,
    rhs=rhs,
    jac=jac,
    accel=accel,
    symplectic_step=step_for,
    symplectic_order=SYMPLECTIC_ORDER,
    # the energy drift of bench workprecision: omega = mu = A = 1 is x'' = -x/2 - x^3/2 in scaled time
    invariant=Invariant(energy, at={"omega": 1.0, "mu": 1.0, "A": 1.0}, period=scaled_period,
                        problem="x'' = -x/2 - x^3/2, x(0) = 1, x'(0) = 0"),
    # bench workprecision: the integrated period against its elliptic closed form, on the shipped scene
    workprecision=WorkPrecision(scene="sweeps/duffing_amplitude_period.toml", output="period",
                                reference="period_exact"),
    measurements=(
        FirstEvent("period", quarter_event, t_max=horizon, value=period_from_quarter, symbol="T", unit="s",
                   long_name="period of the free oscillation", latex="$T$"),
    ),
    closed_forms=(
        ClosedForm("period_exact", period_exact, "T_exact", "s", "period (elliptic closed form)",
                   latex=r"$T_\mathrm{exact}$"),
        ClosedForm("period_error", relative_error, "|T - T_exact| / T_exact", "1",
                   "relative error of the integrated period", needs=("period", "period_exact"),
                   latex=r"$|T - T_\mathrm{exact}|/T_\mathrm{exact}$"),
        ClosedForm("v_max", v_max, "v_max", "rad s-1", "maximum angular velocity", latex=r"$v_\max$"),
        ClosedForm("a_max", a_max, "a_max", "rad s-2", "maximum angular acceleration", latex=r"$a_\max$"),
        ClosedForm("kv", kv, "k_v = v_max T / A", "1", "velocity coefficient (2π when linear)",
                   needs=("v_max", "period_exact"), output_needs=(), latex=r"$k_v = v_\max T/A$"),
        ClosedForm("ka", ka, "k_a = a_max T^2 / A", "1", "acceleration coefficient (4π² when linear)",
                   needs=("a_max", "period_exact"), output_needs=(), latex=r"$k_a = a_\max T^2/A$"),
        ClosedForm("epsilon", epsilon, "ε = μ A² / ω²", "1", "nonlinearity parameter",
                   latex=r"$\varepsilon = \mu A^2/\omega^2$"),
    ),
    statuses=(st.INFEASIBLE, st.NOT_OSCILLATORY, st.NO_MOTION, st.OUT_OF_RANGE, *st.INTEGRATION_FAILURES),
    status_notes={
        st.INFEASIBLE: "omega^2 <= 0: no stable equilibrium at phi = 0 to oscillate about",
        st.NOT_OSCILLATORY: "at or beyond the soft separatrix |mu| A^2 >= omega^2 (mu < 0)",
        st.NO_MOTION: "A = 0: no motion, ratios to A undefined",
        st.NO_EVENT: "the quarter-period crossing did not happen within the horizon",
        st.ILL_CONDITIONED: "the period below 1 + epsilon = 6.8e-7 at the default rtol (next to the soft "
                            "separatrix); the closed form period_exact is still given",
        st.OUT_OF_RANGE: "the integrated period where sqrt(omega^2 + |mu| A^2) is beyond double precision's normal "
                         "range (the period then is below about 1e-308 s or above 1e308 s); every output is "
                         "computed on the point rescaled by powers of two, right wherever its value is representable",
    },
)

SPEC = MODEL.spec(module=__name__, attr="MODEL")
evaluate = SPEC.evaluate
