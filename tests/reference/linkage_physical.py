"""An independent reference for every method that moves or adds a mass: the bodies (links,
counterweights, an added inertia) are placed where the method puts them, the joint positions
come from a closed form of their own (the law of cosines at O_B, not the kernels' circle
intersection), velocities and accelerations from exact derivatives in phi of those positions
(spectral differentiation of the smooth 2 pi-periodic positions on a fine uniform grid), and the
shaking moment and force from the definitions M = -dH_O/dt - g sum m x_G, F = -sum m a_G -
(0, g sum m), gravity included. tests/models/test_linkage_physical.py compares the models' outputs with it.
"""
from __future__ import annotations

import math

import numpy as np

from mechsweep.models import _linkage as L

PHYSICAL_OVERSAMPLE = 2  # grid points per model position (360 x 2 = 720 points per turn)


def periodic_derivatives(f: np.ndarray):
    """(d f / d phi, d2 f / d phi2) of a smooth 2 pi-periodic f (complex) sampled at
    phi_k = 2 pi k / n (spectral: exact to round-off once f's Fourier coefficients have decayed
    within n / 2; the round-off grows like n^2 for the second derivative, so n stays moderate)."""
    n = f.shape[-1]
    k = np.fft.fftfreq(n, 1.0 / n)
    F = np.fft.fft(f)
    if n % 2 == 0:
        k1 = k.copy()
        k1[n // 2] = 0.0  # the Nyquist mode has no first derivative on the grid
    else:
        k1 = k
    return np.fft.ifft(1j * k1 * F), np.fft.ifft(-(k * k) * F)


def physical_grid(n_positions: int = L.N_POSITIONS, oversample: int = PHYSICAL_OVERSAMPLE) -> np.ndarray:
    """phi_k = 2 pi k / (n_positions oversample): every oversample-th point is a model position."""
    return 2.0 * np.pi * np.arange(n_positions * oversample) / (n_positions * oversample)


def on_crank(c0, c1, phi):
    """(z, z', z'') of a point fixed to the crank, z = c0 + c1 e^{i phi} (exact derivatives)."""
    e1 = c1 * np.exp(1j * phi)
    return c0 + e1, 1j * e1, -e1


def body_loads(bodies, phi, omega, delta, g):
    """(M, Fx, Fy) of rigid bodies moving with the crank angle phi (the grid of physical_grid),
    phi' = omega (1 + delta sin phi): bodies = [(mass, centroidal inertia, z, u)], z the complex
    position of the centre of mass and u = e^{i angle} of the body at each phi, each an array or
    a tuple (value, d/dphi, d2/dphi2) of exact derivatives (bodies on the crank: on_crank). Every
    velocity is phi' times a derivative in phi, so H_O = phi' h(phi), h = sum m (z x z') +
    I (u x u'), and dH_O/dt = phi'' h + phi'^2 h' with h' = sum m (z x z'') + I (u x u'');
    a_G = phi'' z' + phi'^2 z'' (' = d/dphi, x the planar cross product Im(conj(a) b))."""
    w1 = omega * (1.0 + delta * np.sin(phi))
    al1 = w1 * omega * delta * np.cos(phi)
    h = np.zeros(phi.shape)
    dh = np.zeros(phi.shape)
    acc = np.zeros(phi.shape, dtype=complex)
    weight_moment = np.zeros(phi.shape)
    mass = 0.0

    def derivatives(f):
        if isinstance(f, tuple):
            return f
        f = np.broadcast_to(np.asarray(f, dtype=complex), phi.shape)
        return (f,) + tuple(periodic_derivatives(f))

    for m, I, z, u in bodies:
        if m != 0.0:
            z, dz, ddz = derivatives(z)
            h += m * np.imag(np.conj(z) * dz)
            dh += m * np.imag(np.conj(z) * ddz)
            acc += m * (al1 * dz + w1 * w1 * ddz)
            weight_moment -= g * m * z.real
            mass += m
        if I != 0.0:
            u, du, ddu = derivatives(u)
            h += I * np.imag(np.conj(u) * du)
            dh += I * np.imag(np.conj(u) * ddu)
    M = -(al1 * h + w1 * w1 * dh) + weight_moment
    return M, -acc.real, -acc.imag - g * mass


def fourbar_joints(a1, a2, a3, a4, sigma, phi):
    """(A, B) complex joint positions of the four-bar: A = a1 e^{i phi}; B from the triangle
    O_B A B by the law of cosines at O_B, on the side sigma of the directed line A -> O_B."""
    A = a1 * np.exp(1j * phi)
    v = A - a4
    Lv = np.abs(v)
    gamma = np.arccos(np.clip((a3 * a3 + Lv * Lv - a2 * a2) / (2.0 * a3 * Lv), -1.0, 1.0))
    B = [a4 + a3 * np.exp(1j * (np.angle(v) + s * gamma)) for s in (1.0, -1.0)]
    left = [np.imag(np.conj(a4 - A) * (b - A)) for b in B]  # > 0: B left of A -> O_B
    return A, np.where(np.sign(left[0]) == sigma, B[0], B[1])


def fourbar_physical(p, phi, cw1=(0.0, 0.0), cw3=(0.0, 0.0), axis=0.0 + 0.0j, J_rocker=0.0):
    """(M, Fx, Fy) on the grid phi of four-bar row p (FOURBAR_PARAMS) with point-mass counterweights
    cw1 = (m r, angle from the crank) at radius r_cw1 turning with the crank about the point
    ``axis`` (complex; 0: the crank axis O_A), cw3 = (m r, angle from the rocker) at r_cw3 on the
    rocker, and a massless inertia J_rocker turning with the rocker."""
    a1, a2, a3, a4 = p[L.P_A1], p[L.P_A2], p[L.P_A3], p[L.P_A4]
    sigma = 1.0 if p[L.P_BRANCH] == 0.0 else -1.0
    r_cw1 = p[L.P_RCW1] if not math.isnan(p[L.P_RCW1]) else a1
    r_cw3 = p[L.P_RCW3] if not math.isnan(p[L.P_RCW3]) else a3
    A, Bj = fourbar_joints(a1, a2, a3, a4, sigma, phi)
    e1, e2, e3 = np.exp(1j * phi), (Bj - A) / a2, (Bj - a4) / a3
    crank = on_crank(0.0, 1.0, phi)
    bodies = [
        (p[L.P_M1], p[L.P_I1], on_crank(0.0, p[L.P_R1] * np.exp(1j * p[L.P_TH1]), phi), crank),
        (cw1[0] / r_cw1, 0.0, on_crank(axis, r_cw1 * np.exp(1j * cw1[1]), phi), crank),
        (p[L.P_M2], p[L.P_I2], A + p[L.P_R2] * np.exp(1j * p[L.P_TH2]) * e2, e2),
        (p[L.P_M3], p[L.P_I3], a4 + p[L.P_R3] * np.exp(1j * p[L.P_TH3]) * e3, e3),
        (cw3[0] / r_cw3, 0.0, a4 + r_cw3 * np.exp(1j * cw3[1]) * e3, e3),
        (0.0, J_rocker, a4 + 0j, e3),
    ]
    return body_loads(bodies, phi, p[L.P_OMEGA], p[L.P_DELTA], p[L.P_G])


def slider_physical(p, phi, cw=(0.0, 0.0)):
    """(M, Fx, Fy) on the grid phi of slider-crank row p (SLIDER_PARAMS) with a point-mass crank
    counterweight cw = (m r, angle from the crank) at radius r_cw: slider on y = e,
    x_B = r cos phi + sigma sqrt(l^2 - (e - r sin phi)^2)."""
    r, e = p[L.S_R], p[L.S_E]
    l = p[L.S_L] if not math.isnan(p[L.S_L]) else r / p[L.S_LAM]
    sigma = 1.0 if p[L.S_BRANCH] == 0.0 else -1.0
    r_cw = p[L.S_RCW] if not math.isnan(p[L.S_RCW]) else r
    e1 = np.exp(1j * phi)
    A = r * e1
    Bj = r * np.cos(phi) + sigma * np.sqrt(l * l - (e - r * np.sin(phi)) ** 2) + 1j * e
    e2 = (Bj - A) / l
    crank = on_crank(0.0, 1.0, phi)
    bodies = [
        (p[L.S_M1], p[L.S_I1], on_crank(0.0, p[L.S_R1] * np.exp(1j * p[L.S_TH1]), phi), crank),
        (cw[0] / r_cw, 0.0, on_crank(0.0, r_cw * np.exp(1j * cw[1]), phi), crank),
        (p[L.S_M2], p[L.S_I2], A + p[L.S_R2] * np.exp(1j * p[L.S_TH2]) * e2, e2),
        (p[L.S_M3], 0.0, Bj, np.ones_like(e1)),
    ]
    return body_loads(bodies, phi, p[L.S_OMEGA], p[L.S_DELTA], p[L.S_G])


def brute_force_minimum(f, start, scale, smallest: float = 1e-10, max_evaluations: int = 20000):
    """(x, y, f) minimising f(x, y) by a grid (pattern) search that uses nothing of f's form: the
    3 x 3 grid of spacing h around the best point so far; move to its best point, or halve h
    when the centre is best; from h = scale down to smallest * scale. For a convex f it ends
    within h of the minimiser (up to f's own round-off near the minimum)."""
    x, y = float(start[0]), float(start[1])
    fc = f(x, y)
    h = float(scale)
    n = 1
    while h > smallest * scale and n < max_evaluations:
        best = (fc, x, y)
        for i in (-1, 0, 1):
            for j in (-1, 0, 1):
                if i or j:
                    v = f(x + i * h, y + j * h)
                    n += 1
                    if v < best[0]:
                        best = (v, x + i * h, y + j * h)
        if best[1] == x and best[2] == y:
            h *= 0.5
        else:
            fc, x, y = best
    return x, y, fc
