"""Linkage balancing as plain functions: numpy in, numpy out, the same numba kernels as the models
``fourbar_balancing`` and ``slidercrank_balancing`` (:mod:`mechsweep.models._linkage`).

Partial dynamic balancing by moving the crank counterweight's axis (physics.md section 3)::

    rms_axis_offset(phi, moment, S, omega)            RMS-optimal axis O1 = (x, y)
    first_harmonic_axis_offset(phi, moment, S, omega) axis cancelling the first harmonic
    axis_moment(phi, x, y, S, omega)                  the moment Delta M(phi) the move adds
    efficiency(dM_static, dM_method)                  R_j in percent

Comprehensive balancing (physics.md section 4), post-processing of a stored sweep::

    pareto_front(indices) -> mask,  weighted_optimum(indices, weights) -> index

Mass substitution and counterweights (physics.md section 4)::

    static_two_point, dynamic_two_point, fourbar_counterweights, slidercrank_counterweight

Curves of one linkage at any crank positions and speed law::

    fourbar_curves(phi, phi_d, phi_dd, **params), slidercrank_curves(...)

A few designs of a model without a scene::

    evaluate("fourbar_balancing", outputs, **params) -> (dict of arrays, status)

Sign convention of the moment (physics.md section 3): M is the principal moment of the inertia
forces about the crank axis, M = -dH/dt (H the angular momentum about that axis); moving a
counterweight of static moment S = m r, whose centre is at angle ``cw_angle`` from the crank
(default pi: opposite the crank), from the crank axis to O1 = (x, y) adds::

    Delta M = -S [phi'^2 (y cos psi - x sin psi) + phi'' (x cos psi + y sin psi)],  psi = phi + cw_angle,

which for cw_angle = pi is the formula printed in physics.md section 3. With gravity (M then
includes the moment of the weights, -g sum m x_G) the moved counterweight's weight adds
-cw_weight x, cw_weight = m_cw g: the ``cw_weight`` argument of the axis functions.
"""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from . import status as st
from ._jit import jit
from .models import _linkage as L

__all__ = [
    "rms_axis_offset", "first_harmonic_axis_offset", "axis_moment", "efficiency",
    "periodic_trapezoid_weights", "pareto_front", "weighted_optimum",
    "static_two_point", "dynamic_two_point", "fourbar_counterweights", "slidercrank_counterweight",
    "fourbar_curves", "slidercrank_curves", "evaluate", "N_POSITIONS", "PHI",
]

N_POSITIONS = L.N_POSITIONS
PHI = L.PHI  # the models' crank positions 2 pi i / 360


# ----------------------------------------------------------------------------- method 2
def _axis_inputs(phi, moment, omega, phi_dd):
    phi = np.ascontiguousarray(phi, dtype=np.float64)
    moment = np.ascontiguousarray(moment, dtype=np.float64)
    if phi.ndim != 1 or moment.shape != phi.shape:
        raise ValueError(f"phi and moment must be 1-D arrays of one length, got {phi.shape} and {moment.shape}")
    if phi.size < 3:
        raise ValueError(f"need at least 3 crank positions, got {phi.size}")
    w1 = np.ascontiguousarray(np.broadcast_to(np.asarray(omega, dtype=np.float64), phi.shape))
    al1 = np.ascontiguousarray(np.broadcast_to(np.asarray(phi_dd, dtype=np.float64), phi.shape))
    return phi, moment, w1, al1


def rms_axis_offset(phi, moment, S, omega, *, phi_dd=0.0, cw_angle=math.pi, weights=None,
                    method: str = "normal", cw_weight=0.0) -> tuple[float, float]:
    """RMS-optimal axis O1 = (x, y) [m] of the crank counterweight (physics.md section 3).

    phi: crank positions [rad] (any, e.g. non-uniform); moment: the shaking moment M(phi) [N m] of
    the statically balanced mechanism at them; S: the counterweight's static moment m r [kg m];
    omega: phi' [rad/s] (scalar: constant speed, or an array per position); phi_dd: phi''
    [rad/s^2] (scalar or array); cw_angle: the counterweight's angle from the crank (pi: opposite);
    weights: optional weights of the positions in the sum (default 1 each); cw_weight: the
    counterweight's weight m_cw g [N] when ``moment`` includes the moment of the weights (gravity):
    moving the axis by x then also adds -cw_weight x (see axis_moment). Default 0: no gravity.

    method "normal" (default): minimise sum (M_i + Delta M_i)^2 through the 2x2 normal equations,
    valid for any positions, speed law and gravity. method "formula1": the source's closed form (1),
    x = sum M sin(phi) / (S w^2 sum sin^2), y = -sum M cos(phi) / (S w^2 sum cos^2) (for
    cw_angle = pi), which needs constant speed and no gravity and is the RMS optimum only when
    sum sin(psi) cos(psi) = 0 (symmetric uniform positions). S = 0 gives (0, 0).
    Raises ValueError if the normal equations are singular."""
    phi, moment, w1, al1 = _axis_inputs(phi, moment, omega, phi_dd)
    S = float(S)
    if S < 0.0:
        raise ValueError(f"S = {S} must be >= 0 (a static moment m r); turn cw_angle by pi instead")
    cb, sb = math.cos(cw_angle), math.sin(cw_angle)
    c, s = np.cos(phi), np.sin(phi)
    if method == "formula1":
        if np.ndim(omega) != 0 or np.any(np.asarray(phi_dd) != 0.0) or weights is not None:
            raise ValueError("formula (1) assumes constant speed: give a scalar omega, phi_dd = 0, no weights")
        if cw_weight != 0.0:
            raise ValueError("formula (1) leaves out the counterweight's weight: with cw_weight != 0 use "
                             "method='normal'")
        if S == 0.0:
            return 0.0, 0.0
        return tuple(float(v) for v in L.axis_formula1(c, s, moment, S, float(omega), cb, sb))
    if method != "normal":
        raise ValueError(f"method {method!r} is not allowed; expected 'normal' or 'formula1'")
    w = np.ones_like(phi) if weights is None else np.ascontiguousarray(np.broadcast_to(weights, phi.shape), float)
    ok, x, y = L.axis_fit(c, s, w1, al1, moment, w, S, cb, sb, False, float(cw_weight))
    if not ok:
        raise ValueError("the normal equations are singular (e.g. omega = 0 and phi_dd = 0 everywhere)")
    return float(x), float(y)


def periodic_trapezoid_weights(phi) -> np.ndarray:
    """Quadrature weights of a periodic function sampled at increasing positions phi covering one
    turn [phi_0, phi_0 + 2 pi): w_i = (phi_{i+1} - phi_{i-1}) / 2 (cyclic). Uniform: all 2 pi / N."""
    phi = np.asarray(phi, dtype=np.float64)
    if np.any(np.diff(phi) <= 0) or phi[-1] - phi[0] >= 2 * np.pi:
        raise ValueError("phi must increase strictly and span less than one turn (2 pi)")
    nxt = np.append(phi[1:], phi[0] + 2 * np.pi)
    prv = np.insert(phi[:-1], 0, phi[-1] - 2 * np.pi)
    return 0.5 * (nxt - prv)


def first_harmonic_axis_offset(phi, moment, S, omega, *, phi_dd=0.0, cw_angle=math.pi,
                               cw_weight=0.0) -> tuple[float, float]:
    """Axis O1 = (x, y) [m] that cancels the first Fourier harmonic (in phi) of M + Delta M
    (cw_weight: as rms_axis_offset).

    The Fourier integrals over one turn use the periodic trapezoid rule at the given positions
    (which must increase and cover one turn). With uniform positions, constant speed and no
    gravity this is the RMS optimum (the least-squares first harmonic is the DFT coefficient,
    physics.md section 3); with phi'' != 0, non-uniform positions or gravity the two differ."""
    phi, moment, w1, al1 = _axis_inputs(phi, moment, omega, phi_dd)
    if S == 0.0:
        return 0.0, 0.0
    ok, x, y = L.axis_fit(np.cos(phi), np.sin(phi), w1, al1, moment, periodic_trapezoid_weights(phi),
                          float(S), math.cos(cw_angle), math.sin(cw_angle), True, float(cw_weight))
    if not ok:
        raise ValueError("the first-harmonic conditions are singular")
    return float(x), float(y)


def axis_moment(phi, x, y, S, omega, *, phi_dd=0.0, cw_angle=math.pi, cw_weight=0.0) -> np.ndarray:
    """Delta M(phi) [N m] added by turning the counterweight about O1 = (x, y) instead of the crank
    axis: -S [phi'^2 (y cos psi - x sin psi) + phi'' (x cos psi + y sin psi)] - cw_weight x,
    psi = phi + cw_angle; cw_weight = m_cw g [N], the counterweight's weight, whose moment about
    the crank axis moves with it (0: no gravity; the source's formula has no such term)."""
    phi, zero, w1, al1 = _axis_inputs(phi, np.zeros(np.shape(phi)), omega, phi_dd)
    out = np.empty_like(phi)
    L.axis_residual(np.cos(phi), np.sin(phi), w1, al1, zero, float(S), math.cos(cw_angle),
                    math.sin(cw_angle), float(x), float(y), out, float(cw_weight))
    return out


def efficiency(dM_static, dM_method):
    """R_j = (max|dM_1| - max|dM_j|) / max|dM_1| * 100 [%] (physics.md section 3).

    dM_static: residual moment of plain static balancing, dM_method: of method j; arrays over
    crank positions (the maximum of |.| is taken along the last axis; scalars are taken as those
    maxima already), so stacks of curves give an array of efficiencies. 100 % removes the moment,
    0 % is no better than static balancing, < 0 is worse."""
    a = np.max(np.abs(np.asarray(dM_static, dtype=float)), axis=-1) if np.ndim(dM_static) else abs(float(dM_static))
    b = np.max(np.abs(np.asarray(dM_method, dtype=float)), axis=-1) if np.ndim(dM_method) else abs(float(dM_method))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = (a - b) / a * 100.0
    return r if np.ndim(r) else float(r)


# ----------------------------------------------------------------------------- method 5
def pareto_front(indices) -> np.ndarray:
    """Boolean mask of the non-dominated rows of ``indices`` [n, k] (every column minimised).

    Row a dominates row b if a <= b in every column and a < b in at least one. Rows with a NaN
    are never on the front (e.g. non-OK grid points); identical rows are all kept. The rows are
    sorted lexicographically (a dominator always sorts first), then each is checked against the
    front found so far in one compiled pass, stopping at the first dominator (which is moved to
    the start of the list, so strong dominators are tried first). Cost: about n x (a few front
    points) for dominated rows, the front size for front rows (measured: 600,625 rows of 4
    indices with a front of 11,805 rows in 1.5 s; with the counterweight mass as a 5th index the
    front has 35,506 rows and takes 11 s)."""
    F = np.asarray(indices, dtype=np.float64)
    if F.ndim == 1:
        F = F[:, None]
    if F.ndim != 2:
        raise ValueError(f"indices must be [n, k], got shape {F.shape}")
    mask = np.zeros(F.shape[0], dtype=bool)
    good = np.flatnonzero(~np.isnan(F).any(axis=1))
    if good.size == 0:
        return mask
    order = good[np.lexsort(F[good].T[::-1])]
    mask[order[_front_of_sorted(np.ascontiguousarray(F[order]))]] = True
    return mask


@jit
def _front_of_sorted(G):
    """Non-dominated rows of lexicographically sorted G (bool mask in G's order)."""
    n, k = G.shape
    keep = np.zeros(n, dtype=np.bool_)
    front = np.empty(n, dtype=np.int64)  # indices of the front rows found so far, in trial order
    nf = 0
    for i in range(n):
        dominated = False
        for t in range(nf):
            j = front[t]
            le = True
            lt = False
            for c in range(k):
                if G[j, c] > G[i, c]:
                    le = False
                    break
                if G[j, c] < G[i, c]:
                    lt = True
            if le and lt:
                dominated = True
                if t > 0:  # move the dominator forward
                    front[t] = front[t // 2]
                    front[t // 2] = j
                break
        if not dominated:
            keep[i] = True
            front[nf] = i
            nf += 1
    return keep


def weighted_optimum(indices, weights) -> int:
    """Row index minimising the textbook's weighted sum f = sum_j w_j f_j (physics.md section 4)
    over the rows of ``indices`` [n, k] without NaN. The weights carry the units (the textbook
    leaves their choice open); divide the columns by reference values first for a dimensionless
    sum. The optimum is always on the Pareto front for positive weights."""
    F = np.asarray(indices, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    if F.ndim != 2 or w.shape != (F.shape[1],):
        raise ValueError(f"indices [n, k] and k weights expected, got {F.shape} and {w.shape}")
    f = F @ w
    f[np.isnan(F).any(axis=1)] = np.inf
    if not np.isfinite(f).any():
        raise ValueError("no row without NaN")
    return int(np.argmin(f))


# ----------------------------------------------------------------------------- substitution, counterweights
def static_two_point(m, b, c):
    """Static two-point substitution of mass m by masses at B and C on a line through its centre
    G, at distances b and c on opposite sides: (m_B, m_C) = (m c, m b) / (b + c). Keeps mass and
    centre of mass (enough for shaking forces), not the moment of inertia."""
    return L.static_two_point.py_func(np.asarray(m, float), np.asarray(b, float), np.asarray(c, float))


def dynamic_two_point(m, I_G, b):
    """Dynamic two-point substitution: B at distance b from G, K on the other side at
    k = I_G / (m b); (m_B, m_K, k) with m_B = m k / (b + k), m_K = m b / (b + k). Keeps mass,
    centre of mass and moment of inertia about G."""
    return L.dynamic_two_point.py_func(np.asarray(m, float), np.asarray(I_G, float), np.asarray(b, float))


def fourbar_counterweights(a1, a2, a3, m1, r1, m2, r2, m3, r3, theta1=0.0, theta2=0.0, theta3=0.0) -> dict:
    """Counterweights on crank and rocker for complete shaking-force balancing of a four-bar
    (linearly independent vectors, physics.md section 4): mass-radius products [kg m] and angles
    from the link lines [rad], keys cw1_mr, cw1_angle, cw3_mr, cw3_angle."""
    c1x, c1y, c3x, c3y = L.fourbar_static_counterweights(
        float(a1), float(a2), float(a3), float(m1), float(r1), float(theta1), float(m2), float(r2),
        float(theta2), float(m3), float(r3), float(theta3))
    return {"cw1_mr": math.hypot(c1x, c1y), "cw1_angle": math.atan2(c1y + 0.0, c1x),
            "cw3_mr": math.hypot(c3x, c3y), "cw3_angle": math.atan2(c3y + 0.0, c3x)}


def slidercrank_counterweight(**params) -> dict:
    """Textbook crank counterweight of a slider-crank (rotating mass + fraction k of the
    reciprocating mass): keys m_A, m_B, cw_mr, cw_angle. Parameters as the model's."""
    params.setdefault("omega", 1.0)  # not used
    p = _row("slidercrank_balancing", params)
    cx, cy, mA, mB = L.slider_counterweight(p, L.slider_conrod_length(p))
    return {"m_A": mA, "m_B": mB, "cw_mr": math.hypot(cx, cy), "cw_angle": math.atan2(cy + 0.0, cx)}


# ----------------------------------------------------------------------------- curves of one linkage
def _spec(model: str):
    from .models import fourbar_balancing, slidercrank_balancing

    specs = {"fourbar_balancing": fourbar_balancing.SPEC, "slidercrank_balancing": slidercrank_balancing.SPEC}
    if model not in specs:
        raise ValueError(f"model {model!r} is not allowed; expected one of {', '.join(specs)}")
    return specs[model]


def _row(model: str, params: Mapping) -> np.ndarray:
    """One parameter row in the model's order (validated like a scene's fixed values)."""
    return _matrix(model, params)[0][0]


def _matrix(model: str, params: Mapping):
    spec = _spec(model)
    aliases = spec.aliases()  # a former name (lambda: now lam) still accepted
    both = [a for a in params if a in aliases and aliases[a] in params]
    if both:
        raise ValueError(f"{both[0]} is the former name of {aliases[both[0]]}, which is given too; keep one")
    params = {aliases.get(k, k): v for k, v in params.items()}
    unknown = set(params) - set(spec.param_names())
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(sorted(unknown))} of {model}; "
                         f"expected some of {', '.join(spec.param_names())}")
    if spec.check is not None:
        problems = spec.check({k: (v,) for k, v in params.items()})
        if problems:
            raise ValueError("; ".join(problems))
    columns = []
    for prm in spec.params:
        if prm.name not in params:
            if prm.required:
                raise ValueError(f"missing parameter {prm.name} ({prm.long_name}, {prm.allowed()})")
            columns.append(np.asarray(prm.default, dtype=float))
            continue
        vals = np.asarray(params[prm.name], dtype=object if prm.categorical else float)
        for v in vals.ravel():
            msg = prm.problem(v if prm.categorical else float(v))
            if msg:
                raise ValueError(f"{prm.name}: {msg}")
        columns.append(np.vectorize(prm.encode, otypes=[float])(vals) if prm.categorical else vals.astype(float))
    cols = np.broadcast_arrays(*columns)
    shape = cols[0].shape
    P = np.stack([c.ravel() for c in cols], axis=1)  # [n, params]; n = 1 for scalars
    return np.ascontiguousarray(P), shape


def _motion(phi, phi_d, phi_dd):
    """Crank angle, speed and acceleration as contiguous float64 arrays of phi's shape."""
    phi = np.ascontiguousarray(np.atleast_1d(np.asarray(phi, dtype=np.float64)))
    w1 = np.ascontiguousarray(np.broadcast_to(np.asarray(phi_d, float), phi.shape))
    al1 = np.ascontiguousarray(np.broadcast_to(np.asarray(phi_dd, float), phi.shape))
    return phi, w1, al1


def fourbar_curves(phi, phi_d, phi_dd=0.0, *, static: bool = False, **params) -> tuple[dict, int]:
    """Kinematics and loads of one four-bar at crank positions phi with phi' = phi_d and
    phi'' = phi_dd (scalars or arrays; any motion law). ``static`` True: with the counterweights of
    complete force balancing (method 1) instead of the given ones. Parameters as the model
    ``fourbar_balancing`` (scalars; its omega and delta are not used here). Returns (curves,
    status): curves phi2, phi3 (link angles), omega2, omega3, alpha2, alpha3, sin_mu (= sin of
    phi3 - phi2), Fx, Fy, M, T as arrays like phi."""
    params.setdefault("omega", 1.0)
    p = _row("fourbar_balancing", params)
    phi, w1, al1 = _motion(phi, phi_d, phi_dd)
    out = np.full((phi.size, 13), np.nan)
    code = L.fourbar_curves_at(p, static, phi, w1, al1, out)
    c = {"phi2": np.arctan2(out[:, 1], out[:, 0]), "phi3": np.arctan2(out[:, 3], out[:, 2])}
    for k, name in enumerate(("omega2", "omega3", "alpha2", "alpha3", "sin_mu", "Fx", "Fy", "M", "T"), start=4):
        c[name] = out[:, k]
    return c, int(code)


def slidercrank_curves(phi, phi_d, phi_dd=0.0, *, balanced: bool = True, **params) -> tuple[dict, int]:
    """Kinematics and loads of one slider-crank at crank positions phi (phi' = phi_d,
    phi'' = phi_dd), with (balanced) or without the k-counterweight. Parameters as the model
    ``slidercrank_balancing``. Returns (curves, status): phi2, omega2, alpha2, x_B, v_B, a_B, Fx,
    Fy, M, T."""
    params.setdefault("omega", 1.0)
    params.setdefault("k", 0.0)
    p = _row("slidercrank_balancing", params)
    phi, w1, al1 = _motion(phi, phi_d, phi_dd)
    out = np.full((phi.size, 11), np.nan)
    code = L.slider_curves_at(p, balanced, phi, w1, al1, out)
    c = {"phi2": np.arctan2(out[:, 1], out[:, 0])}
    for k, name in enumerate(("omega2", "alpha2", "x_B", "v_B", "a_B", "Fx", "Fy", "M", "T"), start=2):
        c[name] = out[:, k]
    return c, int(code)


def evaluate(model: str, outputs, *, n_positions: int = N_POSITIONS, **params) -> tuple[dict, np.ndarray]:
    """Outputs of a linkage model for parameters given as scalars or broadcastable arrays
    (categorical ones by name), without a scene. Returns ({output: array [..., n_positions for
    ``*_phi``]}, status array) in the broadcast shape. n_positions: uniform crank positions per cycle
    behind the maxima, RMS values, fits and curves (default 360, as in every sweep)."""
    spec = _spec(model)
    outputs = (outputs,) if isinstance(outputs, str) else tuple(outputs)
    for o in outputs:
        if o not in spec.output_names():
            raise ValueError(f"unknown output {o!r} of {model}")
    P, shape = _matrix(model, params)
    n = P.shape[0]
    wanted = spec.closure(outputs)
    out = {o: np.full((n,) + ((n_positions,) if spec.output(o).extra_dims else ()), np.nan) for o in wanted}
    status = np.zeros(n, dtype=st.DTYPE)
    spec.evaluate(P, wanted, None, out, status, np.zeros(n, np.int64), np.zeros(n, np.int64), n_positions)
    return ({o: out[o].reshape(shape + out[o].shape[1:]) for o in outputs}, status.reshape(shape))
