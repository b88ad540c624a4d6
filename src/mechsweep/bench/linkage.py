"""`mechsweep bench linkage`: four-bar residual sweep, mechsweep against vectorised numpy, same run.

The computation (per design, 360 crank positions phi_i = 2 pi i / 360, constant crank speed):
closed-form four-bar kinematics (positions, velocities, accelerations), counterweights for
complete shaking-force balancing (method 1), the shaking moment M(phi) that balancing leaves,
the RMS-optimal axis of the crank counterweight from the 2x2 normal equations (method 2), the
residual dM(phi), its RMS and maximum and the efficiency R against static balancing: the outputs
M_rms_static, M_max_static, axis_x, axis_y, dM_rms_axis, dM_max_axis, R_axis of the model
``fourbar_balancing``. numpy does exactly that on [designs, 360] arrays (blocks of 64 designs, its fastest size here;
the same closed forms, formula (1) for the axis as the kernel uses at constant speed, no Python
loop over positions); the two must agree to round-off (checked).

Designs: a random family of Grashof crank-rockers (coupler, rocker and frame lengths, coupler
mass, centre and inertia varied). mechsweep runs on ``threads`` numba threads (default: all,
2 on the reference machine), numpy on one core as numpy elementwise code does.
"""
from __future__ import annotations

import math
import time

import numpy as np

from .. import status as st
from ..models import _linkage as L
from ..models import fourbar_balancing as fb
from ..runner import _threads

OUTPUTS = ("M_rms_static", "M_max_static", "axis_x", "axis_y", "dM_rms_axis", "dM_max_axis", "R_axis")


def design_family(n: int, seed: int = 0) -> np.ndarray:
    """[n, params] rows of a random family of Grashof crank-rockers (all OK)."""
    rng = np.random.default_rng(seed)
    P = np.empty((n, len(L.FOURBAR_PARAMS)))
    base = dict(a1=0.1, a2=0.35, a3=0.3, a4=0.4, branch=0.0, m1=1.0, r1=0.03, theta1=0.0, I1=1e-3,
                m2=2.0, r2=0.175, theta2=0.0, I2=0.02, m3=1.5, r3=0.15, theta3=0.0, I3=0.011,
                omega=20.0, delta=0.0, g=0.0, M_load=0.0, cw1_mr=0.0, cw1_angle=0.0, r_cw1=0.1,
                cw3_mr=0.0, cw3_angle=0.0, r_cw3=0.3)
    for k, v in base.items():
        P[:, L.FOURBAR_PARAMS.index(k)] = v
    col = L.FOURBAR_PARAMS.index
    P[:, col("a2")] = rng.uniform(0.30, 0.45, n)
    P[:, col("a3")] = rng.uniform(0.25, 0.40, n)
    P[:, col("a4")] = rng.uniform(0.35, 0.45, n)
    P[:, col("m2")] = rng.uniform(1.0, 3.0, n)
    P[:, col("r2")] = P[:, col("a2")] * rng.uniform(0.3, 0.7, n)
    P[:, col("theta2")] = rng.uniform(-0.3, 0.3, n)
    P[:, col("I2")] = P[:, col("m2")] * P[:, col("a2")] ** 2 / 12
    P[:, col("branch")] = rng.integers(0, 2, n)
    return P


def numpy_residuals(P: np.ndarray, block: int = 64, n_positions: int = L.N_POSITIONS) -> dict:
    """The same computation as the mechsweep kernel, vectorised with numpy over [designs, N]
    (N = n_positions uniform crank positions, 360 as in sweeps). Constant crank speed and no
    gravity only (delta = 0, g = 0): a ValueError otherwise."""
    for name in ("delta", "g"):
        if np.any(P[:, L.FOURBAR_PARAMS.index(name)] != 0.0):
            raise ValueError(f"the numpy four-bar residuals assume {name} = 0 (constant speed, no gravity)")
    n = P.shape[0]
    res = {k: np.empty(n) for k in OUTPUTS}
    cos_phi, sin_phi, sums = fb.positions(n_positions)
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


def mechsweep_residuals(P: np.ndarray) -> tuple[dict, np.ndarray]:
    n = P.shape[0]
    out = {k: np.full(n, np.nan) for k in OUTPUTS}
    status = np.zeros(n, dtype=st.DTYPE)
    fb.evaluate(P, OUTPUTS, None, out, status, None, None)
    return out, status


def _best(fn, repeats):
    best, result = math.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result


def main(designs: int = 200_000, numpy_designs: int = 20_000, threads: int | None = 2,
         repeats: int = 3, seed: int = 0) -> dict:
    """Measure designs/s of mechsweep (``threads`` numba threads) and of numpy (one core) on the
    four-bar residual sweep, print them and the ratio, and return them as a dict."""
    import os

    import numba

    from . import _args

    designs = _args.count("designs", designs)
    numpy_designs = _args.count("numpy_designs", numpy_designs, 1, designs)
    repeats = _args.count("repeats", repeats, 1, 1000)
    if threads is not None:
        threads = min(_args.count("threads", threads, 1, 10**6), numba.config.NUMBA_NUM_THREADS)
    load_before = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    P = design_family(designs, seed)
    with _threads(threads):
        n_threads = numba.get_num_threads()
        t0 = time.perf_counter()
        mechsweep_residuals(P[:8])
        compile_s = time.perf_counter() - t0  # JIT compile or cache load
        ours_s, (ours, status) = _best(lambda: mechsweep_residuals(P), repeats)
        with _threads(1):
            one_s, _ = _best(lambda: mechsweep_residuals(P[:numpy_designs * 2]), repeats)
    Pn = P[:numpy_designs]
    numpy_s, ref = _best(lambda: numpy_residuals(Pn), repeats)
    worst = 0.0
    for k in OUTPUTS:
        a, b = ours[k][:numpy_designs], ref[k]
        worst = max(worst, float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300 + np.abs(b).max() * 1e-12))))
    r = {
        "designs": designs,
        "positions_per_design": L.N_POSITIONS,
        "threads": n_threads,
        "compile_or_cache_load_s": compile_s,
        "designs_per_s": designs / ours_s,
        "designs_per_s_one_thread": 2 * numpy_designs / one_s,
        "numpy_designs": numpy_designs,
        "numpy_designs_per_s": numpy_designs / numpy_s,
        "ratio": (designs / ours_s) / (numpy_designs / numpy_s),
        "ratio_one_thread": (2 * numpy_designs / one_s) / (numpy_designs / numpy_s),
        "max_rel_difference": worst,
        "ok_fraction": float((status == st.OK).mean()),
        "load_average_before": load_before,  # other work on the machine lowers the thread speed-up
    }
    r["positions_per_s"] = r["designs_per_s"] * L.N_POSITIONS
    _print(r)
    return r


def _print(r: dict) -> None:
    print("mechsweep bench linkage: four-bar residual sweep (kinematics, complete force balancing, "
          f"RMS-optimal counterweight axis, residual RMS/max, efficiency), {r['positions_per_design']} "
          "positions per design")
    print(f"  designs: {r['designs']:,} random Grashof crank-rockers; {r['ok_fraction'] * 100:.1f}% ok; "
          f"first call (JIT compile or cache load) {r['compile_or_cache_load_s']:.2f} s")
    print(f"  mechsweep: {r['designs_per_s']:>12,.0f} designs/s on {r['threads']} threads "
          f"({r['positions_per_s'] / 1e6:.1f} M positions/s); {r['designs_per_s_one_thread']:,.0f} on 1 thread")
    print(f"  numpy    : {r['numpy_designs_per_s']:>12,.0f} designs/s on 1 core ({r['numpy_designs']:,} designs, "
          "blocks of 64 x 360)")
    print(f"  ratio mechsweep / numpy: {r['ratio']:.1f}x ({r['ratio_one_thread']:.1f}x thread for core); "
          f"max relative difference {r['max_rel_difference']:.1e}")
    print(f"  (load average before the run: {r['load_average_before']:.2f}; other processes on the cores "
          "lower the speed-up of the threads)")
