"""Linkage-balancing figures: residual moments per method on one linkage, maps over geometry
families, the slider-crank's residual force against k, and Pareto fronts of the four indices."""
from __future__ import annotations

import numpy as np

from ._registry import ModelFigure
from ._style import (HALO_DARK, Drawn, flag_note, label, name_text, new_figure, ok_values, prose, short_symbol, symbol,
                     log_scale, status_text, title, units_text, value_text, wrap)

FOURBAR, SLIDER = "fourbar_balancing", "slidercrank_balancing"

METHOD_CURVES = (
    ("M_static_phi", "complete force balancing (method 1)", "R_static"),
    ("dM_axis_phi", "RMS-optimal counterweight axis", "R_axis"),
    ("dM_h1_phi", "first-harmonic counterweight axis", "R_h1"),
    ("dM_inertia_phi", "added rocker inertia", "R_inertia"),
)


def _members(ds, skip):
    """Index tuples over the grid dimensions (everything but ``skip``)."""
    dims = [d for d in ds["status"].dims if d not in skip]
    return dims, list(np.ndindex(*(ds.sizes[d] for d in dims)))


def can_moment_methods(ds) -> bool:
    """Crank angle phi is a dimension and the grid has at most four points (one panel each)."""
    if "phi" not in ds.dims:
        return False
    _, members = _members(ds, ("phi",))
    return len(members) <= 4


def moment_methods(ds, *, fig=None, ax=None):
    """Shaking moment after force balancing and the residual moment of each method over a cycle,
    one panel per design (at most four; its title says which, the caption what its parameters
    mean), each with its legend beside it; a curve equal to one drawn before it is drawn dotted
    over it, and its legend entry says so (at constant crank speed the first-harmonic axis is the
    RMS-optimal one: a dashed line hid the other)."""
    dims, members = _members(ds, ("phi",))
    fig, axes = new_figure(len(members), 1, width=8.4, height=3.0, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, lines=[], legends=[])
    phi_deg = np.degrees(ds["phi"].values)
    phi = name_text(ds["phi"])
    for row, idx in enumerate(members):
        ax = axes[row, 0]
        point = ds.isel(dict(zip(dims, idx)))
        drawn = []  # (values, text) of the curves drawn in this panel
        for k, (name, text, eff) in enumerate(METHOD_CURVES):
            if name not in point:
                continue
            values = point[name].values if int(point["status"]) == 0 else np.full(phi_deg.size, np.nan)
            if eff in point and np.isfinite(float(point[eff])):
                text = f"{text}: {short_symbol(point[eff]) or 'R'} = {float(point[eff]):.1f} %"
            twin = next((t for v, t in drawn if np.allclose(v, values, rtol=1e-9, atol=1e-12, equal_nan=True)), None)
            style = dict(lw=1.6, ls="-") if k == 0 else dict(lw=1.2, ls="--")
            if twin is not None:  # the same curve as one drawn already: dotted with dots, over it
                style = dict(lw=2.2, ls=":", marker="o", ms=3, markevery=(k * 7, 30))
                text += f" (the same curve as the {twin.split(':')[0]} here)"
            art["lines"].append(ax.plot(phi_deg, values, label=wrap(text, 40), color=f"C{k}", zorder=2 + k,
                                        **style)[0])
            drawn.append((values, text))
        ax.axhline(0.0, color="0.4", lw=0.6)
        ax.set_xlim(0, 360)
        ax.set_xticks(range(0, 361, 45))
        ax.set_xlabel(f"crank angle {phi} [deg]")
        unit = units_text(ds["M_static_phi"].attrs.get("units", "N m"))
        ax.set_ylabel(wrap(prose(f"shaking moment about O_A [{unit}]"), 24))
        ax.grid(True, alpha=0.3)
        art["legends"].append(ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0)))
        where = ", ".join(value_text(point[d]) + f": {_short_name(point[d])}" for d in dims)
        if where:
            ax.set_title(where, fontsize=9)
    caption = "; ".join(f"{name_text(ds[d])}: {prose(ds[d].attrs.get('long_name', d))}" for d in dims) or None
    title(fig, ds, "Residual shaking moment of each balancing method (R: efficiency against method 1)",
          caption=caption)
    return art


def _short_name(da) -> str:
    """A long name up to its first colon or semicolon ('crank speed modulation: phi' = ...' ->
    'crank speed modulation')."""
    return prose(str(da.attrs.get("long_name", da.name)).split(":")[0].split(";")[0].strip())


MAP_OUTPUTS = ("dM_rms_axis", "R_axis", "R_h1", "R_inertia", "M_rms_static", "cw_mass_static")


def _map_dims(ds):
    if "status" not in ds:  # not a sweep (e.g. a work-precision report of the model)
        return None
    dims = [d for d in ds["status"].dims if ds.sizes[d] > 1]
    return dims if len(dims) == 2 and all(ds[d].dtype.kind == "f" for d in dims) else None


def can_balancing_map(ds) -> bool:
    """Exactly two float axes with more than one value."""
    return _map_dims(ds) is not None


def balancing_map(ds, *, fig=None, ax=None):
    """Maps of residual moments and efficiencies over two geometry axes, with labelled contours to
    read values from; the colour scale spans the 1st to 99th percentile (arrows: beyond); an output
    equal to one already drawn is named in its panel instead of drawn again; grey: not a
    crank-rocker or at a toggle (see status)."""
    from .generic import _contour_labels, _level_text, contour_levels

    ydim, xdim = _map_dims(ds)
    names, same = [], {}
    for n in (n for n in MAP_OUTPUTS if n in ds):
        twin = next((m for m in names if np.allclose(ok_values(ds, n).values, ok_values(ds, m).values,
                                                      rtol=1e-9, atol=0, equal_nan=True)), None)
        if twin is None:
            names.append(n)
        else:
            same.setdefault(twin, []).append(n)
    ncols = 2 if len(names) > 1 else 1
    nrows = (len(names) + ncols - 1) // ncols
    fig, axes = new_figure(nrows, ncols, width=5.6, height=4.4, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, panels={})
    x, y = ds[xdim].values, ds[ydim].values
    flagged = (ds["status"] != 0).transpose(ydim, xdim).values

    from scipy.ndimage import distance_transform_edt

    # how far each grid point lies from the nearest flagged one, in fractions of the panel's sides
    clear = (distance_transform_edt(~flagged, sampling=(1.0 / max(y.size - 1, 1), 1.0 / max(x.size - 1, 1)))
             if flagged.any() else np.full(flagged.shape, np.inf))

    def near_flagged(px, py):
        """Points closer than 5 % of the panel to a flagged grid point (where contours crowd)."""
        ix = np.clip(np.searchsorted(x, px), 0, x.size - 1)
        iy = np.clip(np.searchsorted(y, py), 0, y.size - 1)
        return clear[iy, ix] < 0.05

    for k, name in enumerate(names):
        a = axes[k // ncols, k % ncols]
        v = ok_values(ds, name).transpose(ydim, xdim).values
        fin = v[np.isfinite(v)]
        lo, hi = (np.percentile(fin, [1, 99]) if fin.size else (0.0, 1.0))
        extend = ("both" if fin.min() < lo and fin.max() > hi else "max" if fin.max() > hi
                  else "min" if fin.min() < lo else "neither") if fin.size else "neither"
        cmap = "viridis" if name.startswith("R_") else "magma_r"
        panel = {"mesh": a.pcolormesh(x, y, v, shading="nearest", cmap=cmap, vmin=lo, vmax=hi, rasterized=True)}
        a.contourf(x, y, np.where(flagged, 1.0, np.nan), levels=[0.5, 1.5], colors=["0.85"])
        levels = contour_levels(float(lo), float(hi), False) if fin.size else []
        if len(levels):
            cs = a.contour(x, y, v, levels=levels, colors="white", linewidths=0.9)
            cs.set_path_effects(HALO_DARK)
            # half-way along each contour, away from the grey region's edge (where the contours
            # crowd and matplotlib stacked their labels)
            texts = _contour_labels(a, cs, avoid=near_flagged, fmt=_level_text, halo=HALO_DARK, fontsize=7)
            panel["contours"], panel["contour_labels"] = cs, list(texts)
        cb = a.figure.colorbar(panel["mesh"], ax=a, extend=extend)
        cb.set_label(label(ds[name], width=40), fontsize=8)
        if "contours" in panel:
            cb.add_lines(panel["contours"])
        panel["colorbar"] = cb
        if name in same:
            also = "; ".join(f"{short_symbol(ds[m]) or m}, {prose(ds[m].attrs.get('long_name', m))}" for m in same[name])
            a.set_title(wrap(f"the same values on this grid: {also}", 70), fontsize=8)
        a.set_xlabel(label(ds[xdim]))
        a.set_ylabel(label(ds[ydim]))
        art["panels"][name] = panel
    for k in range(len(names), nrows * ncols):
        fig.delaxes(axes[k // ncols, k % ncols])
    bad = int(flagged.sum())
    caption = (f"grey: {bad:,} of {flagged.size:,} grid points flagged ({status_text(ds)}: not a crank-rocker, or at "
               "a toggle; see status)" if bad else None)
    title(fig, ds, "Four-bar balancing over a geometry family", caption=caption)
    return art


def can_slider_residual(ds) -> bool:
    """The balanced fraction k is an axis."""
    return "k" in ds.dims


TEXTBOOK_K = (1 / 3, 1 / 2)  # the textbook's recommended balanced fraction of the reciprocating mass


def slider_residual(ds, *, fig=None, ax=None):
    """Residual shaking force of the slider-crank against the balanced fraction k of the
    reciprocating mass, one colour per crank-to-rod ratio, the textbook's range k = 1/3 .. 1/2
    shaded; below, the two-term textbook formula's error against the crank-to-rod ratio (it does
    not depend on k: every k's value is a point at its ratio)."""
    names = [n for n in ("F_max", "Fx_max", "Fy_max") if n in ds]
    has_err = "F_tb_error_rel" in ds
    fig, axes = new_figure(1 + has_err, 1, width=7.5, height=3.8, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, lines=[])
    a = axes[0, 0]
    others = [d for d in ds["status"].dims if d != "k"]
    members = list(np.ndindex(*(ds.sizes[d] for d in others)))[:8]
    k = ds["k"].values
    k_sym = name_text(ds["k"])
    art["textbook"] = a.axvspan(*TEXTBOOK_K, color="0.6", alpha=0.18, lw=0,
                                label=f"textbook: {k_sym} = 1/3 to 1/2")
    from matplotlib.lines import Line2D

    for j, idx in enumerate(members):
        sel = dict(zip(others, idx))
        lab = ", ".join(value_text(ds[d], ds[d].values[i]) for d, i in sel.items())
        if names:  # the fraction whose largest residual force is smallest: what a designer picks
            first = np.asarray(ok_values(ds, names[0]).isel(sel).values, dtype=float)
            if np.isfinite(first).any():
                i = int(np.nanargmin(first))
                lab = f"{lab}: best {k_sym} = {k[i]:.3g}" if lab else f"best {k_sym} = {k[i]:.3g}"
        for s_, (name, style) in enumerate(zip(names, ("-", "--", ":"))):
            art["lines"].append(a.plot(k, ok_values(ds, name).isel(sel).values, ls=style, color=f"C{j}", lw=1.3,
                                       label=(lab or name_text(ds[name])) if s_ == 0 else None)[0])
        if names and np.isfinite(first).any():
            art["lines"].append(a.plot([k[i]], [first[i]], "o", ms=6, mfc="white", mec=f"C{j}", mew=1.6,
                                       zorder=5)[0])
        if "F_max_unbalanced" in ds:
            ref = ok_values(ds, "F_max_unbalanced").isel(sel).values
            art["lines"].append(a.plot(k, ref, color=f"C{j}", lw=0.6, alpha=0.5)[0])
    # the line styles, once, in grey (legend entries only: not drawn on the axes)
    longs = [str(ds[n].attrs.get("long_name", n)) for n in names]
    tail = longs[0].rsplit(", ", 1)[-1] if longs and ", " in longs[0] else None
    if tail and all(t.endswith(", " + tail) for t in longs):  # said once, in the axis' caption
        longs = [t[: -len(tail) - 2] for t in longs]
    style_handles = [Line2D([], [], ls=st, color="0.3", lw=1.3, label=f"{short_symbol(ds[n]) or n}, {prose(t)}")
                     for n, t, st in zip(names, longs, ("-", "--", ":"))]
    if names:
        style_handles.append(Line2D([], [], ls="none", marker="o", ms=6, mfc="white", mec="0.3", mew=1.6,
                                    label=f"smallest {short_symbol(ds[names[0]]) or names[0]} of the curve: the best "
                                          f"{k_sym}"))
    if "F_max_unbalanced" in ds:
        style_handles.append(Line2D([], [], color="0.3", lw=0.6, alpha=0.5,
                                    label=f"{short_symbol(ds['F_max_unbalanced']) or 'F_max_unbalanced'}, "
                                          f"{prose(ds['F_max_unbalanced'].attrs.get('long_name', ''))}"))
    handles, labels = a.get_legend_handles_labels()
    handles += style_handles
    labels += [h.get_label() for h in style_handles]
    art["legend"] = a.legend(handles, [wrap(t, 36) for t in labels], fontsize=7, loc="upper left",
                             bbox_to_anchor=(1.01, 1.0))
    a.set_xlabel(label(ds["k"], width=60))
    unit = units_text(ds[names[0]].attrs.get("units", "N")) if names else "N"
    a.set_ylabel(f"residual shaking force [{unit}]")
    a.set_xlim(k.min(), k.max())
    a.grid(True, alpha=0.3)
    art["flag_note"] = flag_note(a, ds)
    if has_err:
        a2 = axes[1, 0]
        err = ok_values(ds, "F_tb_error_rel")
        fam = next((d for d in others if ds[d].dtype.kind in "fiu" and ds.sizes[d] > 1), None)
        if fam is not None:  # the error against the ratio; a spread along k would show as a vertical line
            xv = np.asarray(err[fam].broadcast_like(err).transpose(*err.dims).values, dtype=float).ravel()
            art["error"] = a2.scatter(xv, np.asarray(err.values, dtype=float).ravel(), s=16, color="C3", zorder=3,
                                      label="textbook formula, every k")
            a2.set_xlabel(label(ds[fam], width=60))
        else:
            art["error"], = a2.plot(k, np.asarray(err.values, dtype=float).ravel(), color="C3")
            a2.set_xlabel(label(ds["k"], width=60))
        log_scale(a2, "y")
        a2.set_ylabel(label(ds["F_tb_error_rel"], width=34))
        a2.grid(True, which="both", alpha=0.3)
    caption = f"residual forces {prose(tail)}" if names and tail else None
    title(fig, ds, "Slider-crank: partial balancing of the reciprocating mass", caption=caption)
    return art


PARETO_INDICES = ("Fx_range", "Fy_range", "M_range", "T_range")


def pareto(ds, *, fig=None, ax=None):
    """Pareto front of the four balancing indices f1..f4 over a counterweight sweep as parallel
    coordinates (one polyline per Pareto-optimal design across the four index axes, each axis from
    its smallest to its largest value on the front, in its own unit), coloured by the counterweight
    mass, with the weighted-sum optimum of equal weights on indices scaled by their largest value.
    (Selecting the non-dominated rows of stored data is the only work done.)"""
    from matplotlib.collections import LineCollection

    from ..balancing import pareto_front, weighted_optimum

    F = np.stack([ok_values(ds, n).values.ravel() for n in PARETO_INDICES], axis=1)
    front = pareto_front(F)
    scale = np.nanmax(F, axis=0)
    scale[scale == 0] = 1.0
    best = weighted_optimum(F / scale, np.ones(4))
    mass = ok_values(ds, "cw_mass").values.ravel() if "cw_mass" in ds else None
    fig, axes = new_figure(1, 1, width=9.0, height=5.4, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes)
    a = axes[0, 0]
    P = F[front]
    lo, hi = P.min(axis=0), P.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    u = (P - lo) / span  # 0 at the front's smallest value of each index, 1 at its largest
    xs = np.arange(4.0)
    segs = np.stack([np.column_stack([xs, row]) for row in u])
    order = np.argsort(mass[front])[::-1] if mass is not None else np.arange(len(u))
    lc = LineCollection(segs[order], linewidths=0.7, alpha=0.5, cmap="plasma")
    if mass is not None:
        lc.set_array(mass[front][order])
    else:
        lc.set_color("C3")
    art["front"] = a.add_collection(lc)
    ub = (F[best] - lo) / span
    # the optimum's design, what a designer builds: the grid values (the counterweights swept) at it
    grid = [d for d in ds["status"].dims if ds.sizes[d] > 1]
    at = np.unravel_index(best, ds["status"].shape)
    design = [value_text(ds[d], ds[d].values[i]) for d, i in zip(ds["status"].dims, at) if d in grid]
    if mass is not None and np.isfinite(mass[best]):
        design.append(value_text(ds["cw_mass"], mass[best]))
    indices = ", ".join(f"{short_symbol(ds[n]) or n} = {F[best, i]:.3g}{units_text(ds[n].attrs.get('units', '')) and ' '}"
                        f"{units_text(ds[n].attrs.get('units', ''))}" for i, n in enumerate(PARETO_INDICES))
    art["optimum"], = a.plot(xs, ub, color="C2", lw=3.0, marker="*", ms=14, mec="k", zorder=5,
                             label=wrap(f"weighted-sum optimum (equal weights, scaled): {', '.join(design)}; "
                                        f"{indices}", 110))
    for i, n in enumerate(PARETO_INDICES):
        a.plot([i, i], [0.0, 1.0], color="0.2", lw=0.8)  # from the smallest to the largest value, not through them
        a.annotate(f"{lo[i]:.4g}", (i, 0), xytext=(0, -4), textcoords="offset points", ha="center", va="top",
                   fontsize=8)
        a.annotate(f"{hi[i]:.4g}", (i, 1), xytext=(0, 4), textcoords="offset points", ha="center", va="bottom",
                   fontsize=8)
        for q in (0.25, 0.5, 0.75):
            a.plot([i - 0.03, i + 0.03], [q, q], color="0.2", lw=0.8)
            a.annotate(f"{lo[i] + q * span[i]:.4g}", (i, q), xytext=(4, 0), textcoords="offset points",
                       ha="left", va="center", fontsize=6.5, color="0.2",
                       bbox=dict(facecolor="white", alpha=0.8, edgecolor="none", pad=0.6))
    a.set_xticks(xs, [wrap(f"{symbol(ds[n]) or n} [{units_text(ds[n].attrs.get('units', ''))}]", 22)
                      for n in PARETO_INDICES], fontsize=8)
    a.set_yticks([])
    a.set_xlabel("balancing index (lower is better on every axis)")
    a.set_ylabel("each axis: the front's smallest to largest value")
    a.set_xlim(-0.3, 3.5)
    a.set_ylim(-0.08, 1.08)
    for side in ("top", "right", "left"):
        a.spines[side].set_visible(False)
    if mass is not None:
        art["colorbar"] = a.figure.colorbar(lc, ax=a)
        art["colorbar"].set_label(label(ds["cw_mass"], width=40))
    art["legend"] = a.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), fontsize=8, frameon=False)
    first, last = (short_symbol(ds[n]) or n for n in (PARETO_INDICES[0], PARETO_INDICES[-1]))
    title(fig, ds, "Comprehensive balancing: Pareto front of the four indices",
          caption=f"{int(front.sum()):,} of {int(np.isfinite(F).all(axis=1).sum()):,} designs are Pareto-optimal "
                  f"over {first} to {last} (every one drawn: a line across the four axes, each axis from the front's "
                  "smallest to its largest value; lower is better on every axis)")
    return art


FIGURES = (
    ModelFigure("moment_methods", moment_methods, models=(FOURBAR,), needs=("M_static_phi",),
                draws=tuple(c[0] for c in METHOD_CURVES) + tuple(c[2] for c in METHOD_CURVES),
                fits=can_moment_methods),
    ModelFigure("balancing_map", balancing_map, models=(FOURBAR,), any_of=MAP_OUTPUTS, fits=can_balancing_map),
    ModelFigure("slider_residual", slider_residual, models=(SLIDER,), any_of=("F_max", "Fx_max", "Fy_max"),
                draws=("F_tb_error_rel", "F_max_unbalanced"), fits=can_slider_residual),
    ModelFigure("pareto", pareto, models=(FOURBAR, SLIDER), needs=PARETO_INDICES, draws=("cw_mass",)),
)
