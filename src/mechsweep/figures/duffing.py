"""Duffing nomograms: period and kinematic coefficients against epsilon = mu A^2 / omega^2.

Soft springs (every epsilon below 0, down towards the separatrix epsilon = -1, where the period
grows like ln(1 / (1 + epsilon))) are drawn against 1 + epsilon on a log axis, so the divergence
is a straight line and the points beyond the separatrix (flagged: no oscillation) are marked."""
from __future__ import annotations

import numpy as np

from ._registry import ModelFigure
from ._style import Drawn, flag_note, label, log_or_symlog, new_figure, ok_values, title

MODELS = ("duffing", "torsional_circuit")  # the torsional circuit stores Duffing's outputs too
FLOOR = 1e-17  # exact zeros of the period error drawn at the lower edge


def _flat(da):
    return np.asarray(da.values, dtype=float).ravel()


def _omega(ds):
    if "omega" in ds.coords or "omega" in ds:
        return ds["omega"]
    return None


def can_amplitude_period(ds) -> bool:
    """Needs the linear frequency omega (a parameter of the Duffing model) to scale the period."""
    return _omega(ds) is not None


def _soft(ds) -> bool:
    """Every epsilon that could be computed is negative (soft springs only), some near -1."""
    eps = _flat(ds["epsilon"])
    eps = eps[np.isfinite(eps)]
    return eps.size > 1 and bool((eps < 0).all()) and eps.min() < -0.5


def _x(ds):
    """(x values over the grid, x label, beyond-separatrix mask or None): epsilon, or for soft
    springs 1 + epsilon (distance from the separatrix) on a log axis."""
    eps = _flat(ds["epsilon"].broadcast_like(ds["status"]))
    if not _soft(ds):
        return eps, label(ds["epsilon"]), None
    return (1.0 + eps, "1 + ε, distance from the separatrix ε = μ A² / ω² = −1 (log axis)",
            _status_is(ds, "not_oscillatory"))


def _status_is(ds, meaning):
    """Where the status is the code the dataset's status attributes name ``meaning`` (CF flags)."""
    st = ds["status"]
    names = str(st.attrs.get("flag_meanings", "")).split()
    if meaning not in names:
        return np.zeros(st.size, bool)
    return _flat(st) == int(np.asarray(st.attrs["flag_values"])[names.index(meaning)])


def _spread(x, y, n=100):
    """Indices of at most about ``n`` finite points, one per equal step of x (of log x when x spans
    decades), so markers over a line do not hide it."""
    ok = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
    if ok.size <= n:
        return ok
    t = x[ok]
    if (t > 0).all() and t.max() / t.min() > 50:
        t = np.log10(t)
    bins = np.digitize(t, np.linspace(t.min(), t.max(), n + 1)[1:-1])
    _, first = np.unique(bins, return_index=True)
    return ok[first]


def _separatrix(ax, ds, beyond, x):
    """Shade and say where no oscillation exists (beyond the separatrix), and how many points lie
    there; x is drawn on a log axis so those points (1 + epsilon <= 0) get a band at the left edge."""
    ax.set_xscale("log")
    ok = np.isfinite(x) & (x > 0)
    lo = x[ok].min() if ok.any() else 1e-3
    arts = {}
    if beyond is not None and beyond.any():
        edge = lo / 3.0
        arts["beyond"] = ax.axvspan(edge / 3.0, edge, color="0.85", lw=0)
        arts["beyond_text"] = ax.text(edge / 1.7, 0.5, f"beyond the separatrix\n(ε ≤ −1): no oscillation;\n"
                                      f"{int(beyond.sum())} points, flagged", rotation=90, ha="center", va="center",
                                      fontsize=6.5, color="0.3", transform=ax.get_xaxis_transform(), clip_on=True)
        ax.set_xlim(edge / 3.0, None)
    return arts


def amplitude_period(ds, *, fig=None, ax=None):
    """T omega against epsilon: the elliptic closed form as a line over the integrated points;
    relative error below, with the solver's rtol."""
    has_err = "period_error" in ds
    fig, axes = new_figure(2 if has_err else 1, 1, width=7.0, height=3.8, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes)
    a = axes[0, 0]
    x, xlab, beyond = _x(ds)
    order = np.argsort(x)
    omega = _omega(ds)
    method = str(ds.attrs.get("solver_method", "")).upper() or "integrated"
    if "period" in ds:
        ti = _flat((ok_values(ds, "period") * omega).broadcast_like(ds["status"]))
        pick = _spread(x, ti)  # ~100 points evenly spread along the drawn axis: the line stays visible
        art["integrated"], = a.plot(x[pick], ti[pick], "o", ms=4.5, mfc="none", mew=0.8, color="C3", zorder=2,
                                    label=f"integrated ({method})" + (f", {pick.size} of {np.isfinite(ti).sum()} "
                                                                      "points" if pick.size < np.isfinite(ti).sum()
                                                                      else ""))
    if "period_exact" in ds:
        te = _flat((ok_values(ds, "period_exact") * omega).broadcast_like(ds["status"]))
        art["closed_form"], = a.plot(x[order], te[order], "-", color="k", lw=1.3, zorder=3,
                                     label="closed form 4 K(m) / √(ω² + μA²)")
    art["linear"] = a.axhline(2 * np.pi, color="0.5", lw=0.8, ls="--", label="linear oscillator: 2π")
    if beyond is None:
        log_or_symlog(a, x)
    else:
        art.update(_separatrix(a, ds, beyond, x))
    a.set_xlabel(xlab)
    a.set_ylabel("T ω, dimensionless period")
    a.grid(True, alpha=0.3)
    art["legend"] = a.legend(fontsize=8)
    art["flag_note"] = flag_note(a, ds)
    if has_err:
        a2 = axes[1, 0]
        err = _flat(ok_values(ds, "period_error").broadcast_like(ds["status"]))
        pos = err[np.isfinite(err) & (err > 0)]
        rtol = ds.attrs.get("solver_rtol")
        top = max([pos.max() if pos.size else FLOOR] + ([rtol] if rtol else [])) * 4
        bottom = max(pos.min() / 4, FLOOR) if pos.size else FLOOR
        zeros = np.isfinite(err) & (err == 0)
        art["error"], = a2.plot(x[~zeros], err[~zeros], ".", ms=2.5, color="C3", label="integrated − closed form")
        if zeros.any():
            art["zeros"], = a2.plot(x[zeros], np.full(zeros.sum(), bottom), "v", ms=3, color="C3", clip_on=False,
                                    label=f"exact zeros ({int(zeros.sum())}), on the lower edge")
        a2.set_yscale("log")
        a2.set_ylim(bottom, top)
        if rtol:
            art["rtol"] = a2.axhline(rtol, color="C0", lw=1.0, ls="--", label=f"solver rtol = {rtol:g}")
        if beyond is None:
            log_or_symlog(a2, x)
        else:
            art.update({f"{k}_error": v for k, v in _separatrix(a2, ds, beyond, x).items()})
        a2.set_xlim(a.get_xlim())
        a2.set_xlabel(xlab)
        a2.set_ylabel(label(ds["period_error"]))
        art["error_legend"] = a2.legend(fontsize=8, loc="lower right")
        a2.grid(True, which="major", alpha=0.3)
    title(fig, ds, "Duffing amplitude-period relation")
    return art


def kinematic_coefficients(ds, *, fig=None, ax=None):
    """k_v = v_max T / A and k_a = a_max T^2 / A against epsilon (2 pi and 4 pi^2 when linear)."""
    names = [n for n in ("kv", "ka") if n in ds]
    fig, axes = new_figure(len(names), 1, width=7.0, height=3.4, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes)
    x, xlab, beyond = _x(ds)
    order = np.argsort(x)
    for row, name in enumerate(names):
        a = axes[row, 0]
        v = _flat(ok_values(ds, name).broadcast_like(ds["status"]))
        art[name], = a.plot(x[order], v[order], ".-", ms=2, lw=0.8, color="C2", label=name)
        ref, txt = (2 * np.pi, "2π") if name == "kv" else (4 * np.pi**2, "4π²")
        art[f"{name}_linear"] = a.axhline(ref, color="0.5", ls="--", lw=0.8, label=f"linear oscillator: {txt}")
        if beyond is None:
            log_or_symlog(a, x)
        else:
            art.update({f"{k}_{name}": v for k, v in _separatrix(a, ds, beyond, x).items()})
        a.set_xlabel(xlab)
        a.set_ylabel(label(ds[name], width=34))
        a.grid(True, alpha=0.3)
        a.legend(fontsize=8)
        art[f"{name}_flag_note"] = flag_note(a, ds)
    title(fig, ds, "Kinematic invariants of the Duffing oscillator")
    return art


FIGURES = (
    ModelFigure("amplitude_period", amplitude_period, models=MODELS, needs=("epsilon",),
                any_of=("period", "period_exact"), draws=("period_error",), fits=can_amplitude_period),
    ModelFigure("kinematic_coefficients", kinematic_coefficients, models=MODELS, needs=("epsilon",),
                any_of=("kv", "ka")),
)
