"""Work-precision figure of a `mechsweep bench workprecision` dataset: error against time per point."""
from __future__ import annotations

import textwrap

import numpy as np

from ._registry import ModelFigure
from ._style import label, new_figure

MARKERS = "os^vD<>ph*"


def workprecision(ds):
    """Error against run time per point, one line per method (ours solid, scipy or numpy dashed)."""
    if ds.attrs["mechsweep_kind"] == "workprecision_positions":
        return _positions(ds)
    drift = "energy_error" in ds
    fig, axes = new_figure(1, 2 if drift else 1, width=7.4, height=5.0)
    ax = axes[0, 0]
    rtol = ds["rtol"].values
    for i, name in enumerate(ds["integrator"].values):
        t = ds["time_per_point"].isel(integrator=i).values
        e = ds["error_max"].isel(integrator=i).values
        keep = np.isfinite(t) & np.isfinite(e) & (e > 0)
        if not keep.any():
            continue
        ours = str(name).startswith("mechsweep")
        line, = ax.loglog(t[keep], e[keep], ls="-" if ours else "--", marker=MARKERS[i % len(MARKERS)],
                          lw=1.6 if ours else 1.1, ms=5, label=str(name))
        first = np.flatnonzero(keep)[0]  # tolerance of the loosest point, to read the ladder
        ax.annotate(f"{rtol[first]:.0e}", (t[first], e[first]), textcoords="offset points", xytext=(4, 4),
                    fontsize=7, color=line.get_color())
    ax.set_xlabel(label(ds["time_per_point"]))
    ax.set_ylabel(textwrap.fill(f"{ds.attrs['norm']} (max over {ds.attrs['scipy_points']} points)", 48))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    if drift:
        _energy_drift(axes[0, 1], ds)
    head = f"Work-precision, {ds.attrs['model']}: rtol ladder {rtol.max():.0e} ... {rtol.min():.0e}"
    ref = f"reference: {ds.attrs['reference']}; {ds.attrs['points']} points of {ds.attrs['scene']}, 1 thread"
    fig.suptitle(head + "\n" + textwrap.fill(ref, 100), fontsize=9)
    return fig


def _energy_drift(ax, ds):
    """Energy error against integrated periods: linear growth of the explicit method, none for
    the symplectic one (its error sits at round-off)."""
    for i, name in enumerate(ds["drift_run"].values):
        e = np.maximum(ds["energy_error"].isel(drift_run=i).values, 1e-17)  # exact zeros drawn at the floor
        ax.loglog(ds["periods"].values, e, marker=MARKERS[i % len(MARKERS)], ls="-" if "symplectic" in name else "--",
                  label=f"{name} ({int(ds['drift_rhs'].values[i]):,} rhs)")
    ax.set_xlabel(label(ds["periods"]))
    ax.set_ylabel(label(ds["energy_error"]))
    ax.set_title(textwrap.fill(ds.attrs["drift_problem"], 60), fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="best")


FLOOR = 1e-17  # exact zeros (a maximum on the grid by symmetry) drawn at this floor


def _positions(ds):
    """Linkage models: error against time per point (left) and against the number N of crank
    positions (right, with the slope N^-2 of a maximum), one colour per output; mechsweep solid,
    numpy dashed (same values, its own time)."""
    fig, axes = new_figure(1, 2, width=6.4, height=5.4)
    left, right = axes[0, 0], axes[0, 1]
    N = ds["n_positions"].values
    for o, name in enumerate(ds["output"].values):
        color = f"C{o}"
        for i, impl in enumerate(ds["implementation"].values):
            t = ds["time_per_point"].isel(implementation=i).values
            e = np.maximum(ds["error_max"].isel(implementation=i, output=o).values, FLOOR)
            ours = impl == "mechsweep"
            left.loglog(t, e, ls="-" if ours else "--", marker=MARKERS[o % len(MARKERS)], color=color,
                        lw=1.6 if ours else 1.0, ms=4 if ours else 3, label=f"{name}, {impl}")
            if ours:
                for j in (0, len(N) - 1):
                    left.annotate(f"N={N[j]}", (t[j], e[j]), textcoords="offset points", xytext=(4, 4), fontsize=7,
                                  color=color)
                right.loglog(N, e, marker=MARKERS[o % len(MARKERS)], color=color,
                             label=f"{name} ({ds['kind'].values[o]})")
    e_ref = float(np.nanmax(ds["error_max"].sel(implementation="mechsweep").values[:, N >= 90]))
    right.loglog(N, e_ref * (N / 90.0) ** -2.0, ls=":", color="0.4", label="slope N^-2")
    right.axvline(ds.attrs["default_positions"], color="0.6", lw=0.8)
    right.annotate(f"default N = {ds.attrs['default_positions']}", (ds.attrs["default_positions"], FLOOR * 10),
                   fontsize=7, color="0.4", rotation=90, xytext=(3, 0), textcoords="offset points")
    left.set_xlabel(label(ds["time_per_point"]))
    right.set_xlabel(label(ds["n_positions"]))
    for ax in (left, right):
        ax.set_ylabel(textwrap.fill(f"{ds.attrs['norm']} (max over {ds.attrs['points']} points)", 48))
        ax.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=6.5, loc="best", ncol=2)
    right.legend(fontsize=7, loc="best")
    head = f"Work-precision, {ds.attrs['model']}: crank positions N = {N.min()} ... {N.max()}, 1 thread"
    ref = f"reference: {ds.attrs['reference']}; {ds.attrs['points']} points of {ds.attrs['scene']}"
    fig.suptitle(head + "\n" + textwrap.fill(ref, 120), fontsize=9)
    return fig


FIGURES = (
    ModelFigure("workprecision", workprecision, dataset_kinds=("workprecision", "workprecision_positions")),
)
