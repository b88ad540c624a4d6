"""Labels and style shared by every figure; everything comes from dataset attributes.

Figures are made as ``matplotlib.figure.Figure`` objects, not through pyplot: drawing one changes
no matplotlib global state (backend, rcParams, pyplot's list of open figures), so it works headless
and inside a user's own session alike.

Every figure function takes ``fig=`` (a Figure or SubFigure of the user's to draw into) or ``ax=``
(the user's Axes: one, or a sequence with one per panel) and returns a :class:`Drawn` (a dict of
the artists it made, with the figure under ``"figure"`` and the panels under ``"axes"``)."""
from __future__ import annotations

import re
import textwrap

import matplotlib.patheffects as patheffects
import numpy as np
from matplotlib.figure import Figure

STATUS_OK = 0
NBSP = "\u00a0"
HALO_DARK = [patheffects.withStroke(linewidth=2.6, foreground="0.1")]  # white lines seen on light and dark colours


class Drawn(dict):
    """The artists a figure function made, by name; ``figure`` and ``axes`` always present."""

    @property
    def figure(self):
        return self["figure"]


# ----------------------------------------------------------------------------- units
_POWER = re.compile(r"^([^\W\d]+|°|%)(?:\^?\(?(-?\d+(?:\.\d+)?)\)?)?$")


def units_text(unit) -> str:
    """A UDUNITS/CF unit string as it should read on a figure: ``rad s-1`` -> rad s$^{-1}$,
    ``kg m2`` -> kg m$^{2}$ (also the older ``kg m^2``); ``1``, ``-`` and empty (dimensionless)
    -> ''. A string it does not recognise token by token (e.g. ``1/(rad^2 s^2)``) is kept as is."""
    unit = "" if unit is None else str(unit).strip()
    if unit in ("", "1", "-"):
        return ""
    out = []
    for token in unit.split():
        m = _POWER.match(token)
        if not m:
            return unit
        base, power = m.groups()
        out.append(base if power in (None, "1") else f"{base}$^{{{power}}}$")
    return " ".join(out)


def _unbreakable(text: str, width: int | None = None) -> str:
    """Spaces inside parentheses or brackets become non-breaking, so wrapping never splits them;
    except in a bracketed part longer than ``width`` (it could not fit on one line: kept whole it
    ran off the figure's edge)."""
    opened, spans, chars = [], [], list(text)
    for i, ch in enumerate(text):
        if ch in "([{":
            opened.append(i)
        elif ch in ")]}" and opened:
            spans.append((opened.pop(), i + 1))
    spans += [(i, len(text)) for i in opened]  # one never closed: to the end, as before
    for a, b in spans:  # every part that fits on a line, also one inside a longer part
        if width is None or b - a <= width:
            chars[a:b] = [NBSP if c == " " else c for c in chars[a:b]]
    return "".join(chars)


def wrap(text: str, width: int) -> str:
    """Wrap at spaces, never inside (...) or [...] (those stay on one line) unless one is longer
    than a line."""
    return "\n".join(textwrap.wrap(_unbreakable(text, width), width, break_long_words=False,
                                    break_on_hyphens=False))


def label(da, width: int = 42) -> str:
    """'long name [unit]' from a DataArray's attributes (unit omitted when dimensionless)."""
    name = da.attrs.get("long_name", da.name)
    unit = units_text(da.attrs.get("units", ""))
    sym = da.attrs.get("symbol", "")
    head = f"{sym}, {name}" if sym and len(sym) <= 4 and sym != da.name else name
    text = f"{head} [{unit.replace(' ', NBSP)}]" if unit else head
    return wrap(text, width)


def fixed_text(ds, skip=()) -> str:
    """'lambda1 = 0.8, ...' for the scalar coordinates (fixed parameters) of a dataset."""
    parts = []
    for k in ds.coords:
        if k in ds.dims or k in skip or ds[k].ndim:
            continue
        v = ds[k].values
        unit = units_text(ds[k].attrs.get("units", ""))
        val = str(v) if v.dtype.kind in "OUS" else f"{float(v):g}"
        # non-breaking spaces keep "N m s rad-1" on one line when the caption wraps
        text = f"{k} = {val}" + (f" {unit}" if unit else "")
        parts.append(text.replace(" ", NBSP))
    return ", ".join(parts)


def ok_values(ds, name):
    """The output with non-ok points masked (NaN), so nothing flagged is drawn as a result."""
    return ds[name].where(ds["status"] == STATUS_OK)


# ----------------------------------------------------------------------------- figures and panels
def new_figure(nrows=1, ncols=1, width=6.4, height=4.2, *, fig=None, ax=None):
    """(figure, 2-D array of Axes) for a figure of nrows x ncols panels: the user's Axes (``ax``:
    one, or a sequence with exactly one per panel), a grid in the user's Figure or SubFigure
    (``fig``), or a new Figure (made without pyplot). Only a figure made here or given as ``fig``
    gets a title and a caption (see :func:`title`); given Axes get their panels drawn only."""
    n = nrows * ncols
    if ax is not None:
        axs = np.empty(n, dtype=object)
        given = [ax] if hasattr(ax, "plot") else list(np.asarray(ax, dtype=object).ravel())
        if len(given) != n:
            raise ValueError(f"ax: this figure draws {n} panel(s) ({nrows} x {ncols}); {len(given)} Axes given "
                             f"(pass fig= to let it lay them out)")
        axs[:] = given
        return axs[0].figure, axs.reshape(nrows, ncols)
    if fig is None:
        fig = Figure(figsize=(width * ncols, height * nrows), layout="constrained")
    fig._mechsweep_titled = True
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def width_inches(fig) -> float:
    """Width of a Figure or SubFigure in inches."""
    if hasattr(fig, "get_figwidth"):
        return fig.get_figwidth()
    root = fig.get_figure(root=True)
    return root.get_figwidth() * fig.bbox.width / max(root.bbox.width, 1e-9)


def owns(fig) -> bool:
    """True when the figure's title and caption are ours to set (not a user's Axes)."""
    return bool(getattr(fig, "_mechsweep_titled", False))


def title(fig, ds, what: str, caption: str | None = None, *, caption_box: bool = True) -> str:
    """Title: what the figure shows and the dataset's title. The fixed parameters (and ``caption``
    when given) go to a caption box under the panels, in a smaller font; with ``caption_box``
    False they are returned instead (for a figure whose legend sits under the panels, where the
    box would lie beneath it)."""
    if not owns(fig):
        return ""
    # wrapped here, by characters for the figure's width (~11 per inch at 11 pt): matplotlib's own
    # wrap=True measured at the screen's dpi and let a title saved at 150 dpi run off both edges
    head = textwrap.fill(what, max(20, int(width_inches(fig) * 11)), break_on_hyphens=False)
    fig.suptitle(f"{head}\n{ds.attrs.get('title', '')}".strip(), fontsize=11)
    fixed = fixed_text(ds)
    lines = [c for c in (caption, f"fixed: {fixed}" if fixed else "") if c]
    chars = int(width_inches(fig) * 15)  # ~15 characters per inch at 7.5 pt
    text = "\n".join(textwrap.fill(c, chars, break_on_hyphens=False) for c in lines)
    if text and caption_box:
        fig.supxlabel(text, fontsize=7.5, color="0.25", ha="center",
                      bbox=dict(boxstyle="round,pad=0.4", facecolor="0.96", edgecolor="0.8"))
    return "" if caption_box else text


def flag_note(ax, ds, text=None):
    """Say above the panel (outside it, so it covers nothing) how many points were flagged and so
    are not drawn. Returns the Text (None when nothing is flagged)."""
    bad = int((ds["status"].values != STATUS_OK).sum())
    if not bad:
        return None
    return ax.text(1.0, 1.01, text or f"{bad} flagged point(s) not drawn (see status)", transform=ax.transAxes,
                   ha="right", va="bottom", fontsize=7, color="0.35")


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


def lines_data(fig) -> list[np.ndarray]:
    """The arrays a figure draws (line data, scatter offsets, mesh values, contour paths), in drawing
    order, for fingerprints of figure data (tests) without looking at pixels."""
    from matplotlib.collections import PathCollection, QuadMesh
    from matplotlib.contour import ContourSet

    out = []
    for ax in fig.axes:
        for line in ax.lines:
            out.append(np.asarray(line.get_xydata(), dtype=float))
        for c in ax.collections:
            if isinstance(c, QuadMesh):
                out.append(np.ma.filled(np.ma.asarray(c.get_array(), dtype=float), np.nan).ravel())
            elif isinstance(c, ContourSet):
                verts = [p.vertices for p in c.get_paths() if len(p.vertices)]
                out.append(np.concatenate(verts) if verts else np.zeros((0, 2)))
            elif isinstance(c, PathCollection):
                out.append(np.asarray(c.get_offsets(), dtype=float))
    return out
