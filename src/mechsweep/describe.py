"""What a dataset or a model holds, in words: ``mechsweep info`` (``describe`` a run's dataset,
``describe_boundaries`` a boundaries dataset) and ``mechsweep models`` (``model_text``; the
glossary's tables are docs.py's). Reads a Dataset and a model's declaration; computes and writes nothing."""
from __future__ import annotations


def _status_counts(ds) -> dict[str, int]:
    import numpy as np

    from . import status as st

    codes, counts = np.unique(ds["status"].values, return_counts=True)
    return {st.MEANINGS.get(int(c), str(c)): int(n) for c, n in zip(codes, counts)}


def describe(ds) -> str:
    import numpy as np

    from . import status as st

    lines = [f"{ds.attrs.get('title', '?')}  (model {ds.attrs.get('model', '?')})"]
    lines.append("dimensions:")
    for dim in ds.dims:
        c = ds[dim]
        vals = c.values
        rng = f"{vals[0]} .. {vals[-1]}" if vals.dtype.kind in "fiu" else ", ".join(map(str, vals[:6]))
        lines.append(f"  {dim:<12} {ds.sizes[dim]:>7}  [{c.attrs.get('units') or '-'}]  {rng}  "
                     f"({c.attrs.get('spacing', '')})  {c.attrs.get('long_name', '')}")
    fixed = [k for k in ds.coords if k not in ds.dims]
    if fixed:
        lines.append("fixed: " + ", ".join(f"{k} = {ds[k].values} {ds[k].attrs.get('units', '')}".strip()
                                           for k in fixed))
    lines.append("outputs:")
    status = ds["status"]
    ok = status == 0
    counts = _status_counts(ds)
    codes = status.values
    total = status.size
    for name in _outputs(ds):
        # the range over every finite value, whatever the point's status (a value at a point whose
        # status is not ok, e.g. an unstable point where a second output failed, is still shown),
        # and beside it the range over the ok points when that differs; chunk by chunk when lazy
        lo, hi = float(ds[name].min()), float(ds[name].max())
        v = ds[name].where(ok)
        lo_ok, hi_ok = float(v.min()), float(v.max())
        rng = f"{lo:.6g} .. {hi:.6g}" if np.isfinite(lo) else "no values"
        if np.isfinite(lo) and (lo_ok, hi_ok) != (lo, hi):
            rng += f" (at ok points {lo_ok:.6g} .. {hi_ok:.6g})" if np.isfinite(lo_ok) else " (none at an ok point)"
        lines.append(f"  {name:<20} [{ds[name].attrs.get('units') or '-'}]  {rng}  {ds[name].attrs.get('long_name', '')}")
        lines.append(f"  {'':<20} {_presence(ds, name, codes)}")
    verdicts = [n for n in _outputs(ds) if output_kind(ds, n) == "verdict"]
    for i, a in enumerate(verdicts):
        for b in verdicts[i + 1:]:
            lines.append("verdicts: " + verdict_agreement(ds, a, b))
    lines.append("status: " + ", ".join(f"{k} {n} ({100 * n / total:.3g}%)" for k, n in counts.items()))
    notes = _status_notes(ds)
    for meaning in counts:
        if meaning in notes:
            lines.append(f"  {meaning}: {notes[meaning]}")
    if "n_steps" in ds:
        computed = int((ds["status"] != st.PENDING).sum())  # an unfinished run's pending points took no steps
        mean = f"mean {float(ds['n_steps'].sum()) / computed:.1f} steps/point" if computed else "no point computed yet"
        if 0 < computed < ds["status"].size:
            mean += f" computed ({computed} of {ds['status'].size})"
        lines.append(f"cost: {int(ds['n_steps'].sum())} steps, {int(ds['n_rhs'].sum())} rhs evaluations, {mean}")
        solver = {k[len('solver_'):]: v for k, v in ds.attrs.items() if k.startswith("solver_")}
        lines.append("solver: " + ", ".join(f"{k}={v}" for k, v in solver.items()))
    where = ds.attrs.get("execution") or (f"{ds.attrs['threads']} threads" if "threads" in ds.attrs
                                          else "so far: an unfinished run")
    times = ", ".join(f"{k[:-7]} {float(ds.attrs[k]):.3f} s" for k in ("compile_time_s", "compute_time_s")
                      if k in ds.attrs)
    lines.append(f"wall time: {float(ds.attrs.get('wall_time_s', float('nan'))):.3f} s"
                 f"{f' ({times})' if times else ''} ({where})")
    lines.append("provenance: " + ", ".join(f"{k} {ds.attrs.get(k)}" for k in
                                             ("created", "mechsweep_version", "numba_version", "numpy_version")))
    return "\n".join(lines)


def _outputs(ds) -> list[str]:
    return ds.attrs.get("outputs", "").split()  # one not in the file: KeyError, "not laid out as" (store.read.reading)


def _builtin_spec(ds):
    """The declaration of the dataset's model when it is a built-in one (for datasets written
    before an attribute existed), else None."""
    from .models import MODELS

    return MODELS.get(ds.attrs.get("model"))


def output_kind(ds, name: str) -> str:
    """What an output is (``Output.kind``): the variable's ``mechsweep_kind``; for a dataset written
    before kinds were stored, the built-in model's declaration."""
    kind = ds[name].attrs.get("mechsweep_kind")
    if kind is None and (spec := _builtin_spec(ds)) is not None and name in spec.output_names():
        kind = spec.output(name).kind
    return str(kind or "")


def _status_notes(ds) -> dict[str, str]:
    """The model's notes on its statuses, {meaning: text}: stored with the dataset, else (a dataset
    written before notes were stored) the built-in model's declaration."""
    from . import status as st

    notes = st.stored_notes(ds["status"].attrs)
    if not notes and "status_notes" not in ds["status"].attrs and (spec := _builtin_spec(ds)) is not None:
        notes = {st.MEANINGS.get(c, str(c)): t for c, t in spec.status_notes}
    return notes


def _presence(ds, name: str, codes) -> str:
    """'values at N of M points; missing: status k, ...': a point holds a value when the output is
    finite there (at every sample of its extra dimensions). ``codes``: the status array (grid order)."""
    import numpy as np

    from . import status as st

    v = ds[name]
    extra = [d for d in v.dims if d not in ds["status"].dims]
    held = np.isfinite(v).all(extra) if extra else np.isfinite(v)  # one pass, chunk by chunk when lazy
    held = np.asarray(held.transpose(*ds["status"].dims).values, dtype=bool)
    missing_codes, counts = np.unique(codes[~held], return_counts=True)
    missing = [f"{st.MEANINGS.get(int(c), str(c))} {int(n)}" for c, n in zip(missing_codes, counts)]
    text = f"values at {int(held.sum())} of {codes.size} points"
    text += f"; missing: {', '.join(missing)}" if missing else ""
    not_ok = int((held & (codes != st.OK)).sum())
    return text + (f"; {not_ok} held at points whose status is not ok" if not_ok else "")


def verdict_agreement(ds, a: str, b: str) -> str:
    """How often two verdict outputs (1 = stable, 0 = not) agree, over points where both exist."""
    import numpy as np

    x, y = ds[a].values.ravel(), ds[b].values.ravel()
    both = np.isfinite(x) & np.isfinite(y)
    agree = int((x[both] == y[both]).sum())
    return (f"{a} and {b} agree at {agree} of {int(both.sum())} points with both verdicts; "
            f"disagree at {int(both.sum()) - agree} ({a} 1, {b} 0: {int(((x == 1) & (y == 0)).sum())}; "
            f"{a} 0, {b} 1: {int(((x == 0) & (y == 1)).sum())}); {int((np.isfinite(x) & ~np.isfinite(y)).sum())} "
            f"points have {a} only, {int((~np.isfinite(x) & np.isfinite(y)).sum())} {b} only")


def _bracket_widths(loc, width, attrs, unit) -> list[str]:
    """The final brackets' widths: relative to |x| where the boundary is away from 0, absolute next
    to 0, where a relative width means nothing. The scale is the locator's own: its tolerance is
    rtol max(|x|, ABS_FLOOR span), span the along axis's (attribute along_span; a dataset without that
    attribute, from an older version: relative wherever x != 0)."""
    import numpy as np

    from .boundaries import ABS_FLOOR

    span = float(attrs.get("along_span", np.nan))
    scale = ABS_FLOOR * span if np.isfinite(span) and span > 0 else 0.0
    along = attrs.get("along", "x")
    found = np.isfinite(loc) & np.isfinite(width)
    far = found & (np.abs(loc) > scale) & (loc != 0)
    near = found & ~far
    lines = []
    if far.any():
        rel = width[far] / np.abs(loc[far])
        where = f"|{along}| > {scale:.1e} = {ABS_FLOOR:g} x axis span" if scale > 0 else f"{along} != 0"
        lines.append(f"  bracket width relative to the boundary ({int(far.sum())} with {where}): median "
                     f"{np.median(rel):.1e}, largest {rel.max():.1e}")
    if near.any() and scale > 0:
        w = width[near]
        unit = f" {unit}" if unit and unit != "1" else ""
        lines.append(f"  bracket width absolute next to {along} = 0 ({int(near.sum())} with |{along}| <= {scale:.1e}): "
                     f"median {np.median(w):.1e}{unit}, largest {w.max():.1e}{unit}")
    return lines


def describe_boundaries(ds) -> str:
    """A boundaries dataset (`mechsweep boundaries`) in a few lines: what was located along which
    axis, how many, which accuracy bound stopped each, the cost, the continued curves."""
    import numpy as np

    from .boundaries import BOUND_MEANINGS, CURVE_STOPS

    a = ds.attrs
    what = (f"{a['criterion']} = {float(a.get('level', 1.0)):g}" if a.get("criterion", "status") != "status"
            else "status " + " -> ".join(str(a.get("status_change", "")).split()))
    dims = ", ".join(f"{d} ({ds.sizes[d]})" for d in ds["boundary"].dims)
    bound = np.asarray(ds["boundary_bound"].values)
    loc, width = np.asarray(ds["boundary"].values, float), np.asarray(ds["boundary_width"].values, float)
    lines = [f"{a.get('title', 'boundaries')}",
             f"  model {a.get('model')}: {what}, located along {a.get('along')}; dims {dims}",
             f"  located: {a.get('located', 0)} boundaries, rtol {float(a.get('rtol', np.nan)):.0e} in "
             f"{a.get('along')}" + (f"; criterion accuracy: {a['criterion_accuracy']}" if "criterion_accuracy" in a
                                    else "")]
    counts = ", ".join(f"{BOUND_MEANINGS[c]} {int((bound == c).sum())}" for c in sorted(BOUND_MEANINGS)
                       if (bound == c).any())
    lines.append(f"  accuracy bound met: {counts or 'none'} (parameter: bracket <= rtol max(|x|, 1e-6 x axis span); criterion: the "
                 "criterion's accuracy band is wider; band_edge: edge of that band)")
    lines += _bracket_widths(loc, width, a, ds["boundary"].attrs.get("units", ""))
    lines.append(f"  evaluations: {a.get('evaluated_points', 0)} points in {a.get('evaluate_calls', 0)} calls after "
                 f"the grid, {float(a.get('evaluations_per_point_mean', 0)):.1f} per located point (max "
                 f"{a.get('evaluations_per_point_max', 0)}), {float(a.get('wall_time_s', 0)):.2f} s")
    if "curve_stop" in ds:
        stops = np.asarray(ds["curve_stop"].values)
        kinds = ", ".join(f"{CURVE_STOPS[c]} {int((stops == c).sum())}" for c in range(len(CURVE_STOPS))
                          if (stops == c).any())
        folds = int(np.isfinite(np.asarray(ds[f"fold_{a['along']}"].values, float)).sum())
        lines.append(f"  continued in ({a.get('along')}, {a.get('continue_in')}): {int((stops >= 0).sum())} "
                     f"curve(s) (stopped: {kinds or 'none'}), {folds} fold(s); "
                     f"{a.get('continuation_evaluated_points', 0)} points in {a.get('continuation_calls', 0)} "
                     f"calls, {float(a.get('continuation_wall_time_s', 0)):.2f} s")
    lines.append(f"  created {a.get('created', '?')} by mechsweep {a.get('mechsweep_version', '?')}")
    return "\n".join(lines)


def model_text(spec) -> str:
    lines = [f"{spec.name}: {spec.description}", f"  source: {spec.source}", "  parameters:"]
    for p in spec.params:
        opt = "" if p.required else " (optional)"
        lines.append(f"    {p.name:<10} [{p.unit or '-'}] {p.long_name}; {p.allowed()}{opt}")
    lines.append("  outputs:")
    for o in spec.outputs:
        extra = " (integrated)" if o.integrated else ""
        dims = f" (per {', '.join(d.name for d in o.extra_dims)})" if o.extra_dims else ""
        lines.append(f"    {o.name:<20} [{o.unit or '-'}] {o.long_name}{extra}{dims}")
    if any(o.integrated for o in spec.outputs):
        from .ode import METHOD_HELP

        by_output = [(o.name, tuple(spec.methods_for(spec.closure((o.name,)))) if spec.methods_for else spec.methods)
                     for o in spec.outputs if o.integrated]
        offered = [m for m in spec.methods if any(m in ms for _, ms in by_output)]
        lines.append("  solver.method:")
        lines += [f"    {m:<12} {METHOD_HELP[m]}" for m in offered]
        narrower = [(n, ms) for n, ms in by_output if ms != tuple(offered)]
        if narrower:  # a scene asking for these outputs may choose only among their methods
            lines.append("    methods by output (a scene with several outputs gets the methods they all offer):")
            lines += [f"      {n:<20} {', '.join(m)}" for n, m in narrower]
    if spec.settings:
        lines.append("  solver settings (besides method, rtol, atol, max_steps):")
        for st in spec.settings:
            lines.append(f"    {st.name:<20} [{st.unit or '-'}] {st.long_name}; default {st.default:g}, "
                         f"allowed [{st.lo:g}, {st.hi:g}]")
    from . import status

    lines.append("  statuses: " + ", ".join(status.MEANINGS.get(c, str(c)) for c in spec.possible_statuses()))
    lines += [f"    {status.MEANINGS.get(c, str(c)):<20} {t}" for c, t in spec.status_notes]
    return "\n".join(lines)
