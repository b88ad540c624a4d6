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
from . import _linkage as L
from ._spec import ModelSpec, Output, Param
from .fourbar_balancing import PHI_DIM, fill_outputs

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


def evaluate(P, wanted, solver, out, status, n_steps, n_rhs, n_positions=L.N_POSITIONS):
    """Engine entry point (algebraic: solver is None and unused); n_positions as for
    fourbar_balancing.evaluate."""
    fill_outputs(L.slider_kernel, P, wanted, L.SLIDER_OUTPUTS, L.SLIDER_CURVES, status, out, n_positions)


def check(given):
    """Exactly one of l and lambda."""
    if "l" in given and "lambda" in given:
        return ["fixed.lambda: give the rod length l or lambda = r / l, not both"]
    if "l" not in given and "lambda" not in given:
        return ["fixed.l: missing; give the rod length l or lambda = r / l"]
    return []


SPEC = ModelSpec(
    name="slidercrank_balancing",
    description="Slider-crank with a crank counterweight balancing the rotating mass and a fraction k of the "
                "reciprocating mass: exact residual shaking force, moment, input torque and the error of the "
                "textbook two-term formula; 360 crank positions per design",
    source="physics.md section 4 (machine-dynamics textbook, slider-crank partial balancing)",
    params=PARAMS,
    outputs=tuple(Output(k, *v) for k, v in SCALARS.items())
    + tuple(Output(k, *v, extra_dims=(PHI_DIM,)) for k, v in CURVES.items()),
    evaluate=evaluate,
    check=check,
    statuses=(st.INFEASIBLE, st.SINGULAR, st.NONFINITE),
    status_notes={
        st.INFEASIBLE: "the linkage does not assemble over a full turn",
        st.SINGULAR: "a toggle (sin of the transmission angle below 1e-3) in the cycle",
    },
)
