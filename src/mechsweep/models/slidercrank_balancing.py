"""Slider-crank partial balancing: a crank counterweight for the rotating mass and a fraction k of
the reciprocating mass, with exact kinematics, and the error of the textbook's two-term formula.

Source: physics.md section 4 (machine-dynamics textbook): m_cw r_cw = (m_A + k m_B) r,
residual F_x = (1 - k) m_B r omega^2 cos phi + lambda m_B r omega^2 cos 2 phi,
F_y = -k m_B r omega^2 sin phi, lambda = r / l. Kernels, equations and conventions:
:mod:`mechsweep.models._linkage` (crank pivot O at the origin, slider on the line y = e moving
along x, gravity along -y, crank speed omega(phi) = omega (1 + delta sin phi)).

m_A, m_B come from the static two-point substitution of the conrod on its joints (generalised
complex masses when its centre is off the line AB: the imaginary part at B is not balanced by
the crank counterweight). The counterweight is a point mass at radius r_cw (default r) at angle
cw_angle from the crank (pi when every centre of mass is on its link line).

Every output is evaluated at N_POSITIONS = 360 uniform crank positions phi_i = 2 pi i / 360 (a
fixed constant: algebraic scenes have no solver settings; ``evaluate(..., n_positions=N)`` takes
any N, and ``mechsweep bench workprecision slidercrank_balancing`` measures the error);
``*_phi`` outputs have the extra dimension ``phi`` and are stored only when a scene asks for them. The textbook formula uses the
mean speed omega and e = 0; its curves include the static weight -g m_total in Fy so that the
error measures the kinematic approximation (with delta = 0, e = 0 and centres on the link lines
the error is the lambda^3 and higher terms of the slider acceleration, in Fx only).

Statuses: INFEASIBLE if the crank cannot make a full turn (l < r + |e|); SINGULAR at a toggle
(l = r + |e| within TOGGLE_SIN), or if F_tb_error_rel is asked for with m_B = 0.
"""
from __future__ import annotations

import math

from .. import status as st
from .._jit import jit
from ..model.closed import ClosedFormModel
from . import _linkage as L
from ._linkage import (  # the per-design function's helpers and layout constants
    D_FX, D_FXTB, D_FY, D_FYTB, D_M, D_T, Q_CW, Q_CWA, Q_CWM, Q_FMAX, Q_FMAX_UNB, Q_FXMAX, Q_FXRANGE, Q_FXRMS,
    Q_FYMAX, Q_FYRANGE, Q_FYRMS, Q_MA, Q_MB, Q_MMAX, Q_MRANGE, Q_MRMS, Q_TB_ERR, Q_TB_REL, Q_TMAX, Q_TRANGE,
    Q_TRANS, Q_TRMS, SB_FX, SB_FX0, SB_FXTB, SB_FY, SB_FY0, SB_FYTB, SB_M, SB_T, S_BRANCH, S_DELTA, S_E,
    S_FLOAD, S_G, S_K, S_OMEGA, S_R, S_RCW, branch_sign, cycle_stats, max_force, slider_assembly,
    slider_conrod_length, slider_counterweight, slider_kinematics_cycle, slider_links, slider_loads_cycle)
from ._spec import Output, Param
from .fourbar_balancing import PHI_DIM, positions

_ANGLE = dict(lo=-2.0 * math.pi, hi=2.0 * math.pi)

PARAMS = (
    Param("r", "r", "m", "crank radius O A", lo=0.0, lo_open=True),
    Param("l", "l", "m", "connecting-rod length A B (give l or lambda)", lo=0.0, lo_open=True,
          required=False, default=math.nan),
    Param("lambda", "λ", "1", "crank-to-rod ratio r / l (give l or lambda)", lo=0.0, lo_open=True,
          required=False, default=math.nan),
    Param("e", "e", "m", "offset of the slider line from the crank axis (slider on y = e)", required=False,
          default=0.0),
    Param("branch", "σ", "1", "assembly branch: slider on the +x (right) or -x (left) side of the crank pin",
          choices=("right", "left"), required=False, default=0.0),
    Param("m1", "m1", "kg", "crank mass", lo=0.0),
    Param("r1", "r1", "m", "distance of the crank's centre of mass from O", lo=0.0),
    Param("theta1", "θ1", "rad", "angle of the crank's centre of mass from the crank line", required=False,
          default=0.0, **_ANGLE),
    Param("I1", "I1", "kg m^2", "crank moment of inertia about its centre of mass", lo=0.0),
    Param("m2", "m2", "kg", "connecting-rod mass", lo=0.0),
    Param("r2", "r2", "m", "distance of the rod's centre of mass from the crank pin A", lo=0.0),
    Param("theta2", "θ2", "rad", "angle of the rod's centre of mass from the line A B", required=False,
          default=0.0, **_ANGLE),
    Param("I2", "I2", "kg m^2", "connecting-rod moment of inertia about its centre of mass", lo=0.0),
    Param("m3", "m3", "kg", "slider (piston) mass", lo=0.0),
    Param("omega", "ω", "rad/s", "mean crank speed; phi' = omega (1 + delta sin phi)", lo=0.0, lo_open=True),
    Param("delta", "δ", "1", "crank speed modulation: phi' = omega (1 + delta sin phi)", lo=-1.0, hi=1.0,
          lo_open=True, hi_open=True, required=False, default=0.0),
    Param("g", "g", "m/s^2", "gravitational acceleration along -y (0: no gravity)", lo=0.0, hi=100.0,
          required=False, default=0.0),
    Param("F_load", "F_load", "N", "constant useful-load force on the slider along +x", required=False,
          default=0.0),
    Param("k", "k", "1", "fraction of the reciprocating mass balanced by the crank counterweight "
          "(textbook: 1/3 to 1/2)", lo=0.0, hi=2.0),
    Param("r_cw", "r_cw", "m", "radius of the counterweight's centre (point mass); default r", lo=0.0,
          lo_open=True, required=False, default=math.nan),
)
assert tuple(p.name for p in PARAMS) == L.SLIDER_PARAMS

_K = "with the crank counterweight of fraction k"
SCALARS = {
    "transmission_min": ("μ_min", "rad", "smallest transmission angle (pi/2 minus the largest rod angle to the "
                                         "slider line)"),
    "m_A": ("m_A", "kg", "rotating mass at the crank pin (static two-point substitution; magnitude)"),
    "m_B": ("m_B", "kg", "reciprocating mass at the slider (static two-point substitution)"),
    "cw_mr": ("m_cw r_cw", "kg m", "crank counterweight mass-radius product, (m_A + k m_B) r inline"),
    "cw_angle": ("β", "rad", "crank counterweight angle from the crank line"),
    "cw_mass": ("m_cw", "kg", "crank counterweight mass cw_mr / r_cw"),
    "F_max": ("|F|_max", "N", f"largest magnitude of the shaking force, {_K}"),
    "Fx_max": ("|Fx|_max", "N", f"largest |Fx| (along the stroke), {_K}"),
    "Fy_max": ("|Fy|_max", "N", f"largest |Fy| (across the stroke), {_K}"),
    "Fx_rms": ("Fx_rms", "N", f"RMS of Fx, {_K}"),
    "Fy_rms": ("Fy_rms", "N", f"RMS of Fy, {_K}"),
    "Fx_range": ("f1", "N", f"max - min of Fx, {_K}"),
    "Fy_range": ("f2", "N", f"max - min of Fy, {_K}"),
    "M_rms": ("M_rms", "N m", f"RMS of the shaking moment about the crank axis, {_K}"),
    "M_max": ("|M|_max", "N m", f"largest |shaking moment|, {_K}"),
    "M_range": ("f3", "N m", f"max - min of the shaking moment, {_K}"),
    "T_rms": ("T_rms", "N m", f"RMS of the input torque, {_K}"),
    "T_max": ("|T|_max", "N m", f"largest |input torque|, {_K}"),
    "T_range": ("f4", "N m", f"max - min of the input torque, {_K}"),
    "F_max_unbalanced": ("|F|_max,0", "N", "largest magnitude of the shaking force without counterweight"),
    "F_tb_error_max": ("max|F - F_tb|", "N", "largest error of the textbook two-term residual force against "
                                             "exact kinematics"),
    "F_tb_error_rel": ("max|F - F_tb| / (m_B r ω²)", "1", "textbook residual-force error relative to m_B r omega^2"),
}
CURVES = {
    "Fx_phi": ("Fx", "N", f"shaking force along the stroke, exact, {_K}"),
    "Fy_phi": ("Fy", "N", f"shaking force across the stroke, exact, {_K}"),
    "Fx_tb_phi": ("Fx_tb", "N", "textbook residual (1 - k) m_B r w^2 cos phi + lambda m_B r w^2 cos 2 phi"),
    "Fy_tb_phi": ("Fy_tb", "N", "textbook residual -k m_B r w^2 sin phi (- g m_total)"),
    "M_phi": ("M", "N m", f"shaking moment about the crank axis, {_K}"),
    "T_phi": ("T", "N m", f"input torque, {_K}"),
}
assert tuple(SCALARS) == L.SLIDER_OUTPUTS and tuple(CURVES) == L.SLIDER_CURVES


def crank_data(n_positions: int):
    """The data every design shares (ClosedFormModel.data): cosines and sines of the n uniform
    crank positions."""
    c, s, _ = positions(n_positions)
    return c, s


@jit
def slider_design(p, want, row, crv, slot, buf, cos_phi, sin_phi):
    """The model's per-design function (ClosedFormModel.compute; the engine owns the chunk loop):
    all requested outputs of one slider-crank design over the N uniform crank positions with
    cosines cos_phi and sines sin_phi (crank_positions). buf: (N_SBUF, N) scratch. Returns a
    status."""
    N = cos_phi.shape[0]
    r = p[S_R]
    l = slider_conrod_length(p)
    e = p[S_E]
    code, smin = slider_assembly(r, l, e)
    if code != st.OK:
        return code
    sigma = branch_sign(p[S_BRANCH])
    omega = p[S_OMEGA]
    g = p[S_G]
    F_load = p[S_FLOAD]
    k = p[S_K]
    r_cw = p[S_RCW] if not math.isnan(p[S_RCW]) else r
    cwx, cwy, mA, mB = slider_counterweight(p, l)
    need_tb = want[Q_TB_ERR] or want[Q_TB_REL] or slot[D_FXTB] >= 0 or slot[D_FYTB] >= 0
    if want[Q_TB_REL] and not abs(mB) > 0.0:
        return st.SINGULAR  # no reciprocating mass: the relative error has no scale
    if want[Q_TRANS]:
        row[Q_TRANS] = math.asin(min(smin, 1.0))
    row[Q_MA] = mA
    row[Q_MB] = mB
    row[Q_CW] = math.hypot(cwx, cwy)
    row[Q_CWA] = math.atan2(cwy + 0.0, cwx)
    U1x, U1y, J1, m2, V2x, V2y, J2A, m3, mtot, cwm = slider_links(p, cwx, cwy, r_cw)
    row[Q_CWM] = cwm
    slider_kinematics_cycle(r, l, e, sigma, omega, p[S_DELTA], cos_phi, sin_phi, buf)
    slider_loads_cycle(r, e, U1x, U1y, J1, m2, V2x, V2y, J2A, m3, mtot, g, F_load, cos_phi, sin_phi, buf, SB_FX)
    Fx = buf[SB_FX]
    Fy = buf[SB_FY]
    lo, hi, rms = cycle_stats(Fx)
    row[Q_FXMAX] = max(hi, -lo)
    row[Q_FXRMS] = rms
    row[Q_FXRANGE] = hi - lo
    lo, hi, rms = cycle_stats(Fy)
    row[Q_FYMAX] = max(hi, -lo)
    row[Q_FYRMS] = rms
    row[Q_FYRANGE] = hi - lo
    row[Q_FMAX] = max_force(Fx, Fy, 0.0)
    lo, hi, rms = cycle_stats(buf[SB_M])
    row[Q_MMAX] = max(hi, -lo)
    row[Q_MRMS] = rms
    row[Q_MRANGE] = hi - lo
    lo, hi, rms = cycle_stats(buf[SB_T])
    row[Q_TMAX] = max(hi, -lo)
    row[Q_TRMS] = rms
    row[Q_TRANGE] = hi - lo
    if want[Q_FMAX_UNB]:
        bU1x, bU1y, bJ1, _, _, _, _, _, bmtot, _ = slider_links(p, 0.0, 0.0, r_cw)
        slider_loads_cycle(r, e, bU1x, bU1y, bJ1, m2, V2x, V2y, J2A, m3, bmtot, g, F_load, cos_phi, sin_phi, buf,
                           SB_FX0)
        row[Q_FMAX_UNB] = max_force(buf[SB_FX0], buf[SB_FY0], 0.0)
    if need_tb:
        # textbook residual (physics.md section 4), mean speed omega, plus the static weight -g M:
        # Fx = (1 - k) m_B r w^2 cos phi + lambda m_B r w^2 cos 2 phi,  Fy = -k m_B r w^2 sin phi
        amp = mB * r * omega * omega
        lam = r / l
        for j in range(N):
            c1 = cos_phi[j]
            s1 = sin_phi[j]
            buf[SB_FXTB, j] = (1.0 - k) * amp * c1 + lam * amp * (c1 * c1 - s1 * s1)
            buf[SB_FYTB, j] = -k * amp * s1 - g * mtot
        for j in range(N):  # the error, in the rows of the unbalanced force (free now)
            buf[SB_FX0, j] = Fx[j] - buf[SB_FXTB, j]
            buf[SB_FY0, j] = Fy[j] - buf[SB_FYTB, j]
        err = max_force(buf[SB_FX0], buf[SB_FY0], 0.0)
        row[Q_TB_ERR] = err
        if want[Q_TB_REL]:
            row[Q_TB_REL] = err / abs(amp)
    for c, b in ((D_FX, SB_FX), (D_FY, SB_FY), (D_FXTB, SB_FXTB), (D_FYTB, SB_FYTB), (D_M, SB_M), (D_T, SB_T)):
        if slot[c] >= 0:
            crv[slot[c], :] = buf[b]
    return st.OK


def check(given):
    """Exactly one of l and lambda."""
    if "l" in given and "lambda" in given:
        return ["fixed.lambda: give the rod length l or lambda = r / l, not both"]
    if "l" not in given and "lambda" not in given:
        return ["fixed.l: missing; give the rod length l or lambda = r / l"]
    return []


MODEL = ClosedFormModel(
    name="slidercrank_balancing",
    description="Slider-crank with a crank counterweight balancing the rotating mass and a fraction k of the "
                "reciprocating mass: exact residual shaking force, moment, input torque and the error of the "
                "textbook two-term formula; 360 crank positions per design",
    source="physics.md section 4 (machine-dynamics textbook, slider-crank partial balancing)",
    params=PARAMS,
    outputs=tuple(Output(k, *v) for k, v in SCALARS.items())
    + tuple(Output(k, *v, extra_dims=(PHI_DIM,)) for k, v in CURVES.items()),
    compute=slider_design,
    size=L.N_POSITIONS,
    data=crank_data,
    scratch=L.N_SBUF,
    check=check,
)
SPEC = MODEL.spec()
# the engine entry point, as fourbar_balancing.evaluate (n_positions as its 8th argument)
evaluate = SPEC.evaluate
