"""Located and continued boundaries (a ``mechsweep boundaries`` dataset, DATA.boundaries.h5) drawn
over a chart of the grid they were located on, or alone.

Nothing here computes a boundary: the curves are read from the boundaries dataset, and every label
(what was located, to what tolerance, along which axis) from its attributes and variables.
"""
from __future__ import annotations


import numpy as np

from ._registry import ModelFigure
from ._style import Drawn, label, mathtext, new_figure, short_symbol, title, units_text, value_text, wrap

KIND = "boundaries"
LOCATED_COLOR = "#6a1b9a"
CONTINUED_COLOR = "#0d47a1"


def is_boundaries(ds) -> bool:
    return ds is not None and ds.attrs.get("mechsweep_kind") == KIND and "boundary" in ds


def mismatch(ds, bds) -> str | None:
    """Why the boundaries dataset ``bds`` was not located on the grid of ``ds`` (None: it was, as
    far as the stored attributes and coordinates tell: same model, the axis it was located along
    and every other axis in the grid, with the same values)."""
    if not is_boundaries(bds):
        return "it is not a boundaries dataset (mechsweep_kind = 'boundaries')"
    if bds.attrs.get("model") != ds.attrs.get("model"):
        return f"its model {bds.attrs.get('model')!r} is not the dataset's {ds.attrs.get('model')!r}"
    along = bds.attrs.get("along")
    if along not in ds.dims:
        return f"it was located along {along!r}, which is not a dimension of the dataset"
    for d in bds["boundary"].dims:
        if d == "crossing":
            continue
        if d not in ds.dims or ds.sizes[d] != bds.sizes[d] or not np.array_equal(ds[d].values, bds[d].values):
            return f"its axis {d!r} is not the dataset's (other values or missing)"
    return None


def name_of(bds, name, ds=None) -> str:
    """How a figure writes a variable of the scene: its symbol in mathtext, read from the dataset
    of the grid (``ds``) or the boundaries dataset, else the name as mathtext (never a literal
    underscore)."""
    for where in (ds, bds):
        if where is not None and name in where.variables:
            sym = short_symbol(where[name])
            if sym:
                return sym
    return mathtext(name) or str(name)


def criterion_text(bds, ds=None) -> str:
    """'$\\max|\\rho|$ = 1' or 'status infeasible → ok' (status names without underscores)."""
    if bds.attrs.get("criterion", "status") == "status":
        a, b = str(bds.attrs.get("status_change", "? ?")).split()[:2]
        return f"status {a.replace('_', ' ')} → {b.replace('_', ' ')}"
    return f"{name_of(bds, bds.attrs['criterion'], ds)} = {float(bds.attrs.get('level', 1.0)):g}"


def tolerance_text(bds) -> str:
    """How precisely the stored boundaries were located: the rtol asked for and the widest final
    bracket relative to the boundary (both read from the dataset)."""
    loc = np.asarray(bds["boundary"].values, dtype=float)
    w = np.asarray(bds["boundary_width"].values, dtype=float)
    ok = np.isfinite(loc) & np.isfinite(w)
    # relative to |boundary|, floored (as the location's tolerance is) for a boundary at 0
    scale = np.maximum(np.abs(loc[ok]), 1e-6 * np.max(np.abs(loc[ok]), initial=0.0)) if ok.any() else None
    widest = f", widest relative bracket {np.max(w[ok] / scale):.1e}" if ok.any() and (scale > 0).all() else ""
    return f"rtol {float(bds.attrs.get('rtol', np.nan)):.0e}{widest}"


def overlay(ax, bds, *, line_dim=None, sel=None, xmap=None, ymap=None, color=None, label_prefix="",
            transpose=False, ds=None, chart_other=None):
    """Draw the boundaries of ``bds`` on ``ax``: the located ones as points at (boundary, line) for
    every value of ``line_dim`` (an axis other than the one located along; None: vertical lines at
    the boundaries), the continued ones as curves. ``sel`` picks the other dims (isel); ``xmap`` /
    ``ymap`` map the stored values to the chart's coordinates; ``transpose``: the chart has the
    axis located along vertical (points at (line, boundary)). Returns the artists (the first of
    each kind carries a legend label saying what it is and to what tolerance; ``ds``, the dataset
    of the grid, names the variables by their symbols; :func:`legend_entries` makes the legend's
    entries of them). ``chart_other``: the chart's axis other than the one located along, when
    known: the continued curves, which lie in (along, continue_in), are drawn only when it is
    continue_in (on a chart of another axis they would be drawn in the wrong coordinates)."""
    xmap = xmap or (lambda v: v)
    ymap = ymap or (lambda v: v)
    if transpose:  # every (along, other) pair below is drawn as (other, along)
        ax = _Transposed(ax)
    sel = sel or {}
    along = bds.attrs["along"]
    artists = []
    located = _isel(bds["boundary"], sel)
    text = f"{label_prefix}located along {name_of(bds, along, ds)}: {criterion_text(bds, ds)} ({tolerance_text(bds)})"
    if line_dim is None:
        xs = np.asarray(located.values, dtype=float).ravel()
        for k, x in enumerate(xs[np.isfinite(xs)]):
            artists.append(_role(ax.axvline(xmap(x), color=color or LOCATED_COLOR, lw=1.0, ls=(0, (1, 1)),
                                            label=text if k == 0 else None), "located", text))
    else:
        lines = located.transpose(line_dim, "crossing")
        y = np.repeat(np.asarray(bds[line_dim].values, dtype=float)[:, None], lines.sizes["crossing"], axis=1)
        x = np.asarray(lines.values, dtype=float)
        ok = np.isfinite(x)
        if ok.any():
            # a white edge keeps the marks visible on every colour map, its dark end included
            artists.append(_role(ax.scatter(xmap(x[ok]), ymap(y[ok]), s=16, marker="D", color=color or LOCATED_COLOR,
                                            edgecolors="white", linewidths=0.6, zorder=4, label=text), "located", text))
    cont = bds.attrs.get("continue_in")
    if cont and f"curve_{along}" in bds and chart_other in (None, cont):
        cx, cy = _isel(bds[f"curve_{along}"], sel), _isel(bds[f"curve_{cont}"], sel)
        first = True
        for k in range(cx.sizes["curve"]):
            px = np.asarray(cx.isel(curve=k).values, dtype=float)
            py = np.asarray(cy.isel(curve=k).values, dtype=float)
            ok = np.isfinite(px) & np.isfinite(py)
            if ok.sum() < 2:
                continue
            text = (f"{label_prefix}continued in ({name_of(bds, along, ds)}, {name_of(bds, cont, ds)}) from the "
                    f"located ones (pseudo-arclength; every point on {criterion_text(bds, ds)} to the criterion's "
                    "accuracy)")
            (line,) = ax.plot(xmap(px[ok]), ymap(py[ok]), color=color or CONTINUED_COLOR, lw=1.6, zorder=3,
                              label=text if first else None)
            artists.append(_role(line, "continued", text))
            first = False
        if f"fold_{along}" in bds:
            fx = np.asarray(bds[f"fold_{along}"].values, dtype=float).ravel()
            fy = np.asarray(bds[f"fold_{cont}"].values, dtype=float).ravel()
            ok = np.isfinite(fx) & np.isfinite(fy)
            if ok.any():
                text = f"{label_prefix}fold of a continued boundary (it turns back there)"
                artists.append(_role(ax.scatter(xmap(fx[ok]), ymap(fy[ok]), s=28, marker="o", facecolors="none",
                                                edgecolors=color or CONTINUED_COLOR, zorder=5, label=text),
                                     "fold", text))
    return artists


def _isel(da, sel):
    """``da`` at the indices ``sel`` gives of its own dimensions."""
    return da.isel({k: v for k, v in sel.items() if k in da.dims})


def _role(artist, role, text):
    """Mark what an overlay artist shows (for :func:`legend_entries`)."""
    artist._mechsweep_boundary = (role, text)
    return artist


def legend_entries(artists, bds, ds=None) -> list:
    """Legend entries of :func:`overlay`'s artists, few of them: the located points and the
    continued curves of one boundary as one entry (a tuple: the artists, then the label), the folds
    as another. Entries of artists from several calls (panels) are given once."""
    from matplotlib.lines import Line2D

    found = {}
    for a in artists:
        role, text = getattr(a, "_mechsweep_boundary", (None, None))
        if role is not None:
            found.setdefault(role, (a, text))
    entries = []
    crit = criterion_text(bds, ds)
    along = name_of(bds, bds.attrs.get("along", ""), ds)
    marks = []
    if "located" in found:
        a = found["located"][0]
        marks.append(Line2D([], [], marker="D", ls="none", ms=4.5, color=LOCATED_COLOR, mec="white", mew=0.6) if hasattr(a, "get_offsets")
                     else Line2D([], [], color=LOCATED_COLOR, lw=1.0, ls=(0, (1, 1))))
    if "continued" in found:
        marks.append(Line2D([], [], color=CONTINUED_COLOR, lw=1.6))
    if marks:
        how = []
        if "located" in found:
            points = hasattr(found["located"][0], "get_offsets")  # points on grid lines, or vertical lines
            how.append(f"located along {along} ({tolerance_text(bds)})" + (" (◆)" if points else ""))
        if "continued" in found:
            how.append("continued between them (line)")
        entries.append((*marks, f"boundary where {crit}: " + ", ".join(how)))
    if "fold" in found:
        entries.append((Line2D([], [], marker="o", ls="none", ms=5, mfc="none", mec=CONTINUED_COLOR),
                        "fold of a continued boundary (it turns back there)"))
    return entries


class _Transposed:
    """An Axes seen with x and y swapped, for the few calls overlay makes."""

    def __init__(self, ax):
        self._ax = ax

    def axvline(self, x, **kw):
        return self._ax.axhline(x, **kw)

    def scatter(self, x, y, **kw):
        return self._ax.scatter(y, x, **kw)

    def plot(self, x, y, **kw):
        return self._ax.plot(y, x, **kw)


def small_curves(bds, box, *, xmap=None, ymap=None, frac=0.05):
    """The extent ((x0, x1), (y0, y1)), in chart coordinates, of the continued curves that begin and
    end inside the chart and span less than ``frac`` of ``box`` ((x0, x1), (y0, y1)) both ways (an
    island too small to see on the chart), all of them together; None when there is none."""
    along, cont = bds.attrs.get("along"), bds.attrs.get("continue_in")
    if not cont or f"curve_{along}" not in bds:
        return None
    xmap = xmap or (lambda v: v)
    ymap = ymap or (lambda v: v)
    cx = np.asarray(bds[f"curve_{along}"].values, dtype=float).reshape(-1, bds.sizes["point"])
    cy = np.asarray(bds[f"curve_{cont}"].values, dtype=float).reshape(-1, bds.sizes["point"])
    (bx0, bx1), (by0, by1) = box
    logy = by0 > 0 and by1 / by0 > 50
    span = lambda lo, hi, log: (np.log10(hi) - np.log10(lo)) if log else (hi - lo)  # noqa: E731
    xs, ys = [], []
    for px, py in zip(cx, cy):
        ok = np.isfinite(px) & np.isfinite(py)
        if ok.sum() < 2:
            continue
        x, y = xmap(px[ok]), ymap(py[ok])
        tx, ty = 1e-9 * abs(bx1 - bx0), 1e-9 * abs(by1 - by0)
        if (x.min() <= min(bx0, bx1) + tx or x.max() >= max(bx0, bx1) - tx or y.min() <= min(by0, by1) + ty
                or y.max() >= max(by0, by1) - ty):
            continue  # it reaches the chart's edge: a piece of a boundary that leaves it, not an island
        if (span(x.min(), x.max(), False) < frac * abs(bx1 - bx0)
                and span(y.min(), y.max(), logy) < frac * abs(span(min(by0, by1), max(by0, by1), logy))):
            xs += [x.min(), x.max()]
            ys += [y.min(), y.max()]
    if not xs:
        return None
    return (min(xs), max(xs)), (min(ys), max(ys))


def _line_dim(bds):
    """The first numeric dim (other than crossing) with more than one value, else None."""
    for d in bds["boundary"].dims:
        if d != "crossing" and bds.sizes[d] > 1 and bds[d].dtype.kind in "fiu":
            return d
    return None


def can_boundaries(ds) -> bool:
    """A boundaries dataset with at least one located boundary."""
    return is_boundaries(ds) and bool(np.isfinite(np.asarray(ds["boundary"].values, dtype=float)).any())


def boundaries(ds, *, fig=None, ax=None):
    """The located boundaries (and the continued ones) alone: the axis they were located along
    against another axis of the scene, one colour per combination of the remaining axes."""
    along = ds.attrs["along"]
    line_dim = _line_dim(ds)
    fig, axes = new_figure(1, 1, width=9.5, height=5.0, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, overlays=[])
    ax = axes[0, 0]
    rest = [d for d in ds["boundary"].dims if d not in (line_dim, "crossing")]
    combos = list(np.ndindex(*(ds.sizes[d] for d in rest)))
    for k, idx in enumerate(combos[:10]):  # at most 10 colours stay readable
        sel = dict(zip(rest, idx))
        name = ", ".join(value_text(ds[d], ds[d].values[i]) for d, i in sel.items())
        art["overlays"] += overlay(ax, ds, line_dim=line_dim, sel=sel, color=f"C{k % 10}" if len(combos) > 1 else None,
                label_prefix=f"{name}: " if name else "")
    unit = units_text(ds["boundary"].attrs.get("units", ""))
    ax.set_xlabel(f"{name_of(ds, along)} [{unit}]" if unit else name_of(ds, along))
    if line_dim is not None:
        ax.set_ylabel(label(ds[line_dim]))
        if ds[line_dim].attrs.get("spacing") == "log":
            ax.set_yscale("log")
    else:
        ax.set_yticks([])
        ax.set_ylabel("(no other axis)")
    ax.grid(True, alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    art["legend"] = ax.legend(handles, [wrap(lab, 44) for lab in labels], fontsize=7,
                              loc="upper left", bbox_to_anchor=(1.01, 1.0))
    n = int(ds.attrs.get("located", 0))
    title(fig, ds, f"Boundaries located along {name_of(ds, along)} where {criterion_text(ds)} ({n} located)")
    return art


FIGURES = (
    ModelFigure("boundaries", boundaries, dataset_kinds=(KIND,), needs=("boundary",), fits=can_boundaries),
)
