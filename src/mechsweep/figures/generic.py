"""Figures for any model, chosen from what the dataset declares, never from variable names.

Over 700 lines on purpose: the three generic drawings share their labelling, flag notes and
thinning rules, and ``choose`` decides among them in one place.

Three drawings, each on one matplotlib ``Axes`` (``ax=``; a new figure when omitted), returning its
artists and changing no matplotlib global state:

- :func:`heatmap`: one output over two numeric axes, colour map with labelled contours;
- :func:`nomogram`: one output against one axis, one labelled curve per value of a second axis
  (a single curve when no second axis is given);
- :func:`stability_panel` (via :func:`stability_map`): stable / unstable shading of an output of
  kind ``floquet_max`` with the boundary where it crosses 1.

Labels come from the attributes (``long_name``, ``units``, ``symbol``); an axis whose ``spacing``
attribute is ``"log"`` is drawn on a log scale. Heatmaps and nomograms draw every finite value, also
at points whose status is not ok (a point's status covers all its outputs; one that failed may leave
the others valid) and mark those points lightly; NaN is never drawn.

Which figures a dataset gets (:func:`choose`), per output that no figure for its model draws:

- kind ``floquet_max`` and two or more numeric axes: ``stability_map`` (``stability_map_<output>``
  for a second such output);
- any other float output over the grid (outputs with extra dimensions, e.g. time histories, are
  left out), with the numeric axes that have more than one value, in the scene's order:

  - one numeric axis: ``nomogram_<output>`` when another axis (numeric or a list of names) has at
    most ``FAMILY_MAX`` values, a curve per value; else ``curve_<output>``;
  - two or more: ``heatmap_<output>`` over the first two (the first is y, the second x), and also
    ``nomogram_<output>`` when one of the two has at most ``FAMILY_MAX`` values (the one with fewer
    values gives the curves, the other is x);
  - no numeric axis: nothing.

- an output with one extra numeric dimension (e.g. a time history), when every grid axis has one
  value (one point: ``mechsweep plot --point``, or a one-point scene): ``history_<output>``, the
  output against that dimension.

  Axes a figure does not use give one panel per value, at most ``MAX_PANELS`` panels (the first
  values); the panel titles say which slice each is, and the figure title says when panels were
  left out.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import matplotlib
import matplotlib.patheffects as patheffects
import numpy as np
from matplotlib.colors import ListedColormap, LogNorm, Normalize
from matplotlib.legend_handler import HandlerTuple
from matplotlib.lines import Line2D
from matplotlib.ticker import LogLocator, MaxNLocator

from . import located
from ._style import (STATUS_OK, Drawn, hatch_unstable, label, log_scale, name_text, new_figure, prose,
                     readable_log_ticks, stable_cmap, stable_patch, title, unstable_patch, units_text, value_text, wrap)

STABLE_COLORS = stable_cmap()  # unstable, stable (colour-blind safe; the unstable side also hatched)
FLOQUET_SLACK = 1e-6  # a modulus within this of 1 counts as on the unit circle (stable, undamped)
MAX_PANELS = 4  # panels per generic figure (one per value of the axes the figure does not use)
FAMILY_MAX = 10  # an axis with at most this many values can give a family of curves
LEGEND_MAX = 5  # up to this many curves: a legend; more: a colour scale and labels at the curve ends
MAX_CURVES = 12  # more values than this on the family axis: every k-th value is drawn (said with the family)
LOG_DECADES = 3  # a positive colour scale or y axis spanning at least this many decades is logarithmic
HALO = [patheffects.withStroke(linewidth=2.4, foreground="white")]  # keeps black lines visible on dark colours
FLAG_STYLE = dict(marker="x", s=14, color="0.5", linewidths=0.8, zorder=4,  # grey, haloed: seen on any colour
                  path_effects=[patheffects.withStroke(linewidth=1.8, foreground="white")])


# ----------------------------------------------------------------------------- what the dataset declares
CONTOUR_MIN_VALUES = 5  # a stability map draws its grid contour only with at least this many values per axis

def grid_dims(ds) -> list[str]:
    """The dataset's grid dimensions (those of ``status`` in a run, else all dimensions)."""
    return list(ds["status"].dims) if "status" in ds else list(ds.dims)


def is_numeric(ds, dim) -> bool:
    return ds[dim].dtype.kind in "fiu"


def is_log(ds, dim) -> bool:
    """True when the axis was swept log-spaced (the ``spacing`` attribute a run stores)."""
    return ds[dim].attrs.get("spacing") == "log" and bool((np.asarray(ds[dim].values, dtype=float) > 0).all())


def declared_floats(ds) -> list[str]:
    """The float data variables among the run's declared outputs, in declared order: the ``outputs``
    attribute (the names separated by spaces, as the runner writes it; bytes, as an HDF5 file written
    by another tool may give it, decoded; or a list of names), every data variable when there is none.
    What float_outputs and history_outputs select from."""
    declared = ds.attrs.get("outputs")
    if isinstance(declared, bytes):
        declared = declared.decode(errors="replace")
    if declared is None or isinstance(declared, str):
        names = declared.split() if declared else list(ds.data_vars)
    else:  # a list or array of names
        names = [x.decode(errors="replace") if isinstance(x, bytes) else str(x) for x in np.ravel(declared)]
    return [n for n in names if n in ds.data_vars and ds[n].dtype.kind == "f"]


def float_outputs(ds) -> list[str]:
    """Float outputs defined over the grid only: the run's declared ``outputs`` attribute (every
    float data variable when there is none), in declared order."""
    grid = set(grid_dims(ds))
    return [n for n in declared_floats(ds) if set(ds[n].dims) <= grid]


def _axes(ds, name) -> list[str]:
    """The output's grid dimensions with more than one value, in the scene's order."""
    return [d for d in grid_dims(ds) if d in ds[name].dims and ds.sizes[d] > 1]


@dataclass(frozen=True)
class Choice:
    """One generic figure: ``kind`` (heatmap, nomogram, curve, history, stability_map) of ``output`` with
    ``x`` and ``y`` (the heatmap's y axis or the nomogram's family axis)."""

    name: str
    kind: str
    output: str
    x: str
    y: str | None
    description: str

    def draw(self, ds, *, fig=None, ax=None, boundaries=None):
        """The figure's artists (a Drawn dict; ``["figure"]`` is the Figure). A stability map and a
        heatmap draw ``boundaries`` (located on this grid) over the chart when it was located along
        one of their two axes (:meth:`draws`); the other figures leave them out."""
        if self.kind == "stability_map":
            return stability_map(ds, self.output, x=self.x, y=self.y, fig=fig, ax=ax, boundaries=boundaries)
        return _panel_figure(ds, self, fig=fig, ax=ax, boundaries=boundaries if self.draws(boundaries) else None)

    def draws(self, boundaries) -> bool:
        """Whether this figure draws ``boundaries`` (a boundaries dataset of its grid): a map (stability
        map or heatmap) with the axis they were located along as one of its two axes. A nomogram or a
        curve plots an output's value against one axis, where a boundary in the parameters has no place."""
        return (boundaries is not None and self.kind in ("stability_map", "heatmap")
                and boundaries.attrs.get("along") in (self.x, self.y))


def _map_axes(ds, name) -> tuple[str, str]:
    """(y, x) of a stability map: the first two numeric axes of the scene, the one with more values
    across (a three-value list axis makes three rows, not three wide columns)."""
    first, second = [d for d in _axes(ds, name) if is_numeric(ds, d)][:2]
    return (second, first) if ds.sizes[first] > ds.sizes[second] else (first, second)


def choose(ds, drawn=frozenset(), *, x=None, y=None) -> list[Choice]:
    """The generic figures for ``ds``, leaving out outputs in ``drawn`` (shown by a figure for the
    model). The rule is the module docstring's; ``x`` / ``y`` (axis names, e.g. from
    ``mechsweep plot --x/--y``) replace its choice of axes: ``x`` the horizontal axis, ``y`` the
    vertical axis of a map or the axis whose values give a nomogram's curves. Given, only the
    outputs over those axes get figures (refused with InputError: an axis that is not a grid
    dimension with more than one value, a non-numeric ``x``, ``y`` equal to ``x``)."""
    if x is not None or y is not None:
        _check_axes(ds, x, y)
    choices = []
    floquet = [n for n in float_outputs(ds) if n not in drawn and ds[n].attrs.get("mechsweep_kind") == "floquet_max"
               and len([d for d in _axes(ds, n) if is_numeric(ds, d)]) >= 2]
    for k, name in enumerate(floquet):
        pair = _map_axes(ds, name) if x is None and y is None else _given_map_axes(ds, name, x, y)
        if pair is None:
            continue
        my, mx = pair
        choices.append(Choice("stability_map" if k == 0 else f"stability_map_{name}", "stability_map", name, mx, my,
                              f"Floquet stability of {_what(ds, name)} over {_ax(ds, mx)} and {_ax(ds, my)}: "
                              f"stable where it is at most 1, boundary drawn{_panels_text(ds, name, (mx, my))}."))
    for name in float_outputs(ds):
        if name in drawn or name in floquet:
            continue
        axes = _axes(ds, name)
        if x is not None or y is not None:
            choices += _given_choices(ds, name, axes, x, y)
            continue
        numeric = [d for d in axes if is_numeric(ds, d)]
        if not numeric:
            continue
        if len(numeric) == 1:
            hx = numeric[0]
            family = next((d for d in axes if d != hx and ds.sizes[d] <= FAMILY_MAX), None)
            choices.append(_nomogram_choice(ds, name, hx, family))
            continue
        hy, hx = numeric[:2]
        choices.append(_heatmap_choice(ds, name, hx, hy))
        if min(ds.sizes[hx], ds.sizes[hy]) <= FAMILY_MAX:
            family, hx = (hy, hx) if ds.sizes[hy] <= ds.sizes[hx] else (hx, hy)
            choices.append(_nomogram_choice(ds, name, hx, family))
    if x is None and y is None:
        choices += [_history_choice(ds, name, extra) for name, extra in history_outputs(ds) if name not in drawn]
    return choices


def history_outputs(ds) -> list[tuple[str, str]]:
    """(output, its extra dimension) of the declared float outputs over the grid and one numeric
    dimension more, when the grid is one point (every grid dimension of size 1)."""
    grid = set(grid_dims(ds))
    if any(ds.sizes[d] > 1 for d in grid):
        return []
    found = []
    for n in declared_floats(ds):
        extra = [d for d in ds[n].dims if d not in grid]
        if len(extra) == 1 and extra[0] in ds.coords and is_numeric(ds, extra[0]) and ds.sizes[extra[0]] > 1:
            found.append((n, extra[0]))
    return found


def _history_choice(ds, name, extra) -> Choice:
    return Choice(f"history_{name}", "history", name, extra, None,
                  f"{_what(ds, name)} against {_ax(ds, extra)} at the grid's one point.")


def _check_axes(ds, x, y) -> None:
    from ..errors import InputError

    dims = [d for d in grid_dims(ds) if ds.sizes[d] > 1]
    numeric = [d for d in dims if is_numeric(ds, d)]
    if x is not None and x not in numeric:
        why = ("is not numeric (a list of names cannot be a horizontal axis; use it as --y)" if x in dims else
               "is not an axis of this dataset with more than one value" + _did_you_mean(x, numeric))
        raise InputError(f"--x {x}: {why}; allowed: {', '.join(numeric) or 'none'}")
    if y is not None and y not in dims:
        others = [d for d in dims if d != x]
        raise InputError(f"--y {y}: not an axis of this dataset with more than one value{_did_you_mean(y, others)}; "
                         f"allowed: {', '.join(others) or 'none'}")
    if y is not None and y == x:
        raise InputError(f"--y {y}: the same axis as --x; allowed: {', '.join(d for d in dims if d != x) or 'none'}")


def _did_you_mean(word, allowed) -> str:
    import difflib
    hint = difflib.get_close_matches(word, allowed, n=1, cutoff=0.5) or [a for a in allowed if a.lower() == word.lower()]
    return f" (did you mean {hint[0]!r}?)" if hint else ""


def _given_map_axes(ds, name, x, y):
    """(y, x) of a stability map with the axes given (the missing one: the first other numeric
    axis of the output), or None when the output is not over them."""
    axes = [d for d in _axes(ds, name) if is_numeric(ds, d)]
    if (x is not None and x not in axes) or (y is not None and y not in axes):
        return None
    x = x if x is not None else next(d for d in axes if d != y)
    y = y if y is not None else next(d for d in axes if d != x)
    return y, x


def _given_choices(ds, name, axes, x, y) -> list[Choice]:
    """The figures of output ``name`` (over ``axes``) with the axes given: a heatmap where the vertical
    axis is numeric, a nomogram where the curve axis is ``y`` (any number of values), has at most
    FAMILY_MAX values or is a list of names (its curves thinned beyond MAX_CURVES, as always), a
    curve where there is no second axis."""
    if (x is not None and x not in axes) or (y is not None and y not in axes):
        return []
    if x is None:
        x = next((d for d in axes if d != y and is_numeric(ds, d)), None)
        if x is None:
            return []
    out = []
    vertical = y if y is not None else next((d for d in axes if d != x and is_numeric(ds, d)), None)
    if vertical is not None and is_numeric(ds, vertical):
        out.append(_heatmap_choice(ds, name, x, vertical))
    family = y if y is not None else next((d for d in axes if d != x and ds.sizes[d] <= FAMILY_MAX), None)
    # an axis asked for by --y gives curves however many values it has (thinned beyond MAX_CURVES)
    if family is None or family == y or ds.sizes[family] <= FAMILY_MAX or not is_numeric(ds, family):
        out.append(_nomogram_choice(ds, name, x, family))
    return out


def _heatmap_choice(ds, name, x, y) -> Choice:
    return Choice(f"heatmap_{name}", "heatmap", name, x, y,
                  f"{_what(ds, name)} over {_ax(ds, x)} and {_ax(ds, y)}: colour map with labelled "
                  f"contours{_panels_text(ds, name, (x, y))}.")


def _nomogram_choice(ds, name, x, family) -> Choice:
    if family is None:
        return Choice(f"curve_{name}", "curve", name, x, None,
                      f"{_what(ds, name)} against {_ax(ds, x)}{_panels_text(ds, name, (x,))}.")
    return Choice(f"nomogram_{name}", "nomogram", name, x, family,
                  f"{_what(ds, name)} against {_ax(ds, x)}, one labelled curve per value of {_ax(ds, family)}"
                  f"{_panels_text(ds, name, (x, family))}.")


def _what(ds, name) -> str:
    unit = ds[name].attrs.get("units", "")
    return f"{name} ({ds[name].attrs.get('long_name', name)}" + (f" [{unit}])" if units_text(unit) else ")")


def _ax(ds, dim) -> str:
    return dim + (" (log axis)" if is_log(ds, dim) else "")


def _panels_text(ds, name, used) -> str:
    rest = [d for d in _axes(ds, name) if d not in used]
    if not rest:
        return ""
    n = int(np.prod([ds.sizes[d] for d in rest]))
    return (f"; one panel per value of {', '.join(rest)}" if n <= MAX_PANELS
            else f"; one panel per value of {', '.join(rest)} (the first {MAX_PANELS} of {n})")


# ----------------------------------------------------------------------------- drawing on one Axes
def _new_axes(ax, width=6.4, height=4.4):
    if ax is not None:
        return ax
    _, axes = new_figure(1, 1, width=width, height=height)
    return axes[0, 0]


def _slice(ds, name, used, at):
    """The output with every dimension outside ``used`` reduced to one value: ``at``'s (labels), else
    the first. Returns (data, flagged or None, {dim: value}); ``flagged`` is True where the status
    is not ok (over the dimensions in ``used``)."""
    for d in used:
        if d not in ds[name].dims:
            raise ValueError(f"{d!r} is not a dimension of {name!r} (its dimensions: {', '.join(ds[name].dims)})")
    at = dict(at or {})
    unknown = [d for d in at if d not in ds[name].dims or d in used]
    if unknown:
        raise ValueError(f"at: {', '.join(unknown)} is not one of the dimensions {name} is sliced along "
                         f"({', '.join(d for d in ds[name].dims if d not in used) or 'none'})")
    where = {}
    for d in ds[name].dims:
        if d not in used:
            where[d] = at[d] if d in at else ds[d].values[0]
    da = ds[name].sel(where) if where else ds[name]
    flagged = None
    if "status" in ds:
        st = ds["status"]
        flagged = st.sel({d: v for d, v in where.items() if d in st.dims}) != STATUS_OK
        flagged = flagged.any([d for d in flagged.dims if d not in used])  # any over dims the output lacks
    return da, flagged, where


def _edges(values, log):
    """Cell edges around sorted centres (geometric midpoints on a log axis)."""
    v = np.log(values) if log else np.asarray(values, dtype=float)
    if v.size == 1:
        e = np.array([v[0] - 0.5, v[0] + 0.5])
    else:
        mid = (v[1:] + v[:-1]) / 2
        e = np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])
    return np.exp(e) if log else e


def _spans_decades(v) -> bool:
    v = v[np.isfinite(v)]
    return v.size > 0 and bool((v > 0).all()) and v.max() / v.min() >= 10.0**LOG_DECADES


def contour_levels(vmin: float, vmax: float, log: bool) -> np.ndarray:
    """Readable contour levels inside (vmin, vmax): round numbers (1, 2, 2.5, 5 x 10^k steps, at
    most about 7 of them), or decades on a logarithmic scale (with 2 and 5 when few decades); none
    within 0.1 % of the range from either end (a level at a plateau, e.g. a multiplier modulus of
    1 up to round-off, would draw round-off noise)."""
    if not (np.isfinite(vmin) and np.isfinite(vmax)) or vmax <= vmin:
        return np.array([])
    if log:
        levels = LogLocator(base=10, subs=(1.0,)).tick_values(vmin, vmax)
        inside = levels[(levels > vmin) & (levels < vmax)]
        if inside.size < 3:
            levels = LogLocator(base=10, subs=(1.0, 2.0, 5.0)).tick_values(vmin, vmax)
    else:
        levels = MaxNLocator(nbins=7, steps=[1, 2, 2.5, 5, 10]).tick_values(vmin, vmax)
    margin = 1e-3 * (np.log10(vmax / vmin) if log else vmax - vmin)  # a level at a plateau draws round-off
    lo, hi = (vmin * 10**margin, vmax / 10**margin) if log else (vmin + margin, vmax - margin)
    return levels[(levels > lo) & (levels < hi)]


def _level_text(v: float) -> str:
    return f"{v:.4g}"  # 1000 rather than 1e+03; levels are round numbers, so 4 digits are never cut


def heatmap(ds, name, *, x, y, at=None, ax=None, colorbar=True, contours=True):
    """``name`` over the numeric axes ``x`` and ``y`` as a colour map with labelled contours.

    ``at`` picks the value of every other dimension (labels, e.g. ``{"position": "inverted"}``;
    the first value of each when omitted). Returns a dict of the artists: ``mesh``, ``contours``
    (ContourSet or None), ``contour_labels`` (list of Text), ``colorbar`` (or None), ``flagged``
    (the markers of points whose status is not ok, or None), ``note`` (Text or None) and ``where``
    (the slice drawn, {dim: value}).
    """
    for d in (x, y):
        if d in ds.dims and not is_numeric(ds, d):
            raise ValueError(f"heatmap: axis {d!r} holds names, not numbers; give it as nomogram's family")
    ax = _new_axes(ax)
    da, flagged, where = _slice(ds, name, (x, y), at)
    da = da.sortby([y, x]).transpose(y, x)
    xv, yv = np.asarray(ds[x].sortby(x).values, float), np.asarray(ds[y].sortby(y).values, float)
    v = np.asarray(da.values, dtype=float)
    finite = np.isfinite(v)
    classes = discrete_values(ds, name, v)
    log = classes is None and _spans_decades(v)
    vmin, vmax = (float(v[finite].min()), float(v[finite].max())) if finite.any() else (0.0, 1.0)
    norm = LogNorm(vmin, vmax) if log else (Normalize(vmin, vmax) if vmax > vmin else Normalize(vmin - 0.5, vmin + 0.5))
    cmap = "viridis"
    if classes is not None:  # one flat colour per value, a cell edge between two values: no contours
        cmap, norm = _class_colors(ds, name, classes)
    xlog, ylog = _log_axis(ds, x), _log_axis(ds, y)
    mesh = ax.pcolormesh(_edges(xv, xlog), _edges(yv, ylog), np.ma.masked_invalid(v), norm=norm,
                         cmap=cmap, rasterized=True)
    art = {"mesh": mesh, "contours": None, "contour_labels": [], "colorbar": None, "flagged": None,
           "note": None, "where": where, "hatch": None}
    if classes is not None and ds[name].attrs.get("mechsweep_kind") == "verdict":  # unstable cells dotted too
        art["hatch"] = hatch_unstable(ax, _edges(xv, xlog), _edges(yv, ylog), v)
    # contours interpolate between grid values: not between classes, nor across an axis of fewer
    # than CONTOUR_MIN_VALUES values (straight lines between a few rows mean nothing)
    resolved = min(xv.size, yv.size) >= CONTOUR_MIN_VALUES
    levels = (contour_levels(vmin, vmax, log) if contours and classes is None and resolved and finite.sum() >= 4
              else np.array([]))
    if levels.size:
        cs = ax.contour(xv, yv, np.ma.masked_invalid(v), levels=levels, colors="k", linewidths=0.9)
        cs.set_path_effects(HALO)
        art["contours"] = cs
    if colorbar:
        cb = ax.figure.colorbar(mesh, ax=ax, **({"ticks": classes} if classes is not None else {}))
        if classes is not None:
            cb.ax.set_yticklabels([_level_text(c) for c in classes])
            cb.ax.minorticks_off()
        cb.set_label(label(ds[name], width=34))
        if art["contours"] is not None:
            cb.add_lines(art["contours"])
        if log and classes is None:
            readable_log_ticks(cb.ax.yaxis)
        art["colorbar"] = cb
    if flagged is not None:
        bad = flagged.broadcast_like(da).sortby([y, x]).transpose(y, x).values
        if bad.any():
            yy, xx = np.meshgrid(yv, xv, indexing="ij")
            art["flagged"] = ax.scatter(xx[bad], yy[bad], **FLAG_STYLE)
            art["note"] = _flag_note(ax, int(bad.sum()), int((bad & finite).sum()), _status_counts(_status_codes(ds, where)))
    if xlog:
        log_scale(ax, "x")
    if ylog:
        log_scale(ax, "y")
    ax.set_xlim(_edges(xv, xlog)[[0, -1]])
    ax.set_ylim(_edges(yv, ylog)[[0, -1]])
    if art["contours"] is not None:  # after the scales and limits: labels placed where they do not crowd
        art["contour_labels"] = _contour_labels(ax, art["contours"])
    ax.set_xlabel(label(ds[x]))
    ax.set_ylabel(label(ds[y]))
    return art


DISCRETE_MAX = 8  # an output whose finite values are at most this many whole numbers is drawn by classes
LABEL_GAP = (0.12, 0.07)  # a contour label this close to a kept one (axes fractions, x and y) is left out


def discrete_values(ds, name, v=None):
    """The sorted classes of an output drawn class by class (a flat colour each, no contours), or
    None for a continuous one: a declared ``verdict`` (0/1), or one whose finite values are at most
    DISCRETE_MAX distinct whole numbers (e.g. a -1/0/+1 kind)."""
    v = np.asarray(ds[name].values if v is None else v, dtype=float)
    u = np.unique(v[np.isfinite(v)])
    if ds[name].attrs.get("mechsweep_kind") == "verdict":
        return np.union1d(u, [0.0, 1.0]) if np.isin(u, [0.0, 1.0]).all() else None
    if 1 <= u.size <= DISCRETE_MAX and np.array_equal(u, np.round(u)) and u.size < v.size:
        return u
    return None


def _class_colors(ds, name, classes):
    """(colormap, norm) with one colour per class, the class values at the centres: a verdict in
    the stability map's colours (0 unstable, 1 stable), others from a qualitative palette."""
    from matplotlib.colors import BoundaryNorm

    if ds[name].attrs.get("mechsweep_kind") == "verdict":
        colors = list(STABLE_COLORS.colors)
    else:
        colors = [matplotlib.colormaps["tab10"](k % 10) for k in range(classes.size)]
    mid = (classes[1:] + classes[:-1]) / 2 if classes.size > 1 else np.array([])
    bounds = np.concatenate([[classes[0] - 0.5], mid, [classes[-1] + 0.5]])
    return ListedColormap(colors[:classes.size]), BoundaryNorm(bounds, classes.size)


def _log_axis(ds, dim) -> bool:
    """Whether a heatmap draws the axis on a log scale: swept log-spaced, or a list of positive
    values spread evenly in the logarithm rather than linearly (e.g. 0.1, 1, 10: linear cells would
    stretch the last one to 14.5)."""
    if is_log(ds, dim):
        return True
    v = np.sort(np.asarray(ds[dim].values, dtype=float))
    if ds[dim].attrs.get("spacing") != "list" or v.size < 3 or not (v > 0).all() or v[-1] / v[0] < 10:
        return False
    lin, lg = np.diff(v), np.diff(np.log(v))
    return bool(lg.max() / lg.min() < lin.max() / lin.min())


def _mid_arc_positions(ax, cs, avoid):
    """For each level of ``cs``: the point half-way along its longest line (in axes fractions) that
    ``avoid(x, y)`` does not exclude, searched outwards from the middle (None when every point is
    excluded)."""
    to_axes = ax.transScale + ax.transLimits
    found = []
    for path in cs.get_paths():
        verts, codes = np.asarray(path.vertices), path.codes
        starts = [0] if codes is None else list(np.flatnonzero(codes == path.MOVETO))
        segs = [verts[a:b] for a, b in zip(starts, starts[1:] + [len(verts)]) if b - a >= 2]
        best = None
        for seg in sorted(segs, key=lambda g: -np.hypot(*np.diff(to_axes.transform(g), axis=0).T).sum()):
            f = to_axes.transform(seg)
            arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(f, axis=0).T))])
            bad = np.asarray(avoid(seg[:, 0], seg[:, 1]), dtype=bool)
            for k in np.argsort(np.abs(arc - arc[-1] / 2)):
                if not bad[k] and np.isfinite(f[k]).all():
                    best = seg[k]
                    break
            if best is not None:
                break
        found.append(best)
    return found


def _contour_labels(ax, cs, *, avoid=None, fmt=None, halo=None, fontsize=8):
    """Inline labels on the contours, at most one per level, none within LABEL_GAP of another (where
    levels bunch up, e.g. an error growing steeply near one edge, they would pile up). With
    ``avoid(x, y) -> bool`` (data coordinates), each label sits half-way along its contour, away
    from the points ``avoid`` marks (e.g. the edge of a region of flagged points, where contours
    crowd); else where matplotlib would put it."""
    fmt = fmt or _level_text
    to_axes = ax.transScale + ax.transLimits  # data -> axes fraction (no renderer needed)
    if avoid is None:
        probe = ax.clabel(cs, fmt=fmt, fontsize=fontsize, inline=False)  # where matplotlib would put them
        candidates = [(t.get_text(), np.asarray(t.get_position(), dtype=float)) for t in probe]
        for t in probe:
            t.remove()
        cs.labelTexts, cs.labelCValues, cs.labelXYs = [], [], []
    else:
        candidates = [(fmt(lv), xy) for lv, xy in zip(cs.levels, _mid_arc_positions(ax, cs, avoid)) if xy is not None]
    kept, seen = [], set()
    for text, xy in candidates:
        f = to_axes.transform(xy)
        if text in seen or not np.isfinite(f).all():
            continue
        if all(abs(f[0] - g[0]) >= LABEL_GAP[0] or abs(f[1] - g[1]) >= LABEL_GAP[1] for _, g in kept):
            kept.append((xy, f))
            seen.add(text)
    if not kept:
        return []
    texts = ax.clabel(cs, fmt=fmt, fontsize=fontsize, inline=True, manual=[tuple(xy) for xy, _ in kept])
    for t in texts:
        t.set_path_effects(halo or HALO)
    return list(texts)


def nomogram(ds, name, *, x, family=None, at=None, ax=None):
    """``name`` against the numeric axis ``x``, one labelled curve per value of ``family`` (a
    single curve when None). Up to ``LEGEND_MAX`` curves: a legend; more: colours from a scale (a
    colour bar when the family axis is numeric) and a label at the end of each curve. At most
    ``MAX_CURVES`` curves (every k-th value beyond that).

    ``at`` picks the value of every other dimension (the first when omitted). Returns a dict of
    the artists: ``lines`` (one Line2D per curve), ``end_labels`` (Text), ``legend``, ``colorbar``,
    ``flagged`` (markers on finite values at points whose status is not ok), ``note``, ``where``.
    """
    if x in ds.dims and not is_numeric(ds, x):
        raise ValueError(f"nomogram: axis {x!r} holds names, not numbers; give it as the family")
    ax = _new_axes(ax)
    used = (x,) if family is None else (x, family)
    da, flagged, where = _slice(ds, name, used, at)
    order = np.argsort(np.asarray(ds[x].values, dtype=float), kind="stable")
    xv = np.asarray(ds[x].values, dtype=float)[order]
    members = [None] if family is None else list(ds[family].values)
    step = max(1, -(-len(members) // MAX_CURVES))
    total = len(members)
    members = members[::step]
    # the curves left out are said where the family is named (legend title, colour bar, else a note)
    thinned = f"every {_ordinal(step)} of {total} values drawn" if step > 1 else ""
    many = len(members) > LEGEND_MAX
    numeric_family = family is not None and is_numeric(ds, family)  # a curve's text: its value, else its name
    colors, cmap_norm = _family_colors(ds, family, members)
    art = {"lines": [], "end_labels": [], "legend": None, "colorbar": None, "flagged": [], "note": None,
           "where": where, "thinned": thinned, "thinned_note": None}
    n_bad = n_bad_drawn = 0
    ends, codes = [], []  # codes: the statuses of the curves drawn
    for member, color in zip(members, colors):
        sel = {} if member is None else {family: member}
        yv = np.asarray(da.sel(sel).values, dtype=float)[order]
        text = None if member is None else value_text(ds[family], member) if numeric_family else str(member)
        (line,) = ax.plot(xv, yv, color=color, lw=1.4, label=text, marker="." if xv.size <= 25 else None, ms=4)
        art["lines"].append(line)
        if flagged is not None:
            codes.append(_status_codes(ds, {**where, **sel}))
            bad = np.asarray(flagged.broadcast_like(da).sel(sel).values)[order]
            shown = bad & np.isfinite(yv)
            n_bad += int(bad.sum())
            n_bad_drawn += int(shown.sum())
            if shown.any():
                art["flagged"].append(ax.scatter(xv[shown], yv[shown], **FLAG_STYLE))
        k = np.flatnonzero(np.isfinite(yv))
        if text is not None and k.size:
            ends.append((xv[k[-1]], yv[k[-1]], text if not many else _value(member), color))
    if not np.isfinite(np.asarray([ln.get_ydata() for ln in art["lines"]], dtype=float)).any():
        art["note"] = ax.text(0.5, 0.5, "no finite value to draw", transform=ax.transAxes, ha="center",
                              color="0.35")
    if is_log(ds, x):
        log_scale(ax, "x")
    if _spans_decades(np.concatenate([ln.get_ydata() for ln in art["lines"]])):
        log_scale(ax, "y")
    if family is not None and not many:
        art["legend"] = ax.legend(fontsize=7, title=label(ds[family], width=30) + (f"\n({thinned})" if thinned else ""),
                                  title_fontsize=7)
    elif family is not None:
        art["end_labels"] = _end_labels(ax, ends)
        if cmap_norm is not None:
            sm = matplotlib.cm.ScalarMappable(norm=cmap_norm[1], cmap=cmap_norm[0])
            cb = ax.figure.colorbar(sm, ax=ax, pad=0.09)
            cb.set_label(label(ds[family], width=30) + (f"\n({thinned})" if thinned else ""))
            art["colorbar"] = cb
        elif thinned:  # names at the curve ends only: the note above the panel says it
            art["thinned_note"] = ax.text(0.0, 1.01, f"curves: {family}, {thinned}", transform=ax.transAxes,
                                          ha="left", va="bottom", fontsize=7, color="0.35")
    if n_bad:
        art["note"] = _flag_note(ax, n_bad, n_bad_drawn, _status_counts(np.concatenate(codes)))
    ax.set_xlabel(label(ds[x]))
    ax.set_ylabel(label(ds[name]))
    ax.grid(True, alpha=0.3)
    return art


def _family_colors(ds, family, members):
    """Colours for the curves: a scale over a numeric family (log when its axis is), else the cycle."""
    if family is None:
        return ["C0"], None
    if len(members) <= LEGEND_MAX or not is_numeric(ds, family):
        return [f"C{k % 10}" for k in range(len(members))], None
    values = np.asarray(members, dtype=float)
    norm = (LogNorm if is_log(ds, family) else Normalize)(values.min(), values.max())
    cmap = matplotlib.colormaps["viridis"]
    return [cmap(0.9 * norm(v)) for v in values], (matplotlib.colors.ListedColormap(cmap(np.linspace(0, 0.9, 256))),
                                                   norm)


def _end_labels(ax, ends):
    """A label beside the last finite point of each curve, moved apart vertically so none overlap."""
    if not ends:
        return []
    ylo, yhi = ax.get_ylim()
    log = ax.get_yscale() == "log"

    def frac(v):
        if log:
            return (np.log10(v) - np.log10(ylo)) / (np.log10(yhi) - np.log10(ylo))
        return (v - ylo) / (yhi - ylo)

    order = sorted(range(len(ends)), key=lambda k: frac(ends[k][1]))
    pos = [frac(ends[k][1]) for k in order]
    gap = min(0.05, 1.0 / max(1, len(pos)))
    for i in range(1, len(pos)):
        pos[i] = max(pos[i], pos[i - 1] + gap)
    shift = max(0.0, pos[-1] - 1.0)
    pos = [p - shift for p in pos]
    texts = []
    for k, p in zip(order, pos):
        xe, ye, text, color = ends[k]
        texts.append(ax.annotate(f" {text}", xy=(xe, ye), xytext=(1.01, p), textcoords="axes fraction",
                                 ha="left", va="center", fontsize=7, color=color, annotation_clip=False,
                                 arrowprops=dict(arrowstyle="-", color=color, lw=0.5, alpha=0.6)))
    return texts


def flag_note_text(n_bad: int, n_drawn: int, statuses=None) -> str:
    """What a note says of the flagged points of a panel: how many, how they are marked, and how
    many of them still have a value (drawn) or have none (left blank). ``statuses``: {status name:
    count} of those points, named in the note (e.g. 'undecided 300': an undamped model's stable
    side, where a verdict output has no value)."""
    why = ("status " + ", ".join(f"{k} {n}" for k, n in statuses.items()) if statuses else "status not ok")
    head = f"{n_bad} flagged point{'s' if n_bad != 1 else ''} ({why}, see status) marked ×"
    if n_drawn == n_bad:
        return f"{head}; each has a value, drawn"
    if n_drawn == 0:
        return f"{head}; none has a value (left blank)"
    return f"{head}; {n_drawn} with a value (drawn), {n_bad - n_drawn} without (left blank)"


def _flag_note(ax, n_bad, n_drawn, statuses=None):
    # under the panel's x label, outside the panel: inside, it covered data and tick labels. Wrapped
    # to the panel's width (about 17 characters an inch at 7 pt): a line wider than the panel made the
    # constrained layout shrink the panel to make room for it, down to nothing
    chars = max(30, int(ax.get_position().width * ax.figure.get_figwidth() * 17))
    return ax.annotate(wrap(flag_note_text(n_bad, n_drawn, statuses), chars), xy=(0.0, 0.0),
                       xycoords=("axes fraction", ax.xaxis.label), xytext=(0, -3), textcoords="offset points",
                       fontsize=7, color="0.25", ha="left", va="top")


def _status_codes(ds, where) -> np.ndarray:
    """The status codes of the points of ``ds`` at ``where`` (labels; every point of the other axes)."""
    if "status" not in ds:
        return np.array([], dtype=int)
    return np.asarray(ds["status"].sel({d: v for d, v in where.items() if d in ds["status"].dims}).values).ravel()


def _status_counts(codes) -> dict:
    """{status name: count} of the codes that are not ok, most frequent first."""
    from .. import status as st

    codes = np.asarray(codes)
    found, counts = np.unique(codes[codes != STATUS_OK], return_counts=True)
    # status names without underscores (a figure's text is mathtext: max_steps would read as a subscript)
    return {st.MEANINGS.get(int(c), str(int(c))).replace("_", " "): int(n)
            for c, n in sorted(zip(found, counts), key=lambda x: -x[1])}


def _ordinal(k: int) -> str:
    return f"{k}{'th' if 10 <= k % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')}"


# ----------------------------------------------------------------------------- whole figures
def _grid(n, ax) -> tuple[int, int]:
    """(rows, columns) of ``n`` panels: two columns, or one column on the user's Axes (one per panel)."""
    return (n, 1) if ax is not None else (-(-n // min(2, n)), min(2, n))


def _legend_entries(overlays, boundaries, ds) -> list:
    """(handle, text) of the located boundaries drawn on the panels: a tuple of artists as one handle."""
    return [(e[:-1] if len(e) > 2 else e[0], e[-1]) for e in located.legend_entries(overlays, boundaries, ds)]


def _panel_figure(ds, choice: Choice, *, fig=None, ax=None, boundaries=None):
    """One panel per value of the axes the figure does not use (at most MAX_PANELS). A heatmap draws
    ``boundaries`` (located along one of its axes, on this grid) over each panel, with a legend."""
    used = (choice.x,) if choice.y is None else (choice.x, choice.y)
    rest = [d for d in _axes(ds, choice.output) if d not in used]
    members = list(itertools.product(*(list(ds[d].values) for d in rest)))
    shown = members[:MAX_PANELS]
    nrows, ncols = _grid(len(shown), ax)
    heat = choice.kind == "heatmap"
    over = heat and boundaries is not None
    # located boundaries: their legend goes under the panels, in a taller figure (the panel keeps its height)
    fig, axes = new_figure(nrows, ncols, width=6.0 if heat else 6.6,
                           height=(4.6 + (1.6 / nrows if over else 0.0)) if heat else 4.0, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, panels=[])
    for k, values in enumerate(shown):
        a = axes[k // ncols, k % ncols]
        at = dict(zip(rest, values))
        if heat:
            art["panels"].append(heatmap(ds, choice.output, x=choice.x, y=choice.y, at=at, ax=a))
            if over:
                art["panels"][-1]["located"] = _located_over(a, ds, boundaries, choice.x, choice.y, at)
        else:
            art["panels"].append(nomogram(ds, choice.output, x=choice.x, family=choice.y, at=at, ax=a))
        if at:
            a.set_title(", ".join(value_text(ds[d], v) for d, v in at.items()), fontsize=9)
    for a in axes.ravel()[len(shown):]:
        fig.delaxes(a)
    what = {"heatmap": "Map", "nomogram": "Nomogram", "curve": "Curve", "history": "History"}[choice.kind]
    long = prose(ds[choice.output].attrs.get("long_name", choice.output))
    cut = f" (first {len(shown)} of {len(members)} slices of {', '.join(rest)})" if len(members) > len(shown) else ""
    if choice.kind == "history":  # the point it belongs to
        cut = " at " + ", ".join(value_text(ds[d], ds[d].values[0]) for d in grid_dims(ds) if d in ds.coords)
    overlays = [a for p in art["panels"] for a in p.get("located") or ()]
    caption = title(fig, ds, f"{what}: {long}{cut}", caption_box=not overlays)
    if overlays:  # what the located points and curves are, under the panels (the caption heads it)
        entries = _legend_entries(overlays, boundaries, ds)
        art["legend"] = fig.legend([h for h, _ in entries], [wrap(t, 60) for _, t in entries],
                                   loc="outside lower center", fontsize=8.5,
                                   handler_map={tuple: HandlerTuple(ndivide=None, pad=0.6)},
                                   title=caption or None, title_fontproperties={"size": 7.5})
    return art


def _located_over(ax, ds, boundaries, xdim, ydim, at) -> list:
    """Draw ``boundaries`` (located along ``xdim`` or ``ydim``) on the panel of ``ds`` at ``at``
    (the values of the other axes): the located points and, when continued in the chart's other
    axis, the curves (:func:`located.overlay`). Returns the artists."""
    along = boundaries.attrs.get("along")
    other = ydim if along == xdim else xdim
    dims = boundaries["boundary"].dims
    sel = {}
    for d in dims:
        if d in (xdim, ydim, "crossing"):
            continue
        values = np.asarray(ds[d].values)
        sel[d] = int(np.flatnonzero(values == at[d])[0]) if d in at else 0  # a one-value axis: its value
    return located.overlay(ax, boundaries, line_dim=other if other in dims else None, sel=sel,
                           transpose=along == ydim, ds=ds, chart_other=other)


def stability_map(ds, name=None, *, x=None, y=None, fig=None, ax=None, boundaries=None):
    """Floquet stability over two axes (stable where the largest multiplier modulus is at most 1),
    one panel per value of the other axes, boundary drawn: the grid's contour and, when
    ``boundaries`` (a boundaries dataset located on this grid along one of the two axes) is
    given, the located points. The modulus is drawn wherever it has a value, whatever the point's
    status (e.g. undecided: |multiplier| within the margin of 1, a neutrally stable point).
    ``x`` / ``y``: the horizontal / vertical axis (default: as :func:`choose` picks them)."""
    if name is None:
        name = next(c.output for c in choose(ds) if c.kind == "stability_map")
    ydim, xdim = _map_axes(ds, name) if x is None and y is None else _given_map_axes(ds, name, x, y)
    ds = ds.sortby([ydim, xdim])  # cells in the order of their values (a list axis need not be sorted)
    given = ax is not None
    others = [d for d in ds[name].dims if d not in (xdim, ydim)]
    every = list(itertools.product(*(range(ds.sizes[d]) for d in others)))
    members = every[:MAX_PANELS]  # as choose's description says (--list)
    nrows, ncols = _grid(len(members), ax)
    below = ncols == 1 and not given  # one column: the legend goes below (beside, it would squeeze the panel)
    # ... in a taller figure, so that the panel keeps its height (the legend took half of it)
    fig, axes = new_figure(nrows, ncols, width=6.0 if below else 5.2, height=(4.0 + 2.2 / nrows) if below else 4.0,
                           fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, panels=[])
    x, y = ds[xdim].values, ds[ydim].values
    for k, idx in enumerate(members):
        ax = axes[k // ncols, k % ncols]
        sel = dict(zip(others, idx))
        values = ds[name].isel(sel).transpose(ydim, xdim).values
        art["panels"].append(stability_panel(ax, x, y, values))
        if boundaries is not None and boundaries.attrs.get("along") in (xdim, ydim):
            at = {d: ds[d].values[i] for d, i in sel.items()}
            art["panels"][-1]["located"] = _located_over(ax, ds, boundaries, xdim, ydim, at)
        if is_log(ds, xdim):
            log_scale(ax, "x")
        if is_log(ds, ydim):
            log_scale(ax, "y")
        ax.set_xlabel(label(ds[xdim]))
        ax.set_ylabel(label(ds[ydim]))
        if others:
            ax.set_title(", ".join(value_text(ds[d], ds[d].values[i]) for d, i in sel.items()), fontsize=10)
        missing = int((~np.isfinite(values)).sum())
        if missing:
            ax.text(0.01, 0.01, f"{missing} point(s) without a value (see status), not drawn", transform=ax.transAxes,
                    fontsize=8, color="0.35")
    for a in axes.ravel()[len(members):]:
        fig.delaxes(a)
    sym = name_text(ds[name])
    # stable points whose status is undecided (the modulus at 1 within the verdict's margin: neutrally
    # stable, as every stable point of an undamped model is) are said so: shaded stable all the same
    undecided = _undecided_stable(ds, name, others, members)
    neutral = (f"; {undecided} of them at 1 within the margin (status undecided: neutrally stable, "
               "e.g. undamped)" if undecided else "")
    handles = [stable_patch(f"stable: {sym} ≤ 1{neutral}"), unstable_patch(f"unstable: {sym} > 1 (dotted)"),
               Line2D([], [], color="k", lw=1.2,
                                       label="boundary between the grid's stable and unstable cells")]
    if not any(p["boundary"] is not None for p in art["panels"]):
        handles.pop()  # no grid contour drawn
    overlays = [a for p in art["panels"] for a in p.get("located") or ()]
    entries = [(h, h.get_label()) for h in handles]
    if overlays:  # the located points and continued curves as one entry, the folds as another
        entries += _legend_entries(overlays, boundaries, ds)
    # (a long label would squeeze the panels beside the legend)
    handles, texts = [h for h, _ in entries], [wrap(t, 34) for _, t in entries]
    cut = (f" (first {len(members)} of {len(every)} slices of {', '.join(others)})" if len(every) > len(members)
           else "")
    caption = title(fig, ds, f"Floquet stability: {prose(ds[name].attrs.get('long_name', name))}{cut}",
                    caption_box=not below)
    # beside two columns of panels; below a single column, where a legend beside it would squeeze it
    # (the fixed parameters then head the legend: a caption box under the panels would lie beneath it)
    tuples = {tuple: HandlerTuple(ndivide=None, pad=0.6)}
    art["legend"] = (fig.legend(handles, texts, loc="outside lower center", fontsize=9, ncols=2, handler_map=tuples,
                                title=caption or None, title_fontproperties={"size": 7.5}) if below else
                     fig.legend(handles, texts, loc="outside right center", fontsize=9, handler_map=tuples))
    return art


def _undecided_stable(ds, name, others, members) -> int:
    """How many points drawn stable (modulus <= 1 + FLOQUET_SLACK) on the panels ``members`` have
    status undecided (read from the dataset)."""
    if "status" not in ds:
        return 0
    from .. import status as st

    n = 0
    for idx in members:
        sel = dict(zip(others, idx))
        v = np.asarray(ds[name].isel(sel).values, dtype=float)
        code = np.asarray(ds["status"].isel({d: i for d, i in sel.items() if d in ds["status"].dims})
                          .broadcast_like(ds[name].isel(sel)).transpose(*ds[name].isel(sel).dims).values)
        n += int(((code == st.UNDECIDED) & (v <= 1.0 + FLOQUET_SLACK)).sum())
    return n


def stability_panel(ax, x, y, values) -> dict:
    """Stable/unstable shading of one map (the unstable cells also dotted) and the boundary between
    them: a modulus at most 1 + FLOQUET_SLACK counts as stable (an undamped stable side sits at 1
    up to round-off), and the boundary is the contour of that verdict at 1/2, so it runs along the
    edges of the shaded cells, between the last stable and the first unstable grid point (a contour
    of the modulus itself hugged the stable points, where it is 1, half a cell off the shading)."""
    verdict = np.where(np.isfinite(values), (values <= 1.0 + FLOQUET_SLACK).astype(float), np.nan)
    art = {"mesh": ax.pcolormesh(x, y, verdict, cmap=STABLE_COLORS, vmin=0, vmax=1, shading="nearest"),
           "boundary": None}
    art["hatch"] = hatch_unstable(ax, x, y, verdict)
    # the grid's contour only where both axes resolve it (across 3 rows it would draw straight
    # lines between rows that mean nothing; located boundaries, when given, are drawn anyway)
    resolved = min(np.size(x), np.size(y)) >= CONTOUR_MIN_VALUES
    if resolved and np.nanmin(verdict, initial=np.inf) < 0.5 < np.nanmax(verdict, initial=-np.inf):
        art["boundary"] = ax.contour(x, y, verdict, levels=[0.5], colors="k", linewidths=1.2)
    return art


def _value(v) -> str:
    return str(v) if np.asarray(v).dtype.kind in "OUS" else f"{float(v):g}"
