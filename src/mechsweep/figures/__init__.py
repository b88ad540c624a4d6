"""Figures read a stored Dataset and label themselves from its attributes; they never compute.

``available(ds)`` lists the figures a dataset can draw; ``save(ds, path)`` writes them.
"""
from __future__ import annotations

from pathlib import Path

from . import autobalancer, duffing, generic, linkage, torsional, workprecision

# (name, can_draw, draw), most specific first; draw(ds) -> matplotlib Figure
FIGURES = (
    ("workprecision", workprecision.can_workprecision, workprecision.workprecision),
    ("coefficients", torsional.can_coefficients, torsional.coefficients),
    ("truncation_error", torsional.can_truncation_error, torsional.truncation_error),
    ("amplitude_period", duffing.can_amplitude_period, duffing.amplitude_period),
    ("kinematic_coefficients", duffing.can_kinematic_coefficients, duffing.kinematic_coefficients),
    ("stability_chart", autobalancer.can_stability_chart, autobalancer.stability_chart),
    ("residual", autobalancer.can_residual, autobalancer.residual),
    ("time_history", autobalancer.can_time_history, autobalancer.time_history),
    ("moment_methods", linkage.can_moment_methods, linkage.moment_methods),
    ("balancing_map", linkage.can_balancing_map, linkage.balancing_map),
    ("slider_residual", linkage.can_slider_residual, linkage.slider_residual),
    ("pareto", linkage.can_pareto, linkage.pareto),
    ("stability_map", generic.can_stability_map, generic.stability_map),
)
FALLBACK = ("outputs", generic.can_outputs, generic.outputs)


def available(ds) -> dict[str, str]:
    """Figure kinds this dataset can draw, with one line saying what each shows."""
    kinds = {name: (draw.__doc__ or "").strip().splitlines()[0] for name, can, draw in FIGURES if can(ds)}
    if not kinds and FALLBACK[1](ds):
        kinds[FALLBACK[0]] = FALLBACK[2].__doc__.strip().splitlines()[0]
    return kinds


def draw(ds, kind: str):
    for name, can, fn in FIGURES + (FALLBACK,):
        if name == kind:
            if not can(ds):
                raise ValueError(f"figure {kind!r} does not fit this dataset")
            return fn(ds)
    raise ValueError(f"unknown figure {kind!r}")


def targets(ds, path, *, kind: str | None = None, fmt: str = "png") -> list[Path]:
    """The files ``save`` writes: ``path`` with the format's suffix for one figure, or
    ``<stem>_<kind>.<fmt>`` beside it for each of several."""
    chosen = [kind] if kind else list(available(ds))
    path = Path(path)
    return [path.with_suffix(f".{fmt}") if len(chosen) == 1 else path.with_name(f"{path.stem}_{k}.{fmt}")
            for k in chosen]


def save(ds, path, *, kind: str | None = None, fmt: str = "png", dpi: int = 150) -> list[Path]:
    """Write one figure (``kind``) or every figure that fits (``kind=None``).

    With several figures, each goes to ``<stem>_<kind>.<fmt>`` beside ``path``.
    """
    import matplotlib.pyplot as plt

    from ..errors import InputError

    kinds = available(ds)
    if kind is not None and kind not in kinds:
        raise InputError(f"figure {kind!r} does not fit this dataset; it can draw: "
                         f"{', '.join(kinds) or 'nothing'}")
    if not kinds:
        raise InputError("no figure fits this dataset (it needs one or two numeric axes)")
    written = []
    for k, out in zip([kind] if kind else list(kinds), targets(ds, path, kind=kind, fmt=fmt)):
        fig = draw(ds, k)
        fig.savefig(out, format=fmt, dpi=dpi)
        plt.close(fig)
        written.append(out)
    return written
