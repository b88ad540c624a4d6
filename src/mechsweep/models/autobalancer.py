"""Slider-crank on an elastic platform, balanced by two pendulums on the crank axis.

Over 700 lines on purpose: a model is one module, its derivation, declarations and per-point
functions beside the source equations they implement.

Source: Dubovik & Zamyatin, "Static balancing of a slider-crank mechanism"; equations (1)-(8)
as corrected in physics.md section 2 (damping of the pendulums relative to the crank, platform
damping, omega^2 = c / M, the factor 2 in the balancing condition, "or" between the two stable
ranges).

Lagrange derivation (ours; it confirms eq. (1)-(3) with psi counter-clockwise)
------------------------------------------------------------------------------
Generalised coordinates q = (xi, eta, gamma1, gamma2); the crank angle phi = Omega t and the
conrod angle psi(phi) are prescribed. Relative to the crank axis B = (xi, eta) the masses sit at
  crank centre S3: S3 e(phi); conrod centre: l3 e(phi) + S4 e(psi); slider: l3 e(phi) + l4 e(psi);
  correcting mass: l3 e(phi) - S_k e(psi); pendulum i: a e(gamma_i) (mass m, inertia I_B about B),
with e(x) = (cos x, sin x), and E = l3 e(phi) + l4 e(psi) on the stroke line eta_rel = 0, i.e.
l3 sin(phi) + l4 sin(psi) = 0, cos(psi) > 0, psi counter-clockwise. The first moment of the
crank-conrod-slider-m_k set about B is therefore A0 e(phi) + A1 e(psi) with
A0 = m3 S3 + (m4 + m5 + m_k) l3 and A1 = m4 S4 + m5 l4 - m_k S_k. Kinetic energy:
  T = M/2 (xi'^2 + eta'^2) + (xi', eta') . d/dt[A0 e(phi) + A1 e(psi) + m a sum_i e(gamma_i)]
      + I_B/2 sum_i gamma_i'^2 + (terms in phi', psi' only),
M = every translating mass including both pendulums. Potential c_xi xi^2/2 + c_eta eta^2/2,
Rayleigh function b_xi xi'^2/2 + b_eta eta'^2/2 + h/2 sum_i (gamma_i' - Omega)^2. Lagrange's
equations give exactly eq. (1)-(3) of physics.md:
  xi:    M xi'' + d^2/dt^2 [A0 cos phi + A1 cos psi + m a sum cos gamma_i] = -c_xi xi - b_xi xi'
  eta:   M eta'' + d^2/dt^2 [A0 sin phi + A1 sin psi + m a sum sin gamma_i] = -c_eta eta - b_eta eta'
         (written out: -Omega^2 A0 sin phi + A1 (psi'' cos psi - psi'^2 sin psi) + ..., the sign
         physics.md prints; with psi counter-clockwise (sin psi)'' = (l3/l4) Omega^2 sin phi)
  gamma_i: I_B gamma_i'' + m a (eta'' cos gamma_i - xi'' sin gamma_i) = -h (gamma_i' - Omega)
(the velocity terms of the gamma_i equation cancel). tests/test_autobalancer.py re-derives them
with sympy from the positions above and compares accelerations at random states.
psi: sin psi = -lambda sin phi, lambda = l3 / l4 < 1, cos psi = sqrt(1 - lambda^2 sin^2 phi),
psi' = -lambda Omega cos phi / cos psi, psi'' = (lambda Omega^2 sin phi + psi'^2 sin psi) / cos psi.

Numerics
--------
Everything is integrated in scaled form: time tau = Omega t (= phi), lengths in units of the
pendulum arm a (x = xi / a, y = eta / a), so rtol / atol mean the same thing at every grid point
(atol applies to x, y, gamma_i and their tau-derivatives). Dividing eq. (1)-(2) by m a Omega^2
and eq. (3) by m a^2 Omega^2:
  mu x'' - alpha0 cos tau - alpha1 (psi'' sin psi + psi'^2 cos psi) - sum (g_i'' s_i + g_i'^2 k_i) = -kx x - dx x'
  mu y'' - alpha0 sin tau + alpha1 (psi'' cos psi - psi'^2 sin psi) + sum (g_i'' k_i - g_i'^2 s_i) = -ky y - dy y'
  iota g_i'' + (y'' k_i - x'' s_i) = -eh (g_i' - 1)
with s_i, k_i = sin, cos gamma_i, mu = M/m, alpha0 = A0/(m a), alpha1 = A1/(m a), iota = I_B/(m a^2),
kx = c_xi/(m Omega^2), dx = b_xi/(m Omega), eh = h/(m a^2 Omega). The 4x4 mass matrix is solved
in closed form: eliminating g_i'' = (Q_i - (y'' k_i - x'' s_i)) / iota, Q_i = -eh (g_i' - 1), leaves
  [mu - S_ss/iota, S_sk/iota; S_sk/iota, mu - S_kk/iota] [x''; y''] = [Rx; Ry]
(S_ss = sum s_i^2, S_sk = sum s_i k_i, S_kk = sum k_i^2), positive definite for all gamma when
mu iota > 2, guaranteed by M > 2 m and I_B >= m a^2 (checked per point, else INFEASIBLE).

Balanced state (A1 = 0, eq. (4), (5), (8)): x = y = 0, gamma_i = tau + Theta_i, Theta_{1,2} =
+/- arccos(-A0 / (2 m a)); it exists for 0 <= A0 <= 2 m a and is isolated only for 0 < A0 < 2 m a:
at A0 = 0 any opposite pair of pendulums balances (a family), at A0 = 2 m a the two solutions
merge (Theta = pi); in both a Floquet multiplier is exactly 1, so these ends are NOT_BALANCEABLE
for the stability outputs (theta itself is still given there).

Floquet: the variational equations Phi' = J(tau, z*(tau)) Phi (8x8) about the exact balanced
solution z* (x = y = 0, gamma_i = tau + Theta_i, known in closed form), over one period tau = 2 pi:
the 64 equations of Phi alone (``variational``, ``variational_jac``: the layer's Floquet with the
model's own variational system); J is the analytic Jacobian
(directional derivatives of the closed-form accelerations, ``_jvp``). floquet_max =
max |eig(Phi(2 pi))|; the layer adds the way the critical multiplier leaves the unit circle
(floquet_max_kind: +1, -1 or a complex pair) and its angle (floquet_max_angle).

Direct simulation: start at gamma_i = Theta_i +/- perturbation (gamma1 up, gamma2 down),
gamma_i' = Omega, platform at rest, where Theta_i are the *reference angles*: the balanced angles
(8) when A0 <= 2 m a (for A1 != 0 these balance the first harmonic only), otherwise pi for both
(opposite the unbalance). The phase error of a sample is max_i |wrap(gamma_i - Omega t - Theta_i)|
minimised over the two labellings of the pendulums (they pass through each other on the shaft:
the swapped state is the same physical balanced state).

Decision rule of ``stable_sim`` (settings in brackets), from the phase-error samples e(t) and the
platform amplitude r(t) = sqrt(xi^2 + eta^2), sampled [monitor_samples_per_revolution] times per
revolution, [residual_samples_per_revolution] times in the last 10 % of the horizon:
  e0     = max e over the first revolution (the initial perturbation),
  e_late = max e over the last 10 % of the horizon, r_late likewise,
  r_ref  = max r over the first 10 % of the horizon (the platform's response to the perturbation);
  e_before = max e over the 10 % of the horizon before the last 10 %;
  stable   (1) if e_late <= settle_threshold and e_late <= decay_ratio e0 and r_late <= decay_ratio r_ref
               and the error is not growing at the end (e_late <= e_before, or e_late below the noise
               floor 1e-3 settle_threshold),
  unstable (0) if e_late >= growth_ratio e0 and e_before >= growth_ratio e0 (it left and stayed away
               for the last 20 % of the horizon),
  otherwise UNDECIDED (stable_sim NaN): slow convergence or slow growth within the horizon.
The envelope test is on maxima over whole windows, so oscillating errors do not fool it. A
point whose largest Floquet multiplier rho is so close to 1 that rho^horizon is not small (0.9988^300
= 0.70 at the example below) converges or departs too slowly to be decided within the horizon:
UNDECIDED; raise horizon_revolutions for it.

What the kick verdict means. stable_sim is the fate of one kicked trajectory within the horizon:
1, it came back to the balanced state; 0, it was at least growth_ratio times the kick away over the
whole last 20 % of the horizon, i.e. it had not come back by the end. Floquet (floquet_max,
stable_floquet) answers for infinitesimal kicks. So stable_sim = 1 is evidence of stability (a
kicked trajectory came back), but stable_sim = 0 where stable_floquet = 1, with status ok, is not an
error: the balanced state is stable and its basin of attraction is smaller than the kick (or the
way back is longer than the horizon). To tell, simulate the point again with a smaller
perturbation and a longer horizon. Example (tests/test_autobalancer.py,
test_kick_verdict_is_the_fate_of_one_kick_in_a_finite_basin): Omega = 22.28 rad/s, M = 23 kg,
m = 1 kg (2 m / M = 0.087), a = 0.1 m, I_B = 0.01553 kg m2, A0 = 0.01257 kg m, h = 0.2665 N m s,
omega_xi = 20 < Omega < omega_eta = 24.86 rad/s, zeta_xi = 0.0364, zeta_eta = 0: floquet_max =
0.99881, stable; a 0.1 rad kick leaves for a coexisting steady motion (the pendulums slip
through every phase relative to the crank, the platform keeps vibrating at 0.074 m), stable_sim
= 0 at 300 and at 2000 revolutions; a 0.01 rad kick comes back, stable_sim = 1 at 2000
revolutions (UNDECIDED at the default 300, see above). On the shipped stability chart
(`mechsweep run sweeps/autobalancer_stability_chart.toml`, then `mechsweep info` on the dataset:
3540 points decided by both) the verdicts disagree at 9 points, all Floquet-stable with
stable_sim = 0, where the dataset puts them: heavy pendulums (2 m / M from 0.136 to 0.277) and
Omega > omega_eta; at none does the simulation say stable where Floquet says unstable.

Other outputs and rules:
- stable_first_approx: the source assumes omega_xi < omega_eta; for omega_xi > omega_eta the rule
  is applied to the lower and the higher of the two frequencies (with A1 = 0 the problem is
  symmetric in the two axes). Strict inequalities: 0 on the boundaries.
- Resonances and boundaries within rounding. c_j - M Omega^2 is known to a few ulps of its terms (c_j =
  M omega_j^2, M Omega^2 and an Omega typed or computed equal to omega_j are all rounded), so a detuning
  |c_j - M Omega^2| <= RESONANCE_RTOL max(c_j, M Omega^2) (16 ulps, 3.6e-15) counts as a resonance:
  there Re H_j = 0, and if b_j Omega is within the same tolerance too P_approx is SINGULAR (NaN; an
  undamped resonance, where P is infinite). Nearer than NEAR_RESONANCE (1e-6) the detuning is
  recomputed from exact products, so a P_approx given near a resonance is right to a few ulps of
  itself. stable_damped_approx is 1 only if P < 0 beyond P's error bound (the change of P when each
  detuning moves by the tolerance, plus rounding): a P within rounding of 0 (the damped rule's
  boundary, e.g. omega_p when undamped) gives 0, as stable_first_approx does on its boundaries, where
  an Omega within 8 ulps of omega_lo, omega_p or omega_hi counts as on the boundary. No verdict is
  set by the sign of a rounding error (tests/test_autobalancer_resonance.py).
- Mass matrix: its smallest eigenvalue, M - 2 m^2 a^2 / I_B (pendulums aligned or opposite), relative
  to M is gap = 1 - 2 m^2 a^2 / (M I_B). gap <= RESONANCE_RTOL is INFEASIBLE (singular or indefinite:
  M > 2 m and I_B >= m a^2 with its slack do not ensure M I_B > 2 m^2 a^2); where the accelerations'
  round-off MASS_ERROR u / gap exceeds rtol the point is ILL_CONDITIONED (no integration, closed
  forms kept).
- stable_floquet is UNDECIDED when |floquet_max - 1| <= max(floquet_margin, 100 rtol) (floquet_max
  is within 0.032 rtol of the reference at every rtol from 1e-4 to 1e-12 over the 64 chart points
  of `mechsweep bench workprecision autobalancer`).
- settling_time: NO_EVENT (NaN) when the phase error is still above settle_threshold at the end.
- INFEASIBLE (all outputs NaN): I_B < m a^2 (relative slack 1e-9), M <= 2 m (M includes both
  pendulums), M I_B <= 2 m^2 a^2 (1 + RESONANCE_RTOL) (the mass matrix), l3 >= l4 when both are
  given, A1 != 0 without l3, l4, or a platform parameter pair not given.

Status of a point: the most severe problem among the outputs asked for, in the order
INFEASIBLE > OUT_OF_RANGE > NONFINITE > STEP_UNDERFLOW > MAX_STEPS > STIFF > ILL_CONDITIONED > SINGULAR >
NOT_REPRODUCIBLE > NOT_BALANCEABLE > UNDECIDED > NO_EVENT; outputs that could be computed are kept. OUT_OF_RANGE:
inputs of such magnitudes that a quantity leaves double precision's range (``in_range``: those every
output needs, all outputs NaN; a closed form's own, that output NaN; prepare: a scaled group of the
equations of motion beyond 2^300, the integrated outputs NaN). STIFF: dop853 spent its step budget at the
stability limit (strong pendulum damping h / (m a^2 Omega) of order 1e3 and more, a platform far stiffer
than the crank speed); auto and radau integrate such points.
NOT_REPRODUCIBLE: a simulated output (residual_amplitude, phase_error, settling_time, stable_sim,
the histories) moved by more than reproducibility_factor (rtol |value| + atol) when the trajectory
was integrated again at rtol / 100 (the Recheck below; the rule and its measured cost: TIGHTEN in tests/reference/autobalancer_kernels.py);
the first value is still stored.
Every output is a function of its point and the solver settings only: the simulation samples
that enter the measurements do not depend on the outputs asked for (the history samples are
extra rows that measure() skips), each trajectory starts from its own state with fresh solver
counters, and the lanes give the one-trajectory results bitwise
(tests/test_autobalancer_reproducible.py draws output subsets, point subsets and run orders). NOT_BALANCEABLE is set only when a
balanced-state output (theta, floquet_max, stable_floquet, stable_sim, phase_error,
settling_time) is asked for at a point without an (isolated) balanced state;
residual_amplitude and the histories are always computed (they measure the balancing residual).
residual_amplitude_h1 and residual_amplitude_phase (the layer's Steady measurement) are the
amplitude and phase of the first harmonic (crank frequency) of the platform displacement over the
same window.

On the model layer (docs/model-layer.md): this module is the declaration (``MODEL``, an OdeModel):
the parameters, settings and outputs above, the equations of motion in scaled form (``scaled_rhs``,
``scaled_jacobian``, called by ``rhs``/``jac`` with the scaled parameters that ``prepare`` writes
into the internal slots), ``classify`` (INFEASIBLE), the closed forms, and the measurements: Floquet
(floquet_max, stable_floquet), Kick (stable_sim, settling_time, phase_error), Steady
(residual_amplitude) and four Histories, one sampled trajectory per point; the status rules above
are the measurements' own (their ``classify``: NOT_BALANCEABLE), ``status_order`` (the severity
above) and ``Recheck`` (NOT_REPRODUCIBLE).
"""
from __future__ import annotations

import math

import numpy as np

from .. import status as st
from .._jit import jit, jit_inline, jit_noalloc
from ..model.measure import ClosedForm, Floquet
from ..model.sampled import History, Kick, Recheck, Steady
from ..model.ode import OdeModel
from ..model.workprecision import WorkPrecision
from ..special import ieee_sqrt, sincos
from ._scaling import DBL_MAX, full_precision, normal, product_in_range, quotient_in_range
from ..model.spec import ExtraDim, Output, Param, Setting

TWO_PI = 2.0 * math.pi

# ----------------------------------------------------------------------------- parameters
PARAM_NAMES = (
    "Omega", "M", "m", "a", "I_B", "A0", "h",
    "omega_xi", "omega_eta", "zeta_xi", "zeta_eta", "c_xi", "c_eta", "b_xi", "b_eta",
    "A1", "l3", "l4", "m4", "S4", "m5", "S_k",
)
PAIRS = (("omega_xi", "c_xi"), ("omega_eta", "c_eta"), ("zeta_xi", "b_xi"), ("zeta_eta", "b_eta"))

# Scaled parameter vector p of the equations of motion (see module docstring).
IP_MU, IP_ALPHA0, IP_ALPHA1, IP_LAM, IP_IOTA, IP_KX, IP_KY, IP_DX, IP_DY, IP_EH, IP_TH1, IP_TH2 = range(12)
NP = 12

IB_SLACK = 1e-9  # relative round-off allowed in I_B >= m a^2 (a point-mass pendulum is legal)

# Resonance tolerance: c_j - M Omega^2 is known only to a few ulps of its terms (c_j = M omega_j^2 and
# M Omega^2 are rounded, and an Omega typed or computed to equal omega_j is itself rounded), so a
# detuning |c_j - M Omega^2| <= RESONANCE_RTOL max(c_j, M Omega^2) is a resonance: 16 ulps, which covers
# every way of building Omega = omega_j (or omega_p) tried in tests/test_autobalancer_resonance.py and
# one ulp of Omega either side. The same relative tolerance (halved: omega ~ sqrt(c)) places Omega on a
# frequency boundary of stable_first_approx, and bounds the mass-matrix gap of classify.
EPS = 2.0 ** -52
RESONANCE_RTOL = 16.0 * EPS
# Closer than this (relative to the terms) the detuning is recomputed from exact products, so that a
# P_approx given near a resonance is right to a few ulps of its own size, not of the terms'.
NEAR_RESONANCE = 1e-6
# The accelerations' relative error is MASS_ERROR u / gap, gap = 1 - 2 m^2 a^2 / (M I_B) the relative
# distance of the mass matrix from singular (pendulums aligned or opposite): measured 2.2-2.4 u / gap
# against 50-digit values at gaps 1e-4 .. 1e-14 (tests/test_autobalancer_resonance.py); 4 bounds it.
MASS_ERROR = 4.0
UNIT_ROUNDOFF = 2.0 ** -53

# Status severity (most severe first): what a point shows when several problems occur.
# NOT_REPRODUCIBLE ranks above the statuses that leave an output NaN with a reason: it warns
# about a value that is stored and would otherwise look trustworthy.
STATUS_ORDER = (st.INFEASIBLE, st.OUT_OF_RANGE, st.NONFINITE, st.STEP_UNDERFLOW, st.MAX_STEPS, st.STIFF,
                st.ILL_CONDITIONED, st.SINGULAR, st.NOT_REPRODUCIBLE, st.NOT_BALANCEABLE, st.UNDECIDED, st.NO_EVENT)


# ----------------------------------------------------------------------------- kinematics
@jit_inline
def conrod_terms(sphi, cphi, lam):
    """A1 factors of eq. (1) and (2) (tau-derivatives, Omega = 1) from sin and cos of phi = tau:
    (psi'' sin psi + psi'^2 cos psi, psi'' cos psi - psi'^2 sin psi),
    psi from l3 sin(phi) + l4 sin(psi) = 0, cos psi > 0, lam = l3 / l4 < 1.
    Exactly (0, 0) for lam = 0; computed then selected, without a branch, so that the lane
    right-hand side vectorises."""
    spsi = -lam * sphi
    cpsi = ieee_sqrt(1.0 - spsi * spsi)
    dpsi = -lam * cphi / cpsi
    ddpsi = (lam * sphi + spsi * dpsi * dpsi) / cpsi
    fx = ddpsi * spsi + dpsi * dpsi * cpsi
    fy = ddpsi * cpsi - dpsi * dpsi * spsi
    none = lam == 0.0
    return (0.0 if none else fx), (0.0 if none else fy)


# ----------------------------------------------------------------------------- equations of motion
@jit_inline
def accelerations(tau, x, y, g1, g2, xd, yd, w1, w2, p):
    """Closed-form solution of the mass-matrix system of eq. (1)-(3) (scaled).

    Returns (x'', y'', g1'', g2'', s1, k1, s2, k2, K11, K12, K22, det): the accelerations and
    the intermediate values the Jacobian reuses.
    """
    s1, k1 = sincos(g1)  # one call for both: trigonometry is half the cost of this function
    s2, k2 = sincos(g2)
    st_, ct_ = sincos(tau)
    return accelerations_trig(x, y, xd, yd, w1, w2, s1, k1, s2, k2, st_, ct_, p[IP_MU], 1.0 / p[IP_IOTA], p[IP_EH],
                              p[IP_KX], p[IP_KY], p[IP_DX], p[IP_DY], p[IP_ALPHA0], p[IP_ALPHA1], p[IP_LAM])


@jit_inline
def accelerations_trig(x, y, xd, yd, w1, w2, s1, k1, s2, k2, st_, ct_, mu, inv, eh, kx, ky, dx, dy, al0, al1, lam):
    """accelerations() from the sines and cosines of g1, g2, tau and the scaled parameters
    (inv = 1 / iota): shared by the one-trajectory and the lane right-hand sides, so both
    compute the same floats in the same order."""
    q1 = -eh * (w1 - 1.0)  # pendulum damping relative to the crank, eq. (3) [fix]
    q2 = -eh * (w2 - 1.0)
    cx, cy = conrod_terms(st_, ct_, lam)
    # eq. (1): everything except the acceleration terms, moved to the right-hand side
    rx = -kx * x - dx * xd + al0 * ct_ + al1 * cx + w1 * w1 * k1 + w2 * w2 * k2
    # eq. (2)
    ry = -ky * y - dy * yd + al0 * st_ - al1 * cy + w1 * w1 * s1 + w2 * w2 * s2
    # eq. (3) solved for g_i'' and substituted: 2x2 system in x'', y''
    rx += inv * (s1 * q1 + s2 * q2)
    ry -= inv * (k1 * q1 + k2 * q2)
    k11 = mu - inv * (s1 * s1 + s2 * s2)
    k12 = inv * (s1 * k1 + s2 * k2)
    k22 = mu - inv * (k1 * k1 + k2 * k2)
    det = k11 * k22 - k12 * k12
    inv_det = 1.0 / det
    xdd = (k22 * rx - k12 * ry) * inv_det
    ydd = (k11 * ry - k12 * rx) * inv_det
    g1dd = (q1 - (ydd * k1 - xdd * s1)) * inv  # eq. (3)
    g2dd = (q2 - (ydd * k2 - xdd * s2)) * inv
    return xdd, ydd, g1dd, g2dd, s1, k1, s2, k2, k11, k12, k22, det


@jit_noalloc
def scaled_rhs(tau, z, p, dz):
    """Scaled state z = (x, y, g1, g2, x', y', g1', g2'), ' = d/dtau, tau = Omega t."""
    xdd, ydd, g1dd, g2dd, _, _, _, _, _, _, _, _ = accelerations(
        tau, z[0], z[1], z[2], z[3], z[4], z[5], z[6], z[7], p)
    dz[0] = z[4]
    dz[1] = z[5]
    dz[2] = z[6]
    dz[3] = z[7]
    dz[4] = xdd
    dz[5] = ydd
    dz[6] = g1dd
    dz[7] = g2dd


@jit_inline
def _jvp_acc(w1, w2, p, xdd, ydd, s1, k1, s2, k2, k11, k12, k22, det, vx, vy, vg1, vg2, vxd, vyd, vw1, vw2):
    """Directional derivative of the accelerations (x'', y'', g1'', g2'') along the state
    direction v = (vx, vy, vg1, vg2, vxd, vyd, vw1, vw2): the analytic Jacobian times v.

    Differentiates K [x''; y''] = [Rx; Ry] and g_i'' = (Q_i - (y'' k_i - x'' s_i)) / iota:
    d[x''; y''] = K^-1 (dR - dK [x''; y'']).
    """
    inv = 1.0 / p[IP_IOTA]
    eh = p[IP_EH]
    q1 = -eh * (w1 - 1.0)
    q2 = -eh * (w2 - 1.0)
    drx = (-p[IP_KX] * vx - p[IP_DX] * vxd
           + (-w1 * w1 * s1 + inv * k1 * q1) * vg1 + (2.0 * w1 * k1 - inv * eh * s1) * vw1
           + (-w2 * w2 * s2 + inv * k2 * q2) * vg2 + (2.0 * w2 * k2 - inv * eh * s2) * vw2)
    dry = (-p[IP_KY] * vy - p[IP_DY] * vyd
           + (w1 * w1 * k1 + inv * s1 * q1) * vg1 + (2.0 * w1 * s1 + inv * eh * k1) * vw1
           + (w2 * w2 * k2 + inv * s2 * q2) * vg2 + (2.0 * w2 * s2 + inv * eh * k2) * vw2)
    sk1 = 2.0 * s1 * k1
    sk2 = 2.0 * s2 * k2
    dk11 = -inv * (sk1 * vg1 + sk2 * vg2)
    dk12 = inv * ((k1 * k1 - s1 * s1) * vg1 + (k2 * k2 - s2 * s2) * vg2)
    dk22 = -dk11
    r1 = drx - dk11 * xdd - dk12 * ydd
    r2 = dry - dk12 * xdd - dk22 * ydd
    dxdd = (k22 * r1 - k12 * r2) / det
    dydd = (k11 * r2 - k12 * r1) / det
    dg1dd = (-eh * vw1 - dydd * k1 + dxdd * s1 + (ydd * s1 + xdd * k1) * vg1) * inv
    dg2dd = (-eh * vw2 - dydd * k2 + dxdd * s2 + (ydd * s2 + xdd * k2) * vg2) * inv
    return dxdd, dydd, dg1dd, dg2dd


@jit_inline
def _jvp(w1, w2, p, xdd, ydd, s1, k1, s2, k2, k11, k12, k22, det, v, out):
    """J v for the 8-state rhs: v[4:8] (d of the velocities) into out[0:4], d of the
    accelerations into out[4:8]."""
    a, b, c, d = _jvp_acc(w1, w2, p, xdd, ydd, s1, k1, s2, k2, k11, k12, k22, det,
                          v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7])
    out[0] = v[4]
    out[1] = v[5]
    out[2] = v[6]
    out[3] = v[7]
    out[4] = a
    out[5] = b
    out[6] = c
    out[7] = d


@jit_noalloc
def _jacobian_block(tau, x, y, g1, g2, xd, yd, w1, w2, p, J, r0):
    """The 8x8 Jacobian at the given state into J[r0:r0+8, r0:r0+8] (other entries untouched)."""
    xdd, ydd, _, _, s1, k1, s2, k2, k11, k12, k22, det = accelerations(tau, x, y, g1, g2, xd, yd, w1, w2, p)
    for c in range(8):
        for r in range(4):
            J[r0 + r, r0 + c] = 1.0 if c == r + 4 else 0.0
        a, b, cc, d = _jvp_acc(w1, w2, p, xdd, ydd, s1, k1, s2, k2, k11, k12, k22, det,
                               1.0 if c == 0 else 0.0, 1.0 if c == 1 else 0.0, 1.0 if c == 2 else 0.0,
                               1.0 if c == 3 else 0.0, 1.0 if c == 4 else 0.0, 1.0 if c == 5 else 0.0,
                               1.0 if c == 6 else 0.0, 1.0 if c == 7 else 0.0)
        J[r0 + 4, r0 + c] = a
        J[r0 + 5, r0 + c] = b
        J[r0 + 6, r0 + c] = cc
        J[r0 + 7, r0 + c] = d


@jit_noalloc
def scaled_jacobian(tau, z, p, J):
    """The analytic 8x8 Jacobian d rhs / d z at (tau, z) (radau, tests)."""
    _jacobian_block(tau, z[0], z[1], z[2], z[3], z[4], z[5], z[6], z[7], p, J, 0)



# ----------------------------------------------------------------------------- Floquet (variational system about the exact balanced orbit)
@jit_noalloc
def variational_rhs(tau, Y, p, dY):
    """Phi' = J(tau) Phi about the exact balanced solution x = y = 0, g_i = tau + Theta_i,
    g_i' = 1 (eq. (4), (5), (8)); Phi stored column-major: column c is Y[8c:8c+8]."""
    xdd, ydd, _, _, s1, k1, s2, k2, k11, k12, k22, det = accelerations(
        tau, 0.0, 0.0, tau + p[IP_TH1], tau + p[IP_TH2], 0.0, 0.0, 1.0, 1.0, p)
    for c in range(8):
        _jvp(1.0, 1.0, p, xdd, ydd, s1, k1, s2, k2, k11, k12, k22, det,
             Y[8 * c:8 * c + 8], dY[8 * c:8 * c + 8])


@jit_noalloc
def variational_jacobian(tau, Y, p, J):
    """Jacobian of the (linear) variational system: block diagonal, J(tau) on the orbit 8 times."""
    for r in range(64):
        for c in range(64):
            J[r, c] = 0.0
    for b in range(8):
        _jacobian_block(tau, 0.0, 0.0, tau + p[IP_TH1], tau + p[IP_TH2], 0.0, 0.0, 1.0, 1.0, p, J, 8 * b)



# ----------------------------------------------------------------------------- phase errors, initial state
@jit_noalloc
def wrap(x):
    """x wrapped into [-pi, pi]."""
    return x - TWO_PI * math.floor(x / TWO_PI + 0.5)


@jit_noalloc
def phase_errors(tau, g1, g2, th1, th2):
    """Signed phase errors of the two pendulums against the reference angles, for the
    labelling (1->Theta_1, 2->Theta_2 or swapped) with the smaller maximum."""
    e11 = wrap(g1 - tau - th1)
    e22 = wrap(g2 - tau - th2)
    e12 = wrap(g1 - tau - th2)
    e21 = wrap(g2 - tau - th1)
    if max(abs(e11), abs(e22)) <= max(abs(e12), abs(e21)):
        return e11, e22
    return e12, e21


@jit
def initial_state(p, delta, z):
    """The perturbed balanced state the simulations start from (module docstring)."""
    z[0] = 0.0
    z[1] = 0.0
    z[2] = p[IP_TH1] + delta
    z[3] = p[IP_TH2] - delta
    z[4] = 0.0
    z[5] = 0.0
    z[6] = 1.0
    z[7] = 1.0


def history_revolutions(settings) -> np.ndarray:
    """Coordinate of the history outputs: crank revolutions t Omega / 2 pi."""
    return np.linspace(0.0, float(settings.get("horizon_revolutions", 300.0)),
                       int(settings.get("trajectory_samples", 600)))



# ----------------------------------------------------------------------------- cross-parameter rules
def check(given):
    """Exactly one of each platform pair; l3 and l4 when A1 is non-zero anywhere."""
    problems = []
    meaning = {"omega_xi": "platform natural frequency along xi (rad/s)", "c_xi": "platform stiffness along xi (N/m)",
               "omega_eta": "platform natural frequency along eta (rad/s)",
               "c_eta": "platform stiffness along eta (N/m)",
               "zeta_xi": "platform damping ratio along xi", "b_xi": "platform damping along xi (N s/m)",
               "zeta_eta": "platform damping ratio along eta", "b_eta": "platform damping along eta (N s/m)"}
    for first, second in PAIRS:
        if first in given and second in given:
            problems.append(f"{second}: both {first} = {_show(given[first])} and {second} = "
                            f"{_show(given[second])} are given; give exactly one of {first} "
                            f"({meaning[first]}) or {second} ({meaning[second]})")
        elif first not in given and second not in given:
            problems.append(f"{first}: missing; give exactly one of {first} ({meaning[first]}) or "
                            f"{second} ({meaning[second]})")
    nonzero = [v for v in given.get("A1", ()) if v != 0.0]
    if nonzero:
        for name, what in (("l3", "crank length BD"), ("l4", "conrod length DE")):
            if name not in given:
                problems.append(f"{name}: missing; A1 = {nonzero[0]:g} kg m is non-zero, so the conrod "
                                f"motion is needed: give {name} ({what}, m, with l3 < l4)")
    return problems


def _show(values):
    values = tuple(values)
    return f"{values[0]:g}" if len(values) == 1 else f"[{values[0]:g} ... {values[-1]:g}]"


# ----------------------------------------------------------------------------- declarations
REVOLUTION = ExtraDim("revolution", "1", "crank revolutions t Omega / 2 pi", history_revolutions)
_pos = dict(lo=0.0, lo_open=True)
_opt = dict(required=False, default=math.nan)

SETTINGS = (
    Setting("perturbation", 0.1, "rad", "initial pendulum perturbation (+ on gamma1, - on gamma2)", 1e-6, 1.0),
    Setting("horizon_revolutions", 300.0, "1", "simulated crank revolutions", 1.0, 1e5),
    Setting("settle_threshold", 0.01, "rad", "phase error below which a pendulum counts as settled", 1e-12, 1.0),
    Setting("trajectory_samples", 600, "1", "samples of the history outputs over the horizon", 2, 100_000,
            integer=True),
    # max over the last 10 %: 64 samples per revolution see a 2nd harmonic within 0.5 %
    Setting("residual_samples_per_revolution", 64, "1", "samples per revolution for residual_amplitude", 4, 4096,
            integer=True),
    # the phase error moves on the slow time scale (many revolutions): 8 per revolution is plenty
    Setting("monitor_samples_per_revolution", 8, "1", "phase-error samples per revolution", 1, 1024, integer=True),
    # stable: late envelopes at most half the early ones (and below settle_threshold)
    Setting("decay_ratio", 0.5, "1", "late / early envelope ratio below which a decay is accepted", 1e-6, 0.99),
    # unstable: late phase-error envelope at least twice the initial perturbation
    Setting("growth_ratio", 2.0, "1", "late / initial phase-error ratio above which growth is accepted", 1.01, 1e6),
    # floquet_max is accurate to ~0.1 rtol (measured); the margin used is max(floquet_margin, 100 rtol)
    Setting("floquet_margin", 1e-8, "1", "|floquet_max - 1| within which stable_floquet is undecided", 0.0, 0.1),
    # simulated outputs are re-integrated at rtol / 100 where they may be chaotic (the Recheck of MODEL)
    Setting("reproducibility_factor", 1000.0, "1",
            "a simulated output moving by more than this times (rtol abs(value) + atol) at rtol / 100 is "
            "not_reproducible (0: no check)", 0.0, 1e12),
)

PARAMS = (
    Param("Omega", "Ω", "rad s-1", "crank angular speed", **_pos, latex=r"$\Omega$"),
    Param("M", "M", "kg", "total translating mass (platform, mechanism, both pendulums)", **_pos, latex="$M$"),
    Param("m", "m", "kg", "mass of one pendulum", **_pos, latex="$m$"),
    Param("a", "a", "m", "pendulum arm BC (crank axis to pendulum centre of mass)", **_pos, latex="$a$"),
    Param("I_B", "I_B", "kg m2", "pendulum moment of inertia about the crank axis (at least m a²)", **_pos,
          latex="$I_B$"),
    Param("A0", "A0", "kg m", "rotating unbalance of the crank mechanism", lo=0.0,
          latex=r"$A_0 = m_3 S_3 + (m_4 + m_5 + m_k)\,l_3$"),
    Param("h", "h", "N m s rad-1", "pendulum damping relative to the crank", lo=0.0, latex="$h$"),
    Param("omega_xi", "ω_ξ", "rad s-1", "platform natural frequency along ξ", **_pos, **_opt,
          latex=r"$\omega_\xi = \sqrt{c_\xi/M}$"),
    Param("omega_eta", "ω_η", "rad s-1", "platform natural frequency along η", **_pos, **_opt,
          latex=r"$\omega_\eta = \sqrt{c_\eta/M}$"),
    Param("zeta_xi", "ζ_ξ", "1", "platform damping ratio along ξ", lo=0.0, **_opt,
          latex=r"$\zeta_\xi = b_\xi/(2 M \omega_\xi)$"),
    Param("zeta_eta", "ζ_η", "1", "platform damping ratio along η", lo=0.0, **_opt,
          latex=r"$\zeta_\eta = b_\eta/(2 M \omega_\eta)$"),
    Param("c_xi", "c_ξ", "N m-1", "platform stiffness along ξ", **_pos, **_opt, latex=r"$c_\xi$"),
    Param("c_eta", "c_η", "N m-1", "platform stiffness along η", **_pos, **_opt, latex=r"$c_\eta$"),
    Param("b_xi", "b_ξ", "N s m-1", "platform damping coefficient along ξ", lo=0.0, **_opt, latex=r"$b_\xi$"),
    Param("b_eta", "b_η", "N s m-1", "platform damping coefficient along η", lo=0.0, **_opt, latex=r"$b_\eta$"),
    Param("A1", "A1", "kg m", "conrod mass moment (0: corrected)",
          required=False, default=0.0, latex=r"$A_1 = m_4 S_4 + m_5 l_4 - m_k S_k$"),
    Param("l3", "l3", "m", "crank length BD", **_pos, **_opt, latex="$l_3$"),
    Param("l4", "l4", "m", "conrod length DE (longer than l₃)", **_pos, **_opt, latex="$l_4$"),
    Param("m4", "m4", "kg", "conrod mass", lo=0.0, **_opt, latex="$m_4$"),
    Param("S4", "S4", "m", "conrod centre of mass from D", lo=0.0, **_opt, latex="$S_4$"),
    Param("m5", "m5", "kg", "slider mass", lo=0.0, **_opt, latex="$m_5$"),
    Param("S_k", "S_k", "m", "correcting mass position from D (away from E)", **_pos, **_opt, latex="$S_k$"),
)

# The outputs' names, symbols, units, long names, kinds and dimensions (the measurements and closed
# forms below take them from here)
OUTPUTS = (
    Output("theta", "Θ₁", "rad", "balancing angle of pendulum 1 (Θ₂ = −Θ₁)",
           latex=r"$\Theta_1 = \arccos(-A_0/(2 m a))$"),
    Output("balanceable", "balanceable", "1", "1 if a balanced state exists (A₀ ≤ 2 m a and A₁ = 0)",
           latex=r"$A_0 \leq 2 m a,\ A_1 = 0$"),
    Output("m_k", "m_k", "kg", "correcting mass that makes A₁ = 0",
           needs_params=("m4", "S4", "m5", "S_k", "l4"), latex=r"$m_k = (m_4 S_4 + m_5 l_4)/S_k$"),
    Output("omega_p", "ω_p", "rad s-1", "first-approximation stability boundary",
           latex=r"$\omega_p = \sqrt{(\omega_\xi^2 + \omega_\eta^2)/2}$"),
    Output("stable_first_approx", "stable (1st approx.)", "1",
           "1 if stable by the source's first-approximation rule (corrected): ω_lo < Ω < ω_p or Ω > ω_hi",
           kind="verdict", latex=r"$\omega_\mathrm{lo} < \Omega < \omega_p \;\vee\; \Omega > \omega_\mathrm{hi}$"),
    Output("P_approx", "P(Ω)", "m N-1", "receptance sum of the damped platform",
           latex=r"$P(\Omega) = \mathrm{Re}(H_\xi + H_\eta)$"),
    Output("stable_damped_approx", "P(Ω) < 0", "1", "1 if P(Ω) < 0 (first approximation with damping)",
           needs=("P_approx",), kind="verdict", latex=r"$P(\Omega) < 0$"),
    Output("floquet_max", "max |ρ|", "1", "largest Floquet multiplier modulus of the balanced state",
           integrated=True, latex=r"$\max|\rho|$"),
    Output("stable_floquet", "stable (Floquet)", "1", "1 if the largest Floquet multiplier modulus is below 1",
           integrated=True, needs=("floquet_max",), kind="verdict", latex=r"$\max|\rho| < 1$"),
    Output("stable_sim", "stable (simulation)", "1",
           "1 if the perturbed balanced state settles, 0 if it departs (direct simulation)", integrated=True,
           kind="verdict", latex=r"$\mathrm{stable}_\mathrm{sim}$"),
    Output("residual_amplitude", "r_res", "m",
           "residual platform displacement, largest over the last 10 % of the simulation", integrated=True,
           latex=r"$r_\mathrm{res} = \max\sqrt{\xi^2 + \eta^2}$"),
    Output("phase_error", "δγ", "rad", "final pendulum phase error", integrated=True,
           latex=r"$\delta\gamma = \max_i|\gamma_i - \Omega t - \Theta_i|$"),
    Output("settling_time", "t_s", "s", "time after which the phase error stays below the settling threshold",
           integrated=True, latex="$t_s$"),
    Output("xi_history", "ξ(t)", "m", "platform displacement ξ over the simulation", integrated=True,
           extra_dims=(REVOLUTION,), latex=r"$\xi(t)$"),
    Output("eta_history", "η(t)", "m", "platform displacement η over the simulation", integrated=True,
           extra_dims=(REVOLUTION,), latex=r"$\eta(t)$"),
    Output("phase_error1_history", "δγ₁(t)", "rad", "phase error of pendulum 1 over the simulation",
           integrated=True, extra_dims=(REVOLUTION,), latex=r"$\delta\gamma_1(t)$"),
    Output("phase_error2_history", "δγ₂(t)", "rad", "phase error of pendulum 2 over the simulation",
           integrated=True, extra_dims=(REVOLUTION,), latex=r"$\delta\gamma_2(t)$"),
)

STATUSES = (st.INFEASIBLE, st.SINGULAR, st.NOT_BALANCEABLE, st.UNDECIDED, st.NOT_REPRODUCIBLE, st.OUT_OF_RANGE,
            *st.INTEGRATION_FAILURES)
STATUS_NOTES = {
    st.INFEASIBLE: "I_B < m a^2, M <= 2 m, M I_B within 16 ulps of 2 m^2 a^2 or below (a singular mass matrix), "
                   "l3 >= l4, A1 != 0 without l3 and l4, or a platform parameter pair not given (all outputs NaN)",
    st.SINGULAR: "an undamped resonance of the platform (c_j = M Omega^2 to 16 ulps of its terms, b_j Omega "
                 "within the same): P_approx and stable_damped_approx are NaN, Floquet is still computed",
    st.ILL_CONDITIONED: "the mass matrix is so close to singular (M I_B near 2 m^2 a^2) that the accelerations' "
                        "round-off exceeds rtol: the integrated outputs are NaN, the closed forms are kept",
    st.OUT_OF_RANGE: "inputs of such magnitudes that a quantity every output needs (2 m a, the platform's "
                     "omega, c, b) over- or underflows (all outputs NaN), or one a closed form needs (omega_p's "
                     "sum of squares, P_approx's squares, m_k's products: that output NaN), or a scaled group "
                     "of the equations of motion (M / m, c_xi / (m Omega^2), ...) is beyond 2^300 (the "
                     "integrated outputs NaN)",
    st.NOT_BALANCEABLE: "no isolated balanced state (A0 > 2 m a, A0 = 0, A0 = 2 m a, A1 != 0): balanced-state "
                        "outputs are NaN, residuals are kept",
    st.NO_EVENT: "the pendulums did not settle within the simulation (settling_time)",
    st.UNDECIDED: "the simulation neither settled nor diverged, or floquet_max is within "
                  "solver.floquet_margin of 1",
    st.NOT_REPRODUCIBLE: "integrated again at rtol / 100, a simulated output moved by more than "
                         "reproducibility_factor (rtol |value| + atol), or the second integration failed: the "
                         "value is stored, only its leading digits mean something (chaotic or "
                         "transient-dominated motion; simulations that did not settle early)",
}


# ----------------------------------------------------------------------------- the model on the layer
# Per point the engine calls prepare (the scaled parameters into the internal slots p[OFF:OFF+NP]),
# classify (INFEASIBLE), the closed forms, and the measurements (one sampled trajectory for the
# Kick, Steady and the Histories, one variational integration for Floquet): the engine (engine/)
# composes the chunk kernels for the scene's method from this declaration.
IX = {name: j for j, name in enumerate(PARAM_NAMES)}
I_Omega, I_M, I_m, I_a, I_IB, I_A0, I_h = (IX[k] for k in ("Omega", "M", "m", "a", "I_B", "A0", "h"))
I_omega_xi, I_c_xi, I_b_xi, I_zeta_xi = (IX[k] for k in ("omega_xi", "c_xi", "b_xi", "zeta_xi"))
I_omega_eta, I_c_eta, I_b_eta, I_zeta_eta = (IX[k] for k in ("omega_eta", "c_eta", "b_eta", "zeta_eta"))
I_A1, I_l3, I_l4, I_m4, I_S4, I_m5, I_S_k = (IX[k] for k in ("A1", "l3", "l4", "m4", "S4", "m5", "S_k"))
OFF = len(PARAM_NAMES) + len(SETTINGS)  # p[OFF:OFF + NP]: the scaled parameters (written by prepare)
I_PERT = len(PARAM_NAMES) + [s.name for s in SETTINGS].index("perturbation")


@jit
def _axis(om, c, b, zeta, M):
    """(omega, c, b) of one platform axis from either parametrisation: omega^2 = c / M [fix],
    b = 2 zeta M omega."""
    if math.isnan(om):
        om = math.sqrt(c / M)
    if math.isnan(c):
        c = M * om * om
    if math.isnan(b):
        b = 2.0 * zeta * M * om
    return om, c, b


@jit
def _xi(p):
    return _axis(p[I_omega_xi], p[I_c_xi], p[I_b_xi], p[I_zeta_xi], p[I_M])


@jit
def _eta(p):
    return _axis(p[I_omega_eta], p[I_c_eta], p[I_b_eta], p[I_zeta_eta], p[I_M])


def classify(p):
    """INFEASIBLE outside the physical domain: I_B < m a^2 (relative slack IB_SLACK), M <= 2 m, or
    M I_B within RESONANCE_RTOL of 2 m^2 a^2 or below (the mass matrix is then singular or indefinite
    where the pendulums are aligned or opposite), a platform pair not given, l3 >= l4, A1 != 0
    without l3, l4."""
    M, m, a, IB, A1, l3, l4 = p[I_M], p[I_m], p[I_a], p[I_IB], p[I_A1], p[I_l3], p[I_l4]
    wx, cx, bx = _xi(p)
    wy, cy, by = _eta(p)
    lengths = not math.isnan(l3) and not math.isnan(l4)
    ok = _inertia_at_least(IB, m, a) and M > 2.0 * m
    ok = ok and not _mass_gap(M, m, a, IB) <= RESONANCE_RTOL  # NaN (inputs beyond the range): in_range says
    # each pair given (by the inputs: an overflow of the derived values is a range problem, in_range)
    for i, j in ((I_omega_xi, I_c_xi), (I_omega_eta, I_c_eta), (I_zeta_xi, I_b_xi), (I_zeta_eta, I_b_eta)):
        ok = ok and not (math.isnan(p[i]) and math.isnan(p[j]))
    ok = ok and (not lengths or l3 < l4) and (A1 == 0.0 or lengths)
    if not ok:
        return st.INFEASIBLE
    return st.OK if in_range(p) else st.OUT_OF_RANGE


GROUP_RANGE = 2.0 ** 300  # scaled groups of the equations of motion: finite and at most this


@jit
def _inertia_at_least(IB, m, a):
    """I_B >= m a^2 (1 - IB_SLACK), also where m a^2 over- or underflows (compared on the mantissas)."""
    mma = m * a * a
    if normal(mma):
        return IB >= mma * (1.0 - IB_SLACK)
    fm, em = math.frexp(m)
    fa, ea = math.frexp(a)
    fI, eI = math.frexp(IB)
    return math.ldexp(fI, eI - em - 2 * ea) >= fm * fa * fa * (1.0 - IB_SLACK)


@jit
def in_range(p):
    """The quantities every output is formed from are normal numbers (or an exact 0 from a zero input):
    2 m a and A0 / (2 m a) (theta, the balanced state), the platform's omega, c, b (either
    parametrisation); else the point is OUT_OF_RANGE. The closed forms' own quantities are checked by
    their classify (first_approx_in_range, receptance_in_range, m_k_in_range), the integrated outputs'
    scaled groups by prepare."""
    m, a, A0 = p[I_m], p[I_a], p[I_A0]
    wx, cx, bx = _xi(p)
    wy, cy, by = _eta(p)
    two_ma = 2.0 * m * a
    return (normal(two_ma) and full_precision(A0 / two_ma) and normal(wx) and normal(cx) and full_precision(bx)
            and normal(wy) and normal(cy) and full_precision(by))


def first_approx_in_range(p):
    """omega_xi^2 + omega_eta^2 is a normal number (omega_p, stable_first_approx): else OUT_OF_RANGE
    (at omega_xi = omega_eta = 1e-200 the plain sum underflows and omega_p would be 0)."""
    wx = _xi(p)[0]
    wy = _eta(p)[0]
    return st.OK if normal(wx * wx + wy * wy) else st.OUT_OF_RANGE


@jit
def receptance_in_range(p):
    """The receptance's squares d^2, (b Omega)^2 of each axis (d = c - M Omega^2) are normal, or lost
    below 2^-62 of the other term of their sum (at c_xi = 1e160, d^2 overflows and P_approx would be 0);
    an exact d = 0 is left to the resonance test."""
    Om, M = p[I_Omega], p[I_M]
    _, cx, bx = _xi(p)
    _, cy, by = _eta(p)
    MO2 = M * Om ** 2
    ok = True
    for d, b in ((cx - MO2, bx), (cy - MO2, by)):
        d2 = d * d
        bO2 = (b * Om) ** 2
        ok = (ok and d2 <= DBL_MAX and bO2 <= DBL_MAX and (d == 0.0 or normal(d2) or bO2 >= 2.0 ** -960)
              and (b == 0.0 or normal(bO2) or d2 >= 2.0 ** -960))
    return ok


def m_k_in_range(p):
    """m_k's products and quotient are normal numbers or an exact 0 from a zero input. Where its
    parameters are not given (NaN: a scene that asks for m_k must give them), m_k is NaN and leaves
    the point's status to the other outputs."""
    if math.isnan(p[I_m4] + p[I_S4] + p[I_m5] + p[I_l4] + p[I_S_k]):
        return st.OK
    ok = (product_in_range(p[I_m4], p[I_S4]) and product_in_range(p[I_m5], p[I_l4])
          and quotient_in_range(p[I_m4] * p[I_S4] + p[I_m5] * p[I_l4], p[I_S_k]))
    return st.OK if ok else st.OUT_OF_RANGE


@jit
def _mass_gap(M, m, a, IB):
    """1 - 2 m^2 a^2 / (M I_B): how far the mass matrix of eq. (1)-(3) is from singular (its smallest
    eigenvalue is M - 2 m^2 a^2 / I_B, reached with the pendulums aligned or opposite)."""
    return 1.0 - 2.0 * ((m * a) / M) * ((m * a) / IB)  # as ratios: no overflow of (m a)^2 or M I_B


def prepare(p, rtol):
    """The scaled parameters of the equations of motion (module docstring) into p[OFF:OFF + NP],
    with the reference angles Theta_1,2: eq. (8) when A0 <= 2 m a, else pi for both.
    ILL_CONDITIONED (no integration; the closed forms are kept) where the mass matrix is so close to
    singular that the accelerations' round-off, MASS_ERROR u / gap, exceeds rtol."""
    Om, M, m, a, IB, A0, h = p[I_Omega], p[I_M], p[I_m], p[I_a], p[I_IB], p[I_A0], p[I_h]
    if not MASS_ERROR * UNIT_ROUNDOFF <= rtol * _mass_gap(M, m, a, IB):
        return st.ILL_CONDITIONED
    _, cx, bx = _xi(p)
    _, cy, by = _eta(p)
    A1, l3, l4 = p[I_A1], p[I_l3], p[I_l4]
    lam = l3 / l4 if (A1 != 0.0 and not math.isnan(l3) and not math.isnan(l4)) else 0.0
    two_ma = 2.0 * m * a
    th1 = math.acos(min(1.0, max(-1.0, -A0 / two_ma))) if A0 <= two_ma else math.pi  # eq. (8)
    th2 = -th1 if A0 <= two_ma else math.pi
    q = p[OFF:OFF + NP]
    q[IP_MU] = M / m
    q[IP_ALPHA0] = A0 / (m * a)
    q[IP_ALPHA1] = A1 / (m * a)
    q[IP_LAM] = lam
    q[IP_IOTA] = IB / (m * a * a)
    q[IP_KX] = cx / (m * Om ** 2)
    q[IP_KY] = cy / (m * Om ** 2)
    q[IP_DX] = bx / (m * Om)
    q[IP_DY] = by / (m * Om)
    q[IP_EH] = h / (m * a * a * Om)
    q[IP_TH1] = th1
    q[IP_TH2] = th2
    for j in range(NP):  # the right-hand side multiplies up to three groups: keep them below 2^300
        if not abs(q[j]) <= GROUP_RANGE:  # NaN-safe; a tiny group only scales a negligible term
            return st.OUT_OF_RANGE
    return 0


# --- closed forms (per point)
def theta(p):
    two_ma = 2.0 * p[I_m] * p[I_a]
    return math.acos(min(1.0, max(-1.0, -p[I_A0] / two_ma)))  # eq. (8) with the factor 2 [fix]


def has_balance(p):
    """A balanced state exists: A0 <= 2 m a and A1 = 0 (theta's classify: else NOT_BALANCEABLE)."""
    return st.OK if p[I_A0] <= 2.0 * p[I_m] * p[I_a] and p[I_A1] == 0.0 else st.NOT_BALANCEABLE


def balanceable(p):
    return 1.0 if p[I_A0] <= 2.0 * p[I_m] * p[I_a] and p[I_A1] == 0.0 else 0.0


def m_k(p):  # eq. (6)
    return (p[I_m4] * p[I_S4] + p[I_m5] * p[I_l4]) / p[I_S_k]


def omega_p(p):
    wx = _xi(p)[0]
    wy = _eta(p)[0]
    return math.sqrt(0.5 * (wx * wx + wy * wy))


@jit_inline
def _on_boundary(Om, w):
    """Omega within rounding of the frequency w (RESONANCE_RTOL on squares, half of it on frequencies)."""
    return abs(Om - w) <= 0.5 * RESONANCE_RTOL * max(abs(Om), abs(w))


def stable_first_approx(p):
    """The source's rule, corrected [fix]: omega_lo < Omega < omega_p or Omega > omega_hi (the two
    frequencies sorted: the source assumes omega_xi < omega_eta). Strict: 0 on a boundary, and an
    Omega within rounding of a boundary (_on_boundary) is on it, so no rounding decides the verdict."""
    wx = _xi(p)[0]
    wy = _eta(p)[0]
    Om = p[I_Omega]
    lo, hi = min(wx, wy), max(wx, wy)
    wp = math.sqrt(0.5 * (wx * wx + wy * wy))
    if _on_boundary(Om, lo) or _on_boundary(Om, wp) or _on_boundary(Om, hi):
        return 0.0
    return 1.0 if (lo < Om and Om < wp) or Om > hi else 0.0


@jit_inline
def _two_product(a, b):
    """(p, e) with p + e = a b exactly (Dekker's product; |a|, |b| below about 1e300)."""
    p = a * b
    t = 134217729.0 * a  # 2^27 + 1: Veltkamp's split into 26-bit halves
    ah = t - (t - a)
    al = a - ah
    t = 134217729.0 * b
    bh = t - (t - b)
    bl = b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


@jit
def _detuning(om, c, M, Om):
    """(d, scale) of one platform axis: d = c_j - M Omega^2 (c_j the given stiffness, or M omega_j^2
    when omega_j is given and c is NaN), scale = max(c_j, M Omega^2). Within NEAR_RESONANCE of a
    resonance d is recomputed from exact products (the subtraction of the leading parts is then
    exact), so it is right to a few ulps of d itself; elsewhere the plain formula."""
    cc = M * om * om if math.isnan(c) else c
    k = M * Om ** 2
    d = cc - k
    scale = max(abs(cc), abs(k))
    if abs(d) <= NEAR_RESONANCE * scale:
        s, se = _two_product(Om, Om)
        k_hi, k_lo = _two_product(M, s)
        k_lo = k_lo + M * se
        if math.isnan(c):
            s, se = _two_product(om, om)
            c_hi, c_lo = _two_product(M, s)
            c_lo = c_lo + M * se
        else:
            c_hi, c_lo = c, 0.0
        exact = (c_hi - k_hi) + (c_lo - k_lo)
        if math.isfinite(exact):
            d = exact
    return d, scale


@jit
def _receptance_term(om, c, b, zeta, M, Om):
    """(Re H_j, a bound on its error, singular) of one platform axis, H_j = 1 / (c_j - M Omega^2 +
    i b_j Omega). A detuning within RESONANCE_RTOL of the terms is a resonance (d = 0: Re H_j = 0);
    singular where the damping term b_j Omega is within that tolerance too. The bound: the change of
    Re H_j when d moves by the tolerance, |dRe H / dd| <= 1 / |D|^2, plus 8 ulps of |H_j| (the
    formula's and b_j's rounding)."""
    b = _axis(om, c, b, zeta, M)[2]
    d, scale = _detuning(om, c, M, Om)
    tol = RESONANCE_RTOL * scale
    beta = b * Om
    if abs(d) <= tol:
        d = 0.0
        if beta <= tol:
            return math.nan, math.nan, True
    den = d * d + beta ** 2
    h = d / den
    return h, tol / den + 8.0 * EPS / math.sqrt(den), not math.isfinite(h)


@jit
def _receptance(p):
    """(P, error bound, singular): P(Omega) = Re(H_xi + H_eta), H_j = 1 / (c_j - M Omega^2 + i b_j
    Omega) (m/N); singular at an undamped resonance (_receptance_term)."""
    Om, M = p[I_Omega], p[I_M]
    hx, ex, sx = _receptance_term(p[I_omega_xi], p[I_c_xi], p[I_b_xi], p[I_zeta_xi], M, Om)
    hy, ey, sy = _receptance_term(p[I_omega_eta], p[I_c_eta], p[I_b_eta], p[I_zeta_eta], M, Om)
    total = 0.0
    total = total + hx
    total = total + hy
    return total, ex + ey + EPS * abs(total), sx or sy or not math.isfinite(total)


def P_approx(p):
    return _receptance(p)[0]


def P_classify(p):
    if not receptance_in_range(p):
        return st.OUT_OF_RANGE
    return st.SINGULAR if _receptance(p)[2] else st.OK


def stable_damped_approx(p, P):
    """1 if P < 0 beyond its error bound (_receptance), else 0: strict, like stable_first_approx, so
    a P within rounding of 0 (Omega on a boundary of the damped rule) is 0 whatever its sign."""
    if math.isnan(P):
        return math.nan
    return 1.0 if P < -_receptance(p)[1] else 0.0


# --- dynamics (the scaled equations of motion above; tau = Omega t, lengths in units of a)
def rhs(t, z, p, dz):
    scaled_rhs(t, z, p[OFF:OFF + NP], dz)


def jac(t, z, p, J):
    scaled_jacobian(t, z, p[OFF:OFF + NP], J)


def initial(p, z):
    """The perturbed balanced state the simulation starts from."""
    initial_state(p[OFF:OFF + NP], p[I_PERT], z)


def variational(t, Phi, p, dPhi):
    """Floquet's variational system about the exact balanced orbit (known in closed form): the
    engine integrates these 64 equations alone."""
    variational_rhs(t, Phi, p[OFF:OFF + NP], dPhi)


def variational_jac(t, Phi, p, J):
    variational_jacobian(t, Phi, p[OFF:OFF + NP], J)


def balanced(p, z):
    """The exact balanced state (x = y = 0, gamma_i = Theta_i, gamma_i' = 1): Floquet's orbit."""
    initial_state(p[OFF:OFF + NP], 0.0, z)


def forcing_period(p):
    return 2.0 * math.pi  # one crank revolution in tau


def isolated(p):
    """An isolated balanced state: 0 < A0 < 2 m a and A1 = 0 (else NOT_BALANCEABLE: the balanced-state
    measurements, Floquet and the kick)."""
    two_ma = 2.0 * p[I_m] * p[I_a]
    return st.OK if (p[I_A0] > 0.0 and p[I_A0] < two_ma and p[I_A1] == 0.0) else st.NOT_BALANCEABLE


def phase_error(t, z, p):
    e1, e2 = phase_errors(t, z[2], z[3], p[OFF + IP_TH1], p[OFF + IP_TH2])
    return max(abs(e1), abs(e2))


def phase_error1(t, z, p):
    return phase_errors(t, z[2], z[3], p[OFF + IP_TH1], p[OFF + IP_TH2])[0]


def phase_error2(t, z, p):
    return phase_errors(t, z[2], z[3], p[OFF + IP_TH1], p[OFF + IP_TH2])[1]


def platform_amplitude(t, z, p):
    return math.sqrt(z[0] * z[0] + z[1] * z[1])


def xi(t, z, p):
    return z[0]


def eta(t, z, p):
    return z[1]


def to_seconds(p, tau):
    """A time from the scaled time tau = Omega t."""
    return tau / p[I_Omega]


def to_metres(p, x):
    """A length from units of a."""
    return x * p[I_a]


# --- measurements, under the outputs' names, symbols, units and long names of OUTPUTS
_OUT = {o.name: o for o in OUTPUTS}


def _meta(output, **rename):
    o = _OUT[output]
    return dict(symbol=o.symbol, unit=o.unit, long_name=o.long_name, latex=o.latex, **rename)


def _closed(name, func, needs=(), classify=None):
    o = _OUT[name]
    return ClosedForm(name, func, needs=needs, classify=classify, symbol=o.symbol, unit=o.unit,
                      long_name=o.long_name, output_needs=o.needs, needs_params=o.needs_params, kind=o.kind,
                      latex=o.latex)


H = "horizon_revolutions"


def _history(name, of, **kw):
    return History(name, of, horizon=H, samples="trajectory_samples", dim="revolution",
                   dim_long_name=REVOLUTION.long_name, output_meta={name: _meta(name)}, **kw)


MODEL = OdeModel(
    name="autobalancer",
    description="Slider-crank on an elastic platform balanced by two pendulums on the crank axis",
    source="Dubovik & Zamyatin, static balancing of a slider-crank mechanism, eq. (1)-(8); physics.md section 2",
    params=PARAMS, settings=SETTINGS, internal=tuple(f"q{j}" for j in range(NP)),
    states=("x", "y", "g1", "g2", "xd", "yd", "w1", "w2"),
    rhs=rhs, jac=jac, initial=initial, forcing_period=forcing_period,
    classify=classify, prepare=prepare,
    measurements=(
        # Floquet: the variational equations about the exact balanced orbit over one period (the 64
        # equations of the monodromy matrix alone: the orbit is known), floquet_max = max |eig(monodromy)|;
        # initial: that orbit's start (the work-precision reference integrates it with the state)
        Floquet("floquet_max", initial=balanced, variational=variational, variational_jac=variational_jac,
                stable_name="stable_floquet", classify=isolated,
                output_meta={"floquet_max": _meta("floquet_max"), "floquet_max_stable": _meta("stable_floquet"),
                             "floquet_max_kind": {"latex": r"$\mathrm{kind}(\rho_\mathrm{crit})$"},
                             "floquet_max_angle": {"latex": r"$\arg\rho_\mathrm{crit}$"}}),
        # direct simulation from the perturbed balanced state: the decision rule of stable_sim
        # (module docstring) on the phase error and the platform amplitude
        Kick("stable_sim", phase_error, platform_amplitude, horizon=H, settle_threshold="settle_threshold",
             decay_ratio="decay_ratio", growth_ratio="growth_ratio",
             monitor_per_period="monitor_samples_per_revolution",
             dense_per_period="residual_samples_per_revolution", time_value=to_seconds, classify=isolated,
             output_meta={"stable_sim": _meta("stable_sim"),
                          "stable_sim_settling": _meta("settling_time", name="settling_time"),
                          "stable_sim_final": _meta("phase_error", name="phase_error")}),
        # the balancing residual: max platform displacement over the last 10 % (every feasible point)
        Steady("residual_amplitude", platform_amplitude, horizon=H, window=0.1,  # the last 10 % of the horizon
              
               samples_per_period="residual_samples_per_revolution", settle_rtol=None, value=to_metres,
               output_meta={"residual_amplitude": _meta("residual_amplitude"),
                            "residual_amplitude_h1": dict(
                                symbol="r₁", unit="m", long_name="first-harmonic (crank frequency) amplitude of the "
                                "platform displacement √(ξ² + η²) over the last 10 % of the simulation", latex="$r_1$"),
                            "residual_amplitude_phase": dict(
                                symbol="φ₁", unit="rad", long_name="phase lag of that first harmonic: "
                                "√(ξ² + η²) ≈ r₁ cos(Ω t − φ₁) + other harmonics", latex=r"$\varphi_1$")}),
        _history("xi_history", xi, value=to_metres),
        _history("eta_history", eta, value=to_metres),
        _history("phase_error1_history", phase_error1),
        _history("phase_error2_history", phase_error2),
    ),
    closed_forms=(
        _closed("theta", theta, classify=has_balance),
        _closed("balanceable", balanceable),
        _closed("m_k", m_k, classify=m_k_in_range),
        _closed("omega_p", omega_p, classify=first_approx_in_range),
        _closed("stable_first_approx", stable_first_approx, classify=first_approx_in_range),
        _closed("P_approx", P_approx, classify=P_classify),
        _closed("stable_damped_approx", stable_damped_approx, needs=("P_approx",)),
    ),
    output_order=("theta", "balanceable", "m_k", "omega_p", "stable_first_approx", "P_approx", "stable_damped_approx",
                  "floquet_max", "stable_floquet", "floquet_max_kind", "floquet_max_angle", "stable_sim",
                  "residual_amplitude", "residual_amplitude_h1", "residual_amplitude_phase", "phase_error",
                  "settling_time", "xi_history", "eta_history", "phase_error1_history", "phase_error2_history"),
    status_order=STATUS_ORDER,
    statuses=STATUSES,
    status_notes=STATUS_NOTES,
    check=check,
    # NOT_REPRODUCIBLE: the sampled outputs integrated again at rtol / 100 where the trajectory did
    # not settle in the first half and is not locked to the crank period (the pendulum angles less
    # one turn per revolution), compared in scaled units
    recheck=Recheck(factor="reproducibility_factor", skip_settled="stable_sim", skip_locked=True,
                    lock_rates=(("g1", 1.0), ("g2", 1.0)), measured_units=True),
    # bench workprecision: floquet_max against scipy DOP853 at rtol 1e-13 on the model's own functions
    workprecision=WorkPrecision(scene="sweeps/autobalancer_stability_chart.toml", output="floquet_max"),
)

SPEC = MODEL.spec(module=__name__, attr="MODEL")
