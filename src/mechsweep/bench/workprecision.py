"""`mechsweep bench workprecision MODEL`: error against run time for every method, ours and scipy's.

(A closed-form model has no integrator: its report, error against the length of its extra dimension
(e.g. crank positions), is :mod:`mechsweep.bench.workprecision_linkage`, declared by the model as
``ClosedFormModel(workprecision=SizeWorkPrecision(...))``; ``main`` hands it over.)

The bench knows no model by name: MODEL is a built-in model's name, "file.py:NAME" (relative to the
current folder), "package.module:NAME" or an entry-point name; what it measures comes from the
model's declaration.

A fixed sample of grid points (drawn with a fixed seed from the scene the model declares, or from
--scene) is integrated by every method the model offers (``SPEC.methods``) and by scipy's
solve_ivp (DOP853, Radau, LSODA) over a ladder of tolerances, in the same process:

- error: of one integrated output per model, against the best reference available, as the model
  declares it (``OdeModel(workprecision=WorkPrecision(scene, output, reference))``,
  :mod:`mechsweep.model.workprecision`): the model's closed form ``reference`` where it names one,
  otherwise scipy's DOP853 at rtol 1e-13 on the model's own functions, an implementation independent
  of ours, :mod:`mechsweep.bench.workprecision_ode`; the maximum and the median over the sample;
- time: wall time per point after JIT compilation (the compile or cache-load time of the first
  call is reported separately), the minimum of ``repeats`` runs; ours runs the sample, repeated
  up to cases.TIMED_POINTS points (or until a call takes cases.TIMED_CALL_S), through the model's
  ``evaluate`` on one thread (what a sweep's chunk does, per core; a call's fixed cost is then
  spread as in a sweep); scipy runs
  ``scipy_points`` of the points one by one with the model's jitted right-hand side (scipy's
  best case: its Python-level stepping is then the whole cost), and stops a scipy method's
  ladder once a rung costs more than ``scipy_budget_s`` per point (said in the report);
- scipy's points are spread over the whole sample (``spread``: of the sample's points in grid
  order, the middle one of each of ``scipy_points`` equal shares), so that they span the scene's
  grid rather than its first corner;
- errors of all methods are compared on the points scipy solved; ours also over the whole sample;
- cost: accepted steps and right-hand-side evaluations per point.

The result is an xarray Dataset (dims integrator x rtol) written to DIR/workprecision_MODEL.h5 and
.csv (a model that declares a conserved quantity, ``OdeModel(invariant=Invariant(...))``, e.g. the
Duffing oscillator's energy: its drift also, to DIR/workprecision_MODEL_energy.csv);
``mechsweep plot DIR/workprecision_MODEL.h5`` draws error against time from it.
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
from ..scene import Solver, load_scene
from . import workprecision_linkage
from .cases import all_cases, declared_scene, fastest, latex_symbols, resolve_model, sample, tiled, write  # noqa: F401

LADDER = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13)
ATOL_RATIO = 1e-2  # atol = 1e-2 rtol: the scaled states are O(1)
SCIPY_METHODS = ("DOP853", "Radau", "LSODA")


@dataclass(frozen=True)
class Case:
    """What is measured for one model."""

    scene: str  # the scene the sample is drawn from, as the report names it
    output: str  # integrated output whose error is measured
    error: str  # "relative" or "absolute"
    norm: str  # what the error means, for the report
    reference: Callable  # P -> reference values (n,)
    reference_name: str
    scipy_value: Callable  # (P row, method, rtol, atol) -> (value, n_rhs, accepted steps)
    declaration: object = None  # the model's OdeModel (its invariant: the drift experiment)


# ----------------------------------------------------------------------------- measurement
def spread(n: int, k: int) -> np.ndarray:
    """Positions of k of n sample points (in grid order) spread over the whole sample: the middle
    of each of k equal shares, floor((j + 1/2) n / k), j = 0 .. k-1. Taking the first k instead
    would take the grid's first points only (along its first axis: a Duffing sample's 6 smallest
    amplitudes, all near-linear)."""
    k = min(k, n)
    return np.floor((np.arange(k) + 0.5) * n / k).astype(np.int64)


def scipy_first(n: int, k: int) -> np.ndarray:
    """The order of a sample of n rows that puts the k rows scipy solves (``spread``) first, the
    others after them in grid order: every method's errors, times, steps and rhs calls are compared
    on the first k rows."""
    first = spread(n, k)
    return np.concatenate([first, np.setdiff1d(np.arange(n), first)])


def _run_ours(spec, P, output, solver):
    n = P.shape[0]
    wanted = spec.closure((output,))
    out = {k: np.full(n, np.nan) for k in wanted}
    status = np.zeros(n, st.DTYPE)
    ns = np.zeros(n, np.int64)
    nr = np.zeros(n, np.int64)
    spec.evaluate(P, wanted, solver, out, status, ns, nr)
    return out[output], status, ns, nr


def _error(values, reference, kind):
    err = np.abs(values - reference)
    return err / np.abs(reference) if kind == "relative" else err


def main(model: str, scene_path: str | None = None, points: int = 64, scipy_points: int = 6,
         ladder=LADDER, repeats: int = 3, out_dir: str | Path = "data/bench", quiet: bool = False,
         scipy_budget_s: float = 1.0, output: str | None = None):
    import xarray as xr

    from ..errors import InputError
    from ..model.closed import ClosedFormModel
    from ..model.ode import OdeModel
    from ..scene import SOLVER_LIMITS
    from . import arguments

    points = arguments.count("points", points, 1, 10**6)
    scipy_points = arguments.count("scipy_points", scipy_points, 1, points)
    repeats = arguments.count("repeats", repeats, 1, 1000)
    out_dir = arguments.folder("out", out_dir)
    spec = resolve_model(model)  # what is measured is the model's declaration: no table of models here
    declared = spec.declaration
    if isinstance(declared, ClosedFormModel):  # algebraic: a ladder of its extra dimension's length, not of tolerances
        return workprecision_linkage.main(model, scene_path, points=points, repeats=max(repeats, 5), out_dir=out_dir,
                                          quiet=quiet)
    if not isinstance(declared, OdeModel):
        raise InputError(f"model {model!r} is not declared as a mechsweep.model.OdeModel (a ModelSpec made by hand): "
                         "the bench integrates the declaration's own rhs; it has no work-precision case")
    ladder = arguments.sequence(ladder)
    if not ladder:
        raise InputError("the tolerance ladder is empty; give at least one rtol")
    ladder = tuple(arguments.tolerance("rtol", r, *SOLVER_LIMITS["rtol"]) for r in ladder)
    case, scene = _case(model, spec, declared, scene_path, output)
    model = spec.name
    P = sample(scene, points)
    t0 = time.perf_counter()
    reference = case.reference(P)
    ref_s = time.perf_counter() - t0
    usable = np.isfinite(reference)
    P, reference = P[usable], reference[usable]
    order = scipy_first(P.shape[0], scipy_points)  # scipy's points spread over the whole sample
    P, reference = P[order], reference[order]
    ours = (spec.methods_for(spec.closure((case.output,))) if spec.methods_for is not None  # what this output offers
            else spec.methods)
    methods = [f"mechsweep {m}" for m in ours] + [f"scipy {m}" for m in SCIPY_METHODS]
    shape = (len(methods), len(ladder))
    res = {k: np.full(shape, np.nan) for k in ("error_max", "error_median", "error_max_sample", "time_per_point",
                                                 "steps_per_point", "rhs_per_point", "ok_fraction")}
    k = min(scipy_points, P.shape[0])  # errors of every method are compared on these points
    compile_s = {}
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        for a, method in enumerate(ours):
            for b, rtol in enumerate(ladder):
                solver = Solver.for_model(spec, **{**dict(scene.solver.settings), "method": method, "rtol": rtol,
                                                   "atol": rtol * ATOL_RATIO})
                if method not in compile_s:
                    t0 = time.perf_counter()
                    _run_ours(spec, P[:1], case.output, solver)
                    compile_s[method] = time.perf_counter() - t0
                values, status, ns, nr = _run_ours(spec, P, case.output, solver)
                # timed on the points scipy solves (the table compares the methods on them), tiled
                t0 = time.perf_counter()
                _run_ours(spec, P[:k], case.output, solver)
                P_timed = tiled(P[:k], time.perf_counter() - t0)
                best = fastest(lambda: _run_ours(spec, P_timed, case.output, solver), repeats)
                _fill(res, a, b, values, status, ns, nr, reference, case.error, best / P_timed.shape[0], k)
    finally:
        numba.set_num_threads(before)
    skipped = []
    for a, method in enumerate(SCIPY_METHODS, start=len(ours)):
        case.scipy_value(P[0], method, ladder[0], ladder[0] * ATOL_RATIO)  # first-call costs are not timed
        for b, rtol in enumerate(ladder):
            if b and res["time_per_point"][a, b - 1] > scipy_budget_s:
                skipped.append(f"scipy {method} below rtol {ladder[b - 1]:g}")
                break
            values, nfev, steps, best = np.full(k, np.nan), np.zeros(k, np.int64), np.zeros(k, np.int64), 0.0
            for i in range(k):
                def solve(i=i, method=method, rtol=rtol):
                    values[i], nfev[i], steps[i] = case.scipy_value(P[i], method, rtol, rtol * ATOL_RATIO)
                best += fastest(solve, repeats)
            status = np.where(np.isfinite(values), st.OK, st.NONFINITE)
            _fill(res, a, b, values, status, steps, nfev, reference[:k], case.error, best / k, k)
    ds = xr.Dataset(
        {name: (("integrator", "rtol"), v, {"units": UNITS[name], "long_name": LONG[name]}) for name, v in res.items()},
        coords={"integrator": ("integrator", methods, {"long_name": "implementation and method"}),
                "rtol": ("rtol", np.array(ladder), {"units": "1", "long_name": "relative tolerance (atol = 1e-2 rtol)"})},
        attrs={"mechsweep_kind": "workprecision", "model": model, "output": case.output, "norm": case.norm,
               "reference": case.reference_name, "reference_time_s": ref_s, "points": P.shape[0],
               "scipy_points": k, "repeats": repeats, "skipped": "; ".join(skipped) or "none", "scene": case.scene,
               "compile_or_cache_load_s": ", ".join(f"{m} {s:.2f}" for m, s in compile_s.items()),
               "threads": 1, "latex_symbols": latex_symbols(spec),
               "scipy_rhs": "the model's own rhs (its compiled function, wrapped; a measurement's "
               "System's where it integrates one); Radau/LSODA with the model's jac where it declares one, else "
               "scipy's finite-difference Jacobian"},
    )
    if case.declaration is not None and case.declaration.invariant is not None:
        ds = _with_drift(ds, case.declaration)
    path = write(ds, out_dir, model, ("integrator", "rtol"))
    if "energy_error" in ds:
        ds[["energy_error"]].to_dataframe().to_csv(path.with_name(f"{path.stem}_energy.csv"))
    if not quiet:
        _print(ds, path)
    return ds


def _case(model: str, spec, declared, scene_path, output):
    """The case of a model declared as an OdeModel: scipy runs its own functions
    (bench/workprecision_ode.py); the scene, output and reference its ``WorkPrecision`` declares
    (--scene and --output replace the first two; the reference holds for the declared output)."""
    from ..errors import InputError
    from . import workprecision_ode as wo

    wp = declared.workprecision
    if scene_path is None and (wp is None or not wp.scene):
        raise InputError(f"{model!r} has no reference scene; give one with --scene S.toml (the sample is drawn "
                         "from its grid), or declare it with the model: OdeModel(..., workprecision=WorkPrecision("
                         "scene='S.toml', output='OUTPUT', reference='CLOSED_FORM')) (mechsweep.model.WorkPrecision; "
                         "the scene relative to the model's file, reference optional: a closed form giving the "
                         "output's exact value)")
    path, label = (Path(scene_path), str(scene_path)) if scene_path is not None else declared_scene(wp)
    scene = load_scene(path)
    if scene.model.declaration is not declared:
        same = f" ({scene.model.source})" if scene.model.name == spec.name else ""
        raise InputError(f"scene {label} is for model {scene.model.name!r}{same}, not {model!r}")
    default = wp.output if (wp is not None and wp.output) else wo.default_output(declared)
    output = output or default
    if output not in spec.output_names():
        raise InputError(f"--output {output!r} is not an output of model {spec.name!r}; "
                         f"expected one of {', '.join(spec.output_names())}")
    settings = dict(scene.solver.settings)
    ode = wo.OdeReference(declared, output, settings)
    exact = wp.reference if (wp is not None and wp.reference and output == wp.output) else None
    if exact:  # the model's closed form, evaluated by the engine
        solver = Solver.for_model(spec, **settings)

        def reference(P):
            return _run_ours(spec, P, exact, solver)[0]
        long = spec.output(exact).long_name
        name = f"the model's closed form {exact} ({long})"
        norm = f"relative error |{output} - {exact}| / |{exact}|" if ode.error == "relative" else \
            f"absolute error |{output} - {exact}|"
    else:
        reference, name, norm = ode.reference, ode.reference_name, ode.norm
    case = Case(label, output, ode.error, norm, reference, name, ode.value, declared)
    return case, scene


def _with_drift(ds, declaration):
    """The report with the drift of the quantity the model declares conserved (its Invariant):
    variables energy_error (drift_run x periods) and drift_rhs, whatever the quantity is called
    (its name is in the long name and attrs["drift_problem"])."""
    from . import workprecision_ode as wo

    inv = declaration.invariant
    names, drift, cost = wo.invariant_drift(declaration)
    last = inv.periods[-1]
    span = f"10^{round(math.log10(last))}" if last >= 1000 and 10 ** round(math.log10(last)) == last else f"{last:,}"
    ds["energy_error"] = (("drift_run", "periods"), drift,
                          {"units": "1", "long_name": f"relative {inv.name} error |E - E0| / E0"})
    ds["drift_rhs"] = (("drift_run",), cost, {"units": "1", "long_name": f"rhs evaluations for {span} periods"})
    ds = ds.assign_coords(drift_run=("drift_run", names, {"long_name": "method and tolerance"}),
                          periods=("periods", np.array(inv.periods), {"units": "1",
                                                                      "long_name": "periods integrated"}))
    at = ", ".join(f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}" for k, v in inv.at.items())
    ds.attrs["drift_problem"] = f"{inv.problem or f'{declaration.name} at {at}'}, one integration over {span} periods"
    ds.attrs["drift_quantity"] = inv.name
    return ds


def _fill(res, a, b, values, status, ns, nr, reference, kind, time_per_point, k):
    """One cell of the report; error_max/median, steps and rhs per point over the first k points
    (those every method solved: counted over different points, the methods' steps per point would
    compare different sets of points, not the methods), error_max_sample and ok_fraction over all
    points this method solved."""
    ok = (status == st.OK) & np.isfinite(values)
    err = np.where(ok, _error(values, reference, kind), np.nan)
    res["ok_fraction"][a, b] = ok.mean()
    if ok[:k].any():
        res["error_max"][a, b] = np.nanmax(err[:k])
        res["error_median"][a, b] = np.nanmedian(err[:k])
    if ok.any():
        res["error_max_sample"][a, b] = np.nanmax(err)
    res["time_per_point"][a, b] = time_per_point
    res["steps_per_point"][a, b] = ns[:k].mean()
    res["rhs_per_point"][a, b] = nr[:k].mean()


UNITS = {"error_max": "1", "error_median": "1", "error_max_sample": "1", "time_per_point": "s", "steps_per_point": "1",
         "rhs_per_point": "1", "ok_fraction": "1"}
LONG = {"error_max": "largest error over the points every method solved",
        "error_median": "median error over the points every method solved",
        "error_max_sample": "largest error over all points this method solved",
        "time_per_point": "wall time per point over the points every method solved (1 thread, best of repeats)",
        "steps_per_point": "accepted steps per point over the points every method solved",
        "rhs_per_point": "right-hand-side evaluations per point over the points every method solved",
        "ok_fraction": "fraction of all points with status ok"}


def _print(ds, path) -> None:
    a = ds.attrs
    print(f"mechsweep bench workprecision {a['model']}: {a['norm']}")
    print(f"  reference: {a['reference']} ({a['reference_time_s']:.1f} s); {a['points']} points from "
          f"{a['scene']} (scipy: {a['scipy_points']} of them, spread over the sample); compile/cache load: "
          f"{a['compile_or_cache_load_s']}")
    print(f"  errors, time, steps and rhs per point over the {a['scipy_points']} points scipy solves; "
          f"ok and the last column over all {a['points']}")
    print(f"  {'method':<22}{'rtol':>8}{'max error':>12}{'median':>12}{'time/point':>13}{'steps':>9}{'rhs':>9}"
          f"{'ok':>6}{'max (all)':>12}")
    for i, m in enumerate(ds.integrator.values):
        for j, r in enumerate(ds.rtol.values):
            row = ds.isel(integrator=i, rtol=j)
            print(f"  {m:<22}{r:>8.0e}{float(row.error_max):>12.2e}{float(row.error_median):>12.2e}"
                  f"{float(row.time_per_point) * 1e6:>10.1f} us{float(row.steps_per_point):>9.1f}"
                  f"{float(row.rhs_per_point):>9.1f}{float(row.ok_fraction) * 100:>5.0f}%"
                  f"{float(row.error_max_sample):>12.2e}")
    if "energy_error" in ds:
        print(f"  {a.get('drift_quantity', 'energy')} drift ({a['drift_problem']}):")
        for i, name in enumerate(ds.drift_run.values):
            errs = "  ".join(f"{n:>5d}: {e:.1e}" for n, e in zip(ds.periods.values, ds.energy_error.values[i]))
            print(f"    {name:<34}{errs}   ({int(ds.drift_rhs.values[i]):,} rhs)")
    if a["skipped"] != "none":
        print(f"  skipped (a rung above took more than the time budget per point): {a['skipped']}")
    print(f"  written: {path} and {path.with_suffix('.csv')}")
