"""Auto-balancer figures: the stability chart engineers read a safe speed range from, residual
vibration against crank speed, and time histories of one grid point."""
from __future__ import annotations

import textwrap

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.ticker import MaxNLocator

from . import located
from ._registry import ModelFigure
from ._style import flag_note, label, new_figure, title

MODELS = ("autobalancer",)

STABLE_COLORS = ListedColormap(["#f4c7c3", "#c8e6c9"])  # unstable, stable


def _x(ds):
    """Crank speed axis, as Omega / omega_xi when omega_xi is a fixed value of the dataset."""
    om = ds["Omega"]
    if "omega_xi" in ds.coords and ds["omega_xi"].ndim == 0:
        w = float(ds["omega_xi"])
        return om.values / w, "Ω / ω_ξ, crank speed over the lower platform frequency [1]", w
    return om.values, label(om), 1.0


def _y_dim(ds, name):
    dims = [d for d in ds[name].dims if d != "Omega" and ds.sizes[d] > 1]
    return dims[0] if len(dims) == 1 else None


def _y(ds, dim):
    """Second chart axis; a pendulum or platform mass axis is shown as the mass ratio 2 m / M."""
    ymap, ylab = _y_map(ds, dim)
    return ymap(np.asarray(ds[dim].values, dtype=float)), ylab


def _y_map(ds, dim):
    """(values of ``dim`` -> chart coordinate, label) for the second chart axis."""
    ratio = "2 m / M, pendulum mass ratio [1]"
    if dim == "m" and "M" in ds.coords and ds["M"].ndim == 0:
        M = float(ds["M"])
        return (lambda v: 2.0 * np.asarray(v) / M), ratio
    if dim == "M" and "m" in ds.coords and ds["m"].ndim == 0:
        m = float(ds["m"])
        return (lambda v: 2.0 * m / np.asarray(v)), ratio
    return (lambda v: np.asarray(v)), label(ds[dim])


def can_stability_chart(ds) -> bool:
    """Crank speed Omega and exactly one more axis with more than one value."""
    return "Omega" in ds.dims and _y_dim(ds, "stable_floquet") is not None


def stability_chart(ds, boundaries=None):
    """Floquet stability region over crank speed and a second axis, with the first-approximation
    boundaries and simulation verdicts; the located and continued stability boundaries over it
    when they were computed (`mechsweep boundaries`, DATA.boundaries.h5)."""
    ydim = _y_dim(ds, "stable_floquet")
    x, xlab, scale = _x(ds)
    y, ylab = _y(ds, ydim)
    ymap, _ = _y_map(ds, ydim)
    fig, axes = new_figure(1, 1, width=8.0, height=5.6)
    ax = axes[0, 0]
    verdict = ds["stable_floquet"].where(ds["status"] == 0).transpose(ydim, "Omega").values
    ax.pcolormesh(x, y, verdict, cmap=STABLE_COLORS, vmin=0, vmax=1, shading="nearest")
    flagged = np.isnan(verdict)
    if flagged.any():
        ax.pcolormesh(x, y, np.where(flagged, 1.0, np.nan), cmap=ListedColormap(["0.8"]), shading="nearest")
    handles = [ax.fill_between([], [], color=STABLE_COLORS.colors[1], label="stable (Floquet)"),
               ax.fill_between([], [], color=STABLE_COLORS.colors[0], label="unstable (Floquet)")]
    if flagged.any():
        handles.append(ax.fill_between([], [], color="0.8", label="flagged (see status)"))
    if "floquet_max" in ds:
        fm = ds["floquet_max"].transpose(ydim, "Omega").values
        if np.isfinite(fm).any() and np.nanmin(fm) < 1 < np.nanmax(fm):
            ax.contour(x, y, fm, levels=[1.0], colors="k", linewidths=1.2 if boundaries is None else 0.7,
                       linestyles="solid" if boundaries is None else "dashed")
            handles.append(ax.plot([], [], color="k", lw=1.2 if boundaries is None else 0.7,
                                   ls="-" if boundaries is None else "--",
                                   label="max |Floquet multiplier| = 1: contour of the grid "
                                         f"({len(x)} x {len(y)}; precision ~ its spacing)")[0])
    for name, style, text in (("omega_xi", "--", "ω_ξ"), ("omega_eta", ":", "ω_η"), ("omega_p", "-.", "ω_p")):
        value = _scalar(ds, name)
        if value is not None:
            handles.append(ax.axvline(value / scale, color="C0", ls=style, lw=1.3, label=f"{text} (first approximation)"))
    if "P_approx" in ds:
        P = ds["P_approx"].transpose(ydim, "Omega").values
        if np.isfinite(P).any() and np.nanmin(P) < 0 < np.nanmax(P):
            ax.contour(x, y, P, levels=[0.0], colors="C1", linewidths=1.4)
            handles.append(ax.plot([], [], color="C1", lw=1.4, label="P(Ω) = 0 (damped first approximation)")[0])
    if "stable_sim" in ds:
        sim = ds["stable_sim"].where(ds["status"] == 0).transpose(ydim, "Omega").values
        yy, xx = np.meshgrid(y, x, indexing="ij")
        step_y = max(1, len(y) // 12)
        step_x = max(1, len(x) // 16)
        sub = (slice(None, None, step_y), slice(None, None, step_x))
        s, xs, ys = sim[sub], xx[sub], yy[sub]
        handles.append(ax.scatter(xs[s == 1], ys[s == 1], marker="o", s=14, facecolors="none",
                                  edgecolors="k", lw=0.8, label="simulation: stable"))
        handles.append(ax.scatter(xs[s == 0], ys[s == 0], marker="x", s=14, color="k", lw=0.8,
                                  label="simulation: unstable"))
    if boundaries is not None and boundaries.attrs.get("along") == "Omega":
        line_dim = ydim if ydim in boundaries["boundary"].dims else None
        xmap = lambda v: np.asarray(v) / scale  # noqa: E731
        handles += [a for a in located.overlay(ax, boundaries, line_dim=line_dim, xmap=xmap, ymap=ymap)
                    if a.get_label() and not a.get_label().startswith("_")]
        small = located.small_curves(boundaries, ((x.min(), x.max()), (y.min(), y.max())), xmap=xmap, ymap=ymap)
        if small is not None:  # an island too small to see: a magnified view of it
            (x0, x1), (y0, y1) = small
            dx, dy = 0.15 * (x1 - x0), 0.15 * (y1 - y0)
            inset = ax.inset_axes([0.04, 0.5, 0.36, 0.36])
            inset.pcolormesh(x, y, verdict, cmap=STABLE_COLORS, vmin=0, vmax=1, shading="nearest")
            located.overlay(inset, boundaries, line_dim=line_dim, xmap=xmap, ymap=ymap)
            inset.set_xlim(x0 - dx, x1 + dx)
            inset.set_ylim(y0 - dy, y1 + dy)
            inset.tick_params(labelsize=6)
            inset.xaxis.set_major_locator(MaxNLocator(3))
            inset.yaxis.set_major_locator(MaxNLocator(4))
            inset.set_title("magnified: a boundary closed inside the chart", fontsize=7)
            ax.indicate_inset_zoom(inset, edgecolor="0.3")
    ax.set_xlabel(xlab)
    ax.set_ylabel(ylab)
    ax.set_xlim(x.min(), x.max())
    ax.set_ylim(y.min(), y.max())
    if ds[ydim].attrs.get("spacing") == "log":
        ax.set_yscale("log")
    for h in handles:  # a narrow legend leaves the chart its width
        h.set_label("\n".join(textwrap.wrap(h.get_label(), 44)))
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    flag_note(ax, ds)
    title(fig, ds, "Stability of the balanced state of the pendulum auto-balancer")
    return fig


def _scalar(ds, name):
    """A fixed parameter or an output that is constant over the chart, else None."""
    if name not in ds:
        return None
    v = np.asarray(ds[name].values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size and np.allclose(v, v.flat[0]):
        return float(v.flat[0])
    return None


def can_residual(ds) -> bool:
    """Crank speed Omega is an axis."""
    return "Omega" in ds.dims


def residual(ds):
    """Residual platform vibration and settling time against crank speed."""
    names = [n for n in ("residual_amplitude", "settling_time", "phase_error") if n in ds]
    fig, axes = new_figure(len(names), 1, width=7.5, height=3.2)
    x, xlab, scale = _x(ds)
    for r, name in enumerate(names):
        ax = axes[r, 0]
        # the model keeps what it could compute at a flagged point (e.g. the residual where the
        # pendulums never settle); NaN marks what it could not, and is not drawn
        da = ds[name]
        rest = [d for d in da.dims if d != "Omega"]
        members = list(np.ndindex(*(da.sizes[d] for d in rest)))
        step = max(1, len(members) // 8)  # at most ~8 curves stay readable
        for k, idx in enumerate(members[::step]):
            member = da.isel(dict(zip(rest, idx)))
            lab = ", ".join(f"{d} = {member[d].values:.4g}" for d in rest) or None
            ax.plot(x, member.values, lw=1.2, color=f"C{k % 10}", label=lab)
        if rest:
            ax.legend(fontsize=7)
        if name == "residual_amplitude" and np.nanmin(da.values) > 0:
            ax.set_yscale("log")
        for wname, style in (("omega_xi", "--"), ("omega_eta", ":"), ("omega_p", "-.")):
            value = _scalar(ds, wname)
            if value is not None:
                ax.axvline(value / scale, color="0.5", ls=style, lw=0.9)
        ax.set_xlabel(xlab)
        ax.set_ylabel(label(ds[name], width=30))
        ax.set_xlim(x.min(), x.max())
        ax.grid(True, alpha=0.3)
    bad = int((ds["status"].values != 0).sum())
    if bad:
        axes[0, 0].text(0.01, 0.01, f"{bad} point(s) flagged: drawn only where the value could be computed "
                        "(see the status variable)", transform=axes[0, 0].transAxes, fontsize=7, color="0.35")
    title(fig, ds, "Residual vibration and settling of the pendulum auto-balancer")
    return fig


HISTORIES = ("xi_history", "eta_history", "phase_error1_history", "phase_error2_history")


def can_time_history(ds) -> bool:
    """Drawn for one grid point: every grid dimension must be selected down to one value."""
    return all(ds.sizes[d] == 1 for d in ds[next(n for n in HISTORIES if n in ds)].dims if d != "revolution")


def time_history(ds):
    """Platform displacement and pendulum phase errors of one grid point against crank revolutions."""
    point = ds.squeeze()
    fig, axes = new_figure(2, 1, width=8.0, height=3.2)
    t = point["revolution"].values
    ax = axes[0, 0]
    for name, color in (("xi_history", "C0"), ("eta_history", "C1")):
        if name in point:
            ax.plot(t, point[name].values, lw=0.8, color=color, label=point[name].attrs.get("long_name", name))
    ax.set_ylabel("platform displacement [m]")
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    ax = axes[1, 0]
    for name, color in (("phase_error1_history", "C2"), ("phase_error2_history", "C3")):
        if name in point:
            ax.plot(t, point[name].values, lw=0.9, color=color, label=point[name].attrs.get("long_name", name))
    ax.set_ylabel("pendulum phase error [rad]")
    ax.set_xlabel(label(point["revolution"]))
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_xlim(t[0], t[-1])
    where = ", ".join(f"{d} = {float(point[d]):g}" for d in ds.dims if d != "revolution" and d in point.coords)
    title(fig, point, f"Time history at {where}" if where else "Time history")
    return fig


FIGURES = (
    ModelFigure("stability_chart", stability_chart, models=MODELS, needs=("stable_floquet",),
                draws=("floquet_max", "P_approx", "stable_sim", "omega_p"), fits=can_stability_chart,
                boundaries=True),
    ModelFigure("residual", residual, models=MODELS, any_of=("residual_amplitude", "settling_time"),
                draws=("phase_error", "omega_p"), fits=can_residual),
    ModelFigure("time_history", time_history, models=MODELS, any_of=HISTORIES, fits=can_time_history),
)
