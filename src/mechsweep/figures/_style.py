"""Labels and style shared by every figure; everything comes from dataset attributes.

Figures are made as ``matplotlib.figure.Figure`` objects, not through pyplot: drawing one changes
no matplotlib global state (backend, rcParams, pyplot's list of open figures), so it works headless
and inside a user's own session alike."""
from __future__ import annotations

import textwrap

import numpy as np
from matplotlib.figure import Figure

STATUS_OK = 0


def label(da, width: int = 42) -> str:
    """'long name [unit]' from a DataArray's attributes (unit omitted when dimensionless)."""
    name = da.attrs.get("long_name", da.name)
    unit = da.attrs.get("units", "")
    sym = da.attrs.get("symbol", "")
    head = f"{sym}, {name}" if sym and len(sym) <= 4 and sym != da.name else name
    text = f"{head} [{unit}]" if unit not in ("", "1") else head
    return "\n".join(textwrap.wrap(text, width))


def fixed_text(ds, skip=()) -> str:
    """'lambda1 = 0.8, ...' for the scalar coordinates (fixed parameters) of a dataset."""
    parts = []
    for k in ds.coords:
        if k in ds.dims or k in skip:
            continue
        v = ds[k].values
        unit = ds[k].attrs.get("units", "")
        val = str(v) if v.dtype.kind in "OUS" else f"{float(v):g}"
        # non-breaking spaces keep "N m s/rad" on one line when the title wraps
        text = f"{k} = {val}" + (f" {unit}" if unit not in ("", "1") else "")
        parts.append(text.replace(" ", "\u00a0"))
    return ", ".join(parts)


def ok_values(ds, name):
    """The output with non-ok points masked (NaN), so nothing flagged is drawn as a result."""
    return ds[name].where(ds["status"] == STATUS_OK)


def new_figure(nrows=1, ncols=1, width=6.4, height=4.2):
    fig = Figure(figsize=(width * ncols, height * nrows), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def title(fig, ds, what: str) -> None:
    fixed = fixed_text(ds)
    sub = ds.attrs.get("title", "") + (f": {fixed}" if fixed else "")
    wrapped = "\n".join(textwrap.wrap(sub, int(fig.get_figwidth() * 12)))  # ~12 characters per inch
    fig.suptitle(f"{what}\n{wrapped}", fontsize=11)


def flag_note(ax, ds) -> None:
    """Say on the figure how many points were flagged (and so are not drawn)."""
    bad = int((ds["status"].values != STATUS_OK).sum())
    if bad:
        ax.text(0.01, 0.01, f"{bad} flagged point(s) not drawn", transform=ax.transAxes, ha="left",
                va="bottom", fontsize=8, color="0.35")


def log_or_symlog(ax, values, axis="x") -> None:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return
    setter = ax.set_xscale if axis == "x" else ax.set_yscale
    if (v > 0).all():
        if v.max() / v.min() > 50:
            setter("log")
    elif (v < 0).any() and (v > 0).any():
        setter("symlog", linthresh=max(np.min(np.abs(v[v != 0])), 1e-3))
    # all <= 0 (soft springs up to the separatrix): a linear axis shows T -> inf best
