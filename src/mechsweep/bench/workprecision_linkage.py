"""`mechsweep bench workprecision MODEL` for a closed-form model (e.g. fourbar_balancing,
slidercrank_balancing): the error of its outputs against the length N of its extra dimension (the
number of crank positions of the linkage models), and what each N costs.

What is measured is the model's own declaration, ``ClosedFormModel(workprecision=
SizeWorkPrecision(...))`` (:mod:`mechsweep.model.workprecision`): its scene, outputs, reference,
independent implementation and ladder; this module names no model. The linkage models declare theirs
with the reference implementations of :mod:`mechsweep.models._linkage_reference`: N uniform crank
positions phi_i = 2 pi i / N (N_POSITIONS = 360 in every sweep) behind every maximum, RMS value,
fit and range.

A fixed sample of design points (drawn with a fixed seed from the declared scene, or from --scene;
points that are not OK, and those the declaration's ``applies`` refuses, are dropped, said in the
report) is evaluated for each N of the ladder by

- mechsweep: the model's kernel at N (``evaluate(..., size=N)``), on one thread, all of the
  declared outputs in one call (the sample repeated as in `workprecision`, the fastest of
  ``repeats``; the first call, JIT compile or disk-cache load, is reported separately), and
- the declaration's independent implementation (``compare``, e.g. vectorised numpy) of the same
  outputs at the same N, on the same repeated sample in the same run (its values must agree with
  the kernel's to round-off: the largest relative difference is reported).

Errors are relative, |value - reference| / |reference|, the maximum and median over the sample,
against the declared reference on the continuous dimension (its own error estimate reported).

Expected for the linkage models, and measured rather than assumed: the uniform rule on a smooth
periodic function converges faster than any power of 1/N (RMS values and the fitted axis), maxima
converge as 1/N^2 (the grid misses the peak by up to pi / N; exact when the peak is on the grid by
symmetry).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numba
import numpy as np

from .. import status as st
from ..scene import load_scene


# ============================================================================= measurement
def _evaluate_ours(spec, P, outputs, n_positions):
    n = P.shape[0]
    out = {k: np.full(n, np.nan) for k in outputs}
    status = np.zeros(n, st.DTYPE)
    spec.evaluate(P, outputs, None, out, status, None, None, n_positions)  # the closed-form engine's size
    return out, status


ROUNDOFF = 1e-13  # relative errors at or below this are round-off (a few hundred ulp)
FIT_FROM = 90  # the fitted order uses the rungs from this N on (the asymptotic range)


def fitted_order(errors, positions, n_from: int = FIT_FROM) -> float:
    """Least-squares p of error ~ C N^-p over the rungs N >= n_from whose error is above ROUNDOFF
    (NaN with fewer than 3 such rungs: the error reached round-off first)."""
    e = np.asarray(errors, dtype=float)
    N = np.asarray(positions, dtype=float)
    use = (N >= n_from) & (e > ROUNDOFF)
    if use.sum() < 3:
        return math.nan
    return float(-np.polyfit(np.log(N[use]), np.log(e[use]), 1)[0])


def roundoff_from(errors, positions) -> float:
    """The smallest N of the ladder from which on every error is at or below ROUNDOFF (NaN: never)."""
    e = np.asarray(errors, dtype=float)
    above = np.flatnonzero(e > ROUNDOFF)
    first = 0 if above.size == 0 else above[-1] + 1
    return float(positions[first]) if first < len(positions) else math.nan


def observed_orders(errors, positions) -> np.ndarray:
    """p between consecutive rungs: error ~ N^-p, p = log(e_a / e_b) / log(N_b / N_a) (NaN at the
    first rung and where an error is 0)."""
    e = np.asarray(errors, dtype=float)
    N = np.asarray(positions, dtype=float)
    p = np.full(e.shape, np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        p[..., 1:] = np.log(e[..., :-1] / e[..., 1:]) / np.log(N[1:] / N[:-1])
    p[~np.isfinite(p)] = np.nan
    return p


def main(model: str, scene_path: str | None = None, points: int = 64, positions=None, repeats: int = 5,
         out_dir: str | Path = "data/bench", quiet: bool = False, seed: int = 0):
    """The report of a ClosedFormModel that declares a SizeWorkPrecision; ``positions``: the ladder
    of N (default: the declaration's ``sizes``)."""
    import xarray as xr

    from ..errors import InputError
    from ..model.closed import ClosedFormModel
    from . import arguments
    from .cases import declared_scene, fastest, latex_symbols, resolve_model, sample, tiled, write

    spec = resolve_model(model) if isinstance(model, str) else None
    declared = getattr(spec, "declaration", None)
    case = getattr(declared, "workprecision", None) if isinstance(declared, ClosedFormModel) else None
    if case is None:
        raise InputError(f"no linkage work-precision case for model {model!r}: a closed-form model declares one as "
                         "ClosedFormModel(..., workprecision=SizeWorkPrecision(scene='S.toml', outputs={...}, "
                         "reference=..., compare=...)) (mechsweep.model.SizeWorkPrecision)")
    points = arguments.count("points", points, 1, 10**6)
    repeats = arguments.count("repeats", repeats, 1, 1000)
    out_dir = arguments.folder("out", out_dir)
    positions = arguments.sequence(case.sizes if positions is None else positions)
    if not positions:
        raise InputError("the ladder of crank positions is empty; give at least one")
    positions = tuple(arguments.count("positions", n, 1, 10**6) for n in positions)
    if min(positions) < 4:
        raise InputError(f"need at least 4 crank positions per cycle, got {min(positions)}")
    path, label = (Path(scene_path), str(scene_path)) if scene_path is not None else declared_scene(case)
    scene = load_scene(path)
    if scene.model.declaration is not declared:
        raise InputError(f"scene {label} is for model {scene.model.name!r}, not {model!r}")
    kinds = dict(case.outputs)
    outputs = tuple(kinds)
    P = sample(scene, points, seed)
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        t0 = time.perf_counter()
        _, status = _evaluate_ours(spec, P, outputs, declared.size)  # JIT compile or cache load
        first_call_s = time.perf_counter() - t0
        drawn = P.shape[0]
        P = P[status == st.OK]
        if case.applies is not None:
            P = _described_rows(P, case.applies)
        if P.shape[0] == 0:
            raise InputError(f"no usable design point among the {drawn} drawn from {label}")
        t0 = time.perf_counter()
        refs, estimates = zip(*(case.reference(p) for p in P))
        ref_s = time.perf_counter() - t0
        reference = {k: np.array([r[k] for r in refs]) for k in outputs}
        shape = (2, len(outputs), len(positions))
        res = {k: np.full(shape, np.nan) for k in ("error_max", "error_median")}
        time_per_point = np.full((2, len(positions)), np.nan)
        numpy_difference = np.full((len(outputs), len(positions)), np.nan)
        for b, n in enumerate(positions):
            t0 = time.perf_counter()
            ours, status = _evaluate_ours(spec, P, outputs, n)
            P_timed = tiled(P, time.perf_counter() - t0)
            ours_s = fastest(lambda: _evaluate_ours(spec, P_timed, outputs, n), repeats)
            time_per_point[0, b] = ours_s / P_timed.shape[0]
            theirs = case.compare(P, n)
            time_per_point[1, b] = fastest(lambda: case.compare(P_timed, n), repeats) / P_timed.shape[0]
            for a, values in enumerate((ours, theirs)):
                for o, name in enumerate(outputs):
                    err = np.abs(values[name] - reference[name]) / np.abs(reference[name])
                    res["error_max"][a, o, b] = np.max(err)
                    res["error_median"][a, o, b] = np.median(err)
            for o, name in enumerate(outputs):
                numpy_difference[o, b] = np.max(np.abs(theirs[name] - ours[name]) / np.abs(ours[name]))
    finally:
        numba.set_num_threads(before)
    implementations = ["mechsweep", case.compare_label]
    dims3 = ("implementation", "output", "n_positions")
    ds = xr.Dataset(
        {
            "error_max": (dims3, res["error_max"], {"units": "1",
                                                     "long_name": "largest relative error over the sample"}),
            "error_median": (dims3, res["error_median"], {"units": "1", "long_name": "median relative error"}),
            "time_per_point": (("implementation", "n_positions"), time_per_point,
                               {"units": "s", "long_name": "wall time per design point, all outputs "
                                                            "(1 thread, best of repeats)"}),
            "order": (("output", "n_positions"), observed_orders(res["error_max"][0], positions),
                      {"units": "1", "long_name": "observed order p of mechsweep's largest error, "
                                                  "error ~ N^-p from the previous rung"}),
            "order_fit": (("output",), [fitted_order(e, positions) for e in res["error_max"][0]],
                          {"units": "1", "long_name": f"order p of mechsweep's largest error fitted over "
                                                      f"N >= {FIT_FROM} (errors above {ROUNDOFF:g})"}),
            "roundoff_from": (("output",), [roundoff_from(e, positions) for e in res["error_max"][0]],
                              {"units": "1", "long_name": f"smallest N from which mechsweep's largest error stays "
                                                          f"at or below {ROUNDOFF:g}"}),
            "numpy_difference": (("output", "n_positions"), numpy_difference,
                                 {"units": "1", "long_name": f"largest relative difference {case.compare_label} - mechsweep"}),
        },
        coords={"implementation": ("implementation", implementations, {"long_name": "implementation"}),
                "output": ("output", list(outputs), {"long_name": "output"}),
                "n_positions": ("n_positions", np.array(positions), {"units": "1",
                                                                     "long_name": "crank positions per cycle N"}),
                "kind": ("output", [kinds[o] for o in outputs], {"long_name": "kind of quantity"})},
        attrs={"mechsweep_kind": "workprecision_positions", "model": spec.name,
               "norm": "relative error |value - reference| / |reference|", "reference": case.reference_name,
               "reference_error_estimate": float(max(estimates)), "reference_time_s": ref_s,
               "points": P.shape[0], "points_drawn": drawn, "seed": seed, "repeats": repeats,
               "scene": label, "compile_or_cache_load_s": first_call_s, "threads": 1,
               "default_positions": declared.size, case.compare_label: case.compare_name,
               "latex_symbols": latex_symbols(spec)},
    )
    path = write(ds, out_dir, spec.name, dims3)
    if not quiet:
        _print(ds, path)
    return ds


def _described_rows(P, applies):
    """The rows the declaration's reference describes (``applies(p) == ""``); the others are
    dropped, said with the first one's reason."""
    keep = np.array([applies(p) == "" for p in P], dtype=bool)
    if not keep.all():
        why = applies(P[np.flatnonzero(~keep)[0]])
        print(f"  {int((~keep).sum())} of {P.shape[0]} points dropped: no reference for {why}")
    return P[keep]


def _print(ds, path) -> None:
    a = ds.attrs
    print(f"mechsweep bench workprecision {a['model']}: {a['norm']} against the number N of crank positions")
    print(f"  reference: {a['reference']} ({a['reference_time_s']:.1f} s; its own error estimate "
          f"{a['reference_error_estimate']:.1e})")
    print(f"  {a['points']} OK points of {a['points_drawn']} drawn from {a['scene']}; 1 thread, best of "
          f"{a['repeats']}; first call (JIT compile or cache load) {a['compile_or_cache_load_s']:.2f} s")
    n_pos = ds.n_positions.values
    other = str(ds.implementation.values[1])
    for o, name in enumerate(ds.output.values):
        fit, flat = float(ds.order_fit[o]), float(ds.roundoff_from[o])
        print(f"  {name} ({ds.kind.values[o]}): fitted order over N >= {FIT_FROM}: "
              + (f"{fit:.2f}" if math.isfinite(fit) else "- (round-off reached first)")
              + (f"; at round-off (<= {ROUNDOFF:g}) from N = {flat:.0f}" if math.isfinite(flat) else ""))
        print(f"    {'N':>6}{'max error':>12}{'median':>12}{'order':>8}{other + ' max err':>15}{other + ' - ours':>14}")
        for b, n in enumerate(n_pos):
            print(f"    {n:>6d}{float(ds.error_max[0, o, b]):>12.2e}{float(ds.error_median[0, o, b]):>12.2e}"
                  f"{float(ds.order[o, b]):>8.2f}{float(ds.error_max[1, o, b]):>15.2e}"
                  f"{float(ds.numpy_difference[o, b]):>14.1e}")
    print(f"  time per point, all {ds.sizes['output']} outputs in one call:")
    print(f"    {'N':>6}{'mechsweep':>13}{other:>13}{other + ' / mechsweep':>19}")
    for b, n in enumerate(n_pos):
        ours, theirs = ds.time_per_point.values[:, b]
        print(f"    {n:>6d}{ours * 1e6:>10.2f} us{theirs * 1e6:>10.1f} us{theirs / ours:>18.1f}x")
    print(f"  written: {path} and {path.with_suffix('.csv')}")
