"""Linkage-balancing figures: residual moments per method on one linkage, maps over geometry
families, the slider-crank's residual force against k, and Pareto fronts of the four indices."""
from __future__ import annotations

import numpy as np

from ._registry import ModelFigure
from ._style import flag_note, label, new_figure, ok_values, title

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


def moment_methods(ds):
    """Shaking moment after force balancing and the residual moment of each method over a cycle,
    one panel per design (at most four)."""
    dims, members = _members(ds, ("phi",))
    fig, axes = new_figure(len(members), 1, width=8.0, height=3.4)
    phi_deg = np.degrees(ds["phi"].values)
    for row, idx in enumerate(members):
        ax = axes[row, 0]
        point = ds.isel(dict(zip(dims, idx)))
        for k, (name, text, eff) in enumerate(METHOD_CURVES):
            if name not in point:
                continue
            values = point[name].values if int(point["status"]) == 0 else np.full(phi_deg.size, np.nan)
            if eff in point and np.isfinite(float(point[eff])):
                text = f"{text}: R = {float(point[eff]):.1f} %"
            ax.plot(phi_deg, values, lw=1.6 if k == 0 else 1.2, ls="-" if k == 0 else "--", label=text,
                    color=f"C{k}")
        ax.axhline(0.0, color="0.4", lw=0.6)
        ax.set_xlim(0, 360)
        ax.set_xticks(range(0, 361, 45))
        ax.set_xlabel("crank angle φ [deg]")
        ax.set_ylabel("shaking moment about O_A [N m]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
        where = ", ".join(f"{d} = {point[d].values}" for d in dims)
        if where:
            ax.set_title(where, fontsize=9)
    title(fig, ds, "Residual shaking moment of each balancing method (R: efficiency against method 1)")
    return fig


MAP_OUTPUTS = ("dM_rms_axis", "R_axis", "R_h1", "R_inertia", "M_rms_static", "cw_mass_static")


def _map_dims(ds):
    if "status" not in ds:  # not a sweep (e.g. a work-precision report of the model)
        return None
    dims = [d for d in ds["status"].dims if ds.sizes[d] > 1]
    return dims if len(dims) == 2 and all(ds[d].dtype.kind == "f" for d in dims) else None


def can_balancing_map(ds) -> bool:
    """Exactly two float axes with more than one value."""
    return _map_dims(ds) is not None


def balancing_map(ds):
    """Maps of residual moments and efficiencies over two geometry axes; grey: not a crank-rocker
    or at a toggle (see status)."""
    ydim, xdim = _map_dims(ds)
    names = [n for n in MAP_OUTPUTS if n in ds]
    ncols = 2 if len(names) > 1 else 1
    nrows = (len(names) + ncols - 1) // ncols
    fig, axes = new_figure(nrows, ncols, width=5.6, height=4.4)
    x, y = ds[xdim].values, ds[ydim].values
    flagged = (ds["status"] != 0).transpose(ydim, xdim).values
    for k, name in enumerate(names):
        ax = axes[k // ncols, k % ncols]
        v = ok_values(ds, name).transpose(ydim, xdim).values
        cmap = "viridis" if name.startswith("R_") else "magma_r"
        mesh = ax.pcolormesh(x, y, v, shading="nearest", cmap=cmap, rasterized=True)
        ax.contourf(x, y, np.where(flagged, 1.0, np.nan), levels=[0.5, 1.5], colors=["0.85"])
        fig.colorbar(mesh, ax=ax).set_label(label(ds[name], width=34), fontsize=8)
        ax.set_xlabel(label(ds[xdim]))
        ax.set_ylabel(label(ds[ydim]))
        flag_note(ax, ds)
    for k in range(len(names), nrows * ncols):
        fig.delaxes(axes[k // ncols, k % ncols])
    title(fig, ds, "Four-bar balancing over a geometry family")
    return fig


def can_slider_residual(ds) -> bool:
    """The balanced fraction k is an axis."""
    return "k" in ds.dims


def slider_residual(ds):
    """Residual shaking force of the slider-crank against the balanced fraction k of the
    reciprocating mass, one curve per crank-to-rod ratio; the textbook formula's error below."""
    names = [n for n in ("F_max", "Fx_max", "Fy_max") if n in ds]
    has_err = "F_tb_error_rel" in ds
    fig, axes = new_figure(1 + has_err, 1, width=7.5, height=3.8)
    ax = axes[0, 0]
    others = [d for d in ds["status"].dims if d != "k"]
    members = list(np.ndindex(*(ds.sizes[d] for d in others)))
    for j, idx in enumerate(members[:8]):
        sel = dict(zip(others, idx))
        lab = ", ".join(f"{d} = {ds[d].values[i]:g}" for d, i in sel.items())
        for s, (name, style) in enumerate(zip(names, ("-", "--", ":"))):
            ax.plot(ds["k"].values, ok_values(ds, name).isel(sel).values, ls=style, color=f"C{j}", lw=1.3,
                    label=f"{name}, {lab}" if s == 0 or j == 0 else None)
        if "F_max_unbalanced" in ds:
            ref = ok_values(ds, "F_max_unbalanced").isel(sel).values
            ax.plot(ds["k"].values, ref, color=f"C{j}", lw=0.6, alpha=0.5,
                    label="thin: |F| max without counterweight" if j == 0 else None)
    ax.set_xlabel(label(ds["k"]))
    ax.set_ylabel("residual shaking force [N]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncols=2)
    flag_note(ax, ds)
    if has_err:
        ax2 = axes[1, 0]
        for j, idx in enumerate(members[:8]):
            sel = dict(zip(others, idx))
            lab = ", ".join(f"{d} = {ds[d].values[i]:g}" for d, i in sel.items())
            ax2.plot(ds["k"].values, ok_values(ds, "F_tb_error_rel").isel(sel).values, color=f"C{j}", label=lab)
        ax2.set_yscale("log")
        ax2.set_xlabel(label(ds["k"]))
        ax2.set_ylabel(label(ds["F_tb_error_rel"], width=34))
        ax2.grid(True, which="both", alpha=0.3)
        ax2.legend(fontsize=7)
    title(fig, ds, "Slider-crank: partial balancing of the reciprocating mass")
    return fig


PARETO_INDICES = ("Fx_range", "Fy_range", "M_range", "T_range")


def pareto(ds):
    """Pareto front of the four balancing indices f1..f4 over a counterweight sweep, coloured by
    the counterweight mass, with the weighted-sum optimum of equal weights on indices scaled by
    their largest value. (Selecting the non-dominated rows of stored data is the only work done.)"""
    from ..balancing import pareto_front, weighted_optimum

    F = np.stack([ok_values(ds, n).values.ravel() for n in PARETO_INDICES], axis=1)
    front = pareto_front(F)
    scale = np.nanmax(F, axis=0)
    scale[scale == 0] = 1.0
    best = weighted_optimum(F / scale, np.ones(4))
    mass = ok_values(ds, "cw_mass").values.ravel() if "cw_mass" in ds else None
    fig, axes = new_figure(1, 2, width=6.0, height=5.0)
    pairs = ((0, 1), (2, 3))
    for ax, (i, j) in zip(axes[0], pairs):
        ax.scatter(F[:, i], F[:, j], s=3, color="0.8", rasterized=True, label="all designs")
        sc = ax.scatter(F[front, i], F[front, j], s=12, c=mass[front] if mass is not None else "C3",
                        cmap="plasma", label="Pareto-optimal over f1..f4")
        ax.scatter(F[best, i], F[best, j], marker="*", s=220, color="C2", edgecolor="k", zorder=5,
                   label="weighted-sum optimum (equal weights, scaled)")
        for setter, n in ((ax.set_xlabel, PARETO_INDICES[i]), (ax.set_ylabel, PARETO_INDICES[j])):
            setter(f"f{PARETO_INDICES.index(n) + 1}: {n.replace('_', ' ')} over a cycle [{ds[n].attrs['units']}]")
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    if mass is not None:
        fig.colorbar(sc, ax=axes[0, 1]).set_label(label(ds["cw_mass"]))
    axes[0, 1].text(0.99, 0.99, f"{int(front.sum())} of {int(np.isfinite(F).all(axis=1).sum())} designs "
                    "are Pareto-optimal", transform=axes[0, 1].transAxes, ha="right", va="top", fontsize=8)
    title(fig, ds, "Comprehensive balancing: Pareto front of the four indices")
    return fig


FIGURES = (
    ModelFigure("moment_methods", moment_methods, models=(FOURBAR,), needs=("M_static_phi",),
                draws=tuple(c[0] for c in METHOD_CURVES) + tuple(c[2] for c in METHOD_CURVES),
                fits=can_moment_methods),
    ModelFigure("balancing_map", balancing_map, models=(FOURBAR,), any_of=MAP_OUTPUTS, fits=can_balancing_map),
    ModelFigure("slider_residual", slider_residual, models=(SLIDER,), any_of=("F_max", "Fx_max", "Fy_max"),
                draws=("F_tb_error_rel", "F_max_unbalanced"), fits=can_slider_residual),
    ModelFigure("pareto", pareto, models=(FOURBAR, SLIDER), needs=PARETO_INDICES, draws=("cw_mass",)),
)
