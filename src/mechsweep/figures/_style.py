"""Labels and style shared by every figure; everything comes from dataset attributes.

Figures are made as ``matplotlib.figure.Figure`` objects, not through pyplot: drawing one changes
no matplotlib global state (backend, rcParams, pyplot's list of open figures), so it works headless
and inside a user's own session alike.

Every figure function takes ``fig=`` (a Figure or SubFigure of the user's to draw into) or ``ax=``
(the user's Axes: one, or a sequence with one per panel) and returns a :class:`Drawn` (a dict of
the artists it made, with the figure under ``"figure"`` and the panels under ``"axes"``)."""
from __future__ import annotations

import re

import matplotlib.patheffects as patheffects
import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import Locator, LogLocator

from .._mathtext import _parses

STATUS_OK = 0
NBSP = "\u00a0"
HALO_DARK = [patheffects.withStroke(linewidth=2.6, foreground="0.1")]  # white lines seen on light and dark colours


class Drawn(dict):
    """The artists a figure function made, by name; ``figure`` and ``axes`` always present."""

    @property
    def figure(self):
        return self["figure"]


# ----------------------------------------------------------------------------- symbols, names, units
# mathtext's Greek letters, by name (one string: letters, not names of any model's variables)
GREEK = tuple("alpha beta gamma delta epsilon varepsilon zeta eta theta vartheta iota kappa lambda mu nu xi pi rho "
              "sigma tau upsilon phi varphi chi psi omega Gamma Delta Theta Lambda Xi Pi Sigma Upsilon Phi "
              "Psi Omega".split())
_UNICODE_GREEK = dict(zip("αβγδεϵζηθϑικλμµνξπρστυφϕχψωΓΔΘΛΞΠΣΥΦΨΩ",
                          ("alpha beta gamma delta varepsilon epsilon zeta eta theta vartheta iota kappa lambda mu mu "
                           "nu xi pi rho sigma tau upsilon varphi phi chi psi omega Gamma Delta Theta Lambda Xi Pi "
                           "Sigma Upsilon Phi Psi Omega").split()))
_SUBSCRIPTS = dict(zip("₀₁₂₃₄₅₆₇₈₉₊₋ₐₑₒₓᵢⱼₖₘₙₚₛₜ", "0123456789+-aeoxijkmnpst"))
_SUPERSCRIPTS = dict(zip("⁰¹²³⁴⁵⁶⁷⁸⁹⁺⁻ⁿ", "0123456789+-n"))
_OPERATORS = {"≤": r"\leq", "≥": r"\geq", "≈": r"\approx", "±": r"\pm", "−": "-", "×": r"\times", "·": r"\cdot",
              "~": r"\sim", "%": r"\%", "#": r"\#", "&": r"\&", "′": "'", "→": r"\rightarrow", "∞": r"\infty"}
_FUNCTIONS = ("max", "min", "sin", "cos", "tan", "exp", "log", "ln", "arg", "sup", "inf", "det", "lim")
_TOKEN = re.compile(r"[A-Za-z]+\d*|\d+(?:\.\d+)?|[_^]|\s+|.", re.S)


def _math_word(word: str, sub: bool = False) -> str:
    """One identifier as mathtext: a Greek name as its letter, a function name upright, one letter
    italic, a longer word upright; trailing digits as a subscript (a1 -> a_1, lambda2 -> lambda_2)."""
    m = re.fullmatch(r"([A-Za-z]+)(\d*)", word)
    if not m:
        return word
    base, digits = m.groups()
    if base in GREEK:
        out = "\\" + base
    elif base in _UPRIGHT:
        out = r"\mathrm{" + base + "}"
    elif base in _FUNCTIONS and not sub:
        out = "\\" + base
    elif len(base) == 1:
        out = base
    else:
        return r"\mathrm{" + word + "}" if sub else r"\mathrm{" + base + "}" + (f"_{{{digits}}}" if digits else "")
    return out + (f"_{{{digits}}}" if digits and not sub else digits)


_UPRIGHT = ("sign", "sgn", "Re", "Im", "RMS", "rms")  # operator names mathtext has no command for


def _is_name(text: str) -> bool:
    """True when a declared symbol is a name in words (``position``, ``stable (kick)``, ``kind``)
    rather than a symbol: most of its letters are in lower-case words of three or more letters that
    are neither Greek letters nor operator names (subscripts, after ``_``, not counted)."""
    plain = re.sub(r"_\w+", "", text)
    letters = sum(c.isalpha() for c in plain)
    words = [w for w in re.findall(r"(?<![A-Za-z])[a-z]{3,}(?![A-Za-z])", plain)
             if w not in GREEK and w not in _FUNCTIONS and w not in _UPRIGHT]
    return letters > 0 and sum(map(len, words)) >= 0.6 * letters


def mathtext(symbol) -> str:
    """A plain-text symbol as matplotlib mathtext, e.g. ``omega_xi`` -> ``$\\omega_{\\xi}$``,
    ``A1`` -> ``$A_{1}$``, ``max |λ|`` -> ``$\\max|\\lambda|$``, ``T²`` -> ``$T^{2}$``; one that already
    holds ``$`` is returned as it is when matplotlib renders it. Empty when the symbol is empty or
    is a word rather than a symbol (``position``, ``stable (kick)``: those are names). A symbol
    whose mathtext matplotlib cannot parse is given as plain text, its ``$`` escaped (a figure
    must never fail on a label, whatever a user declares)."""
    text = "" if symbol is None else str(symbol).strip()
    if not text:
        return text
    if "$" in text:
        return text if renders(text) else escaped(text)
    if _is_name(text):
        return ""
    tokens = _TOKEN.findall(text)
    out, i = [], 0
    while i < len(tokens):
        t = tokens[i]
        if t in "_^" and i + 1 < len(tokens) and not tokens[i + 1].isspace():
            nxt = tokens[i + 1]
            arg = "\\" + _UNICODE_GREEK[nxt] if nxt in _UNICODE_GREEK else _math_word(nxt, sub=True)
            out.append(f"{t}{{{arg}}}")
            i += 2
            continue
        if t.isspace():
            prev, nxt = (out[-1] if out else ""), (tokens[i + 1] if i + 1 < len(tokens) else "")
            # a space between two words or letters is kept; around operators mathtext spaces itself
            if prev and nxt and (prev[-1].isalnum() or prev[-1] == "}") and (nxt[0].isalnum() or nxt in _UNICODE_GREEK):
                out.append(r"\ ")
        elif t in _UNICODE_GREEK:
            out.append("\\" + _UNICODE_GREEK[t] + " ")
        elif t in _SUBSCRIPTS or t in _SUPERSCRIPTS:  # a run of them: one script
            mark, table = ("_", _SUBSCRIPTS) if t in _SUBSCRIPTS else ("^", _SUPERSCRIPTS)
            run = ""
            while i < len(tokens) and tokens[i] in table:
                run += table[tokens[i]]
                i += 1
            out.append(f"{mark}{{{run}}}")
            continue
        elif t in _OPERATORS:
            out.append(_OPERATORS[t])
        elif re.fullmatch(r"[A-Za-z]+\d*", t):
            out.append(_math_word(t))
        elif t in "{}":
            out.append("\\" + t)
        else:
            out.append(t)
        i += 1
    result = "$" + re.sub(r"\s+$", "", "".join(out)).replace(" \\ ", "\\ ") + "$"
    return result if _parses(result) else escaped(text)


def escaped(text) -> str:
    """``text`` as plain text that matplotlib never reads as mathtext: every ``$`` escaped
    (matplotlib draws ``\\$`` as ``$``)."""
    return re.sub(r"(?<!\\)\$", r"\\$", str(text))


def renders(text) -> bool:
    """Whether matplotlib draws ``text`` without a mathtext error: each line (matplotlib lays out
    and parses a text line by line) either holds no mathtext (no even number of unescaped ``$``)
    or is parsed by matplotlib's mathtext parser."""
    from matplotlib.cbook import is_math_text

    return all(not is_math_text(line) or _parses(line) for line in str(text).split("\n"))


def safe(text) -> str:
    """``text`` when matplotlib draws it (:func:`renders`), else the same as plain text (its ``$``
    escaped): the last guard of every label made from a dataset's attributes."""
    return text if renders(text) else escaped(text)


def symbol(da) -> str:
    """The variable's symbol in mathtext: its ``latex`` attribute (declared by the model), else its
    plain ``symbol`` converted (:func:`mathtext`); '' when it has neither (or the symbol is a word)."""
    latex = str(da.attrs.get("latex", "") or "")
    if latex and "$" in latex and renders(latex):
        return latex
    return mathtext(da.attrs.get("symbol", ""))


_DEFINED = re.compile(r"^\$([^$=<>]*?)\s*=\s*[^$]*\$$")


def undefined(sym: str) -> str:
    """A mathtext symbol without a definition the declaration may add (``$k_v = v_max T/A$`` ->
    ``$k_v$``)."""
    m = _DEFINED.match(sym)
    head = m.group(1).strip() if m else ""
    return f"${head}$" if head and " " not in head else sym


def short_symbol(da) -> str:
    """The variable's symbol alone (:func:`undefined`), for values (``k_v = 2.5``) and legends; ''
    when there is none."""
    return undefined(symbol(da))


def name_text(da) -> str:
    """How a figure names a variable in running text: its short symbol, else its name (written as
    mathtext when that parses, so that an underscore is a subscript and never printed)."""
    return short_symbol(da) or mathtext(da.name) or escaped(da.name)


_SUBSCRIPTED = re.compile(r"(?<![\w$\\])([A-Za-zα-ωΑ-Ω])_([A-Za-z0-9]{1,3}|[α-ωΑ-Ω])(?![\w])")


def prose(text: str) -> str:
    """Words of a long name as a figure writes them: an identifier with a one-letter base and a
    short subscript (``O_A``, ``m_k``, ``b_xi``) as mathtext, so that no underscore is printed."""
    def sub(m):
        base, low = m.groups()
        base = "\\" + _UNICODE_GREEK[base] if base in _UNICODE_GREEK else base
        low = "\\" + _UNICODE_GREEK[low] if low in _UNICODE_GREEK else ("\\" + low if low in GREEK else low)
        return f"${base}_{{{low}}}$"

    # a user's mathtext span is kept where matplotlib parses it; any other $ is drawn as a $
    parts = _MATH_SPLIT.split(str(text))
    return "".join((p if _parses(p) else escaped(p)) if p.startswith("$") and len(p) > 1
                   else _SUBSCRIPTED.sub(sub, escaped(p)) for p in parts)


def code(text) -> str:
    """An identifier or a file name as figures write it: monospace mathtext, its underscores the
    name's own characters (``vibrating_pendulum_stability``, ``sweeps/quickstart.toml``), never a
    subscript; plain when matplotlib cannot parse it."""
    body = re.sub(r"([_%#&{}$])", r"\\\1", str(text)).replace(" ", r"\ ")
    body = re.sub(r"([-.,:;])", r"\\text{\1}", body)  # as text: in math, '-' is a minus and '.' punctuation
    out = r"$\mathtt{" + body + "}$"
    return out if _parses(out) else str(text)


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
            return escaped(unit)
        base, power = m.groups()
        out.append(base if power in (None, "1") else f"{base}$^{{{power}}}$")
    return " ".join(out)


def value_text(da, value=None, *, digits: int = 4) -> str:
    """'symbol = value unit' of a scalar (a fixed parameter, a slice, a curve of a family): the
    short symbol (the name when there is none), the value to ``digits`` significant digits, the
    unit as figures write it; a name for a categorical value."""
    v = np.asarray(da.values if value is None else value)
    if v.dtype.kind in "OUS":
        return safe(f"{name_text(da)} = {escaped(v)}")
    unit = nobreak(units_text(da.attrs.get("units", "")))
    return safe(f"{name_text(da)} = {float(v):.{digits}g}" + (f"{NBSP}{unit}" if unit else ""))


# ----------------------------------------------------------------------------- wrapping
_MATH = re.compile(r"(?<!\\)\$[^$]*(?<!\\)\$")  # a mathtext span (an escaped \$ is a dollar sign)
_MATH_SPLIT = re.compile(r"((?<!\\)\$[^$]*(?<!\\)\$)")


def visible_len(text: str) -> int:
    """About how many characters wide ``text`` renders: a mathtext span counts its glyphs, not its
    commands and braces (``$\\omega_\\xi$`` is 2 wide, not 12)."""
    def width(m):
        body = re.sub(r"\\(mathrm|,|;|!|\s)", "", m.group(0)[1:-1])
        body = re.sub(r"\\[A-Za-z]+", "x", body)
        return "x" * len(re.sub(r"[{}_^\s]", "", body))

    return len(_MATH.sub(width, text))


def _unbreakable(text: str, width: int | None = None) -> list[str]:
    """The words of ``text`` (split at spaces) that wrapping may put on separate lines: never split
    inside a mathtext span, nor inside (...) or [...] that fits on a line."""
    spans = [(m.start(), m.end()) for m in _MATH.finditer(text)]
    opened = []
    for i, ch in enumerate(text):
        if any(a <= i < b for a, b in spans):
            continue
        if ch in "([{":
            opened.append(i)
        elif ch in ")]}" and opened:
            a = opened.pop()
            if width is None or visible_len(text[a:i + 1]) <= width:
                spans.append((a, i + 1))
    words, cur = [], ""
    for i, ch in enumerate(text):
        if ch == " " and not any(a <= i < b for a, b in spans):
            words.append(cur)
            cur = ""
        else:
            cur += ch
    return [w for w in words + [cur] if w]


def wrap(text: str, width: int) -> str:
    """Wrap at spaces to about ``width`` visible characters a line; never inside a mathtext span,
    nor inside (...) or [...] unless one is longer than a line."""
    lines, cur = [], ""
    for word in _unbreakable(text, width):
        if cur and visible_len(cur) + 1 + visible_len(word) > width:
            lines.append(cur)
            cur = word
        else:
            cur = f"{cur} {word}" if cur else word
    lines.append(cur)
    return "\n".join(lines)


def label(da, width: int = 42, *, name: bool = True) -> str:
    """'symbol, long name [unit]' from a DataArray's attributes: the symbol in mathtext (the
    declared ``latex``, else the plain symbol converted), the long name with its subscripted
    identifiers as mathtext, the unit in brackets (omitted when dimensionless). ``name=False``:
    'symbol [unit]' only (a panel whose title gives the long name)."""
    long = prose(str(da.attrs.get("long_name", da.name)))
    sym = symbol(da)
    head = (f"{sym}, {long}" if sym else long) if name else (sym or long)
    unit = nobreak(units_text(da.attrs.get("units", "")))  # "[N m]" never split over two lines
    return safe(wrap(f"{head} [{unit}]" if unit else head, width))


def fixed_text(ds, skip=()) -> str:
    """'$\\lambda_1$ = 0.8, ...' for the scalar coordinates (fixed parameters) of a dataset."""
    parts = []
    for k in ds.coords:
        if k in ds.dims or k in skip or ds[k].ndim:
            continue
        # non-breaking outside mathtext only: a space inside it is mathtext's ("$m_{e}\\ e$")
        parts.append(nobreak(value_text(ds[k], digits=6)))
    return safe(", ".join(parts))


def status_counts(ds) -> list[tuple[str, int]]:
    """(status meaning, number of points) of every status other than ok in ``ds``, most frequent
    first; the meanings are the status variable's ``flag_meanings`` (the code itself when absent)."""
    st = np.asarray(ds["status"].values).ravel()
    codes, counts = np.unique(st[st != STATUS_OK], return_counts=True)
    names = str(ds["status"].attrs.get("flag_meanings", "")).split()
    values = [int(v) for v in np.ravel(ds["status"].attrs.get("flag_values", []))]
    meaning = dict(zip(values, names))
    found = [(meaning.get(int(c), f"status {int(c)}"), int(n)) for c, n in zip(codes, counts)]
    return sorted(found, key=lambda t: -t[1])


def status_text(ds) -> str:
    """'240 not_balanceable, 95 no_event' for the points not ok ('' when every point is ok); the
    names are the status meanings of the glossary (docs/glossary.md), written without underscores."""
    return ", ".join(f"{n:,} {m.replace('_', ' ')}" for m, n in status_counts(ds))


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


def nobreak(text: str) -> str:
    """``text`` with its spaces non-breaking (outside mathtext spans, where a space is mathtext's)."""
    return "".join(p if p.startswith("$") and len(p) > 1 else p.replace(" ", NBSP) for p in _MATH_SPLIT.split(text))


def title(fig, ds, what: str, caption: str | None = None, *, caption_box: bool = True) -> str:
    """Title: what the figure shows. The fixed parameters (and ``caption`` when given) go to a
    caption box under the panels, in a smaller font, with the scene's name last (a footer, not a
    title: the name is the file's, the title says what is drawn); with ``caption_box`` False they
    are returned instead (for a figure whose legend sits under the panels, where the box would lie
    beneath it)."""
    if not owns(fig):
        return ""
    # wrapped here, by characters for the figure's width (~11 per inch at 11 pt): matplotlib's own
    # wrap=True measured at the screen's dpi and let a title saved at 150 dpi run off both edges
    fig.suptitle(safe(wrap(what, max(20, int(width_inches(fig) * 11)))), fontsize=11)
    fixed = fixed_text(ds)
    scene = str(ds.attrs.get("title", "") or "")
    lines = [c for c in (caption, f"fixed: {fixed}" if fixed else "", f"scene: {code(scene)}" if scene else "") if c]
    chars = int(width_inches(fig) * 15)  # ~15 characters per inch at 7.5 pt
    text = "\n".join(safe(wrap(c, chars)) for c in lines)
    if text and caption_box:
        fig.supxlabel(text, fontsize=7.5, color="0.25", ha="center",
                      bbox=dict(boxstyle="round,pad=0.4", facecolor="0.96", edgecolor="0.8"))
    return "" if caption_box else text


def flag_note(ax, ds, text=None):
    """Say above the panel (outside it, so it covers nothing) how many points were flagged and so
    are not drawn, and why (the status meanings). Returns the Text (None when nothing is flagged)."""
    bad = int((ds["status"].values != STATUS_OK).sum())
    if not bad:
        return None
    return ax.text(1.0, 1.01, text or f"not drawn: {status_text(ds)} (see status)", transform=ax.transAxes,
                   ha="right", va="bottom", fontsize=7, color="0.35")


def log_or_symlog(ax, values, axis="x") -> None:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return
    if (v > 0).all():
        if v.max() / v.min() > 50:
            log_scale(ax, axis)
    elif (v < 0).any() and (v > 0).any():
        # asinh: linear near 0, logarithmic far from it, smooth in between (symlog's kink at its
        # threshold drew a kink into every smooth curve)
        getattr(ax, f"set_{axis}scale")("asinh", linear_width=max(np.min(np.abs(v[v != 0])), 1e-3))
        readable_asinh_ticks(getattr(ax, f"{axis}axis"))
    # all <= 0 (soft springs up to the separatrix): a linear axis shows T -> inf best


# ----------------------------------------------------------------------------- log axes that read
class _LogTicks(LogLocator):
    """Decades when the view spans 4 or more; else 1, 2, 5 times each power of ten (and 1..9 within
    one decade), so that a short log axis is labelled more than once or twice."""

    def tick_values(self, vmin, vmax):
        lo, hi = sorted((vmin, vmax))
        if lo <= 0 or not np.isfinite(lo) or not np.isfinite(hi):
            return super().tick_values(vmin, vmax)
        span = np.log10(hi / lo)
        subs = (1.0,) if span >= 4 else (1.0, 2.0, 5.0) if span >= 1 else (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0)
        return LogLocator(base=10, subs=subs, numticks=30).tick_values(vmin, vmax)


def _log_label(v: float, span: float) -> str:
    """A tick value of a log axis: plain (0.005, 20, 300) over a short span of ordinary numbers,
    a power of ten (mathtext) otherwise."""
    if v <= 0 or not np.isfinite(v):
        return ""
    e = int(np.floor(np.log10(v) + 1e-9))
    m = v / 10.0**e
    if span < 4 and -4 <= e <= 5:
        return f"{v:.6g}"
    if abs(m - 1) < 1e-6:
        return f"$10^{{{e}}}$"
    return f"${m:.2g}\\times10^{{{e}}}$"


def readable_log_ticks(axis) -> None:
    """Ticks of a log axis an engineer can read values from: labels at 1, 2, 5 x 10^k on a span of
    under 4 decades (plain numbers), decades otherwise; unlabelled minor ticks between them."""
    from matplotlib.ticker import FuncFormatter, LogLocator as _LL, NullFormatter

    def fmt(v, _pos=None):
        lo, hi = sorted(axis.get_view_interval())
        span = np.log10(hi / lo) if lo > 0 and hi > 0 else 10.0
        return _log_label(v, span)

    axis.set_major_locator(_LogTicks(base=10))
    axis.set_major_formatter(FuncFormatter(fmt))
    axis.set_minor_locator(_LL(base=10, subs=np.arange(2, 10) * 1.0, numticks=30))
    axis.set_minor_formatter(NullFormatter())


def log_scale(ax, axis: str) -> None:
    """A log scale on the ``axis`` ("x" or "y") of ``ax``, its ticks readable (:func:`readable_log_ticks`)."""
    getattr(ax, f"set_{axis}scale")("log")
    readable_log_ticks(getattr(ax, f"{axis}axis"))


class _AsinhTicks(Locator):
    """Ticks of an asinh axis: 0 and round values (1, 2, 5 x 10^k) of either sign, the decades first,
    kept only where they stand apart on the axis (near 0 the decades bunch up and their labels ran
    into one another)."""

    def tick_values(self, vmin, vmax):
        lo, hi = sorted((vmin, vmax))
        tr = self.axis.get_transform() if self.axis is not None else None
        if tr is None or not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
            return np.array([])
        mags = [m * 10.0**k for k in range(-15, 16) for m in (1.0, 2.0, 5.0)]
        cands = [c for c in [0.0] + mags + [-v for v in mags] if lo <= c <= hi]
        # 0 first, then the decades from the largest, then 2 and 5 times them
        cands.sort(key=lambda c: (c != 0, round(abs(c) / 10.0**np.floor(np.log10(abs(c)) + 1e-9)) != 1 if c else 0,
                                  -abs(c)))
        t = lambda v: float(tr.transform(np.array([v]))[0])  # noqa: E731
        span = t(hi) - t(lo)
        kept = []
        for c in cands:
            if all(abs(t(c) - t(k)) >= 0.09 * span for k in kept):
                kept.append(c)
        return np.array(sorted(kept))

    def __call__(self):
        return self.tick_values(*self.axis.get_view_interval())


def _plain(v, _pos=None) -> str:
    """A tick value as a plain number (a power of ten in mathtext beyond 1e-3 .. 1e5), minus as −."""
    if v == 0:
        return "0"
    text = f"{abs(v):g}" if 1e-3 <= abs(v) < 1e5 else _log_label(abs(v), 10.0)
    return ("−" if v < 0 else "") + text


def readable_asinh_ticks(axis) -> None:
    """Ticks of an asinh axis that stand apart, labelled as plain numbers."""
    from matplotlib.ticker import FuncFormatter, NullLocator

    axis.set_major_locator(_AsinhTicks())
    axis.set_major_formatter(FuncFormatter(_plain))
    axis.set_minor_locator(NullLocator())


# ----------------------------------------------------------------------------- stable / unstable
# Light blue and light orange: 34 CIEDE2000 units apart, 35 under a deuteranopia and 32 under a
# protanopia simulation (tests/test_figure_readability.py measures them); the unstable side also
# carries a dot hatch, so the two read apart without colour too.
STABLE_COLOR, UNSTABLE_COLOR = "#b3d4ea", "#fdc08a"
UNSTABLE_HATCH = ".."
HATCH_WIDTH = 0.5
HATCH_COLOR = (0.35, 0.22, 0.1, 0.55)
STYLE_GID = "mechsweep-style"  # artists that restyle data drawn elsewhere (lines_data skips them)


def stable_cmap():
    """The two-colour map of a stability verdict: 0 unstable, 1 stable."""
    from matplotlib.colors import ListedColormap

    return ListedColormap([UNSTABLE_COLOR, STABLE_COLOR])


def hatch_unstable(ax, x, y, verdict, **kw):
    """Dot hatching over the cells whose verdict is 0 (unstable), cell for cell as the fill draws
    them (``x``, ``y`` the cell centres, or their edges): the second cue beside the colour. Returns
    the artist (None when no cell is unstable)."""
    v = np.ma.masked_where(~(np.asarray(verdict) == 0), np.asarray(verdict, dtype=float))
    if v.count() == 0:
        return None
    # x, y: cell centres (as the fill's shading "nearest") or one more each, the cells' edges
    shading = "flat" if np.size(x) == v.shape[1] + 1 else "nearest"
    art = ax.pcolor(x, y, v, shading=shading, facecolor="none", edgecolor=HATCH_COLOR, linewidth=0.0,
                    hatch=UNSTABLE_HATCH, **kw)
    art.set_facecolor("none")
    if hasattr(art, "set_hatch_linewidth"):  # matplotlib >= 3.10: fine dots (else rcParams' width, at draw)
        art.set_hatch_linewidth(HATCH_WIDTH)
    art.set_gid(STYLE_GID)
    return art


def unstable_patch(label="unstable"):
    """A legend handle for the unstable fill with its hatch."""
    import matplotlib.patches

    patch = matplotlib.patches.Patch(facecolor=UNSTABLE_COLOR, edgecolor=HATCH_COLOR, hatch=UNSTABLE_HATCH, lw=0,
                                     label=label)
    if hasattr(patch, "set_hatch_linewidth"):
        patch.set_hatch_linewidth(HATCH_WIDTH)
    return patch


def ticked():
    """Path effects that draw a line with short ticks on its right (seen walking along it)."""
    return [patheffects.withTickedStroke(angle=-135, length=0.7, spacing=7), patheffects.Normal()]


def ticked_contour(ax, cs, x, y, z, *, color, lw=1.4):
    """The lines of the contour set ``cs`` of the grid ``z`` (rows along ``y``, columns along
    ``x``) drawn again with ticks on their lower side (e.g. a boundary ticked on the side where a
    criterion below 0 calls the design stable). A contour line's direction says nothing of which
    side is lower, so each line is turned to have the lower grid values, read next to its middle,
    on its right. Call it once the axes' scales and limits are set. Returns the lines (gid
    STYLE_GID: they restyle the contour, which stays the data drawn)."""
    from matplotlib.lines import Line2D

    x, y, z = np.asarray(x, dtype=float), np.asarray(y, dtype=float), np.asarray(z, dtype=float)
    to_axes = ax.transData + ax.transAxes.inverted()
    to_data = to_axes.inverted()

    def at(point):  # the grid value nearest a point given in axes fractions
        px, py = to_data.transform(point)
        return z[np.argmin(np.abs(y - py)), np.argmin(np.abs(x - px))]

    lines = []
    for path in cs.get_paths():
        verts, codes = np.asarray(path.vertices), path.codes
        starts = [0] if codes is None else list(np.flatnonzero(codes == path.MOVETO))
        for a, b in zip(starts, starts[1:] + [len(verts)]):
            seg = verts[a:b]
            if codes is not None and codes[b - 1] == path.CLOSEPOLY:  # a closed line: its vertex back to the start
                seg = np.vstack([seg[:-1], seg[:1]])
            if len(seg) < 3:
                continue
            f = to_axes.transform(seg)
            k = len(f) // 2
            t = f[min(k + 1, len(f) - 1)] - f[max(k - 1, 0)]
            n = np.array([t[1], -t[0]]) / max(np.hypot(*t), 1e-12)  # to the right of the direction of travel
            right, left = at(f[k] + 0.03 * n), at(f[k] - 0.03 * n)
            if np.isfinite(right) and np.isfinite(left) and right > left:
                seg = seg[::-1]
            line = Line2D(seg[:, 0], seg[:, 1], color=color, lw=lw, path_effects=ticked())
            line.set_gid(STYLE_GID)
            ax.add_line(line)
            lines.append(line)
    return lines


def stable_patch(label="stable"):
    import matplotlib.patches

    return matplotlib.patches.Patch(facecolor=STABLE_COLOR, edgecolor="none", lw=0, label=label)


def lines_data(fig) -> list[np.ndarray]:
    """The arrays a figure draws (line data, scatter offsets, mesh values, contour paths), in drawing
    order, for fingerprints of figure data (tests) without looking at pixels. Artists whose gid is
    STYLE_GID only restyle data drawn by another artist (a hatch over a fill): left out."""
    from matplotlib.collections import PathCollection, QuadMesh
    from matplotlib.contour import ContourSet

    out = []
    for ax in fig.axes:
        for line in ax.lines:
            if line.get_gid() == STYLE_GID:
                continue
            out.append(np.asarray(line.get_xydata(), dtype=float))
        for c in ax.collections:
            if c.get_gid() == STYLE_GID:  # a second cue over data drawn already (e.g. hatching)
                continue
            if isinstance(c, QuadMesh):
                out.append(np.ma.filled(np.ma.asarray(c.get_array(), dtype=float), np.nan).ravel())
            elif isinstance(c, ContourSet):
                verts = [p.vertices for p in c.get_paths() if len(p.vertices)]
                out.append(np.concatenate(verts) if verts else np.zeros((0, 2)))
            elif isinstance(c, PathCollection):
                out.append(np.asarray(c.get_offsets(), dtype=float))
    return out
