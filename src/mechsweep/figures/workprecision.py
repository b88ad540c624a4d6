"""Work-precision figure of a `mechsweep bench workprecision` dataset: error against time per point."""
from __future__ import annotations

import json
import re
import zlib

import numpy as np

from ._registry import ModelFigure
from ._style import Drawn, code, label, mathtext, new_figure, owns, undefined, width_inches, wrap

def _symbols(ds) -> dict:
    """{name: mathtext symbol, without its definition} the bench stored from the model's declaration."""
    try:
        found = json.loads(str(ds.attrs.get("latex_symbols", "") or "{}"))
    except ValueError:
        return {}
    return {name: undefined(str(latex)) for name, latex in found.items()}


def _named(ds, text: str) -> str:
    """``text`` with the model's variable names written as their symbols (``period_exact`` ->
    $T_\\mathrm{exact}$); a name with an underscore and no symbol as code (monospace)."""
    syms = _symbols(ds)

    def sub(m):
        word = m.group(0)
        # a plain word is a variable only inside a formula (next to |, -, +, /, *, =): "period" is a word in
        # "period (elliptic closed form)", the output in "|period - period_exact|"
        near = (text[:m.start()].rstrip()[-1:] + text[m.end():].lstrip()[:1])
        if word in syms and ("_" in word or any(c in "|-+/*=" for c in near)):
            return syms[word]
        return code(word) if "_" in word else word

    return re.sub(r"\b[A-Za-z][A-Za-z0-9]*_[A-Za-z0-9_]*\b|\b[A-Za-z][A-Za-z0-9]*\b", sub, text)


def _model_text(ds) -> str:
    return str(ds.attrs.get("model", "")).replace("_", " ")


def _norm_text(ds) -> str:
    """What the error is, with symbols: the bench's description of it ('norm')."""
    norm = str(ds.attrs.get("norm", "error"))
    generic = "relative error |value - reference| / |reference|"
    if norm.startswith(generic):
        return r"relative error $|v - v_\mathrm{ref}|\,/\,|v_\mathrm{ref}|$" + norm[len(generic):]
    return _named(ds, norm)


def _formula(text: str) -> str:
    """A bench's problem statement ('x'' = -x/2 - x^3/2, x(0) = 1, ..., one integration over ...') with
    its comma-separated formulas as mathtext where each parses, the words after them kept."""
    parts = [p.strip() for p in str(text).split(", ")]
    out = []
    for p in parts:
        if re.search(r"[=^']", p) and not re.search(r"[A-Za-z]{4,}", p):
            math = mathtext(p.replace(" ", ""))
            out.append(math or p)
        else:
            out.append(re.sub(r"\b(\d+)\^(\d+)\b", r"$\1^{\2}$", p))
    return ", ".join(out)

MARKERS = "os^vD<>ph*"
# One colour per method, by name, in every panel of every work-precision figure: our implementation
# and another library's of the same method share it (ours solid, theirs dashed).
METHOD_COLORS = {"dop853": "#1f77b4", "radau": "#ff7f0e", "symplectic": "#2ca02c", "auto": "#d62728",
                 "lsoda": "#9467bd", "rk45": "#8c564b", "bdf": "#e377c2", "rk23": "#7f7f7f"}
SPARE_COLORS = ("#bcbd22", "#17becf", "#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd")
LIBRARIES = ("mechsweep", "scipy", "numpy", "numbalsoda", "diffrax")


def method_key(name) -> str:
    """'scipy DOP853' and 'mechsweep dop853, rtol 1e-06' -> 'dop853': the method, without the
    library that implements it or the run's settings."""
    words = str(name).split(",")[0].strip().split()
    if len(words) > 1 and words[0].lower() in LIBRARIES:
        words = words[1:]
    return " ".join(words).lower()


def method_color(name) -> str:
    """The colour of a method in every work-precision figure (a fixed table; a method it does not
    know gets a spare colour chosen from its name, the same in every figure)."""
    key = method_key(name)
    return METHOD_COLORS.get(key) or SPARE_COLORS[zlib.crc32(key.encode()) % len(SPARE_COLORS)]


def workprecision(ds, *, fig=None, ax=None):
    """Error against run time per point, one line per method (ours solid, scipy or numpy dashed),
    one colour per method in every panel and figure; the hollow marker is the loosest tolerance."""
    if ds.attrs["mechsweep_kind"] == "workprecision_positions":
        return _positions(ds, fig=fig, ax=ax)
    drift = "energy_error" in ds
    fig, axes = new_figure(1, 2 if drift else 1, width=7.4, height=5.0, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, lines={})
    a = axes[0, 0]
    rtol = ds["rtol"].values
    for i, name in enumerate(ds["integrator"].values):
        t = ds["time_per_point"].isel(integrator=i).values
        e = ds["error_max"].isel(integrator=i).values
        keep = np.isfinite(t) & np.isfinite(e) & (e > 0)
        if not keep.any():
            continue
        ours = str(name).startswith("mechsweep")
        color = method_color(name)
        marker = MARKERS[i % len(MARKERS)]
        line, = a.loglog(t[keep], e[keep], ls="-" if ours else "--", marker=marker, color=color,
                         lw=1.6 if ours else 1.1, ms=5, label=str(name))
        first = np.flatnonzero(keep)[0]  # the loosest tolerance: a hollow marker, to read the ladder
        a.plot(t[first], e[first], marker=marker, ms=9, mfc="white", mec=color, mew=1.4, ls="none", zorder=4)
        art["lines"][str(name)] = line
    a.set_xlabel(label(ds["time_per_point"]))
    k = ds.attrs["scipy_points"]
    a.set_ylabel(wrap(f"{_norm_text(ds)} (largest over the {k} points every method solved)", 48))
    a.grid(True, which="both", alpha=0.3)
    art["legend"] = a.legend(fontsize=8, loc="best")
    if drift:
        art.update(_energy_drift(axes[0, 1], ds))
    if owns(fig):
        fig.suptitle(wrap(f"Work and precision of each method, model {_model_text(ds)}: error against run time per "
                          f"point, rtol {rtol.max():.0e} to {rtol.min():.0e}", int(width_inches(fig) * 12)), fontsize=10)
        fig.supxlabel(wrap(f"hollow marker: the loosest tolerance, rtol = {rtol.max():.0e}; each next marker a tighter "
                           f"one, down to {rtol.min():.0e}. Errors: the largest over the {k} points every method "
                           f"solved, the first {k} of a sample of {ds.attrs['points']} points of {code(ds.attrs['scene'])}; "
                           f"reference: {_named(ds, str(ds.attrs['reference']))}; 1 thread",
                           int(width_inches(fig) * 15)), fontsize=7.5, color="0.25")
    return art


def _energy_drift(ax, ds):
    """Energy error against integrated periods: linear growth of the explicit method, none for
    the symplectic one (its error sits at round-off). Colour by method, line style by tolerance."""
    lines = {}
    runs = [str(name).split("rtol")[-1].strip() if "rtol" in str(name) else "" for name in ds["drift_run"].values]
    rtols = list(dict.fromkeys(runs))  # one line style per tolerance, in the order met
    for i, name in enumerate(ds["drift_run"].values):
        j = rtols.index(runs[i])
        e = np.maximum(ds["energy_error"].isel(drift_run=i).values, 1e-17)  # exact zeros drawn at the floor
        lines[str(name)], = ax.loglog(ds["periods"].values, e, marker=MARKERS[j % len(MARKERS)],
                                      ls=("-", "--", ":", "-.")[j % 4], color=method_color(name),
                                      label=f"{name} ({int(ds['drift_rhs'].values[i]):,} rhs)")
    ax.set_xlabel(label(ds["periods"]))
    ax.set_ylabel(label(ds["energy_error"]))
    ax.set_title(wrap(_formula(ds.attrs["drift_problem"]), 60), fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    return {"drift_lines": lines, "drift_legend": ax.legend(fontsize=7, loc="best")}


FLOOR = 1e-17  # exact zeros (a maximum on the grid by symmetry) drawn at this floor


def _positions(ds, *, fig=None, ax=None):
    """Linkage models: error against time per point (left) and against the number N of crank
    positions (right, with the slope N^-2 of a maximum), one colour per output; mechsweep solid,
    numpy dashed (same values, its own time); the hollow marker is the fewest positions."""
    fig, axes = new_figure(1, 2, width=6.4, height=5.4, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, lines={})
    left, right = axes[0, 0], axes[0, 1]
    N = ds["n_positions"].values
    for o, name in enumerate(ds["output"].values):
        color = f"C{o}"
        for i, impl in enumerate(ds["implementation"].values):
            t = ds["time_per_point"].isel(implementation=i).values
            e = np.maximum(ds["error_max"].isel(implementation=i, output=o).values, FLOOR)
            ours = impl == "mechsweep"
            marker = MARKERS[o % len(MARKERS)]
            sym = _named(ds, str(name))
            art["lines"][(str(name), str(impl))], = left.loglog(
                t, e, ls="-" if ours else "--", marker=marker, color=color, lw=1.6 if ours else 1.0,
                ms=4 if ours else 3, label=f"{sym}, {impl}")
            left.plot(t[0], e[0], marker=marker, ms=8, mfc="white", mec=color, mew=1.3, ls="none", zorder=4)
            if ours:
                right.loglog(N, e, marker=marker, color=color, label=f"{sym} ({ds['kind'].values[o]})")
                right.plot(N[0], e[0], marker=marker, ms=8, mfc="white", mec=color, mew=1.3, ls="none", zorder=4)
    e_ref = float(np.nanmax(ds["error_max"].sel(implementation="mechsweep").values[:, N >= 90]))
    right.loglog(N, e_ref * (N / 90.0) ** -2.0, ls=":", color="0.4", label="slope N$^{-2}$")
    right.axvline(ds.attrs["default_positions"], color="0.6", lw=0.8)
    right.annotate(f"default N = {ds.attrs['default_positions']}", (ds.attrs["default_positions"], FLOOR * 10),
                   fontsize=7, color="0.4", rotation=90, xytext=(3, 0), textcoords="offset points")
    left.set_xlabel(label(ds["time_per_point"]))
    right.set_xlabel(label(ds["n_positions"]))
    for a in (left, right):
        a.set_ylabel(wrap(f"{_norm_text(ds)} (largest over {ds.attrs['points']} points)", 48))
        a.grid(True, which="both", alpha=0.3)
    # beside the panels: inside, the legends lay over the curves
    art["legend"] = left.legend(fontsize=6.5, loc="upper left", bbox_to_anchor=(0.0, -0.2), ncol=2)
    art["legend_right"] = right.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.2))
    if owns(fig):
        fig.suptitle(wrap(f"Work and precision of the model {_model_text(ds)}: error against run time and against "
                          f"the crank positions per cycle N = {N.min()} to {N.max()}, 1 thread",
                          int(width_inches(fig) * 12)), fontsize=10)
        notes = [f"hollow marker: the fewest positions, N = {N.min()}; each next marker more, up to N = {N.max()}. "
                 f"Reference: {_named(ds, str(ds.attrs['reference']))}; {ds.attrs['points']} points of "
                 f"{code(ds.attrs['scene'])}."] + _exact_maxima(ds, N)
        fig.supxlabel(wrap(" ".join(notes), int(width_inches(fig) * 15)), fontsize=7.5, color="0.25")
    return art


EXACT = 1e-12  # an error at or below this is round-off: the discrete value is the exact one


def _exact_maxima(ds, N) -> list[str]:
    """Why an error jumps between round-off and a large value as N grows: a maximum over N crank
    positions is exact when a position falls on the maximising crank angle and off when none does;
    said for each output whose error does so (read from the stored errors, nothing computed)."""
    notes = []
    for o, name in enumerate(ds["output"].values):
        if "max" not in str(ds["kind"].values[o]):
            continue
        e = np.asarray(ds["error_max"].sel(implementation="mechsweep").values[o], dtype=float)
        exact = np.isfinite(e) & (e <= EXACT)
        inexact = np.isfinite(e) & (e > EXACT)
        if exact.any() and inexact.any() and np.flatnonzero(inexact).max() > np.flatnonzero(exact).min():
            notes.append(f"{_named(ds, str(name))}, a maximum over the positions, is exact (round-off) for "
                         f"N = {', '.join(str(n) for n in N[exact])}, where a crank position falls on the maximising "
                         f"angle, and off by up to {e[inexact].max():.0e} for N = {', '.join(str(n) for n in N[inexact])}, "
                         "where none does.")
    return notes


FIGURES = (
    ModelFigure("workprecision", workprecision, dataset_kinds=("workprecision", "workprecision_positions")),
)
