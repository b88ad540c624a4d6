"""Duffing nomograms: period and kinematic coefficients against epsilon = mu A^2 / omega^2.

Soft springs (every epsilon below 0, down towards the separatrix epsilon = -1, where the period
grows like ln(1 / (1 + epsilon))) are drawn against 1 + epsilon on a log axis, so the divergence
is a straight line; the points at or beyond the separatrix (1 + epsilon <= 0: no oscillation,
flagged) have no place on that axis and are counted in the caption."""
from __future__ import annotations

import numpy as np

from ._registry import ModelFigure
from ._style import (Drawn, flag_note, label, log_or_symlog, log_scale, new_figure, ok_values, short_symbol, symbol,
                     title)

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


def _inner(math: str) -> str:
    """The body of a mathtext span ('$x$' -> 'x')."""
    return math[1:-1] if math.startswith("$") and math.endswith("$") else math


def _x(ds):
    """(x values over the grid, x label, beyond-separatrix mask or None): epsilon, or for soft
    springs 1 + epsilon (distance from the separatrix) on a log axis."""
    eps = _flat(ds["epsilon"].broadcast_like(ds["status"]))
    if not _soft(ds):
        return eps, label(ds["epsilon"], width=70), None
    e = _inner(short_symbol(ds["epsilon"]) or "epsilon")
    return (1.0 + eps, f"$1 + {e}$, distance from the soft separatrix $ {e} = -1$ ({symbol(ds['epsilon'])})",
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


def _x_scale(ax, x, beyond, art, key="") -> None:
    """The x scale of a panel: epsilon on the scale its values ask for (:func:`log_or_symlog`); for
    soft springs (``beyond`` given) a log axis of 1 + epsilon, with an arrow at its left edge pointing
    to the separatrix (1 + epsilon -> 0, off the axis: a log axis has no place for 1 + epsilon <= 0),
    stored in ``art`` as ``towards`` + ``key``."""
    if beyond is None:
        log_or_symlog(ax, x)
        return
    log_scale(ax, "x")
    art["towards" + key] = ax.annotate("separatrix", xy=(0.0, 0.12), xytext=(0.07, 0.12), xycoords="axes fraction",
                                       textcoords="axes fraction", ha="left", va="center", fontsize=7, color="0.3",
                                       arrowprops=dict(arrowstyle="->", color="0.3", lw=0.8))


def _beyond_note(ds, beyond) -> str | None:
    if beyond is None or not beyond.any():
        return None
    e = _inner(short_symbol(ds["epsilon"]) or "epsilon")
    return (f"{int(beyond.sum())} grid points lie at or beyond the separatrix ($1 + {e} \\leq 0$: no oscillation): "
            "flagged, and not on the log axis")


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
                                     label=r"closed form $4K(m)/\sqrt{\omega^2 + \mu A^2}$")
    art["linear"] = a.axhline(2 * np.pi, color="0.5", lw=0.8, ls="--", label=r"linear oscillator: $2\pi$")
    _x_scale(a, x, beyond, art)
    a.set_xlabel(xlab)
    t_sym = _inner(short_symbol(ds["period"]) if "period" in ds else "$T$")
    w_sym = _inner(short_symbol(omega) or "omega")
    a.set_ylabel(f"${t_sym}\\,{w_sym}$, dimensionless period")
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
        _x_scale(a2, x, beyond, art, "_error")
        a2.set_xlim(a.get_xlim())
        a2.set_xlabel(xlab)
        a2.set_ylabel(label(ds["period_error"]))
        art["error_legend"] = a2.legend(fontsize=8, loc="lower right")
        a2.grid(True, which="major", alpha=0.3)
    title(fig, ds, "Duffing amplitude-period relation: period against the nonlinearity, integrated and in closed "
                   "form", caption=_beyond_note(ds, beyond))
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
        art[name], = a.plot(x[order], v[order], ".-", ms=2, lw=0.8, color="C2", label=short_symbol(ds[name]) or name)
        ref, txt = (2 * np.pi, r"$2\pi$") if name == "kv" else (4 * np.pi**2, r"$4\pi^2$")
        art[f"{name}_linear"] = a.axhline(ref, color="0.5", ls="--", lw=0.8, label=f"linear oscillator: {txt}")
        _x_scale(a, x, beyond, art, f"_{name}")
        a.set_xlabel(xlab)
        a.set_ylabel(label(ds[name], width=34))
        a.grid(True, alpha=0.3)
        a.legend(fontsize=8)
        art[f"{name}_flag_note"] = flag_note(a, ds)
    title(fig, ds, "Kinematic coefficients of the Duffing oscillator against the nonlinearity",
          caption=_beyond_note(ds, beyond))
    return art


FIGURES = (
    ModelFigure("amplitude_period", amplitude_period, models=MODELS, needs=("epsilon",),
                any_of=("period", "period_exact"), draws=("period_error",), fits=can_amplitude_period),
    ModelFigure("kinematic_coefficients", kinematic_coefficients, models=MODELS, needs=("epsilon",),
                any_of=("kv", "ka")),
)
