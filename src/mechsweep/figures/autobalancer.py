"""Auto-balancer figures: the stability chart engineers read a safe speed range from, residual
vibration against crank speed, and time histories of one grid point."""
from __future__ import annotations

import matplotlib.patches
import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.legend_handler import HandlerTuple
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from . import located
from ._registry import ModelFigure
from ._style import (Drawn, hatch_unstable, label, log_scale, new_figure, prose, short_symbol, stable_cmap,
                     stable_patch, status_text, ticked, ticked_contour, title, unstable_patch, value_text, wrap)

MODELS = ("autobalancer",)

STABLE_COLORS = stable_cmap()  # unstable, stable (colour-blind safe; the unstable cells also dotted)
APPROX_COLOR = "#6a3d9a"  # the first approximation (line and hatch): apart from both fills and the boundaries
FLAGGED_COLOR = "0.8"


def _x(ds):
    """Crank speed axis, as Omega / omega_xi when omega_xi is a fixed value of the dataset:
    (values, label, scale)."""
    om = ds["Omega"]
    if "omega_xi" in ds.coords and ds["omega_xi"].ndim == 0:
        w = float(ds["omega_xi"])
        text = f"{short_symbol(om) or 'Omega'} / {short_symbol(ds['omega_xi']) or 'omega_xi'}"
        return om.values / w, f"{text}, crank speed over the platform's lower natural frequency", w
    return om.values, label(om), 1.0


def _y_dim(ds, name):
    dims = [d for d in ds[name].dims if d != "Omega" and ds.sizes[d] > 1]
    return dims[0] if len(dims) == 1 else None


def _y_map(ds, dim):
    """(values of ``dim`` -> chart coordinate, label) for the second chart axis; a pendulum or
    platform mass axis is shown as the mass ratio 2 m / M."""
    def ratio():
        m, M = (short_symbol(ds[n]) or n for n in ("m", "M"))
        return f"2{m} / {M}, pendulum mass ratio"

    if dim == "m" and "M" in ds.coords and ds["M"].ndim == 0:
        M = float(ds["M"])
        return (lambda v: 2.0 * np.asarray(v) / M), ratio()
    if dim == "M" and "m" in ds.coords and ds["m"].ndim == 0:
        m = float(ds["m"])
        return (lambda v: 2.0 * m / np.asarray(v)), ratio()
    return (lambda v: np.asarray(v)), label(ds[dim], width=60)


def can_stability_chart(ds) -> bool:
    """Crank speed Omega and exactly one more axis with more than one value."""
    return "Omega" in ds.dims and _y_dim(ds, "stable_floquet") is not None


# the platform's natural frequencies and the first-approximation boundary between them, on a top axis
FREQUENCIES = ("omega_xi", "omega_eta", "omega_p")


def _frequency_ticks(ax, ds, scale):
    """The platform's natural frequencies (first approximation) and omega_p as labelled ticks on a
    top axis, not as lines across the chart (where they would lie on the P(Omega) = 0 curves).
    Returns the secondary axis, or None when none is a fixed value of the dataset."""
    ticks = [(v / scale, short_symbol(ds[name]) or name) for name in FREQUENCIES
             if (v := _scalar(ds, name)) is not None]
    if not ticks:
        return None
    top = ax.secondary_xaxis("top")
    top.set_xticks([t for t, _ in ticks], [t for _, t in ticks])
    top.tick_params(direction="inout", length=9, width=1.4, colors="C0", labelsize=9)
    return top


def _frequency_note(ds) -> str | None:
    """What the top axis marks (the platform's natural frequencies, and omega_p: not a natural
    frequency, the first approximation's stability boundary between them)."""
    shown = [n for n in FREQUENCIES if _scalar(ds, n) is not None]
    if not shown:
        return None
    sym = {n: short_symbol(ds[n]) or n for n in shown}
    natural = [sym[n] for n in ("omega_xi", "omega_eta") if n in sym]
    parts = [f"the platform's natural frequenc{'ies' if len(natural) > 1 else 'y'} {' and '.join(natural)}"] if natural \
        else []
    if "omega_p" in sym:
        parts.append(f"{sym['omega_p']}, the first approximation's stability boundary between them")
    return "top axis: " + "; ".join(parts)


def _chart_layout(fig, ax, zoom: bool):
    """(figure, main Axes, Axes for the legend or None, Axes for the magnified view or None). A figure
    of its own (or the user's ``fig``) gets a column right of the chart: the legend above, the
    magnified view below it when there is one (inside the chart it hid data); on the user's ``ax``
    the chart alone (the legend beside it, no magnified view)."""
    if ax is not None:
        f, axes = new_figure(1, 1, fig=fig, ax=ax)
        return f, axes[0, 0], None, None
    if not zoom:
        f, axes = new_figure(1, 1, width=8.4, height=5.6, fig=fig)
        return f, axes[0, 0], None, None
    from matplotlib.figure import Figure

    f = fig if fig is not None else Figure(figsize=(11.0, 6.0), layout="constrained")
    f._mechsweep_titled = True
    grid = f.subplot_mosaic([["chart", "legend"], ["chart", "zoom"]], width_ratios=[2.1, 1.0],
                            height_ratios=[1.25, 1.0])
    grid["legend"].set_axis_off()
    return f, grid["chart"], grid["legend"], grid["zoom"]


def stability_chart(ds, boundaries=None, *, fig=None, ax=None):
    """Floquet stability region over crank speed and a second axis (stable light blue, unstable
    orange and dotted), with the damped first approximation (P(Omega) = 0, its stable side
    P < 0 hatched), the platform's natural frequencies and omega_p (top ticks) and simulation
    verdicts; the located and continued stability boundaries over it when they were computed
    (`mechsweep boundaries`, DATA.boundaries.h5), a boundary closed inside the chart magnified
    beside it."""
    ydim = _y_dim(ds, "stable_floquet")
    x, xlab, scale = _x(ds)
    ymap, ylab = _y_map(ds, ydim)
    y = ymap(np.asarray(ds[ydim].values, dtype=float))
    xmap = lambda v: np.asarray(v) / scale  # noqa: E731
    use_boundaries = boundaries is not None and boundaries.attrs.get("along") == "Omega"
    small = (located.small_curves(boundaries, ((x.min(), x.max()), (y.min(), y.max())), xmap=xmap, ymap=ymap)
             if use_boundaries else None)
    fig, ax, legend_ax, zoom_ax = _chart_layout(fig, ax, zoom=small is not None)
    axes = np.array([[ax]], dtype=object)
    art = Drawn(figure=fig, axes=axes)
    verdict = ds["stable_floquet"].where(ds["status"] == 0).transpose(ydim, "Omega").values
    flagged = np.isnan(verdict)

    def shade(a):
        mesh = a.pcolormesh(x, y, verdict, cmap=STABLE_COLORS, vmin=0, vmax=1, shading="nearest")
        grey = (a.pcolormesh(x, y, np.where(flagged, 1.0, np.nan), cmap=ListedColormap([FLAGGED_COLOR]),
                             shading="nearest") if flagged.any() else None)
        return mesh, grey, hatch_unstable(a, x, y, verdict)

    art["mesh"], art["flagged"], art["unstable_hatch"] = shade(ax)
    sym = short_symbol(ds["floquet_max"]) if "floquet_max" in ds else "max |Floquet multiplier|"
    handles = [stable_patch(f"stable (Floquet: {sym} < 1)"), unstable_patch(f"unstable (Floquet: {sym} > 1), dotted")]
    if flagged.any():
        handles.append(matplotlib.patches.Patch(facecolor=FLAGGED_COLOR, lw=0,
                                                label=f"no verdict at {int(flagged.sum())} points (see status)"))
    if "floquet_max" in ds:
        fm = ds["floquet_max"].transpose(ydim, "Omega").values
        if np.isfinite(fm).any() and np.nanmin(fm) < 1 < np.nanmax(fm):
            lw, ls = (1.2, "solid") if not use_boundaries else (0.7, "dashed")
            art["floquet_contour"] = ax.contour(x, y, fm, levels=[1.0], colors="k", linewidths=lw, linestyles=ls)
            handles.append(Line2D([], [], color="k", lw=lw, ls="-" if ls == "solid" else "--",
                                  label=f"{sym} = 1 interpolated on the grid ({len(x)} × {len(y)} points)"))
    if "P_approx" in ds:
        P = ds["P_approx"].transpose(ydim, "Omega").values
        if np.isfinite(P).any() and np.nanmin(P) < 0 < np.nanmax(P):
            # its boundary, ticked on the side it calls stable (a hatched area over the dotted one read as
            # a third fill)
            art["P_contour"] = ax.contour(x, y, P, levels=[0.0], colors=APPROX_COLOR, linewidths=1.4)
            p = short_symbol(ds["P_approx"]) or "P"
            handles.append(Line2D([], [], color=APPROX_COLOR, lw=1.4, path_effects=ticked(),
                                  label=f"damped first approximation: boundary {p} = 0, ticked on the side it "
                                        f"calls stable ({p} < 0)"))
    if "stable_sim" in ds:
        sim = ds["stable_sim"].where(ds["status"] == 0).transpose(ydim, "Omega").values
        yy, xx = np.meshgrid(y, x, indexing="ij")
        step_y = max(1, len(y) // 12)
        step_x = max(1, len(x) // 16)
        sub = (slice(None, None, step_y), slice(None, None, step_x))
        s, xs, ys = sim[sub], xx[sub], yy[sub]
        art["sim_stable"] = ax.scatter(xs[s == 1], ys[s == 1], marker="o", s=14, facecolors="none",
                                       edgecolors="k", lw=0.8)
        art["sim_unstable"] = ax.scatter(xs[s == 0], ys[s == 0], marker="x", s=14, color="k", lw=0.8)
        handles.append((Line2D([], [], marker="o", ls="none", mfc="none", mec="k", ms=4.5),
                        Line2D([], [], marker="x", ls="none", color="k", ms=4.5),
                        "direct simulation from a kicked balanced state: settles (○), departs (×)"))
    if use_boundaries:
        line_dim = ydim if ydim in boundaries["boundary"].dims else None
        art["boundaries"] = located.overlay(ax, boundaries, line_dim=line_dim, xmap=xmap, ymap=ymap, ds=ds)
        handles += located.legend_entries(art["boundaries"], boundaries, ds)
        if zoom_ax is not None:  # an island too small to see on the chart: magnified beside it
            (x0, x1), (y0, y1) = small
            dx, dy = 0.15 * (x1 - x0), 0.15 * (y1 - y0)
            shade(zoom_ax)
            located.overlay(zoom_ax, boundaries, line_dim=line_dim, xmap=xmap, ymap=ymap, ds=ds)
            zoom_ax.set_xlim(x0 - dx, x1 + dx)
            zoom_ax.set_ylim(y0 - dy, y1 + dy)
            zoom_ax.xaxis.set_major_locator(MaxNLocator(4))
            zoom_ax.yaxis.set_major_locator(MaxNLocator(5))
            zoom_ax.tick_params(labelsize=8)
            zoom_ax.set_title(wrap(f"magnified (grey frame on the chart): a small region closed by boundaries, "
                                   f"{xlab.split(',')[0]} = {x0:.4g} to {x1:.4g}", 44), fontsize=8)
            ax.indicate_inset((x0 - dx, y0 - dy, 2 * dx + x1 - x0, 2 * dy + y1 - y0), inset_ax=zoom_ax,
                              edgecolor="0.3")
            art["inset"] = zoom_ax
    ax.set_xlabel(xlab)
    ax.set_ylabel(ylab)
    ax.set_xlim(x.min(), x.max())
    ax.set_ylim(y.min(), y.max())
    if ds[ydim].attrs.get("spacing") == "log":
        log_scale(ax, "y")
    if "P_contour" in art:  # once the scales are set: ticks on the side the first approximation calls stable
        art["P_ticks"] = ticked_contour(ax, art["P_contour"], x, y, P, color=APPROX_COLOR)
    art["frequencies"] = _frequency_ticks(ax, ds, scale)
    art["legend"] = _legend(legend_ax or ax, handles, outside=legend_ax is None)
    title(fig, ds, "Stability of the balanced state of the pendulum auto-balancer", caption=_frequency_note(ds))
    return art


def _legend(ax, handles, *, outside: bool):
    """One legend for the chart: entries given as an artist (its label) or as a tuple of artists
    and a label (drawn side by side). ``outside``: right of ``ax``; else inside ``ax`` (an Axes of
    its own, kept for the legend)."""
    artists, labels = [], []
    for h in handles:
        if isinstance(h, tuple):
            artists.append(h[:-1])
            labels.append(h[-1])
        else:
            artists.append(h)
            labels.append(h.get_label())
    labels = [wrap(t, 44) for t in labels]  # a narrow legend leaves the chart its width
    where = dict(loc="upper left", bbox_to_anchor=(1.01, 1.0)) if outside else dict(loc="upper left",
                                                                                     bbox_to_anchor=(0.0, 1.0))
    return ax.legend(artists, labels, fontsize=7.5, handler_map={tuple: HandlerTuple(ndivide=None, pad=0.6)},
                     borderaxespad=0.0 if not outside else 0.5, **where)


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
    (the same in every panel; one legend, which says which curves have no value in a panel); the
    pendulums' final phase error where they settled; the platform's natural frequencies as
    labelled ticks on the top axis."""
    names = [n for n in ("residual_amplitude", "settling_time", "phase_error") if n in ds]
    fig, axes = new_figure(len(names), 1, width=7.5, height=3.0, fig=fig, ax=ax)
    art = Drawn(figure=fig, axes=axes, lines={})
    x, xlab, scale = _x(ds)
    rest = [d for d in ds[names[0]].dims if d != "Omega"]
    members = list(np.ndindex(*(ds.sizes[d] for d in rest)))
    step = max(1, len(members) // 8)  # at most ~8 curves stay readable
    members = members[::step]
    settled = np.isfinite(ds["settling_time"]) if "settling_time" in ds else ds["status"] == 0

    def member_text(idx):
        return ", ".join(value_text(ds[d], ds[d].values[i]) for d, i in zip(rest, idx))

    handles, missing = {}, {}
    for r, name in enumerate(names):
        a = axes[r, 0]
        # the model keeps what it could compute at a flagged point (e.g. the residual where the
        # pendulums never settle); NaN marks what it could not, and is not drawn. The phase error is
        # drawn only where the pendulums settled: elsewhere it is the phase of a wandering pendulum.
        da = ds[name].where(settled) if name == "phase_error" else ds[name]
        for k, idx in enumerate(members):
            lab = member_text(idx) or name
            v = np.asarray(da.isel(dict(zip(rest, idx))).values, dtype=float)
            if not np.isfinite(v).any():
                missing.setdefault(lab, []).append(short_symbol(ds[name]) or name)
                continue
            (line,) = a.plot(x, v, lw=1.2, color=f"C{k % 10}", label=lab)
            art["lines"][(name, lab)] = line
            handles.setdefault(lab, line)
        v = np.asarray(da.values, dtype=float)
        pos = v[np.isfinite(v)]
        if name in ("residual_amplitude", "phase_error") and pos.size and pos.min() > 0:
            a.set_yscale("log")
        _frequency_ticks(a, ds, scale)
        a.set_xlabel(xlab)
        # the symbol and unit beside the axis, what it is above the panel: a short label beside
        # each of three stacked panels (the long names wrapped to four lines there)
        a.set_ylabel(label(ds[name], width=24, name=False))
        a.set_title(wrap(prose(ds[name].attrs.get("long_name", name))
                         + (" (drawn where the pendulums settled)" if name == "phase_error" else ""), 80),
                    fontsize=9, loc="left")
        a.set_xlim(x.min(), x.max())
        a.grid(True, alpha=0.3)
    if rest:
        order = [member_text(idx) for idx in members]
        shown = []
        for k, lab in enumerate(order):
            if lab not in handles:  # no value in any panel: a legend entry all the same, saying so
                handles[lab] = Line2D([], [], lw=1.2, color=f"C{k % 10}")
            note = f" (no {', '.join(missing[lab])}: never settles)" if lab in missing else ""
            shown.append((handles[lab], lab + note))
        art["legend"] = axes[0, 0].legend([h for h, _ in shown], [wrap(t, 34) for _, t in shown], fontsize=7,
                                          loc="upper left", bbox_to_anchor=(1.01, 1.0),
                                          title="one colour per curve, all panels", title_fontsize=7)
    bad = int((ds["status"].values != 0).sum())
    caption = _frequency_note(ds) or ""
    if bad:
        caption += ((". " if caption else "") + f"{bad} of {ds['status'].size} points flagged ({status_text(ds)}; "
                    "the status variable says why): each output is drawn wherever it has a value")
    title(fig, ds, "Residual vibration and settling of the pendulum auto-balancer", caption=caption or None)
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
    panels = ((HISTORIES[:2], 0.8, "platform displacement [m]"), (HISTORIES[2:], 0.9, "pendulum phase error [rad]"))
    for ax, (names, lw, text) in zip(axes[:, 0], panels):
        for name in names:
            if name in point:
                art[name], = ax.plot(t, point[name].values, lw=lw, color=f"C{HISTORIES.index(name)}",
                                     label=label(point[name], width=60))
        ax.set_ylabel(text)
        ax.legend(fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.set_xlim(t[0], t[-1])
    axes[1, 0].set_xlabel(label(point["revolution"]))
    where = ", ".join(value_text(point[d]) for d in ds.dims if d != "revolution" and d in point.coords)
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
