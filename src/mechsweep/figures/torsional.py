"""Torsional-circuit nomograms: chi and xi against lambda2 (a family of S0/R curves), and the
map of the two-term model's period error."""
from __future__ import annotations

import numpy as np
from matplotlib.colors import LogNorm

from . import located
from ._registry import ModelFigure
from ._style import flag_note, label, new_figure, ok_values, title


def _family_dim(ds, x="lambda2"):
    others = [d for d in ds.dims if d not in (x, "spring")]
    return others[0] if len(others) == 1 else None


def can_coefficients(ds) -> bool:
    """lambda2 is an axis and at most one more axis (the family) besides the spring kind."""
    if "lambda2" not in ds.dims:
        return False
    extra = [d for d in ds.dims if d not in ("lambda2", "spring")]
    return len(extra) <= 1


def coefficients(ds, boundaries=None):
    """chi and xi against lambda2, one curve per value of the family axis (e.g. S0/R);
    columns for tension / compression; xi panels shaded hard (xi > 0) and soft (xi < 0); the
    located feasibility limits along lambda2 (e.g. the spring's free length reaching 0) as vertical
    lines in the curve's colour when they were computed (`mechsweep boundaries`)."""
    if boundaries is not None and boundaries.attrs.get("along") != "lambda2":
        boundaries = None
    rows = [n for n in ("chi", "xi") if n in ds]
    springs = list(ds["spring"].values) if "spring" in ds.dims else [None]
    fam = _family_dim(ds)
    fig, axes = new_figure(len(rows), len(springs), width=5.4, height=3.8)
    for c, spring in enumerate(springs):
        sub = ds.sel(spring=spring) if spring is not None else ds
        for r, name in enumerate(rows):
            ax = axes[r, c]
            da = ok_values(sub, name)
            members = list(sub[fam].values) if fam else [None]
            colors = __import__("matplotlib").colormaps["viridis"](np.linspace(0, 0.9, max(1, len(members))))
            for k, val in enumerate(members):
                line = da.sel({fam: val}) if fam else da
                lab = f"{val:g}" if fam else None
                ax.plot(sub["lambda2"].values, line.values, color=colors[k], lw=1.4, label=lab)
                if boundaries is not None:
                    b = boundaries["boundary"]
                    pick = {d: v for d, v in (("spring", spring), (fam, val)) if d is not None and d in b.dims}
                    for x in np.asarray(b.sel(pick).values, dtype=float).ravel():
                        if np.isfinite(x):
                            ax.axvline(x, color=colors[k], lw=1.0, ls=":")
            ax.axhline(0.0, color="0.3", lw=0.6)
            if name == "xi":
                ylo, yhi = ax.get_ylim()
                ax.axhspan(0, max(yhi, 0), color="C3", alpha=0.07, lw=0)
                ax.axhspan(min(ylo, 0), 0, color="C0", alpha=0.07, lw=0)
                ax.set_ylim(ylo, yhi)
                ax.text(0.98, 0.96, "hard (ξ > 0)", transform=ax.transAxes, ha="right", va="top", color="C3", fontsize=8)
                ax.text(0.98, 0.04, "soft (ξ < 0)", transform=ax.transAxes, ha="right", va="bottom", color="C0", fontsize=8)
            ax.set_xlabel(label(ds["lambda2"]))
            ax.set_ylabel(label(ds[name]))
            ax.grid(True, alpha=0.3)
            if spring is not None:
                ax.set_title(f"{spring} spring", fontsize=10)
            flag_note(ax, sub)
        if fam:
            axes[0, c].legend(fontsize=7, title=label(ds[fam], width=30), title_fontsize=7, ncols=2)
    if boundaries is not None:
        fig.supxlabel(f"dotted vertical lines: {located.criterion_text(boundaries)} located along lambda2 "
                 f"({located.tolerance_text(boundaries)}) for the curve of that colour; the curves are the "
                 "grid's feasible points", fontsize=8, color=located.LOCATED_COLOR)
    title(fig, ds, "Duffing coefficients of the torsional oscillating circuit")
    return fig


def _map_dims(ds, name):
    dims = [d for d in ds[name].dims if ds.sizes[d] > 1]
    return dims if len(dims) == 2 else None


def can_truncation_error(ds) -> bool:
    """Exactly two axes with more than one value."""
    return _map_dims(ds, "truncation_error") is not None


def truncation_error(ds):
    """Relative period error of the two-term Duffing model against the exact spring moment."""
    da = ok_values(ds, "truncation_error").squeeze()
    ydim, xdim = _map_dims(ds, "truncation_error")
    fig, axes = new_figure(1, 1, width=7.0, height=5.0)
    ax = axes[0, 0]
    v = da.transpose(ydim, xdim).values
    pos = v[np.isfinite(v) & (v > 0)]
    norm = LogNorm(vmin=max(pos.min(), 1e-16), vmax=pos.max()) if pos.size else None
    mesh = ax.pcolormesh(ds[xdim].values, ds[ydim].values, np.where(v > 0, v, np.nan), norm=norm,
                         shading="nearest", cmap="magma_r")
    cb = fig.colorbar(mesh, ax=ax)
    cb.set_label(label(ds["truncation_error"], width=40))
    levels = [lv for lv in (1e-4, 1e-3, 1e-2, 1e-1) if pos.size and pos.min() < lv < pos.max()]
    if levels:
        cs = ax.contour(ds[xdim].values, ds[ydim].values, v, levels=levels, colors="k", linewidths=0.8)
        ax.clabel(cs, fmt=lambda x: f"{100 * x:g} %", fontsize=8)
    ax.set_xlabel(label(ds[xdim]))
    ax.set_ylabel(label(ds[ydim]))
    flag_note(ax, ds)
    title(fig, ds, "Period error of the two-term (Duffing) spring model")
    return fig


FIGURES = (
    ModelFigure("coefficients", coefficients, models=("torsional_circuit",), any_of=("chi", "xi"),
                fits=can_coefficients, boundaries=True),
    ModelFigure("truncation_error", truncation_error, models=("torsional_circuit",), needs=("truncation_error",),
                fits=can_truncation_error),
)
