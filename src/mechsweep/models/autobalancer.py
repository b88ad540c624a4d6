"""Slider-crank on an elastic platform, balanced by two pendulums on the crank axis.

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
  xi:    M xi'' - d^2/dt^2 [A0 cos phi + A1 cos psi + m a sum cos gamma_i] = -c_xi xi - b_xi xi'
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

Floquet: the variational equations Phi' = J(tau) Phi (8x8, stored column by column as 64 states)
about the exact balanced solution, over one period tau = 2 pi; J is the analytic Jacobian
(directional derivatives of the closed-form accelerations, ``_jvp``). floquet_max = max |eig|.

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
The envelope test is on maxima over whole windows, so oscillating errors do not fool it. With the
default horizon (300 revolutions) points whose Floquet multiplier is within ~0.01 of 1 converge
or depart too slowly to be decided; raise horizon_revolutions for them.

stable_sim answers "does the balanced state recover from a perturbation of `perturbation` rad";
Floquet answers it for infinitesimal perturbations. They agree except where the basin of
attraction is smaller than the perturbation: measured on the shipped stability chart (3600
points, 2 m / M from 0.005 to 0.5), 10 points with heavy pendulums (2 m / M >= 0.14), weak h
and Omega > omega_eta are Floquet-stable but leave the balanced state after a 0.1 rad kick (the
pendulums wander on a coexisting non-synchronous motion, or return only after a long
excursion); of three re-run with 0.01 and 0.03 rad, two settle and one converges too slowly
(multiplier 0.9993) to be decided in 1000 revolutions. No point was found that simulation calls
stable and Floquet unstable (3000 random points: 2053 decided by both, 1 such disagreement, same
mechanism).

Other outputs and rules:
- stable_first_approx: the source assumes omega_xi < omega_eta; for omega_xi > omega_eta the rule
  is applied to the lower and the higher of the two frequencies (with A1 = 0 the problem is
  symmetric in the two axes). Strict inequalities: 0 on the boundaries.
- P_approx at an undamped resonance (c_j = M Omega^2, b_j = 0) is infinite: SINGULAR, NaN.
- stable_floquet is UNDECIDED when |floquet_max - 1| <= max(floquet_margin, 100 rtol) (floquet_max
  is accurate to ~0.1 rtol, measured).
- settling_time: NO_EVENT (NaN) when the phase error is still above settle_threshold at the end.
- INFEASIBLE (all outputs NaN): I_B < m a^2 (relative slack 1e-9), M <= 2 m (M includes both
  pendulums; the mass matrix needs M I_B > 2 m^2 a^2), l3 >= l4 when both are given, A1 != 0
  without l3, l4, or a platform parameter pair not given.

Status of a point: the most severe problem among the outputs asked for, in the order
INFEASIBLE > NONFINITE > STEP_UNDERFLOW > MAX_STEPS > SINGULAR > NOT_REPRODUCIBLE > NOT_BALANCEABLE >
UNDECIDED > NO_EVENT; outputs that could be computed are kept.
NOT_REPRODUCIBLE: a simulated output (residual_amplitude, phase_error, settling_time, stable_sim,
the histories) moved by more than reproducibility_factor (rtol |value| + atol) when the trajectory
was integrated again at rtol / 100 (see TIGHTEN below for which points, and the measured cost);
the first value is still stored.
Every output is a function of its point and the solver settings only: the simulation samples
that enter the measurements do not depend on the outputs asked for (the history samples are
extra rows that measure() skips), each trajectory starts from its own state with fresh solver
counters, and the lanes give the one-trajectory results bitwise
(tests/test_autobalancer_reproducible.py draws output subsets, point subsets and run orders). NOT_BALANCEABLE is set only when a
balanced-state output (theta, floquet_max, stable_floquet, stable_sim, phase_error,
settling_time) is asked for at a point without an (isolated) balanced state;
residual_amplitude and the histories are always computed (they measure the balancing residual).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .. import status as st
from .._jit import call_with_literal, compile_time_switch, jit, jit_inline, jit_noalloc, literally, pjit, prange
from ..ode import AUTO, DOP853, METHOD_CODES, RADAU, dop853, dop853_lanes, radau
from ..special import SINCOS_MAX, ieee_sqrt, sincos, sincos_reduced
from ._spec import ExtraDim, ModelSpec, Output, Param, Setting

TWO_PI = 2.0 * math.pi

# ----------------------------------------------------------------------------- parameters
PARAM_NAMES = (
    "Omega", "M", "m", "a", "I_B", "A0", "h",
    "omega_xi", "omega_eta", "zeta_xi", "zeta_eta", "c_xi", "c_eta", "b_xi", "b_eta",
    "A1", "l3", "l4", "m4", "S4", "m5", "S_k",
)
PAIRS = (("omega_xi", "c_xi"), ("omega_eta", "c_eta"), ("zeta_xi", "b_xi"), ("zeta_eta", "b_eta"))

# Scaled parameter vector p of the kernels (see module docstring).
IP_MU, IP_ALPHA0, IP_ALPHA1, IP_LAM, IP_IOTA, IP_KX, IP_KY, IP_DX, IP_DY, IP_EH, IP_TH1, IP_TH2 = range(12)
NP = 12

IB_SLACK = 1e-9  # relative round-off allowed in I_B >= m a^2 (a point-mass pendulum is legal)
BLOCK = 8  # points per scratch allocation in the parallel loops
LATE_FRACTION = 0.1  # last 10 % of the horizon: residual amplitude and late envelopes
EARLY_FRACTION = 0.1  # first 10 %: reference platform amplitude

# Status severity (most severe first): what a point shows when several problems occur.
# NOT_REPRODUCIBLE ranks above the statuses that leave an output NaN with a reason: it warns
# about a value that is stored and would otherwise look trustworthy.
SEVERITY = (st.INFEASIBLE, st.NONFINITE, st.STEP_UNDERFLOW, st.MAX_STEPS, st.SINGULAR, st.NOT_REPRODUCIBLE,
            st.NOT_BALANCEABLE, st.UNDECIDED, st.NO_EVENT, st.OK)


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
def rhs(tau, z, p, dz):
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


@jit_noalloc
def rhs_lanes(tau, Z, P, dZ):
    """rhs() for several trajectories side by side (lanes): tau[l], state Z[:, l], scaled
    parameters P[:, l], derivative into dZ[:, l]. Bitwise the same floats as rhs() per lane.

    The main loop has no branch and no call, so LLVM vectorises it over the lanes (4 doubles
    per AVX2 instruction); the velocity rows are copied in a separate loop because writing all
    eight rows of dZ in one loop needs more run-time aliasing checks than LLVM makes, and it
    then leaves the loop scalar. An angle beyond the reduction range of sincos_reduced (or
    infinite) sends every lane through the scalar rhs, with libm's sin and cos; NaN stays on the
    fast path (sincos_reduced gives NaN for it, like libm; idle lanes may hold NaN)."""
    lanes = Z.shape[1]
    beyond = 0
    for l in range(lanes):
        beyond += 1 if max(abs(Z[2, l]), abs(Z[3, l]), abs(tau[l])) > SINCOS_MAX else 0  # NaN: not beyond
    if beyond:
        for l in range(lanes):
            xdd, ydd, g1dd, g2dd, _, _, _, _, _, _, _, _ = accelerations(
                tau[l], Z[0, l], Z[1, l], Z[2, l], Z[3, l], Z[4, l], Z[5, l], Z[6, l], Z[7, l], P[:, l])
            dZ[4, l] = xdd
            dZ[5, l] = ydd
            dZ[6, l] = g1dd
            dZ[7, l] = g2dd
    else:
        for l in range(lanes):
            s1, k1 = sincos_reduced(Z[2, l])
            s2, k2 = sincos_reduced(Z[3, l])
            st_, ct_ = sincos_reduced(tau[l])
            xdd, ydd, g1dd, g2dd, _, _, _, _, _, _, _, _ = accelerations_trig(
                Z[0, l], Z[1, l], Z[4, l], Z[5, l], Z[6, l], Z[7, l], s1, k1, s2, k2, st_, ct_, P[IP_MU, l],
                1.0 / P[IP_IOTA, l], P[IP_EH, l], P[IP_KX, l], P[IP_KY, l], P[IP_DX, l], P[IP_DY, l],
                P[IP_ALPHA0, l], P[IP_ALPHA1, l], P[IP_LAM, l])
            dZ[4, l] = xdd
            dZ[5, l] = ydd
            dZ[6, l] = g1dd
            dZ[7, l] = g2dd
    for r in range(4):
        for l in range(lanes):
            dZ[r, l] = Z[4 + r, l]


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
def jacobian(tau, z, p, J):
    """The analytic 8x8 Jacobian d rhs / d z at (tau, z) (radau, tests)."""
    _jacobian_block(tau, z[0], z[1], z[2], z[3], z[4], z[5], z[6], z[7], p, J, 0)


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


# ----------------------------------------------------------------------------- Floquet
floquet_solver = dop853.make_solver(variational_rhs)
floquet_solver_stiffness_test = dop853.make_solver(variational_rhs, stiffness_test=True)
floquet_solver_radau = radau.make_solver(variational_rhs, variational_jacobian)


@jit_noalloc
def _identity(Y):
    for i in range(64):
        Y[i] = 0.0
    for i in range(8):
        Y[9 * i] = 1.0


@jit_noalloc
def _monodromy_dop853(Y, p, rtol, atol, max_steps, work, rwork):
    return floquet_solver(0.0, Y, p, TWO_PI, rtol, atol, 0.0, max_steps, work)


@jit_noalloc
def _monodromy_radau(Y, p, rtol, atol, max_steps, work, rwork):
    return floquet_solver_radau(0.0, Y, p, TWO_PI, rtol, atol, 0.0, max_steps, rwork)


@jit_noalloc
def _monodromy_auto(Y, p, rtol, atol, max_steps, work, rwork):
    """dop853 with the stiffness test; a stiff point starts again with radau (costs add up)."""
    code, ns, nr = floquet_solver_stiffness_test(0.0, Y, p, TWO_PI, rtol, atol, 0.0, max_steps, work)
    if code != st.STIFF:
        return code, ns, nr
    _identity(Y)
    code, ns2, nr2 = floquet_solver_radau(0.0, Y, p, TWO_PI, rtol, atol, 0.0, max_steps, rwork)
    return code, ns + ns2, nr + nr2


# monodromy(method, Y, p, rtol, atol, max_steps, work, rwork) -> (status, n_steps, n_rhs): the
# variational system over one period from Y = identity; only the method's solver is compiled.
monodromy = compile_time_switch("monodromy", {DOP853: _monodromy_dop853, RADAU: _monodromy_radau,
                                              AUTO: _monodromy_auto})


@jit
def floquet_point(method, p, rtol, atol, max_steps, Y, work, rwork):
    """Largest |Floquet multiplier| of the balanced state. Returns (status, value, steps, rhs)."""
    _identity(Y)
    code, ns, nr = monodromy(method, Y, p, rtol, atol, max_steps, work, rwork)
    if code != st.OK:
        return code, math.nan, ns, nr
    mono = np.empty((8, 8), dtype=np.complex128)
    for c in range(8):
        for r in range(8):
            v = Y[8 * c + r]
            if not math.isfinite(v):
                return st.NONFINITE, math.nan, ns, nr
            mono[r, c] = v
    ev = np.linalg.eigvals(mono)  # complex input: numba raises on a real -> complex domain change
    big = 0.0
    for k in range(8):
        big = max(big, abs(ev[k]))
    return st.OK, big, ns, nr


@pjit
def floquet_kernel(method, pp, run, rtol, atol, max_steps, value, code, n_steps, n_rhs):
    literally(method)  # one cached kernel per method
    n = pp.shape[0]
    n_blocks = (n + BLOCK - 1) // BLOCK
    for b in prange(n_blocks):
        work = dop853.workspace(64)
        rwork = radau.workspace(64)
        Y = np.empty(64)
        for i in range(b, n, n_blocks):  # strided: cost varies along the grid
            if not run[i]:
                continue
            c, v, ns, nr = floquet_point(method, pp[i], rtol, atol, max_steps, Y, work, rwork)
            code[i] = c
            value[i] = v
            n_steps[i] += ns
            n_rhs[i] += nr


# ----------------------------------------------------------------------------- direct simulation
trajectory_solver = dop853.make_trajectory_solver(rhs)
trajectory_solver_stiffness_test = dop853.make_trajectory_solver(rhs, stiffness_test=True)
trajectory_solver_radau = radau.make_trajectory_solver(rhs, jacobian)


@jit_noalloc
def _trajectory_dop853(z, p, t_eval, rtol, atol, max_steps, work, rwork, traj):
    return trajectory_solver(0.0, z, p, t_eval, rtol, atol, 0.0, max_steps, work, traj)


@jit_noalloc
def _trajectory_radau(z, p, t_eval, rtol, atol, max_steps, work, rwork, traj):
    return trajectory_solver_radau(0.0, z, p, t_eval, rtol, atol, 0.0, max_steps, rwork, traj)


@jit_noalloc
def _trajectory_auto(z, p, t_eval, rtol, atol, max_steps, work, rwork, traj):
    """dop853 with the stiffness test; a stiff point starts again with radau (costs add up)."""
    z0, z1, z2, z3, z4, z5, z6, z7 = z[0], z[1], z[2], z[3], z[4], z[5], z[6], z[7]
    code, ns, nr = trajectory_solver_stiffness_test(0.0, z, p, t_eval, rtol, atol, 0.0, max_steps, work, traj)
    if code != st.STIFF:
        return code, ns, nr
    z[0], z[1], z[2], z[3], z[4], z[5], z[6], z[7] = z0, z1, z2, z3, z4, z5, z6, z7
    code, ns2, nr2 = trajectory_solver_radau(0.0, z, p, t_eval, rtol, atol, 0.0, max_steps, rwork, traj)
    return code, ns + ns2, nr + nr2


# trajectory(method, z, p, t_eval, rtol, atol, max_steps, work, rwork, traj) -> (status, n_steps, n_rhs)
trajectory = compile_time_switch("trajectory", {DOP853: _trajectory_dop853, RADAU: _trajectory_radau,
                                                AUTO: _trajectory_auto})

# Columns of the per-point measurement table of the simulation kernel.
M_E0, M_ELATE, M_RREF, M_RLATE, M_EFINAL, M_TSETTLE, M_EPREV, M_LOCK = range(8)
N_MEAS = 8
# Bits of sample_grid's meas_rows: a row of the measurement grid; a whole revolution of the
# second half of the horizon (the once-per-revolution map, M_LOCK).
ROW_MEASURE = 1
ROW_REVOLUTION = 2


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


@jit
def simulate_point(method, p, delta, t_eval, n_rev1, n_early, i_prev, i_late, rtol, atol, max_steps, settle,
                   hist_idx, meas_rows, hist, z, work, rwork, traj, meas):
    """One direct simulation (scaled). Fills meas (N_MEAS) and, if hist has columns, hist[4, k].
    Returns (status, n_steps, n_rhs)."""
    initial_state(p, delta, z)
    code, ns, nr = trajectory(method, z, p, t_eval, rtol, atol, max_steps, work, rwork, traj)
    if code != st.OK:
        return code, ns, nr
    return measure(traj, p, t_eval, n_rev1, n_early, i_prev, i_late, settle, hist_idx, meas_rows, hist, meas), ns, nr


@jit
def measure(traj, p, t_eval, n_rev1, n_early, i_prev, i_late, settle, hist_idx, meas_rows, hist, meas):
    """The measurements of one simulated trajectory (samples traj[k] at t_eval[k]) into meas and,
    if hist has columns, hist[4, k]. Returns OK, or NONFINITE for a non-finite sample.

    Only the rows with meas_rows[k] & ROW_MEASURE (the measurement grid, the same whichever outputs are asked
    for) enter the measurements; the rows added for the histories do not, so that no output
    depends on whether histories are requested (the trajectory itself never does: samples come
    from the dense output and do not change the steps)."""
    th1 = p[IP_TH1]
    th2 = p[IP_TH2]
    n_eval = t_eval.size
    e0 = 0.0
    e_late = 0.0
    e_before = 0.0
    r_ref = 0.0
    r_late = 0.0
    last_above = -1
    k_rev = -1  # previous whole-revolution row
    n_rev = 0
    lock = 0.0
    k_prev = -1
    k_next = -1
    e_prev = 0.0
    e_last_above = 0.0
    e_next = 0.0
    for k in range(n_eval):
        if meas_rows[k] & ROW_REVOLUTION:
            # M_LOCK: largest change of the state over one revolution (the pendulum angles less
            # one turn) in the second half: ~0 once the motion is locked to the crank period
            if k_rev >= 0:
                for i in range(8):
                    dz = traj[k, i] - traj[k_rev, i]
                    if i == 2 or i == 3:
                        dz -= t_eval[k] - t_eval[k_rev]
                    if not abs(dz) <= lock:  # NaN propagates
                        lock = abs(dz)
            k_rev = k
            n_rev += 1
        if not meas_rows[k] & ROW_MEASURE:
            continue
        tau = t_eval[k]
        e1, e2 = phase_errors(tau, traj[k, 2], traj[k, 3], th1, th2)
        e = max(abs(e1), abs(e2))
        r = math.sqrt(traj[k, 0] * traj[k, 0] + traj[k, 1] * traj[k, 1])
        if not (math.isfinite(e) and math.isfinite(r)):
            return st.NONFINITE
        if k < n_rev1:
            e0 = max(e0, e)
        if k < n_early:
            r_ref = max(r_ref, r)
        if k >= i_late:
            e_late = max(e_late, e)
            r_late = max(r_late, r)
        elif k >= i_prev:
            e_before = max(e_before, e)
        if e > settle:
            last_above = k
            e_last_above = e
        elif last_above >= 0 and last_above == k_prev:
            e_next = e
            k_next = k
        e_prev = e
        k_prev = k
    meas[M_E0] = e0
    meas[M_ELATE] = e_late
    meas[M_RREF] = r_ref
    meas[M_RLATE] = r_late
    meas[M_EFINAL] = e_prev
    meas[M_EPREV] = e_before
    meas[M_LOCK] = lock if n_rev >= 2 else math.inf
    if last_above == k_prev:
        meas[M_TSETTLE] = math.nan  # never settled within the horizon
    elif last_above < 0:
        meas[M_TSETTLE] = 0.0
    else:  # linear interpolation of the last crossing of the threshold (between measurement rows)
        t0 = t_eval[last_above]
        t1 = t_eval[k_next]
        meas[M_TSETTLE] = t0 + (t1 - t0) * (e_last_above - settle) / (e_last_above - e_next)
    for j in range(hist_idx.size if hist.shape[1] > 0 else 0):
        k = hist_idx[j]
        e1, e2 = phase_errors(t_eval[k], traj[k, 2], traj[k, 3], th1, th2)
        hist[0, j] = traj[k, 0]
        hist[1, j] = traj[k, 1]
        hist[2, j] = e1
        hist[3, j] = e2
    return st.OK


@pjit
def simulation_kernel(method, pp, run, delta, t_eval, n_rev1, n_early, i_prev, i_late, rtol, atol, max_steps, settle,
                      hist_idx, meas_rows, hist, meas, code, n_steps, n_rhs):
    literally(method)  # one cached kernel per method
    n = pp.shape[0]
    n_blocks = (n + BLOCK - 1) // BLOCK
    for b in prange(n_blocks):
        work = dop853.workspace(8)
        rwork = radau.workspace(8)
        z = np.empty(8)
        traj = np.empty((t_eval.size, 8))
        for i in range(b, n, n_blocks):
            if not run[i]:
                continue
            c, ns, nr = simulate_point(method, pp[i], delta, t_eval, n_rev1, n_early, i_prev, i_late, rtol, atol,
                                       max_steps, settle, hist_idx, meas_rows, hist[i], z, work, rwork, traj,
                                       meas[i])
            code[i] = c
            n_steps[i] += ns
            n_rhs[i] += nr


# The DOP853 simulations run LANES trajectories side by side per thread (ode/dop853_lanes.py):
# bitwise the results of simulation_kernel, about 3x the steps per second. The lane right-hand
# side took 23 ns per lane with 32 lanes, 24 with 16, 29 with 8, 77 with 4 (the vector loops then
# run in their scalar remainders), 95 ns alone; a whole simulation of 512 points on one thread
# ran 8-10 % faster with 32 lanes than with 16 (one-off measurements, alternating). More lanes
# idle longer at the end of a thread's queue, and 32 lanes' stages (55 kB) already leave L1.
LANES = 32
# Each lane keeps its trajectory's samples (n_eval x 8 floats) until it ends: with long horizons
# or dense sampling fewer lanes are used, so that a thread's samples stay within this budget
# (16, then 8 lanes, else one trajectory at a time, as simulation_kernel always keeps one).
LANE_SAMPLES_BYTES = 256 * 2**20
lane_load, lane_run = dop853_lanes.make_lane_trajectory_solver(rhs_lanes, rhs)


def simulation_lanes(n_eval: int) -> int:
    """Lanes per thread for trajectories of n_eval samples: LANES, 16, 8, or 0 (one at a time)."""
    for lanes in (LANES, 16, 8):
        if lanes * n_eval * 8 * 8 <= LANE_SAMPLES_BYTES:
            return lanes
    return 0


def lane_queues(n_points: int, lanes: int = LANES) -> int:
    """Queues for n points: one per thread (a queue's lanes idle only at its end), fewer when
    there are not lanes / 2 points per thread."""
    return max(1, min(numba.get_num_threads(), -(-n_points // max(1, lanes // 2))))


@jit
def _load_next(ws, lane, i, step, pp, run, delta, t_eval, rtol, atol, z):
    """Load the next point of the queue (i, i + step, ... with run[i]) into the lane, or leave it
    idle; returns the queue position after it."""
    n = pp.shape[0]
    while i < n and not run[i]:
        i += step
    if i >= n:
        dop853_lanes.idle(ws, lane)
        return i
    initial_state(pp[i], delta, z)
    lane_load(ws, lane, i, 0.0, z, pp[i], t_eval, rtol, atol)
    return i + step


@jit
def simulate_queue(lanes, first, step, pp, run, delta, t_eval, n_rev1, n_early, i_prev, i_late, rtol, atol, max_steps,
                   settle, hist_idx, meas_rows, hist, meas, code, n_steps, n_rhs):
    """The points first, first + step, ... (those with run[i]) through the lanes of one thread."""
    ws = dop853_lanes.workspace(8, NP, lanes, t_eval.size)
    traj = ws[dop853_lanes.TRAJ]
    z = np.empty(8)
    nxt = first
    for lane in range(lanes):
        nxt = _load_next(ws, lane, nxt, step, pp, run, delta, t_eval, rtol, atol, z)
    while True:
        lane = lane_run(ws, t_eval, rtol, atol, max_steps)
        if lane < 0:
            return
        i, c, ns, nr = dop853_lanes.lane_result(ws, lane)
        if c == st.OK:
            c = measure(traj[lane], pp[i], t_eval, n_rev1, n_early, i_prev, i_late, settle, hist_idx, meas_rows,
                        hist[i], meas[i])
        code[i] = c
        n_steps[i] += ns
        n_rhs[i] += nr
        nxt = _load_next(ws, lane, nxt, step, pp, run, delta, t_eval, rtol, atol, z)


def simulate_lanes(lanes, pp, run, *args):
    """simulation_kernel's work for DOP853 through the lanes: lane_queues() queues of points, each
    run by simulate_queue (nogil) in a pool of numba.get_num_threads() Python threads, which
    take the next queue as they finish one. A numba parallel loop would do the same, but it
    compiles the whole lane solver once more into its loop body (about 12 s, measured)."""
    n_queues = lane_queues(pp.shape[0], lanes)
    threads = min(numba.get_num_threads(), n_queues)

    def queue(b):
        simulate_queue(lanes, b, n_queues, pp, run, *args)

    if threads == 1:
        for b in range(n_queues):
            queue(b)
        return
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="mechsweep-lanes") as pool:
        for _ in pool.map(queue, range(n_queues)):
            pass


def sample_grid(settings, histories: bool):
    """The tau instants of the simulation samples (identical for every point) and the row
    indices the kernel needs: (t_eval, n_rev1, n_early, i_prev, i_late, hist_idx, meas_rows).
    meas_rows[k] has the bit ROW_MEASURE for the rows of the measurement grid, which depends on
    the settings only (rows only the histories need have not: measure() skips them), and
    ROW_REVOLUTION for the whole revolutions of the second half of the horizon (M_LOCK)."""
    H = float(settings["horizon_revolutions"])
    tau_end = TWO_PI * H
    per_rev = int(settings["monitor_samples_per_revolution"])
    dense = int(settings["residual_samples_per_revolution"])
    tau_late = (1.0 - LATE_FRACTION) * tau_end
    parts = [np.linspace(0.0, tau_end, max(2, int(math.ceil(per_rev * H)) + 1)),
             np.linspace(tau_late, tau_end, max(2, int(math.ceil(dense * LATE_FRACTION * H)) + 1)),
             np.linspace(0.0, TWO_PI * min(1.0, H), per_rev + 1)]
    hist_tau = TWO_PI * history_revolutions(settings) if histories else np.empty(0)
    rev_tau = TWO_PI * np.arange(math.ceil(0.5 * H), math.floor(H) + 1)  # whole revolutions, second half
    t_eval = np.unique(np.concatenate(parts + [hist_tau, rev_tau]))
    n_rev1 = int(np.searchsorted(t_eval, TWO_PI * min(1.0, H), side="right"))
    n_early = int(np.searchsorted(t_eval, EARLY_FRACTION * tau_end, side="right"))
    i_late = int(np.searchsorted(t_eval, tau_late, side="left"))
    i_prev = int(np.searchsorted(t_eval, (1.0 - 2.0 * LATE_FRACTION) * tau_end, side="left"))
    hist_idx = np.searchsorted(t_eval, hist_tau).astype(np.int64)
    meas_rows = np.where(np.isin(t_eval, np.concatenate(parts)), ROW_MEASURE, 0)
    meas_rows |= np.where(np.isin(t_eval, rev_tau), ROW_REVOLUTION, 0)
    return t_eval, n_rev1, n_early, i_prev, i_late, hist_idx, meas_rows.astype(np.int8)


def history_revolutions(settings) -> np.ndarray:
    """Coordinate of the history outputs: crank revolutions t Omega / 2 pi."""
    return np.linspace(0.0, float(settings.get("horizon_revolutions", 300.0)),
                       int(settings.get("trajectory_samples", 600)))


# ----------------------------------------------------------------------------- closed forms (numpy)
def platform(P):
    """Platform frequencies, stiffnesses and damping coefficients from either parametrisation:
    omega^2 = c / M [fix], b = 2 zeta M omega."""
    col = {name: P[:, j] for j, name in enumerate(PARAM_NAMES)}
    M = col["M"]
    with np.errstate(invalid="ignore", divide="ignore"):
        out = {}
        for ax in ("xi", "eta"):
            om = np.where(np.isnan(col[f"omega_{ax}"]), np.sqrt(col[f"c_{ax}"] / M), col[f"omega_{ax}"])
            c = np.where(np.isnan(col[f"c_{ax}"]), M * om * om, col[f"c_{ax}"])
            b = np.where(np.isnan(col[f"b_{ax}"]), 2.0 * col[f"zeta_{ax}"] * M * om, col[f"b_{ax}"])
            out[f"omega_{ax}"], out[f"c_{ax}"], out[f"b_{ax}"] = om, c, b
    return out


def scaled_parameters(Omega, M, m, a, I_B, A0, A1, lam, c_xi, c_eta, b_xi, b_eta, h, th1, th2):
    """The kernels' parameter vectors p (n, NP) from SI values (arrays or floats)."""
    Omega, M, m, a, I_B, A0, A1, lam, c_xi, c_eta, b_xi, b_eta, h, th1, th2 = np.broadcast_arrays(
        *(np.asarray(v, dtype=float) for v in (Omega, M, m, a, I_B, A0, A1, lam, c_xi, c_eta, b_xi,
                                                b_eta, h, th1, th2)))
    p = np.empty(Omega.shape + (NP,))
    p[..., IP_MU] = M / m
    p[..., IP_ALPHA0] = A0 / (m * a)
    p[..., IP_ALPHA1] = A1 / (m * a)
    p[..., IP_LAM] = lam
    p[..., IP_IOTA] = I_B / (m * a * a)
    p[..., IP_KX] = c_xi / (m * Omega**2)
    p[..., IP_KY] = c_eta / (m * Omega**2)
    p[..., IP_DX] = b_xi / (m * Omega)
    p[..., IP_DY] = b_eta / (m * Omega)
    p[..., IP_EH] = h / (m * a * a * Omega)
    p[..., IP_TH1] = th1
    p[..., IP_TH2] = th2
    return p


def receptance_sum(Omega, M, c_xi, c_eta, b_xi, b_eta):
    """P(Omega) = Re(H_xi + H_eta), H_j = 1 / (c_j - M Omega^2 + i b_j Omega) (m/N)."""
    total = 0.0
    for c, b in ((c_xi, b_xi), (c_eta, b_eta)):
        d = c - M * Omega**2
        total = total + d / (d * d + (b * Omega) ** 2)
    return total


def _worse(current, new):
    """Element-wise the more severe of two status arrays (SEVERITY order)."""
    rank = np.empty(max(SEVERITY) + 2, dtype=np.int64)
    rank[:] = len(SEVERITY)
    for r, code in enumerate(SEVERITY):
        rank[code] = r
    new = np.broadcast_to(np.asarray(new, dtype=current.dtype), current.shape)
    return np.where(rank[new] < rank[current], new, current)


# ----------------------------------------------------------------------------- engine entry point
BALANCED_OUTPUTS = ("theta", "floquet_max", "stable_floquet", "stable_sim", "phase_error", "settling_time")
SIM_OUTPUTS = ("stable_sim", "residual_amplitude", "phase_error", "settling_time",
               "xi_history", "eta_history", "phase_error1_history", "phase_error2_history")
HISTORIES = ("xi_history", "eta_history", "phase_error1_history", "phase_error2_history")


def evaluate(P, wanted, solver, out, status, n_steps, n_rhs):
    n = P.shape[0]
    col = {name: np.ascontiguousarray(P[:, j]) for j, name in enumerate(PARAM_NAMES)}
    Omega, M, m, a, I_B, A0, A1 = (col[k] for k in ("Omega", "M", "m", "a", "I_B", "A0", "A1"))
    l3, l4 = col["l3"], col["l4"]
    pf = platform(P)
    code = np.full(n, st.OK, dtype=status.dtype)

    with np.errstate(invalid="ignore", divide="ignore"):
        # physical domain of a point
        lengths_given = ~np.isnan(l3) & ~np.isnan(l4)
        # I_B >= m a^2 with a relative slack of IB_SLACK: I_B = m a^2 typed as numbers must pass
        feasible = (I_B >= m * a * a * (1.0 - IB_SLACK)) & (M > 2.0 * m)
        feasible &= np.isfinite(pf["omega_xi"]) & np.isfinite(pf["omega_eta"])
        feasible &= np.isfinite(pf["b_xi"]) & np.isfinite(pf["b_eta"])
        feasible &= ~lengths_given | (l3 < l4)
        feasible &= (A1 == 0.0) | lengths_given
        code[~feasible] = st.INFEASIBLE
        lam = np.where((A1 != 0.0) & lengths_given, l3 / l4, 0.0)

        two_ma = 2.0 * m * a
        has_balance = (A0 <= two_ma) & (A1 == 0.0)  # eq. (8) with the factor 2 [fix]
        isolated = has_balance & (A0 > 0.0) & (A0 < two_ma)
        ratio = np.clip(-A0 / two_ma, -1.0, 1.0)
        theta_ref = np.where(A0 <= two_ma, np.arccos(ratio), math.pi)  # eq. (8); pi: opposite the unbalance
        th2_ref = np.where(A0 <= two_ma, -theta_ref, math.pi)

        wants = set(wanted)
        if wants & set(BALANCED_OUTPUTS):
            need_isolated = wants & set(BALANCED_OUTPUTS) - {"theta"}
            bad = ~isolated if need_isolated else ~has_balance
            code = _worse(code, np.where(bad & feasible, st.NOT_BALANCEABLE, st.OK))

        if "theta" in wants:
            out["theta"][:] = np.where(has_balance & feasible, theta_ref, np.nan)
        if "balanceable" in wants:
            out["balanceable"][:] = np.where(feasible, has_balance.astype(float), np.nan)
        if "m_k" in wants:  # eq. (6)
            out["m_k"][:] = np.where(feasible, (col["m4"] * col["S4"] + col["m5"] * l4) / col["S_k"], np.nan)
        wx, wy = pf["omega_xi"], pf["omega_eta"]
        if "omega_p" in wants:
            out["omega_p"][:] = np.where(feasible, np.sqrt(0.5 * (wx * wx + wy * wy)), np.nan)
        if "stable_first_approx" in wants:
            lo, hi = np.minimum(wx, wy), np.maximum(wx, wy)  # omega_xi < omega_eta assumed: sort them
            wp = np.sqrt(0.5 * (wx * wx + wy * wy))
            first = ((lo < Omega) & (Omega < wp)) | (Omega > hi)  # [fix]: "or"
            out["stable_first_approx"][:] = np.where(feasible, first.astype(float), np.nan)
        if "P_approx" in wants:
            Pv = receptance_sum(Omega, M, pf["c_xi"], pf["c_eta"], pf["b_xi"], pf["b_eta"])
            singular = feasible & ~np.isfinite(Pv)  # undamped resonance: c = M Omega^2, b = 0
            code = _worse(code, np.where(singular, st.SINGULAR, st.OK))
            ok = feasible & ~singular
            out["P_approx"][:] = np.where(ok, Pv, np.nan)
            if "stable_damped_approx" in wants:
                out["stable_damped_approx"][:] = np.where(ok, (Pv < 0.0).astype(float), np.nan)

        pp = scaled_parameters(Omega, M, m, a, I_B, A0, A1, lam, pf["c_xi"], pf["c_eta"], pf["b_xi"],
                               pf["b_eta"], col["h"], theta_ref, th2_ref)

    if "floquet_max" in wants:
        run = feasible & isolated
        value = np.full(n, np.nan)
        fcode = np.zeros(n, dtype=np.int8)
        if run.any():
            call_with_literal(floquet_kernel, METHOD_CODES[solver.method], pp, run, solver.rtol, solver.atol,
                              solver.max_steps, value, fcode, n_steps, n_rhs)
        code = _worse(code, fcode)
        good = run & (fcode == st.OK)
        out["floquet_max"][:] = np.where(good, value, np.nan)
        if "stable_floquet" in wants:
            # measured: |error of floquet_max| <= 0.13 rtol (rtol 1e-6 ... 5e-11, 400 random points)
            margin = max(float(solver.settings["floquet_margin"]), 100.0 * solver.rtol)
            decided = good & (np.abs(value - 1.0) > margin)
            code = _worse(code, np.where(good & ~decided, st.UNDECIDED, st.OK))
            out["stable_floquet"][:] = np.where(decided, (value < 1.0).astype(float), np.nan)

    sim_wanted = wants & set(SIM_OUTPUTS)
    if sim_wanted:
        _simulate(sim_wanted, solver, pp, feasible, isolated, Omega, a, code, out, n_steps, n_rhs)
    status[:] = _worse(status, code)


def _simulate(wants, solver, pp, feasible, isolated, Omega, a, code, out, n_steps, n_rhs):
    s = solver.settings
    histories = bool(wants & set(HISTORIES))
    always = wants - set(BALANCED_OUTPUTS)  # residual amplitude and histories: every feasible point
    run = feasible & (isolated | bool(always))
    meas, hist, scode = integrate(solver.method, pp, run, s, histories, solver.rtol, solver.atol, solver.max_steps,
                                  n_steps, n_rhs)
    code[:] = _worse(code, scode)
    good = run & (scode == st.OK)
    bal = good & isolated
    values, vcode = sim_values(wants, s, meas, hist, good, bal)
    code[:] = _worse(code, vcode)
    factor = float(s["reproducibility_factor"])
    check = good & recheck_needed(s, meas, good, solver.rtol, solver.atol) & (factor > 0.0)
    if check.any():
        tight = tighter_rtol(solver.rtol)
        meas2, hist2, scode2 = integrate(solver.method, pp, check, s, histories, tight, solver.atol,
                                         solver.max_steps, n_steps, n_rhs)
        good2 = check & (scode2 == st.OK)
        values2, _ = sim_values(wants, s, meas2, hist2, good2, good2 & isolated)
        moved = ~good2 & check  # the tighter run failed: the value could not be confirmed
        for name, v in values.items():
            moved |= check & _moved(v, values2[name], solver.rtol, solver.atol, factor)
        code[:] = _worse(code, np.where(moved, st.NOT_REPRODUCIBLE, st.OK))
    for name, v in values.items():  # to SI units
        if name == "settling_time":
            v = v / Omega
        elif name in ("residual_amplitude", "xi_history", "eta_history"):
            v = v * (a if v.ndim == 1 else a[:, None])
        out[name][:] = v


def integrate(method, pp, run, settings, histories, rtol, atol, max_steps, n_steps, n_rhs, lanes=True):
    """The perturbed-balanced-state simulations of the points with run[i], by ``method`` at
    (rtol, atol); steps and evaluations are added to n_steps, n_rhs. Returns (meas, hist, code):
    the measurements (N_MEAS per point), the history samples (n, 4, k) and the status per point.
    DOP853 runs in SIMD lanes unless ``lanes`` is False (the same results, bitwise)."""
    n = pp.shape[0]
    t_eval, n_rev1, n_early, i_prev, i_late, hist_idx, meas_rows = sample_grid(settings, histories)
    hist = np.full((n, 4, hist_idx.size), np.nan) if histories else np.empty((n, 4, 0))
    meas = np.full((n, N_MEAS), np.nan)
    scode = np.zeros(n, dtype=np.int8)
    args = (pp, run, float(settings["perturbation"]), t_eval, n_rev1, n_early, i_prev, i_late, rtol, atol,
            max_steps, float(settings["settle_threshold"]), hist_idx, meas_rows, hist, meas, scode, n_steps, n_rhs)
    lanes = simulation_lanes(t_eval.size) if lanes else 0
    if run.any():
        if method == "dop853" and lanes:
            simulate_lanes(lanes, *args)
        else:
            call_with_literal(simulation_kernel, METHOD_CODES[method], *args)
    return meas, hist, scode


def sim_values(wants, s, meas, hist, good, bal):
    """The simulation outputs asked for, in scaled units (lengths / a, time tau = Omega t), from
    the measurements, and the status their rules give (NO_EVENT, UNDECIDED)."""
    n = meas.shape[0]
    code = np.zeros(n, dtype=np.int8)
    values = {}
    e0, e_late, r_ref, r_late, e_final, t_settle, e_before, _ = meas.T
    if "residual_amplitude" in wants:
        values["residual_amplitude"] = np.where(good, r_late, np.nan)
    if "phase_error" in wants:
        values["phase_error"] = np.where(bal, e_final, np.nan)
    if "settling_time" in wants:
        settled = bal & np.isfinite(t_settle)
        code = _worse(code, np.where(bal & ~settled, st.NO_EVENT, st.OK))
        values["settling_time"] = np.where(settled, t_settle, np.nan)
    if "stable_sim" in wants:
        decay, growth = float(s["decay_ratio"]), float(s["growth_ratio"])
        settle = float(s["settle_threshold"])
        with np.errstate(invalid="ignore"):
            stable = (e_late <= settle) & (e_late <= decay * e0) & (r_late <= decay * r_ref)
            # not still growing at the end (a weak unstable mode that has just become dominant);
            # below 1e-3 settle_threshold the error is at the integration noise floor: no trend test
            stable &= (e_late <= e_before) | (e_late <= 1e-3 * settle)
            unstable = (e_late >= growth * e0) & (e_before >= growth * e0)  # departed, and stayed away
        decided = bal & (stable | unstable)
        code = _worse(code, np.where(bal & ~decided, st.UNDECIDED, st.OK))
        values["stable_sim"] = np.where(decided, stable.astype(float), np.nan)
    g = good[:, None]
    for k, name in enumerate(HISTORIES):
        if name in wants:
            values[name] = np.where(g, hist[:, k, :], np.nan)
    return values, code


# Reproducibility check (status NOT_REPRODUCIBLE). The simulated outputs of a trajectory that
# leaves the balanced state, or wanders for long before it settles, can be dominated by chaotic
# transients: their values then move by per cent between tolerances, although every step met
# the tolerance. Such points are integrated a second time at TIGHTEN times smaller rtol (the
# same atol, the same method) and every requested simulation output is compared; a point whose
# output moves by more than reproducibility_factor (rtol |v| + atol) (scaled units: lengths in
# units of a, angles in rad, time in tau = Omega t; histories sample by sample), whose stable_sim
# verdict changes, or whose tighter integration fails, gets NOT_REPRODUCIBLE. The first values
# are kept (bitwise as without the check); only the status says that their digits are not all
# meaningful. Not re-integrated (recheck_needed): trajectories that settled within the first
# SETTLED_FRACTION of the horizon, or whose state repeats from revolution to revolution through
# the second half; they end on an attracting periodic motion, on which integration errors decay.
# Measured (2026-11-23): checking every point flagged no point that this selection skips (1,860
# points: random mechanisms at rtol 5e-11 and 1e-8, sweeps/autobalancer_residual.toml and
# autobalancer_stability_chart.toml); 40-59 % of the points are integrated again, and the
# simulated outputs cost 1.8x (one thread; the second run takes ~1.1-1.2x the first's steps).
# Skipped points whose value sits at the noise floor (|value| ~ atol) may still move by a large
# relative amount: the tolerance is rtol |value| + atol, the integrator's own.
TIGHTEN = 100.0
RTOL_TIGHT_FLOOR = 1e-14
SETTLED_FRACTION = 0.5


def tighter_rtol(rtol):
    """The rtol of the second integration: TIGHTEN times smaller, not below RTOL_TIGHT_FLOOR
    (unless rtol itself is below it)."""
    return min(rtol, max(rtol / TIGHTEN, RTOL_TIGHT_FLOOR))


def recheck_needed(settings, meas, good, rtol, atol):
    """Points whose simulation is integrated again for the reproducibility check: every
    successful trajectory except those that settled early (phase error below settle_threshold
    from the first SETTLED_FRACTION of the horizon on) and those locked to the crank period
    through the whole second half (the state changes by at most reproducibility_factor
    (rtol + atol) per revolution, M_LOCK): both end on an attracting periodic motion. A function
    of the point's own measurements only, so the decision does not depend on the other points
    or outputs."""
    tau_end = TWO_PI * float(settings["horizon_revolutions"])
    factor = float(settings["reproducibility_factor"])
    t_settle = meas[:, M_TSETTLE]
    with np.errstate(invalid="ignore"):
        early = np.isfinite(t_settle) & (t_settle <= SETTLED_FRACTION * tau_end)
        locked = meas[:, M_LOCK] <= factor * (rtol + atol)
    return good & ~early & ~locked


def _moved(v, v2, rtol, atol, factor):
    """True where the two values differ by more than factor (rtol |v| + atol), or where one is
    NaN and the other not; rows of a history compare sample by sample (any sample moved)."""
    with np.errstate(invalid="ignore"):
        tol = factor * (rtol * np.maximum(np.abs(v), np.abs(v2)) + atol)
        bad = (np.abs(v - v2) > tol) | (np.isnan(v) != np.isnan(v2))
    return bad.reshape(bad.shape[0], -1).any(axis=1)


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
    # simulated outputs are re-integrated at rtol / 100 where they may be chaotic (see TIGHTEN)
    Setting("reproducibility_factor", 1000.0, "1",
            "a simulated output moving by more than this times (rtol abs(value) + atol) at rtol / 100 is "
            "not_reproducible (0: no check)", 0.0, 1e12),
)

SPEC = ModelSpec(
    name="autobalancer",
    description="Slider-crank on an elastic platform balanced by two pendulums on the crank axis",
    source="Dubovik & Zamyatin, static balancing of a slider-crank mechanism, eq. (1)-(8); physics.md section 2",
    params=(
        Param("Omega", "Ω", "rad s-1", "crank angular speed", **_pos),
        Param("M", "M", "kg", "total translating mass (platform, mechanism, both pendulums)", **_pos),
        Param("m", "m", "kg", "mass of one pendulum", **_pos),
        Param("a", "a", "m", "pendulum arm BC (crank axis to pendulum centre of mass)", **_pos),
        Param("I_B", "I_B", "kg m2", "pendulum moment of inertia about the crank axis (>= m a^2)", **_pos),
        Param("A0", "A0", "kg m", "rotating unbalance m3 S3 + (m4 + m5 + m_k) l3", lo=0.0),
        Param("h", "h", "N m s rad-1", "pendulum damping relative to the crank", lo=0.0),
        Param("omega_xi", "ω_ξ", "rad s-1", "platform natural frequency along xi, sqrt(c_xi / M)", **_pos, **_opt),
        Param("omega_eta", "ω_η", "rad s-1", "platform natural frequency along eta, sqrt(c_eta / M)", **_pos, **_opt),
        Param("zeta_xi", "ζ_ξ", "1", "platform damping ratio along xi, b_xi / (2 M omega_xi)", lo=0.0, **_opt),
        Param("zeta_eta", "ζ_η", "1", "platform damping ratio along eta, b_eta / (2 M omega_eta)", lo=0.0, **_opt),
        Param("c_xi", "c_ξ", "N m-1", "platform stiffness along xi", **_pos, **_opt),
        Param("c_eta", "c_η", "N m-1", "platform stiffness along eta", **_pos, **_opt),
        Param("b_xi", "b_ξ", "N s m-1", "platform damping coefficient along xi", lo=0.0, **_opt),
        Param("b_eta", "b_η", "N s m-1", "platform damping coefficient along eta", lo=0.0, **_opt),
        Param("A1", "A1", "kg m", "conrod mass moment m4 S4 + m5 l4 - m_k S_k (0: corrected)",
              required=False, default=0.0),
        Param("l3", "l3", "m", "crank length BD", **_pos, **_opt),
        Param("l4", "l4", "m", "conrod length DE (> l3)", **_pos, **_opt),
        Param("m4", "m4", "kg", "conrod mass", lo=0.0, **_opt),
        Param("S4", "S4", "m", "conrod centre of mass from D", lo=0.0, **_opt),
        Param("m5", "m5", "kg", "slider mass", lo=0.0, **_opt),
        Param("S_k", "S_k", "m", "correcting mass position from D (away from E)", **_pos, **_opt),
    ),
    outputs=(
        Output("theta", "Θ₁", "rad", "balancing angle of pendulum 1, arccos(-A0 / (2 m a)); Theta_2 = -Theta_1"),
        Output("balanceable", "balanceable", "1", "1 if a balanced state exists (A0 <= 2 m a and A1 = 0)"),
        Output("m_k", "m_k", "kg", "correcting mass (m4 S4 + m5 l4) / S_k that makes A1 = 0",
               needs_params=("m4", "S4", "m5", "S_k", "l4")),
        Output("omega_p", "ω_p", "rad s-1", "first-approximation boundary sqrt((omega_xi^2 + omega_eta^2) / 2)"),
        Output("stable_first_approx", "stable (1st approx.)", "1",
               "1 if omega_lo < Omega < omega_p or Omega > omega_hi (source's rule, corrected)", kind="verdict"),
        Output("P_approx", "P(Ω)", "m N-1", "Re(H_xi + H_eta), receptance sum of the damped platform"),
        Output("stable_damped_approx", "P(Ω) < 0", "1", "1 if P(Omega) < 0 (first approximation with damping)",
               needs=("P_approx",), kind="verdict"),
        Output("floquet_max", "max |ρ|", "1", "largest Floquet multiplier modulus of the balanced state",
               integrated=True),
        Output("stable_floquet", "stable (Floquet)", "1", "1 if floquet_max < 1", integrated=True,
               needs=("floquet_max",), kind="verdict"),
        Output("stable_sim", "stable (simulation)", "1",
               "1 if the perturbed balanced state settles, 0 if it departs (direct simulation)", integrated=True,
               kind="verdict"),
        Output("residual_amplitude", "r_res", "m",
               "max platform displacement sqrt(xi^2 + eta^2) over the last 10 % of the simulation", integrated=True),
        Output("phase_error", "δγ", "rad", "final pendulum phase error max_i |gamma_i - Omega t - Theta_i|",
               integrated=True),
        Output("settling_time", "t_s", "s", "time after which the phase error stays below settle_threshold",
               integrated=True),
        Output("xi_history", "ξ(t)", "m", "platform displacement xi over the simulation", integrated=True,
               extra_dims=(REVOLUTION,)),
        Output("eta_history", "η(t)", "m", "platform displacement eta over the simulation", integrated=True,
               extra_dims=(REVOLUTION,)),
        Output("phase_error1_history", "δγ₁(t)", "rad", "phase error of pendulum 1 over the simulation",
               integrated=True, extra_dims=(REVOLUTION,)),
        Output("phase_error2_history", "δγ₂(t)", "rad", "phase error of pendulum 2 over the simulation",
               integrated=True, extra_dims=(REVOLUTION,)),
    ),
    evaluate=evaluate,
    settings=SETTINGS,
    check=check,
    methods=("dop853", "radau", "auto"),
    statuses=(st.INFEASIBLE, st.SINGULAR, st.NOT_BALANCEABLE, st.UNDECIDED, st.NOT_REPRODUCIBLE,
              *st.INTEGRATION_FAILURES),
    status_notes={
        st.INFEASIBLE: "I_B < m a^2, M <= 2 m, l3 >= l4, A1 != 0 without l3 and l4, or a platform parameter "
                       "pair not given (all outputs NaN)",
        st.SINGULAR: "an undamped resonance of the platform (c_j = M Omega^2, b_j = 0): P_approx is NaN, "
                     "Floquet is still computed",
        st.NOT_BALANCEABLE: "no isolated balanced state (A0 > 2 m a, A0 = 0, A0 = 2 m a, A1 != 0): balanced-state "
                            "outputs are NaN, residuals are kept",
        st.NO_EVENT: "the pendulums did not settle within the simulation (settling_time)",
        st.UNDECIDED: "the simulation neither settled nor diverged, or floquet_max is within "
                      "solver.floquet_margin of 1",
        st.NOT_REPRODUCIBLE: "integrated again at rtol / 100, a simulated output moved by more than "
                             "reproducibility_factor (rtol |value| + atol), or the second integration failed: the "
                             "value is stored, only its leading digits mean something (chaotic or "
                             "transient-dominated motion; simulations that did not settle early)",
    },
)
