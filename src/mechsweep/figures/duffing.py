"""Duffing nomograms: period and kinematic coefficients against epsilon = mu A^2 / omega^2."""
from __future__ import annotations

import numpy as np

from ._registry import ModelFigure
from ._style import flag_note, label, log_or_symlog, new_figure, ok_values, title

MODELS = ("duffing", "torsional_circuit")  # the torsional circuit stores Duffing's outputs too


def _flat(da):
    return np.asarray(da.values, dtype=float).ravel()


def _omega(ds):
    if "omega" in ds.coords or "omega" in ds:
        return ds["omega"]
    return None


def can_amplitude_period(ds) -> bool:
    """Needs the linear frequency omega (a parameter of the Duffing model) to scale the period."""
    return _omega(ds) is not None


def amplitude_period(ds):
    """T omega against epsilon: integrated points over the elliptic closed form; relative error below."""
    has_err = "period_error" in ds
    fig, axes = new_figure(2 if has_err else 1, 1, width=7.0, height=3.8)
    ax = axes[0, 0]
    eps_da = ok_values(ds, "epsilon")
    eps = _flat(eps_da.broadcast_like(ds["status"]))
    omega = _omega(ds)
    if "period_exact" in ds:
        te = _flat((ok_values(ds, "period_exact") * omega).broadcast_like(ds["status"]))
        order = np.argsort(eps)
        ax.plot(eps[order], te[order], "-", color="C0", lw=1.6, label="closed form 4K(m)/sqrt(ω²+μA²)")
    if "period" in ds:
        ti = _flat((ok_values(ds, "period") * omega).broadcast_like(ds["status"]))
        step = max(1, eps.size // 1500)  # keep the marker cloud readable
        ax.plot(eps[::step], ti[::step], "o", ms=3, mfc="none", color="C3", label="integrated (DOP853)")
    ax.axhline(2 * np.pi, color="0.5", lw=0.8, ls="--", label="linear: 2π")
    log_or_symlog(ax, eps)
    ax.set_xlabel(label(ds["epsilon"]))
    ax.set_ylabel("T ω, dimensionless period [1]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    flag_note(ax, ds)
    if has_err:
        ax2 = axes[1, 0]
        err = _flat(ok_values(ds, "period_error"))
        floor = 1e-17
        ax2.semilogy(eps, np.maximum(err, floor), ".", ms=2, color="C3")
        ax2.axhline(floor, color="0.7", lw=0.6)
        ax2.text(0.01, 0.02, f"exact zeros shown at {floor:g}", transform=ax2.transAxes, fontsize=7, color="0.4")
        log_or_symlog(ax2, eps)
        ax2.set_xlabel(label(ds["epsilon"]))
        ax2.set_ylabel(label(ds["period_error"]))
        if "solver_rtol" in ds.attrs:
            ax2.axhline(ds.attrs["solver_rtol"], color="C0", lw=0.8, ls=":", label=f"rtol = {ds.attrs['solver_rtol']:g}")
            ax2.legend(fontsize=8)
        ax2.grid(True, alpha=0.3)
    title(fig, ds, "Duffing amplitude-period relation")
    return fig


def kinematic_coefficients(ds):
    """k_v = v_max T / A and k_a = a_max T^2 / A against epsilon (2 pi and 4 pi^2 when linear)."""
    names = [n for n in ("kv", "ka") if n in ds]
    fig, axes = new_figure(len(names), 1, width=7.0, height=3.4)
    eps = _flat(ok_values(ds, "epsilon").broadcast_like(ds["status"]))
    order = np.argsort(eps)
    for row, name in enumerate(names):
        ax = axes[row, 0]
        v = _flat(ok_values(ds, name).broadcast_like(ds["status"]))
        ax.plot(eps[order], v[order], ".-", ms=2, lw=0.8, color="C2")
        ref, txt = (2 * np.pi, "2π") if name == "kv" else (4 * np.pi**2, "4π²")
        ax.axhline(ref, color="0.5", ls="--", lw=0.8, label=f"linear oscillator: {txt}")
        log_or_symlog(ax, eps)
        ax.set_xlabel(label(ds["epsilon"]))
        ax.set_ylabel(label(ds[name]))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        flag_note(ax, ds)
    title(fig, ds, "Kinematic invariants of the Duffing oscillator")
    return fig


FIGURES = (
    ModelFigure("amplitude_period", amplitude_period, models=MODELS, needs=("epsilon",),
                any_of=("period", "period_exact"), draws=("period_error",), fits=can_amplitude_period),
    ModelFigure("kinematic_coefficients", kinematic_coefficients, models=MODELS, needs=("epsilon",),
                any_of=("kv", "ka")),
)
