"""Record the auto-balancer's values before it moves onto the model layer:
``python tests/data/record_autobalancer.py [record|stiff|compare]``.

``record`` writes tests/data/autobalancer_reference.npz with the CURRENT code; it was run once on
commit 016a0b6 (the hand-written kernels, now tests/reference/autobalancer_kernels.py). ``stiff``
re-stamps, from those kernels as they are now, the statuses the dop853 solver's stiffness test
turned from MAX_STEPS into STIFF (a step budget spent at the stability limit; the test changes no
step): only those entries change, and it stops if the kernels differ from the file anywhere else.
Re-stamped so: point 25 of the design grid (the stiff platform, h = 1e4) in every grid-dop853 case,
points 9-11 of scene-autobalancer_damping_range-dop853 and 2, 5, 8 of
scene-autobalancer_stiff_platform-dop853. ``compare [prefix]``
computes every case (whose label starts with prefix) again with the model as registered (since the
swap: the layer declaration, models/autobalancer.py) and reports, per array, whether it is bitwise
equal to the file, within the documented tolerance (``verdict``: residual_amplitude 1 ulp; since
Floquet runs on the model's own variational system, floquet_max, n_steps and n_rhs must be bitwise)
or DIFFERENT (exit 1). Cases (outputs, status, n_steps, n_rhs of each):
- a 40-point design grid with every status the model gives (INFEASIBLE, SINGULAR, NOT_BALANCEABLE,
  UNDECIDED, NO_EVENT, NOT_REPRODUCIBLE, MAX_STEPS; A1 != 0 with the conrod; c/b parametrisation),
  all outputs (with 7 history samples), each simulated output alone, by dop853, radau and auto,
  at a short horizon (20 revolutions); a step budget; a tight and a loose tolerance;
- small versions of every shipped auto-balancer scene (sweeps/autobalancer_*.toml and
  sweeps/extreme/autobalancer_*.toml): each range axis cut to at most 4 values, horizon 20
  revolutions, by dop853, radau and auto.
"""
from __future__ import annotations

import itertools
import math
import sys
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
FILE = HERE / "autobalancer_reference.npz"
METHODS = ("dop853", "radau", "auto")
SCENES = sorted(REPO.glob("sweeps/autobalancer_*.toml")) + sorted(REPO.glob("sweeps/extreme/autobalancer_*.toml"))
HORIZON = 20.0
ALL = ("theta", "balanceable", "m_k", "omega_p", "stable_first_approx", "P_approx", "stable_damped_approx",
       "floquet_max", "stable_floquet", "stable_sim", "residual_amplitude", "phase_error", "settling_time",
       "xi_history", "eta_history", "phase_error1_history", "phase_error2_history")
SIM = ("stable_sim", "residual_amplitude", "phase_error", "settling_time", "xi_history")


def design_points() -> np.ndarray:
    from mechsweep.models.autobalancer import PARAM_NAMES

    nan = math.nan
    base = dict(Omega=25.0, M=20.0, m=1.0, a=0.1, I_B=0.012, A0=0.1, h=0.02, omega_xi=20.0, omega_eta=30.0,
                zeta_xi=0.05, zeta_eta=0.05, c_xi=nan, c_eta=nan, b_xi=nan, b_eta=nan, A1=0.0, l3=nan, l4=nan,
                m4=nan, S4=nan, m5=nan, S_k=nan)
    rows = []
    for Om, h in itertools.product((8.0, 15.0, 25.0, 45.0), (0.002, 0.02, 0.5)):  # stable and unstable
        rows.append(dict(base, Omega=Om, h=h))
    for A0 in (0.0, 0.1999999998, 0.2, 0.3):  # NOT_BALANCEABLE ends and beyond the limit
        rows.append(dict(base, A0=A0, Omega=40.0))
    rows.append(dict(base, A1=0.02, l3=0.05, l4=0.2, m4=0.5, S4=0.1, m5=0.3, S_k=0.05))  # uncorrected conrod
    rows.append(dict(base, A1=0.02, l3=0.05, l4=0.2, Omega=45.0, A0=0.3))
    rows.append(dict(base, I_B=0.005))  # INFEASIBLE: I_B < m a^2
    rows.append(dict(base, M=1.5))  # INFEASIBLE: M <= 2 m
    rows.append(dict(base, A1=0.02))  # INFEASIBLE: A1 without l3, l4
    rows.append(dict(base, omega_xi=nan))  # INFEASIBLE: pair not given
    rows.append(dict(base, Omega=20.0, zeta_xi=0.0))  # SINGULAR: undamped resonance
    rows.append(dict(base, omega_xi=nan, omega_eta=nan, c_xi=8000.0, c_eta=18000.0, zeta_xi=nan, zeta_eta=nan,
                     b_xi=20.0, b_eta=30.0))  # the c/b parametrisation
    rows.append(dict(base, m=1e-5, I_B=1e-7, A0=1e-6, h=2e-6))  # light pendulum: UNDECIDED
    rows.append(dict(base, Omega=3.0, omega_xi=400.0, omega_eta=600.0, h=1e4))  # stiff platform
    rows.append(dict(base, Omega=3.0, omega_xi=400.0, omega_eta=600.0, h=1e-6))
    rows.append(dict(base, h=1e-6, Omega=15.0))
    rows.append(dict(base, M=4.0, Omega=35.0, h=0.005))  # heavy pendulums
    rows.append(dict(base, M=5.0, Omega=12.0, h=0.02))
    for Om in (22.0, 26.0, 31.0):
        rows.append(dict(base, M=6.0, Omega=Om, h=0.01))
    return np.array([[r[k] for k in PARAM_NAMES] for r in rows], dtype=float)


def design_cases():
    P = design_points()
    out = []
    hist = dict(trajectory_samples=7)
    for method in METHODS:
        kw = dict(method=method, rtol=1e-8, atol=1e-10, horizon_revolutions=HORIZON, **hist)
        out.append((f"grid-{method}-all", P, ALL, kw))
        for name in SIM:
            out.append((f"grid-{method}-{name}", P, (name,), kw))
        out.append((f"grid-{method}-floquet", P, ("floquet_max", "stable_floquet"), kw))
        out.append((f"grid-{method}-maxsteps", P, ("floquet_max", "residual_amplitude", "stable_sim"),
                    dict(kw, max_steps=300)))
    out.append(("grid-dop853-loose", P, ALL, dict(method="dop853", rtol=1e-5, atol=1e-8, horizon_revolutions=HORIZON,
                                                     **hist)))
    out.append(("grid-dop853-tight", P, ALL, dict(method="dop853", rtol=1e-11, atol=1e-13,
                                                     horizon_revolutions=HORIZON, **hist)))
    out.append(("grid-dop853-norecheck", P, SIM, dict(method="dop853", rtol=1e-8, atol=1e-10,
                                                         horizon_revolutions=HORIZON, reproducibility_factor=0.0)))
    return out


def small_scene(path: Path, method: str) -> dict:
    raw = tomllib.loads(path.read_text())
    for name, ax in raw["axes"].items():
        if isinstance(ax, dict):
            ax["num"] = min(int(ax["num"]), 4)
    raw.pop("storage", None)
    raw.pop("boundaries", None)
    solver = raw.setdefault("solver", {})
    solver["method"] = method
    solver["horizon_revolutions"] = HORIZON
    return raw


def scene_cases():
    return [(f"scene-{p.stem}-{m}", p, m) for p in SCENES for m in METHODS]


def evaluate_case(P, wanted, kw, spec=None):
    """The arrays of one design case by the registered model (spec: another ModelSpec instead)."""
    from mechsweep.models import MODELS
    from mechsweep.scene import Solver

    spec = MODELS["autobalancer"] if spec is None else spec
    solver = Solver.for_model(spec, **kw)
    return _evaluate(spec, P, wanted, solver)


def _evaluate(spec, P, wanted, solver):
    n = P.shape[0]
    out = {}
    for name in wanted:
        o = spec.output(name)
        extra = tuple(len(d.values(solver.settings)) for d in o.extra_dims)
        out[name] = np.full((n,) + extra, np.nan)
    status = np.zeros(n, dtype=np.int8)
    n_steps = np.zeros(n, dtype=np.int64)
    n_rhs = np.zeros(n, dtype=np.int64)
    with np.errstate(all="ignore"):
        spec.evaluate(P, wanted, solver, out, status, n_steps, n_rhs)
    return {**out, "status": status, "n_steps": n_steps, "n_rhs": n_rhs}


def evaluate_scene(path, method):
    from mechsweep.chunks import Chunk
    from mechsweep.execution.execute import evaluate_chunk
    from mechsweep.scene import load_scene

    scene = load_scene(small_scene(path, method))
    cols, status, n_steps, n_rhs = evaluate_chunk(scene, Chunk(0, 0, scene.n_points, ()))
    return {**cols, "status": status, "n_steps": n_steps, "n_rhs": n_rhs}


def reference_spec():
    """The hand-written kernels' ModelSpec (tests/reference/autobalancer_kernels.py)."""
    if str(REPO) not in sys.path:
        sys.path.insert(0, str(REPO))
    from tests.reference import autobalancer_kernels

    return autobalancer_kernels.SPEC


def reference_arrays(select=None):
    """(label, arrays) of every case (select: a filter on the label) by the hand-written kernels as
    they are now; a scene's points and solver as the scene gives them."""
    from mechsweep.grid import parameter_matrix
    from mechsweep.scene import load_scene

    spec = reference_spec()
    for label, P, wanted, kw in design_cases():
        if select is None or select(label):
            yield label, evaluate_case(P, wanted, kw, spec)
    for label, path, method in scene_cases():
        if select is None or select(label):
            scene = load_scene(small_scene(path, method))
            P = parameter_matrix(scene, 0, scene.n_points)
            yield label, _evaluate(spec, P, tuple(scene.computed_outputs), scene.solver)


def all_arrays(select=None):
    """(label, arrays, rtol, floquet_max asked for) of every case (select: a filter on the label)."""
    for label, P, wanted, kw in design_cases():
        if select is None or select(label):
            yield label, evaluate_case(P, wanted, kw), kw["rtol"], "floquet_max" in wanted
    for label, path, method in scene_cases():
        if select is None or select(label):
            from mechsweep.scene import load_scene
            scene = load_scene(small_scene(path, method))
            yield (label, evaluate_scene(path, method), scene.solver.rtol,
                   "floquet_max" in scene.computed_outputs)


# What the model on the layer may change against the hand-written kernels' reference (docs/model-layer.md):
RESIDUAL_ULP = 1e-15  # residual_amplitude: 1 ulp (sample instants t = T s against a linspace in tau)
# floquet_max (and the n_steps/n_rhs of the cases that ask for it) had 0.1 rtol while the layer
# integrated the state with the variational equations (72 against 64); the declaration's own
# variational system (Floquet(variational=...)) gives them bitwise: no tolerance any more


def verdict(k, e, v, rtol=None, floquet_wanted=None, max_steps=None):
    """("bitwise" | "tolerance" | "DIFFERENT", max relative difference, NaNs moved) of array k, new v
    against reference e: residual_amplitude within RESIDUAL_ULP (relative; NaN at the same points);
    everything else (floquet_max, n_steps, n_rhs, every status among it) bitwise. (rtol,
    floquet_wanted, max_steps: the callers' former arguments, no longer used.)"""
    if e.dtype == v.dtype and np.array_equal(e, v, equal_nan=True):
        return "bitwise", 0.0, 0
    with np.errstate(all="ignore"):
        both = np.isfinite(e) & np.isfinite(v)
        rel = float(np.max(np.abs(v - e)[both] / np.maximum(np.abs(e[both]), 1e-300))) if both.any() else 0.0
        moved = np.isnan(e.astype(float)) != np.isnan(v.astype(float))
        nan = int(moved.sum())
    ok = k == "residual_amplitude" and nan == 0 and rel <= RESIDUAL_ULP
    return ("tolerance" if ok else "DIFFERENT"), rel, nan


def compare(select=None):
    """{(case, array): (verdict, max relative difference, NaNs moved)} of the model now against the file
    (arrays the reference has; the layer's added outputs are not in it)."""
    from mechsweep import status as st

    ref = np.load(FILE)
    result = {}
    for label, res, rtol, floquet_wanted in all_arrays(select):
        budget = (ref[f"{label}/status"] == st.MAX_STEPS) & (res["status"] == st.MAX_STEPS)
        for k, v in res.items():
            if f"{label}/{k}" in ref:
                result[(label, k)] = verdict(k, ref[f"{label}/{k}"], v, rtol, floquet_wanted, budget)
    return result


def stamp_stiff(select=None):
    """The file's arrays with each MAX_STEPS the hand-written kernels now give as STIFF re-stamped
    STIFF, and the re-stamped [(case, point)]. Raises where the kernels differ from the file in
    anything else (a value, a count, another status): that is not the stiffness test's change."""
    from mechsweep import status as st

    ref = np.load(FILE)
    arrays = {k: ref[k] for k in ref.files}
    stamped = []
    for label, res in reference_arrays(select):
        for k, v in res.items():
            key = f"{label}/{k}"
            if key not in arrays:  # an output the file does not hold
                continue
            e = arrays[key]
            if k == "status":
                moved = (e == st.MAX_STEPS) & (v == st.STIFF)
                same = np.where(moved, st.STIFF, e)
                if not np.array_equal(same, v):
                    raise AssertionError(f"{key}: the kernels differ beyond MAX_STEPS -> STIFF at "
                                         f"{np.nonzero(same != v)[0].tolist()}")
                if moved.any():
                    arrays[key] = same.astype(e.dtype)
                    stamped += [(label, int(i)) for i in np.nonzero(moved)[0]]
            elif e.dtype != v.dtype or not np.array_equal(e, v, equal_nan=True):
                raise AssertionError(f"{key}: the kernels differ from the file")
    return arrays, stamped


def main(mode="compare", prefix=""):
    select = (lambda label: label.startswith(prefix)) if prefix else None
    if mode == "stiff":
        arrays, stamped = stamp_stiff(select)
        if stamped:
            np.savez_compressed(FILE, **arrays)
        for label, i in stamped:
            print(f"{label} point {i}: max_steps -> stiff")
        print("re-stamped", len(stamped), "statuses in", FILE)
        return 0
    if mode == "record":
        arrays = {f"{label}/{k}": v for label, res, _, _ in all_arrays() for k, v in res.items()}
        np.savez_compressed(FILE, **arrays)
        print("wrote", FILE, len(arrays), "arrays")
        return 0
    r = compare(select)
    for (label, k), (what, rel, nan) in r.items():
        if what != "bitwise":
            print(f"{label} {k}: {what} (max rel {rel:.3g}, NaN moved at {nan})")
    counts = {w: sum(1 for x in r.values() if x[0] == w) for w in ("bitwise", "tolerance", "DIFFERENT")}
    statuses = sum(1 for (label, k), x in r.items() if k == "status" and x[0] == "bitwise")
    print(counts, f"status arrays bitwise: {statuses} of {sum(1 for _, k in r if k == 'status')}")
    return 1 if counts["DIFFERENT"] else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
