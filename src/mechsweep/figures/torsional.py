"""Torsional-circuit nomograms: chi and xi against lambda2 (a family of S0/R curves), and the
map of the two-term model's period error."""
from __future__ import annotations

import numpy as np
from matplotlib.colors import ListedColormap, LogNorm
from matplotlib.ticker import FuncFormatter

from . import located
from ._registry import ModelFigure
from ._style import (HALO_DARK, Drawn, flag_note, label, name_text, new_figure, ok_values, readable_asinh_ticks, readable_log_ticks,
                     short_symbol, title, wrap)

# one colour and one marker per curve of a family: hues apart from one another (viridis' two greens
# were alike), ordered dark to light with the family's values
FAMILY_CMAP = "plasma"
FAMILY_MARKERS = "osD^vP*X"


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


def _family_colors(n):
    from matplotlib import colormaps

    return colormaps[FAMILY_CMAP](np.linspace(0.0, 0.82, max(1, n)))


def _limits_text(lam, bad, x_name, located_at=()):
    """Where a curve has no feasible point, as an engineer reads it off: '$\\lambda_2$ < 0.3455', the
    located limit when one was located nearby, else the midpoint between grid points (then said:
    'to the grid's spacing')."""
    parts, gridded = [], False
    for i0, i1 in _runs(bad):
        def edge(i_bad, i_ok):
            nonlocal gridded
            mid = 0.5 * (lam[i_bad] + lam[i_ok])
            near = [v for v in located_at if abs(v - mid) <= abs(lam[i_ok] - lam[i_bad])]
            gridded |= not near
            return near[0] if near else mid

        if i0 == 0 and i1 == lam.size:
            parts.append("everywhere")
        elif i0 == 0:
            limit = edge(i1 - 1, i1)
            tiny = 0 <= limit < 1e-3 * (lam.max() - lam.min())
            parts.append(f"{x_name} ≈ 0 (below {limit:.4g})" if tiny else f"{x_name} < {limit:.4g}")
        elif i1 == lam.size:
            parts.append(f"{x_name} > {edge(i0, i0 - 1):.4g}")
        else:
            parts.append(f"{edge(i0, i0 - 1):.4g} < {x_name} < {edge(i1 - 1, i1):.4g}")
    return ", ".join(parts) + (" (to the grid's spacing)" if gridded and parts != ["everywhere"] else "")


def _located_at(boundaries, spring, fam, val) -> list[float]:
    """The located limits along lambda2 of the curve of ``val`` (of the family ``fam``) for ``spring``."""
    if boundaries is None:
        return []
    b = boundaries["boundary"]
    pick = {d: v for d, v in (("spring", spring), (fam, val)) if d is not None and d in b.dims}
    return [v for v in np.asarray(b.sel(pick).values, dtype=float).ravel() if np.isfinite(v)]


def coefficients(ds, boundaries=None, *, fig=None, ax=None):
    """chi and xi against lambda2, one curve per value of the family axis (e.g. S0/R; one colour and
    marker each, one legend beside the panels saying where each curve has no feasible design);
    columns for tension / compression; xi panels shaded hard (xi > 0) and soft (xi < 0), on an
    asinh axis (linear near 0, logarithmic beyond, smooth between) when the curves span decades one
    side of 0 and not the other; the located feasibility limits along lambda2 (e.g. the spring's
    free length reaching 0) as dotted vertical lines in the curve's colour when they were computed
    (`mechsweep boundaries`)."""
    if boundaries is not None and boundaries.attrs.get("along") != "lambda2":
        boundaries = None
    rows = [n for n in ("chi", "xi") if n in ds]
    springs = list(ds["spring"].values) if "spring" in ds.dims else [None]
    fam = _family_dim(ds)
    fig, axes = new_figure(len(rows), len(springs), width=5.0, height=3.8, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, lines=[], located=[])
    lam = np.asarray(ds["lambda2"].values, dtype=float)
    x_name = name_text(ds["lambda2"])
    members = list(ds[fam].values) if fam else [None]
    colors = _family_colors(len(members))
    every = max(1, lam.size // 8)
    notes = {k: [] for k in range(len(members))}  # per curve: where it has no feasible design
    for c, spring in enumerate(springs):
        sub = ds.sel(spring=spring) if spring is not None else ds
        for k, val in enumerate(members):
            st = (sub["status"].sel({fam: val}) if fam else sub["status"]).values != 0
            if st.any():
                where = _limits_text(lam, st, x_name, _located_at(boundaries, spring, fam, val))
                notes[k].append(f"{spring}: none for {where}" if spring is not None else f"none for {where}")
        for r, name in enumerate(rows):
            a = axes[r, c]
            da = ok_values(sub, name)
            for k, val in enumerate(members):
                line = da.sel({fam: val}) if fam else da
                art["lines"].append(a.plot(lam, line.values, color=colors[k], lw=1.4,
                                           marker=FAMILY_MARKERS[k % len(FAMILY_MARKERS)], ms=3.5,
                                           markevery=(k * every // max(1, len(members)), every),
                                           label=f"{val:g}" if fam else None)[0])
                for xb in _located_at(boundaries, spring, fam, val):
                    art["located"].append(a.axvline(xb, color=colors[k], lw=1.0, ls=":"))
            a.axhline(0.0, color="0.3", lw=0.6)
            if name == "xi":
                v = np.asarray(da.values, dtype=float)
                v = v[np.isfinite(v)]
                neg, pos = (-v[v < 0]).max(initial=0.0), v[v > 0].max(initial=0.0)
                if neg > 0 and pos > 0 and max(neg, pos) / min(neg, pos) > 8:
                    # asinh: as symlog, linear about 0 and logarithmic far from it, but smooth (symlog's
                    # kink at its threshold drew a kink into every curve that crossed it)
                    a.set_yscale("asinh", linear_width=min(neg, pos))
                    readable_asinh_ticks(a.yaxis)
                ylo, yhi = a.get_ylim()
                xi = short_symbol(ds[name]) or name
                a.axhspan(0, max(yhi, 0), color="C3", alpha=0.07, lw=0)
                a.axhspan(min(ylo, 0), 0, color="C0", alpha=0.07, lw=0)
                a.set_ylim(ylo, yhi)
                # the words sit in the margin right of the panel, level with their region (never on a
                # curve), and only where the region is tall enough to hold them
                tr = a.yaxis.get_transform()
                t0, tz, t1 = tr.transform(np.array([ylo, 0.0, yhi]))
                for frac_lo, frac_hi, text, color in ((0.0, (tz - t0) / (t1 - t0), f"soft ({xi} < 0)", "C0"),
                                                      ((tz - t0) / (t1 - t0), 1.0, f"hard ({xi} > 0)", "C3")):
                    if frac_hi - frac_lo > 0.22:
                        a.text(1.01, (frac_lo + frac_hi) / 2, text, transform=a.transAxes, rotation=90, ha="left",
                               va="center", color=color, fontsize=8)
            a.set_xlabel(label(ds["lambda2"], width=56))
            a.set_ylabel(label(ds[name], width=34))
            a.set_xlim(lam.min(), lam.max())
            a.grid(True, alpha=0.3)
            if spring is not None:
                a.set_title(f"{spring} spring", fontsize=10)
    if fam:
        handles = [art["lines"][k] for k in range(len(members))]
        texts = [f"{val:g}" + (f" ({'; '.join(notes[k])})" if notes[k] else "") for k, val in enumerate(members)]
        # beside the panels (inside one, it lay over a curve), one legend for every panel
        art["legend"] = axes[0, -1].legend(handles, [wrap(t, 30) for t in texts], fontsize=7.5,
                                           title=label(ds[fam], width=30), title_fontsize=7.5, loc="upper left",
                                           bbox_to_anchor=(1.06, 1.0))
    bad = int((ds["status"].values != 0).sum())
    notes_text = []
    if bad:
        notes_text.append(f"{bad} grid points have no feasible spring (free length ≤ 0) or are flagged: not drawn; "
                          "the legend says where each curve has none")
    if boundaries is not None:
        notes_text.append(f"dotted vertical lines: {located.criterion_text(boundaries, ds)} located along "
                          f"{x_name} ({located.tolerance_text(boundaries)}) for the curve of that colour")
    title(fig, ds, "Duffing coefficients of the torsional oscillating circuit",
          caption="; ".join(notes_text) or None)
    return art


def _map_dims(ds, name):
    dims = [d for d in ds[name].dims if ds.sizes[d] > 1]
    return dims if len(dims) == 2 else None


def can_truncation_error(ds) -> bool:
    """Exactly two axes with more than one value."""
    return _map_dims(ds, "truncation_error") is not None


def _percent(v, _pos=None) -> str:
    """A fraction as a percentage, to the digits it has (0.0001 %, 2 %, 50 %; 10$^{-5}$ % below)."""
    p = 100 * v
    if 0 < p < 1e-4:
        return f"$10^{{{int(round(np.log10(p)))}}}$ %" if abs(np.log10(p) - round(np.log10(p))) < 1e-6 else f"{p:.1e} %"
    return f"{p:.3g} %"


TRUNCATION_LEVELS = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 0.05, 1e-1, 0.2, 0.5)  # labelled contours, fractions


def truncation_error(ds, *, fig=None, ax=None):
    """Relative period error of the two-term Duffing model against the exact spring moment, in
    percent (colour bar and contour labels alike), with labelled contours up to the largest error:
    read the amplitude up to which the two-term model is good to 1 %."""
    da = ok_values(ds, "truncation_error").squeeze()
    ydim, xdim = _map_dims(ds, "truncation_error")
    fig, axes = new_figure(1, 1, width=7.0, height=5.0, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, contours=None, contour_labels=[])
    ax = axes[0, 0]
    v = da.transpose(ydim, xdim).values
    pos = v[np.isfinite(v) & (v > 0)]
    norm = LogNorm(vmin=max(pos.min(), 1e-16), vmax=pos.max()) if pos.size else None
    # magma without its black end: the largest errors keep a colour of their own under the labels
    from matplotlib import colormaps

    cmap = ListedColormap(colormaps["magma_r"](np.linspace(0.0, 0.82, 256)))
    mesh = ax.pcolormesh(ds[xdim].values, ds[ydim].values, np.where(v > 0, v, np.nan), norm=norm,
                         shading="nearest", cmap=cmap)
    art["mesh"] = mesh
    cb = art["colorbar"] = ax.figure.colorbar(mesh, ax=ax)
    cb.set_label(wrap(label(ds["truncation_error"], width=10**6) + " [%]", 40))  # dimensionless: shown in %
    if norm is not None:
        readable_log_ticks(cb.ax.yaxis)
        cb.ax.yaxis.set_major_formatter(FuncFormatter(_percent))
    levels = [lv for lv in TRUNCATION_LEVELS if pos.size and pos.min() < lv < pos.max()]
    if levels:
        # white lines with a dark halo read on both the light and the dark end of the scale
        cs = ax.contour(ds[xdim].values, ds[ydim].values, v, levels=levels, colors="white", linewidths=1.0)
        cs.set_path_effects(HALO_DARK)
        texts = ax.clabel(cs, fmt=_percent, fontsize=8)
        for t in texts:
            t.set_path_effects(HALO_DARK)
        cb.add_lines(cs)
        art["contours"], art["contour_labels"] = cs, list(texts)
    ax.set_xlabel(label(ds[xdim], width=60))
    ax.set_ylabel(label(ds[ydim]))
    art["flag_note"] = flag_note(ax, ds)
    title(fig, ds, "Period error of the two-term (Duffing) spring model against the exact spring moment")
    return art


FIGURES = (
    ModelFigure("coefficients", coefficients, models=("torsional_circuit",), any_of=("chi", "xi"),
                fits=can_coefficients, boundaries=True),
    ModelFigure("truncation_error", truncation_error, models=("torsional_circuit",), needs=("truncation_error",),
                fits=can_truncation_error),
)
