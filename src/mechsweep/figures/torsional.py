"""Torsional-circuit nomograms: chi and xi against lambda2 (a family of S0/R curves), and the
map of the two-term model's period error."""
from __future__ import annotations

import numpy as np
from matplotlib.colors import LogNorm

from . import located
from ._registry import ModelFigure
from ._style import HALO_DARK, Drawn, flag_note, label, new_figure, ok_values, title


def _family_dim(ds, x="lambda2"):
    others = [d for d in ds.dims if d not in (x, "spring")]
    return others[0] if len(others) == 1 else None


def can_coefficients(ds) -> bool:
    """lambda2 is an axis and at most one more axis (the family) besides the spring kind."""
    if "lambda2" not in ds.dims:
        return False
    extra = [d for d in ds.dims if d not in ("lambda2", "spring")]
    return len(extra) <= 1


def _runs(mask):
    """(start, stop) index pairs of the runs of True in a 1-D boolean array."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.flatnonzero(np.diff(m.astype(int)))
    return list(zip(d[::2], d[1::2]))


def _padded(ax, frac):
    """The y limits with ``frac`` of the panel's height added below (in the axis' own scale)."""
    lo, hi = ax.get_ylim()
    if frac <= 0:
        return lo, hi
    tr = ax.yaxis.get_transform()
    t0, t1 = tr.transform(np.array([lo, hi]))
    return float(tr.inverted().transform(np.array([t0 - frac * (t1 - t0) / (1 - frac)]))[0]), hi


def coefficients(ds, boundaries=None, *, fig=None, ax=None):
    """chi and xi against lambda2, one curve per value of the family axis (e.g. S0/R);
    columns for tension / compression; xi panels shaded hard (xi > 0) and soft (xi < 0), on a
    symmetric-log axis when the curves span decades one side of 0 and not the other; the lambda2
    ranges where a curve is infeasible as bars in its colour along the foot of each panel; the
    located feasibility limits along lambda2 (e.g. the spring's free length reaching 0) as vertical
    lines in the curve's colour when they were computed (`mechsweep boundaries`)."""
    from matplotlib import colormaps
    from matplotlib.transforms import blended_transform_factory

    if boundaries is not None and boundaries.attrs.get("along") != "lambda2":
        boundaries = None
    rows = [n for n in ("chi", "xi") if n in ds]
    springs = list(ds["spring"].values) if "spring" in ds.dims else [None]
    fam = _family_dim(ds)
    fig, axes = new_figure(len(rows), len(springs), width=5.4, height=3.8, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, lines=[], infeasible=[], located=[])
    lam = np.asarray(ds["lambda2"].values, dtype=float)
    for c, spring in enumerate(springs):
        sub = ds.sel(spring=spring) if spring is not None else ds
        members = list(sub[fam].values) if fam else [None]
        colors = colormaps["viridis"](np.linspace(0, 0.9, max(1, len(members))))
        for r, name in enumerate(rows):
            a = axes[r, c]
            da = ok_values(sub, name)
            bar_rows = [k for k, val in enumerate(members)
                        if ((sub["status"].sel({fam: val}) if fam else sub["status"]).values != 0).any()]
            for k, val in enumerate(members):
                line = da.sel({fam: val}) if fam else da
                lab = f"{val:g}" if fam else None
                art["lines"].append(a.plot(lam, line.values, color=colors[k], lw=1.4, label=lab)[0])
                if boundaries is not None:
                    b = boundaries["boundary"]
                    pick = {d: v for d, v in (("spring", spring), (fam, val)) if d is not None and d in b.dims}
                    for xb in np.asarray(b.sel(pick).values, dtype=float).ravel():
                        if np.isfinite(xb):
                            art["located"].append(a.axvline(xb, color=colors[k], lw=1.0, ls=":"))
                # infeasible lambda2 ranges of this curve: a bar at the foot of the panel, one row per curve
                st = (sub["status"].sel({fam: val}) if fam else sub["status"]).values != 0
                feet = blended_transform_factory(a.transData, a.transAxes)
                for i0, i1 in _runs(st):
                    x0 = lam[i0] if i0 == 0 else 0.5 * (lam[i0 - 1] + lam[i0])
                    x1 = lam[i1 - 1] if i1 == lam.size else 0.5 * (lam[i1 - 1] + lam[i1])
                    row = bar_rows.index(k)
                    art["infeasible"].append(a.plot([x0, x1], [0.02 + 0.03 * row] * 2, color=colors[k], lw=3.5,
                                                    solid_capstyle="butt", transform=feet, alpha=0.8)[0])
            a.axhline(0.0, color="0.3", lw=0.6)
            pad = 0.04 + 0.03 * len(bar_rows) if bar_rows else 0.0  # room under the curves for the bars
            if name == "xi":
                v = np.asarray(da.values, dtype=float)
                v = v[np.isfinite(v)]
                neg, pos = (-v[v < 0]).max(initial=0.0), v[v > 0].max(initial=0.0)
                if neg > 0 and pos > 0 and max(neg, pos) / min(neg, pos) > 8:
                    a.set_yscale("symlog", linthresh=min(neg, pos), linscale=1.0)
                ylo0 = a.get_ylim()[0]
                ylo, yhi = _padded(a, pad)
                a.axhspan(0, max(yhi, 0), color="C3", alpha=0.07, lw=0)
                a.axhspan(min(ylo0, 0), 0, color="C0", alpha=0.07, lw=0)  # the bars' strip below stays white
                a.set_ylim(ylo, yhi)
                # the words sit in the margin right of the panel, level with their region (never on a
                # curve), and only where the region is tall enough to hold them
                tr = a.yaxis.get_transform()
                t0, tz, t1 = tr.transform(np.array([ylo, 0.0, yhi]))
                for frac_lo, frac_hi, text, color in ((0.0, (tz - t0) / (t1 - t0), "soft (ξ < 0)", "C0"),
                                                      ((tz - t0) / (t1 - t0), 1.0, "hard (ξ > 0)", "C3")):
                    if frac_hi - frac_lo > 0.22:
                        a.text(1.01, (frac_lo + frac_hi) / 2, text, transform=a.transAxes, rotation=90, ha="left",
                               va="center", color=color, fontsize=8)
            elif pad:
                a.set_ylim(*_padded(a, pad))
            a.set_xlabel(label(ds["lambda2"]))
            a.set_ylabel(label(ds[name]))
            a.grid(True, alpha=0.3)
            if spring is not None:
                a.set_title(f"{spring} spring", fontsize=10)
        if fam:
            art[f"legend_{c}"] = axes[0, c].legend(fontsize=7, title=label(ds[fam], width=30), title_fontsize=7,
                                                   ncols=2)
    bad = int((ds["status"].values != 0).sum())
    notes = []
    if bad:
        notes.append(f"{bad} infeasible or flagged grid points are not drawn; bars along the foot of a panel, in "
                     "a curve's colour: the lambda2 range where that curve has no feasible point")
    if boundaries is not None:
        notes.append(f"dotted vertical lines: {located.criterion_text(boundaries)} located along lambda2 "
                     f"({located.tolerance_text(boundaries)}) for the curve of that colour")
    title(fig, ds, "Duffing coefficients of the torsional oscillating circuit", caption="; ".join(notes) or None)
    return art


def _map_dims(ds, name):
    dims = [d for d in ds[name].dims if ds.sizes[d] > 1]
    return dims if len(dims) == 2 else None


def can_truncation_error(ds) -> bool:
    """Exactly two axes with more than one value."""
    return _map_dims(ds, "truncation_error") is not None


def truncation_error(ds, *, fig=None, ax=None):
    """Relative period error of the two-term Duffing model against the exact spring moment."""
    da = ok_values(ds, "truncation_error").squeeze()
    ydim, xdim = _map_dims(ds, "truncation_error")
    fig, axes = new_figure(1, 1, width=7.0, height=5.0, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, contours=None, contour_labels=[])
    ax = axes[0, 0]
    v = da.transpose(ydim, xdim).values
    pos = v[np.isfinite(v) & (v > 0)]
    norm = LogNorm(vmin=max(pos.min(), 1e-16), vmax=pos.max()) if pos.size else None
    mesh = ax.pcolormesh(ds[xdim].values, ds[ydim].values, np.where(v > 0, v, np.nan), norm=norm,
                         shading="nearest", cmap="magma_r")
    art["mesh"] = mesh
    cb = art["colorbar"] = ax.figure.colorbar(mesh, ax=ax)
    cb.set_label(label(ds["truncation_error"], width=40))
    levels = [lv for lv in (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1) if pos.size and pos.min() < lv < pos.max()]
    if levels:
        # white lines with a dark halo read on both the light and the dark end of the scale
        cs = ax.contour(ds[xdim].values, ds[ydim].values, v, levels=levels, colors="white", linewidths=1.0)
        cs.set_path_effects(HALO_DARK)
        texts = ax.clabel(cs, fmt=lambda x: f"{100 * x:g} %", fontsize=8)
        for t in texts:
            t.set_path_effects(HALO_DARK)
        cb.add_lines(cs)
        art["contours"], art["contour_labels"] = cs, list(texts)
    ax.set_xlabel(label(ds[xdim]))
    ax.set_ylabel(label(ds[ydim]))
    art["flag_note"] = flag_note(ax, ds)
    title(fig, ds, "Period error of the two-term (Duffing) spring model")
    return art


FIGURES = (
    ModelFigure("coefficients", coefficients, models=("torsional_circuit",), any_of=("chi", "xi"),
                fits=can_coefficients, boundaries=True),
    ModelFigure("truncation_error", truncation_error, models=("torsional_circuit",), needs=("truncation_error",),
                fits=can_truncation_error),
)
