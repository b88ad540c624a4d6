"""Work-precision figure of a `mechsweep bench workprecision` dataset: error against time per point."""
from __future__ import annotations

import textwrap

import numpy as np

from ._style import label, new_figure

MARKERS = "os^vD<>ph*"


def can_workprecision(ds) -> bool:
    return ds.attrs.get("mechsweep_kind") == "workprecision"


def workprecision(ds):
    """Error against run time per point, one line per method (ours solid, scipy dashed)."""
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
