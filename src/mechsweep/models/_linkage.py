"""Planar four-bar and slider-crank: closed-form kinematics, inertia loads and balancing helpers.

Over 700 lines on purpose: the kinematics and loads of both linkages share one set of conventions
(below) and their balancing methods reuse the same position functions.

Pure numba functions on floats and arrays; they write into caller-owned arrays and return status
codes (never raise), and allocate nothing: compiled without numba's reference counting (jit_noalloc). No units, no xarray, no scene: the per-design functions of the models
``fourbar_balancing`` and ``slidercrank_balancing`` (closed-form models on the model layer, which
owns the chunk loop: mechsweep.model.closed) and the plain functions of :mod:`mechsweep.balancing`
call them.

Conventions (SI, angles in rad, counter-clockwise positive, gravity g along -y)
------------------------------------------------------------------------------
Four-bar: crank pivot O_A = (0, 0), rocker pivot O_B = (a4, 0) (the frame on the x axis);
crank O_A A (a1, angle phi), coupler A B (a2, angle phi2), rocker O_B B (a3, angle phi3),
e_i = (cos phi_i, sin phi_i), loop a1 e1 + a2 e2 = a4 x + a3 e3. Link i has its centre of mass
at distance r_i from its first joint (O_A, A, O_B) at angle theta_i from the link line:
G1 = r1 e^{i theta1} e1, G2 = A + r2 e^{i theta2} e2, G3 = O_B + r3 e^{i theta3} e3 (complex
products), and centroidal inertia I_i. Branch sigma = +1 ("open"): B lies to the left of the
directed line A -> O_B (above the frame when phi = 0); sigma = -1 ("crossed"): to the right.

Slider-crank: crank O A (r, angle phi), conrod A B (l, angle phi2), slider B on the line
y = e (offset e), sigma = +1: slider on the +x side of the crank pin, x_B = r cos phi + l cos phi2.

Crank motion: phi' = w1, phi'' = al1 are inputs of every position function (any prescribed
motion). The sweep models use the speed law omega(phi) = omega (1 + delta sin phi), so
phi'' = omega(phi) d omega / d phi = omega^2 (1 + delta sin phi) delta cos phi; delta = 0 is the
constant speed of the sources.

Loads (per position), for links described by first moments and inertias about their joints
(so counterweights just add to them, and no division by a mass is ever needed):
  crank: U1 = sum m r e^{i theta} (crank frame), J1 = inertia about O_A;
  coupler: m2, V2 = m2 r2 e^{i theta2} (coupler frame, about A), J2A = I2 + m2 r2^2 about A;
  rocker: U3 (rocker frame, about O_B), J3 about O_B, m3.
  shaking force  F = -sum m_i a_Gi + (0, -g sum m_i)            (force of the mechanism on the frame)
  shaking moment M = -dH_O/dt - g sum m_i x_Gi                  (about the crank axis O_A)
      H_O = total angular momentum about O_A; with g = 0 this is the principal moment of the
      inertia forces of physics.md section 3. The useful load's reaction is assumed to close
      through the frame (the process is mounted on it), so it does not enter F or M.
  input torque   T = (dE_kin/dt + dV/dt - P_load) / phi'         (power balance, virtual work)
      four-bar: P_load = M_load phi3' (constant torque M_load on the rocker, ccw positive);
      slider-crank: P_load = F_load x_B' (constant force F_load on the slider along +x).
tests/models/test_linkage.py checks F and M against finite differences of the total momentum and
angular momentum, T against energy balance and a Newton-Euler solve of the joint forces.
"""
from __future__ import annotations

import math

import numpy as np

from .. import status as st
from .._jit import jit_noalloc

# ----------------------------------------------------------------------------- positions
N_POSITIONS = 360  # crank positions per cycle of the stored curves and of every sweep


def crank_positions(n: int):
    """(phi, cos phi, sin phi) of n uniform crank positions phi_i = 2 pi i / n, with the exact
    values at the quarter points that are on the grid (they decide toggle and stroke extremes).
    Every kernel takes the cosines and sines as arguments: N_POSITIONS for sweeps, any n >= 4
    for convergence studies (``mechsweep bench workprecision fourbar_balancing``)."""
    if n < 4:
        raise ValueError(f"need at least 4 crank positions, got {n}")
    phi = 2.0 * np.pi * np.arange(n) / n
    c = np.cos(phi)
    s = np.sin(phi)
    if n % 4 == 0:
        c[[n // 4, 3 * n // 4]] = 0.0
    s[0] = 0.0
    if n % 2 == 0:
        s[n // 2] = 0.0
    return phi, c, s


def position_sums(c, s):
    """[sum cos^2, sum sin^2, sum sin cos] over the positions: the sums of formula (1)."""
    return np.array([float(c @ c), float(s @ s), float(s @ c)])


PHI, COS_PHI, SIN_PHI = crank_positions(N_POSITIONS)

# |sin(transmission angle)| below this anywhere in the cycle: a toggle (0.057 deg from it);
# velocities grow like 1 / sin(mu), accelerations like 1 / sin(mu)^3 there.
TOGGLE_SIN = 1e-3
# relative tolerance of the assembly (full-turn) test: a change-point linkage (s + l = p + q)
# given in floats is a toggle (SINGULAR), not INFEASIBLE
ASSEMBLY_RTOL = 1e-12

SUMS = position_sums(COS_PHI, SIN_PHI)  # sums over the positions for formula (1)
SUM_CC, SUM_SS, SUM_SC = (float(v) for v in SUMS)

# ----------------------------------------------------------------------------- four-bar layout
# parameter columns (the model's ModelSpec declares its Params in exactly this order)
FOURBAR_PARAMS = (
    "a1", "a2", "a3", "a4", "branch",
    "m1", "r1", "theta1", "I1",
    "m2", "r2", "theta2", "I2",
    "m3", "r3", "theta3", "I3",
    "omega", "delta", "g", "M_load",
    "cw1_mr", "cw1_angle", "r_cw1", "cw3_mr", "cw3_angle", "r_cw3",
)
(P_A1, P_A2, P_A3, P_A4, P_BRANCH, P_M1, P_R1, P_TH1, P_I1, P_M2, P_R2, P_TH2, P_I2,
 P_M3, P_R3, P_TH3, P_I3, P_OMEGA, P_DELTA, P_G, P_MLOAD,
 P_CW1, P_CW1A, P_RCW1, P_CW3, P_CW3A, P_RCW3) = range(len(FOURBAR_PARAMS))

# scalar outputs (columns of a design's row; the model declares its Outputs in this order)
FOURBAR_OUTPUTS = (
    "transmission_min",
    # the mechanism as given (links + counterweights cw1_*, cw3_* of the parameters): method 5 indices
    "Fx_range", "Fy_range", "M_range", "T_range", "Fx_rms", "Fy_rms", "M_rms", "T_rms",
    "F_max", "M_max", "T_max", "cw_mass",
    # method 1: complete shaking-force balancing by counterweights on crank and rocker
    "cw1_mr_static", "cw1_angle_static", "cw3_mr_static", "cw3_angle_static", "cw_mass_static",
    "mass_ratio_static", "F_max_static", "M_rms_static", "M_max_static", "M_range_static",
    "T_rms_static", "T_max_static", "T_range_static",
    # method 2: crank counterweight on a moved axis O1(x, y): RMS-optimal and first harmonic
    "axis_x", "axis_y", "dM_rms_axis", "dM_max_axis", "R_axis",
    "axis_x_h1", "axis_y_h1", "dM_rms_h1", "dM_max_h1", "R_h1",
    # method 4: added inertia on the rocker after force balancing
    "J_rocker", "dM_rms_inertia", "dM_max_inertia", "R_inertia", "T_rms_inertia", "T_max_inertia",
)
FOURBAR_CURVES = ("Fx_phi", "Fy_phi", "M_phi", "T_phi", "M_static_phi", "T_static_phi",
                  "dM_axis_phi", "dM_h1_phi", "dM_inertia_phi")
(K_TRANS, K_FX_RANGE, K_FY_RANGE, K_M_RANGE, K_T_RANGE, K_FX_RMS, K_FY_RMS, K_M_RMS, K_T_RMS,
 K_F_MAX, K_M_MAX, K_T_MAX, K_CW_MASS,
 K_CW1_S, K_CW1A_S, K_CW3_S, K_CW3A_S, K_CWM_S, K_MASSR_S, K_FMAX_S, K_MRMS_S, K_MMAX_S,
 K_MRANGE_S, K_TRMS_S, K_TMAX_S, K_TRANGE_S,
 K_AX, K_AY, K_DMRMS_AX, K_DMMAX_AX, K_R_AX,
 K_H1X, K_H1Y, K_DMRMS_H1, K_DMMAX_H1, K_R_H1,
 K_JR, K_DMRMS_IN, K_DMMAX_IN, K_R_IN, K_TRMS_IN, K_TMAX_IN) = range(len(FOURBAR_OUTPUTS))
(C_FX, C_FY, C_M, C_T, C_MS, C_TS, C_DM_AX, C_DM_H1, C_DM_IN) = range(len(FOURBAR_CURVES))

# ----------------------------------------------------------------------------- slider-crank layout
SLIDER_PARAMS = (
    "r", "l", "lam", "e", "branch",
    "m1", "r1", "theta1", "I1",
    "m2", "r2", "theta2", "I2",
    "m3",
    "omega", "delta", "g", "F_load",
    "k", "r_cw",
)
(S_R, S_L, S_LAM, S_E, S_BRANCH, S_M1, S_R1, S_TH1, S_I1, S_M2, S_R2, S_TH2, S_I2, S_M3,
 S_OMEGA, S_DELTA, S_G, S_FLOAD, S_K, S_RCW) = range(len(SLIDER_PARAMS))

SLIDER_OUTPUTS = (
    "transmission_min", "m_A", "m_B", "cw_mr", "cw_angle", "cw_mass",
    "F_max", "Fx_max", "Fy_max", "Fx_rms", "Fy_rms", "Fx_range", "Fy_range",
    "M_rms", "M_max", "M_range", "T_rms", "T_max", "T_range",
    "F_max_unbalanced", "F_tb_error_max", "F_tb_error_rel",
)
SLIDER_CURVES = ("Fx_phi", "Fy_phi", "Fx_tb_phi", "Fy_tb_phi", "M_phi", "T_phi")
(Q_TRANS, Q_MA, Q_MB, Q_CW, Q_CWA, Q_CWM, Q_FMAX, Q_FXMAX, Q_FYMAX, Q_FXRMS, Q_FYRMS,
 Q_FXRANGE, Q_FYRANGE, Q_MRMS, Q_MMAX, Q_MRANGE, Q_TRMS, Q_TMAX, Q_TRANGE,
 Q_FMAX_UNB, Q_TB_ERR, Q_TB_REL) = range(len(SLIDER_OUTPUTS))
(D_FX, D_FY, D_FXTB, D_FYTB, D_M, D_T) = range(len(SLIDER_CURVES))


# ============================================================================= shared helpers
@jit_noalloc
def crank_speed(omega, delta, c1, s1):
    """phi' and phi'' for omega(phi) = omega (1 + delta sin phi): phi'' = omega(phi) d omega/d phi."""
    w1 = omega * (1.0 + delta * s1)
    return w1, w1 * omega * delta * c1


@jit_noalloc
def branch_sign(code):
    """Categorical branch index -> sigma: choice 0 -> +1, choice 1 -> -1."""
    return 1.0 if code == 0.0 else -1.0


@jit_noalloc
def static_two_point(m, b, c):
    """Static two-point mass substitution (physics.md section 4): points B and C on a line through
    the centre of mass G, at signed distances b (to B) and c (to C) on opposite sides (b, c > 0).
    Preserves mass and centre of mass: m_B = m c / (b + c), m_C = m b / (b + c)."""
    return m * c / (b + c), m * b / (b + c)


@jit_noalloc
def dynamic_two_point(m, I_G, b):
    """Dynamic two-point substitution (physics.md section 4): a point B at distance b > 0 from G,
    and the point K on the other side at k = I_G / (m b). Preserves mass, centre of mass and the
    moment of inertia: m_B = m k / (b + k), m_K = m b / (b + k). Returns (m_B, m_K, k)."""
    k = I_G / (m * b)
    return m * k / (b + k), m * b / (b + k), k


@jit_noalloc
def solve2(a11, a12, a21, a22, b1, b2):
    """[a11 a12; a21 a22] x = b by Cramer's rule; (ok, x1, x2)."""
    det = a11 * a22 - a12 * a21
    scale = abs(a11 * a22) + abs(a12 * a21)
    if not (abs(det) > 1e-14 * scale) or scale == 0.0:
        return False, math.nan, math.nan
    return True, (b1 * a22 - a12 * b2) / det, (a11 * b2 - a21 * b1) / det


# ============================================================================= four-bar
@jit_noalloc
def fourbar_assembly(a1, a2, a3, a4):
    """(status, sin of the smallest transmission angle over a full crank turn).

    The crank turns fully iff |a2 - a3| <= L <= a2 + a3 for every distance L = |A O_B| in
    [|a4 - a1|, a4 + a1] (Grashof crank, both assembly branches); sin(mu), with mu the angle
    between coupler and rocker, follows from cos(mu) = (a2^2 + a3^2 - L^2) / (2 a2 a3) and is
    smallest at an end of that interval (phi = 0 or pi; in closed form, whatever the positions).
    Products of differences keep it accurate next to a toggle. INFEASIBLE: no full turn;
    SINGULAR: a toggle (sin mu < TOGGLE_SIN) in the cycle, e.g. a change-point linkage."""
    tol = ASSEMBLY_RTOL * (a1 + a2 + a3 + a4)
    s_min = math.inf
    for L in (abs(a4 - a1), a4 + a1):
        f1 = a2 + a3 - L  # >= 0: the coupler and rocker reach
        f2 = L - abs(a2 - a3)  # >= 0: they can fold that short
        if f1 < -tol or f2 < -tol:
            return st.INFEASIBLE, math.nan
        f1 = max(f1, 0.0)
        f2 = max(f2, 0.0)
        # 1 - cos^2 mu = (1 + cos mu)(1 - cos mu) with 1 + cos mu = (a2+a3-L)(a2+a3+L) / (2 a2 a3)
        # and 1 - cos mu = (L-|a2-a3|)(L+|a2-a3|) / (2 a2 a3)
        one_plus = f1 * (a2 + a3 + L) / (2.0 * a2 * a3)
        one_minus = f2 * (L + abs(a2 - a3)) / (2.0 * a2 * a3)
        s = math.sqrt(max(one_plus * one_minus, 0.0))
        s_min = min(s_min, s)
    if s_min < TOGGLE_SIN:
        return st.SINGULAR, s_min
    return st.OK, s_min


@jit_noalloc
def fourbar_position(a1, a2, a3, a4, sigma, c1, s1, w1, al1):
    """Closed-form position, velocity and acceleration of coupler and rocker.

    Position: B is the intersection of the circles (A, a2) and (O_B, a3): with d = O_B - A,
    L = |d|, p = (a2^2 - a3^2 + L^2) / (2 L), h = sigma sqrt(a2^2 - p^2),
    B = A + (p d + h k x d) / L, computed as q d + hL k x d with q = p / L, hL = h / L. Velocity and acceleration from the derivatives of the loop
    a1 e1 + a2 e2 - a3 e3 = a4 x dotted with e3 and e2 (D = e2 x e3 = sin(phi3 - phi2)):
      w2 = -a1 w1 (e1 x e3) / (a2 D),  w3 = -a1 w1 (e1 x e2) / (a3 D),
      K = a1 (al1 k x e1 - w1^2 e1) - a2 w2^2 e2 + a3 w3^2 e3,
      al2 = -(K . e3) / (a2 D),  al3 = -(K . e2) / (a3 D).
    Returns (c2, s2, c3, s3, w2, w3, al2, al3, D)."""
    # divisions by the link lengths as products with reciprocals: inside the position loops
    # LLVM hoists 1 / a2 and 1 / a3, leaving two divisions and one square root per position
    ia2 = 1.0 / a2
    ia3 = 1.0 / a3
    dx = a4 - a1 * c1
    dy = -a1 * s1
    iL2 = 1.0 / (dx * dx + dy * dy)
    # B - A = (p d + h k x d) / L = q d + hL k x d with q = p / L, hL = h / L (one square root)
    q = (a2 * a2 - a3 * a3) * (0.5 * iL2) + 0.5
    hL = sigma * math.sqrt(max(a2 * a2 * iL2 - q * q, 0.0))
    ex = q * dx - hL * dy
    ey = q * dy + hL * dx
    c2 = ex * ia2
    s2 = ey * ia2
    c3 = (ex - dx) * ia3
    s3 = (ey - dy) * ia3
    D = c2 * s3 - s2 * c3
    iD = 1.0 / D
    w2 = -a1 * w1 * (c1 * s3 - s1 * c3) * iD * ia2
    w3 = -a1 * w1 * (c1 * s2 - s1 * c2) * iD * ia3
    w1s = w1 * w1
    w2s = w2 * w2
    w3s = w3 * w3
    kx = a1 * (-al1 * s1 - w1s * c1) - a2 * w2s * c2 + a3 * w3s * c3
    ky = a1 * (al1 * c1 - w1s * s1) - a2 * w2s * s2 + a3 * w3s * s3
    al2 = -(kx * c3 + ky * s3) * iD * ia2
    al3 = -(kx * c2 + ky * s2) * iD * ia3
    return c2, s2, c3, s3, w2, w3, al2, al3, D


@jit_noalloc
def fourbar_loads(a1, a4, c1, s1, w1, al1, c2, s2, c3, s3, w2, w3, al2, al3,
                  U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, mtot, g, M_load):
    """Shaking force (Fx, Fy), shaking moment M about O_A and input torque T at one position.

    Links by first moments (U1 about O_A in the crank frame, V2 = m2 r2 e^{i theta2} about A in
    the coupler frame, U3 about O_B in the rocker frame) and inertias about the joints
    (J1 about O_A, J2A about A, J3 about O_B); m3 = rocker mass (for its weight's moment),
    mtot = total moving mass. m_i a_Gi: crank al1 k x U1w - w1^2 U1w; coupler
    m2 a_A + al2 k x V2w - w2^2 V2w; rocker al3 k x U3w - w3^2 U3w (U_w: first moment turned
    into the frame of the ground).
      dH_O/dt = J1 al1 + [J2A al2 + A x (m2 a_G2) + V2w x a_A] + [J3 al3 + a4 (m3 a_G3)_y]
      T = J1 al1 + g U1w_x + (w3/w1)(J3 al3 + g U3w_x - M_load)
          + a1 (k x e1) . (m2 a_G2) + (w2/w1)((k x V2w) . a_A + J2A al2 + g V2w_x) + g m2 A_x
    (the coupler's kinetic-energy rate is v_A . m2 a_G2 + w2 (k x V2w) . a_A + J2A w2 al2)."""
    w1s = w1 * w1
    # crank
    u1x = U1x * c1 - U1y * s1
    u1y = U1x * s1 + U1y * c1
    ma1x = -al1 * u1y - w1s * u1x
    ma1y = al1 * u1x - w1s * u1y
    # crank pin A
    ax = a1 * c1
    ay = a1 * s1
    aax = a1 * (-al1 * s1 - w1s * c1)
    aay = a1 * (al1 * c1 - w1s * s1)
    # coupler
    w2s = w2 * w2
    v2x = V2x * c2 - V2y * s2
    v2y = V2x * s2 + V2y * c2
    ma2x = m2 * aax - al2 * v2y - w2s * v2x
    ma2y = m2 * aay + al2 * v2x - w2s * v2y
    # rocker
    w3s = w3 * w3
    u3x = U3x * c3 - U3y * s3
    u3y = U3x * s3 + U3y * c3
    ma3x = -al3 * u3y - w3s * u3x
    ma3y = al3 * u3x - w3s * u3y
    Fx = -(ma1x + ma2x + ma3x)
    Fy = -(ma1y + ma2y + ma3y) - g * mtot
    dH = (J1 * al1 + (J2A * al2 + (ax * ma2y - ay * ma2x) + (v2x * aay - v2y * aax))
          + (J3 * al3 + a4 * ma3y))
    M = -dH - g * (u1x + m2 * ax + v2x + m3 * a4 + u3x)
    q2 = w2 / w1
    q3 = w3 / w1
    T = (J1 * al1 + g * u1x + q3 * (J3 * al3 + g * u3x - M_load)
         + a1 * (c1 * ma2y - s1 * ma2x)
         + q2 * (v2x * aay - v2y * aax + J2A * al2 + g * v2x) + g * m2 * ax)
    return Fx, Fy, M, T


@jit_noalloc
def fourbar_static_counterweights(a1, a2, a3, m1, r1, th1, m2, r2, th2, m3, r3, th3):
    """Complete shaking-force balancing by linearly independent vectors (physics.md section 4):
    the crank and rocker first moments must become
      U1 = m2 a1 ((r2 / a2) e^{i theta2} - 1),   U3 = -m2 r2 (a3 / a2) e^{i theta2},
    so the counterweights are C1 = U1 - m1 r1 e^{i theta1}, C3 = U3 - m3 r3 e^{i theta3}
    (link frames). Returns (C1x, C1y, C3x, C3y)."""
    c2 = math.cos(th2)
    s2 = math.sin(th2)
    u1x = m2 * a1 * (r2 / a2 * c2 - 1.0)
    u1y = m2 * a1 * (r2 / a2 * s2)
    u3x = -m2 * r2 * a3 / a2 * c2
    u3y = -m2 * r2 * a3 / a2 * s2
    return (u1x - m1 * r1 * math.cos(th1), u1y - m1 * r1 * math.sin(th1),
            u3x - m3 * r3 * math.cos(th3), u3y - m3 * r3 * math.sin(th3))


@jit_noalloc
def fourbar_links(p, cw1x, cw1y, cw3x, cw3y, r_cw1, r_cw3):
    """Link constants for loads: links of row p plus point-mass counterweights C1 (crank, at
    radius r_cw1) and C3 (rocker, at r_cw3), first moments in the link frames.
    Returns (U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, mtot, cw_mass)."""
    m1 = p[P_M1]
    m2 = p[P_M2]
    m3 = p[P_M3]
    r1 = p[P_R1]
    r2 = p[P_R2]
    r3 = p[P_R3]
    mc1 = math.hypot(cw1x, cw1y) / r_cw1
    mc3 = math.hypot(cw3x, cw3y) / r_cw3
    U1x = m1 * r1 * math.cos(p[P_TH1]) + cw1x
    U1y = m1 * r1 * math.sin(p[P_TH1]) + cw1y
    J1 = p[P_I1] + m1 * r1 * r1 + mc1 * r_cw1 * r_cw1
    V2x = m2 * r2 * math.cos(p[P_TH2])
    V2y = m2 * r2 * math.sin(p[P_TH2])
    J2A = p[P_I2] + m2 * r2 * r2
    U3x = m3 * r3 * math.cos(p[P_TH3]) + cw3x
    U3y = m3 * r3 * math.sin(p[P_TH3]) + cw3y
    J3 = p[P_I3] + m3 * r3 * r3 + mc3 * r_cw3 * r_cw3
    return (U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3 + mc3,
            m1 + m2 + m3 + mc1 + mc3, mc1 + mc3)


@jit_noalloc
def fourbar_cw_radii(p):
    """Counterweight radii; NaN (absent) means at the link's far joint (a1 and a3)."""
    r_cw1 = p[P_RCW1] if not math.isnan(p[P_RCW1]) else p[P_A1]
    r_cw3 = p[P_RCW3] if not math.isnan(p[P_RCW3]) else p[P_A3]
    return r_cw1, r_cw3


@jit_noalloc
def fourbar_curves_at(p, static, phi, w1, al1, out):
    """Per-position kinematics and loads of four-bar row ``p`` at arbitrary crank angles phi with
    arbitrary phi' = w1, phi'' = al1 (arrays of one length). ``static`` False: the mechanism as
    given (counterweights of the parameters); True: completely force-balanced (method 1).
    out[:, :] columns: c2, s2, c3, s3, w2, w3, al2, al3, D, Fx, Fy, M, T. Returns a status
    (assembly check; SINGULAR also if a given position is at a toggle)."""
    a1, a2, a3, a4 = p[P_A1], p[P_A2], p[P_A3], p[P_A4]
    code, _ = fourbar_assembly(a1, a2, a3, a4)
    if code != st.OK:
        return code
    sigma = branch_sign(p[P_BRANCH])
    r_cw1, r_cw3 = fourbar_cw_radii(p)
    if static:
        c1x, c1y, c3x, c3y = fourbar_static_counterweights(
            a1, a2, a3, p[P_M1], p[P_R1], p[P_TH1], p[P_M2], p[P_R2], p[P_TH2], p[P_M3], p[P_R3], p[P_TH3])
    else:
        c1x = p[P_CW1] * math.cos(p[P_CW1A])
        c1y = p[P_CW1] * math.sin(p[P_CW1A])
        c3x = p[P_CW3] * math.cos(p[P_CW3A])
        c3y = p[P_CW3] * math.sin(p[P_CW3A])
    U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, mtot, _ = fourbar_links(p, c1x, c1y, c3x, c3y, r_cw1, r_cw3)
    g = p[P_G]
    for j in range(phi.shape[0]):
        c1 = math.cos(phi[j])
        s1 = math.sin(phi[j])
        c2, s2, c3, s3, w2, w3, al2, al3, D = fourbar_position(a1, a2, a3, a4, sigma, c1, s1, w1[j], al1[j])
        if abs(D) < TOGGLE_SIN:
            code = st.SINGULAR
        Fx, Fy, M, T = fourbar_loads(a1, a4, c1, s1, w1[j], al1[j], c2, s2, c3, s3, w2, w3, al2, al3,
                                     U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, mtot, g, p[P_MLOAD])
        row = out[j]
        row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7], row[8] = c2, s2, c3, s3, w2, w3, al2, al3, D
        row[9], row[10], row[11], row[12] = Fx, Fy, M, T
    return code


@jit_noalloc
def dot4(x, y):
    """sum x_i y_i with four interleaved accumulators (see cycle_stats)."""
    n = x.shape[0]
    s0 = s1 = s2 = s3 = 0.0
    m = n - n % 4
    for j in range(0, m, 4):
        s0 += x[j] * y[j]
        s1 += x[j + 1] * y[j + 1]
        s2 += x[j + 2] * y[j + 2]
        s3 += x[j + 3] * y[j + 3]
    for j in range(m, n):
        s0 += x[j] * y[j]
    return (s0 + s1) + (s2 + s3)


@jit_noalloc
def axis_basis(S, cb, sb, c1, s1, w1, al1, W):
    """d(Delta M)/dx and d(Delta M)/dy for the crank counterweight (static moment S, at angle beta
    from the crank, weight W = m_cw g) turning about O1 = (x, y) instead of O_A.

    Its angular momentum about O_A changes by S phi' (x cos psi + y sin psi), psi = phi + beta, so
    the moment of the inertia forces changes by
      -S [phi'^2 (y cos psi - x sin psi) + phi'' (x cos psi + y sin psi)]
    (physics.md section 3 prints this for beta = pi, the counterweight opposite the crank), and its
    weight, now acting x further along the frame, changes the moment of the weights by -W x: with
    M = -dH/dt - g sum m x_G (the shaking moment of every output, gravity included),
      Delta M = -S [phi'^2 (y cos psi - x sin psi) + phi'' (x cos psi + y sin psi)] - W x.
    (The source's formula has no gravity term: right only for g = 0.) cb, sb = cos(beta),
    sin(beta). Returns (gx, gy) with Delta M = gx x + gy y."""
    cp = c1 * cb - s1 * sb
    sp = s1 * cb + c1 * sb
    w1s = w1 * w1
    return S * (w1s * sp - al1 * cp) - W, -S * (w1s * cp + al1 * sp)


@jit_noalloc
def axis_fit(c, s, w1, al1, moment, weight, S, cb, sb, harmonic, W):
    """Axis O1 = (x, y) of the crank counterweight (static moment S, angle beta from the crank,
    weight W = m_cw g: axis_basis).

    harmonic False, RMS-optimal: minimise sum_i w_i (M_i + gx_i x + gy_i y)^2, the 2x2 normal
    equations [sum w gx^2, sum w gx gy; sum w gx gy, sum w gy^2] (x, y) = -(sum w M gx, sum w M gy)
    (physics.md section 3 "in general"; any positions, any speed law).
    harmonic True: the first Fourier harmonic of the residual vanishes,
    sum_i w_i (M_i + gx_i x + gy_i y) (cos phi_i, sin phi_i) = 0 (w_i: quadrature weights in phi).
    c, s = cos, sin of the crank positions; w1, al1 = phi', phi'' there. S = 0: nothing to move,
    the minimum-norm solution (0, 0). Returns (ok, x, y)."""
    if S == 0.0:
        return True, 0.0, 0.0
    a11 = a12 = a21 = a22 = b1 = b2 = 0.0
    if harmonic:
        for j in range(moment.shape[0]):
            gx, gy = axis_basis(S, cb, sb, c[j], s[j], w1[j], al1[j], W)
            wc = weight[j] * c[j]
            ws = weight[j] * s[j]
            a11 += gx * wc
            a12 += gy * wc
            a21 += gx * ws
            a22 += gy * ws
            b1 -= moment[j] * wc
            b2 -= moment[j] * ws
    else:
        for j in range(moment.shape[0]):
            gx, gy = axis_basis(S, cb, sb, c[j], s[j], w1[j], al1[j], W)
            wgx = weight[j] * gx
            wgy = weight[j] * gy
            a11 += wgx * gx
            a12 += wgx * gy
            a22 += wgy * gy
            b1 -= moment[j] * wgx
            b2 -= moment[j] * wgy
        a21 = a12
    return solve2(a11, a12, a21, a22, b1, b2)


@jit_noalloc
def axis_formula1_sums(smc, sms, scc, sss, scs, S, w, cb, sb):
    """Formula (1) of the source (physics.md section 3) at constant speed w and without gravity
    (the counterweight's weight adds -W x to Delta M, which the formula leaves out), written for a
    counterweight at angle beta from the crank, psi = phi + beta (beta = pi gives the printed form
    x = sum M sin phi / (S w^2 sum sin^2 phi), y = -sum M cos phi / (S w^2 sum cos^2 phi)):
      x = -sum M sin psi / (S w^2 sum sin^2 psi),  y = sum M cos psi / (S w^2 sum cos^2 psi),
    from the sums over the positions smc = sum M cos phi, sms = sum M sin phi, scc = sum cos^2,
    sss = sum sin^2, scs = sum sin cos (sin psi = sin phi cb + cos phi sb, cos psi =
    cos phi cb - sin phi sb). It is the exact RMS optimum when sum sin psi cos psi = 0
    (symmetric uniform positions)."""
    k = S * w * w
    m_sin = sms * cb + smc * sb
    m_cos = smc * cb - sms * sb
    sin2 = sss * cb * cb + 2.0 * scs * cb * sb + scc * sb * sb
    cos2 = scc * cb * cb - 2.0 * scs * cb * sb + sss * sb * sb
    return -m_sin / (k * sin2), m_cos / (k * cos2)


@jit_noalloc
def axis_formula1(c, s, moment, S, w, cb, sb):
    """axis_formula1_sums at positions with cosines c and sines s."""
    return axis_formula1_sums(dot4(moment, c), dot4(moment, s), dot4(c, c), dot4(s, s), dot4(s, c), S, w, cb, sb)


@jit_noalloc
def axis_residual_const(c, s, moment, Sw2, cb, sb, x, y, out):
    """The residual at constant speed (phi'' = 0): dM_i = M_i + S w^2 (x sin psi_i - y cos psi_i)
    = M_i + A sin phi_i + B cos phi_i, A = S w^2 (x cb + y sb), B = S w^2 (x sb - y cb),
    Sw2 = S w^2. Returns (RMS, max |dM|)."""
    A = Sw2 * (x * cb + y * sb)
    B = Sw2 * (x * sb - y * cb)
    for j in range(moment.shape[0]):
        out[j] = moment[j] + (A * s[j] + B * c[j])
    lo, hi, rms = cycle_stats(out)
    return rms, max(hi, -lo)


@jit_noalloc
def axis_residual(c, s, w1, al1, moment, S, cb, sb, x, y, out, W):
    """Residual dM_i = M_i + Delta M_i of the counterweight (weight W = m_cw g) on axis (x, y) into
    out; returns (RMS, max |dM|)."""
    ss = 0.0
    mx = 0.0
    n = moment.shape[0]
    for j in range(n):
        gx, gy = axis_basis(S, cb, sb, c[j], s[j], w1[j], al1[j], W)
        dm = moment[j] + gx * x + gy * y
        out[j] = dm
        ss += dm * dm
        mx = max(mx, abs(dm))
    return math.sqrt(ss / n), mx


# rows of a design's scratch buffer: the kinematics over the cycle, then the loads
N_BUF = 19
(R_C2, R_S2, R_C3, R_S3, R_W2, R_W3, R_AL2, R_AL3, R_W1, R_AL1, R_Q, R_H, R_ID,
 B_FX, B_FY, B_M, B_T, B_Q3, B_DM) = range(N_BUF)


@jit_noalloc
def fourbar_kinematics_cycle(a1, a2, a3, a4, sigma, omega, delta, cos_phi, sin_phi, buf):
    """fourbar_position at the crank positions with cosines cos_phi and sines sin_phi (speed law
    of crank_speed) into rows R_C2 .. R_AL1 of buf: the same expressions, term for term (so
    bitwise the same numbers), split into four loops. Each loop is branch-free and vectorised by
    LLVM; splitting the long chain div -> sqrt -> div of one position lets the processor overlap
    many positions (one fused loop is latency-bound, and slower)."""
    N = cos_phi.shape[0]
    ia2 = 1.0 / a2
    ia3 = 1.0 / a3
    for j in range(N):
        dx = a4 - a1 * cos_phi[j]
        dy = -a1 * sin_phi[j]
        iL2 = 1.0 / (dx * dx + dy * dy)
        q = (a2 * a2 - a3 * a3) * (0.5 * iL2) + 0.5
        buf[R_Q, j] = q
        buf[R_H, j] = max(a2 * a2 * iL2 - q * q, 0.0)
    for j in range(N):
        buf[R_H, j] = sigma * math.sqrt(buf[R_H, j])
    for j in range(N):
        dx = a4 - a1 * cos_phi[j]
        dy = -a1 * sin_phi[j]
        q = buf[R_Q, j]
        hL = buf[R_H, j]
        ex = q * dx - hL * dy
        ey = q * dy + hL * dx
        c2 = ex * ia2
        s2 = ey * ia2
        c3 = (ex - dx) * ia3
        s3 = (ey - dy) * ia3
        buf[R_C2, j] = c2
        buf[R_S2, j] = s2
        buf[R_C3, j] = c3
        buf[R_S3, j] = s3
        buf[R_ID, j] = 1.0 / (c2 * s3 - s2 * c3)
    for j in range(N):
        c1 = cos_phi[j]
        s1 = sin_phi[j]
        w1, al1 = crank_speed(omega, delta, c1, s1)
        c2 = buf[R_C2, j]
        s2 = buf[R_S2, j]
        c3 = buf[R_C3, j]
        s3 = buf[R_S3, j]
        iD = buf[R_ID, j]
        w2 = -a1 * w1 * (c1 * s3 - s1 * c3) * iD * ia2
        w3 = -a1 * w1 * (c1 * s2 - s1 * c2) * iD * ia3
        w1s = w1 * w1
        w2s = w2 * w2
        w3s = w3 * w3
        kx = a1 * (-al1 * s1 - w1s * c1) - a2 * w2s * c2 + a3 * w3s * c3
        ky = a1 * (al1 * c1 - w1s * s1) - a2 * w2s * s2 + a3 * w3s * s3
        buf[R_W2, j] = w2
        buf[R_W3, j] = w3
        buf[R_AL2, j] = -(kx * c3 + ky * s3) * iD * ia2
        buf[R_AL3, j] = -(kx * c2 + ky * s2) * iD * ia3
        buf[R_W1, j] = w1
        buf[R_AL1, j] = al1


@jit_noalloc
def fourbar_loads_cycle(a1, a4, U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, mtot, g, M_load,
                        cos_phi, sin_phi, buf):
    """fourbar_loads over the cycle from the kinematics rows of buf into rows B_FX, B_FY, B_M,
    B_T and B_Q3 (phi3' / phi'). Branch-free, vectorised."""
    for j in range(cos_phi.shape[0]):
        w1 = buf[R_W1, j]
        w3 = buf[R_W3, j]
        Fx, Fy, M, T = fourbar_loads(a1, a4, cos_phi[j], sin_phi[j], w1, buf[R_AL1, j],
                                     buf[R_C2, j], buf[R_S2, j], buf[R_C3, j], buf[R_S3, j],
                                     buf[R_W2, j], w3, buf[R_AL2, j], buf[R_AL3, j],
                                     U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, mtot, g, M_load)
        buf[B_FX, j] = Fx
        buf[B_FY, j] = Fy
        buf[B_M, j] = M
        buf[B_T, j] = T
        buf[B_Q3, j] = w3 / w1


@jit_noalloc
def fourbar_moment_cycle(a1, a4, U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, g, cos_phi, sin_phi, buf):
    """Only the shaking moment (row B_M), when no force or torque is asked for: fourbar_loads
    inlined, whose unused force and torque LLVM drops, so M is bitwise fourbar_loads_cycle's."""
    for j in range(cos_phi.shape[0]):
        buf[B_M, j] = fourbar_loads(a1, a4, cos_phi[j], sin_phi[j], buf[R_W1, j], buf[R_AL1, j],
                                    buf[R_C2, j], buf[R_S2, j], buf[R_C3, j], buf[R_S3, j],
                                    buf[R_W2, j], buf[R_W3, j], buf[R_AL2, j], buf[R_AL3, j],
                                    U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, 0.0, g, 0.0)[2]


@jit_noalloc
def stats_into(row, x, k_range, k_rms, k_max):
    """cycle_stats of curve x into row: its range (max - min) at k_range, RMS at k_rms and largest
    magnitude at k_max (not written where k_max < 0). Returns the largest magnitude."""
    lo, hi, rms = cycle_stats(x)
    row[k_range] = hi - lo
    row[k_rms] = rms
    if k_max >= 0:
        row[k_max] = max(hi, -lo)
    return max(hi, -lo)


@jit_noalloc
def copy_curve(crv, slot, x):
    """x into row slot of the curves, where the curve is asked for (slot >= 0); element by element:
    a whole-row copy needs numba's NRT."""
    if slot >= 0:
        for j in range(x.shape[0]):
            crv[slot, j] = x[j]


@jit_noalloc
def cycle_stats(x):
    """(min, max, RMS) of a curve. Four interleaved accumulators (combined as (0 + 1) + (2 + 3)):
    a strict-IEEE reduction cannot be vectorised, but four chains keep the adder busy."""
    n = x.shape[0]
    lo0 = lo1 = lo2 = lo3 = x[0]
    hi0 = hi1 = hi2 = hi3 = x[0]
    s0 = s1 = s2 = s3 = 0.0
    m = n - n % 4
    for j in range(0, m, 4):
        v0 = x[j]
        v1 = x[j + 1]
        v2 = x[j + 2]
        v3 = x[j + 3]
        lo0 = v0 if v0 < lo0 else lo0
        lo1 = v1 if v1 < lo1 else lo1
        lo2 = v2 if v2 < lo2 else lo2
        lo3 = v3 if v3 < lo3 else lo3
        hi0 = v0 if v0 > hi0 else hi0
        hi1 = v1 if v1 > hi1 else hi1
        hi2 = v2 if v2 > hi2 else hi2
        hi3 = v3 if v3 > hi3 else hi3
        s0 += v0 * v0
        s1 += v1 * v1
        s2 += v2 * v2
        s3 += v3 * v3
    for j in range(m, n):
        v = x[j]
        lo0 = v if v < lo0 else lo0
        hi0 = v if v > hi0 else hi0
        s0 += v * v
    lo = min(min(lo0, lo1), min(lo2, lo3))
    hi = max(max(hi0, hi1), max(hi2, hi3))
    return lo, hi, math.sqrt(((s0 + s1) + (s2 + s3)) / n)


@jit_noalloc
def max_force(fx, fy, fy_offset):
    """max over the cycle of |(fx, fy + fy_offset)|."""
    m = 0.0
    for j in range(fx.shape[0]):
        fyj = fy[j] + fy_offset
        v = fx[j] * fx[j] + fyj * fyj
        m = v if v > m else m
    return math.sqrt(m)


# ============================================================================= slider-crank
@jit_noalloc
def slider_assembly(r, l, e):
    """(status, sin of the smallest transmission angle). The crank turns fully iff
    |e - r sin phi| <= l for all phi, i.e. l >= r + |e|; the conrod is then closest to
    perpendicular to the slider line at phi = -/+ 90 deg, where
    cos(phi2) = sqrt((l - r - |e|)(l + r + |e|)) / l = sin(mu_min)."""
    reach = r + abs(e)
    f = l - reach
    if f < -ASSEMBLY_RTOL * (l + reach):
        return st.INFEASIBLE, math.nan
    s = math.sqrt(max(f, 0.0) * (l + reach)) / l
    if s < TOGGLE_SIN:
        return st.SINGULAR, s
    return st.OK, s


@jit_noalloc
def slider_position(r, l, e, sigma, c1, s1, w1, al1):
    """Exact slider-crank kinematics. sin phi2 = (e - r sin phi) / l, cos phi2 = sigma sqrt(1 - sin^2),
    x_B = r cos phi + l cos phi2; from r w1 cos phi + l w2 cos phi2 = 0 and its derivative:
      w2 = -r w1 c1 / (l c2),  al2 = (r w1^2 s1 + l w2^2 s2 - r al1 c1) / (l c2),
      v_B = -r w1 s1 - l w2 s2,  a_B = -r al1 s1 - r w1^2 c1 - l al2 s2 - l w2^2 c2.
    Returns (c2, s2, w2, al2, xB, vB, aB)."""
    s2 = (e - r * s1) / l
    c2 = sigma * math.sqrt(max((1.0 - s2) * (1.0 + s2), 0.0))
    w2 = -r * w1 * c1 / (l * c2)
    w1s = w1 * w1
    w2s = w2 * w2
    al2 = (r * w1s * s1 + l * w2s * s2 - r * al1 * c1) / (l * c2)
    xB = r * c1 + l * c2
    vB = -r * w1 * s1 - l * w2 * s2
    aB = -r * al1 * s1 - r * w1s * c1 - l * al2 * s2 - l * w2s * c2
    return c2, s2, w2, al2, xB, vB, aB


@jit_noalloc
def slider_loads(r, e, c1, s1, w1, al1, c2, s2, w2, al2, xB, vB, aB,
                 U1x, U1y, J1, m2, V2x, V2y, J2A, m3, mtot, g, F_load):
    """Shaking force, shaking moment about O and input torque of the slider-crank (same
    conventions as fourbar_loads; the slider is a point mass m3 at B = (x_B, e)):
      dH_O/dt = J1 al1 + [J2A al2 + A x (m2 a_G2) + V2w x a_A] + B x (m3 a_B),  B x (m3 a_B) = -e m3 a_B
      T = J1 al1 + g U1w_x + r (k x e1) . (m2 a_G2) + (w2/w1)((k x V2w) . a_A + J2A al2 + g V2w_x)
          + g m2 A_x + (v_B / w1)(m3 a_B - F_load)."""
    w1s = w1 * w1
    u1x = U1x * c1 - U1y * s1
    u1y = U1x * s1 + U1y * c1
    ma1x = -al1 * u1y - w1s * u1x
    ma1y = al1 * u1x - w1s * u1y
    ax = r * c1
    ay = r * s1
    aax = r * (-al1 * s1 - w1s * c1)
    aay = r * (al1 * c1 - w1s * s1)
    w2s = w2 * w2
    v2x = V2x * c2 - V2y * s2
    v2y = V2x * s2 + V2y * c2
    ma2x = m2 * aax - al2 * v2y - w2s * v2x
    ma2y = m2 * aay + al2 * v2x - w2s * v2y
    ma3x = m3 * aB
    Fx = -(ma1x + ma2x + ma3x)
    Fy = -(ma1y + ma2y) - g * mtot
    dH = J1 * al1 + (J2A * al2 + (ax * ma2y - ay * ma2x) + (v2x * aay - v2y * aax)) - e * ma3x
    M = -dH - g * (u1x + m2 * ax + v2x + m3 * xB)
    T = (J1 * al1 + g * u1x + r * (c1 * ma2y - s1 * ma2x)
         + (w2 / w1) * (v2x * aay - v2y * aax + J2A * al2 + g * v2x) + g * m2 * ax
         + (vB / w1) * (ma3x - F_load))
    return Fx, Fy, M, T


@jit_noalloc
def slider_conrod_length(p):
    """l, or r / lam when l is absent (NaN)."""
    return p[S_L] if not math.isnan(p[S_L]) else p[S_R] / p[S_LAM]


@jit_noalloc
def slider_counterweight(p, l):
    """Textbook partial balancing (physics.md section 4) with static two-point substitution of the
    conrod on A and B (generalised complex masses when its centre is off the line AB):
      conrod: m2 (1 - u2 / l) at A, m2 u2 / l at B, u2 = r2 e^{i theta2};
      rotating first moment (crank frame) U_rot = m1 r1 e^{i theta1} + m2 r (1 - u2 / l),
      reciprocating mass m_B = m3 + m2 Re(u2) / l,  m_A = |U_rot| / r;
      counterweight C = -(U_rot + k m_B r): m_cw r_cw = |C| (= (m_A + k m_B) r inline), angle arg C.
    Returns (Cx, Cy, m_A, m_B)."""
    r = p[S_R]
    m2 = p[S_M2]
    u2x = p[S_R2] * math.cos(p[S_TH2])
    u2y = p[S_R2] * math.sin(p[S_TH2])
    urx = p[S_M1] * p[S_R1] * math.cos(p[S_TH1]) + m2 * r * (1.0 - u2x / l)
    ury = p[S_M1] * p[S_R1] * math.sin(p[S_TH1]) - m2 * r * u2y / l
    mB = p[S_M3] + m2 * u2x / l
    return -(urx + p[S_K] * mB * r), -ury, math.hypot(urx, ury) / r, mB


@jit_noalloc
def slider_links(p, cwx, cwy, r_cw):
    """(U1x, U1y, J1, m2, V2x, V2y, J2A, m3, mtot, cw_mass) with a point counterweight (cwx, cwy)
    at radius r_cw on the crank."""
    m1 = p[S_M1]
    m2 = p[S_M2]
    r1 = p[S_R1]
    r2 = p[S_R2]
    mc = math.hypot(cwx, cwy) / r_cw
    U1x = m1 * r1 * math.cos(p[S_TH1]) + cwx
    U1y = m1 * r1 * math.sin(p[S_TH1]) + cwy
    J1 = p[S_I1] + m1 * r1 * r1 + mc * r_cw * r_cw
    V2x = m2 * r2 * math.cos(p[S_TH2])
    V2y = m2 * r2 * math.sin(p[S_TH2])
    J2A = p[S_I2] + m2 * r2 * r2
    return U1x, U1y, J1, m2, V2x, V2y, J2A, p[S_M3], m1 + m2 + p[S_M3] + mc, mc


@jit_noalloc
def slider_curves_at(p, balanced, phi, w1, al1, out):
    """Per-position kinematics and loads of slider-crank row p at arbitrary phi, phi', phi''.
    balanced: with the k-counterweight (else bare). out columns: c2, s2, w2, al2, xB, vB, aB,
    Fx, Fy, M, T. Returns a status."""
    r = p[S_R]
    l = slider_conrod_length(p)
    e = p[S_E]
    code, _ = slider_assembly(r, l, e)
    if code != st.OK:
        return code
    sigma = branch_sign(p[S_BRANCH])
    r_cw = p[S_RCW] if not math.isnan(p[S_RCW]) else r
    cwx, cwy = 0.0, 0.0
    if balanced:
        cwx, cwy, _, _ = slider_counterweight(p, l)
    U1x, U1y, J1, m2, V2x, V2y, J2A, m3, mtot, _ = slider_links(p, cwx, cwy, r_cw)
    for j in range(phi.shape[0]):
        c1 = math.cos(phi[j])
        s1 = math.sin(phi[j])
        c2, s2, w2, al2, xB, vB, aB = slider_position(r, l, e, sigma, c1, s1, w1[j], al1[j])
        if abs(c2) < TOGGLE_SIN:
            code = st.SINGULAR
        Fx, Fy, M, T = slider_loads(r, e, c1, s1, w1[j], al1[j], c2, s2, w2, al2, xB, vB, aB,
                                    U1x, U1y, J1, m2, V2x, V2y, J2A, m3, mtot, p[S_G], p[S_FLOAD])
        row = out[j]
        row[0], row[1], row[2], row[3], row[4], row[5], row[6] = c2, s2, w2, al2, xB, vB, aB
        row[7], row[8], row[9], row[10] = Fx, Fy, M, T
    return code


# rows of a slider-crank design's scratch buffer
N_SBUF = 17
(SR_C2, SR_S2, SR_W2, SR_AL2, SR_XB, SR_VB, SR_AB, SR_W1, SR_AL1,
 SB_FX, SB_FY, SB_M, SB_T, SB_FX0, SB_FY0, SB_FXTB, SB_FYTB) = range(N_SBUF)


@jit_noalloc
def slider_kinematics_cycle(r, l, e, sigma, omega, delta, cos_phi, sin_phi, buf):
    """slider_position at the crank positions with cosines cos_phi and sines sin_phi into rows
    SR_C2 .. SR_AL1 (two branch-free loops, vectorised)."""
    N = cos_phi.shape[0]
    for j in range(N):
        s2 = (e - r * sin_phi[j]) / l
        buf[SR_S2, j] = s2
        buf[SR_C2, j] = sigma * math.sqrt(max((1.0 - s2) * (1.0 + s2), 0.0))
    for j in range(N):
        c1 = cos_phi[j]
        s1 = sin_phi[j]
        w1, al1 = crank_speed(omega, delta, c1, s1)
        c2 = buf[SR_C2, j]
        s2 = buf[SR_S2, j]
        w2 = -r * w1 * c1 / (l * c2)
        w1s = w1 * w1
        w2s = w2 * w2
        al2 = (r * w1s * s1 + l * w2s * s2 - r * al1 * c1) / (l * c2)
        buf[SR_W2, j] = w2
        buf[SR_AL2, j] = al2
        buf[SR_XB, j] = r * c1 + l * c2
        buf[SR_VB, j] = -r * w1 * s1 - l * w2 * s2
        buf[SR_AB, j] = -r * al1 * s1 - r * w1s * c1 - l * al2 * s2 - l * w2s * c2
        buf[SR_W1, j] = w1
        buf[SR_AL1, j] = al1


@jit_noalloc
def slider_loads_cycle(r, e, U1x, U1y, J1, m2, V2x, V2y, J2A, m3, mtot, g, F_load, cos_phi, sin_phi, buf, first):
    """slider_loads over the cycle from the kinematics rows into rows first .. first + 3
    (Fx, Fy, M, T). Branch-free, vectorised."""
    for j in range(cos_phi.shape[0]):
        Fx, Fy, M, T = slider_loads(r, e, cos_phi[j], sin_phi[j], buf[SR_W1, j], buf[SR_AL1, j],
                                    buf[SR_C2, j], buf[SR_S2, j], buf[SR_W2, j], buf[SR_AL2, j],
                                    buf[SR_XB, j], buf[SR_VB, j], buf[SR_AB, j],
                                    U1x, U1y, J1, m2, V2x, V2y, J2A, m3, mtot, g, F_load)
        buf[first, j] = Fx
        buf[first + 1, j] = Fy
        buf[first + 2, j] = M
        buf[first + 3, j] = T
