"""Four-bar and slider-crank kernels: kinematics, loads and balancing methods against independent
references (finite differences of positions, energy balance, -dH/dt, a Newton-Euler solve,
brute-force least squares), statuses, Hypothesis properties, jitted vs pure Python."""
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as hs

import mechsweep
from mechsweep import balancing as B
from mechsweep import models
from mechsweep import status as st
from mechsweep.models import _linkage as L
from mechsweep.models import fourbar_balancing as fb
from mechsweep.models import slidercrank_balancing as sc

# a crank-rocker with every centre of mass off its link line and given counterweights
GEO = dict(a1=0.1, a2=0.35, a3=0.3, a4=0.4, m1=1.0, r1=0.05, theta1=0.3, I1=1e-3,
           m2=2.0, r2=0.175, theta2=0.2, I2=0.02, m3=1.5, r3=0.15, theta3=-0.4, I3=0.011,
           g=9.81, M_load=3.0, cw1_mr=0.05, cw1_angle=2.0, cw3_mr=0.1, cw3_angle=3.0, r_cw1=0.08)
SLIDER = dict(r=0.05, l=0.2, e=0.01, m1=1.0, r1=0.02, theta1=0.3, I1=1e-3, m2=0.8, r2=0.06, theta2=0.1,
              I2=3e-3, m3=0.6, g=9.81, F_load=-50.0, k=0.5, r_cw=0.04)


def motion(t):
    """A non-uniform crank motion: phi, phi', phi''."""
    return 0.3 + 20 * t + 0.4 * np.sin(7 * t), 20 + 2.8 * np.cos(7 * t), -19.6 * np.sin(7 * t)


T_GRID = np.linspace(0.0, 0.5, 10001)
DT = T_GRID[1] - T_GRID[0]
INNER = slice(10, -10)


def d_dt(x):
    return np.gradient(x, DT, edge_order=2)


def rel_err(a, b):
    return np.max(np.abs(a - b)[INNER]) / np.max(np.abs(b)[INNER])


def cis(r, angle):
    return r * np.cos(angle), r * np.sin(angle)


def fourbar_bodies(geo, c, phi, counterweights):
    """(mass, centroidal inertia, x_G, y_G, angular velocity) of every moving body, built from the
    link angles alone (counterweights: point masses, dict cw1_mr, cw1_angle, cw3_mr, cw3_angle)."""
    a1, a4 = geo["a1"], geo["a4"]
    r_cw1, r_cw3 = geo.get("r_cw1", a1), geo.get("r_cw3", geo["a3"])
    w1 = d_dt(phi)
    w2, w3 = d_dt(np.unwrap(c["phi2"])), d_dt(np.unwrap(c["phi3"]))
    ax, ay = cis(a1, phi)
    out = []
    x, y = cis(geo["r1"], phi + geo.get("theta1", 0.0))
    out.append((geo["m1"], geo["I1"], x, y, w1))
    x, y = cis(r_cw1, phi + counterweights["cw1_angle"])
    out.append((counterweights["cw1_mr"] / r_cw1, 0.0, x, y, w1))
    x, y = cis(geo["r2"], c["phi2"] + geo.get("theta2", 0.0))
    out.append((geo["m2"], geo["I2"], ax + x, ay + y, w2))
    x, y = cis(geo["r3"], c["phi3"] + geo.get("theta3", 0.0))
    out.append((geo["m3"], geo["I3"], a4 + x, y, w3))
    x, y = cis(r_cw3, c["phi3"] + counterweights["cw3_angle"])
    out.append((counterweights["cw3_mr"] / r_cw3, 0.0, a4 + x, y, w3))
    return out


def momenta(bodies, g):
    """Kinetic + potential energy, angular momentum about the origin, linear momentum, total mass
    and moment of the weights about the origin; velocities by finite differences of positions."""
    E = H = Px = Py = M_g = 0.0
    m_tot = 0.0
    for m, I, x, y, om in bodies:
        vx, vy = d_dt(x), d_dt(y)
        E = E + 0.5 * m * (vx ** 2 + vy ** 2) + 0.5 * I * om ** 2 + m * g * y
        H = H + m * (x * vy - y * vx) + I * om
        Px, Py = Px + m * vx, Py + m * vy
        M_g = M_g - g * m * x
        m_tot += m
    return E, H, Px, Py, m_tot, M_g


# ============================================================================= four-bar kinematics and loads
@pytest.mark.parametrize("branch", ["open", "crossed"])
def test_fourbar_positions_close_the_loop_on_the_chosen_side(branch):
    phi = np.linspace(0, 2 * np.pi, 73)
    c, code = B.fourbar_curves(phi, 1.0, 0.0, branch=branch, **GEO)
    assert code == st.OK
    a1, a2, a3, a4 = (GEO[k] for k in ("a1", "a2", "a3", "a4"))
    bx = a1 * np.cos(phi) + a2 * np.cos(c["phi2"])
    by = a1 * np.sin(phi) + a2 * np.sin(c["phi2"])
    np.testing.assert_allclose(bx, a4 + a3 * np.cos(c["phi3"]), atol=1e-15)
    np.testing.assert_allclose(by, a3 * np.sin(c["phi3"]), atol=1e-15)
    # side of B relative to the directed line A -> O_B: left (+) for open, right (-) for crossed
    cross = (a4 - a1 * np.cos(phi)) * (by - a1 * np.sin(phi)) - (-a1 * np.sin(phi)) * (bx - a1 * np.cos(phi))
    assert np.all(np.sign(cross) == (1 if branch == "open" else -1))


@pytest.mark.parametrize("branch", ["open", "crossed"])
def test_fourbar_velocities_accelerations_against_finite_differences(branch):
    phi, w, al = motion(T_GRID)
    c, code = B.fourbar_curves(phi, w, al, branch=branch, **GEO)
    assert code == st.OK
    assert rel_err(d_dt(np.unwrap(c["phi2"])), c["omega2"]) < 1e-6
    assert rel_err(d_dt(np.unwrap(c["phi3"])), c["omega3"]) < 1e-6
    assert rel_err(d_dt(c["omega2"]), c["alpha2"]) < 1e-6
    assert rel_err(d_dt(c["omega3"]), c["alpha3"]) < 1e-6


@pytest.mark.parametrize("branch", ["open", "crossed"])
def test_fourbar_loads_against_energy_balance_and_momenta(branch):
    """input power T phi' + M_load phi3' = d(E_kin + V)/dt; M = -dH/dt + moment of the weights;
    F = -dP/dt - weight; all from positions alone (velocities by finite differences)."""
    phi, w, al = motion(T_GRID)
    c, code = B.fourbar_curves(phi, w, al, branch=branch, **GEO)
    assert code == st.OK
    E, H, Px, Py, m_tot, M_g = momenta(fourbar_bodies(GEO, c, phi, GEO), GEO["g"])
    power = c["T"] * w + GEO["M_load"] * c["omega3"]
    assert rel_err(d_dt(E), power) < 1e-5
    assert rel_err(-d_dt(H) + M_g, c["M"]) < 1e-5
    assert rel_err(-d_dt(Px), c["Fx"]) < 1e-5
    assert rel_err(-d_dt(Py) - m_tot * GEO["g"], c["Fy"]) < 1e-5


def newton_euler(geo, phi, w1, al1, branch="open"):
    """Joint forces and input torque from the 9 Newton-Euler equations of the three links (an
    independent route to T and to the forces and moment on the frame). Returns (T, Fx, Fy, M)."""
    c, _ = B.fourbar_curves(np.array([phi]), w1, al1, branch=branch, **geo)
    a1, a4 = geo["a1"], geo["a4"]
    g = np.array([0.0, -geo["g"]])
    p2, p3 = c["phi2"][0], c["phi3"][0]
    w2, w3, al2, al3 = (c[k][0] for k in ("omega2", "omega3", "alpha2", "alpha3"))

    def cross(u, v):
        return u[0] * v[1] - u[1] * v[0]

    def acc(p, w, al):  # acceleration of a point p (relative to a fixed pivot) of a turning link
        return al * np.array([-p[1], p[0]]) - w * w * p

    # crank with its counterweight, about O_A
    rc1, rc3 = geo.get("r_cw1", a1), geo.get("r_cw3", geo["a3"])
    m1c = geo["cw1_mr"] / rc1
    G1 = (geo["m1"] * np.array(cis(geo["r1"], phi + geo["theta1"]))
          + m1c * np.array(cis(rc1, phi + geo["cw1_angle"]))) / (geo["m1"] + m1c)
    M1 = geo["m1"] + m1c
    J1 = geo["I1"] + geo["m1"] * geo["r1"] ** 2 + m1c * rc1 ** 2
    A = np.array(cis(a1, phi))
    aA = acc(A, w1, al1)
    G2 = A + np.array(cis(geo["r2"], p2 + geo["theta2"]))
    aG2 = aA + acc(G2 - A, w2, al2)
    Bp = A + np.array(cis(geo["a2"], p2))
    OB = np.array([a4, 0.0])
    m3c = geo["cw3_mr"] / rc3
    M3 = geo["m3"] + m3c
    G3 = OB + (geo["m3"] * np.array(cis(geo["r3"], p3 + geo["theta3"]))
               + m3c * np.array(cis(rc3, p3 + geo["cw3_angle"]))) / M3
    J3 = geo["I3"] + geo["m3"] * geo["r3"] ** 2 + m3c * rc3 ** 2
    # unknowns: R01 (frame on crank at O_A), R12 (crank on coupler at A), R23 (coupler on rocker
    # at B), R03 (frame on rocker at O_B), T (motor on crank)
    Aq = np.zeros((9, 9))
    b = np.zeros(9)
    Aq[0:2, 0:2] = np.eye(2)
    Aq[0:2, 2:4] = -np.eye(2)
    b[0:2] = M1 * acc(G1, w1, al1) - M1 * g
    Aq[2, 2:4] = [A[1], -A[0]]  # moment of -R12 at A about O_A: -cross(A, R12)
    Aq[2, 8] = 1.0
    b[2] = J1 * al1 - cross(G1, M1 * g)
    Aq[3:5, 2:4] = np.eye(2)
    Aq[3:5, 4:6] = -np.eye(2)
    b[3:5] = geo["m2"] * aG2 - geo["m2"] * g
    ra, rb = A - G2, Bp - G2
    Aq[5, 2:4] = [-ra[1], ra[0]]
    Aq[5, 4:6] = [rb[1], -rb[0]]
    b[5] = geo["I2"] * al2
    Aq[6:8, 4:6] = np.eye(2)
    Aq[6:8, 6:8] = np.eye(2)
    b[6:8] = M3 * acc(G3 - OB, w3, al3) - M3 * g
    rB = Bp - OB
    Aq[8, 4:6] = [-rB[1], rB[0]]
    b[8] = J3 * al3 - cross(G3 - OB, M3 * g) - geo["M_load"]
    x = np.linalg.solve(Aq, b)
    R01, R03, T = x[0:2], x[6:8], x[8]
    F = -(R01 + R03)
    # on the frame: -R01 at O_A, -R03 at O_B, the stator reaction -T, the process reaction -M_load
    M = -T - cross(OB, R03) - geo["M_load"]
    return T, F[0], F[1], M


@pytest.mark.parametrize("branch", ["open", "crossed"])
def test_fourbar_loads_against_newton_euler(branch):
    for phi, w1, al1 in [(0.0, 20.0, 0.0), (1.1, 15.0, 40.0), (2.5, 30.0, -100.0), (4.4, 5.0, 3.0)]:
        c, _ = B.fourbar_curves(np.array([phi]), w1, al1, branch=branch, **GEO)
        T, Fx, Fy, M = newton_euler(GEO, phi, w1, al1, branch)
        assert c["T"][0] == pytest.approx(T, rel=1e-11, abs=1e-11)
        assert c["Fx"][0] == pytest.approx(Fx, rel=1e-11, abs=1e-11)
        assert c["Fy"][0] == pytest.approx(Fy, rel=1e-11, abs=1e-11)
        assert c["M"][0] == pytest.approx(M, rel=1e-11, abs=1e-11)


def evaluate1(model, outputs, **params):
    """B.evaluate with a leading design axis even for scalar parameters."""
    out, status = B.evaluate(model, outputs, **params)
    n = status.size
    return {k: v.reshape((n,) + v.shape[status.ndim:]) for k, v in out.items()}, status.reshape(n)


def fourbar_outputs(outputs, **kw):
    params = dict(GEO, omega=20.0)
    params.update(kw)
    out, status = evaluate1("fourbar_balancing", outputs, **params)
    return {k: v[0] for k, v in out.items()}, status


@pytest.mark.parametrize("delta", [0.0, 0.3])
def test_sweep_kernel_matches_the_position_function(delta):
    """The vectorised cycle loops of the sweep kernel against fourbar_curves at the model's
    positions (the same formulas, so to round-off), and its statistics against numpy's."""
    params = dict(GEO, omega=20.0, delta=delta)
    names = ["Fx_phi", "Fy_phi", "M_phi", "T_phi", "M_static_phi", "T_static_phi", "Fx_range", "Fy_rms",
             "M_max", "T_range", "F_max", "M_rms_static", "T_range_static", "F_max_static"]
    out, status = evaluate1("fourbar_balancing", names, **params)
    assert status[0] == st.OK
    w1 = 20.0 * (1 + delta * np.sin(B.PHI))
    al1 = w1 * 20.0 * delta * np.cos(B.PHI)
    given, _ = B.fourbar_curves(B.PHI, w1, al1, **params)
    static, _ = B.fourbar_curves(B.PHI, w1, al1, static=True, **params)
    for name, ref in [("Fx_phi", given["Fx"]), ("Fy_phi", given["Fy"]), ("M_phi", given["M"]),
                      ("T_phi", given["T"]), ("M_static_phi", static["M"]), ("T_static_phi", static["T"])]:
        np.testing.assert_allclose(out[name][0], ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    assert out["Fx_range"][0] == pytest.approx(np.ptp(given["Fx"]), rel=1e-12)
    assert out["Fy_rms"][0] == pytest.approx(np.sqrt(np.mean(given["Fy"] ** 2)), rel=1e-12)
    assert out["M_max"][0] == pytest.approx(np.abs(given["M"]).max(), rel=1e-12)
    assert out["T_range"][0] == pytest.approx(np.ptp(given["T"]), rel=1e-12)
    assert out["F_max"][0] == pytest.approx(np.hypot(given["Fx"], given["Fy"]).max(), rel=1e-12)
    assert out["M_rms_static"][0] == pytest.approx(np.sqrt(np.mean(static["M"] ** 2)), rel=1e-12)
    assert out["T_range_static"][0] == pytest.approx(np.ptp(static["T"]), rel=1e-12)
    assert out["F_max_static"][0] < 1e-12 * out["F_max"][0]
    # asked alone, the moment takes the cheaper moment-only loop: the same numbers
    alone, _ = evaluate1("fourbar_balancing", ["M_static_phi", "M_max_static"], **params)
    np.testing.assert_array_equal(alone["M_static_phi"][0], out["M_static_phi"][0])


def test_kinematics_cycle_is_the_position_function_term_for_term():
    buf = np.empty((L.N_BUF, L.N_POSITIONS))
    L.fourbar_kinematics_cycle(0.1, 0.35, 0.3, 0.4, -1.0, 20.0, 0.4, L.COS_PHI, L.SIN_PHI, buf)
    for j in (0, 17, 90, 181, 359):
        w1, al1 = L.crank_speed(20.0, 0.4, L.COS_PHI[j], L.SIN_PHI[j])
        ref = L.fourbar_position(0.1, 0.35, 0.3, 0.4, -1.0, L.COS_PHI[j], L.SIN_PHI[j], w1, al1)
        got = [buf[r, j] for r in (L.R_C2, L.R_S2, L.R_C3, L.R_S3, L.R_W2, L.R_W3, L.R_AL2, L.R_AL3)]
        np.testing.assert_allclose(got, ref[:8], rtol=4e-16, atol=1e-300)


# ============================================================================= method 1: complete force balancing
@pytest.mark.parametrize("branch", ["open", "crossed"])
def test_complete_force_balancing_keeps_the_centre_of_mass_still(branch):
    phi, w, al = motion(T_GRID[::10])
    c, code = B.fourbar_curves(phi, w, al, branch=branch, static=True, **GEO)
    cw = B.fourbar_counterweights(*(GEO[k] for k in ("a1", "a2", "a3", "m1", "r1", "m2", "r2", "m3", "r3")),
                                  GEO["theta1"], GEO["theta2"], GEO["theta3"])
    bodies = fourbar_bodies(GEO, c, phi, cw)
    sx = sum(m * x for m, _, x, _, _ in bodies)
    sy = sum(m * y for m, _, _, y, _ in bodies)
    scale = sum(m for m, *_ in bodies) * GEO["a4"]
    assert np.ptp(sx) < 1e-14 * scale and np.ptp(sy) < 1e-14 * scale
    # ... and without the counterweights it moves
    bare = fourbar_bodies(GEO, c, phi, dict(cw1_mr=0.0, cw1_angle=0.0, cw3_mr=0.0, cw3_angle=0.0))
    assert np.ptp(sum(m * x for m, _, x, _, _ in bare)) > 1e-3 * scale
    # the shaking force left is the static weight only
    assert np.abs(c["Fx"]).max() < 1e-12 * scale * 400
    np.testing.assert_allclose(c["Fy"], -GEO["g"] * sum(m for m, *_ in bodies), rtol=1e-13)


def test_counterweights_are_the_linearly_independent_vectors_formula():
    g = GEO
    u2 = g["r2"] * np.exp(1j * g["theta2"])
    C1 = g["m2"] * g["a1"] * (u2 / g["a2"] - 1) - g["m1"] * g["r1"] * np.exp(1j * g["theta1"])
    C3 = -g["m2"] * u2 * g["a3"] / g["a2"] - g["m3"] * g["r3"] * np.exp(1j * g["theta3"])
    out, status = fourbar_outputs(["cw1_mr_static", "cw1_angle_static", "cw3_mr_static", "cw3_angle_static",
                                   "cw_mass_static", "mass_ratio_static"])
    assert out["cw1_mr_static"] == pytest.approx(abs(C1), rel=1e-14)
    assert out["cw1_angle_static"] == pytest.approx(np.angle(C1), rel=1e-14)
    assert out["cw3_mr_static"] == pytest.approx(abs(C3), rel=1e-14)
    assert out["cw3_angle_static"] == pytest.approx(np.angle(C3), rel=1e-14)
    m_cw = abs(C1) / g["r_cw1"] + abs(C3) / g["a3"]
    assert out["cw_mass_static"] == pytest.approx(m_cw, rel=1e-14)
    assert out["mass_ratio_static"] == pytest.approx(1 + m_cw / (g["m1"] + g["m2"] + g["m3"]), rel=1e-14)


# ============================================================================= method 2: moving the counterweight axis
def test_axis_moment_is_the_change_of_minus_dH_dt():
    """Turning the crank counterweight about O1 = (x, y) instead of O_A changes the shaking moment
    by axis_moment (the physics.md section 3 formula), computed here from positions alone."""
    phi, w, al = motion(T_GRID)
    geo = dict(GEO, g=0.0)
    c, _ = B.fourbar_curves(phi, w, al, static=True, **geo)
    cw = B.fourbar_counterweights(*(geo[k] for k in ("a1", "a2", "a3", "m1", "r1", "m2", "r2", "m3", "r3")),
                                  geo["theta1"], geo["theta2"], geo["theta3"])
    x, y = 0.07, -0.05
    bodies = fourbar_bodies(geo, c, phi, cw)
    m, I, bx, by, om = bodies[1]  # the crank counterweight: move it to O1
    bodies[1] = (m, I, bx + x, by + y, om)
    _, H, Px, Py, _, _ = momenta(bodies, 0.0)
    dM = B.axis_moment(phi, x, y, cw["cw1_mr"], w, phi_dd=al, cw_angle=cw["cw1_angle"])
    assert rel_err(-d_dt(H), c["M"] + dM) < 1e-5
    assert np.abs(d_dt(Px))[INNER].max() < 1e-5 * np.abs(dM).max()  # still force-balanced


def test_rms_axis_offset_against_brute_force_least_squares():
    rng = np.random.default_rng(1)
    phi = np.sort(rng.uniform(0, 2 * np.pi, 50))  # non-uniform positions
    M = 3 * np.cos(phi) - 2 * np.sin(2 * phi) + rng.normal(0, 0.3, phi.size)
    w = 10 + 2 * np.sin(phi)
    al = 10 * w * 0.2 * np.cos(phi)
    S, beta = 0.7, 2.5
    x, y = B.rms_axis_offset(phi, M, S, w, phi_dd=al, cw_angle=beta)
    G = np.stack([B.axis_moment(phi, 1, 0, S, w, phi_dd=al, cw_angle=beta),
                  B.axis_moment(phi, 0, 1, S, w, phi_dd=al, cw_angle=beta)], axis=1)
    ref = np.linalg.lstsq(G, -M, rcond=None)[0]
    assert (x, y) == pytest.approx(tuple(ref), rel=1e-12)
    # the optimum: any other axis leaves a larger sum of squares
    best = np.sum((M + G @ ref) ** 2)
    for dx, dy in [(1e-3, 0), (0, 1e-3), (-1e-3, 1e-3)]:
        assert np.sum((M + G @ (ref + [dx, dy])) ** 2) > best


def test_formula1_equals_normal_equations_only_for_symmetric_uniform_positions():
    rng = np.random.default_rng(2)
    phi = 2 * np.pi * np.arange(36) / 36
    M = 5 * np.cos(phi + 0.4) + np.cos(3 * phi) + rng.normal(0, 0.1, 36)
    for beta in (np.pi, 2.0):
        normal = B.rms_axis_offset(phi, M, 0.3, 12.0, cw_angle=beta)
        f1 = B.rms_axis_offset(phi, M, 0.3, 12.0, cw_angle=beta, method="formula1")
        assert f1 == pytest.approx(normal, rel=1e-12)
    # the printed form (beta = pi): x = sum M sin / (S w^2 sum sin^2), y = -sum M cos / (S w^2 sum cos^2)
    x, y = B.rms_axis_offset(phi, M, 0.3, 12.0, method="formula1")
    assert x == pytest.approx(np.sum(M * np.sin(phi)) / (0.3 * 144 * np.sum(np.sin(phi) ** 2)), rel=1e-13)
    assert y == pytest.approx(-np.sum(M * np.cos(phi)) / (0.3 * 144 * np.sum(np.cos(phi) ** 2)), rel=1e-13)
    # positions crowded in one quadrant: sum sin cos != 0 and formula (1) is no longer the optimum
    phi = np.linspace(0.1, 1.5, 30)
    M = 5 * np.cos(phi + 0.4)
    normal = np.array(B.rms_axis_offset(phi, M, 0.3, 12.0))
    f1 = np.array(B.rms_axis_offset(phi, M, 0.3, 12.0, method="formula1"))
    assert np.abs(f1 - normal).max() > 1e-2 * np.abs(normal).max()


def test_first_harmonic_and_rms_axes_coincide_only_for_uniform_positions_and_constant_speed():
    """physics.md section 3: the least-squares first harmonic at uniform positions is the DFT
    coefficient, so the methods differ only through phi'' != 0, non-uniform positions or gravity
    (the moved counterweight's weight adds a constant -W x, which the RMS optimum uses against the
    moment's mean and the first harmonic does not see)."""
    out, status = fourbar_outputs(["axis_x", "axis_y", "axis_x_h1", "axis_y_h1", "R_axis", "R_h1",
                                   "dM_rms_axis", "dM_rms_h1", "M_rms_static"], g=0.0)
    assert status[0] == st.OK
    assert out["axis_x_h1"] == pytest.approx(out["axis_x"], rel=1e-12)
    assert out["axis_y_h1"] == pytest.approx(out["axis_y"], rel=1e-12)
    assert out["R_h1"] == pytest.approx(out["R_axis"], rel=1e-10)
    # gravity: y (the first harmonic alone) agrees, x differs and the RMS method wins on RMS
    out, status = fourbar_outputs(["axis_x", "axis_y", "axis_x_h1", "axis_y_h1", "dM_rms_axis", "dM_rms_h1"])
    assert status[0] == st.OK and GEO["g"] > 0
    assert out["axis_y_h1"] == pytest.approx(out["axis_y"], rel=1e-12)
    assert abs(out["axis_x_h1"] - out["axis_x"]) > 1e-3 * abs(out["axis_x"])
    assert out["dM_rms_axis"] < out["dM_rms_h1"]
    # non-constant speed: the RMS method wins on RMS, and the axes differ
    out, status = fourbar_outputs(["axis_x", "axis_y", "axis_x_h1", "axis_y_h1", "dM_rms_axis",
                                   "dM_rms_h1", "M_rms_static"], delta=0.3)
    assert status[0] == st.OK
    assert abs(out["axis_x_h1"] - out["axis_x"]) > 1e-3 * abs(out["axis_x"])
    assert out["dM_rms_axis"] < out["dM_rms_h1"] < out["M_rms_static"]
    # non-uniform positions with the plain functions (constant speed)
    phi = np.sort(np.concatenate([np.linspace(0, np.pi, 40, endpoint=False), np.linspace(np.pi, 2 * np.pi, 10,
                                                                                          endpoint=False)]))
    M = 4 * np.cos(phi - 0.3) + 2 * np.sin(2 * phi)
    rms = np.array(B.rms_axis_offset(phi, M, 0.5, 10.0))
    h1 = np.array(B.first_harmonic_axis_offset(phi, M, 0.5, 10.0))
    assert np.abs(rms - h1).max() > 1e-3 * np.abs(rms).max()
    uniform = 2 * np.pi * np.arange(50) / 50
    M = 4 * np.cos(uniform - 0.3) + 2 * np.sin(2 * uniform)
    assert B.first_harmonic_axis_offset(uniform, M, 0.5, 10.0) == pytest.approx(
        B.rms_axis_offset(uniform, M, 0.5, 10.0), rel=1e-12)


@pytest.mark.parametrize("delta", [0.0, 0.3])
def test_model_axis_equals_the_plain_function_on_its_moment(delta):
    # GEO has gravity: the plain functions get the moved counterweight's weight m_cw g (cw_weight)
    names = ["M_static_phi", "dM_axis_phi", "dM_h1_phi", "axis_x", "axis_y", "axis_x_h1", "axis_y_h1",
             "cw1_mr_static", "cw1_angle_static", "dM_max_axis", "M_max_static", "R_axis", "dM_rms_axis"]
    out, status = fourbar_outputs(names, delta=delta)
    w = 20.0 * (1 + delta * np.sin(B.PHI))
    al = w * 20.0 * delta * np.cos(B.PHI)
    kw = dict(phi_dd=al, cw_angle=out["cw1_angle_static"], cw_weight=GEO["g"] * out["cw1_mr_static"] / GEO["r_cw1"])
    x, y = B.rms_axis_offset(B.PHI, out["M_static_phi"], out["cw1_mr_static"], w, **kw)
    assert (out["axis_x"], out["axis_y"]) == pytest.approx((x, y), rel=1e-11)
    x1, y1 = B.first_harmonic_axis_offset(B.PHI, out["M_static_phi"], out["cw1_mr_static"], w, **kw)
    assert (out["axis_x_h1"], out["axis_y_h1"]) == pytest.approx((x1, y1), rel=1e-11)
    dM = out["M_static_phi"] + B.axis_moment(B.PHI, x, y, out["cw1_mr_static"], w, **kw)
    np.testing.assert_allclose(out["dM_axis_phi"], dM, atol=1e-11 * np.abs(dM).max())
    assert out["dM_max_axis"] == pytest.approx(np.abs(dM).max(), rel=1e-11)
    assert out["dM_rms_axis"] == pytest.approx(np.sqrt(np.mean(dM ** 2)), rel=1e-11)
    assert out["R_axis"] == pytest.approx(B.efficiency(out["M_static_phi"], dM), rel=1e-10)


# ============================================================================= method 4: added rocker inertia
def test_rocker_inertia_cancels_the_moment_of_a_pendulum_coupler():
    """Inline links and a coupler with I_A = m2 r2 a2 (physical-pendulum condition): after force
    balancing the angular momentum has no coupler term, so at constant speed a rocker inertia
    cancels the shaking moment exactly; otherwise it is the least-squares fit on phi3''."""
    m2, r2, a2 = 2.0, 0.12, 0.35
    geo = dict(a1=0.1, a2=a2, a3=0.3, a4=0.4, m1=1.0, r1=0.05, I1=1e-3, m2=m2, r2=r2, I2=m2 * r2 * (a2 - r2),
               m3=1.5, r3=0.15, I3=0.011, omega=20.0)
    names = ["dM_rms_inertia", "dM_max_inertia", "M_rms_static", "R_inertia", "J_rocker"]
    out, status = evaluate1("fourbar_balancing", names, **geo)
    assert status[0] == st.OK
    assert out["dM_rms_inertia"][0] < 1e-12 * out["M_rms_static"][0]
    assert out["R_inertia"][0] == pytest.approx(100.0, abs=1e-9)
    out, status = evaluate1("fourbar_balancing", names + ["M_static_phi", "dM_inertia_phi"], **dict(geo, I2=0.02))
    c, _ = B.fourbar_curves(B.PHI, 20.0, 0.0, static=True, **dict(geo, I2=0.02))
    J = np.linalg.lstsq(c["alpha3"][:, None], out["M_static_phi"][0], rcond=None)[0][0]
    assert out["J_rocker"][0] == pytest.approx(J, rel=1e-12)
    ref = out["M_static_phi"][0] - J * c["alpha3"]
    np.testing.assert_allclose(out["dM_inertia_phi"][0], ref, atol=1e-12 * np.abs(ref).max())
    assert 0 < out["R_inertia"][0] < 100


def test_rocker_inertia_torque_adds_its_kinetic_energy_rate():
    out, _ = fourbar_outputs(["J_rocker", "T_static_phi", "T_rms_inertia", "T_max_inertia"])
    c, _ = B.fourbar_curves(B.PHI, 20.0, 0.0, static=True, **dict(GEO, omega=20.0))
    T = out["T_static_phi"] + abs(out["J_rocker"]) * c["alpha3"] * c["omega3"] / 20.0
    assert out["T_rms_inertia"] == pytest.approx(np.sqrt(np.mean(T ** 2)), rel=1e-12)
    assert out["T_max_inertia"] == pytest.approx(np.abs(T).max(), rel=1e-12)


# ============================================================================= slider-crank
def slider_bodies(geo, c, phi, balanced=True):
    cw = B.slidercrank_counterweight(**geo) if balanced else dict(cw_mr=0.0, cw_angle=0.0)
    rc = geo.get("r_cw", geo["r"])
    ax, ay = cis(geo["r"], phi)
    w1 = d_dt(phi)
    out = [(geo["m1"], geo["I1"], *cis(geo["r1"], phi + geo["theta1"]), w1),
           (cw["cw_mr"] / rc, 0.0, *cis(rc, phi + cw["cw_angle"]), w1)]
    x, y = cis(geo["r2"], c["phi2"] + geo["theta2"])
    out.append((geo["m2"], geo["I2"], ax + x, ay + y, d_dt(np.unwrap(c["phi2"]))))
    out.append((geo["m3"], 0.0, c["x_B"], geo["e"] + 0 * phi, 0 * phi))
    return out


@pytest.mark.parametrize("branch", ["right", "left"])
def test_slider_kinematics_and_loads_against_positions(branch):
    phi, w, al = motion(T_GRID)
    c, code = B.slidercrank_curves(phi, w, al, branch=branch, **SLIDER)
    assert code == st.OK
    l, r, e = SLIDER["l"], SLIDER["r"], SLIDER["e"]
    np.testing.assert_allclose(r * np.sin(phi) + l * np.sin(c["phi2"]), e, atol=1e-15)
    np.testing.assert_allclose(r * np.cos(phi) + l * np.cos(c["phi2"]), c["x_B"], atol=1e-15)
    assert np.all(np.sign(c["x_B"] - r * np.cos(phi)) == (1 if branch == "right" else -1))
    assert rel_err(d_dt(np.unwrap(c["phi2"])), c["omega2"]) < 1e-6
    assert rel_err(d_dt(c["omega2"]), c["alpha2"]) < 1e-6
    assert rel_err(d_dt(c["x_B"]), c["v_B"]) < 1e-6
    assert rel_err(d_dt(c["v_B"]), c["a_B"]) < 1e-6
    E, H, Px, Py, m_tot, M_g = momenta(slider_bodies(SLIDER, c, phi), SLIDER["g"])
    assert rel_err(d_dt(E), c["T"] * w + SLIDER["F_load"] * c["v_B"]) < 1e-5
    assert rel_err(-d_dt(H) + M_g, c["M"]) < 1e-5
    assert rel_err(-d_dt(Px), c["Fx"]) < 1e-5
    assert rel_err(-d_dt(Py) - m_tot * SLIDER["g"], c["Fy"]) < 1e-5


def slider_outputs(outputs, **kw):
    params = dict(r=0.05, m1=1.0, r1=0.02, I1=1e-3, m2=0.8, r2=0.06, I2=3e-3, m3=0.6, omega=100.0, k=0.5)
    params.update(kw)
    if "l" not in params:
        params.setdefault("lambda", 0.25)
    return evaluate1("slidercrank_balancing", outputs, **params)


def test_slider_counterweight_is_the_textbook_one():
    out, status = slider_outputs(["m_A", "m_B", "cw_mr", "cw_angle", "cw_mass"], r_cw=0.04)
    l = 0.05 / 0.25
    mA = 1.0 * 0.02 / 0.05 + 0.8 * (1 - 0.06 / l)  # static two-point substitution
    mB = 0.6 + 0.8 * 0.06 / l
    assert out["m_A"][0] == pytest.approx(mA, rel=1e-14)
    assert out["m_B"][0] == pytest.approx(mB, rel=1e-14)
    assert out["cw_mr"][0] == pytest.approx((mA + 0.5 * mB) * 0.05, rel=1e-14)
    assert out["cw_angle"][0] == pytest.approx(np.pi, rel=1e-15)
    assert out["cw_mass"][0] == pytest.approx((mA + 0.5 * mB) * 0.05 / 0.04, rel=1e-14)


@pytest.mark.parametrize("k", [0.0, 0.5, 1.0])
def test_slider_residual_force_against_the_textbook_formula(k):
    """Inline slider-crank at constant speed: Fy is the textbook -k m_B r w^2 sin phi exactly;
    Fx differs by the lambda^3 and higher terms of the exact slider acceleration
    (max error -> lambda^3 / 2 m_B r w^2 as lambda -> 0)."""
    lams = np.array([0.02, 0.04, 0.08, 0.16])
    out, status = slider_outputs(["Fx_phi", "Fy_phi", "Fx_tb_phi", "Fy_tb_phi", "F_tb_error_rel", "m_B"],
                                 k=k, **{"lambda": lams}, r1=0.0)
    assert (status == st.OK).all()
    scale = out["m_B"] * 0.05 * 100.0 ** 2
    np.testing.assert_allclose(out["Fy_phi"], out["Fy_tb_phi"], atol=1e-12 * scale.max())
    err = out["F_tb_error_rel"]
    slope = np.polyfit(np.log(lams), np.log(err), 1)[0]
    assert slope == pytest.approx(3.0, abs=0.02)
    assert err[0] / lams[0] ** 3 == pytest.approx(0.5, rel=0.01)
    # the exact series of x_B'': -r w^2 (cos phi + (lambda + lambda^3/4) cos 2phi - lambda^3/4 cos 4phi + ...)
    lam = lams[1]
    series = out["Fx_tb_phi"][1] + scale[1] * (lam ** 3 / 4) * (np.cos(2 * B.PHI) - np.cos(4 * B.PHI))
    assert np.abs(out["Fx_phi"][1] - series).max() < 2 * lam ** 5 * scale[1]


def textbook_error_bound(lam):
    """physics.md section 4: the largest error of the two-term slider acceleration over a cycle,
    in units of r w^2 (at phi = 90 deg)."""
    return lam * (1.0 / np.sqrt(1.0 - lam ** 2) - 1.0)


@pytest.mark.parametrize("lam", [0.05, 0.15, 0.3, 0.45, 0.5, 0.7])
def test_textbook_residual_bound_is_exact(lam):
    """The bound physics.md states, lambda (1/sqrt(1 - lambda^2) - 1) m_B r w^2, is the largest
    difference between the exact slider acceleration (differentiated by sympy from the position)
    and the two-term series over the cycle (densely sampled, then refined by a bounded search),
    and the model's F_tb_error_rel equals it; lambda^3 / 2 (the bound stated before) is 24 %
    short of it at lambda = 0.5."""
    import sympy as sp
    from scipy.optimize import minimize_scalar

    phi, L = sp.symbols("phi lambda", positive=True)
    x = sp.cos(phi) + sp.sqrt(1 / L ** 2 - sp.sin(phi) ** 2)  # x_B / r, crank at constant speed
    acc = sp.lambdify((phi, L), sp.diff(x, phi, 2), "numpy")  # x_B'' / (r w^2)
    def err(p):
        return np.abs(acc(p, lam) + np.cos(p) + lam * np.cos(2 * p))
    grid = np.linspace(0.0, 2 * np.pi, 20001)
    j = int(np.argmax(err(grid)))
    best = minimize_scalar(lambda p: -err(p), bounds=(grid[j - 1], grid[j + 1]), method="bounded",
                           options={"xatol": 1e-12})
    measured = max(err(grid).max(), -best.fun)
    assert measured == pytest.approx(textbook_error_bound(lam), rel=1e-9)
    out, status = slider_outputs(["F_tb_error_rel"], **{"lambda": lam}, r1=0.0)
    assert status[0] == st.OK
    assert out["F_tb_error_rel"][0] == pytest.approx(textbook_error_bound(lam), rel=1e-12)
    if lam == 0.5:
        assert textbook_error_bound(lam) / (lam ** 3 / 2) == pytest.approx(1.2376, abs=1e-4)


def test_slider_counterweight_reduces_the_first_order_force():
    out, _ = slider_outputs(["F_max", "F_max_unbalanced", "Fx_max", "Fy_max"], k=0.5, r1=0.0)
    out0, _ = slider_outputs(["Fy_max"], k=0.0, r1=0.0)
    assert out["F_max"][0] < out["F_max_unbalanced"][0]
    assert out0["Fy_max"][0] < 1e-12 * out["Fy_max"][0]  # k = 0: the rotating mass is balanced exactly


# ============================================================================= statuses
@pytest.mark.parametrize("branch", ["open", "crossed"])
@pytest.mark.parametrize("a1,a2,a3,a4,code", [
    (0.1, 0.35, 0.3, 0.4, st.OK),
    (0.3, 0.35, 0.3, 0.4, st.INFEASIBLE),  # crank longer than allowed: not a Grashof crank
    (0.1, 0.2, 0.3, 0.6, st.INFEASIBLE),  # coupler + rocker too short to reach
    (0.1, 0.2, 0.35, 0.45, st.SINGULAR),  # change point s + l = p + q: a toggle
    (0.1, 0.3, 0.3, 0.1, st.SINGULAR),  # crank = frame, coupler = rocker: A meets O_B
    (0.1, 0.2, 0.35, 0.45 - 1e-8, st.SINGULAR),  # within TOGGLE_SIN of a toggle
    (0.1, 0.2, 0.35, 0.45 - 1e-3, st.OK),
])
def test_fourbar_statuses(branch, a1, a2, a3, a4, code):
    names = list(fb.SPEC.output_names())
    out, status = evaluate1("fourbar_balancing", names, **dict(GEO, a1=a1, a2=a2, a3=a3, a4=a4, omega=10.0,
                                                                 branch=branch))
    assert status[0] == code
    finite = [np.isfinite(out[k]).all() for k in names]
    assert all(finite) if code == st.OK else not any(finite)


@pytest.mark.parametrize("l,e,code", [(0.2, 0.0, st.OK), (0.2, 0.1, st.OK), (0.2, 0.15, st.SINGULAR),
                                      (0.2, -0.16, st.INFEASIBLE), (0.04, 0.0, st.INFEASIBLE)])
def test_slider_statuses(l, e, code):
    names = list(sc.SPEC.output_names())
    out, status = slider_outputs(names, l=l, e=e)
    assert status[0] == code
    finite = [np.isfinite(out[k]).all() for k in names]
    assert all(finite) if code == st.OK else not any(finite)
    _, curve_status = B.slidercrank_curves(np.array([0.0, 1.0]), 1.0, **dict(SLIDER, l=l, e=e))
    assert curve_status == code


def test_a_position_at_a_toggle_of_the_position_function_is_singular():
    _, code = B.fourbar_curves(np.array([0.0, np.pi]), 1.0, a1=0.1, a2=0.2, a3=0.35, a4=0.45,
                               **{k: v for k, v in GEO.items() if k not in ("a1", "a2", "a3", "a4")})
    assert code == st.SINGULAR


# ============================================================================= Hypothesis properties
def grashof_crank(a1, a2, a3, a4):
    """Classical statement: s + l <= p + q and the shortest link is the crank or the frame."""
    s, l = min(a1, a2, a3, a4), max(a1, a2, a3, a4)
    return s + l < a1 + a2 + a3 + a4 - s - l and s in (a1, a4)


@settings(max_examples=80, deadline=None)
@given(a=hs.tuples(*[hs.floats(0.05, 1.0)] * 4), branch=hs.sampled_from(["open", "crossed"]),
       th=hs.tuples(*[hs.floats(-3.0, 3.0)] * 3), delta=hs.floats(-0.5, 0.5))
def test_property_status_and_balancing(a, branch, th, delta):
    a1, a2, a3, a4 = a
    s, l = min(a), max(a)
    assume(abs((s + l) - (sum(a) - s - l)) > 1e-3)  # away from change points
    names = ["transmission_min", "M_rms_static", "F_max_static", "F_max", "dM_rms_axis", "dM_rms_h1",
             "dM_rms_inertia", "R_axis", "R_h1", "R_inertia", "T_rms", "M_range"]
    params = dict(GEO, a1=a1, a2=a2, a3=a3, a4=a4, branch=branch, theta1=th[0], theta2=th[1], theta3=th[2],
                  delta=delta, omega=10.0, r2=0.5 * a2, r3=0.5 * a3, r_cw1=a1)
    out, status = evaluate1("fourbar_balancing", names, **params)
    o = {k: v[0] for k, v in out.items()}
    if not grashof_crank(a1, a2, a3, a4):
        assert status[0] == st.INFEASIBLE
        return
    assert status[0] in (st.OK, st.SINGULAR)
    if status[0] == st.SINGULAR:
        assert o["transmission_min"] != o["transmission_min"]  # NaN
        return
    assert all(np.isfinite(v) for v in o.values())
    assert o["F_max_static"] <= 1e-10 * o["F_max"] + 1e-12
    assert o["dM_rms_axis"] <= o["M_rms_static"] * (1 + 1e-12)
    assert o["dM_rms_axis"] <= o["dM_rms_h1"] * (1 + 1e-12)  # the RMS optimum is optimal
    assert o["dM_rms_inertia"] <= o["M_rms_static"] * (1 + 1e-12)
    assert 0 < o["transmission_min"] <= np.pi / 2


@settings(max_examples=40, deadline=None)
@given(lam=hs.floats(0.05, 0.6), e_frac=hs.floats(-0.99, 0.99), k=hs.floats(0, 1),
       branch=hs.sampled_from(["right", "left"]))
def test_property_slider_statuses_and_finiteness(lam, e_frac, k, branch):
    r = 0.05
    l = r / lam
    e = e_frac * (l - r) * 1.2  # sometimes beyond l - r: no full turn
    out, status = slider_outputs(list(sc.SPEC.output_names()[:22]), **{"lambda": lam}, e=e, k=k, branch=branch)
    margin = l - r - abs(e)
    if margin < -1e-9:
        assert status[0] == st.INFEASIBLE
    elif math.sqrt(max(margin, 0) * (l + r + abs(e))) / l >= 1.01 * L.TOGGLE_SIN:
        assert status[0] == st.OK
        assert all(np.isfinite(v[0]) for v in out.values())
        assert out["F_max"][0] <= np.hypot(out["Fx_max"][0], out["Fy_max"][0]) * (1 + 1e-12)


# ============================================================================= jitted vs pure Python
def test_jitted_kernels_agree_with_python():
    args = (0.1, 0.35, 0.3, 0.4, -1.0, math.cos(0.7), math.sin(0.7), 12.0, 5.0)
    np.testing.assert_allclose(L.fourbar_position(*args), L.fourbar_position.py_func(*args), rtol=1e-14)
    kin = L.fourbar_position(*args)[:8]
    links = (0.1, 0.02, 0.01, 2.0, 0.3, 0.05, 0.05, 0.2, -0.03, 0.05, 2.0, 5.0, 9.81, 1.5)
    full = (0.1, 0.4, args[5], args[6], 12.0, 5.0, *kin, *links)
    np.testing.assert_allclose(L.fourbar_loads(*full), L.fourbar_loads.py_func(*full), rtol=1e-14)
    sargs = (0.05, 0.2, 0.01, 1.0, math.cos(2.0), math.sin(2.0), 30.0, -4.0)
    np.testing.assert_allclose(L.slider_position(*sargs), L.slider_position.py_func(*sargs), rtol=1e-14)
    assert L.fourbar_assembly(0.1, 0.2, 0.35, 0.45) == L.fourbar_assembly.py_func(0.1, 0.2, 0.35, 0.45)
    x = np.random.default_rng(3).normal(size=361)
    assert L.cycle_stats(x) == pytest.approx(L.cycle_stats.py_func(x), rel=1e-15)
    assert L.dot4(x, x[::-1].copy()) == pytest.approx(L.dot4.py_func(x, x[::-1].copy()), rel=1e-15)


@pytest.mark.parametrize("model", [fb, sc])
def test_design_functions_agree_with_python(model):
    """The engine's compiled chunk kernel (ClosedFormModel) against the model's per-design function
    run as plain Python, every output asked for."""
    spec, decl = model.SPEC, model.MODEL
    if spec is fb.SPEC:
        P, _ = B._matrix("fourbar_balancing", dict(GEO, omega=20.0, delta=0.2))
    else:
        P, _ = B._matrix("slidercrank_balancing", dict(SLIDER, omega=30.0, delta=0.2))
    names = spec.output_names()
    out = {k: np.full((1, L.N_POSITIONS) if spec.output(k).extra_dims else 1, np.nan) for k in names}
    status = np.zeros(1, np.int8)
    spec.evaluate(P, names, None, out, status, None, None)
    want = np.ones(len(decl.scalars), bool)
    slot = np.arange(len(decl.curves))
    row = np.full(len(decl.scalars), np.nan)
    crv_py = np.full((len(decl.curves), L.N_POSITIONS), np.nan)
    args = (P[0], want, row, crv_py, slot, np.empty((decl.scratch, L.N_POSITIONS))) + decl.shared_data(L.N_POSITIONS)
    assert decl.compute.py_func(*args) == status[0] == st.OK
    np.testing.assert_allclose(row, [out[k][0] for k in decl.scalars], rtol=1e-13)
    crv = np.array([out[k][0] for k in decl.curves])
    np.testing.assert_allclose(crv_py, crv, rtol=1e-13, atol=1e-13 * np.abs(crv).max())


# ============================================================================= end to end
@pytest.fixture
def linkage_models(monkeypatch):
    monkeypatch.setitem(models.MODELS, fb.SPEC.name, fb.SPEC)
    monkeypatch.setitem(models.MODELS, sc.SPEC.name, sc.SPEC)
    monkeypatch.setattr(mechsweep.scene.sections, "MODELS", models.MODELS)


def test_run_stores_curves_with_the_phi_dimension(linkage_models, in_tmp):
    fixed = {k: v for k, v in GEO.items() if k != "a4"}
    scene = {"scene": {"name": "fourbar", "model": "fourbar_balancing",
                       "outputs": ["R_axis", "dM_max_axis", "M_static_phi", "dM_axis_phi"]},
             "axes": {"a4": [0.4, 0.42, 0.6]}, "fixed": dict(fixed, omega=20.0, branch="crossed")}
    ds = mechsweep.run(scene, output="data/runs/fb.h5")
    assert ds["dM_axis_phi"].dims == ("a4", "phi")
    assert ds["phi"].attrs["units"] == "rad" and ds["phi"].size == 360
    np.testing.assert_allclose(ds["phi"].values, B.PHI)
    assert ds["status"].values.tolist() == [st.OK, st.OK, st.INFEASIBLE]
    assert np.isnan(ds["dM_axis_phi"].values[2]).all() and np.isfinite(ds["dM_axis_phi"].values[:2]).all()
    assert ds["R_axis"].attrs["units"] == "%"
    ref, _ = evaluate1("fourbar_balancing", ["R_axis"], **dict(fixed, a4=0.42, omega=20.0, branch="crossed"))
    assert ds["R_axis"].values[1] == pytest.approx(ref["R_axis"][0], rel=1e-14)


def test_slider_scene_needs_l_or_lambda(linkage_models):
    from mechsweep.scene import SceneError, load_scene

    fixed = dict(r=0.05, m1=1.0, r1=0.0, I1=0.0, m2=0.8, r2=0.06, I2=3e-3, m3=0.6, omega=100.0)
    scene = {"scene": {"name": "s", "model": "slidercrank_balancing", "outputs": ["F_max"]},
             "axes": {"k": [0.0, 0.5]}, "fixed": dict(fixed, l=0.2, **{"lambda": 0.25})}
    with pytest.raises(SceneError, match="not both"):
        load_scene(scene)
    scene["fixed"] = fixed
    with pytest.raises(SceneError, match="give the rod length l or lambda"):
        load_scene(scene)
