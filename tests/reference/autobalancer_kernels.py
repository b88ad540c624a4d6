"""The auto-balancer's hand-written kernels: a reference implementation the model layer is compared
against (tests, benchmarks/autobalancer.py, tests/data/record_autobalancer.py); not part of mechsweep.

The built-in model "autobalancer" is the layer declaration in models/autobalancer.py (its module
docstring has the physics, the decision rules and the statuses). This module is the code that was
models/autobalancer.py before the model moved onto the layer, unchanged: the Floquet kernel (the
64-state variational system about the exact balanced orbit, ``variational_rhs``), the direct
simulation (``simulation_kernel`` one trajectory at a time, ``simulate_lanes`` in SIMD lanes,
``integrate``, ``sample_grid``, ``measure``), the reproducibility re-check and the vectorised
``evaluate`` with its own method switch, under ``SPEC`` (a ModelSpec named "autobalancer" that is
not registered in MODELS). The equations of motion, Jacobian, phase errors, initial state,
parameters, settings, outputs' metadata and cross-parameter rules are imported from
models/autobalancer.py (one place), under the names this code used (rhs, jacobian); the hand-written lane
right-hand side ``rhs_lanes`` is here (the model's lane form is written by the engine, engine/lane_rhs.py).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from mechsweep import status as st
from mechsweep._jit import jit, jit_noalloc, pjit, prange
from mechsweep.model.spec import ModelSpec
from mechsweep.models.autobalancer import (  # noqa: F401 (re-exported: the reference's names)
    IB_SLACK, IP_ALPHA0, IP_ALPHA1, IP_DX, IP_DY, IP_EH, IP_IOTA, IP_KX, IP_KY, IP_LAM, IP_MU, IP_TH1, IP_TH2, NP,
    OUTPUTS, PAIRS, PARAM_NAMES, PARAMS, REVOLUTION, SETTINGS, STATUS_NOTES, STATUS_ORDER, STATUSES, TWO_PI,
    accelerations, accelerations_trig, check, conrod_terms, history_revolutions, initial_state, phase_errors,
    variational_jacobian, variational_rhs, wrap)
from mechsweep.models.autobalancer import scaled_jacobian as jacobian
from mechsweep.models.autobalancer import scaled_rhs as rhs
from mechsweep.special import SINCOS_MAX, sincos_reduced
from mechsweep.ode import AUTO, DOP853, METHOD_CODES, RADAU, dop853, dop853_lanes, radau

from .literal_switch import call_with_literal, compile_time_switch, literally


@jit_noalloc
def rhs_lanes(tau, Z, P, dZ):
    """rhs() (models/autobalancer.py's scaled_rhs) for several trajectories side by side (lanes):
    tau[l], state Z[:, l], scaled parameters P[:, l], derivative into dZ[:, l]. Bitwise the same
    floats as rhs() per lane.

    The main loop has no branch and no call, so LLVM vectorises it over the lanes (4 doubles
    per AVX2 instruction); the velocity rows are copied in a separate loop because writing all
    eight rows of dZ in one loop needs more run-time aliasing checks than LLVM makes, and it
    then leaves the loop scalar. An angle beyond the reduction range of sincos_reduced (or
    infinite) sends every lane through the scalar rhs, with libm's sin and cos; NaN stays on the
    fast path (sincos_reduced gives NaN for it, like libm; idle lanes may hold NaN)."""
    lanes = Z.shape[1]
    beyond = 0
    for l in range(lanes):
        beyond += 1 if max(abs(Z[2, l]), abs(Z[3, l]), abs(tau[l])) > SINCOS_MAX else 0  # NaN: not beyond
    if beyond:
        for l in range(lanes):
            xdd, ydd, g1dd, g2dd, _, _, _, _, _, _, _, _ = accelerations(
                tau[l], Z[0, l], Z[1, l], Z[2, l], Z[3, l], Z[4, l], Z[5, l], Z[6, l], Z[7, l], P[:, l])
            dZ[4, l] = xdd
            dZ[5, l] = ydd
            dZ[6, l] = g1dd
            dZ[7, l] = g2dd
    else:
        for l in range(lanes):
            s1, k1 = sincos_reduced(Z[2, l])
            s2, k2 = sincos_reduced(Z[3, l])
            st_, ct_ = sincos_reduced(tau[l])
            xdd, ydd, g1dd, g2dd, _, _, _, _, _, _, _, _ = accelerations_trig(
                Z[0, l], Z[1, l], Z[4, l], Z[5, l], Z[6, l], Z[7, l], s1, k1, s2, k2, st_, ct_, P[IP_MU, l],
                1.0 / P[IP_IOTA, l], P[IP_EH, l], P[IP_KX, l], P[IP_KY, l], P[IP_DX, l], P[IP_DY, l],
                P[IP_ALPHA0, l], P[IP_ALPHA1, l], P[IP_LAM, l])
            dZ[4, l] = xdd
            dZ[5, l] = ydd
            dZ[6, l] = g1dd
            dZ[7, l] = g2dd
    for r in range(4):
        for l in range(lanes):
            dZ[r, l] = Z[4 + r, l]


BLOCK = 8  # points per scratch allocation in the parallel loops
LATE_FRACTION = 0.1  # last 10 % of the horizon: residual amplitude and late envelopes
EARLY_FRACTION = 0.1  # first 10 %: reference platform amplitude
SEVERITY = STATUS_ORDER + (st.OK,)  # most severe first (models/autobalancer.py)


# ----------------------------------------------------------------------------- Floquet
floquet_solver = dop853.make_solver(variational_rhs)
floquet_solver_stiffness_test = dop853.make_solver(variational_rhs, stiffness_test=True)
floquet_solver_radau = radau.make_solver(variational_rhs, variational_jacobian)


@jit_noalloc
def _identity(Y):
    for i in range(64):
        Y[i] = 0.0
    for i in range(8):
        Y[9 * i] = 1.0


@jit_noalloc
def _monodromy_dop853(Y, p, rtol, atol, max_steps, work, rwork):
    return floquet_solver(0.0, Y, p, TWO_PI, rtol, atol, 0.0, max_steps, work)


@jit_noalloc
def _monodromy_radau(Y, p, rtol, atol, max_steps, work, rwork):
    return floquet_solver_radau(0.0, Y, p, TWO_PI, rtol, atol, 0.0, max_steps, rwork)


@jit_noalloc
def _monodromy_auto(Y, p, rtol, atol, max_steps, work, rwork):
    """dop853 with the stiffness test; a stiff point starts again with radau (costs add up)."""
    code, ns, nr = floquet_solver_stiffness_test(0.0, Y, p, TWO_PI, rtol, atol, 0.0, max_steps, work)
    if code != st.STIFF:
        return code, ns, nr
    _identity(Y)
    code, ns2, nr2 = floquet_solver_radau(0.0, Y, p, TWO_PI, rtol, atol, 0.0, max_steps, rwork)
    return code, ns + ns2, nr + nr2


# monodromy(method, Y, p, rtol, atol, max_steps, work, rwork) -> (status, n_steps, n_rhs): the
# variational system over one period from Y = identity; only the method's solver is compiled.
monodromy = compile_time_switch("monodromy", {DOP853: _monodromy_dop853, RADAU: _monodromy_radau,
                                              AUTO: _monodromy_auto})


@jit
def floquet_point(method, p, rtol, atol, max_steps, Y, work, rwork):
    """Largest |Floquet multiplier| of the balanced state. Returns (status, value, steps, rhs)."""
    _identity(Y)
    code, ns, nr = monodromy(method, Y, p, rtol, atol, max_steps, work, rwork)
    if code != st.OK:
        return code, math.nan, ns, nr
    mono = np.empty((8, 8), dtype=np.complex128)
    for c in range(8):
        for r in range(8):
            v = Y[8 * c + r]
            if not math.isfinite(v):
                return st.NONFINITE, math.nan, ns, nr
            mono[r, c] = v
    ev = np.linalg.eigvals(mono)  # complex input: numba raises on a real -> complex domain change
    big = 0.0
    for k in range(8):
        big = max(big, abs(ev[k]))
    return st.OK, big, ns, nr


@pjit
def floquet_kernel(method, pp, run, rtol, atol, max_steps, value, code, n_steps, n_rhs):
    literally(method)  # one cached kernel per method
    n = pp.shape[0]
    n_blocks = (n + BLOCK - 1) // BLOCK
    for b in prange(n_blocks):
        work = dop853.workspace(64)
        rwork = radau.workspace(64)
        Y = np.empty(64)
        for i in range(b, n, n_blocks):  # strided: cost varies along the grid
            if not run[i]:
                continue
            c, v, ns, nr = floquet_point(method, pp[i], rtol, atol, max_steps, Y, work, rwork)
            code[i] = c
            value[i] = v
            n_steps[i] += ns
            n_rhs[i] += nr


# ----------------------------------------------------------------------------- direct simulation
trajectory_solver = dop853.make_trajectory_solver(rhs)
trajectory_solver_stiffness_test = dop853.make_trajectory_solver(rhs, stiffness_test=True)
trajectory_solver_radau = radau.make_trajectory_solver(rhs, jacobian)


@jit_noalloc
def _trajectory_dop853(z, p, t_eval, rtol, atol, max_steps, work, rwork, traj):
    return trajectory_solver(0.0, z, p, t_eval, rtol, atol, 0.0, max_steps, work, traj)


@jit_noalloc
def _trajectory_radau(z, p, t_eval, rtol, atol, max_steps, work, rwork, traj):
    return trajectory_solver_radau(0.0, z, p, t_eval, rtol, atol, 0.0, max_steps, rwork, traj)


@jit_noalloc
def _trajectory_auto(z, p, t_eval, rtol, atol, max_steps, work, rwork, traj):
    """dop853 with the stiffness test; a stiff point starts again with radau (costs add up)."""
    z0, z1, z2, z3, z4, z5, z6, z7 = z[0], z[1], z[2], z[3], z[4], z[5], z[6], z[7]
    code, ns, nr = trajectory_solver_stiffness_test(0.0, z, p, t_eval, rtol, atol, 0.0, max_steps, work, traj)
    if code != st.STIFF:
        return code, ns, nr
    z[0], z[1], z[2], z[3], z[4], z[5], z[6], z[7] = z0, z1, z2, z3, z4, z5, z6, z7
    code, ns2, nr2 = trajectory_solver_radau(0.0, z, p, t_eval, rtol, atol, 0.0, max_steps, rwork, traj)
    return code, ns + ns2, nr + nr2


# trajectory(method, z, p, t_eval, rtol, atol, max_steps, work, rwork, traj) -> (status, n_steps, n_rhs)
trajectory = compile_time_switch("trajectory", {DOP853: _trajectory_dop853, RADAU: _trajectory_radau,
                                                AUTO: _trajectory_auto})

# Columns of the per-point measurement table of the simulation kernel.
M_E0, M_ELATE, M_RREF, M_RLATE, M_EFINAL, M_TSETTLE, M_EPREV, M_LOCK = range(8)
N_MEAS = 8
# Bits of sample_grid's meas_rows: a row of the measurement grid; a whole revolution of the
# second half of the horizon (the once-per-revolution map, M_LOCK).
ROW_MEASURE = 1
ROW_REVOLUTION = 2




@jit
def simulate_point(method, p, delta, t_eval, n_rev1, n_early, i_prev, i_late, rtol, atol, max_steps, settle,
                   hist_idx, meas_rows, hist, z, work, rwork, traj, meas):
    """One direct simulation (scaled). Fills meas (N_MEAS) and, if hist has columns, hist[4, k].
    Returns (status, n_steps, n_rhs)."""
    initial_state(p, delta, z)
    code, ns, nr = trajectory(method, z, p, t_eval, rtol, atol, max_steps, work, rwork, traj)
    if code != st.OK:
        return code, ns, nr
    return measure(traj, p, t_eval, n_rev1, n_early, i_prev, i_late, settle, hist_idx, meas_rows, hist, meas), ns, nr


@jit
def measure(traj, p, t_eval, n_rev1, n_early, i_prev, i_late, settle, hist_idx, meas_rows, hist, meas):
    """The measurements of one simulated trajectory (samples traj[k] at t_eval[k]) into meas and,
    if hist has columns, hist[4, k]. Returns OK, or NONFINITE for a non-finite sample.

    Only the rows with meas_rows[k] & ROW_MEASURE (the measurement grid, the same whichever outputs are asked
    for) enter the measurements; the rows added for the histories do not, so that no output
    depends on whether histories are requested (the trajectory itself never does: samples come
    from the dense output and do not change the steps)."""
    th1 = p[IP_TH1]
    th2 = p[IP_TH2]
    n_eval = t_eval.size
    e0 = 0.0
    e_late = 0.0
    e_before = 0.0
    r_ref = 0.0
    r_late = 0.0
    last_above = -1
    k_rev = -1  # previous whole-revolution row
    n_rev = 0
    lock = 0.0
    k_prev = -1
    k_next = -1
    e_prev = 0.0
    e_last_above = 0.0
    e_next = 0.0
    for k in range(n_eval):
        if meas_rows[k] & ROW_REVOLUTION:
            # M_LOCK: largest change of the state over one revolution (the pendulum angles less
            # one turn) in the second half: ~0 once the motion is locked to the crank period
            if k_rev >= 0:
                for i in range(8):
                    dz = traj[k, i] - traj[k_rev, i]
                    if i == 2 or i == 3:
                        dz -= t_eval[k] - t_eval[k_rev]
                    if not abs(dz) <= lock:  # NaN propagates
                        lock = abs(dz)
            k_rev = k
            n_rev += 1
        if not meas_rows[k] & ROW_MEASURE:
            continue
        tau = t_eval[k]
        e1, e2 = phase_errors(tau, traj[k, 2], traj[k, 3], th1, th2)
        e = max(abs(e1), abs(e2))
        r = math.sqrt(traj[k, 0] * traj[k, 0] + traj[k, 1] * traj[k, 1])
        if not (math.isfinite(e) and math.isfinite(r)):
            return st.NONFINITE
        if k < n_rev1:
            e0 = max(e0, e)
        if k < n_early:
            r_ref = max(r_ref, r)
        if k >= i_late:
            e_late = max(e_late, e)
            r_late = max(r_late, r)
        elif k >= i_prev:
            e_before = max(e_before, e)
        if e > settle:
            last_above = k
            e_last_above = e
        elif last_above >= 0 and last_above == k_prev:
            e_next = e
            k_next = k
        e_prev = e
        k_prev = k
    meas[M_E0] = e0
    meas[M_ELATE] = e_late
    meas[M_RREF] = r_ref
    meas[M_RLATE] = r_late
    meas[M_EFINAL] = e_prev
    meas[M_EPREV] = e_before
    meas[M_LOCK] = lock if n_rev >= 2 else math.inf
    if last_above == k_prev:
        meas[M_TSETTLE] = math.nan  # never settled within the horizon
    elif last_above < 0:
        meas[M_TSETTLE] = 0.0
    else:  # linear interpolation of the last crossing of the threshold (between measurement rows)
        t0 = t_eval[last_above]
        t1 = t_eval[k_next]
        meas[M_TSETTLE] = t0 + (t1 - t0) * (e_last_above - settle) / (e_last_above - e_next)
    for j in range(hist_idx.size if hist.shape[1] > 0 else 0):
        k = hist_idx[j]
        e1, e2 = phase_errors(t_eval[k], traj[k, 2], traj[k, 3], th1, th2)
        hist[0, j] = traj[k, 0]
        hist[1, j] = traj[k, 1]
        hist[2, j] = e1
        hist[3, j] = e2
    return st.OK


@pjit
def simulation_kernel(method, pp, run, delta, t_eval, n_rev1, n_early, i_prev, i_late, rtol, atol, max_steps, settle,
                      hist_idx, meas_rows, hist, meas, code, n_steps, n_rhs):
    literally(method)  # one cached kernel per method
    n = pp.shape[0]
    n_blocks = (n + BLOCK - 1) // BLOCK
    for b in prange(n_blocks):
        work = dop853.workspace(8)
        rwork = radau.workspace(8)
        z = np.empty(8)
        traj = np.empty((t_eval.size, 8))
        for i in range(b, n, n_blocks):
            if not run[i]:
                continue
            c, ns, nr = simulate_point(method, pp[i], delta, t_eval, n_rev1, n_early, i_prev, i_late, rtol, atol,
                                       max_steps, settle, hist_idx, meas_rows, hist[i], z, work, rwork, traj,
                                       meas[i])
            code[i] = c
            n_steps[i] += ns
            n_rhs[i] += nr


# The DOP853 simulations run LANES trajectories side by side per thread (ode/dop853_lanes.py):
# bitwise the results of simulation_kernel, about 3x the steps per second. The lane right-hand
# side took 23 ns per lane with 32 lanes, 24 with 16, 29 with 8, 77 with 4 (the vector loops then
# run in their scalar remainders), 95 ns alone; a whole simulation of 512 points on one thread
# ran 8-10 % faster with 32 lanes than with 16 (one-off measurements, alternating). More lanes
# idle longer at the end of a thread's queue, and 32 lanes' stages (55 kB) already leave L1.
LANES = 32
# Each lane keeps its trajectory's samples (n_eval x 8 floats) until it ends: with long horizons
# or dense sampling fewer lanes are used, so that a thread's samples stay within this budget
# (16, then 8 lanes, else one trajectory at a time, as simulation_kernel always keeps one).
LANE_SAMPLES_BYTES = 256 * 2**20
lane_load, lane_run = dop853_lanes.make_lane_trajectory_solver(rhs_lanes, rhs)


def simulation_lanes(n_eval: int) -> int:
    """Lanes per thread for trajectories of n_eval samples: LANES, 16, 8, or 0 (one at a time)."""
    for lanes in (LANES, 16, 8):
        if lanes * n_eval * 8 * 8 <= LANE_SAMPLES_BYTES:
            return lanes
    return 0


def lane_queues(n_points: int, lanes: int = LANES) -> int:
    """Queues for n points: one per thread (a queue's lanes idle only at its end), fewer when
    there are not lanes / 2 points per thread."""
    return max(1, min(numba.get_num_threads(), -(-n_points // max(1, lanes // 2))))


@jit
def _load_next(ws, lane, i, step, pp, run, delta, t_eval, rtol, atol, z):
    """Load the next point of the queue (i, i + step, ... with run[i]) into the lane, or leave it
    idle; returns the queue position after it."""
    n = pp.shape[0]
    while i < n and not run[i]:
        i += step
    if i >= n:
        dop853_lanes.idle(ws, lane)
        return i
    initial_state(pp[i], delta, z)
    lane_load(ws, lane, i, 0.0, z, pp[i], t_eval, rtol, atol)
    return i + step


@jit
def simulate_queue(lanes, first, step, pp, run, delta, t_eval, n_rev1, n_early, i_prev, i_late, rtol, atol, max_steps,
                   settle, hist_idx, meas_rows, hist, meas, code, n_steps, n_rhs):
    """The points first, first + step, ... (those with run[i]) through the lanes of one thread."""
    ws = dop853_lanes.workspace(8, NP, lanes, t_eval.size)
    traj = ws[dop853_lanes.TRAJ]
    z = np.empty(8)
    nxt = first
    for lane in range(lanes):
        nxt = _load_next(ws, lane, nxt, step, pp, run, delta, t_eval, rtol, atol, z)
    while True:
        lane = lane_run(ws, t_eval, rtol, atol, max_steps)
        if lane < 0:
            return
        i, c, ns, nr = dop853_lanes.lane_result(ws, lane)
        if c == st.OK:
            c = measure(traj[lane], pp[i], t_eval, n_rev1, n_early, i_prev, i_late, settle, hist_idx, meas_rows,
                        hist[i], meas[i])
        code[i] = c
        n_steps[i] += ns
        n_rhs[i] += nr
        nxt = _load_next(ws, lane, nxt, step, pp, run, delta, t_eval, rtol, atol, z)


def simulate_lanes(lanes, pp, run, *args):
    """simulation_kernel's work for DOP853 through the lanes: lane_queues() queues of points, each
    run by simulate_queue (nogil) in a pool of numba.get_num_threads() Python threads, which
    take the next queue as they finish one. A numba parallel loop would do the same, but it
    compiles the whole lane solver once more into its loop body (about 12 s, measured)."""
    n_queues = lane_queues(pp.shape[0], lanes)
    threads = min(numba.get_num_threads(), n_queues)

    def queue(b):
        simulate_queue(lanes, b, n_queues, pp, run, *args)

    if threads == 1:
        for b in range(n_queues):
            queue(b)
        return
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="mechsweep-lanes") as pool:
        for _ in pool.map(queue, range(n_queues)):
            pass


def sample_grid(settings, histories: bool):
    """The tau instants of the simulation samples (identical for every point) and the row
    indices the kernel needs: (t_eval, n_rev1, n_early, i_prev, i_late, hist_idx, meas_rows).
    meas_rows[k] has the bit ROW_MEASURE for the rows of the measurement grid, which depends on
    the settings only (rows only the histories need have not: measure() skips them), and
    ROW_REVOLUTION for the whole revolutions of the second half of the horizon (M_LOCK)."""
    H = float(settings["horizon_revolutions"])
    tau_end = TWO_PI * H
    per_rev = int(settings["monitor_samples_per_revolution"])
    dense = int(settings["residual_samples_per_revolution"])
    tau_late = (1.0 - LATE_FRACTION) * tau_end
    parts = [np.linspace(0.0, tau_end, max(2, int(math.ceil(per_rev * H)) + 1)),
             np.linspace(tau_late, tau_end, max(2, int(math.ceil(dense * LATE_FRACTION * H)) + 1)),
             np.linspace(0.0, TWO_PI * min(1.0, H), per_rev + 1)]
    hist_tau = TWO_PI * history_revolutions(settings) if histories else np.empty(0)
    rev_tau = TWO_PI * np.arange(math.ceil(0.5 * H), math.floor(H) + 1)  # whole revolutions, second half
    t_eval = np.unique(np.concatenate(parts + [hist_tau, rev_tau]))
    n_rev1 = int(np.searchsorted(t_eval, TWO_PI * min(1.0, H), side="right"))
    n_early = int(np.searchsorted(t_eval, EARLY_FRACTION * tau_end, side="right"))
    i_late = int(np.searchsorted(t_eval, tau_late, side="left"))
    i_prev = int(np.searchsorted(t_eval, (1.0 - 2.0 * LATE_FRACTION) * tau_end, side="left"))
    hist_idx = np.searchsorted(t_eval, hist_tau).astype(np.int64)
    meas_rows = np.where(np.isin(t_eval, np.concatenate(parts)), ROW_MEASURE, 0)
    meas_rows |= np.where(np.isin(t_eval, rev_tau), ROW_REVOLUTION, 0)
    return t_eval, n_rev1, n_early, i_prev, i_late, hist_idx, meas_rows.astype(np.int8)


# ----------------------------------------------------------------------------- closed forms (numpy)
def platform(P):
    """Platform frequencies, stiffnesses and damping coefficients from either parametrisation:
    omega^2 = c / M [fix], b = 2 zeta M omega."""
    col = {name: P[:, j] for j, name in enumerate(PARAM_NAMES)}
    M = col["M"]
    with np.errstate(invalid="ignore", divide="ignore"):
        out = {}
        for ax in ("xi", "eta"):
            om = np.where(np.isnan(col[f"omega_{ax}"]), np.sqrt(col[f"c_{ax}"] / M), col[f"omega_{ax}"])
            c = np.where(np.isnan(col[f"c_{ax}"]), M * om * om, col[f"c_{ax}"])
            b = np.where(np.isnan(col[f"b_{ax}"]), 2.0 * col[f"zeta_{ax}"] * M * om, col[f"b_{ax}"])
            out[f"omega_{ax}"], out[f"c_{ax}"], out[f"b_{ax}"] = om, c, b
    return out


def scaled_parameters(Omega, M, m, a, I_B, A0, A1, lam, c_xi, c_eta, b_xi, b_eta, h, th1, th2):
    """The kernels' parameter vectors p (n, NP) from SI values (arrays or floats)."""
    Omega, M, m, a, I_B, A0, A1, lam, c_xi, c_eta, b_xi, b_eta, h, th1, th2 = np.broadcast_arrays(
        *(np.asarray(v, dtype=float) for v in (Omega, M, m, a, I_B, A0, A1, lam, c_xi, c_eta, b_xi,
                                                b_eta, h, th1, th2)))
    p = np.empty(Omega.shape + (NP,))
    p[..., IP_MU] = M / m
    p[..., IP_ALPHA0] = A0 / (m * a)
    p[..., IP_ALPHA1] = A1 / (m * a)
    p[..., IP_LAM] = lam
    p[..., IP_IOTA] = I_B / (m * a * a)
    p[..., IP_KX] = c_xi / (m * Omega**2)
    p[..., IP_KY] = c_eta / (m * Omega**2)
    p[..., IP_DX] = b_xi / (m * Omega)
    p[..., IP_DY] = b_eta / (m * Omega)
    p[..., IP_EH] = h / (m * a * a * Omega)
    p[..., IP_TH1] = th1
    p[..., IP_TH2] = th2
    return p


def receptance_sum(Omega, M, c_xi, c_eta, b_xi, b_eta):
    """P(Omega) = Re(H_xi + H_eta), H_j = 1 / (c_j - M Omega^2 + i b_j Omega) (m/N)."""
    total = 0.0
    for c, b in ((c_xi, b_xi), (c_eta, b_eta)):
        d = c - M * Omega**2
        total = total + d / (d * d + (b * Omega) ** 2)
    return total


def _worse(current, new):
    """Element-wise the more severe of two status arrays (SEVERITY order)."""
    rank = np.empty(max(SEVERITY) + 2, dtype=np.int64)
    rank[:] = len(SEVERITY)
    for r, code in enumerate(SEVERITY):
        rank[code] = r
    new = np.broadcast_to(np.asarray(new, dtype=current.dtype), current.shape)
    return np.where(rank[new] < rank[current], new, current)


# ----------------------------------------------------------------------------- engine entry point
BALANCED_OUTPUTS = ("theta", "floquet_max", "stable_floquet", "stable_sim", "phase_error", "settling_time")
SIM_OUTPUTS = ("stable_sim", "residual_amplitude", "phase_error", "settling_time",
               "xi_history", "eta_history", "phase_error1_history", "phase_error2_history")
HISTORIES = ("xi_history", "eta_history", "phase_error1_history", "phase_error2_history")


def evaluate(P, wanted, solver, out, status, n_steps, n_rhs):
    n = P.shape[0]
    col = {name: np.ascontiguousarray(P[:, j]) for j, name in enumerate(PARAM_NAMES)}
    Omega, M, m, a, I_B, A0, A1 = (col[k] for k in ("Omega", "M", "m", "a", "I_B", "A0", "A1"))
    l3, l4 = col["l3"], col["l4"]
    pf = platform(P)
    code = np.full(n, st.OK, dtype=status.dtype)

    with np.errstate(invalid="ignore", divide="ignore"):
        # physical domain of a point
        lengths_given = ~np.isnan(l3) & ~np.isnan(l4)
        # I_B >= m a^2 with a relative slack of IB_SLACK: I_B = m a^2 typed as numbers must pass
        feasible = (I_B >= m * a * a * (1.0 - IB_SLACK)) & (M > 2.0 * m)
        feasible &= np.isfinite(pf["omega_xi"]) & np.isfinite(pf["omega_eta"])
        feasible &= np.isfinite(pf["b_xi"]) & np.isfinite(pf["b_eta"])
        feasible &= ~lengths_given | (l3 < l4)
        feasible &= (A1 == 0.0) | lengths_given
        code[~feasible] = st.INFEASIBLE
        lam = np.where((A1 != 0.0) & lengths_given, l3 / l4, 0.0)

        two_ma = 2.0 * m * a
        has_balance = (A0 <= two_ma) & (A1 == 0.0)  # eq. (8) with the factor 2 [fix]
        isolated = has_balance & (A0 > 0.0) & (A0 < two_ma)
        ratio = np.clip(-A0 / two_ma, -1.0, 1.0)
        theta_ref = np.where(A0 <= two_ma, np.arccos(ratio), math.pi)  # eq. (8); pi: opposite the unbalance
        th2_ref = np.where(A0 <= two_ma, -theta_ref, math.pi)

        wants = set(wanted)
        if wants & set(BALANCED_OUTPUTS):
            need_isolated = wants & set(BALANCED_OUTPUTS) - {"theta"}
            bad = ~isolated if need_isolated else ~has_balance
            code = _worse(code, np.where(bad & feasible, st.NOT_BALANCEABLE, st.OK))

        if "theta" in wants:
            out["theta"][:] = np.where(has_balance & feasible, theta_ref, np.nan)
        if "balanceable" in wants:
            out["balanceable"][:] = np.where(feasible, has_balance.astype(float), np.nan)
        if "m_k" in wants:  # eq. (6)
            out["m_k"][:] = np.where(feasible, (col["m4"] * col["S4"] + col["m5"] * l4) / col["S_k"], np.nan)
        wx, wy = pf["omega_xi"], pf["omega_eta"]
        if "omega_p" in wants:
            out["omega_p"][:] = np.where(feasible, np.sqrt(0.5 * (wx * wx + wy * wy)), np.nan)
        if "stable_first_approx" in wants:
            lo, hi = np.minimum(wx, wy), np.maximum(wx, wy)  # omega_xi < omega_eta assumed: sort them
            wp = np.sqrt(0.5 * (wx * wx + wy * wy))
            first = ((lo < Omega) & (Omega < wp)) | (Omega > hi)  # [fix]: "or"
            out["stable_first_approx"][:] = np.where(feasible, first.astype(float), np.nan)
        if "P_approx" in wants:
            Pv = receptance_sum(Omega, M, pf["c_xi"], pf["c_eta"], pf["b_xi"], pf["b_eta"])
            singular = feasible & ~np.isfinite(Pv)  # undamped resonance: c = M Omega^2, b = 0
            code = _worse(code, np.where(singular, st.SINGULAR, st.OK))
            ok = feasible & ~singular
            out["P_approx"][:] = np.where(ok, Pv, np.nan)
            if "stable_damped_approx" in wants:
                out["stable_damped_approx"][:] = np.where(ok, (Pv < 0.0).astype(float), np.nan)

        pp = scaled_parameters(Omega, M, m, a, I_B, A0, A1, lam, pf["c_xi"], pf["c_eta"], pf["b_xi"],
                               pf["b_eta"], col["h"], theta_ref, th2_ref)

    if "floquet_max" in wants:
        run = feasible & isolated
        value = np.full(n, np.nan)
        fcode = np.zeros(n, dtype=np.int8)
        if run.any():
            call_with_literal(floquet_kernel, METHOD_CODES[solver.method], pp, run, solver.rtol, solver.atol,
                              solver.max_steps, value, fcode, n_steps, n_rhs)
        code = _worse(code, fcode)
        good = run & (fcode == st.OK)
        out["floquet_max"][:] = np.where(good, value, np.nan)
        if "stable_floquet" in wants:
            # measured: |error of floquet_max| <= 0.13 rtol (rtol 1e-6 ... 5e-11, 400 random points)
            margin = max(float(solver.settings["floquet_margin"]), 100.0 * solver.rtol)
            decided = good & (np.abs(value - 1.0) > margin)
            code = _worse(code, np.where(good & ~decided, st.UNDECIDED, st.OK))
            out["stable_floquet"][:] = np.where(decided, (value < 1.0).astype(float), np.nan)

    sim_wanted = wants & set(SIM_OUTPUTS)
    if sim_wanted:
        _simulate(sim_wanted, solver, pp, feasible, isolated, Omega, a, code, out, n_steps, n_rhs)
    status[:] = _worse(status, code)


def _simulate(wants, solver, pp, feasible, isolated, Omega, a, code, out, n_steps, n_rhs):
    s = solver.settings
    histories = bool(wants & set(HISTORIES))
    always = wants - set(BALANCED_OUTPUTS)  # residual amplitude and histories: every feasible point
    run = feasible & (isolated | bool(always))
    meas, hist, scode = integrate(solver.method, pp, run, s, histories, solver.rtol, solver.atol, solver.max_steps,
                                  n_steps, n_rhs)
    code[:] = _worse(code, scode)
    good = run & (scode == st.OK)
    bal = good & isolated
    values, vcode = sim_values(wants, s, meas, hist, good, bal)
    code[:] = _worse(code, vcode)
    factor = float(s["reproducibility_factor"])
    check = good & recheck_needed(s, meas, good, solver.rtol, solver.atol) & (factor > 0.0)
    if check.any():
        tight = tighter_rtol(solver.rtol)
        meas2, hist2, scode2 = integrate(solver.method, pp, check, s, histories, tight, solver.atol,
                                         solver.max_steps, n_steps, n_rhs)
        good2 = check & (scode2 == st.OK)
        values2, _ = sim_values(wants, s, meas2, hist2, good2, good2 & isolated)
        moved = ~good2 & check  # the tighter run failed: the value could not be confirmed
        for name, v in values.items():
            moved |= check & _moved(v, values2[name], solver.rtol, solver.atol, factor)
        code[:] = _worse(code, np.where(moved, st.NOT_REPRODUCIBLE, st.OK))
    for name, v in values.items():  # to SI units
        if name == "settling_time":
            v = v / Omega
        elif name in ("residual_amplitude", "xi_history", "eta_history"):
            v = v * (a if v.ndim == 1 else a[:, None])
        out[name][:] = v


def integrate(method, pp, run, settings, histories, rtol, atol, max_steps, n_steps, n_rhs, lanes=True):
    """The perturbed-balanced-state simulations of the points with run[i], by ``method`` at
    (rtol, atol); steps and evaluations are added to n_steps, n_rhs. Returns (meas, hist, code):
    the measurements (N_MEAS per point), the history samples (n, 4, k) and the status per point.
    DOP853 runs in SIMD lanes unless ``lanes`` is False (the same results, bitwise)."""
    n = pp.shape[0]
    t_eval, n_rev1, n_early, i_prev, i_late, hist_idx, meas_rows = sample_grid(settings, histories)
    hist = np.full((n, 4, hist_idx.size), np.nan) if histories else np.empty((n, 4, 0))
    meas = np.full((n, N_MEAS), np.nan)
    scode = np.zeros(n, dtype=np.int8)
    args = (pp, run, float(settings["perturbation"]), t_eval, n_rev1, n_early, i_prev, i_late, rtol, atol,
            max_steps, float(settings["settle_threshold"]), hist_idx, meas_rows, hist, meas, scode, n_steps, n_rhs)
    lanes = simulation_lanes(t_eval.size) if lanes else 0
    if run.any():
        if method == "dop853" and lanes:
            simulate_lanes(lanes, *args)
        else:
            call_with_literal(simulation_kernel, METHOD_CODES[method], *args)
    return meas, hist, scode


def sim_values(wants, s, meas, hist, good, bal):
    """The simulation outputs asked for, in scaled units (lengths / a, time tau = Omega t), from
    the measurements, and the status their rules give (NO_EVENT, UNDECIDED)."""
    n = meas.shape[0]
    code = np.zeros(n, dtype=np.int8)
    values = {}
    e0, e_late, r_ref, r_late, e_final, t_settle, e_before, _ = meas.T
    if "residual_amplitude" in wants:
        values["residual_amplitude"] = np.where(good, r_late, np.nan)
    if "phase_error" in wants:
        values["phase_error"] = np.where(bal, e_final, np.nan)
    if "settling_time" in wants:
        settled = bal & np.isfinite(t_settle)
        code = _worse(code, np.where(bal & ~settled, st.NO_EVENT, st.OK))
        values["settling_time"] = np.where(settled, t_settle, np.nan)
    if "stable_sim" in wants:
        decay, growth = float(s["decay_ratio"]), float(s["growth_ratio"])
        settle = float(s["settle_threshold"])
        with np.errstate(invalid="ignore"):
            stable = (e_late <= settle) & (e_late <= decay * e0) & (r_late <= decay * r_ref)
            # not still growing at the end (a weak unstable mode that has just become dominant);
            # below 1e-3 settle_threshold the error is at the integration noise floor: no trend test
            stable &= (e_late <= e_before) | (e_late <= 1e-3 * settle)
            unstable = (e_late >= growth * e0) & (e_before >= growth * e0)  # departed, and stayed away
        decided = bal & (stable | unstable)
        code = _worse(code, np.where(bal & ~decided, st.UNDECIDED, st.OK))
        values["stable_sim"] = np.where(decided, stable.astype(float), np.nan)
    g = good[:, None]
    for k, name in enumerate(HISTORIES):
        if name in wants:
            values[name] = np.where(g, hist[:, k, :], np.nan)
    return values, code


# Reproducibility check (status NOT_REPRODUCIBLE). The simulated outputs of a trajectory that
# leaves the balanced state, or wanders for long before it settles, can be dominated by chaotic
# transients: their values then move by per cent between tolerances, although every step met
# the tolerance. Such points are integrated a second time at TIGHTEN times smaller rtol (the
# same atol, the same method) and every requested simulation output is compared; a point whose
# output moves by more than reproducibility_factor (rtol |v| + atol) (scaled units: lengths in
# units of a, angles in rad, time in tau = Omega t; histories sample by sample), whose stable_sim
# verdict changes, or whose tighter integration fails, gets NOT_REPRODUCIBLE. The first values
# are kept (bitwise as without the check); only the status says that their digits are not all
# meaningful. Not re-integrated (recheck_needed): trajectories that settled within the first
# SETTLED_FRACTION of the horizon, or whose state repeats from revolution to revolution through
# the second half; they end on an attracting periodic motion, on which integration errors decay.
# Measured: checking every point flagged no point that this selection skips (1,860
# points: random mechanisms at rtol 5e-11 and 1e-8, sweeps/autobalancer_residual.toml and
# autobalancer_stability_chart.toml); 40-59 % of the points are integrated again, and the
# simulated outputs cost 1.8x (one thread; the second run takes ~1.1-1.2x the first's steps).
# Skipped points whose value sits at the noise floor (|value| ~ atol) may still move by a large
# relative amount: the tolerance is rtol |value| + atol, the integrator's own.
TIGHTEN = 100.0
RTOL_TIGHT_FLOOR = 1e-14
SETTLED_FRACTION = 0.5


def tighter_rtol(rtol):
    """The rtol of the second integration: TIGHTEN times smaller, not below RTOL_TIGHT_FLOOR
    (unless rtol itself is below it)."""
    return min(rtol, max(rtol / TIGHTEN, RTOL_TIGHT_FLOOR))


def recheck_needed(settings, meas, good, rtol, atol):
    """Points whose simulation is integrated again for the reproducibility check: every
    successful trajectory except those that settled early (phase error below settle_threshold
    from the first SETTLED_FRACTION of the horizon on) and those locked to the crank period
    through the whole second half (the state changes by at most reproducibility_factor
    (rtol + atol) per revolution, M_LOCK): both end on an attracting periodic motion. A function
    of the point's own measurements only, so the decision does not depend on the other points
    or outputs."""
    tau_end = TWO_PI * float(settings["horizon_revolutions"])
    factor = float(settings["reproducibility_factor"])
    t_settle = meas[:, M_TSETTLE]
    with np.errstate(invalid="ignore"):
        early = np.isfinite(t_settle) & (t_settle <= SETTLED_FRACTION * tau_end)
        locked = meas[:, M_LOCK] <= factor * (rtol + atol)
    return good & ~early & ~locked


def _moved(v, v2, rtol, atol, factor):
    """True where the two values differ by more than factor (rtol |v| + atol), or where one is
    NaN and the other not; rows of a history compare sample by sample (any sample moved)."""
    with np.errstate(invalid="ignore"):
        tol = factor * (rtol * np.maximum(np.abs(v), np.abs(v2)) + atol)
        bad = (np.abs(v - v2) > tol) | (np.isnan(v) != np.isnan(v2))
    return bad.reshape(bad.shape[0], -1).any(axis=1)


# ----------------------------------------------------------------------------- the reference ModelSpec
SPEC = ModelSpec(
    name="autobalancer",
    description="Slider-crank on an elastic platform balanced by two pendulums on the crank axis",
    source="Dubovik & Zamyatin, static balancing of a slider-crank mechanism, eq. (1)-(8); physics.md section 2",
    params=PARAMS,
    outputs=OUTPUTS,
    evaluate=evaluate,
    settings=SETTINGS,
    check=check,
    methods=("dop853", "radau", "auto"),
    statuses=STATUSES,
    status_notes=STATUS_NOTES,
)
