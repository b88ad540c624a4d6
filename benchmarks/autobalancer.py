"""`python benchmarks/autobalancer.py`: Floquet chart throughput and direct-simulation speed, measured now.

1. Floquet chart: floquet_max on an Omega x mass-ratio grid (Omega in [0.5, 2.5] rad/s, 2 m / M in
   [1e-3, 0.1] log; omega_xi = 1, omega_eta = 1.5 rad/s, zeta = 0.02, A0 = m a, h = m a^2 x 1 rad/s),
   all numba threads, the solver's tolerances (defaults rtol 5e-11, atol 1e-12). A grid smaller than
   200 x 200 is extrapolated to 200 x 200 by points (and says so).
2. Direct simulation: the model's stable_sim and residual_amplitude (the layer's sampled
   trajectory of the scaled equations in the engine's lane form of the model's rhs: up to 32
   trajectories side by side in SIMD lanes per thread, engine/sampling.py and ode/dop853_lanes.py;
   the bench sets trajectory.USE_LANES: the route a sweep of LANES_FROM_POINTS points or a warm cache takes), timed on one thread
   (accepted steps per second per core) and on all numba threads (4x as many points), best of
   REPEATS runs each. The points are a sweep's worth per thread (512 by default; on 2 threads the
   shipped scenes give a thread 180-3,000): a thread's lanes idle at the end of its queue, which a
   handful of points would overstate. For comparison, once, the same points one trajectory at a
   time (the same DOP853 without lanes: it must take the same steps, and the bench says if not),
   and with method "auto" (the same DOP853 steps plus the stiffness test; a point it finds stiff is
   integrated again with radau, so its step count legitimately adds both integrations: the number
   of such points is printed). The simulation times include the model's reproducibility check
   (points whose trajectory did not settle early are integrated again at rtol / 100, see
   models/autobalancer.py, Recheck); its steps count in the steps per second.
   scipy.integrate.solve_ivp(method="DOP853", t_eval=the model's samples, the same tolerances)
   integrates a sample of the same trajectories in the same process, each the best of REPEATS runs
   too, twice: with the equations written in Python with math/numpy, and with the model's own
   compiled right-hand side (``ab.scaled_rhs`` under numba, called by scipy through a one-line
   Python function: what a user who knows numba passes to scipy, scipy's best case). Its step count
   comes from scipy's DOP853 class stepped by hand (untimed), whose samples must equal solve_ivp's.
   Both implement the same step-size control, so their step counts agree and the ratio of steps
   per second is the speed-up at equal accuracy.
3. The strongest competitor we know for the simulation, when numbalsoda is installed: its
   ``dop853`` (Hairer's Fortran DOP853, which returns the state at the given times, exactly what
   the simulation samples) on the model's compiled rhs as a ``cfunc``, in a ``numba.prange`` loop
   over the same trajectories, against mechsweep's first integration of them (the re-check off,
   ``reproducibility_factor = 0``: the same work), on one thread and on all threads: time per
   trajectory (its step count is not reported, and Hairer's controller is not scipy's, so the ratio
   is of times, with the largest residual_amplitude difference printed beside it).
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/NAME.py`: import from the repository's root, as -m does
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import math
import time

import numba
import numpy as np

from mechsweep import status as st
from mechsweep._jit import jit
from mechsweep.engine import sampling as trajectory
from mechsweep.engine.sampling import LANES as _LANE_CHOICES
from mechsweep.models import autobalancer as ab
from mechsweep.scene import Solver
from tests.reference import autobalancer_kernels as ref  # scaled parameters and sample grid for scipy

LANES = _LANE_CHOICES[0]  # the lane right-hand side's cost is measured with the most lanes the model uses

CHART = 200  # the chart the target refers to: 200 x 200
REPEATS = 3  # simulations (ours and scipy's) are timed as the best of this many runs


def _best_of(repeats, func, *args):
    """(shortest wall time, result) of `repeats` calls: the least disturbed by other processes."""
    best, result = math.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = func(*args)
        best = min(best, time.perf_counter() - t0)
    return best, result


def chart_parameters(n_omega: int, n_ratio: int) -> np.ndarray:
    """P matrix (declared parameter order) of the Omega x mass-ratio chart."""
    Om, eps = np.meshgrid(np.linspace(0.5, 2.5, n_omega), np.geomspace(1e-3, 0.1, n_ratio), indexing="ij")
    Om, eps = Om.ravel(), eps.ravel()
    m = eps / 2
    values = dict(Omega=Om, M=1.0, m=m, a=0.1, I_B=m * 0.01, A0=m * 0.1, h=m * 0.01, omega_xi=1.0,
                  omega_eta=1.5, zeta_xi=0.02, zeta_eta=0.02)
    P = np.empty((Om.size, len(ab.SPEC.params)))
    for j, prm in enumerate(ab.SPEC.params):
        P[:, j] = values.get(prm.name, prm.default)
    return P


def run_outputs(P, outputs, solver):
    wanted = ab.SPEC.closure(outputs)
    n = P.shape[0]
    out = {k: np.full((n,) + tuple(len(d.values(solver.settings)) for d in ab.SPEC.output(k).extra_dims), np.nan)
           for k in wanted}
    status = np.zeros(n, np.int8)
    ns = np.zeros(n, np.int64)
    nr = np.zeros(n, np.int64)
    ab.SPEC.evaluate(P, wanted, solver, out, status, ns, nr)
    return out, status, ns, nr


# ----------------------------------------------------------------------------- scipy reference
def python_rhs(p):
    """The scaled equations of motion (module docstring of the model) in plain Python."""
    mu, al0, al1, lam, iota, kx, ky, dx, dy, eh = (float(v) for v in p[:10])
    inv = 1.0 / iota
    sin, cos, sqrt = math.sin, math.cos, math.sqrt

    def f(tau, z):
        x, y, g1, g2, xd, yd, w1, w2 = z
        s1, k1, s2, k2 = sin(g1), cos(g1), sin(g2), cos(g2)
        q1, q2 = -eh * (w1 - 1.0), -eh * (w2 - 1.0)
        if lam != 0.0:
            sp_, cp_ = -lam * sin(tau), 0.0
            cp_ = sqrt(1.0 - sp_ * sp_)
            d = -lam * cos(tau) / cp_
            dd = (lam * sin(tau) + sp_ * d * d) / cp_
            cx, cy = dd * sp_ + d * d * cp_, dd * cp_ - d * d * sp_
        else:
            cx = cy = 0.0
        rx = -kx * x - dx * xd + al0 * cos(tau) + al1 * cx + w1 * w1 * k1 + w2 * w2 * k2 + inv * (s1 * q1 + s2 * q2)
        ry = -ky * y - dy * yd + al0 * sin(tau) - al1 * cy + w1 * w1 * s1 + w2 * w2 * s2 - inv * (k1 * q1 + k2 * q2)
        k11 = mu - inv * (s1 * s1 + s2 * s2)
        k12 = inv * (s1 * k1 + s2 * k2)
        k22 = mu - inv * (k1 * k1 + k2 * k2)
        det = k11 * k22 - k12 * k12
        xdd = (k22 * rx - k12 * ry) / det
        ydd = (k11 * ry - k12 * rx) / det
        return np.array([xd, yd, w1, w2, xdd, ydd, (q1 - (ydd * k1 - xdd * s1)) * inv,
                         (q2 - (ydd * k2 - xdd * s2)) * inv])

    return f


def scipy_trajectory(p, delta, t_eval, rtol, atol):
    """scipy's DOP853 stepped as solve_ivp does with t_eval. Returns (samples, n_steps): the step
    count, which solve_ivp does not report (not timed)."""
    from scipy.integrate import DOP853

    z0 = initial_state(p, delta)
    solver = DOP853(python_rhs(p), 0.0, z0, t_eval[-1], rtol=rtol, atol=atol)
    out = np.empty((t_eval.size, 8))
    out[0] = z0
    k = 1
    steps = 0
    while solver.status == "running":
        t_old = solver.t
        solver.step()
        steps += 1
        if k < t_eval.size and t_eval[k] <= solver.t:
            dense = solver.dense_output()
            while k < t_eval.size and t_eval[k] <= solver.t:
                out[k] = dense(t_eval[k]) if t_eval[k] > t_old else solver.y
                k += 1
    return out, steps


def solve_ivp_trajectory(p, delta, t_eval, rtol, atol):
    """The trajectory by scipy.integrate.solve_ivp(method="DOP853", t_eval=...): the timed one."""
    from scipy.integrate import solve_ivp

    sol = solve_ivp(python_rhs(p), (0.0, t_eval[-1]), initial_state(p, delta), method="DOP853", t_eval=t_eval,
                    rtol=rtol, atol=atol)
    return sol.y.T


def initial_state(p, delta):
    return np.array([0.0, 0.0, p[ab.IP_TH1] + delta, p[ab.IP_TH2] - delta, 0.0, 0.0, 1.0, 1.0])


@jit
def _rhs_array(tau, z, p):
    """The model's compiled rhs returning a new array, as scipy's solve_ivp wants it."""
    dz = np.empty(8)
    ab.scaled_rhs(tau, z, p, dz)
    return dz


def solve_ivp_jitted_trajectory(p, delta, t_eval, rtol, atol):
    """solve_ivp(method="DOP853", t_eval=...) on the model's compiled rhs (scipy's best case)."""
    from scipy.integrate import solve_ivp

    sol = solve_ivp(lambda tau, z: _rhs_array(tau, z, p), (0.0, t_eval[-1]), initial_state(p, delta),
                    method="DOP853", t_eval=t_eval, rtol=rtol, atol=atol)
    return sol.y.T


_NUMBALSODA = []


def numbalsoda_available() -> bool:
    try:
        import numbalsoda  # noqa: F401
        return True
    except Exception:  # not installed, or broken: the bench says so
        return False


def _numbalsoda_kernel():
    if _NUMBALSODA:
        return _NUMBALSODA[0]
    from numba import carray, cfunc
    from numbalsoda import dop853, lsoda_sig

    n_p = ab.NP

    @cfunc(lsoda_sig)
    def rhs(tau, u, du, p):  # the model's own compiled rhs on numbalsoda's pointers
        ab.scaled_rhs(tau, carray(u, (8,)), carray(p, (n_p,)), carray(du, (8,)))

    rhs_ptr = rhs.address
    i_th1, i_th2 = ab.IP_TH1, ab.IP_TH2

    @numba.njit(parallel=True)
    def kernel(pp, delta, t_eval, late, rtol, atol, max_steps, residual):
        # t_eval ends with one time past the horizon: dop853 leaves its last row unwritten where its
        # final step ends an ulp short of it (bench/competitors.py)
        for i in numba.prange(pp.shape[0]):
            p = pp[i].copy()
            y0 = np.zeros(8)
            y0[2], y0[3], y0[6], y0[7] = p[i_th1] + delta, p[i_th2] - delta, 1.0, 1.0
            u, ok = dop853(rhs_ptr, y0, t_eval, p, rtol, atol, max_steps)
            r = np.nan
            if ok:
                r = 0.0
                for k in range(late, t_eval.size - 1):
                    r = max(r, math.hypot(u[k, 0], u[k, 1]))
            residual[i] = r

    _NUMBALSODA.append((kernel, rhs))  # keep the cfunc alive
    return _NUMBALSODA[0]


def numbalsoda_residuals(pp, delta, t_eval, rtol, atol, max_steps):
    """residual_amplitude / a of each row of scaled parameters pp by numbalsoda's dop853, sampled at
    t_eval (max of the platform's distance over the last 10 % of the horizon, as the scipy check)."""
    kernel = _numbalsoda_kernel()[0]
    times = np.append(t_eval, t_eval[-1] * (1.0 + 1e-9))
    late = int(np.searchsorted(t_eval, 0.9 * t_eval[-1], side="left"))
    residual = np.empty(pp.shape[0])
    kernel(np.ascontiguousarray(pp), delta, times, late, rtol, atol, int(max_steps), residual)
    return residual


# ----------------------------------------------------------------------------- right-hand side cost
@jit
def _rhs_loop(n, p, z, dz):
    """n evaluations of the model's rhs, each from the previous derivative (a dependent chain,
    as the stages of a step are)."""
    for i in range(n):
        ab.scaled_rhs(0.01 * i, z, p, dz)
        for k in range(8):
            z[k] += 1e-9 * dz[k]
    return z[0]


@jit
def _lane_rhs_loop(n, tau, P, Z, dZ):
    """n lane right-hand sides (every lane at once), each from the previous derivative."""
    for i in range(n):
        ref.rhs_lanes(tau, Z, P, dZ)
        for k in range(8):
            for l in range(Z.shape[1]):
                Z[k, l] += 1e-9 * dZ[k, l]
    return Z[0, 0]


def lane_rhs_ns(pp, n: int = 125_000, repeats: int = REPEATS) -> float:
    """Nanoseconds per lane per lane right-hand side (LANES lanes, parameters pp[:LANES])."""
    P = np.ascontiguousarray(np.resize(pp, (LANES, pp.shape[1])).T)
    Z = np.zeros((8, LANES))
    Z[2], Z[3], Z[6], Z[7] = P[ab.IP_TH1] + 0.1, P[ab.IP_TH2] - 0.1, 1.0, 1.0
    tau = np.linspace(0.0, 1.0, LANES)
    dZ = np.empty_like(Z)
    _lane_rhs_loop(10, tau, P, Z.copy(), dZ)
    best, _ = _best_of(repeats, _lane_rhs_loop, n, tau, P, Z.copy(), dZ)
    return best / (n * LANES) * 1e9


def rhs_ns(p, n: int = 2_000_000, repeats: int = REPEATS) -> float:
    """Nanoseconds per right-hand-side evaluation, best of `repeats` loops."""
    z = np.array([0.0, 0.0, p[ab.IP_TH1] + 0.1, p[ab.IP_TH2] - 0.1, 0.0, 0.0, 1.0, 1.0])
    dz = np.empty(8)
    _rhs_loop(10, p, z.copy(), dz)
    best, _ = _best_of(repeats, _rhs_loop, n, p, z.copy(), dz)
    return best / n * 1e9


# ----------------------------------------------------------------------------- main
def main(n_omega: int = CHART, n_ratio: int = CHART, sim_points: int = 512, scipy_points: int = 3,
         threads: int | None = None, rtol: float = Solver.rtol, atol: float = Solver.atol) -> dict:
    from mechsweep.scene import SOLVER_LIMITS
    from mechsweep.bench import arguments

    n_omega, n_ratio = arguments.count("n_omega", n_omega, 2, 10**4), arguments.count("n_ratio", n_ratio, 2, 10**4)
    sim_points = arguments.count("sim_points", sim_points, 1, 10**6)
    scipy_points = arguments.count("scipy_points", scipy_points, 1, sim_points)
    threads = arguments.threads("threads", threads)
    rtol = arguments.tolerance("rtol", rtol, *SOLVER_LIMITS["rtol"])
    atol = arguments.tolerance("atol", atol, *SOLVER_LIMITS["atol"])
    before = numba.get_num_threads()
    if threads is not None:
        numba.set_num_threads(threads)
    try:
        return _main(n_omega, n_ratio, sim_points, scipy_points, rtol, atol)
    finally:
        numba.set_num_threads(before)


def _main(n_omega, n_ratio, sim_points, scipy_points, rtol, atol):
    before = trajectory.USE_LANES
    trajectory.USE_LANES = True  # the lanes, as a sweep of LANES_FROM_POINTS points or a warm cache takes them
    try:
        return _measure(n_omega, n_ratio, sim_points, scipy_points, rtol, atol)
    finally:
        trajectory.USE_LANES = before


def _measure(n_omega, n_ratio, sim_points, scipy_points, rtol, atol):
    solver = Solver.for_model(ab.SPEC, rtol=rtol, atol=atol)
    n_threads = numba.get_num_threads()
    P_small = chart_parameters(2, 2)
    t0 = time.perf_counter()
    run_outputs(P_small, ("floquet_max", "stable_sim"), solver)  # compile or load every kernel timed below
    compile_s = time.perf_counter() - t0

    # 1. Floquet chart
    P = chart_parameters(n_omega, n_ratio)
    t0 = time.perf_counter()
    out, status, ns, _ = run_outputs(P, ("floquet_max",), solver)
    chart_s = time.perf_counter() - t0
    n = P.shape[0]
    chart_200_s = chart_s * CHART * CHART / n

    # 2. direct simulation, one thread, points spread over the chart
    rng = np.random.default_rng(0)
    pick = np.sort(rng.choice(n, size=min(sim_points, n), replace=False))
    Psim = P[pick]
    sim_outputs = ("residual_amplitude", "stable_sim")
    numba.set_num_threads(1)
    try:
        sim_s, (sim, sstatus, sns, snr) = _best_of(REPEATS, run_outputs, Psim, sim_outputs, solver)
    finally:
        numba.set_num_threads(n_threads)
    ours_steps_per_s = sns.sum() / sim_s
    # all threads: 4x the points, so that every thread stays busy to the end
    Pall = P[np.sort(rng.choice(n, size=min(4 * sim_points, n), replace=False))]
    sim_all_s, (_, _, ans, _) = _best_of(REPEATS, run_outputs, Pall, sim_outputs, solver)
    ours_all_steps_per_s = ans.sum() / sim_all_s
    t_eval, *_ = ref.sample_grid(solver.settings, histories=False)
    col = {name: Psim[:, j] for j, name in enumerate(ab.PARAM_NAMES)}
    pf = ref.platform(Psim)
    theta = np.arccos(-col["A0"] / (2 * col["m"] * col["a"]))
    pp = ref.scaled_parameters(col["Omega"], col["M"], col["m"], col["a"], col["I_B"], col["A0"], 0.0, 0.0,
                              pf["c_xi"], pf["c_eta"], pf["b_xi"], pf["b_eta"], col["h"], theta, -theta)

    # one trajectory at a time, once (slower: a few seconds): the same DOP853 must take the same
    # steps as the lanes; method auto takes them too, unless its stiffness test hands a point to
    # radau (then its count adds both integrations: counted and printed, not a disagreement)
    def first_integration(method, lanes, points):
        # the model's sampled trajectory without the re-check (reproducibility_factor 0): the first integration
        slv = Solver.for_model(ab.SPEC, method=method, rtol=rtol, atol=atol, reproducibility_factor=0.0)
        counts = np.zeros(points.shape[0], np.int64)
        out = {k: np.full(points.shape[0], np.nan) for k in sim_outputs}
        chosen = tuple(m for m in ab.MODEL.measurements if m.name in sim_outputs)
        trajectory.evaluate(ab.MODEL, chosen, points, sim_outputs, slv, out, np.zeros(points.shape[0], np.int8),
                            counts, np.zeros_like(counts), lanes=lanes)
        return counts

    numba.set_num_threads(1)
    try:
        lane_ns = first_integration("dop853", True, Psim)
        first_integration("dop853", False, Psim[:1])  # compile or load
        t0 = time.perf_counter()
        one_ns = first_integration("dop853", False, Psim)
        one_steps_per_s = one_ns.sum() / (time.perf_counter() - t0)
        auto_ns = first_integration("auto", False, Psim)
    finally:
        numba.set_num_threads(n_threads)

    # scipy on the first scipy_points of those trajectories
    delta = solver.settings["perturbation"]
    k_sp = min(scipy_points, pick.size)
    sp_steps, sp_time, sp_jit_time, diffs = [], 0.0, 0.0, []
    late = t_eval >= 0.9 * t_eval[-1]
    solve_ivp_jitted_trajectory(pp[0], delta, t_eval[:3], rtol, atol)  # compile the rhs (not timed)
    for i in range(k_sp):  # solve_ivp timed best of REPEATS, as ours: the least disturbed run
        t_best, traj = _best_of(REPEATS, solve_ivp_trajectory, pp[i], delta, t_eval, rtol, atol)
        stepped, steps = scipy_trajectory(pp[i], delta, t_eval, rtol, atol)  # its steps (the same solver)
        if not np.array_equal(stepped, traj):
            raise AssertionError("scipy's DOP853 stepped by hand and solve_ivp disagree")
        t_jit, traj_jit = _best_of(REPEATS, solve_ivp_jitted_trajectory, pp[i], delta, t_eval, rtol, atol)
        sp_time += t_best
        sp_jit_time += t_jit
        sp_steps.append(steps)
        for tr in (traj, traj_jit):
            r_late = np.hypot(tr[late, 0], tr[late, 1]).max()
            diffs.append(abs(r_late * col["a"][i] - sim["residual_amplitude"][i]))
    scipy_steps_per_s = sum(sp_steps) / sp_time
    scipy_jit_steps_per_s = sum(sp_steps) / sp_jit_time

    # numbalsoda's dop853 on the same trajectories against our first integration of them
    nb = None
    if numbalsoda_available():
        first_only = Solver.for_model(ab.SPEC, rtol=rtol, atol=atol, reproducibility_factor=0.0)
        max_steps = solver.settings.get("max_steps", Solver.max_steps)
        nb = {}
        numbalsoda_residuals(pp[:2], delta, t_eval, rtol, atol, max_steps)  # compile (not timed)
        run_outputs(Psim[:2], sim_outputs, first_only)
        for label, n_thr in (("one_thread", 1), ("all_threads", n_threads)):
            numba.set_num_threads(n_thr)
            try:
                t_nb, res_nb = _best_of(REPEATS, numbalsoda_residuals, pp, delta, t_eval, rtol, atol, max_steps)
                t_ours, (first_out, *_) = _best_of(REPEATS, run_outputs, Psim, sim_outputs, first_only)
            finally:
                numba.set_num_threads(n_threads)
            nb[label] = {"numbalsoda_ms_per_trajectory": t_nb / pick.size * 1e3,
                         "ours_ms_per_trajectory": t_ours / pick.size * 1e3, "ratio": t_nb / t_ours}
        nb["failed"] = int(np.isnan(res_nb).sum())
        nb["max_residual_difference_m"] = float(np.nanmax(np.abs(res_nb * col["a"] - first_out["residual_amplitude"])))
    rhs_cost = rhs_ns(pp[0])
    lane_rhs_cost = lane_rhs_ns(pp)

    result = {
        "threads": n_threads,
        "compile_or_cache_load_s": compile_s,
        "chart_points": n,
        "chart_s": chart_s,
        "chart_200x200_s": chart_200_s,
        "chart_extrapolated": n != CHART * CHART,
        "chart_mean_steps": float(ns.mean()),
        "chart_ok_fraction": float((status == st.OK).mean()),
        "sim_points": int(pick.size),
        "sim_s_one_thread": sim_s,
        "sim_mean_steps": float(sns.mean()),
        "sim_steps_per_s_per_core": float(ours_steps_per_s),
        "sim_ok_fraction": float((sstatus == st.OK).mean()),
        "scipy_trajectories": k_sp,
        "scipy_mean_steps": float(np.mean(sp_steps)),
        "ours_steps_same_trajectories": [int(s) for s in lane_ns[:k_sp]],  # first integration, as scipy's
        "scipy_steps_per_s": float(scipy_steps_per_s),
        "ratio_vs_scipy_per_core": float(ours_steps_per_s / scipy_steps_per_s),
        "scipy_jitted_rhs_steps_per_s": float(scipy_jit_steps_per_s),
        "ratio_vs_scipy_jitted_rhs_per_core": float(ours_steps_per_s / scipy_jit_steps_per_s),
        "ratio_vs_scipy_jitted_rhs_all_threads": float(ours_all_steps_per_s / scipy_jit_steps_per_s),
        "numbalsoda": nb,
        "sim_steps_per_s_all_threads": float(ours_all_steps_per_s),
        "ratio_vs_scipy_all_threads": float(ours_all_steps_per_s / scipy_steps_per_s),
        "one_at_a_time_steps_per_s": float(one_steps_per_s),
        "one_at_a_time_same_steps": bool(np.array_equal(one_ns, lane_ns)),
        "auto_radau_handoffs": int((auto_ns != one_ns).sum()),
        "auto_same_steps_elsewhere": bool((auto_ns >= one_ns).all()),
        "rhs_ns": rhs_cost,
        "lane_rhs_ns": lane_rhs_cost,
        "lanes": trajectory.lane_count(t_eval.size, ab.MODEL),
        "rhs_per_step": float(snr.sum() / sns.sum()),
        "max_residual_difference_m": float(max(diffs)) if diffs else math.nan,
        "rtol": rtol,
        "atol": atol,
    }
    _print(result, solver)
    return result


def _print(r: dict, solver) -> None:
    print(f"benchmarks/autobalancer.py: DOP853, rtol={r['rtol']:g}, atol={r['atol']:g}, {r['threads']} threads")
    print(f"  first call (JIT compile or cache load of both kernels): {r['compile_or_cache_load_s']:.2f} s")
    extra = (f" (measured on {r['chart_points']} points in {r['chart_s']:.2f} s, extrapolated by points)"
             if r["chart_extrapolated"] else "")
    print(f"  Floquet chart floquet_max, Omega x 2m/M, 200 x 200: {r['chart_200x200_s']:.2f} s on "
          f"{r['threads']} threads{extra}; {r['chart_mean_steps']:.1f} steps/point (the 64 variational "
          f"equations about the exact balanced orbit over one period), {r['chart_ok_fraction'] * 100:.1f}% ok")
    H = solver.settings["horizon_revolutions"]
    print(f"  direct simulation ({H:g} revolutions, {r['sim_points']} chart points, best of {REPEATS} runs): "
          f"{r['sim_steps_per_s_per_core']:,.0f} steps/s on 1 thread, {r['sim_steps_per_s_all_threads']:,.0f} "
          f"steps/s on {r['threads']} threads; {r['sim_mean_steps']:.0f} steps/trajectory, "
          f"{r['sim_s_one_thread'] / r['sim_points'] * 1e3:.1f} ms/trajectory on 1 thread")
    print(f"  scipy solve_ivp DOP853 (Python rhs), {r['scipy_trajectories']} of the same trajectories, best of {REPEATS} runs each: "
          f"{r['scipy_steps_per_s']:,.0f} steps/s ({r['scipy_mean_steps']:.0f} steps/trajectory; ours "
          f"{r['ours_steps_same_trajectories']})")
    print(f"  the same points one trajectory at a time (DOP853 without lanes): {r['one_at_a_time_steps_per_s']:,.0f} "
          f"steps/s on 1 thread, lanes {r['sim_steps_per_s_per_core'] / r['one_at_a_time_steps_per_s']:.1f}x faster; "
          f"step counts {'the same' if r['one_at_a_time_same_steps'] else 'DIFFER (a bug: the lanes must take the same steps)'}"
          f"; method auto: {r['auto_radau_handoffs']} of {r['sim_points']} points found stiff and integrated again "
          f"with radau (their counts add both integrations), the others the same steps")
    print(f"  right-hand side: {r['rhs_ns']:.0f} ns alone, {r['lane_rhs_ns']:.1f} ns per lane in {r['lanes']} lanes; "
          f"{r['rhs_per_step']:.1f} per step (counted as one trajectory would: lanes compute the dense "
          f"output's 3 whenever any lane needs them); a step takes {1e6 / r['sim_steps_per_s_per_core']:.2f} us "
          f"per lane on one thread")
    print(f"  scipy solve_ivp DOP853 with the model's compiled rhs (numba), the same trajectories: "
          f"{r['scipy_jitted_rhs_steps_per_s']:,.0f} steps/s")
    print(f"  ratio mechsweep / scipy (one process), Python rhs: {r['ratio_vs_scipy_per_core']:,.0f}x on 1 thread, "
          f"{r['ratio_vs_scipy_all_threads']:,.0f}x on {r['threads']} threads; compiled rhs: "
          f"{r['ratio_vs_scipy_jitted_rhs_per_core']:,.0f}x on 1 thread, "
          f"{r['ratio_vs_scipy_jitted_rhs_all_threads']:,.0f}x on {r['threads']} threads; "
          f"largest residual_amplitude difference {r['max_residual_difference_m']:.2e} m")
    nb = r["numbalsoda"]
    if nb is None:
        print("  numbalsoda: not installed (pip install mechsweep[compare])")
        return
    one, every = nb["one_thread"], nb["all_threads"]
    print(f"  numbalsoda dop853 (the model's compiled rhs as a cfunc, prange), the same {r['sim_points']} trajectories "
          f"and samples, against mechsweep's first integration (re-check off), best of {REPEATS}: "
          f"{one['numbalsoda_ms_per_trajectory']:.2f} against {one['ours_ms_per_trajectory']:.2f} ms/trajectory on "
          f"1 thread ({one['ratio']:.1f}x), {every['numbalsoda_ms_per_trajectory']:.2f} against "
          f"{every['ours_ms_per_trajectory']:.2f} on {r['threads']} threads ({every['ratio']:.1f}x); "
          f"{nb['failed']} failed; largest residual_amplitude difference {nb['max_residual_difference_m']:.2e} m")


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/autobalancer.py [--threads N] [--sim-points N] [--scipy-points N]``."""
    from benchmarks import _cli

    p = _cli.parser("autobalancer", "Floquet chart time (200 x 200) and simulation throughput vs scipy")
    p.add_argument("--threads", type=int, default=None, help="numba threads (default: all cores)")
    p.add_argument("--sim-points", type=int, default=512,
                   help="trajectories simulated by mechsweep on one thread (4x on all threads; default 512)")
    p.add_argument("--scipy-points", type=int, default=3, help="of those, solved with scipy too (default 3)")

    def command(a) -> int:
        main(sim_points=a.sim_points, scipy_points=a.scipy_points, threads=a.threads)
        return 0

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
