"""What a reader of a figure needs, checked on the drawn figure (never on pixels): colours apart for
colour-blind eyes, tick labels that do not run into one another, symbols in mathtext, no literal
underscores, legends off the data. Used by tests/figures/test_figure_data.py (every shipped scene's
figures) and tests/figures/test_figure_readability.py."""
from __future__ import annotations

import re

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb

# ----------------------------------------------------------------------------- colour vision
# Machado, Oliveira & Fernandes (2009), "A physiologically-based model for simulation of color vision
# deficiency", IEEE TVCG 15(6), Table 1, severity 1.0; applied to linear RGB.
DEUTERANOPIA = np.array([[0.367322, 0.860646, -0.227968],
                         [0.280085, 0.672501, 0.047413],
                         [-0.011820, 0.042940, 0.968881]])
PROTANOPIA = np.array([[0.152286, 1.052583, -0.204868],
                       [0.114503, 0.786281, 0.099216],
                       [-0.003882, -0.048116, 1.051998]])


def _linear(c):
    c = np.asarray(c, dtype=float)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _srgb(c):
    c = np.clip(np.asarray(c, dtype=float), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)


def simulate(color, matrix):
    """An sRGB colour as seen with the colour-vision deficiency of ``matrix``."""
    return _srgb(matrix @ _linear(to_rgb(color)))


def lab(color):
    """CIELAB (D65) of an sRGB colour."""
    xyz = np.array([[0.4124564, 0.3575761, 0.1804375],
                    [0.2126729, 0.7151522, 0.0721750],
                    [0.0193339, 0.1191920, 0.9503041]]) @ _linear(to_rgb(color))
    t = xyz / np.array([0.95047, 1.0, 1.08883])
    f = np.where(t > (6 / 29) ** 3, np.cbrt(t), t / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def ciede2000(lab1, lab2) -> float:
    """The CIEDE2000 colour difference (Sharma, Wu & Dalal 2005, equations 1-24; kL = kC = kH = 1)."""
    L1, a1, b1 = lab1
    L2, a2, b2 = lab2
    C = (np.hypot(a1, b1) + np.hypot(a2, b2)) / 2
    G = 0.5 * (1 - np.sqrt(C**7 / (C**7 + 25.0**7)))
    a1p, a2p = (1 + G) * a1, (1 + G) * a2
    C1p, C2p = np.hypot(a1p, b1), np.hypot(a2p, b2)
    h1p = np.degrees(np.arctan2(b1, a1p)) % 360
    h2p = np.degrees(np.arctan2(b2, a2p)) % 360
    dL, dC = L2 - L1, C2p - C1p
    dh = 0.0 if C1p * C2p == 0 else (h2p - h1p + 180) % 360 - 180
    dH = 2 * np.sqrt(C1p * C2p) * np.sin(np.radians(dh / 2))
    Lm, Cm = (L1 + L2) / 2, (C1p + C2p) / 2
    if C1p * C2p == 0:
        hm = h1p + h2p
    elif abs(h1p - h2p) <= 180:
        hm = (h1p + h2p) / 2
    else:
        hm = (h1p + h2p + 360) / 2 if h1p + h2p < 360 else (h1p + h2p - 360) / 2
    T = (1 - 0.17 * np.cos(np.radians(hm - 30)) + 0.24 * np.cos(np.radians(2 * hm))
         + 0.32 * np.cos(np.radians(3 * hm + 6)) - 0.20 * np.cos(np.radians(4 * hm - 63)))
    dtheta = 30 * np.exp(-(((hm - 275) / 25) ** 2))
    RC = 2 * np.sqrt(Cm**7 / (Cm**7 + 25.0**7))
    SL = 1 + 0.015 * (Lm - 50) ** 2 / np.sqrt(20 + (Lm - 50) ** 2)
    SC, SH = 1 + 0.045 * Cm, 1 + 0.015 * Cm * T
    RT = -np.sin(np.radians(2 * dtheta)) * RC
    return float(np.sqrt((dL / SL) ** 2 + (dC / SC) ** 2 + (dH / SH) ** 2 + RT * (dC / SC) * (dH / SH)))


def distance(c1, c2, matrix=None) -> float:
    """CIEDE2000 between two colours, as seen through ``matrix`` (a deficiency) when given."""
    if matrix is not None:
        c1, c2 = simulate(c1, matrix), simulate(c2, matrix)
    return ciede2000(lab(c1), lab(c2))


# ----------------------------------------------------------------------------- the drawn figure
def renderer(fig):
    """The renderer of a figure laid out as saved (an Agg canvas attached when it has none)."""
    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    fig.canvas.draw()
    return fig.canvas.get_renderer()


def _drawn_tick_labels(axis, r):
    """(text, window extent) of the tick labels an axis draws: visible, not empty, at a tick inside
    the view (a Tick object also exists for locations outside it)."""
    lo, hi = sorted(axis.get_view_interval())
    tr = axis.get_transform()
    t0, t1 = sorted(tr.transform(np.array([lo, hi])))
    eps = 1e-9 * max(abs(t1 - t0), 1e-300)
    out = []
    for tick in axis.get_major_ticks() + axis.get_minor_ticks():
        loc = tick.get_loc()
        if loc is None or not np.isfinite(loc) or not tick.get_visible():
            continue
        if not t0 - eps <= tr.transform(np.array([loc]))[0] <= t1 + eps:
            continue
        for text in (tick.label1, tick.label2):
            if text.get_visible() and text.get_text().strip():
                box = text.get_window_extent(r)
                if box.width > 0 and box.height > 0:
                    out.append((text.get_text(), box))
    return out


def tick_label_overlaps(fig) -> list[tuple[str, str, str]]:
    """(axis, label, label) for each two tick labels of one axis whose rendered extents overlap
    (every axis of the figure: panels, colour bars, secondary axes)."""
    r = renderer(fig)
    bad = []
    for ax in fig.get_axes():
        for axis in [ax.xaxis, ax.yaxis] + [a for c in ax.child_axes for a in (c.xaxis, c.yaxis)]:
            boxes = _drawn_tick_labels(axis, r)
            for i, (ta, a) in enumerate(boxes):
                for tb, b in boxes[i + 1:]:
                    if a.overlaps(b):
                        bad.append((f"{ax.get_xlabel() or ax.get_ylabel() or ax.get_title()!r} {axis.axis_name}", ta, tb))
    return bad


_MATH = re.compile(r"\$[^$]*\$")


def texts(fig) -> list[str]:
    """Every piece of text the figure shows (titles, labels, ticks, legends, notes, the caption)."""
    from matplotlib.text import Text

    renderer(fig)
    return [t.get_text() for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]


def literal_underscores(fig) -> list[str]:
    """The texts that would print an underscore: outside mathtext (where it is a subscript or, in
    \\mathtt, a code name's own character)."""
    return [t for t in texts(fig) if "_" in _MATH.sub("", t)]


def legends_over_data(fig) -> list[str]:
    """Legends lying over the data of the panel they belong to: a legend inside a panel must hold
    none of its lines' vertices or markers; one outside every panel covers nothing."""
    r = renderer(fig)
    bad = []
    for ax in fig.get_axes():
        legend = ax.get_legend()
        if legend is None or not legend.get_visible():
            continue
        box = legend.get_window_extent(r)
        if not box.overlaps(ax.get_window_extent(r)):
            continue
        points = [line.get_xydata() for line in ax.lines if line.get_visible() and len(line.get_xydata())]
        points += [np.asarray(c.get_offsets()) for c in ax.collections
                   if hasattr(c, "get_offsets") and len(c.get_offsets()) and c.get_visible()
                   and type(c).__name__ == "PathCollection"]
        for xy in points:
            xy = np.asarray(xy, dtype=float)
            xy = xy[np.isfinite(xy).all(axis=1)]
            if not len(xy):
                continue
            display = ax.transData.transform(xy)
            inside = ((display[:, 0] > box.x0) & (display[:, 0] < box.x1) & (display[:, 1] > box.y0)
                      & (display[:, 1] < box.y1))
            if inside.any():
                bad.append(f"{ax.get_xlabel()!r}: {int(inside.sum())} data points under the legend")
                break
    return bad


def unlabelled_symbols(fig, ds) -> list[str]:
    """Axis and colour-bar labels that name a variable of ``ds`` with a symbol (its long name in
    the label) but show no mathtext."""
    from mechsweep.figures._style import prose, symbol

    renderer(fig)
    names = {}
    for name in ds.variables:
        long = ds[name].attrs.get("long_name")
        if long and symbol(ds[name]):
            names[" ".join(prose(long).split())] = name
    bad = []
    for ax in fig.get_axes():
        for text in (ax.get_xlabel(), ax.get_ylabel()):
            flat = " ".join(text.replace("\u00a0", " ").split())
            for long, name in names.items():
                if long and long in flat and "$" not in flat:
                    bad.append(f"{name}: {flat!r}")
    return bad


def check_readable(fig, ds=None) -> list[str]:
    """Every problem the checks above find in one figure, one line each."""
    problems = [f"tick labels overlap on {a}: {x!r} / {y!r}" for a, x, y in tick_label_overlaps(fig)]
    problems += [f"literal underscore: {t!r}" for t in literal_underscores(fig)]
    problems += [f"legend over data: {t}" for t in legends_over_data(fig)]
    if ds is not None:
        problems += [f"label without mathtext: {t}" for t in unlabelled_symbols(fig, ds)]
    return problems
