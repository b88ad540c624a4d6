"""The picture of docs/architecture.md: a run's data flow (left) and the layers of the package, whose
imports point down (right). Boxes and arrows only; nothing is computed.

    python docs/make_architecture_figure.py   # or: python docs/make_figures.py architecture

Writes docs/figures/architecture.png (recorded in docs/figures/MANIFEST.json by make_figures.py).
"""
from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "figures" / "architecture.png"

# colours by role: what the user writes, the run, the numerics, the datasets and what reads them
USER, RUN, NUMERICS, DATA, FRONT = "#fde9c9", "#d6e6f5", "#dcefd6", "#ece0f3", "#eeeeee"

# the data flow, top to bottom: (title, detail, colour)
FLOW = [
    ("scene TOML", "sweeps/*.toml, or a dict", USER),
    ("scene/", "load_scene: every key checked -> frozen Scene", USER),
    ("execution/plan.py", "make_plan -> Plan: outputs, measurements, method,\nroute, chunks, settings (stored in the dataset)", RUN),
    ("execution/execute.py", "evaluate_chunk per chunk: here (local_results)\nor on a dask worker (cluster.compute_chunk)", RUN),
    ("the model's evaluate", "ModelSpec.evaluate (OdeModel.spec, ClosedFormModel)", USER),
    ("engine/", "kernel_for: kernels composed from factories;\nbinding module -> numba's disk cache", NUMERICS),
    ("ode/", "method objects (methods.py): dop853, radau,\nsymplectic, auto; their solvers", NUMERICS),
]
SINKS = [
    ("store/ sinks", "journal (crash-safe, resumable), Early (the HDF5\nfile while chunks compute), MemorySink", DATA),
    ("dataset", "xarray Dataset / HDF5 (CF): outputs, status,\nn_steps, n_rhs; scene, plan, provenance", DATA),
    ("figures/  boundaries/  describe.py", "read the dataset (boundaries also evaluate\nnew points between grid values)", FRONT),
]

# the layers, top (imports the ones below) to bottom: (packages, what they own, colour)
LAYERS = [
    ("cli.py  commands/  bench/", "the command line; what a user measures", FRONT),
    ("figures/  boundaries/  describe.py  docs.py", "read datasets: nomograms, boundaries, words", FRONT),
    ("execution/", "plan, execute, runner, cluster, checks, stopping", RUN),
    ("store/", "write, assemble, read, journal", DATA),
    ("scene/", "TOML -> validated, frozen Scene", USER),
    ("engine/", "kernels composed from the declarations", NUMERICS),
    ("model/  models/", "the declarative layer; the built-in models' declarations", USER),
    ("ode/", "integrators and method objects", NUMERICS),
    ("_jit  status  errors  grid  cf  special", "numba options, status codes, exceptions", FRONT),
]


def _box(ax, x, y, w, h, title, detail, colour):
    ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.0,rounding_size=0.012",
                                facecolor=colour, edgecolor="#555555", linewidth=0.8))
    if detail:
        ax.text(x + 0.015, y + h - 0.012, title, ha="left", va="top", fontsize=9.5, fontweight="bold",
                family="monospace")
        ax.text(x + 0.015, y + h - 0.042, detail, ha="left", va="top", fontsize=8.2, linespacing=1.25)
    else:
        ax.text(x + w / 2, y + h / 2, title, ha="center", va="center", fontsize=9, family="monospace")


def _arrow(ax, start, end, style="-|>", dashed=False, colour="#333333", rad=0.0):
    ax.add_patch(FancyArrowPatch(start, end, arrowstyle=style, mutation_scale=11, linewidth=1.0, color=colour,
                                 linestyle="--" if dashed else "-", shrinkA=0, shrinkB=0,
                                 connectionstyle=f"arc3,rad={rad}"))


def _flow(ax):
    ax.set_title("A run's data flow", fontsize=11, loc="left")
    h, gap, x, w = 0.105, 0.030, 0.01, 0.50
    top = 0.985
    ys = [top - h - k * (h + gap) for k in range(len(FLOW))]
    for (title, detail, colour), y in zip(FLOW, ys):
        _box(ax, x, y, w, h, title, detail, colour)
    for y0, y1 in zip(ys, ys[1:]):
        _arrow(ax, (x + 0.10, y0), (x + 0.10, y1 + h))
    # the chunk's arrays come back up from the kernels to the run, then go to the sinks
    back = x + w + 0.025
    _arrow(ax, (x + w, ys[6] + h / 2), (back, ys[6] + h / 2), style="-", colour="#8a5a00")
    _arrow(ax, (back, ys[6] + h / 2), (back, ys[3] + h / 2), style="-", colour="#8a5a00")
    _arrow(ax, (back, ys[3] + h / 2), (x + w, ys[3] + h / 2), colour="#8a5a00")
    ax.text(back + 0.008, (ys[6] + ys[3] + h) / 2, "per chunk:\noutputs,\nstatus,\nn_steps,\nn_rhs",
            fontsize=7.6, color="#8a5a00", va="center", ha="left")
    sx, sw = 0.63, 0.365
    step = 1.25 * (h + gap)
    sy = [ys[3] + 0.6 * step, ys[3] - 0.6 * step, ys[3] - 1.8 * step]
    for (title, detail, colour), y in zip(SINKS, sy):
        _box(ax, sx, y, sw, h, title, detail, colour)
    _arrow(ax, (x + w, ys[3] + h * 0.8), (sx, sy[0] + h / 2))
    _arrow(ax, (sx + 0.10, sy[0]), (sx + 0.10, sy[1] + h))
    _arrow(ax, (sx + 0.10, sy[1]), (sx + 0.10, sy[2] + h))
    ax.text(sx + 0.11, (sy[0] + sy[1] + h) / 2, "assembled (one rename)\nor kept in memory", fontsize=7.6,
            va="center", ha="left")


def _layers(ax):
    ax.set_title("Layers: a package imports its own layer and those below", fontsize=11, loc="left")
    h, gap, x, w = 0.080, 0.025, 0.04, 0.80
    top = 0.985
    ys = [top - h - k * (h + gap) for k in range(len(LAYERS))]
    for (title, detail, colour), y in zip(LAYERS, ys):
        _box(ax, x, y, w, h, title, detail, colour)
    _arrow(ax, (0.92, ys[0] + h), (0.92, ys[-1]), style="-|>")
    ax.text(0.945, (ys[0] + ys[-1] + h) / 2, "imports point down", rotation=-90, va="center", ha="center",
            fontsize=9)
    # the model layer's calls into the engine, made inside functions when a kernel is wanted
    ym, ye = ys[6], ys[5]
    _arrow(ax, (x + w - 0.05, ym + h), (x + w - 0.05, ye), dashed=True, colour="#2f6f2f")
    ax.text(x + w - 0.06, (ym + h + ye) / 2, "a model's evaluate asks the engine for its kernel", fontsize=7.6,
            color="#2f6f2f", ha="right", va="center")


def draw() -> Figure:
    fig = Figure(figsize=(14.0, 8.0), layout="constrained")
    left, right = fig.subplots(1, 2, width_ratios=[1.45, 1.0])
    for ax in (left, right):
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_axis_off()
    _flow(left)
    _layers(right)
    return fig


def main() -> Path:
    draw().savefig(OUT, dpi=100, metadata={"Software": None})
    return OUT


if __name__ == "__main__":
    print(main().relative_to(ROOT))
