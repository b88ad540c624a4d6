"""A measured experiment, not the model: the auto-balancer's simulated outputs declared on the
model layer (an OdeModel with the layer's Kick, Steady, History and Floquet; the physics imported
from models/autobalancer.py) against the hand-written kernels' reference values
(tests/data/autobalancer_reference.npz, design grid, feasible points with an isolated balanced
state): ``python tests/data/autobalancer_on_layer.py [method]``. Prints, per output, how many
points are bitwise equal, the largest relative difference elsewhere, and whether n_steps and the
status agree. What it shows is in docs/model-layer.md ("What issue 13 still needs").
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numba
import numpy as np

from mechsweep import status as st
from mechsweep.model import Floquet, History, Kick, OdeModel, Steady
from mechsweep.models import autobalancer as ab

NPAR = len(ab.PARAM_NAMES)
NSET = len(ab.SETTINGS)
OFF = NPAR + NSET  # the internal slots: the 12 scaled parameters of the hand-written kernels
I_PERT = NPAR + [s.name for s in ab.SETTINGS].index("perturbation")
IX = {name: j for j, name in enumerate(ab.PARAM_NAMES)}
I_omega_xi = ab.PARAM_NAMES.index("omega_xi")
I_c_xi = ab.PARAM_NAMES.index("c_xi")
I_b_xi = ab.PARAM_NAMES.index("b_xi")
I_zeta_xi = ab.PARAM_NAMES.index("zeta_xi")
I_omega_eta = ab.PARAM_NAMES.index("omega_eta")
I_c_eta = ab.PARAM_NAMES.index("c_eta")
I_b_eta = ab.PARAM_NAMES.index("b_eta")
I_zeta_eta = ab.PARAM_NAMES.index("zeta_eta")
I_A1 = ab.PARAM_NAMES.index("A1")
I_l3 = ab.PARAM_NAMES.index("l3")
I_l4 = ab.PARAM_NAMES.index("l4")
I_a = ab.PARAM_NAMES.index("a")
I_Omega = ab.PARAM_NAMES.index("Omega")


def rhs(t, z, p, dz):
    ab.rhs(t, z, p[OFF:OFF + ab.NP], dz)


def rhs_lanes(t, Z, P, dZ):
    ab.rhs_lanes(t, Z, P[OFF:OFF + ab.NP], dZ)


def jac(t, z, p, J):
    ab.jacobian(t, z, p[OFF:OFF + ab.NP], J)


def initial(p, z):
    ab.initial_state(p[OFF:OFF + ab.NP], p[I_PERT], z)


def balanced(p, z):
    """The exact balanced state (x = y = 0, gamma_i = Theta_i, gamma_i' = 1): Floquet's orbit."""
    ab.initial_state(p[OFF:OFF + ab.NP], 0.0, z)


def forcing(p):
    return 2.0 * math.pi


@numba.njit
def _platform(om, c, b, zeta, M):
    """(c, b) of one axis from either parametrisation (autobalancer.platform)."""
    if math.isnan(om):
        om = math.sqrt(c / M)
    if math.isnan(c):
        c = M * om * om
    if math.isnan(b):
        b = 2.0 * zeta * M * om
    return c, b


def prepare(p, rtol):
    """The scaled parameters (autobalancer.platform and scaled_parameters, per point)."""
    Om, M, m, a, IB, A0, h = p[0], p[1], p[2], p[3], p[4], p[5], p[6]  # PARAM_NAMES order
    cx, bx = _platform(p[I_omega_xi], p[I_c_xi], p[I_b_xi], p[I_zeta_xi], M)
    cy, by = _platform(p[I_omega_eta], p[I_c_eta], p[I_b_eta], p[I_zeta_eta], M)
    A1, l3, l4 = p[I_A1], p[I_l3], p[I_l4]
    lam = l3 / l4 if (A1 != 0.0 and not math.isnan(l3) and not math.isnan(l4)) else 0.0
    two_ma = 2.0 * m * a
    th1 = math.acos(min(1.0, max(-1.0, -A0 / two_ma))) if A0 <= two_ma else math.pi
    th2 = -th1 if A0 <= two_ma else math.pi
    q = p[OFF:OFF + ab.NP]
    q[ab.IP_MU] = M / m
    q[ab.IP_ALPHA0] = A0 / (m * a)
    q[ab.IP_ALPHA1] = A1 / (m * a)
    q[ab.IP_LAM] = lam
    q[ab.IP_IOTA] = IB / (m * a * a)
    q[ab.IP_KX] = cx / (m * Om ** 2)
    q[ab.IP_KY] = cy / (m * Om ** 2)
    q[ab.IP_DX] = bx / (m * Om)
    q[ab.IP_DY] = by / (m * Om)
    q[ab.IP_EH] = h / (m * a * a * Om)
    q[ab.IP_TH1] = th1
    q[ab.IP_TH2] = th2
    return 0


def phase_error(t, z, p):
    e1, e2 = ab.phase_errors(t, z[2], z[3], p[OFF + ab.IP_TH1], p[OFF + ab.IP_TH2])
    return max(abs(e1), abs(e2))


def platform(t, z, p):
    return math.sqrt(z[0] * z[0] + z[1] * z[1])


def xi(t, z, p):
    return z[0]


def to_seconds(p, tau):  # the settling time from the scaled time tau = Omega t, as the old model divides
    return tau / p[I_Omega]


def to_metres(p, x):  # a length in units of a, as the old model multiplies
    return x * p[I_a]


H = "horizon_revolutions"
MODEL = OdeModel(
    name="autobalancer_layer", description="the auto-balancer's dynamics on the layer (experiment)",
    params=ab.SPEC.params, settings=ab.SETTINGS, internal=tuple(f"q{j}" for j in range(ab.NP)),
    states=("x", "y", "g1", "g2", "xd", "yd", "w1", "w2"), rhs=rhs, initial=initial, jac=jac,
    forcing_period=forcing, prepare=prepare, rhs_lanes=rhs_lanes,
    measurements=(
        Floquet("floquet", initial=balanced),
        Kick("sim", phase_error, platform, horizon=H, settle_threshold="settle_threshold",
             decay_ratio="decay_ratio", growth_ratio="growth_ratio",
             monitor_per_period="monitor_samples_per_revolution",
             dense_per_period="residual_samples_per_revolution", time_value=to_seconds),
        Steady("residual", platform, horizon=H, window=0.1, samples_per_period="residual_samples_per_revolution",
               settle_rtol=None, value=to_metres),
        History("xi_history", xi, horizon=H, samples="trajectory_samples", dim="revolution", value=to_metres),
    ))


def compare(method="dop853"):
    """{reference output: (bitwise equal points, points, largest relative difference, points where
    NaN differs)} on the design grid's feasible points with an isolated balanced state, and
    "steps": (n_steps equal, n_rhs equal, statuses equal, points) of the simulated outputs together
    against the reference run without the re-integration at rtol / 100 (dop853 only)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import record_autobalancer as rec
    from mechsweep.model import load
    from mechsweep.scene import Solver

    spec = load.resolve(f"{Path(__file__).resolve()}:MODEL")
    ref = np.load(rec.FILE)
    P = rec.design_points()
    label = f"grid-{method}-all"
    kw = dict(method=method, rtol=1e-8, atol=1e-10, horizon_revolutions=rec.HORIZON, trajectory_samples=7)
    slv = Solver.for_model(spec, **kw)
    ok = np.isfinite(ref[f"{label}/floquet_max"])  # feasible, isolated balanced state
    Pk = P[ok]
    n = Pk.shape[0]
    result = {}
    pairs = (("floquet", "floquet_max"), ("sim", "stable_sim"), ("sim_settling", "settling_time"),
             ("sim_final", "phase_error"), ("residual", "residual_amplitude"), ("xi_history", "xi_history"))
    for mine, theirs in pairs:
        if mine == "floquet" and method != "dop853":
            continue  # the layer's Floquet integrates with dop853 only
        o = spec.output(mine)
        shape = (n,) + tuple(len(d.values(slv.settings)) for d in o.extra_dims)
        out = {mine: np.full(shape, np.nan)}
        status, ns, nr = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
        with np.errstate(all="ignore"):
            spec.evaluate(Pk, (mine,), slv, out, status, ns, nr)
        v = out[mine]  # in SI units (Kick's time_value, Steady's and History's value)
        e = ref[f"{label}/{theirs}"][ok]
        same = np.array([np.array_equal(a, b, equal_nan=True) for a, b in zip(v, e)])
        with np.errstate(all="ignore"):
            rel = (np.abs(v - e) / np.maximum(np.abs(e), 1e-300)).reshape(n, -1)
        both = np.isfinite(rel)
        worst = float(np.nanmax(np.where(both, rel, np.nan))) if both.any() else 0.0
        result[theirs] = (int(same.sum()), n, worst, int((np.isnan(v) != np.isnan(e)).reshape(n, -1).any(axis=1).sum()))
    if method == "dop853":
        want = ("sim", "sim_settling", "sim_final", "residual", "xi_history")
        slv = Solver.for_model(spec, method=method, rtol=1e-8, atol=1e-10, horizon_revolutions=rec.HORIZON)
        out = {k: np.full((n,) + tuple(len(d.values(slv.settings)) for d in spec.output(k).extra_dims), np.nan)
               for k in want}
        status, ns, nr = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
        spec.evaluate(Pk, want, slv, out, status, ns, nr)
        lab = f"grid-{method}-norecheck"
        result["steps"] = (int((ns == ref[lab + "/n_steps"][ok]).sum()), int((nr == ref[lab + "/n_rhs"][ok]).sum()),
                           int((status == ref[lab + "/status"][ok]).sum()), n)
    return result


def mixed():
    """Floquet (the main kernel) and the sampled measurements asked for together give the values
    and statuses of each asked alone, and their steps add up: (all values equal, steps add up,
    statuses of the sampled request kept where Floquet was OK)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import record_autobalancer as rec
    from mechsweep.model import load
    from mechsweep.scene import Solver

    spec = load.resolve(f"{Path(__file__).resolve()}:MODEL")
    P = rec.design_points()
    n = P.shape[0]
    slv = Solver.for_model(spec, rtol=1e-8, atol=1e-10, horizon_revolutions=rec.HORIZON)

    def ev(wanted):
        out = {k: np.full(n, np.nan) for k in wanted}
        status, ns, nr = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
        with np.errstate(all="ignore"):
            spec.evaluate(P, wanted, slv, out, status, ns, nr)
        return out, status, ns

    both, f, g = ev(("floquet", "stable_floquet", "sim", "residual")), ev(("floquet", "stable_floquet")), \
        ev(("sim", "residual"))
    same = all(np.array_equal(both[0][k], (f if k in f[0] else g)[0][k], equal_nan=True) for k in both[0])
    status_ok = np.array_equal(both[1], np.where(f[1] == 0, g[1], f[1]))
    return same, bool(np.array_equal(both[2], f[2] + g[2])), bool(status_ok)


def main(method="dop853"):
    for name, r in compare(method).items():
        if name == "steps":
            print(f"{method} simulated outputs together: n_steps equal at {r[0]}/{r[3]}, n_rhs at {r[1]}/{r[3]}, "
                  f"status at {r[2]}/{r[3]}")
        else:
            print(f"{method} {name:20s}: bitwise {r[0]}/{r[1]}, max rel diff {r[2]:.2e}, NaN differs at {r[3]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:2]))
