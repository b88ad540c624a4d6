"""Four-bar linkage balancing: what each balancing method leaves behind, and what it costs.

Sources: physics.md section 4 (a Chinese machine-dynamics textbook: complete shaking-force
balancing by linearly independent vectors, added rocker inertia, optimisation-based
comprehensive balancing with the indices f1..f4) and section 3 (Dzhavakhyan & Arakelyan 1988:
partial dynamic balancing by moving the crank counterweight's axis). Kernels, equations and
conventions: :mod:`mechsweep.models._linkage` (frame on the x axis from the crank pivot O_A to
the rocker pivot O_B, gravity along -y, crank speed omega(phi) = omega (1 + delta sin phi)).

Every per-design output is evaluated at N_POSITIONS = 360 uniform crank positions
phi_i = 2 pi i / 360 (a fixed constant: algebraic scenes have no solver settings; the kernels and
``evaluate(..., n_positions=N)`` take any N, for convergence studies). RMS values are
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
   (S = cw1_mr_static, beta1 = cw1_angle_static; physics.md prints it for beta1 = pi). The
   RMS-optimal axis minimises sum (M_i + Delta M_i)^2: at constant speed (delta = 0) by the
   source's formula (1), which is exact there (uniform symmetric positions: sum sin psi cos psi
   = 0), otherwise by the 2x2 normal equations. ``*_h1``: the axis that cancels the first Fourier
   harmonic (in phi) of the residual moment. With delta = 0 the two coincide (the least-squares
   first harmonic at uniform positions is the DFT coefficient); with delta != 0 they differ.
   Force balance and input torque are unchanged by the move (same counterweight motion,
   translated). R_j = (max|dM_1| - max|dM_j|) / max|dM_1| * 100 % (physics.md section 3).
3. (slider-crank: model ``slidercrank_balancing``)
4. ``*_inertia``: after method 1, an inertia J_rocker turning with the rocker, J minimising the
   RMS of M_static - J phi3''; J < 0 means a counter-rotating 1:-1 gear pair of inertia |J|.
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

import math
import operator

import numpy as np

from .. import status as st
from . import _linkage as L
from ._spec import ExtraDim, ModelSpec, Output, Param, wanted_flags

N_POSITIONS = L.N_POSITIONS
PHI_DIM = ExtraDim("phi", "rad", "crank angle (360 uniform positions 2 pi i / 360)",
                   values=lambda settings: L.PHI.copy())

_ANGLE = dict(lo=-2.0 * math.pi, hi=2.0 * math.pi)


def _link(i: int, name: str, joint: str):
    return (
        Param(f"m{i}", f"m{i}", "kg", f"{name} mass", lo=0.0, lo_open=(i == 2)),
        Param(f"r{i}", f"r{i}", "m", f"distance of the {name}'s centre of mass from {joint}", lo=0.0),
        Param(f"theta{i}", f"θ{i}", "rad", f"angle of the {name}'s centre of mass from the {name} line "
              f"(seen from {joint}, ccw)", required=False, default=0.0, **_ANGLE),
        Param(f"I{i}", f"I{i}", "kg m^2", f"{name} moment of inertia about its centre of mass", lo=0.0),
    )


PARAMS = (
    Param("a1", "a1", "m", "crank length O_A A", lo=0.0, lo_open=True),
    Param("a2", "a2", "m", "coupler length A B", lo=0.0, lo_open=True),
    Param("a3", "a3", "m", "rocker length O_B B", lo=0.0, lo_open=True),
    Param("a4", "a4", "m", "frame length O_A O_B (along x)", lo=0.0, lo_open=True),
    Param("branch", "σ", "1", "assembly branch: open = B left of the line A -> O_B (sigma = +1), "
          "crossed = right (sigma = -1)", choices=("open", "crossed"), required=False, default=0.0),
    *_link(1, "crank", "O_A"),
    *_link(2, "coupler", "A"),
    *_link(3, "rocker", "O_B"),
    Param("omega", "ω", "rad/s", "mean crank speed; phi' = omega (1 + delta sin phi)", lo=0.0, lo_open=True),
    Param("delta", "δ", "1", "crank speed modulation: phi' = omega (1 + delta sin phi), "
          "phi'' = omega^2 (1 + delta sin phi) delta cos phi", lo=-1.0, hi=1.0, lo_open=True, hi_open=True,
          required=False, default=0.0),
    Param("g", "g", "m/s^2", "gravitational acceleration along -y (0: no gravity)", lo=0.0, hi=100.0,
          required=False, default=0.0),
    Param("M_load", "M_load", "N m", "constant useful-load torque applied to the rocker (ccw positive)",
          required=False, default=0.0),
    Param("cw1_mr", "(m r)_cw1", "kg m", "given crank counterweight: mass-radius product", lo=0.0,
          required=False, default=0.0),
    Param("cw1_angle", "β1", "rad", "given crank counterweight: angle from the crank line", required=False,
          default=0.0, **_ANGLE),
    Param("r_cw1", "r_cw1", "m", "radius of the crank counterweight's centre (point mass); default a1",
          lo=0.0, lo_open=True, required=False, default=math.nan),
    Param("cw3_mr", "(m r)_cw3", "kg m", "given rocker counterweight: mass-radius product", lo=0.0,
          required=False, default=0.0),
    Param("cw3_angle", "β3", "rad", "given rocker counterweight: angle from the rocker line", required=False,
          default=0.0, **_ANGLE),
    Param("r_cw3", "r_cw3", "m", "radius of the rocker counterweight's centre (point mass); default a3",
          lo=0.0, lo_open=True, required=False, default=math.nan),
)
assert tuple(p.name for p in PARAMS) == L.FOURBAR_PARAMS

_GIVEN = "the mechanism as given (counterweights cw1_*, cw3_* of the parameters)"
_STATIC = "after complete shaking-force balancing (method 1)"
SCALARS = {
    "transmission_min": ("μ_min", "rad", "smallest transmission angle over the cycle (folded into [0, pi/2])"),
    "Fx_range": ("f1", "N", f"f1 = max - min of the shaking force Fx over a cycle, {_GIVEN}"),
    "Fy_range": ("f2", "N", f"f2 = max - min of the shaking force Fy over a cycle, {_GIVEN}"),
    "M_range": ("f3", "N m", f"f3 = max - min of the shaking moment about O_A over a cycle, {_GIVEN}"),
    "T_range": ("f4", "N m", f"f4 = max - min of the input torque over a cycle, {_GIVEN}"),
    "Fx_rms": ("Fx_rms", "N", f"RMS of the shaking force Fx, {_GIVEN}"),
    "Fy_rms": ("Fy_rms", "N", f"RMS of the shaking force Fy, {_GIVEN}"),
    "M_rms": ("M_rms", "N m", f"RMS of the shaking moment about O_A, {_GIVEN}"),
    "T_rms": ("T_rms", "N m", f"RMS of the input torque, {_GIVEN}"),
    "F_max": ("|F|_max", "N", f"largest magnitude of the shaking force, {_GIVEN}"),
    "M_max": ("|M|_max", "N m", f"largest magnitude of the shaking moment, {_GIVEN}"),
    "T_max": ("|T|_max", "N m", f"largest magnitude of the input torque, {_GIVEN}"),
    "cw_mass": ("m_cw", "kg", "mass of the given counterweights cw1_mr / r_cw1 + cw3_mr / r_cw3"),
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
    "M_range_static": ("f3", "N m", f"max - min of the shaking moment {_STATIC}"),
    "T_rms_static": ("T_rms", "N m", f"RMS of the input torque {_STATIC}"),
    "T_max_static": ("|T|_max", "N m", f"largest |input torque| {_STATIC}"),
    "T_range_static": ("f4", "N m", f"max - min of the input torque {_STATIC}"),
    "axis_x": ("x", "m", "RMS-optimal axis O1 of the crank counterweight, x (method 2, normal equations)"),
    "axis_y": ("y", "m", "RMS-optimal axis O1 of the crank counterweight, y (method 2, normal equations)"),
    "dM_rms_axis": ("RMS dM_2", "N m", "RMS of the residual shaking moment, RMS-optimal counterweight axis"),
    "dM_max_axis": ("max|dM_2|", "N m", "largest |residual shaking moment|, RMS-optimal counterweight axis"),
    "R_axis": ("R_2", "%", "efficiency of the RMS-optimal axis against static balancing, "
                           "(max|dM_1| - max|dM_2|) / max|dM_1|"),
    "axis_x_h1": ("x_h1", "m", "counterweight axis cancelling the first harmonic of the shaking moment, x"),
    "axis_y_h1": ("y_h1", "m", "counterweight axis cancelling the first harmonic of the shaking moment, y"),
    "dM_rms_h1": ("RMS dM_h1", "N m", "RMS of the residual shaking moment, first-harmonic axis"),
    "dM_max_h1": ("max|dM_h1|", "N m", "largest |residual shaking moment|, first-harmonic axis"),
    "R_h1": ("R_h1", "%", "efficiency of first-harmonic balancing against static balancing"),
    "J_rocker": ("J_r", "kg m^2", "RMS-optimal inertia added to the rocker after force balancing "
                                  "(<0: counter-rotating gear pair)"),
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


def evaluate(P, wanted, solver, out, status, n_steps, n_rhs, n_positions=N_POSITIONS):
    """Engine entry point (algebraic: solver is None and unused). ``n_positions``: crank
    positions per cycle (sweeps: N_POSITIONS; other values for convergence studies, curves then
    have that length)."""
    fill_outputs(L.fourbar_kernel, P, wanted, L.FOURBAR_OUTPUTS, L.FOURBAR_CURVES, status, out, n_positions)


def fill_outputs(kernel, P, wanted, scalar_names, curve_names, status, out, n_positions=N_POSITIONS):
    """Run a linkage chunk kernel and copy the wanted scalars and curves into ``out``."""
    table, curves, names = run_kernel(kernel, P, wanted, scalar_names, curve_names, status, n_positions)
    for name in wanted:
        if name in curve_names:
            out[name][:] = curves[:, names.index(name), :]
        else:
            out[name][:] = table[:, scalar_names.index(name)]


def positions(n_positions: int = N_POSITIONS):
    """(cos phi, sin phi, position sums) of n uniform crank positions, the kernels' last three
    arguments; the module's constants for N_POSITIONS (built once)."""
    if n_positions == N_POSITIONS:
        return L.COS_PHI, L.SIN_PHI, L.SUMS
    n = operator.index(n_positions)
    _, c, s = L.crank_positions(n)
    return c, s, L.position_sums(c, s)


def run_kernel(kernel, P, wanted, scalar_names, curve_names, status, n_positions=N_POSITIONS):
    """Call a linkage chunk kernel at n_positions uniform crank positions: (table [n, scalars],
    curves [n, wanted curves, n_positions], their names)."""
    cos_phi, sin_phi, sums = positions(n_positions)
    N = cos_phi.shape[0]
    P = np.ascontiguousarray(P, dtype=np.float64)
    n = P.shape[0]
    want = wanted_flags(scalar_names, tuple(wanted))
    names = [c for c in curve_names if c in wanted]
    slot = np.array([names.index(c) if c in names else -1 for c in curve_names], dtype=np.int64)
    table = np.full((n, len(scalar_names)), np.nan)
    shape = (n, len(names), N) if names else (0, 0, N)
    curves = np.full(shape, np.nan)
    kernel(P, want, slot, table, curves, status, cos_phi, sin_phi, sums)
    return table, curves, names


SPEC = ModelSpec(
    name="fourbar_balancing",
    description="Four-bar linkage: shaking force, shaking moment and input torque left by each balancing "
                "method (complete force balancing, moved counterweight axis, first harmonic, added rocker "
                "inertia) and the indices f1..f4 of given counterweights; 360 crank positions per design",
    source="physics.md sections 3 (Dzhavakhyan & Arakelyan 1988) and 4 (machine-dynamics textbook, balancing)",
    params=PARAMS,
    outputs=tuple(Output(k, *v) for k, v in SCALARS.items())
    + tuple(Output(k, *v, extra_dims=(PHI_DIM,)) for k, v in CURVES.items()),
    evaluate=evaluate,
    statuses=(st.INFEASIBLE, st.SINGULAR, st.NONFINITE),
    status_notes={
        st.INFEASIBLE: "the linkage does not assemble over a full turn (no Grashof crank)",
        st.SINGULAR: "a toggle (sin of the transmission angle below 1e-3) in the cycle, e.g. a change-point linkage",
    },
)
