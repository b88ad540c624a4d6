"""Auto-balancer figures: the stability chart engineers read a safe speed range from, residual
vibration against crank speed, and time histories of one grid point."""
from __future__ import annotations

import textwrap

import matplotlib.patches
import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.ticker import MaxNLocator

from . import located
from ._registry import ModelFigure
from ._style import Drawn, flag_note, label, new_figure, title

MODELS = ("autobalancer",)

STABLE_COLORS = ListedColormap(["#f4c7c3", "#c8e6c9"])  # unstable, stable


def _x(ds):
    """Crank speed axis, as Omega / omega_xi when omega_xi is a fixed value of the dataset."""
    om = ds["Omega"]
    if "omega_xi" in ds.coords and ds["omega_xi"].ndim == 0:
        w = float(ds["omega_xi"])
        return om.values / w, "Ω / ω_ξ, crank speed over the lower platform frequency", w
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
    ratio = "2 m / M, pendulum mass ratio"
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


FREQUENCIES = (("omega_xi", "ω_ξ", "--"), ("omega_eta", "ω_η", ":"), ("omega_p", "ω_p", "-."))


def _frequency_ticks(ax, ds, scale):
    """The platform's natural frequencies (first approximation) as labelled ticks on a top axis,
    not as lines across the chart (where they would lie on the P(Omega) = 0 curves). Returns the
    secondary axis, or None when no frequency is a fixed value of the dataset."""
    ticks = [(v / scale, text) for name, text, _ in FREQUENCIES if (v := _scalar(ds, name)) is not None]
    if not ticks:
        return None
    top = ax.secondary_xaxis("top")
    top.set_xticks([t for t, _ in ticks], [t for _, t in ticks])
    top.tick_params(direction="inout", length=9, width=1.4, colors="C0", labelsize=9)
    return top


def stability_chart(ds, boundaries=None, *, fig=None, ax=None):
    """Floquet stability region over crank speed and a second axis, with the damped first
    approximation (P(Omega) = 0, its stable side P < 0 hatched), the platform's natural
    frequencies (top ticks) and simulation verdicts; the located and continued stability boundaries
    over it when they were computed (`mechsweep boundaries`, DATA.boundaries.h5)."""
    ydim = _y_dim(ds, "stable_floquet")
    x, xlab, scale = _x(ds)
    y, ylab = _y(ds, ydim)
    ymap, _ = _y_map(ds, ydim)
    fig, axes = new_figure(1, 1, width=8.0, height=5.6, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes)
    ax = axes[0, 0]
    verdict = ds["stable_floquet"].where(ds["status"] == 0).transpose(ydim, "Omega").values
    art["mesh"] = ax.pcolormesh(x, y, verdict, cmap=STABLE_COLORS, vmin=0, vmax=1, shading="nearest")
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
            art["floquet_contour"] = ax.contour(x, y, fm, levels=[1.0], colors="k",
                                                linewidths=1.2 if boundaries is None else 0.7,
                                                linestyles="solid" if boundaries is None else "dashed")
            handles.append(ax.plot([], [], color="k", lw=1.2 if boundaries is None else 0.7,
                                   ls="-" if boundaries is None else "--",
                                   label="max |Floquet multiplier| = 1: contour of the grid "
                                         f"({len(x)} x {len(y)}; precision ~ its spacing)")[0])
    if "P_approx" in ds:
        P = ds["P_approx"].transpose(ydim, "Omega").values
        if np.isfinite(P).any() and np.nanmin(P) < 0 < np.nanmax(P):
            art["P_stable"] = ax.contourf(x, y, P, levels=[-np.inf, 0.0], colors="none", hatches=["//"])
            art["P_stable"].set_edgecolor((1.0, 0.5, 0.05, 0.55))
            art["P_stable"].set_linewidth(0.0)
            art["P_contour"] = ax.contour(x, y, P, levels=[0.0], colors="C1", linewidths=1.6)
            handles.append(ax.plot([], [], color="C1", lw=1.6, label="P(Ω) = 0 (damped first approximation)")[0])
            handles.append(matplotlib.patches.Patch(facecolor="none", edgecolor=(1.0, 0.5, 0.05, 0.55), hatch="//",
                                                    lw=0,
                                                    label="P(Ω) < 0: stable by the first approximation"))
    if "stable_sim" in ds:
        sim = ds["stable_sim"].where(ds["status"] == 0).transpose(ydim, "Omega").values
        yy, xx = np.meshgrid(y, x, indexing="ij")
        step_y = max(1, len(y) // 12)
        step_x = max(1, len(x) // 16)
        sub = (slice(None, None, step_y), slice(None, None, step_x))
        s, xs, ys = sim[sub], xx[sub], yy[sub]
        art["sim_stable"] = ax.scatter(xs[s == 1], ys[s == 1], marker="o", s=14, facecolors="none",
                                       edgecolors="k", lw=0.8, label="simulation: stable")
        art["sim_unstable"] = ax.scatter(xs[s == 0], ys[s == 0], marker="x", s=14, color="k", lw=0.8,
                                         label="simulation: unstable")
        handles += [art["sim_stable"], art["sim_unstable"]]
    if boundaries is not None and boundaries.attrs.get("along") == "Omega":
        line_dim = ydim if ydim in boundaries["boundary"].dims else None
        xmap = lambda v: np.asarray(v) / scale  # noqa: E731
        art["boundaries"] = located.overlay(ax, boundaries, line_dim=line_dim, xmap=xmap, ymap=ymap)
        handles += [a for a in art["boundaries"] if a.get_label() and not a.get_label().startswith("_")]
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
            art["inset"] = inset
    ax.set_xlabel(xlab)
    ax.set_ylabel(ylab)
    ax.set_xlim(x.min(), x.max())
    ax.set_ylim(y.min(), y.max())
    if ds[ydim].attrs.get("spacing") == "log":
        ax.set_yscale("log")
    art["frequencies"] = _frequency_ticks(ax, ds, scale)
    for h in handles:  # a narrow legend leaves the chart its width
        h.set_label("\n".join(textwrap.wrap(h.get_label(), 44)))
    art["legend"] = ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    art["flag_note"] = flag_note(ax, ds, f"{int(flagged.sum())} flagged point(s), grey (see status)")
    title(fig, ds, "Stability of the balanced state of the pendulum auto-balancer",
          caption="top axis: the platform's natural frequencies (first approximation)"
          if art["frequencies"] is not None else None)
    return art


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


def residual(ds, *, fig=None, ax=None):
    """Residual platform vibration and settling time against crank speed, one colour per curve
    (the same in every panel; one legend); the pendulums' final phase error where they settled;
    the platform's natural frequencies as labelled ticks on the top axis."""
    names = [n for n in ("residual_amplitude", "settling_time", "phase_error") if n in ds]
    fig, axes = new_figure(len(names), 1, width=7.5, height=3.0, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, lines={})
    x, xlab, scale = _x(ds)
    rest = [d for d in ds[names[0]].dims if d != "Omega"]
    members = list(np.ndindex(*(ds.sizes[d] for d in rest)))
    step = max(1, len(members) // 8)  # at most ~8 curves stay readable
    members = members[::step]
    settled = np.isfinite(ds["settling_time"]) if "settling_time" in ds else ds["status"] == 0
    handles = {}
    for r, name in enumerate(names):
        a = axes[r, 0]
        # the model keeps what it could compute at a flagged point (e.g. the residual where the
        # pendulums never settle); NaN marks what it could not, and is not drawn. The phase error is
        # drawn only where the pendulums settled: elsewhere it is the phase of a wandering pendulum.
        da = ds[name].where(settled) if name == "phase_error" else ds[name]
        missing = []
        for k, idx in enumerate(members):
            member = da.isel(dict(zip(rest, idx)))
            lab = ", ".join(f"{d} = {member[d].values:.4g}" for d in rest) or name
            v = np.asarray(member.values, dtype=float)
            if not np.isfinite(v).any():
                missing.append(lab)
                continue
            (line,) = a.plot(x, v, lw=1.2, color=f"C{k % 10}", label=lab)
            art["lines"][(name, lab)] = line
            handles.setdefault(lab, line)
        if missing:
            a.text(0.01, 0.97, "no value: " + "; ".join(missing), transform=a.transAxes, fontsize=7, va="top",
                   color="0.35")
        v = np.asarray(da.values, dtype=float)
        pos = v[np.isfinite(v)]
        if name in ("residual_amplitude", "phase_error") and pos.size and pos.min() > 0:
            a.set_yscale("log")
        _frequency_ticks(a, ds, scale)
        a.set_xlabel(xlab)
        a.set_ylabel(label(ds[name], width=30) + ("\n(where settled)" if name == "phase_error" else ""))
        a.set_xlim(x.min(), x.max())
        a.grid(True, alpha=0.3)
    if rest:
        order = [lab for lab in (", ".join(f"{d} = {ds[d].values[i]:.4g}" for d, i in zip(rest, idx))
                                 for idx in members) if lab in handles]
        art["legend"] = axes[0, 0].legend([handles[k] for k in order], order, fontsize=7, loc="upper left",
                                          bbox_to_anchor=(1.01, 1.0), title="one colour per curve, all panels",
                                          title_fontsize=7)
    bad = int((ds["status"].values != 0).sum())
    caption = "top axis: the platform's natural frequencies (first approximation)"
    if bad:
        caption += (f"; {bad} of {ds['status'].size} points flagged (see the status variable): each output is "
                    "drawn wherever it could be computed")
    title(fig, ds, "Residual vibration and settling of the pendulum auto-balancer", caption=caption)
    return art


HISTORIES = ("xi_history", "eta_history", "phase_error1_history", "phase_error2_history")


def can_time_history(ds) -> bool:
    """Drawn for one grid point: every grid dimension must be selected down to one value."""
    return all(ds.sizes[d] == 1 for d in ds[next(n for n in HISTORIES if n in ds)].dims if d != "revolution")


def time_history(ds, *, fig=None, ax=None):
    """Platform displacement and pendulum phase errors of one grid point against crank revolutions."""
    point = ds.squeeze()
    fig, axes = new_figure(2, 1, width=8.0, height=3.2, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes)
    t = point["revolution"].values
    ax = axes[0, 0]
    for name, color in (("xi_history", "C0"), ("eta_history", "C1")):
        if name in point:
            art[name], = ax.plot(t, point[name].values, lw=0.8, color=color,
                                 label=point[name].attrs.get("long_name", name))
    ax.set_ylabel("platform displacement [m]")
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    ax = axes[1, 0]
    for name, color in (("phase_error1_history", "C2"), ("phase_error2_history", "C3")):
        if name in point:
            art[name], = ax.plot(t, point[name].values, lw=0.9, color=color,
                                 label=point[name].attrs.get("long_name", name))
    ax.set_ylabel("pendulum phase error [rad]")
    ax.set_xlabel(label(point["revolution"]))
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_xlim(t[0], t[-1])
    where = ", ".join(f"{d} = {float(point[d]):g}" for d in ds.dims if d != "revolution" and d in point.coords)
    title(fig, point, f"Time history at {where}" if where else "Time history")
    return art


FIGURES = (
    ModelFigure("stability_chart", stability_chart, models=MODELS, needs=("stable_floquet",),
                draws=("floquet_max", "P_approx", "stable_sim", "omega_p"), fits=can_stability_chart,
                boundaries=True),
    ModelFigure("residual", residual, models=MODELS, any_of=("residual_amplitude", "settling_time"),
                draws=("phase_error", "omega_p"), fits=can_residual),
    ModelFigure("time_history", time_history, models=MODELS, any_of=HISTORIES, fits=can_time_history),
)
