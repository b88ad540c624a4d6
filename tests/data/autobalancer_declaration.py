"""The whole auto-balancer declared on the model layer (not the shipped model: docs/model-layer.md,
"What issue 13 still needs"): the closed forms of tests/data/autobalancer_closed_on_layer.py, the
dynamics of tests/data/autobalancer_on_layer.py (physics kernels imported from
models/autobalancer.py), and the status rules of the hand-written model expressed by the layer's
generic ones: the model's classify (INFEASIBLE), the balanced-state measurements' own classify
(Floquet and the Kick: NOT_BALANCEABLE without an isolated balanced state; residual and histories
at every feasible point), ``status_order`` = the old SEVERITY, and the Recheck with the old rule's
two skips (settled in the first half; locked to the crank period, the pendulum angles less one turn
per revolution) compared in scaled units.

``python tests/data/autobalancer_declaration.py [prefix]`` compares it with
tests/data/autobalancer_reference.npz (tests/data/record_autobalancer.py) on the design-grid cases
(prefix "grid-...") or the small shipped scenes ("scene-...") (the old output names, symbols, units
and long names given by ``output_meta``; the old cross-parameter rules by ``check``): per case and array, bitwise or the largest
relative difference. Floquet integrates the state with the variational equations (the old kernel:
about the exact orbit), so floquet_max is compared to a tolerance.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from mechsweep import status as st
from mechsweep.model import ClosedForm, Floquet, History, Kick, OdeModel, Recheck, Steady
from mechsweep.models import autobalancer as ab

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import autobalancer_closed_on_layer as cl  # noqa: E402
import autobalancer_on_layer as dyn  # noqa: E402

IX = {name: j for j, name in enumerate(ab.PARAM_NAMES)}
I_M, I_m, I_a, I_A0, I_A1 = (IX[k] for k in ("M", "m", "a", "A0", "A1"))
OFF = dyn.OFF


def isolated(p):
    """An isolated balanced state: 0 < A0 < 2 m a and A1 = 0 (else NOT_BALANCEABLE)."""
    two_ma = 2.0 * p[I_m] * p[I_a]
    return st.OK if (p[I_A0] > 0.0 and p[I_A0] < two_ma and p[I_A1] == 0.0) else st.NOT_BALANCEABLE


def phase_error1(t, z, p):
    return ab.phase_errors(t, z[2], z[3], p[OFF + ab.IP_TH1], p[OFF + ab.IP_TH2])[0]


def phase_error2(t, z, p):
    return ab.phase_errors(t, z[2], z[3], p[OFF + ab.IP_TH1], p[OFF + ab.IP_TH2])[1]


def eta(t, z, p):
    return z[1]


H = "horizon_revolutions"
HIST = dict(horizon=H, samples="trajectory_samples", dim="revolution", dim_long_name=ab.REVOLUTION.long_name)


def old(name):
    """The hand-written model's symbol, unit and long name of an output (output_meta's fields)."""
    o = ab.SPEC.output(name)
    return dict(symbol=o.symbol, unit=o.unit, long_name=o.long_name)


def history(name, of, **kw):
    return History(name, of, output_meta={name: old(name)}, **HIST, **kw)


def closed_form(c):
    """A closed form of autobalancer_closed_on_layer.py with the old output's metadata."""
    o = ab.SPEC.output(c.name)
    return ClosedForm(c.name, c.func, needs=c.needs, classify=c.classify, symbol=o.symbol, unit=o.unit,
                      long_name=o.long_name, output_needs=o.needs, needs_params=o.needs_params, kind=o.kind)


SEVERITY = (st.INFEASIBLE, st.NONFINITE, st.STEP_UNDERFLOW, st.MAX_STEPS, st.SINGULAR, st.NOT_REPRODUCIBLE,
            st.NOT_BALANCEABLE, st.UNDECIDED, st.NO_EVENT)
MODEL = OdeModel(
    name="autobalancer_declared", description="the auto-balancer declared on the layer (experiment)",
    params=ab.SPEC.params, settings=ab.SETTINGS, internal=tuple(f"q{j}" for j in range(ab.NP)),
    states=("x", "y", "g1", "g2", "xd", "yd", "w1", "w2"), rhs=dyn.rhs, initial=dyn.initial, jac=dyn.jac,
    forcing_period=dyn.forcing, classify=cl.classify, prepare=dyn.prepare, rhs_lanes=dyn.rhs_lanes,
    measurements=(
        Floquet("floquet_max", initial=dyn.balanced, stable_name="stable_floquet", classify=isolated,
                output_meta={"floquet_max": old("floquet_max"), "floquet_max_stable": old("stable_floquet")}),
        Kick("stable_sim", dyn.phase_error, dyn.platform, horizon=H, settle_threshold="settle_threshold",
             decay_ratio="decay_ratio", growth_ratio="growth_ratio",
             monitor_per_period="monitor_samples_per_revolution",
             dense_per_period="residual_samples_per_revolution", time_value=dyn.to_seconds, classify=isolated,
             output_meta={"stable_sim": old("stable_sim"),
                          "stable_sim_settling": dict(name="settling_time", **old("settling_time")),
                          "stable_sim_final": dict(name="phase_error", **old("phase_error"))}),
        Steady("residual_amplitude", dyn.platform, horizon=H, window=0.1,
               samples_per_period="residual_samples_per_revolution", settle_rtol=None, value=dyn.to_metres,
               output_meta={"residual_amplitude": old("residual_amplitude")}),
        history("xi_history", dyn.xi, value=dyn.to_metres),
        history("eta_history", eta, value=dyn.to_metres),
        history("phase_error1_history", phase_error1),
        history("phase_error2_history", phase_error2),
    ),
    closed_forms=tuple(closed_form(c) for c in cl.MODEL.closed_forms),
    status_order=SEVERITY, check=ab.check,
    recheck=Recheck(factor="reproducibility_factor", skip_settled="stable_sim", skip_locked=True,
                    lock_rates=(("g1", 1.0), ("g2", 1.0)), measured_units=True),
)


def evaluate(spec, P, wanted, kw):
    from mechsweep.scene import Solver
    solver = Solver.for_model(spec, **kw)
    n = P.shape[0]
    out = {k: np.full((n,) + tuple(len(d.values(solver.settings)) for d in spec.output(k).extra_dims), np.nan)
           for k in wanted}
    status, ns, nr = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
    with np.errstate(all="ignore"):
        spec.evaluate(P, tuple(wanted), solver, out, status, ns, nr)
    return {**{k: out[k] for k in wanted}, "status": status, "n_steps": ns, "n_rhs": nr}


def compare(prefix="grid-", floquet_tol=0.1):
    """{(case, array): (verdict, detail)}: 'bitwise', 'tolerance' (floquet_max within floquet_tol
    times the case's rtol, relative, NaN at the same points; n_steps and n_rhs of a case that asks
    for floquet_max: Floquet integrates other equations, the steps differ) or 'DIFFERENT'."""
    import record_autobalancer as rec
    from mechsweep.model import load
    spec = load.resolve(f"{Path(__file__).resolve()}:MODEL")
    ref = np.load(rec.FILE)
    result = {}
    for label, P, wanted, kw in rec.design_cases():
        if not label.startswith(prefix):
            continue
        res = evaluate(spec, P, wanted, kw)
        for k, v in res.items():
            e = ref[f"{label}/{k}"]
            verdict, rel, nan = _verdict(k, e, v, floquet_tol * kw["rtol"], "floquet_max" in wanted)
            if verdict == "bitwise":
                result[(label, k)] = (verdict, "")
                continue
            where = np.flatnonzero((e != v).reshape(e.shape[0], -1).any(axis=1)) if e.ndim else []
            detail = f"max rel {rel:.3g}, NaN moved at {nan}, points {list(where)[:8]}"
            if k == "status":
                detail += f" old {[int(x) for x in e[where][:8]]} new {[int(x) for x in v[where][:8]]}"
            result[(label, k)] = (verdict, detail)
    return result


def _verdict(k, e, v, floquet_tol, floquet_wanted):
    """("bitwise" | "tolerance" | "DIFFERENT", max relative difference, NaNs moved) of output k, new v
    against reference e: floquet_max may differ within floquet_tol (its own integration), and
    n_steps/n_rhs where floquet_max is computed (its steps count)."""
    if np.array_equal(e, v.astype(e.dtype), equal_nan=True):
        return "bitwise", 0.0, 0
    with np.errstate(all="ignore"):
        both = np.isfinite(e) & np.isfinite(v)
        rel = float(np.max(np.abs(v - e)[both] / np.maximum(np.abs(e[both]), 1e-300))) if both.any() else 0.0
    nan = int((np.isnan(e.astype(float)) != np.isnan(v.astype(float))).sum())
    ok = k == "floquet_max" and nan == 0 and rel <= floquet_tol
    ok = ok or (k in ("n_steps", "n_rhs") and floquet_wanted)
    return ("tolerance" if ok else "DIFFERENT"), rel, nan


def compare_scenes(prefix="scene-", floquet_tol=0.1):
    """As compare, on the small versions of the shipped auto-balancer scenes (record_autobalancer's
    scene cases): each scene's points and outputs, the runner's rule (a non-finite requested value:
    NONFINITE) applied as runner.evaluate_rows does."""
    import record_autobalancer as rec
    from mechsweep.model import load
    from mechsweep.grid import ParameterMatrix
    from mechsweep.scene import load_scene
    spec = load.resolve(f"{Path(__file__).resolve()}:MODEL")
    ref = np.load(rec.FILE)
    result = {}
    for label, path, method in rec.scene_cases():
        if not label.startswith(prefix):
            continue
        scene = load_scene(rec.small_scene(path, method))
        P = ParameterMatrix(scene)(0, scene.n_points)
        slv = scene.solver
        kw = dict(slv.settings, method=slv.method, rtol=slv.rtol, atol=slv.atol, max_steps=slv.max_steps)
        res = evaluate(spec, P, tuple(scene.computed_outputs), kw)
        n = P.shape[0]
        finite = np.ones(n, dtype=bool)
        for k in scene.outputs:
            finite &= np.isfinite(res[k].reshape(n, -1)).all(axis=1)
            res[k][np.isinf(res[k])] = np.nan
        res["status"][(res["status"] == st.OK) & ~finite] = st.NONFINITE
        for k in tuple(scene.outputs) + ("status", "n_steps", "n_rhs"):
            v, e = res[k], ref[f"{label}/{k}"]
            verdict, rel, nan = _verdict(k, e, v, floquet_tol * slv.rtol, "floquet_max" in scene.computed_outputs)
            result[(label, k)] = (verdict, "" if verdict == "bitwise" else f"max rel {rel:.3g}, NaN moved at {nan} of {n}")
    return result


def main(prefix="grid-"):
    r = compare_scenes(prefix) if prefix.startswith("scene") else compare(prefix)
    for (label, k), (verdict, detail) in r.items():
        if verdict != "bitwise":
            print(f"{label} {k}: {verdict} {detail}")
    counts = {v: sum(1 for x, _ in r.values() if x == v) for v in ("bitwise", "tolerance", "DIFFERENT")}
    print(counts)
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:2]))
