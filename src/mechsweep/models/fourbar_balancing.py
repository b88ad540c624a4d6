"""Four-bar linkage balancing: what each balancing method leaves behind, and what it costs.

Sources: physics.md section 4 (a Chinese machine-dynamics textbook: complete shaking-force
balancing by linearly independent vectors, added rocker inertia, optimisation-based
comprehensive balancing with the indices f1..f4) and section 3 (Dzhavakhyan & Arakelyan 1988:
partial dynamic balancing by moving the crank counterweight's axis). Equations, numba helpers and
conventions: :mod:`mechsweep.models._linkage` (frame on the x axis from the crank pivot O_A to
the rocker pivot O_B, gravity along -y, crank speed omega(phi) = omega (1 + delta sin phi)).
The model is a closed-form model of the model layer (:class:`mechsweep.model.ClosedFormModel`):
this module declares it (``MODEL``, ``SPEC``) and holds its per-design function
``fourbar_design``; the engine generates the chunk loop.

Every per-design output is evaluated at N_POSITIONS = 360 uniform crank positions
phi_i = 2 pi i / 360 (a fixed constant: algebraic scenes have no solver settings; the per-design
function and ``evaluate(..., n_positions=N)`` take any N, for convergence studies). RMS values are
over those positions (uniform in phi, as the source's sums over computed positions), maxima and
ranges too (``mechsweep bench workprecision fourbar_balancing`` measures their error).
Per-position outputs (``*_phi``) have the extra dimension ``phi`` with these positions and are
stored only when a scene asks for them (360 floats per design each).

Methods (each output is computed only when a scene asks for it or for an output of the same
method):
1. ``*_static``: complete shaking-force balancing by counterweights on crank and rocker (point
   masses at radius r_cw1, r_cw3; angles measured from the link line). The total centre of mass
   is stationary; the shaking moment and input torque it leaves are dM_1 = M_static(phi) and
   T_static(phi).
2. ``axis_*`` / ``*_axis``: the crank counterweight of method 1 turns about O1 = (axis_x, axis_y)
   (gear/chain driven at the crank's speed and direction) instead of O_A; it adds
   Delta M = -S [phi'^2 (y cos psi - x sin psi) + phi'' (x cos psi + y sin psi)], psi = phi + beta1
   (S = cw1_mr_static, beta1 = cw1_angle_static; physics.md prints it for beta1 = pi), and with
   gravity its weight W = g S / r_cw1, acting x further along the frame, adds -W x: the same
   moment M = -dH/dt - g sum m x_G as M_static (the source's formula leaves the weight out). The
   RMS-optimal axis minimises sum (M_i + Delta M_i)^2: at constant speed without gravity
   (delta = 0, g = 0) by the source's formula (1), which is exact there (uniform symmetric
   positions: sum sin psi cos psi = 0), otherwise by the 2x2 normal equations. ``*_h1``: the
   axis that cancels the first Fourier harmonic (in phi) of the residual moment (with gravity
   its residual includes -W x_h1 too). With delta = 0 and g = 0 the two coincide (the
   least-squares first harmonic at uniform positions is the DFT coefficient); with delta != 0 they
   differ, and with g != 0 the RMS-optimal x also uses -W x against the moment's mean. Force
   balance and input torque are unchanged by the move (same counterweight motion, translated:
   its velocity and the rate of its potential energy do not change). Every output of the method
   equals the moment of the counterweight placed on the reported axis
   (tests/test_linkage_physical.py). R_j = (max|dM_1| - max|dM_j|) / max|dM_1| * 100 %
   (physics.md section 3).
3. (slider-crank: model ``slidercrank_balancing``)
4. ``*_inertia``: after method 1, an inertia J_rocker turning with the rocker, J minimising the
   RMS of M_static - J phi3''; J < 0 means a counter-rotating 1:-1 gear pair of inertia |J|. The
   inertia is taken massless (a flywheel's own weight on the rocker axis would add the constant
   -m g a4 to the moment with gravity, and its mass the weight to Fy).
   Exact (to round-off) only when the force-balanced linkage's angular momentum has no coupler
   term (e.g. an inline coupler with I2 + m2 r2^2 = m2 r2 a2) and the crank speed is constant.
5. the unsuffixed outputs (``Fx_range`` .. ``T_rms``): the mechanism as given, with the
   counterweights of the parameters cw1_mr, cw1_angle, cw3_mr, cw3_angle (none by default), so a
   sweep over those parameters stores the textbook's four indices and their RMS; the Pareto front
   and the weighted-sum optimum are post-processing: mechsweep.balancing.pareto_front,
   mechsweep.balancing.weighted_optimum.

Statuses: INFEASIBLE if the crank cannot make a full turn (not a Grashof crank for that
geometry, either branch); SINGULAR if the cycle passes within TOGGLE_SIN of a toggle
(coupler and rocker collinear; change-point linkages included), or if method 2 or 4 is asked
for and the static residual is identically zero (R_j = 0/0). Non-OK points have NaN outputs.
"""
from __future__ import annotations

import dataclasses
import math
import operator

import numpy as np

from .. import status as st
from .._jit import jit_noalloc
from ..model.closed import ClosedFormModel
from ..model.workprecision import SizeWorkPrecision
from . import _linkage_reference as R
from . import _linkage as L
from ._linkage import (  # the per-design function's helpers and layout constants
    B_DM, B_FX, B_FY, B_M, B_Q3, B_T, C_DM_AX, C_DM_H1, C_DM_IN, C_FX, C_FY, C_M, C_MS, C_T, C_TS, K_AX, K_AY,
    K_CW1A_S, K_CW1_S, K_CW3A_S, K_CW3_S, K_CWM_S, K_CW_MASS, K_DMMAX_AX, K_DMMAX_H1, K_DMMAX_IN, K_DMRMS_AX,
    K_DMRMS_H1, K_DMRMS_IN, K_FMAX_S, K_FX_RANGE, K_FX_RMS, K_FY_RANGE, K_FY_RMS, K_F_MAX, K_H1X, K_H1Y, K_JR,
    K_MASSR_S, K_MMAX_S, K_MRANGE_S, K_MRMS_S, K_M_MAX, K_M_RANGE, K_M_RMS, K_R_AX, K_R_H1, K_R_IN, K_TMAX_IN,
    K_TMAX_S, K_TRANGE_S, K_TRANS, K_TRMS_IN, K_TRMS_S, K_T_MAX, K_T_RANGE, K_T_RMS, P_A1, P_A2, P_A3, P_A4,
    P_BRANCH, P_CW1, P_CW1A, P_CW3, P_CW3A, P_DELTA, P_G, P_M1, P_M2, P_M3, P_MLOAD, P_OMEGA, P_R1, P_R2,
    P_R3, P_TH1, P_TH2, P_TH3, P_I1, P_I2, P_I3, R_AL1, R_AL3, R_W1, axis_fit, axis_formula1_sums, axis_residual,
    axis_residual_const, branch_sign, copy_curve, dot4, fourbar_assembly, fourbar_cw_radii,
    fourbar_kinematics_cycle, fourbar_links, fourbar_loads_cycle, fourbar_moment_cycle,
    fourbar_static_counterweights, max_force, stats_into)
from ._scaling import NONE, UnitScaling, largest_exponent
from ..model.spec import ExtraDim, Output, Param

N_POSITIONS = L.N_POSITIONS
PHI_DIM = ExtraDim("phi", "rad", "crank angle (360 uniform positions 2π i / 360)",
                   values=lambda settings: L.PHI.copy())

_ANGLE = dict(lo=-2.0 * math.pi, hi=2.0 * math.pi)


def _link(i: int, name: str, joint: str):
    return (
        Param(f"m{i}", f"m{i}", "kg", f"{name} mass", lo=0.0, lo_open=(i == 2), latex=f"$m_{i}$"),
        Param(f"r{i}", f"r{i}", "m", f"distance of the {name}'s centre of mass from {joint}", lo=0.0,
              latex=f"$r_{i}$"),
        Param(f"theta{i}", f"θ{i}", "rad", f"angle of the {name}'s centre of mass from the {name} line "
              f"(seen from {joint}, ccw)", required=False, default=0.0, **_ANGLE, latex=f"$\\theta_{i}$"),
        Param(f"I{i}", f"I{i}", "kg m2", f"{name} moment of inertia about its centre of mass", lo=0.0,
              latex=f"$I_{i}$"),
    )


PARAMS = (
    Param("a1", "a1", "m", "crank length O_A A", lo=0.0, lo_open=True, latex="$a_1$"),
    Param("a2", "a2", "m", "coupler length A B", lo=0.0, lo_open=True, latex="$a_2$"),
    Param("a3", "a3", "m", "rocker length O_B B", lo=0.0, lo_open=True, latex="$a_3$"),
    Param("a4", "a4", "m", "frame length O_A O_B (along x)", lo=0.0, lo_open=True, latex="$a_4$"),
    Param("branch", "σ", "1", "assembly branch: open = B left of the line A → O_B (σ = +1), "
          "crossed = right (σ = −1)", choices=("open", "crossed"), required=False, default=0.0,
          latex=r"$\sigma$"),
    *_link(1, "crank", "O_A"),
    *_link(2, "coupler", "A"),
    *_link(3, "rocker", "O_B"),
    Param("omega", "ω", "rad s-1", "mean crank speed: φ′ = ω (1 + δ sin φ)", lo=0.0, lo_open=True,
          latex=r"$\omega$"),
    Param("delta", "δ", "1", "crank speed modulation: φ′ = ω (1 + δ sin φ), "
          "φ″ = ω² (1 + δ sin φ) δ cos φ", lo=-1.0, hi=1.0, lo_open=True, hi_open=True,
          required=False, default=0.0, latex=r"$\delta$"),
    Param("g", "g", "m s-2", "gravitational acceleration along −y (0: no gravity)", lo=0.0, hi=100.0,
          required=False, default=0.0, latex="$g$"),
    Param("M_load", "M_load", "N m", "constant useful-load torque applied to the rocker (ccw positive)",
          required=False, default=0.0, latex=r"$M_\mathrm{load}$"),
    Param("cw1_mr", "(m r)_cw1", "kg m", "given crank counterweight: mass-radius product", lo=0.0,
          required=False, default=0.0, latex=r"$(m r)_\mathrm{cw1}$"),
    Param("cw1_angle", "β1", "rad", "given crank counterweight: angle from the crank line", required=False,
          default=0.0, **_ANGLE, latex=r"$\beta_1$"),
    Param("r_cw1", "r_cw1", "m", "radius of the crank counterweight's centre (point mass); default a₁",
          lo=0.0, lo_open=True, required=False, default=math.nan, latex=r"$r_\mathrm{cw1}$"),
    Param("cw3_mr", "(m r)_cw3", "kg m", "given rocker counterweight: mass-radius product", lo=0.0,
          required=False, default=0.0, latex=r"$(m r)_\mathrm{cw3}$"),
    Param("cw3_angle", "β3", "rad", "given rocker counterweight: angle from the rocker line", required=False,
          default=0.0, **_ANGLE, latex=r"$\beta_3$"),
    Param("r_cw3", "r_cw3", "m", "radius of the rocker counterweight's centre (point mass); default a₃",
          lo=0.0, lo_open=True, required=False, default=math.nan, latex=r"$r_\mathrm{cw3}$"),
)
assert tuple(p.name for p in PARAMS) == L.FOURBAR_PARAMS

_GIVEN = "the mechanism as given (with the counterweights the parameters give)"
_STATIC = "after complete shaking-force balancing (method 1)"
SCALARS = {
    "transmission_min": ("μ_min", "rad", "smallest transmission angle over the cycle (folded into [0, π/2])"),
    "Fx_range": ("f1", "N", f"range (max − min) of the shaking force Fx over a cycle, {_GIVEN}"),
    "Fy_range": ("f2", "N", f"range (max − min) of the shaking force Fy over a cycle, {_GIVEN}"),
    "M_range": ("f3", "N m", f"range (max − min) of the shaking moment about O_A over a cycle, {_GIVEN}"),
    "T_range": ("f4", "N m", f"range (max − min) of the input torque over a cycle, {_GIVEN}"),
    "Fx_rms": ("Fx_rms", "N", f"RMS of the shaking force Fx, {_GIVEN}"),
    "Fy_rms": ("Fy_rms", "N", f"RMS of the shaking force Fy, {_GIVEN}"),
    "M_rms": ("M_rms", "N m", f"RMS of the shaking moment about O_A, {_GIVEN}"),
    "T_rms": ("T_rms", "N m", f"RMS of the input torque, {_GIVEN}"),
    "F_max": ("|F|_max", "N", f"largest magnitude of the shaking force, {_GIVEN}"),
    "M_max": ("|M|_max", "N m", f"largest magnitude of the shaking moment, {_GIVEN}"),
    "T_max": ("|T|_max", "N m", f"largest magnitude of the input torque, {_GIVEN}"),
    "cw_mass": ("m_cw", "kg", "mass of the given counterweights"),
    "cw1_mr_static": ("(m r)_cw1", "kg m", "crank counterweight for complete force balancing: mass-radius product"),
    "cw1_angle_static": ("β1", "rad", "crank counterweight for complete force balancing: angle from the crank line"),
    "cw3_mr_static": ("(m r)_cw3", "kg m", "rocker counterweight for complete force balancing: mass-radius product"),
    "cw3_angle_static": ("β3", "rad", "rocker counterweight for complete force balancing: angle from the rocker line"),
    "cw_mass_static": ("m_cw", "kg", "mass of both counterweights of complete force balancing"),
    "mass_ratio_static": ("m_total / m_links", "1",
                          "moving mass with the counterweights of method 1 over the links' mass"),
    "F_max_static": ("|F|_max", "N", f"largest dynamic shaking force {_STATIC} (round-off; a check)"),
    "M_rms_static": ("RMS dM_1", "N m", f"RMS of the shaking moment {_STATIC}"),
    "M_max_static": ("max|dM_1|", "N m", f"largest |shaking moment| {_STATIC}"),
    "M_range_static": ("f3", "N m", f"range (max − min) of the shaking moment {_STATIC}"),
    "T_rms_static": ("T_rms", "N m", f"RMS of the input torque {_STATIC}"),
    "T_max_static": ("|T|_max", "N m", f"largest |input torque| {_STATIC}"),
    "T_range_static": ("f4", "N m", f"range (max − min) of the input torque {_STATIC}"),
    "axis_x": ("x", "m", "RMS-optimal axis O1 of the crank counterweight, x (method 2, normal equations)"),
    "axis_y": ("y", "m", "RMS-optimal axis O1 of the crank counterweight, y (method 2, normal equations)"),
    "dM_rms_axis": ("RMS dM_2", "N m", "RMS of the residual shaking moment, RMS-optimal counterweight axis"),
    "dM_max_axis": ("max|dM_2|", "N m", "largest |residual shaking moment|, RMS-optimal counterweight axis"),
    "R_axis": ("R_2", "%", "efficiency of the RMS-optimal axis against static balancing"),
    "axis_x_h1": ("x_h1", "m", "counterweight axis cancelling the first harmonic of the shaking moment, x"),
    "axis_y_h1": ("y_h1", "m", "counterweight axis cancelling the first harmonic of the shaking moment, y"),
    "dM_rms_h1": ("RMS dM_h1", "N m", "RMS of the residual shaking moment, first-harmonic axis"),
    "dM_max_h1": ("max|dM_h1|", "N m", "largest |residual shaking moment|, first-harmonic axis"),
    "R_h1": ("R_h1", "%", "efficiency of first-harmonic balancing against static balancing"),
    "J_rocker": ("J_r", "kg m2", "RMS-optimal inertia added to the rocker after force balancing "
                                  "(< 0: counter-rotating gear pair)"),
    "dM_rms_inertia": ("RMS dM_4", "N m", "RMS of the residual shaking moment with the added rocker inertia"),
    "dM_max_inertia": ("max|dM_4|", "N m", "largest |residual shaking moment| with the added rocker inertia"),
    "R_inertia": ("R_4", "%", "efficiency of the added rocker inertia against static balancing"),
    "T_rms_inertia": ("T_rms", "N m", "RMS of the input torque with the counterweights of method 1 and the added "
                                      "rocker inertia"),
    "T_max_inertia": ("|T|_max", "N m", "largest |input torque| with the counterweights of method 1 and the added "
                                        "rocker inertia"),
}
CURVES = {
    "Fx_phi": ("Fx", "N", f"shaking force Fx on the frame, {_GIVEN}"),
    "Fy_phi": ("Fy", "N", f"shaking force Fy on the frame, {_GIVEN}"),
    "M_phi": ("M", "N m", f"shaking moment about O_A, {_GIVEN}"),
    "T_phi": ("T", "N m", f"input torque, {_GIVEN}"),
    "M_static_phi": ("dM_1", "N m", f"shaking moment {_STATIC}"),
    "T_static_phi": ("T_1", "N m", f"input torque {_STATIC}"),
    "dM_axis_phi": ("dM_2", "N m", "residual shaking moment, RMS-optimal counterweight axis"),
    "dM_h1_phi": ("dM_h1", "N m", "residual shaking moment, first-harmonic counterweight axis"),
    "dM_inertia_phi": ("dM_4", "N m", "residual shaking moment with the added rocker inertia"),
}
assert tuple(SCALARS) == L.FOURBAR_OUTPUTS and tuple(CURVES) == L.FOURBAR_CURVES
_DM1, _DM2 = r"\max|\Delta M_1|", r"\max|\Delta M_2|"
LATEX = {  # the outputs' symbols in mathtext, for figures
    "transmission_min": r"$\mu_\min$", "Fx_range": r"$f_1 = \max F_x - \min F_x$",
    "Fy_range": r"$f_2 = \max F_y - \min F_y$", "M_range": r"$f_3 = \max M - \min M$",
    "T_range": r"$f_4 = \max T - \min T$", "Fx_rms": r"$F_{x,\mathrm{rms}}$", "Fy_rms": r"$F_{y,\mathrm{rms}}$",
    "M_rms": r"$M_\mathrm{rms}$", "T_rms": r"$T_\mathrm{rms}$", "F_max": r"$|F|_\max$", "M_max": r"$|M|_\max$",
    "T_max": r"$|T|_\max$",
    "cw_mass": r"$m_\mathrm{cw} = (m r)_\mathrm{cw1}/r_\mathrm{cw1} + (m r)_\mathrm{cw3}/r_\mathrm{cw3}$",
    "cw1_mr_static": r"$(m r)_\mathrm{cw1}$", "cw1_angle_static": r"$\beta_1$", "cw3_mr_static": r"$(m r)_\mathrm{cw3}$",
    "cw3_angle_static": r"$\beta_3$", "cw_mass_static": r"$m_\mathrm{cw}$",
    "mass_ratio_static": r"$m_\mathrm{total}/m_\mathrm{links}$", "F_max_static": r"$|F|_\max$",
    "M_rms_static": r"$\mathrm{RMS}\,\Delta M_1$", "M_max_static": f"${_DM1}$", "M_range_static": "$f_3$",
    "T_rms_static": r"$T_\mathrm{rms}$", "T_max_static": r"$|T|_\max$", "T_range_static": "$f_4$",
    "axis_x": "$x_{O_1}$", "axis_y": "$y_{O_1}$", "dM_rms_axis": r"$\mathrm{RMS}\,\Delta M_2$",
    "dM_max_axis": f"${_DM2}$", "R_axis": f"$R_2 = ({_DM1} - {_DM2})/{_DM1}$", "axis_x_h1": r"$x_\mathrm{h1}$",
    "axis_y_h1": r"$y_\mathrm{h1}$", "dM_rms_h1": r"$\mathrm{RMS}\,\Delta M_\mathrm{h1}$",
    "dM_max_h1": r"$\max|\Delta M_\mathrm{h1}|$", "R_h1": r"$R_\mathrm{h1}$", "J_rocker": "$J_r$",
    "dM_rms_inertia": r"$\mathrm{RMS}\,\Delta M_4$", "dM_max_inertia": r"$\max|\Delta M_4|$",
    "R_inertia": "$R_4$", "T_rms_inertia": r"$T_\mathrm{rms}$", "T_max_inertia": r"$|T|_\max$",
    "Fx_phi": "$F_x$", "Fy_phi": "$F_y$", "M_phi": "$M$", "T_phi": "$T$", "M_static_phi": r"$\Delta M_1$",
    "T_static_phi": "$T_1$", "dM_axis_phi": r"$\Delta M_2$", "dM_h1_phi": r"$\Delta M_\mathrm{h1}$",
    "dM_inertia_phi": r"$\Delta M_4$",
}
assert set(LATEX) == set(SCALARS) | set(CURVES)


def positions(n_positions: int = N_POSITIONS):
    """(cos phi, sin phi, position sums) of n uniform crank positions; the module's constants for
    N_POSITIONS (built once)."""
    if n_positions == N_POSITIONS:
        return L.COS_PHI, L.SIN_PHI, L.SUMS
    n = operator.index(n_positions)
    _, c, s = L.crank_positions(n)
    return c, s, L.position_sums(c, s)


def crank_data(n_positions: int):
    """The data every design shares (ClosedFormModel.data): cosines and sines of the n uniform
    crank positions, their sums for formula (1) and the positions' weights (ones)."""
    c, s, sums = positions(n_positions)
    return c, s, sums, np.ones(c.shape[0])



# without numba's reference counting (jit_noalloc; the engine's copy keeps it, model/load.jitted): it
# allocates nothing, and its views of buf cost atomic increments and decrements per design otherwise
@jit_noalloc
def fourbar_design(p, want, row, crv, slot, buf, cos_phi, sin_phi, sums, unit):
    """The model's per-design function (ClosedFormModel.compute; the engine owns the chunk loop):
    all requested outputs of one four-bar design (row p of the parameter matrix) over the
    N uniform crank positions with cosines cos_phi and sines sin_phi (crank_positions).
    row: the design's scalar outputs (prefilled NaN); crv: (n_curve_slots, N) the design's
    curves; slot[c] = row of curve c in crv or -1; buf: (N_BUF, N) scratch; sums: position_sums
    of the positions; unit: N ones (the positions' weights). Returns a status; outputs of a
    non-OK design stay NaN."""
    N = cos_phi.shape[0]
    a1, a2, a3, a4 = p[P_A1], p[P_A2], p[P_A3], p[P_A4]
    code, smin = fourbar_assembly(a1, a2, a3, a4)
    if code != st.OK:
        return code
    sigma = branch_sign(p[P_BRANCH])
    omega = p[P_OMEGA]
    delta = p[P_DELTA]
    g = p[P_G]
    M_load = p[P_MLOAD]
    r_cw1, r_cw3 = fourbar_cw_radii(p)

    need_axis = want[K_AX] or want[K_AY] or want[K_DMRMS_AX] or want[K_DMMAX_AX] or want[K_R_AX] or slot[C_DM_AX] >= 0
    need_h1 = want[K_H1X] or want[K_H1Y] or want[K_DMRMS_H1] or want[K_DMMAX_H1] or want[K_R_H1] or slot[C_DM_H1] >= 0
    need_in = (want[K_JR] or want[K_DMRMS_IN] or want[K_DMMAX_IN] or want[K_R_IN] or want[K_TRMS_IN]
               or want[K_TMAX_IN] or slot[C_DM_IN] >= 0)
    need_static = need_axis or need_h1 or need_in or slot[C_MS] >= 0 or slot[C_TS] >= 0
    for k in range(K_CW1_S, K_TRANGE_S + 1):
        need_static = need_static or want[k]
    need_given = slot[C_FX] >= 0 or slot[C_FY] >= 0 or slot[C_M] >= 0 or slot[C_T] >= 0
    for k in range(K_FX_RANGE, K_CW_MASS + 1):
        need_given = need_given or want[k]

    if want[K_TRANS]:
        row[K_TRANS] = math.asin(min(smin, 1.0))
    Fx = buf[B_FX]
    Fy = buf[B_FY]
    Ms = buf[B_M]
    Ts = buf[B_T]

    m_links = p[P_M1] + p[P_M2] + p[P_M3]
    if need_given or need_static:
        fourbar_kinematics_cycle(a1, a2, a3, a4, sigma, omega, delta, cos_phi, sin_phi, buf)  # shared by both
    # ---- the mechanism as given (method 5 indices)
    if need_given:
        U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, mtot, cwm = fourbar_links(
            p, p[P_CW1] * math.cos(p[P_CW1A]), p[P_CW1] * math.sin(p[P_CW1A]),
            p[P_CW3] * math.cos(p[P_CW3A]), p[P_CW3] * math.sin(p[P_CW3A]), r_cw1, r_cw3)
        fourbar_loads_cycle(a1, a4, U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, mtot, g, M_load,
                            cos_phi, sin_phi, buf)
        # method 5: the textbook's four indices f1..f4 and their RMS
        stats_into(row, Fx, K_FX_RANGE, K_FX_RMS, -1)
        stats_into(row, Fy, K_FY_RANGE, K_FY_RMS, -1)
        stats_into(row, Ms, K_M_RANGE, K_M_RMS, K_M_MAX)
        stats_into(row, Ts, K_T_RANGE, K_T_RMS, K_T_MAX)
        row[K_F_MAX] = max_force(Fx, Fy, 0.0)
        row[K_CW_MASS] = cwm
        for c, b in ((C_FX, B_FX), (C_FY, B_FY), (C_M, B_M), (C_T, B_T)):
            copy_curve(crv, slot[c], buf[b])

    if not need_static:
        return st.OK
    # ---- method 1: complete shaking-force balancing (physics.md section 4)
    C1x, C1y, C3x, C3y = fourbar_static_counterweights(
        a1, a2, a3, p[P_M1], p[P_R1], p[P_TH1], p[P_M2], p[P_R2], p[P_TH2], p[P_M3], p[P_R3], p[P_TH3])
    U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, mtot, cwm = fourbar_links(p, C1x, C1y, C3x, C3y, r_cw1, r_cw3)
    need_T = (want[K_TRMS_S] or want[K_TMAX_S] or want[K_TRANGE_S] or slot[C_TS] >= 0
              or want[K_TRMS_IN] or want[K_TMAX_IN])
    need_F = want[K_FMAX_S]
    if need_T or need_F:
        fourbar_loads_cycle(a1, a4, U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, mtot, g, M_load,
                            cos_phi, sin_phi, buf)
    else:
        fourbar_moment_cycle(a1, a4, U1x, U1y, J1, m2, V2x, V2y, J2A, U3x, U3y, J3, m3, g, cos_phi, sin_phi, buf)
    S = math.hypot(C1x, C1y)  # static moment of the crank counterweight
    row[K_CW1_S] = S
    row[K_CW1A_S] = math.atan2(C1y + 0.0, C1x)  # + 0.0: no -pi from a -0.0
    row[K_CW3_S] = math.hypot(C3x, C3y)
    row[K_CW3A_S] = math.atan2(C3y + 0.0, C3x)
    row[K_CWM_S] = cwm
    row[K_MASSR_S] = (m_links + cwm) / m_links
    if need_F:
        row[K_FMAX_S] = max_force(Fx, Fy, g * mtot)  # the dynamic part (the weight is static)
    dm1_max = stats_into(row, Ms, K_MRANGE_S, K_MRMS_S, K_MMAX_S)  # max |dM_1|: the residual of static balancing
    if need_T:
        stats_into(row, Ts, K_TRANGE_S, K_TRMS_S, K_TMAX_S)
    copy_curve(crv, slot[C_MS], Ms)
    copy_curve(crv, slot[C_TS], Ts)
    if (need_axis or need_h1 or need_in) and not dm1_max > 0.0:
        return st.SINGULAR  # nothing to balance: efficiencies R_j = 0 / 0

    # ---- method 2: move the crank counterweight's axis to O1(x, y) (physics.md section 3)
    if need_axis or need_h1:
        cb = C1x / S if S > 0.0 else 1.0  # cos(beta), sin(beta)
        sb = C1y / S if S > 0.0 else 0.0
        # the counterweight's weight m_cw g (its mass S / r_cw1, as fourbar_links): moving its axis by
        # x moves its weight's moment about O_A by -W x, part of M_static's gravity term
        W = g * S / r_cw1
        W1 = buf[R_W1]
        AL1 = buf[R_AL1]
        for method in range(2):
            if method == 0:
                if not need_axis:
                    continue
                kx, ky, krms, kmax, kr, cslot = K_AX, K_AY, K_DMRMS_AX, K_DMMAX_AX, K_R_AX, slot[C_DM_AX]
            else:
                if not need_h1:
                    continue
                kx, ky, krms, kmax, kr, cslot = K_H1X, K_H1Y, K_DMRMS_H1, K_DMMAX_H1, K_R_H1, slot[C_DM_H1]
            dM = buf[B_DM] if cslot < 0 else crv[cslot]
            if method == 0 and delta == 0.0 and g == 0.0:
                # constant speed, no gravity, symmetric uniform positions: sum sin(psi) cos(psi) = 0,
                # so the source's formula (1) is the exact solution of the normal equations (and cheaper)
                if S == 0.0:
                    x, y = 0.0, 0.0
                else:
                    x, y = axis_formula1_sums(dot4(Ms, cos_phi), dot4(Ms, sin_phi), sums[0], sums[1], sums[2],
                                              S, omega, cb, sb)
                rms, mx = axis_residual_const(cos_phi, sin_phi, Ms, S * omega * omega, cb, sb, x, y, dM)
            else:
                ok, x, y = axis_fit(cos_phi, sin_phi, W1, AL1, Ms, unit, S, cb, sb, method == 1, W)
                if not ok:
                    return st.SINGULAR
                rms, mx = axis_residual(cos_phi, sin_phi, W1, AL1, Ms, S, cb, sb, x, y, dM, W)
            row[kx] = x
            row[ky] = y
            row[krms] = rms
            row[kmax] = mx
            row[kr] = (dm1_max - mx) / dm1_max * 100.0  # R_j of physics.md section 3

    # ---- method 4: inertia J on the rocker (J < 0: counter-rotating 1:-1 gear pair of inertia |J|)
    if need_in:
        A3 = buf[R_AL3]
        Q3 = buf[B_Q3]
        saa = sma = 0.0
        for j in range(N):
            saa += A3[j] * A3[j]
            sma += Ms[j] * A3[j]
        J = sma / saa if saa > 0.0 else 0.0  # minimise sum (M_i - J al3_i)^2
        ss = 0.0
        mx = 0.0
        t_ss = 0.0
        t_mx = 0.0
        cslot = slot[C_DM_IN]
        for j in range(N):
            dm = Ms[j] - J * A3[j]
            ss += dm * dm
            mx = max(mx, abs(dm))
            T = Ts[j] + abs(J) * A3[j] * Q3[j]  # kinetic energy of the added inertia is |J| w3^2 / 2
            t_ss += T * T
            t_mx = max(t_mx, abs(T))
            if cslot >= 0:
                crv[cslot, j] = dm
        row[K_JR] = J
        row[K_DMRMS_IN] = math.sqrt(ss / N)
        row[K_DMMAX_IN] = mx
        row[K_R_IN] = (dm1_max - mx) / dm1_max * 100.0
        row[K_TRMS_IN] = math.sqrt(t_ss / N)
        row[K_TMAX_IN] = t_mx
    return st.OK


MODEL = ClosedFormModel(
    name="fourbar_balancing",
    description="Four-bar linkage: shaking force, shaking moment and input torque left by each balancing "
                "method (complete force balancing, moved counterweight axis, first harmonic, added rocker "
                "inertia) and the indices f1..f4 of given counterweights; 360 crank positions per design",
    source="physics.md sections 3 (Dzhavakhyan & Arakelyan 1988) and 4 (machine-dynamics textbook, balancing)",
    references=(
        "Dzhavakhyan & Arakelyan, partial dynamic balancing of linkages by a moved counterweight axis, "
        "Izv. AN ArmSSR, 1988",
        "Balancing of planar mechanisms, a textbook chapter on machine dynamics",
        "mechsweep docs/physics.md sections 3 and 4: the checks and corrections made to the sources",
    ),
    params=PARAMS,
    outputs=tuple(Output(k, *v, latex=LATEX[k]) for k, v in SCALARS.items())
    + tuple(Output(k, *v, extra_dims=(PHI_DIM,), latex=LATEX[k]) for k, v in CURVES.items()),
    compute=fourbar_design,
    size=N_POSITIONS,
    data=crank_data,
    scratch=L.N_BUF,
    statuses=(st.INFEASIBLE, st.SINGULAR, st.NONFINITE, st.OUT_OF_RANGE),
    status_notes={
        st.INFEASIBLE: "the linkage does not assemble over a full turn (no Grashof crank)",
        st.SINGULAR: "a toggle (sin of the transmission angle below 1e-3) in the cycle, e.g. a change-point linkage",
        st.OUT_OF_RANGE: "a link length, distance, mass, inertia or counterweight more than 2^300 (1e90) from the "
                         "largest of its kind, in the design's own units (every design is computed in units of its "
                         "longest link, largest mass and fastest rate, so any overall scale is fine)",
    },
    # bench workprecision: error against the number of crank positions (models/_linkage_reference.py)
    workprecision=SizeWorkPrecision(
        scene="sweeps/fourbar_geometry_family.toml",
        outputs={"M_max_static": "maximum", "M_rms_static": "RMS", "dM_rms_axis": "optimised (RMS-optimal axis), RMS",
                 "dM_max_axis": "optimised (RMS-optimal axis), maximum"},
        reference=R.fourbar_reference, reference_name=R.FOURBAR_REFERENCE,
        compare=R.numpy_fourbar, compare_name=R.NUMPY),
)


def design_units(P):
    """(a, c, t): each design's units of mass 2^a kg, length 2^c m and time 2^t s (_scaling.UnitScaling):
    the longest link, the faster of the crank speed and sqrt(g / length), and the largest of the masses,
    inertias / length^2, counterweight products / length and |M_load| / (length^2 / time^2)."""
    c = largest_exponent(P[:, P_A1], P[:, P_A2], P[:, P_A3], P[:, P_A4])
    rate = largest_exponent(P[:, P_OMEGA])
    gravity = largest_exponent((P[:, P_G], c))
    rate = np.maximum(rate, np.where(gravity == NONE, NONE, (gravity + 1) // 2))
    t = -rate
    a = largest_exponent(P[:, P_M1], P[:, P_M2], P[:, P_M3], (P[:, P_I1], 2 * c), (P[:, P_I2], 2 * c),
                         (P[:, P_I3], 2 * c), (P[:, P_CW1], c), (P[:, P_CW3], c), (P[:, P_MLOAD], 2 * c - 2 * t))
    return np.where(a == NONE, 0, a), c, t


UNITS = UnitScaling(PARAMS, MODEL.outputs, design_units,
                    spread=("a1", "a2", "a3", "a4", "r1", "r2", "r3", "r_cw1", "r_cw3", "m1", "m2", "m3", "I1", "I2",
                            "I3", "cw1_mr", "cw3_mr"))
_UNSCALED = MODEL.spec()
SPEC = dataclasses.replace(_UNSCALED, evaluate=UNITS.wrap(_UNSCALED.evaluate))
# the engine entry point: evaluate(P, wanted, solver, out, status, n_steps, n_rhs, n_positions=N_POSITIONS)
# (algebraic: solver, n_steps and n_rhs are unused; n_positions: crank positions per cycle, for
# convergence studies; curves then have that length)
evaluate = SPEC.evaluate
