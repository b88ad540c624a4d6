"""Figures for any model, chosen by what its outputs declare (``mechsweep_kind``), and the fallback
for any dataset: lines over one axis."""
from __future__ import annotations

import itertools

import numpy as np
from matplotlib.colors import ListedColormap

from ._style import STATUS_OK, flag_note, label, log_or_symlog, new_figure, ok_values, title

STABLE_COLORS = ListedColormap(["#f4c7c3", "#c8e6c9"])  # unstable, stable
FLOQUET_SLACK = 1e-6  # a modulus within this of 1 counts as on the unit circle (stable, undamped)
MAX_PANELS = 6


def _numeric_dims(ds):
    return [d for d in ds.dims if ds[d].dtype.kind in "fiu" and ds.sizes[d] > 1]


def can_outputs(ds) -> bool:
    return 1 <= len(_numeric_dims(ds)) <= 2 and bool(ds.attrs.get("outputs"))


def outputs(ds):
    """Each output against the first axis (lines, one per value of a second axis) ."""
    names = ds.attrs["outputs"].split()
    dims = _numeric_dims(ds)
    x = dims[-1]
    fig, axes = new_figure(len(names), 1, width=6.4, height=3.0)
    for r, name in enumerate(names):
        ax = axes[r, 0]
        da = ok_values(ds, name)
        rest = [d for d in da.dims if d != x]
        flat = da.transpose(*rest, x).values.reshape(-1, ds.sizes[x]) if rest else da.values[None, :]
        step = max(1, flat.shape[0] // 12)
        for row in flat[::step]:
            ax.plot(ds[x].values, row, lw=1.0)
        log_or_symlog(ax, ds[x].values)
        ax.set_xlabel(label(ds[x]))
        ax.set_ylabel(label(ds[name]))
        ax.grid(True, alpha=0.3)
        flag_note(ax, ds)
    title(fig, ds, "Outputs")
    return fig


def _floquet_outputs(ds) -> list[str]:
    return [n for n in ds.data_vars if ds[n].attrs.get("mechsweep_kind") == "floquet_max"]


def can_stability_map(ds) -> bool:
    return bool(_floquet_outputs(ds)) and len(_numeric_dims(ds)) >= 2


def stability_map(ds):
    """Floquet stability over two axes (stable where the largest multiplier modulus is at most 1),
    one panel per value of the other axes, boundary drawn."""
    name = _floquet_outputs(ds)[0]
    ydim, xdim = _numeric_dims(ds)[:2]
    others = [d for d in ds[name].dims if d not in (xdim, ydim)]
    members = list(itertools.product(*(range(ds.sizes[d]) for d in others)))[:MAX_PANELS]
    ncols = min(2, len(members))
    nrows = -(-len(members) // ncols)
    fig, axes = new_figure(nrows, ncols, width=5.2, height=4.0)
    x, y = ds[xdim].values, ds[ydim].values
    for k, idx in enumerate(members):
        ax = axes[k // ncols, k % ncols]
        sel = dict(zip(others, idx))
        values = ok_values(ds, name).isel(sel).transpose(ydim, xdim).values
        _stability_panel(ax, x, y, values)
        if ds[xdim].attrs.get("spacing") == "log":
            ax.set_xscale("log")
        if ds[ydim].attrs.get("spacing") == "log":
            ax.set_yscale("log")
        ax.set_xlabel(label(ds[xdim]))
        ax.set_ylabel(label(ds[ydim]))
        if others:
            ax.set_title(", ".join(f"{d} = {_value(ds[d].values[i])}" for d, i in sel.items()), fontsize=10)
        flagged = int((ds["status"].isel(sel).values != STATUS_OK).sum())
        if flagged:
            ax.text(0.01, 0.01, f"{flagged} flagged point(s) not drawn", transform=ax.transAxes, fontsize=8,
                    color="0.35")
    for k in range(len(members), nrows * ncols):
        axes[k // ncols, k % ncols].set_visible(False)
    handles = [axes[0, 0].fill_between([], [], color=STABLE_COLORS.colors[1], label="stable"),
               axes[0, 0].fill_between([], [], color=STABLE_COLORS.colors[0], label="unstable"),
               axes[0, 0].plot([], [], color="k", lw=1.2, label=f"{ds[name].attrs.get('symbol', name)} = 1")[0]]
    fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=9)
    title(fig, ds, f"Floquet stability: {ds[name].attrs.get('long_name', name)}")
    return fig


def _stability_panel(ax, x, y, values) -> None:
    """Stable/unstable shading of one map and the boundary between them (contour of the modulus
    at 1 + FLOQUET_SLACK, so that an undamped stable side, at 1 up to round-off, counts as stable)."""
    verdict = np.where(np.isfinite(values), (values <= 1.0 + FLOQUET_SLACK).astype(float), np.nan)
    ax.pcolormesh(x, y, verdict, cmap=STABLE_COLORS, vmin=0, vmax=1, shading="nearest")
    margin = values - (1.0 + FLOQUET_SLACK)
    if np.nanmin(margin, initial=np.inf) < 0 < np.nanmax(margin, initial=-np.inf):
        ax.contour(x, y, np.log1p(np.maximum(margin, -0.5)), levels=[0.0], colors="k", linewidths=1.2)


def _value(v) -> str:
    return str(v) if np.asarray(v).dtype.kind in "OUS" else f"{float(v):g}"
