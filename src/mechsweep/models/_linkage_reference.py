"""Reference implementations of the two linkage models' outputs, for their work-precision
reports (``mechsweep bench workprecision fourbar_balancing | slidercrank_balancing``, declared by
each model as its ``SizeWorkPrecision``) and for ``python benchmarks/linkage.py``: outputs on the
continuous crank angle (the references) and plain vectorised numpy versions of the kernels' outputs
at N crank positions (the independent implementations).

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

The models import this module; it imports none of them (it uses the shared helpers of
models/_linkage.py).
"""
from __future__ import annotations

import math
import operator

import numpy as np

from .. import status as st
from . import _linkage as L

NUMPY_BLOCK = 64  # designs per numpy block (benchmarks/linkage.py: numpy's fastest size here)
SEARCH_POSITIONS = 16384  # grid on which the maxima are located before Brent's refinement
GL_NODES = 16  # Gauss-Legendre nodes per panel of the four-bar reference
GL_PANELS = (256, 512)  # coarse (error estimate) and fine (reference)
FOURBAR_OUTPUTS = ("M_rms_static", "M_max_static", "axis_x", "axis_y", "dM_rms_axis", "dM_max_axis", "R_axis")

FOURBAR_REFERENCE = (f"continuous crank angle: composite Gauss-Legendre ({GL_PANELS[1]} panels x {GL_NODES} nodes) "
                     f"for the RMS values and the axis, maxima by Brent's method from a {SEARCH_POSITIONS}-position "
                     "grid")
SLIDER_REFERENCE = ("closed form: harmonic series of the slider position (RMS by Parseval), maxima by Brent's method "
                    f"from a {SEARCH_POSITIONS}-position grid")
NUMPY = f"vectorised numpy on [designs, N] arrays, blocks of {NUMPY_BLOCK} designs, same outputs"


def _positions(n_positions: int):
    """(cos phi, sin phi, position sums) of n uniform crank positions, as the models compute them
    (_linkage.crank_positions, position_sums)."""
    _, c, s = L.crank_positions(operator.index(n_positions))
    return c, s, L.position_sums(c, s)


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
    cos_phi, sin_phi, _ = _positions(n_positions)
    c1, s1 = cos_phi[None, :], sin_phi[None, :]
    n = P.shape[0]
    res = {k: np.empty(n) for k in ("F_max", "Fx_rms", "F_tb_error_rel")}
    for start in range(0, n, block):
        p = P[start:start + block]
        col = lambda name: p[:, L.SLIDER_PARAMS.index(name)][:, None]  # noqa: E731
        r, e, k, omega, delta, g = col("r"), col("e"), col("k"), col("omega"), col("delta"), col("g")
        l = np.where(np.isnan(col("l")), r / col("lam"), col("l"))
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
        self.W = p[L.P_G] * self.S / L.fourbar_cw_radii(self.p)[0]  # the counterweight's weight m_cw g

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
        """(gx, gy): Delta M = gx x + gy y (``axis_basis`` of the kernels, on arrays; with gravity
        the moved counterweight's weight adds -W x)."""
        w1, al1 = self.motion(phi)
        c, s = np.cos(phi), np.sin(phi)
        cp, sp = c * self.cb - s * self.sb, s * self.cb + c * self.sb
        return self.S * (w1 * w1 * sp - al1 * cp) - self.W, -self.S * (w1 * w1 * cp + al1 * sp)

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


# ============================================================================= four-bar: numpy at N positions
def numpy_fourbar(P: np.ndarray, n_positions: int = L.N_POSITIONS, block: int = NUMPY_BLOCK) -> dict:
    """The same computation as the mechsweep kernel, vectorised with numpy over [designs, N]
    (N = n_positions uniform crank positions, 360 as in sweeps). Constant crank speed and no
    gravity only (delta = 0, g = 0): a ValueError otherwise."""
    for name in ("delta", "g"):
        if np.any(P[:, L.FOURBAR_PARAMS.index(name)] != 0.0):
            raise ValueError(f"the numpy four-bar residuals assume {name} = 0 (constant speed, no gravity)")
    n = P.shape[0]
    res = {k: np.empty(n) for k in FOURBAR_OUTPUTS}
    cos_phi, sin_phi, sums = _positions(n_positions)
    SUM_CC, SUM_SS, SUM_SC = sums
    c1 = cos_phi[None, :]
    s1 = sin_phi[None, :]
    for s in range(0, n, block):
        p = P[s:s + block]
        col = lambda name: p[:, L.FOURBAR_PARAMS.index(name)][:, None]  # noqa: E731
        a1, a2, a3, a4 = col("a1"), col("a2"), col("a3"), col("a4")
        sigma = 1.0 - 2.0 * col("branch")
        w1 = col("omega")  # constant speed: phi'' = 0
        m1, r1, th1 = col("m1"), col("r1"), col("theta1")  # I1: no effect at constant crank speed
        m2, r2, th2, I2 = col("m2"), col("r2"), col("theta2"), col("I2")
        m3, r3, th3, I3 = col("m3"), col("r3"), col("theta3"), col("I3")
        rc3 = np.where(np.isnan(col("r_cw3")), a3, col("r_cw3"))  # absent: at the rocker's joint B
        # method 1: counterweights (linearly independent vectors)
        C1x = m2 * a1 * (r2 / a2 * np.cos(th2) - 1.0) - m1 * r1 * np.cos(th1)
        C1y = m2 * a1 * (r2 / a2 * np.sin(th2)) - m1 * r1 * np.sin(th1)
        C3x = -m2 * r2 * a3 / a2 * np.cos(th2) - m3 * r3 * np.cos(th3)
        C3y = -m2 * r2 * a3 / a2 * np.sin(th2) - m3 * r3 * np.sin(th3)
        S = np.hypot(C1x, C1y)
        S3 = np.hypot(C3x, C3y)
        J2A = I2 + m2 * r2 * r2
        V2x, V2y = m2 * r2 * np.cos(th2), m2 * r2 * np.sin(th2)
        U3x, U3y = m3 * r3 * np.cos(th3) + C3x, m3 * r3 * np.sin(th3) + C3y
        J3 = I3 + m3 * r3 * r3 + S3 * rc3
        # kinematics
        ax, ay = a1 * c1, a1 * s1
        dx, dy = a4 - ax, -ay
        iL2 = 1.0 / (dx * dx + dy * dy)
        q = (a2 * a2 - a3 * a3) * (0.5 * iL2) + 0.5
        hL = sigma * np.sqrt(np.maximum(a2 * a2 * iL2 - q * q, 0.0))
        ex, ey = q * dx - hL * dy, q * dy + hL * dx  # B - A
        c2, s2 = ex / a2, ey / a2
        c3, s3 = (ex - dx) / a3, (ey - dy) / a3
        D = c2 * s3 - s2 * c3
        w2 = -a1 * w1 * (c1 * s3 - s1 * c3) / (a2 * D)
        w3 = -a1 * w1 * (c1 * s2 - s1 * c2) / (a3 * D)
        w1s, w2s, w3s = w1 * w1, w2 * w2, w3 * w3
        kx = -a1 * w1s * c1 - a2 * w2s * c2 + a3 * w3s * c3
        ky = -a1 * w1s * s1 - a2 * w2s * s2 + a3 * w3s * s3
        al2 = -(kx * c3 + ky * s3) / (a2 * D)
        al3 = -(kx * c2 + ky * s2) / (a3 * D)
        # shaking moment after force balancing: -dH/dt (crank term J1 al1 = 0 at constant speed)
        aax, aay = -a1 * w1s * c1, -a1 * w1s * s1
        v2x, v2y = V2x * c2 - V2y * s2, V2x * s2 + V2y * c2
        ma2x = m2 * aax - al2 * v2y - w2s * v2x
        ma2y = m2 * aay + al2 * v2x - w2s * v2y
        u3x, u3y = U3x * c3 - U3y * s3, U3x * s3 + U3y * c3
        ma3y = al3 * u3x - w3s * u3y
        M = -((J2A * al2 + (ax * ma2y - ay * ma2x) + (v2x * aay - v2y * aax)) + (J3 * al3 + a4 * ma3y))
        # method 2: RMS-optimal axis O1 (x, y); constant speed and uniform positions: formula (1)
        cb, sb = C1x[:, 0] / S[:, 0], C1y[:, 0] / S[:, 0]
        k = S[:, 0] * w1[:, 0] ** 2
        smc, sms = M @ cos_phi, M @ sin_phi
        m_sin, m_cos = sms * cb + smc * sb, smc * cb - sms * sb
        sin2 = SUM_SS * cb * cb + 2.0 * SUM_SC * cb * sb + SUM_CC * sb * sb
        cos2 = SUM_CC * cb * cb - 2.0 * SUM_SC * cb * sb + SUM_SS * sb * sb
        x, y = -m_sin / (k * sin2), m_cos / (k * cos2)
        A, Bc = k * (x * cb + y * sb), k * (x * sb - y * cb)
        dM = M + (A[:, None] * s1 + Bc[:, None] * c1)
        m1max = np.abs(M).max(1)
        dmax = np.abs(dM).max(1)
        sl = slice(s, s + p.shape[0])
        res["M_rms_static"][sl] = np.sqrt((M * M).mean(1))
        res["M_max_static"][sl] = m1max
        res["axis_x"][sl] = x
        res["axis_y"][sl] = y
        res["dM_rms_axis"][sl] = np.sqrt((dM * dM).mean(1))
        res["dM_max_axis"][sl] = dmax
        res["R_axis"][sl] = (m1max - dmax) / m1max * 100.0
    return res
