"""`mechsweep bench workprecision fourbar_balancing | slidercrank_balancing`: the error of the
algebraic linkage outputs against the number N of crank positions, and what each N costs.

The linkage models have one discretisation: N uniform crank positions phi_i = 2 pi i / N
(N_POSITIONS = 360 in every sweep) behind every maximum, RMS value, fit and range. A fixed sample
of design points (drawn with a fixed seed from the model's shipped scene, or from --scene; points
that are not OK are dropped, said in the report) is evaluated for each N of a ladder by

- mechsweep: the model's kernel at N positions (``evaluate(..., n_positions=N)``), on one thread,
  all of the case's outputs in one call (the sample repeated as in `workprecision`, the fastest
  of ``repeats``; the first call, JIT compile or disk-cache load, is reported separately), and
- numpy: a plain vectorised numpy implementation of the same outputs at the same N, [designs, N]
  arrays in blocks of 64 designs, on the same repeated sample in the same run (its values must agree
  with the kernel's to round-off: the largest relative difference is reported).

Errors are relative, |value - reference| / |reference|, the maximum and median over the sample,
against the best reference there is, on the continuous crank angle:

- slider-crank (e = 0, delta = 0, centres of mass on the link lines, the shipped scene): closed
  form. x_B = r cos phi + l sqrt(1 - lambda^2 sin^2 phi), and with the textbook counterweight the
  shaking force is Fx = m_B r w^2 [(1 - k) cos phi + sum_n (4 n^2 a_n / lambda) cos 2 n phi],
  Fy = -k m_B r w^2 sin phi - g m_total, a_n the Fourier coefficients of
  sqrt(1 - lambda^2 sin^2 phi), summed from its binomial series to round-off. RMS values by
  Parseval, maxima by Brent's method (scipy minimize_scalar) from the local maxima on a
  16384-position grid.
- four-bar (no closed form): the same continuous-angle functions as the models
  (``fourbar_curves_at``, one position at a time), integrated by composite Gauss-Legendre
  (512 panels x 16 nodes; the difference to 256 panels is the reference's own error estimate,
  reported), the counterweight axis from the 2x2 normal equations with those integrals, maxima
  by Brent's method as above.

Expected, and measured rather than assumed: the uniform rule on a smooth periodic function
converges faster than any power of 1/N (RMS values and the fitted axis), maxima converge as
1/N^2 (the grid misses the peak by up to pi / N; exact when the peak is on the grid by symmetry).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numba
import numpy as np

from .. import status as st
from ..models import MODELS
from ..models import _linkage as L
from ..models import fourbar_balancing as fb
from ..scene import load_scene
from . import scenes

POSITIONS = (12, 24, 45, 90, 180, 360, 720, 1440, 2880)
TIMED_POINTS = 1024  # our time per point: the sample repeated up to this many points ...
TIMED_CALL_S = 0.05  # ... or until one call takes this long
NUMPY_BLOCK = 64  # designs per numpy block (bench linkage: numpy's fastest size here)
SEARCH_POSITIONS = 16384  # grid on which the maxima are located before Brent's refinement
GL_NODES = 16  # Gauss-Legendre nodes per panel of the four-bar reference
GL_PANELS = (256, 512)  # coarse (error estimate) and fine (reference)


@dataclass(frozen=True)
class LinkageCase:
    """What is measured for one linkage model."""

    scene: str  # default scene the sample is drawn from: a packaged copy of sweeps/<scene> (bench/scenes)
    outputs: dict  # output -> what kind of quantity it is (for the report)
    reference: Callable  # P row -> ({output: exact value}, error estimate of the reference)
    reference_name: str
    numpy_outputs: Callable  # (P, n_positions) -> {output: values}


# ============================================================================= continuous-angle maxima
def refined_maximum(f, n_search: int = SEARCH_POSITIONS) -> float:
    """max of a smooth 2 pi-periodic f (vectorised over phi) on the continuous angle: every local
    maximum of f on n_search uniform positions within 10 % of the largest is refined by Brent's
    method (golden section and parabolas, scipy minimize_scalar) between its neighbours."""
    from scipy.optimize import minimize_scalar

    h = 2.0 * np.pi / n_search
    phi = h * np.arange(n_search)
    v = f(phi)
    top = v.max()
    local = (v >= np.roll(v, 1)) & (v >= np.roll(v, -1)) & (v >= top - 0.1 * abs(top))
    best = top
    for j in np.flatnonzero(local):
        res = minimize_scalar(lambda x: -f(np.array([x]))[0], bounds=(phi[j] - h, phi[j] + h), method="bounded",
                              options={"xatol": 1e-12 * max(1.0, abs(phi[j])), "maxiter": 200})
        best = max(best, -res.fun)
    return float(best)


# ============================================================================= slider-crank: closed form
def sqrt_series_coefficients(lam: float, terms: int = 80) -> np.ndarray:
    """a_n, n = 0 .. terms, of sqrt(1 - lam^2 sin^2 phi) = sum_n a_n cos(2 n phi).

    With theta = 2 phi: 1 - lam^2 sin^2 phi = A + B cos theta, A = 1 - lam^2 / 2, B = lam^2 / 2, so
    sqrt(A) sum_j binom(1/2, j) (B / A)^j cos^j theta, cos^j theta = 2^-j sum_m C(j, m) cos((j - 2m) theta).
    B / A <= 1/3 for lam <= 0.7071, so 80 terms are far below round-off for every feasible rod ratio
    of interest (B / A = 0.11 at lam = 0.45); the terms alternate in sign without cancellation."""
    A = 1.0 - 0.5 * lam * lam
    q = 0.5 * lam * lam / A
    if not q < 1.0:
        raise ValueError(f"the binomial series of sqrt(1 - lambda^2 sin^2 phi) needs lambda < 1, got {lam}")
    a = np.zeros(terms + 1)
    binom = 1.0  # binom(1/2, j)
    for j in range(terms + 1):
        w = binom * q**j / 2.0**j
        for m in range(j + 1):
            a[abs(j - 2 * m)] += w * math.comb(j, m)  # harmonic n of theta is harmonic 2n of phi
        binom *= (0.5 - j) / (j + 1)
    return math.sqrt(A) * a


def slider_series_applies(p) -> str:
    """'' if the closed-form series describes slider-crank row p, else why not."""
    if p[L.S_E] != 0.0:
        return "an offset slider (e != 0)"
    if p[L.S_DELTA] != 0.0:
        return "a non-constant crank speed (delta != 0)"
    if math.sin(p[L.S_TH2]) != 0.0 and p[L.S_R2] != 0.0:
        return "a connecting rod whose centre of mass is off its line (theta2 != 0)"
    return ""


class SliderSeries:
    """Exact shaking force of a slider-crank row p with its textbook counterweight, from the
    harmonic series of the slider position (see the module docstring)."""

    def __init__(self, p):
        why = slider_series_applies(p)
        if why:
            raise ValueError(f"the closed-form slider-crank reference does not hold for {why}")
        r = p[L.S_R]
        l = L.slider_conrod_length(p)
        cwx, cwy, _, mB = L.slider_counterweight(p, l)
        r_cw = p[L.S_RCW] if not math.isnan(p[L.S_RCW]) else r
        mtot = L.slider_links(p, cwx, cwy, r_cw)[8]
        self.lam = r / l
        self.amp = mB * r * p[L.S_OMEGA] ** 2
        self.k = p[L.S_K]
        self.weight = p[L.S_G] * mtot
        a = sqrt_series_coefficients(self.lam)
        n = np.arange(a.size)
        self.b = 4.0 * n * n * a / self.lam  # Fx / amp = (1 - k) cos phi + sum_n b_n cos 2 n phi
        self.b[0] = 0.0

    def force(self, phi):
        n = np.arange(1, self.b.size)
        fx = self.amp * ((1.0 - self.k) * np.cos(phi) + np.cos(2.0 * np.multiply.outer(phi, n)) @ self.b[1:])
        fy = -self.k * self.amp * np.sin(phi) - self.weight
        return fx, fy

    def textbook_error(self, phi):
        """|F - F_tb|: the series beyond the textbook's (1 - k) cos phi + lambda cos 2 phi."""
        fx, _ = self.force(phi)
        tb = self.amp * ((1.0 - self.k) * np.cos(phi) + self.lam * np.cos(2.0 * phi))
        return np.abs(fx - tb)

    def fx_rms(self):
        """Parseval: mean of Fx^2 = amp^2 ((1 - k)^2 + sum b_n^2) / 2."""
        return abs(self.amp) * math.sqrt(0.5 * ((1.0 - self.k) ** 2 + float(self.b[1:] @ self.b[1:])))


def slider_reference(p):
    s = SliderSeries(p)
    ref = {
        "F_max": math.sqrt(refined_maximum(lambda phi: np.add(*(np.square(f) for f in s.force(phi))))),
        "Fx_rms": s.fx_rms(),
        "F_tb_error_rel": refined_maximum(s.textbook_error) / abs(s.amp),
    }
    return ref, 0.0


def numpy_slider(P: np.ndarray, n_positions: int, block: int = NUMPY_BLOCK) -> dict:
    """F_max, Fx_rms and F_tb_error_rel of slider-crank rows P at n_positions uniform crank
    positions: the kernel's closed forms (exact kinematics, textbook counterweight, loads) on
    [designs, N] numpy arrays, no status checks (feasible designs only)."""
    cos_phi, sin_phi, _ = fb.positions(n_positions)
    c1, s1 = cos_phi[None, :], sin_phi[None, :]
    n = P.shape[0]
    res = {k: np.empty(n) for k in ("F_max", "Fx_rms", "F_tb_error_rel")}
    for start in range(0, n, block):
        p = P[start:start + block]
        col = lambda name: p[:, L.SLIDER_PARAMS.index(name)][:, None]  # noqa: E731
        r, e, k, omega, delta, g = col("r"), col("e"), col("k"), col("omega"), col("delta"), col("g")
        l = np.where(np.isnan(col("l")), r / col("lambda"), col("l"))
        r_cw = np.where(np.isnan(col("r_cw")), r, col("r_cw"))
        sigma = 1.0 - 2.0 * col("branch")
        m1, r1, th1, m2, r2, th2, m3 = (col(x) for x in ("m1", "r1", "theta1", "m2", "r2", "theta2", "m3"))
        # textbook counterweight: rotating first moment and reciprocating mass (static substitution)
        u2x, u2y = r2 * np.cos(th2), r2 * np.sin(th2)
        urx = m1 * r1 * np.cos(th1) + m2 * r * (1.0 - u2x / l)
        ury = m1 * r1 * np.sin(th1) - m2 * r * u2y / l
        mB = m3 + m2 * u2x / l
        cwx, cwy = -(urx + k * mB * r), -ury
        U1x, U1y = m1 * r1 * np.cos(th1) + cwx, m1 * r1 * np.sin(th1) + cwy
        V2x, V2y = m2 * u2x, m2 * u2y
        mtot = m1 + m2 + m3 + np.hypot(cwx, cwy) / r_cw
        # exact kinematics
        w1 = omega * (1.0 + delta * s1)
        al1 = w1 * omega * delta * c1
        s2 = (e - r * s1) / l
        c2 = sigma * np.sqrt(np.maximum((1.0 - s2) * (1.0 + s2), 0.0))
        w2 = -r * w1 * c1 / (l * c2)
        w1s, w2s = w1 * w1, w2 * w2
        al2 = (r * w1s * s1 + l * w2s * s2 - r * al1 * c1) / (l * c2)
        aB = -r * al1 * s1 - r * w1s * c1 - l * al2 * s2 - l * w2s * c2
        # shaking force -sum m a_G - g m_total
        u1x, u1y = U1x * c1 - U1y * s1, U1x * s1 + U1y * c1
        aax, aay = r * (-al1 * s1 - w1s * c1), r * (al1 * c1 - w1s * s1)
        v2x, v2y = V2x * c2 - V2y * s2, V2x * s2 + V2y * c2
        Fx = -((-al1 * u1y - w1s * u1x) + (m2 * aax - al2 * v2y - w2s * v2x) + m3 * aB)
        Fy = -((al1 * u1x - w1s * u1y) + (m2 * aay + al2 * v2x - w2s * v2y)) - g * mtot
        amp = mB * r * omega * omega
        Fx_tb = (1.0 - k) * amp * c1 + (r / l) * amp * (c1 * c1 - s1 * s1)
        Fy_tb = -k * amp * s1 - g * mtot
        sl = slice(start, start + p.shape[0])
        res["F_max"][sl] = np.sqrt((Fx * Fx + Fy * Fy).max(1))
        res["Fx_rms"][sl] = np.sqrt((Fx * Fx).mean(1))
        res["F_tb_error_rel"][sl] = np.sqrt(((Fx - Fx_tb) ** 2 + (Fy - Fy_tb) ** 2).max(1)) / np.abs(amp[:, 0])
    return res


# ============================================================================= four-bar: quadrature
def gauss_legendre_periodic(panels: int, nodes: int = GL_NODES):
    """(phi, weights / 2 pi) of composite Gauss-Legendre on [0, 2 pi): the mean of f is f(phi) @ w."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    h = 2.0 * np.pi / panels
    left = h * np.arange(panels)
    phi = (left[:, None] + 0.5 * h * (x[None, :] + 1.0)).ravel()
    return phi, np.tile(0.5 * w / panels, panels)


class FourbarContinuous:
    """Shaking moment after complete force balancing and the counterweight-axis basis of four-bar
    row p at any crank angles (the models' position functions, ``fourbar_curves_at``)."""

    def __init__(self, p):
        self.p = np.ascontiguousarray(p, dtype=np.float64)
        a1, a2, a3 = p[L.P_A1], p[L.P_A2], p[L.P_A3]
        C1x, C1y, _, _ = L.fourbar_static_counterweights(
            a1, a2, a3, p[L.P_M1], p[L.P_R1], p[L.P_TH1], p[L.P_M2], p[L.P_R2], p[L.P_TH2], p[L.P_M3], p[L.P_R3],
            p[L.P_TH3])
        self.S = math.hypot(C1x, C1y)
        self.cb, self.sb = (C1x / self.S, C1y / self.S) if self.S > 0.0 else (1.0, 0.0)

    def motion(self, phi):
        omega, delta = self.p[L.P_OMEGA], self.p[L.P_DELTA]
        w1 = omega * (1.0 + delta * np.sin(phi))
        return w1, w1 * omega * delta * np.cos(phi)

    def moment(self, phi):
        phi = np.ascontiguousarray(np.atleast_1d(phi), dtype=np.float64)
        w1, al1 = self.motion(phi)
        out = np.empty((phi.size, 13))
        code = L.fourbar_curves_at(self.p, True, phi, w1, al1, out)
        if code != st.OK:
            raise ValueError(f"four-bar reference at a design with status {st.MEANINGS[code]}")
        return out[:, 11]

    def axis_basis(self, phi):
        """(gx, gy): Delta M = gx x + gy y (``axis_basis`` of the kernels, on arrays)."""
        w1, al1 = self.motion(phi)
        c, s = np.cos(phi), np.sin(phi)
        cp, sp = c * self.cb - s * self.sb, s * self.cb + c * self.sb
        return self.S * (w1 * w1 * sp - al1 * cp), -self.S * (w1 * w1 * cp + al1 * sp)

    def outputs(self, panels: int) -> dict:
        """Continuous-angle M_rms_static, M_max_static, dM_rms_axis, dM_max_axis (RMS and the
        normal equations by composite Gauss-Legendre with ``panels`` panels)."""
        phi, w = gauss_legendre_periodic(panels)
        M = self.moment(phi)
        gx, gy = self.axis_basis(phi)
        ok, x, y = L.solve2(gx * gx @ w, gx * gy @ w, gx * gy @ w, gy * gy @ w, -(M * gx) @ w, -(M * gy) @ w)
        if not ok:
            raise ValueError("singular normal equations of the counterweight axis")
        dM = M + gx * x + gy * y
        return {"M_rms_static": math.sqrt(M * M @ w), "dM_rms_axis": math.sqrt(dM * dM @ w), "axis": (x, y)}


def fourbar_reference(p):
    f = FourbarContinuous(p)
    coarse, fine = f.outputs(GL_PANELS[0]), f.outputs(GL_PANELS[1])
    x, y = fine.pop("axis")
    coarse.pop("axis")
    estimate = max(abs(fine[k] - coarse[k]) / abs(fine[k]) for k in fine)

    def residual(phi):
        gx, gy = f.axis_basis(phi)
        return np.square(f.moment(phi) + gx * x + gy * y)
    fine["M_max_static"] = math.sqrt(refined_maximum(lambda phi: np.square(f.moment(phi))))
    fine["dM_max_axis"] = math.sqrt(refined_maximum(residual))
    return fine, estimate


def numpy_fourbar(P: np.ndarray, n_positions: int) -> dict:
    from .linkage import numpy_residuals

    return numpy_residuals(P, block=NUMPY_BLOCK, n_positions=n_positions)


CASES = {
    "fourbar_balancing": LinkageCase(
        "fourbar_geometry_family.toml",
        {"M_max_static": "maximum", "M_rms_static": "RMS", "dM_rms_axis": "optimised (RMS-optimal axis), RMS",
         "dM_max_axis": "optimised (RMS-optimal axis), maximum"},
        fourbar_reference,
        f"continuous crank angle: composite Gauss-Legendre ({GL_PANELS[1]} panels x {GL_NODES} nodes) for the "
        f"RMS values and the axis, maxima by Brent's method from a {SEARCH_POSITIONS}-position grid",
        numpy_fourbar),
    "slidercrank_balancing": LinkageCase(
        "slidercrank_partial.toml",
        {"F_max": "maximum (partial-balancing residual)", "Fx_rms": "RMS", "F_tb_error_rel": "maximum"},
        slider_reference,
        "closed form: harmonic series of the slider position (RMS by Parseval), maxima by Brent's method from "
        f"a {SEARCH_POSITIONS}-position grid",
        numpy_slider),
}


# ============================================================================= measurement
def _evaluate_ours(spec, P, outputs, n_positions):
    n = P.shape[0]
    out = {k: np.full(n, np.nan) for k in outputs}
    status = np.zeros(n, st.DTYPE)
    spec.evaluate(P, outputs, None, out, status, None, None, n_positions)
    return out, status


def _fastest(fn, repeats):
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _tiled(P, once_s):
    """The sample repeated until a call takes ~TIMED_CALL_S (at most TIMED_POINTS points), so that a
    call's fixed cost is spread as over a sweep's chunk."""
    tiles = int(min(max(1, TIMED_POINTS // P.shape[0]), max(1, math.ceil(TIMED_CALL_S / max(once_s, 1e-9)))))
    return np.tile(P, (tiles, 1))


ROUNDOFF = 1e-13  # relative errors at or below this are round-off (a few hundred ulp)
FIT_FROM = 90  # the fitted order uses the rungs from this N on (the asymptotic range)


def fitted_order(errors, positions, n_from: int = FIT_FROM) -> float:
    """Least-squares p of error ~ C N^-p over the rungs N >= n_from whose error is above ROUNDOFF
    (NaN with fewer than 3 such rungs: the error reached round-off first)."""
    e = np.asarray(errors, dtype=float)
    N = np.asarray(positions, dtype=float)
    use = (N >= n_from) & (e > ROUNDOFF)
    if use.sum() < 3:
        return math.nan
    return float(-np.polyfit(np.log(N[use]), np.log(e[use]), 1)[0])


def roundoff_from(errors, positions) -> float:
    """The smallest N of the ladder from which on every error is at or below ROUNDOFF (NaN: never)."""
    e = np.asarray(errors, dtype=float)
    above = np.flatnonzero(e > ROUNDOFF)
    first = 0 if above.size == 0 else above[-1] + 1
    return float(positions[first]) if first < len(positions) else math.nan


def observed_orders(errors, positions) -> np.ndarray:
    """p between consecutive rungs: error ~ N^-p, p = log(e_a / e_b) / log(N_b / N_a) (NaN at the
    first rung and where an error is 0)."""
    e = np.asarray(errors, dtype=float)
    N = np.asarray(positions, dtype=float)
    p = np.full(e.shape, np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        p[..., 1:] = np.log(e[..., :-1] / e[..., 1:]) / np.log(N[1:] / N[:-1])
    p[~np.isfinite(p)] = np.nan
    return p


def main(model: str, scene_path: str | None = None, points: int = 64, positions=POSITIONS, repeats: int = 5,
         out_dir: str | Path = "data/bench", quiet: bool = False, seed: int = 0):
    import xarray as xr

    from ..errors import InputError
    from .workprecision import sample

    from . import _args

    if not isinstance(model, str) or model not in CASES:
        raise InputError(f"no linkage work-precision case for model {model!r}; cases: {', '.join(CASES)}")
    points = _args.count("points", points, 1, 10**6)
    repeats = _args.count("repeats", repeats, 1, 1000)
    out_dir = _args.folder("out", out_dir)
    positions = _args.sequence(positions)
    if not positions:
        raise InputError("the ladder of crank positions is empty; give at least one")
    positions = tuple(_args.count("positions", n, 1, 10**6) for n in positions)
    if min(positions) < 4:
        raise InputError(f"need at least 4 crank positions per cycle, got {min(positions)}")
    case = CASES[model]
    spec = MODELS[model]
    scene = load_scene(scene_path or scenes.path(case.scene))
    if scene.model.name != model:
        raise InputError(f"scene {scene_path} is for model {scene.model.name!r}, not {model!r}")
    outputs = tuple(case.outputs)
    P = sample(scene, points, seed)
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        t0 = time.perf_counter()
        _, status = _evaluate_ours(spec, P, outputs, L.N_POSITIONS)  # JIT compile or cache load
        first_call_s = time.perf_counter() - t0
        drawn = P.shape[0]
        P = P[status == st.OK]
        if model == "slidercrank_balancing":
            P = _closed_form_rows(P)
        if P.shape[0] == 0:
            raise InputError(f"no usable design point among the {drawn} drawn from {scene_path or scenes.path(case.scene)}")
        t0 = time.perf_counter()
        refs, estimates = zip(*(case.reference(p) for p in P))
        ref_s = time.perf_counter() - t0
        reference = {k: np.array([r[k] for r in refs]) for k in outputs}
        shape = (2, len(outputs), len(positions))
        res = {k: np.full(shape, np.nan) for k in ("error_max", "error_median")}
        time_per_point = np.full((2, len(positions)), np.nan)
        numpy_difference = np.full((len(outputs), len(positions)), np.nan)
        for b, n in enumerate(positions):
            t0 = time.perf_counter()
            ours, status = _evaluate_ours(spec, P, outputs, n)
            P_timed = _tiled(P, time.perf_counter() - t0)
            ours_s = _fastest(lambda: _evaluate_ours(spec, P_timed, outputs, n), repeats)
            time_per_point[0, b] = ours_s / P_timed.shape[0]
            theirs = case.numpy_outputs(P, n)
            time_per_point[1, b] = _fastest(lambda: case.numpy_outputs(P_timed, n), repeats) / P_timed.shape[0]
            for a, values in enumerate((ours, theirs)):
                for o, name in enumerate(outputs):
                    err = np.abs(values[name] - reference[name]) / np.abs(reference[name])
                    res["error_max"][a, o, b] = np.max(err)
                    res["error_median"][a, o, b] = np.median(err)
            for o, name in enumerate(outputs):
                numpy_difference[o, b] = np.max(np.abs(theirs[name] - ours[name]) / np.abs(ours[name]))
    finally:
        numba.set_num_threads(before)
    implementations = ["mechsweep", "numpy"]
    dims3 = ("implementation", "output", "n_positions")
    ds = xr.Dataset(
        {
            "error_max": (dims3, res["error_max"], {"units": "1",
                                                     "long_name": "largest relative error over the sample"}),
            "error_median": (dims3, res["error_median"], {"units": "1", "long_name": "median relative error"}),
            "time_per_point": (("implementation", "n_positions"), time_per_point,
                               {"units": "s", "long_name": "wall time per design point, all outputs "
                                                            "(1 thread, best of repeats)"}),
            "order": (("output", "n_positions"), observed_orders(res["error_max"][0], positions),
                      {"units": "1", "long_name": "observed order p of mechsweep's largest error, "
                                                  "error ~ N^-p from the previous rung"}),
            "order_fit": (("output",), [fitted_order(e, positions) for e in res["error_max"][0]],
                          {"units": "1", "long_name": f"order p of mechsweep's largest error fitted over "
                                                      f"N >= {FIT_FROM} (errors above {ROUNDOFF:g})"}),
            "roundoff_from": (("output",), [roundoff_from(e, positions) for e in res["error_max"][0]],
                              {"units": "1", "long_name": f"smallest N from which mechsweep's largest error stays "
                                                          f"at or below {ROUNDOFF:g}"}),
            "numpy_difference": (("output", "n_positions"), numpy_difference,
                                 {"units": "1", "long_name": "largest relative difference numpy - mechsweep"}),
        },
        coords={"implementation": ("implementation", implementations, {"long_name": "implementation"}),
                "output": ("output", list(outputs), {"long_name": "output"}),
                "n_positions": ("n_positions", np.array(positions), {"units": "1",
                                                                     "long_name": "crank positions per cycle N"}),
                "kind": ("output", [case.outputs[o] for o in outputs], {"long_name": "kind of quantity"})},
        attrs={"mechsweep_kind": "workprecision_positions", "model": model,
               "norm": "relative error |value - reference| / |reference|", "reference": case.reference_name,
               "reference_error_estimate": float(max(estimates)), "reference_time_s": ref_s,
               "points": P.shape[0], "points_drawn": drawn, "seed": seed, "repeats": repeats,
               "scene": str(scene_path or f"sweeps/{case.scene}"), "compile_or_cache_load_s": first_call_s, "threads": 1,
               "default_positions": L.N_POSITIONS,
               "numpy": f"vectorised numpy on [designs, N] arrays, blocks of {NUMPY_BLOCK} designs, same outputs"},
    )
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"workprecision_{model}.h5"
    ds.to_netcdf(path, engine="h5netcdf")
    table = [name for name in ds.data_vars if ds[name].dims == dims3]
    ds[table].to_dataframe().to_csv(path.with_suffix(".csv"))
    if not quiet:
        _print(ds, path)
    return ds


def _closed_form_rows(P):
    """The slider-crank rows the closed-form reference describes (the shipped scene: all)."""
    keep = np.array([slider_series_applies(p) == "" for p in P], dtype=bool)
    if not keep.all():
        why = slider_series_applies(P[np.flatnonzero(~keep)[0]])
        print(f"  {int((~keep).sum())} of {P.shape[0]} points dropped: no closed-form reference for {why}")
    return P[keep]


def _print(ds, path) -> None:
    a = ds.attrs
    print(f"mechsweep bench workprecision {a['model']}: {a['norm']} against the number N of crank positions")
    print(f"  reference: {a['reference']} ({a['reference_time_s']:.1f} s; its own error estimate "
          f"{a['reference_error_estimate']:.1e})")
    print(f"  {a['points']} OK points of {a['points_drawn']} drawn from {a['scene']}; 1 thread, best of "
          f"{a['repeats']}; first call (JIT compile or cache load) {a['compile_or_cache_load_s']:.2f} s")
    n_pos = ds.n_positions.values
    for o, name in enumerate(ds.output.values):
        fit, flat = float(ds.order_fit[o]), float(ds.roundoff_from[o])
        print(f"  {name} ({ds.kind.values[o]}): fitted order over N >= {FIT_FROM}: "
              + (f"{fit:.2f}" if math.isfinite(fit) else "- (round-off reached first)")
              + (f"; at round-off (<= {ROUNDOFF:g}) from N = {flat:.0f}" if math.isfinite(flat) else ""))
        print(f"    {'N':>6}{'max error':>12}{'median':>12}{'order':>8}{'numpy max err':>15}{'numpy - ours':>14}")
        for b, n in enumerate(n_pos):
            print(f"    {n:>6d}{float(ds.error_max[0, o, b]):>12.2e}{float(ds.error_median[0, o, b]):>12.2e}"
                  f"{float(ds.order[o, b]):>8.2f}{float(ds.error_max[1, o, b]):>15.2e}"
                  f"{float(ds.numpy_difference[o, b]):>14.1e}")
    print(f"  time per point, all {ds.sizes['output']} outputs in one call:")
    print(f"    {'N':>6}{'mechsweep':>13}{'numpy':>13}{'numpy / mechsweep':>19}")
    for b, n in enumerate(n_pos):
        ours, theirs = ds.time_per_point.values[:, b]
        print(f"    {n:>6d}{ours * 1e6:>10.2f} us{theirs * 1e6:>10.1f} us{theirs / ours:>18.1f}x")
    print(f"  written: {path} and {path.with_suffix('.csv')}")
