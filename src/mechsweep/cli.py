"""Command line: ``mechsweep run | plot | info | bench``. Thin: parsing and messages only."""
from __future__ import annotations

import argparse
import errno
import gc
import math
import os
import signal
import sys
import warnings
from contextlib import contextmanager
from pathlib import Path

EXIT_INVALID = 2

DESCRIPTION = """\
Parameter sweeps over the dynamics of machine mechanisms, compiled with numba.

A study is a scene: a TOML file naming a model, the axes of a grid, the fixed
parameters, the outputs wanted and (for integrated outputs) the solver settings.
`run` computes it on all cores into an HDF5 file (an xarray Dataset), `plot` draws
its nomogram, `info` summarises a stored run.

typical session:
  mechsweep run sweeps/quickstart.toml             # -> data/runs/quickstart.h5
  mechsweep plot data/runs/quickstart.h5           # -> data/runs/quickstart_<figure>.png
  mechsweep info data/runs/quickstart.h5
  mechsweep models                                 # every model, parameter and output
  mechsweep models my_models.py:NAME               # a model of your own (see `models --help`)

exit codes: 0 done, 1 unexpected error, 2 invalid input (nothing written) or a failed write
(disk full: the journal is kept for --resume), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM)
"""

MODELS_EPILOG = """\
Lists the built-in models, then the models installed packages register (entry-point group
mechsweep.models), with their parameters and outputs. A user model comes in by one of four doors:
  model = "my_models.py:NAME"       in a scene: a file path relative to the scene file
  model = "mypkg.models:NAME"       in a scene: an importable module
  model = "NAME"                    registered by an installed package, in its pyproject.toml:
                                      [project.entry-points."mechsweep.models"]
                                      NAME = "mypkg.models:NAME"
  mechsweep.run(scene, models={"NAME": my_ode_model})   from Python (runs locally only)
`mechsweep models my_models.py:NAME` or `mechsweep models --scene S.toml` shows one user model;
`mechsweep models my_models.py` every model the file defines, with the names a scene uses.
Loading a model file or module executes it: only name code you trust. A model that fails to
load is reported with its file and line (exit 2).

examples:
  mechsweep models
  mechsweep models duffing
  mechsweep models --scene sweeps/vibrating_pendulum_stability.toml
"""

PLOT_DESCRIPTION = """\
Draw the figures that fit a dataset's model and dimensions (the nomograms of a built-in model,
generic maps and curves for any other). Plots read the stored data only; they never compute.

Where the figures go (NAME: the dataset's file name without .h5):
  no -o            beside DATASET: NAME.png for one figure, NAME_<figure>.png for each of
                   several (with --point: NAME_at_<point>... so they never replace those)
  -o FIGURE.png    that file for one figure; for several, FIGURE_<figure>.png beside it
                   (the suffix chooses the format: png, svg or pdf)
  -o FOLDER        an existing folder: each figure under its default name inside it
`--list` names the figures a dataset can draw, `--kind` draws one of them.

examples:
  mechsweep plot data/runs/quickstart.h5
  mechsweep plot data/runs/quickstart.h5 -o /tmp/quickstart.svg
  mechsweep plot data/runs/quickstart.h5 --list
  mechsweep plot data/runs/autobalancer_residual.h5 --point Omega=55,A0=0.1
"""

INFO_DESCRIPTION = """\
Summarise a dataset written by `mechsweep run` (or `mechsweep boundaries`): its dimensions and
fixed values, each output's unit and range, how many grid points ended with each status, the cost
(steps, wall and compile time), the solver settings and the provenance (creation time, versions).
An unfinished run (PATH.partial/) is summarised as far as it got. Reads the file only.

examples:
  mechsweep info data/runs/quickstart.h5
  mechsweep info data/runs/autobalancer_stability_chart.boundaries.h5
"""

CHECK_DESCRIPTION = """\
Load and validate each scene file as `mechsweep run` would (model, axes, fixed values, outputs,
solver, storage, boundaries), without computing anything or touching a file. Prints one line per
valid scene (model, number of grid points, outputs) and every problem of an invalid one with its
key, the bad value and what is allowed; exit 2 if any scene is invalid.

examples:
  mechsweep check sweeps/quickstart.toml
  mechsweep check sweeps/*.toml
"""

BOUNDARIES_DESCRIPTION = """\
Locate where a criterion crosses its level (or the status changes) along one axis, for every
combination of the other axes: bracketed on the scene's grid (computed first, or completed,
unless its dataset is finished), refined to [boundaries] rtol. Writes NAME.boundaries.h5 beside
the grid's dataset NAME.h5 (atomically; the dataset is only read); `mechsweep plot NAME.h5` draws
them over the charts. See docs/boundaries.md.

examples:
  mechsweep boundaries sweeps/autobalancer_stability_chart.toml
  mechsweep boundaries sweeps/autobalancer_stability_chart.toml --data /tmp/chart.h5 -o /tmp/b.h5
"""

EXAMPLES_DESCRIPTION = """\
Copy the example scenes that ship with mechsweep into DIR/sweeps/ (every study of the
documentation, and the user model they name, sweeps/models/vibrating_pendulum.py), with an empty
DIR/data/runs/ for the datasets they write: what a pip-installed mechsweep needs to run the
quickstart without a clone of the repository. DIR is made if missing; an existing file is never
replaced (nothing is copied then).

example:
  mechsweep examples my-study && cd my-study
  mechsweep run sweeps/quickstart.toml && mechsweep plot data/runs/quickstart.h5
"""

BENCH_DESCRIPTION = """\
Benchmarks print measured numbers of this machine, with ratios against the alternatives measured
in the same run. `mechsweep bench BENCH --help` describes each.

examples:
  mechsweep bench duffing --points 20000
  mechsweep bench workprecision duffing
"""

RUN_EPILOG = """\
The grid is cut into chunks; each finished chunk is saved at once to the journal PATH.partial/
(a kill leaves every chunk file whole or absent). When every chunk is in, the dataset is
assembled and renamed to PATH, so an existing PATH is never left half overwritten. If the run is
interrupted (Ctrl-C, kill, power cut), `--resume` computes only the missing chunks; the result is
identical to an uninterrupted run. A second run on the same PATH is refused while one is writing.
SIGTERM stops a run like Ctrl-C (exit 143). A failed write (disk full, ulimit -f, quota, I/O error)
ends it with a message and exit 2, the journal kept for --resume; a damaged chunk file in the
journal is removed and computed again.
An existing PATH is replaced by a run of the same scene; a dataset of a different scene, or a file
mechsweep did not write, is kept and the run refused unless --overwrite. PATH, its lock
.PATH.lock and its journal must be regular files and folders (not pipes, sockets or devices).

With --scheduler (or [execution] scheduler in the scene) the chunks run as tasks on a
dask.distributed cluster (pip install "mechsweep[distributed]"); this process still writes the
file, and the result is the same as a local run, bit for bit.

examples:
  mechsweep run sweeps/duffing_amplitude_period.toml
  mechsweep run sweeps/duffing_amplitude_period.toml -o /tmp/ap.h5 --threads 1
  mechsweep run sweeps/duffing_amplitude_period.toml --resume
  mechsweep run sweeps/duffing_amplitude_period.toml --scheduler tcp://10.0.0.5:8786
"""


_START_UP = {"collector": False}  # True while main holds Python's cyclic garbage collector off (see _started)


def main(argv: list[str] | None = None) -> int:
    quick = argv is None and len(sys.argv) > 1 and sys.argv[1] in ("run", "plot") and gc.isenabled()
    if quick:  # the command's process: no full collections during its start-up (see _started)
        gc.disable()
        _START_UP["collector"] = True
    try:
        return _main(argv)
    finally:
        if quick and _START_UP["collector"]:
            _START_UP["collector"] = False
            gc.enable()


def _started() -> None:
    """The start-up of a `run` or `plot` process is over (imports, scene or dataset): the objects made so
    far are frozen (``gc.freeze``: never traversed by a collection again) and the collector is turned
    back on for the command's work. During the start-up it is off (``main``, only for the command's own
    process, ``argv`` None: a caller of ``main`` in a process of its own keeps its collector as it is).
    The imports (numpy, numba, xarray, matplotlib, the package) make hundreds of thousands of objects that
    live as long as the process, and each full collection traversed all of them (measured with
    ``python benchmarks/startup.py --only warmstart``: docs/performance-startup.md). A forked figure process
    (:func:`_side_by_side`) then also leaves the frozen objects' memory shared with its parent."""
    if _START_UP["collector"]:
        _START_UP["collector"] = False
        gc.freeze()
        gc.enable()


def _main(argv: list[str] | None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_INVALID
    from .errors import MechsweepError, RunInterrupted

    import threading

    main_thread = threading.current_thread() is threading.main_thread()  # only it may set handlers
    previous = signal.signal(signal.SIGTERM, _terminate) if main_thread else None  # SIGTERM stops like Ctrl-C
    from . import cf

    cli_args = cf.CLI_ARGS.set(tuple(sys.argv[1:] if argv is None else argv))
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning(args.command, warnings.showwarning)
            return args.func(args)
    except RunInterrupted as exc:  # the journal is kept: the message says how to resume
        print(f"mechsweep {args.command}: {exc}", file=sys.stderr)
        return 128 + exc.signum
    except (MechsweepError, FileNotFoundError) as exc:
        # bad input (InputError) and a run that failed on the way (RunError: disk full, lost cluster) both
        # exit 2 with one line, as the exit codes above say; a bug (any other exception) exits 1 with its traceback.
        # A FileNotFoundError of the system (with an errno) is said as the others are; mechsweep's own say it all
        text = os_error_text(exc) if isinstance(exc, FileNotFoundError) and exc.errno is not None else exc
        print(f"mechsweep {args.command}: error: {text}", file=sys.stderr)
        return EXIT_INVALID
    except KeyboardInterrupt as exc:
        signum = exc.signum if isinstance(exc, _Terminated) else signal.SIGINT
        print(f"mechsweep {args.command}: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
        return 128 + signum
    except BrokenPipeError:  # `mechsweep models | head`: the reader left, nothing is wrong
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return 0
    except OSError as exc:  # a read or write the system refused: its cause and the file, in one line
        print(f"mechsweep {args.command}: error: {os_error_text(exc)}", file=sys.stderr)
        return EXIT_INVALID
    finally:
        cf.CLI_ARGS.reset(cli_args)
        if main_thread:
            signal.signal(signal.SIGTERM, previous if previous is not None else signal.SIG_DFL)


def _show_warning(command, default):
    """A user model's warning, or one on the scene's settings, as one line on stderr (no source line of
    mechsweep's); others as usual."""
    from .errors import SettingsWarning, UserModelWarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, (UserModelWarning, SettingsWarning)):
            print(f"mechsweep {command}: warning: {message}", file=sys.stderr)
        else:
            default(message, category, filename, lineno, file, line)
    return show


class _Terminated(KeyboardInterrupt):
    signum = signal.SIGTERM


def _terminate(signum, frame):
    raise _Terminated


def _parser() -> argparse.ArgumentParser:
    fmt = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(prog="mechsweep", description=DESCRIPTION, formatter_class=fmt)
    from . import __version__

    parser.add_argument("--version", action="version", version=f"mechsweep {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("run", help="compute a scene's grid into an HDF5 dataset", description=RUN_EPILOG,
                       formatter_class=fmt)
    p.add_argument("scene", metavar="SCENE", help="scene TOML file, e.g. sweeps/quickstart.toml")
    p.add_argument("-o", "--output", metavar="PATH", help="output file (default: [storage] path of the scene)")
    p.add_argument("--resume", action="store_true", help="complete an interrupted run of the same scene")
    p.add_argument("--restart", action="store_true", help="discard an unfinished run and start over")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing PATH that holds a run of a different scene, or a file mechsweep "
                        "did not write (refused without it; re-running the same scene needs no flag)")
    p.add_argument("--threads", type=int, metavar="N",
                   help="numba threads (default: all cores); with --scheduler, per dask worker")
    p.add_argument("--no-progress", action="store_true", help="do not show the progress bar")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the chunks on this dask.distributed scheduler, e.g. tcp://10.0.0.5:8786 "
                        "(default: the scene's [execution] scheduler, else local threads)")
    p.add_argument("--worker-timeout", type=float, metavar="SECONDS",
                   help="with --scheduler: stop (journal kept) when the scheduler is lost or has no worker "
                        "for this long (default: the scene's [execution] worker_timeout, else 120)")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("plot", help="draw the nomograms of a stored dataset", description=PLOT_DESCRIPTION,
                       formatter_class=fmt)
    p.add_argument("dataset", metavar="DATASET", help="HDF5 file written by `mechsweep run`")
    p.add_argument("-o", "--output", metavar="FIGURE",
                   help="the figure file (for several figures: their common stem, FIGURE_<figure>.png beside it), "
                        "or an existing folder (default: beside DATASET; see above)")
    p.add_argument("--format", choices=("png", "svg", "pdf"), default=None, help="figure format (default png)")
    p.add_argument("--kind", default=None, help="which figure, when a dataset has several (see --list)")
    p.add_argument("--list", action="store_true", help="list the figures this dataset can draw (those drawn by default, then generic ones drawn only with --kind)")
    p.add_argument("--point", metavar="KEY=VALUE,...",
                   help="select one grid point (nearest values), e.g. --point Omega=12.5,m=0.2; "
                        "draws its time histories when the dataset stores them")
    p.add_argument("--boundaries", metavar="PATH",
                   help="located boundaries (`mechsweep boundaries`) to draw over the charts that show them: "
                        "stability maps and heatmaps with the axis they were located along (refused when no "
                        "figure drawn shows them; default: DATASET.boundaries.h5 beside the dataset, when it "
                        "exists)")
    p.add_argument("--no-boundaries", action="store_true", help="draw the charts without located boundaries")
    p.add_argument("--x", metavar="AXIS", help="draw the generic figures (stability map, heatmap, nomogram) with AXIS "
                   "across; only the outputs over it (default: the figures' own choice, see --list)")
    p.add_argument("--y", metavar="AXIS", help="with the generic figures: AXIS up the stability map or heatmap, "
                   "and one curve per value of AXIS in the nomogram (a list axis gives curves only)")
    p.set_defaults(func=_cmd_plot)

    p = sub.add_parser("info", help="summarise a stored dataset: dims, outputs, status counts, cost, provenance",
                       description=INFO_DESCRIPTION, formatter_class=fmt)
    p.add_argument("dataset", metavar="DATASET", help="HDF5 file written by `mechsweep run` or `mechsweep boundaries`")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("models", help="list models with their parameters and outputs (name, unit, range)",
                       description=MODELS_EPILOG, formatter_class=fmt)
    p.add_argument("model", nargs="?", help="one model only: a built-in or registered name, 'file.py:NAME' "
                   "(relative to the current directory) or 'package.module:NAME'; a bare 'file.py': "
                   "the models that file defines")
    p.add_argument("--scene", metavar="SCENE", help="the model the scene file SCENE names (a user model "
                   "file is found relative to the scene)")
    p.add_argument("--markdown", action="store_true", help="print the glossary page of the documentation "
                   "(built-in models and status codes), or one model's tables; `python -m mechsweep.docs "
                   "docs/glossary.md` rewrites it in place")
    p.set_defaults(func=_cmd_models)

    p = sub.add_parser("boundaries", help="locate the boundaries a scene's [boundaries] section asks for",
                       formatter_class=fmt, description=BOUNDARIES_DESCRIPTION)
    p.add_argument("scene", metavar="SCENE", help="scene TOML file with a [boundaries] section")
    p.add_argument("-o", "--output", metavar="PATH", help="output file (default: NAME.boundaries.h5 beside the dataset NAME.h5)")
    p.add_argument("--data", metavar="DATA", help="the grid's dataset (default: [storage] path of the scene)")
    p.add_argument("--threads", type=int, metavar="N", help="numba threads (default: all cores)")
    p.add_argument("--no-progress", action="store_true", help="do not show the progress bar of the grid")
    p.set_defaults(func=_cmd_boundaries)

    p = sub.add_parser("check", help="validate scene files without running them", description=CHECK_DESCRIPTION,
                       formatter_class=fmt)
    p.add_argument("scenes", nargs="+", metavar="SCENE", help="scene TOML files")
    p.set_defaults(func=_cmd_check)

    p = sub.add_parser("examples", help="copy the shipped example scenes into a folder, to run them there",
                       description=EXAMPLES_DESCRIPTION, formatter_class=fmt)
    p.add_argument("folder", metavar="DIR", help="the folder to copy them into (made if missing)")
    p.set_defaults(func=_cmd_examples)

    p = sub.add_parser("bench", help="benchmarks: speed and accuracy against scipy / numpy, measured now",
                       formatter_class=fmt, description=BENCH_DESCRIPTION)
    bsub = p.add_subparsers(dest="bench", metavar="BENCH")
    from .bench import commands as bench_commands

    bench_commands.add_parsers(bsub, fmt)
    p.set_defaults(func=lambda a: (p.print_help(), EXIT_INVALID)[1])
    return parser


def _cmd_run(args) -> int:
    from .runner import RunInterrupted, compute
    from .scene import load_scene

    scene = load_scene(args.scene)
    _started()
    try:  # the dataset is not opened: its status counts were added up as its chunks were assembled
        summary = compute(scene, output=args.output, resume=args.resume, restart=args.restart,
                          threads=args.threads, progress=False if args.no_progress else None,
                          scheduler=args.scheduler, worker_timeout=args.worker_timeout,
                          overwrite=args.overwrite)
    except RunInterrupted as exc:
        print(f"mechsweep run: {exc}", file=sys.stderr)
        return 128 + exc.signum
    print(f"wrote {summary.path.resolve()}: {summary.sizes}, outputs {', '.join(scene.outputs)}; "
          f"status {summary.status_names()}; wall time {summary.wall_time_s:.2f} s "
          f"(compile {summary.compile_time_s:.2f} s, compute {summary.compute_time_s:.2f} s)")
    return 0


def _cmd_boundaries(args) -> int:
    from .boundaries import BAND_EDGE, BOUND_MEANINGS, run_boundaries, warnings_for
    from .scene import load_scene

    scene = load_scene(args.scene)
    for text in warnings_for(scene):
        print(f"mechsweep boundaries: warning: {text}", file=sys.stderr)
    path, ds = run_boundaries(scene, data=args.data, output=args.output, threads=args.threads,
                              progress=False if args.no_progress else None, warn=False)
    bound = ds["boundary_bound"].values
    counts = {BOUND_MEANINGS[c]: int((bound == c).sum()) for c in sorted(BOUND_MEANINGS) if (bound == c).any()}
    print(f"wrote {path}: {ds.attrs['located']} boundaries located along {ds.attrs['along']} ({counts}); "
          f"{ds.attrs['evaluations_per_point_mean']:.1f} evaluations per point (max "
          f"{ds.attrs['evaluations_per_point_max']}) in {ds.attrs['evaluate_calls']} calls, "
          f"{ds.attrs['wall_time_s']:.2f} s")
    if "curve_stop" in ds:
        stops = ds["curve_stop"].values
        print(f"  continued in {ds.attrs['continue_in']}: {int((stops >= 0).sum())} curve(s), "
              f"{int((ds['fold_axis'].values >= 0).sum())} fold(s), {ds.attrs['continuation_evaluated_points']:,} points "
              f"in {ds.attrs['continuation_calls']:,} calls, {ds.attrs['continuation_wall_time_s']:.2f} s")
        if (edges := int((bound == BAND_EDGE).sum())):
            print(f"  {edges} band edge(s) not continued: the criterion stays at its level on one side (a neutral "
                  "stretch), so there is no crossing to follow; a little damping makes it cross (docs/boundaries.md)")
    return 0


@contextmanager
def _no_dask_probe():
    """While the body runs, xarray takes dask to be absent unless ``dask.array`` is already imported.

    xarray asks, for every variable it makes (``ds.a == 0``, ``where``, ...), whether the data is a
    dask array, and to find out imports ``dask.array`` when dask is installed (with it scipy.fft:
    0.4-1.0 s of a warm ``mechsweep plot``, more than drawing one figure). ``plot`` opens its
    datasets loaded into memory (``open_dataset``'s default, numpy arrays), so no dask array can
    occur in it. The answer is put into xarray's cache of such probes for the body only and taken
    out again afterwards (a caller of ``main`` in the same process, e.g. a test that later opens a
    dataset lazily, gets xarray's own probe). When xarray's internals differ, nothing is done.

    The same for xarray's other question, whether an array is a dask collection (asked of every
    index it makes, e.g. when it opens a dataset): it imports ``dask.base`` to answer when dask is
    installed (most of the plot's opening of the quickstart's dataset). While the body runs, the answer is no without that import as long as
    dask is not imported (no object can be a dask collection then), else xarray's own."""
    seeded = False
    collection = None
    try:
        if "dask.array" not in sys.modules:
            from xarray.namedarray import pycompat

            cache = pycompat._cached_duck_array_modules
            if "dask" not in cache:
                absent = object.__new__(pycompat.DuckArrayModule)
                absent.module, absent.version, absent.type, absent.available = None, pycompat.Version("0.0.0"), (), False
                cache["dask"] = absent
                seeded = True
    except (ImportError, AttributeError, TypeError):
        pass
    try:
        if "dask" not in sys.modules:
            from xarray.namedarray import utils as xr_utils

            collection = xr_utils.is_dask_collection

            def is_dask_collection(x, own=collection):
                return "dask" in sys.modules and own(x)

            xr_utils.is_dask_collection = is_dask_collection
    except (ImportError, AttributeError):
        collection = None
    try:
        yield
    finally:
        if seeded:
            cache.pop("dask", None)
        if collection is not None:
            xr_utils.is_dask_collection = collection


def _cmd_plot(args) -> int:
    with _no_dask_probe():
        return _plot(args)


def _plot(args) -> int:
    from . import figures
    from .errors import InputError
    from .store import open_dataset

    ds = open_dataset(args.dataset)
    bds = _boundaries_for(ds, args)
    _started()
    with _laid_out(args.dataset):
        check_layout(ds)
        if args.point:
            ds = select_point(ds, args.point)
        axes = (args.x, args.y) if args.x or args.y else None
        kinds = figures.available(ds, axes)
        extra = figures.on_request(ds, axes) if args.list else {}
    if args.point and not kinds and not extra and args.kind is None and not args.list:
        raise InputError(f"--point {args.point}: nothing to draw at one point: its figures are time histories (outputs "
                         "with one extra dimension, e.g. a History measurement) and this dataset stores none; its "
                         "values at the point: mechsweep info, or xarray's ds.sel(...)")
    if args.list:
        for k, doc in kinds.items():
            print(f"{k}: {doc}")
        for k, doc in extra.items():
            print(f"{k} (on request: --kind {k}): {doc}")
        return 0
    if bds is not None and args.boundaries:
        _check_boundaries_drawn(ds, bds, args, [args.kind] if args.kind else list(kinds), axes)
    # -o naming an existing folder: the figures go into it under their default names (a folder named
    # like a figure file, x.png, is taken as a figure path and refused below: not a regular file)
    folder = None
    if args.output and os.path.isdir(args.output) and Path(args.output).suffix.lower() not in (".png", ".svg", ".pdf"):
        folder = Path(args.output)
    elif args.output and args.output.endswith(("/", os.sep)):
        raise InputError(f"-o {args.output}: the folder does not exist; create it first (mkdir -p {args.output}) "
                         "or give a figure file such as figure.png")
    fmt = args.format or (Path(args.output).suffix.lstrip(".") if args.output and folder is None else "png")
    if fmt not in ("png", "svg", "pdf"):
        raise InputError(f"figure format {fmt!r} (the suffix of -o {args.output}) is not allowed; expected png, svg "
                         "or pdf (or -o an existing folder)" if args.output and not args.format else
                         f"figure format {fmt!r} is not allowed; expected png, svg or pdf")
    # a one-point figure has names of its own (never those of the full grid's figures): STEM_at_<point>
    stem = Path(args.dataset).stem + (f"_at_{point_slug(ds)}" if args.point else "")
    if args.output and folder is None:
        out = Path(args.output)
    else:
        out = (folder if folder is not None else Path(args.dataset).parent) / f"{stem}.{fmt}"
    for target in figures.targets(ds, out, kind=args.kind, fmt=fmt, axes=axes):
        _check_figure_path(target, Path(args.dataset))
    with _drawing(args.dataset), _writing_figures(out):
        kinds = list(figures.available(ds, axes)) if args.kind is None else []
        if len(kinds) > 1 and _can_fork():  # several figures: side by side on the cores (the same files)
            written = figures.targets(ds, out, fmt=fmt, axes=axes)
            _side_by_side([lambda k=k, path=path: figures.save(ds, path, kind=k, fmt=fmt, boundaries=bds, axes=axes)
                           for k, path in zip(kinds, written)])
        else:
            written = figures.save(ds, out, kind=args.kind, fmt=fmt, boundaries=bds, axes=axes)
    for path in written:
        print(f"wrote {path}")
    return 0


def _can_fork() -> bool:
    """Whether `plot` may draw its figures in forked processes: Linux (elsewhere, e.g. macOS, a fork
    without exec is unsafe once some system libraries are loaded), more than one core for this process,
    and no other Python thread (a thread holding a lock at the fork would leave it held in the child: the
    command's process has none; a notebook or a test runner calling ``main`` may)."""
    import threading

    if not sys.platform.startswith("linux") or not hasattr(os, "fork") or threading.active_count() != 1:
        return False
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return cores > 1


def _side_by_side(jobs) -> None:
    """Run ``jobs`` (callables) at the same time: every one but the first in a forked child, the first
    here; return when all have finished. A job that raised has its exception raised here (the first
    in the jobs' order), after the others have finished (no figure file is left half written by a
    sibling's error). When this process is interrupted (Ctrl-C, SIGTERM), the children are stopped
    (SIGTERM) and reaped before the interruption goes on. What matplotlib spends on a figure (its
    layout, tick labels, rendering, PNG) is Python in one process: two figures on two cores take the
    time of the longer one instead of the sum."""
    import pickle

    children = []
    try:
        for job in jobs[1:]:
            read, write = os.pipe()
            pid = os.fork()
            if pid == 0:  # the child: do the job, send back what it raised, leave without cleaning up
                code = 0
                try:
                    os.close(read)
                    job()
                except BaseException as exc:  # noqa: BLE001 (sent to the parent, raised there)
                    code = 1
                    try:
                        try:
                            data = pickle.dumps(exc)
                        except Exception:  # an exception that cannot be pickled: its type and text
                            data = pickle.dumps(RuntimeError(f"{type(exc).__name__}: {exc}"))
                        with os.fdopen(write, "wb") as f:
                            f.write(data)
                    except BaseException:  # noqa: BLE001
                        pass
                finally:
                    os._exit(code)  # no atexit handlers, no flush of the parent's buffers
            os.close(write)
            children.append((pid, read))
        raised = None
        try:
            jobs[0]()
        except Exception as exc:  # the children finish first (below), then this is raised
            raised = exc
        while children:
            pid, read = children[0]
            with os.fdopen(read, "rb") as f:
                data = f.read()
            _, status = os.waitpid(pid, 0)
            children.pop(0)
            if raised is None and data:
                raised = pickle.loads(data)
            elif raised is None and status != 0:
                raised = RuntimeError(f"drawing a figure in process {pid} failed (wait status {status})")
        if raised is not None:
            raise raised
    finally:
        for pid, read in children:  # interrupted: stop the others
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            os.waitpid(pid, 0)
            try:
                os.close(read)
            except OSError:
                pass


def _boundaries_for(ds, args):
    """The located boundaries to draw over a run's charts: --boundaries PATH (refused, exit 2, when
    they were not located on this dataset's grid), else DATASET.boundaries.h5 when it exists (left
    out with a note when it does not fit), else None."""
    from . import figures
    from .errors import InputError
    from .store import is_run_dataset, open_dataset

    if args.no_boundaries or not is_run_dataset(ds):
        if args.boundaries and args.no_boundaries:
            raise InputError("give either --boundaries PATH or --no-boundaries, not both")
        return None
    path = Path(args.boundaries) if args.boundaries else figures.sibling_boundaries(args.dataset)
    if path is None:
        return None
    bds = open_dataset(path)
    why = figures.boundaries_mismatch(ds, bds)
    if why is None:
        return bds
    if args.boundaries:
        raise InputError(f"--boundaries {path}: not located on the grid of {args.dataset}: {why}")
    print(f"note: {path} not drawn: {why}", file=sys.stderr)
    return None


def _check_boundaries_drawn(ds, bds, args, drawing, axes) -> None:
    """--boundaries PATH is drawn by some of the figures ``drawing`` (refused, exit 2, when by none:
    naming the figures of this dataset that draw them, or saying which would); a note names the
    figures drawn without them (a nomogram, a curve: an output against one axis)."""
    from . import figures
    from .errors import InputError

    can = figures.boundary_figures(ds, bds, axes)
    drawn = [k for k in drawing if k in can]
    along = bds.attrs.get("along")
    if not drawn:
        what = ", ".join(drawing) or "none"
        if can:
            raise InputError(f"--boundaries {args.boundaries}: none of the figures drawn ({what}) draws located "
                             f"boundaries; the figures of this dataset that do: {', '.join(can)} (--kind NAME)")
        raise InputError(f"--boundaries {args.boundaries}: no figure of this dataset draws them (figures drawn: "
                         f"{what}): a stability map or heatmap with {along!r} as one of its two axes does (--x, "
                         "--y choose a heatmap's axes); a nomogram or curve has no place for them")
    left = [k for k in drawing if k not in can]
    if left:
        print(f"note: --boundaries {args.boundaries}: drawn on {', '.join(drawn)}; not on {', '.join(left)} "
              f"(only a stability map or heatmap with {along!r} as one of its axes draws them)", file=sys.stderr)


@contextmanager
def _writing_figures(out: Path):
    """An OSError while the figures are written (the dataset is in memory by then: ``plot`` loads it)
    is the figure file's: say which file and why, with what to do."""
    from .errors import InputError

    try:
        yield
    except OSError as exc:
        raise InputError(os_error_text(exc, out, writing="the figure")) from None


def _check_figure_path(target: Path, dataset: Path) -> None:
    """Refuse a figure path that would overwrite the dataset it is drawn from, another HDF5 file,
    or something that is not a regular file, or whose folder is missing or not writable."""
    from .errors import InputError

    folder = target.parent
    if not folder.is_dir():
        if not os.path.lexists(folder):
            raise InputError(f"figure path {target}: the folder {folder} does not exist; create it first "
                             f"(mkdir -p {folder}) or give another path with -o")
        raise InputError(f"figure path {target}: {folder} is {_entry_kind(folder)}, not a folder; give another path "
                         "with -o")
    if not (os.access(folder, os.W_OK) and folder.stat().st_mode & 0o222):
        raise InputError(f"figure path {target}: cannot write into {folder} (permission denied); give another path "
                         "with -o")
    if not os.path.lexists(target):
        return
    if os.path.exists(target) and os.path.samefile(target, dataset):
        raise InputError(f"figure path {target} is the dataset {dataset} itself; drawing would overwrite it: "
                         "give another figure path with -o")
    if not target.is_file():
        raise InputError(f"figure path {target} exists and is not a regular file; give another path with -o")
    try:
        with open(target, "rb") as f:
            head = f.read(8)
    except OSError as exc:
        raise InputError(f"figure path {target} exists and cannot be read ({_why(exc)}), so it is not known what "
                         "drawing would overwrite; give another path with -o") from None
    if head == b"\x89HDF\r\n\x1a\n":
        raise InputError(f"figure path {target} is an HDF5 file (a dataset?); drawing would overwrite it: "
                         "give another figure path with -o")


# errnos with which the system refuses a read or write (not a fault in a file's bytes)
_SYSTEM_ERRNOS = frozenset(getattr(errno, n) for n in (
    "ENOENT", "EACCES", "EPERM", "EROFS", "EISDIR", "ENOTDIR", "ELOOP", "ENOSPC", "EDQUOT", "EFBIG", "EMFILE",
    "ENFILE", "ENAMETOOLONG", "EXDEV", "EAGAIN") if hasattr(errno, n))

# what to do about a refused write, by errno ({folder}: the file's folder)
_WRITE_ADVICE = {
    "ENOENT": "the folder {folder} does not exist (or was removed); create it (mkdir -p {folder}) or give another "
              "path with -o",
    "EACCES": "give another path with -o, or make {folder} writable",
    "EPERM": "give another path with -o",
    "EROFS": "its file system is mounted read-only; give a path elsewhere with -o",
    "ENOSPC": "its disk is full (of space, or of inodes); free some or give a path elsewhere with -o",
    "EDQUOT": "your disk quota there is used up; free some or give a path elsewhere with -o",
    "EFBIG": "it would exceed the file size limit (ulimit -f); raise it or draw fewer or smaller figures",
    "EISDIR": "a directory has that name; give a figure file name with -o",
    "ENOTDIR": "a part of the path is a file, not a folder; give another path with -o",
    "ENAMETOOLONG": "give a shorter path with -o",
}


def _why(exc: OSError) -> str:
    from .errors import why_os_error

    return why_os_error(exc.errno, exc.strerror or str(exc))


def _entry_kind(path) -> str:
    from .store import file_kind

    try:
        return file_kind(os.stat(path).st_mode)
    except OSError:
        return "a broken link"


def os_error_text(exc: OSError, path=None, writing: str = "") -> str:
    """One line for an OSError: the file it names (else ``path``), its cause by errno, and, for a
    write (``writing``: what was being written), what to do."""
    name = exc.filename if exc.filename is not None else path
    where = f"{name}: " if name is not None else ""
    if not writing:
        return f"{where}{_why(exc)}"
    code = errno.errorcode.get(exc.errno or 0, "")
    folder = Path(str(name)).parent if name is not None else Path(".")
    advice = _WRITE_ADVICE.get(code, "give another path with -o").format(folder=folder)
    return f"cannot write {writing} {name}: {_why(exc)}; {advice}"


def select_point(ds, text: str):
    """The sub-dataset at one grid point, from 'key=value,...' (nearest grid values)."""
    from .errors import InputError

    wanted = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in ds.dims:
            raise InputError(f"--point: {item!r} is not KEY=VALUE with KEY one of the grid dimensions "
                             f"{', '.join(ds.dims)}")
        if ds[key].dtype.kind in "fiu":
            try:
                number = float(value)
            except ValueError:
                raise InputError(f"--point: {key} needs a number, got {value!r}") from None
            if not math.isfinite(number):
                raise InputError(f"--point: {key} = {value.strip()} is not a finite number")
            _check_in_grid(key, number, ds[key].values)
            wanted[key] = [number]
        elif value.strip() not in ds[key].values:
            raise InputError(f"--point: {key} = {value!r} is not in the grid ({', '.join(map(str, ds[key].values))})")
        else:
            wanted[key] = [value.strip()]
    grid_dims = [d for d in ds["status"].dims]
    missing = [d for d in grid_dims if d not in wanted and ds.sizes[d] > 1]
    if missing:
        raise InputError(f"--point: give a value for {', '.join(missing)} too")
    numeric = {k: v for k, v in wanted.items() if ds[k].dtype.kind in "fiu"}
    other = {k: v for k, v in wanted.items() if k not in numeric}
    # the nearest grid value by position: a list axis need not be sorted (ds.sel(method="nearest")
    # refused an index that is not monotonic); a tie goes to the larger value, as sel's did
    import numpy as np

    nearest = {}
    for k, (number,) in numeric.items():
        grid = np.asarray(ds[k].values, dtype=float)
        gap = np.abs(grid - number)
        ties = np.flatnonzero(gap == gap.min())
        nearest[k] = [int(ties[np.argmax(grid[ties])])]
    return ds.isel(nearest).sel(other)


def point_slug(ds) -> str:
    """The grid point a --point selection holds, for file names: 'A0.5_mu1.47' (its grid values,
    '%g'; a categorical value as it is, characters unsafe in names replaced)."""
    import re

    parts = []
    for dim in ds["status"].dims:  # each of size 1 after select_point
        value = ds[dim].values.ravel()[0]
        text = f"{float(value):.6g}" if ds[dim].dtype.kind in "fiu" else str(value)
        parts.append(f"{dim}{text}")
    return re.sub(r"[^A-Za-z0-9_.+-]", "-", "_".join(parts)) or "point"


def _check_in_grid(key: str, value: float, grid) -> None:
    """Refuse a --point value beyond the grid by more than half the spacing at that end (the
    nearest grid value would be a silent guess), or off a one-value axis."""
    import numpy as np

    from .errors import InputError

    grid = np.sort(np.asarray(grid, dtype=float))
    lo, hi = float(grid[0]), float(grid[-1])
    if grid.size > 1:
        slack_lo, slack_hi = (grid[1] - grid[0]) / 2, (grid[-1] - grid[-2]) / 2
    else:
        slack_lo = slack_hi = 1e-9 * max(1.0, abs(lo))
    if not lo - slack_lo <= value <= hi + slack_hi:
        span = f"{lo:g} .. {hi:g}" if grid.size > 1 else f"only {lo:g}"
        raise InputError(f"--point: {key} = {value:g} is outside the grid ({span}); "
                         "give a value within it")


def _cmd_info(args) -> int:
    from .errors import InputError
    from .store import is_run_dataset, open_dataset

    ds = open_dataset(args.dataset, allow_partial=True, lazy=None)
    if ds.attrs.get("mechsweep_kind") == "boundaries" and "boundary" in ds:
        with _laid_out(args.dataset):
            text = describe_boundaries(ds)
        print(text)
        return 0
    if not is_run_dataset(ds):
        raise InputError(f"{args.dataset} is a mechsweep benchmark dataset ({ds.attrs.get('mechsweep_kind')}), "
                         "not a run; `mechsweep plot` draws it, `info` summarises runs")
    with _laid_out(args.dataset):
        text = describe(ds)
    print(text)
    return 0


def _bracket_widths(loc, width, attrs, unit) -> list[str]:
    """The final brackets' widths: relative to |x| where the boundary is away from 0, absolute next
    to 0, where a relative width means nothing. The scale is the locator's own: its tolerance is
    rtol max(|x|, ABS_FLOOR span), span the along axis's (attribute along_span; a dataset without that
    attribute, from an older version: relative wherever x != 0)."""
    import numpy as np

    from .boundaries import ABS_FLOOR

    span = float(attrs.get("along_span", np.nan))
    scale = ABS_FLOOR * span if np.isfinite(span) and span > 0 else 0.0
    along = attrs.get("along", "x")
    found = np.isfinite(loc) & np.isfinite(width)
    far = found & (np.abs(loc) > scale) & (loc != 0)
    near = found & ~far
    lines = []
    if far.any():
        rel = width[far] / np.abs(loc[far])
        where = f"|{along}| > {scale:.1e} = {ABS_FLOOR:g} x axis span" if scale > 0 else f"{along} != 0"
        lines.append(f"  bracket width relative to the boundary ({int(far.sum())} with {where}): median "
                     f"{np.median(rel):.1e}, largest {rel.max():.1e}")
    if near.any() and scale > 0:
        w = width[near]
        unit = f" {unit}" if unit and unit != "1" else ""
        lines.append(f"  bracket width absolute next to {along} = 0 ({int(near.sum())} with |{along}| <= {scale:.1e}): "
                     f"median {np.median(w):.1e}{unit}, largest {w.max():.1e}{unit}")
    return lines


def describe_boundaries(ds) -> str:
    """A boundaries dataset (`mechsweep boundaries`) in a few lines: what was located along which
    axis, how many, which accuracy bound stopped each, the cost, the continued curves."""
    import numpy as np

    from .boundaries import BOUND_MEANINGS, CURVE_STOPS

    a = ds.attrs
    what = (f"{a['criterion']} = {float(a.get('level', 1.0)):g}" if a.get("criterion", "status") != "status"
            else "status " + " -> ".join(str(a.get("status_change", "")).split()))
    dims = ", ".join(f"{d} ({ds.sizes[d]})" for d in ds["boundary"].dims)
    bound = np.asarray(ds["boundary_bound"].values)
    loc, width = np.asarray(ds["boundary"].values, float), np.asarray(ds["boundary_width"].values, float)
    lines = [f"{a.get('title', 'boundaries')}",
             f"  model {a.get('model')}: {what}, located along {a.get('along')}; dims {dims}",
             f"  located: {a.get('located', 0)} boundaries, rtol {float(a.get('rtol', np.nan)):.0e} in "
             f"{a.get('along')}" + (f"; criterion accuracy: {a['criterion_accuracy']}" if "criterion_accuracy" in a
                                    else "")]
    counts = ", ".join(f"{BOUND_MEANINGS[c]} {int((bound == c).sum())}" for c in sorted(BOUND_MEANINGS)
                       if (bound == c).any())
    lines.append(f"  accuracy bound met: {counts or 'none'} (parameter: bracket <= rtol max(|x|, 1e-6 x axis span); criterion: the "
                 "criterion's accuracy band is wider; band_edge: edge of that band)")
    lines += _bracket_widths(loc, width, a, ds["boundary"].attrs.get("units", ""))
    lines.append(f"  evaluations: {a.get('evaluated_points', 0)} points in {a.get('evaluate_calls', 0)} calls after "
                 f"the grid, {float(a.get('evaluations_per_point_mean', 0)):.1f} per located point (max "
                 f"{a.get('evaluations_per_point_max', 0)}), {float(a.get('wall_time_s', 0)):.2f} s")
    if "curve_stop" in ds:
        stops = np.asarray(ds["curve_stop"].values)
        kinds = ", ".join(f"{CURVE_STOPS[c]} {int((stops == c).sum())}" for c in range(len(CURVE_STOPS))
                          if (stops == c).any())
        folds = int(np.isfinite(np.asarray(ds[f"fold_{a['along']}"].values, float)).sum())
        lines.append(f"  continued in ({a.get('along')}, {a.get('continue_in')}): {int((stops >= 0).sum())} "
                     f"curve(s) (stopped: {kinds or 'none'}), {folds} fold(s); "
                     f"{a.get('continuation_evaluated_points', 0)} points in {a.get('continuation_calls', 0)} "
                     f"calls, {float(a.get('continuation_wall_time_s', 0)):.2f} s")
    lines.append(f"  created {a.get('created', '?')} by mechsweep {a.get('mechsweep_version', '?')}")
    return "\n".join(lines)


@contextmanager
def _laid_out(path):
    """A file that passed the opener's checks (a run's attributes and variables) but whose
    contents are not laid out as a run writes them (edited, or made elsewhere to look alike):
    say so in one line, exit 2."""
    from .errors import InputError

    from .store import is_lock_error, lock_holder
    from .errors import FileBusy

    try:
        yield
    except InputError:
        raise
    except OSError as exc:
        if is_lock_error(exc):  # another process took the dataset for writing meanwhile
            raise FileBusy(path, lock_holder(path)) from None
        if exc.filename is not None or exc.errno in _SYSTEM_ERRNOS:  # the system's refusal, not the file's bytes
            raise InputError(os_error_text(exc, path)) from None
        # a lazily opened dataset whose data turn out damaged when read (HDF5 says why, without an errno)
        raise InputError(f"{path} cannot be read, it is damaged ({str(exc).splitlines()[0][:200]})") from None
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        detail = str(exc).splitlines()[0][:200] if str(exc) else ""
        raise InputError(f"{path} is not laid out as a mechsweep dataset ({type(exc).__name__}: {detail}); "
                         "was it written by `mechsweep run`?") from None


def check_layout(ds) -> None:
    """What drawing a run's figures reads of its layout, checked before anything is drawn (a
    ValueError, said by :func:`_laid_out` as a dataset not laid out as a run writes it): every grid
    dimension has one value per index (a 1-D coordinate), numeric ones finite and distinct."""
    import numpy as np

    if "status" not in ds:  # a benchmark's dataset: its figures read it their own way
        return
    grid = list(ds["status"].dims)
    for d in grid:
        values = ds[d]
        if values.dims != (d,) or values.size != ds.sizes[d]:
            raise ValueError(f"the grid dimension {d!r} has no coordinate of its own")
        if values.dtype.kind in "fiu":
            v = np.asarray(values.values, dtype=float)
            if not np.isfinite(v).all() or np.unique(v).size != v.size:
                raise ValueError(f"the values of the grid dimension {d!r} are not finite and distinct")


@contextmanager
def _drawing(path):
    """Drawing the figures of a dataset that passed the layout checks: a mechsweep error (bad
    input) or a system error is said in one line as usual (exit 2); any other exception is a bug
    of mechsweep's drawing, not a problem of the file: it goes on (a traceback, exit 1) with a note
    saying so, never as 'not laid out as a mechsweep dataset'."""
    from .errors import MechsweepError

    try:
        yield
    except (MechsweepError, OSError, KeyboardInterrupt):
        raise
    except Exception as exc:
        exc.add_note(f"mechsweep plot: internal error while drawing the figures of {path}: a bug in mechsweep, not "
                     "a problem of the dataset (it passed the layout checks); please report it with the "
                     "command and the dataset")
        raise


def _cmd_models(args) -> int:
    from .errors import InputError
    from .model import user
    from .models import MODELS

    if args.scene and args.model:
        raise InputError("give either a MODEL or --scene SCENE, not both")
    if args.scene:
        from .scene import load_scene

        specs = [load_scene(args.scene).model]
    elif args.model:
        name = args.model
        if name in MODELS:
            specs = [MODELS[name]]
        elif ":" in name:
            specs = [user.resolve(name)]
        elif name.endswith(".py") or "/" in name or "\\" in name:  # a model file without :NAME
            found = _models_in_file(name)
            print(f"{name} defines {len(found)} model(s): {', '.join(found)}; a scene names one as "
                  f"{name}:NAME (e.g. model = \"{name}:{found[0]}\")\n")
            specs = [user.resolve(f"{name}:{n}") for n in found]
        else:
            points = user.entry_points()
            if name not in points:
                known = list(MODELS) + sorted(set(points) - set(MODELS))
                raise InputError(f"unknown model {name!r}; models: {', '.join(known)} (or 'file.py:NAME', "
                                 "'package.module:NAME')")
            specs = [_entry_point_model(name, points[name])]
    elif args.markdown:  # the docs' glossary page: the built-in models and the status codes
        from .docs import glossary

        print(glossary(), end="")
        return 0
    else:
        points = user.entry_points()
        specs = list(MODELS.values()) + [_entry_point_model(n, ep) for n, ep in points.items() if n not in MODELS]
    for spec in specs:
        print(model_markdown(spec) if args.markdown else model_text(spec))
    return 0


def _models_in_file(name: str) -> list[str]:
    """The names of the OdeModel and ClosedFormModel objects a model file defines (InputError
    naming the file when it is missing, fails to import or defines none)."""
    from pathlib import Path

    from .errors import InputError
    from .model import load, user
    from .model.closed import ClosedFormModel
    from .model.ode import OdeModel

    path = Path(name).resolve()
    user.check_model_file(name, path)  # a regular .py file; its import's failures and exits are InputErrors
    mod = user.import_model(name, load.module_name(path), str(path), str(path))
    found = [k for k, v in vars(mod).items() if isinstance(v, (OdeModel, ClosedFormModel))]
    if not found:
        raise InputError(f"{name!r}: {path} defines no mechsweep.model.OdeModel or ClosedFormModel")
    return found


def _entry_point_model(name: str, ep):
    from .errors import InputError
    from .model import user

    dist = getattr(getattr(ep, "dist", None), "name", None)
    try:
        return user.resolve(ep.value)
    except InputError as exc:
        raise InputError(f"entry point {name!r} (group {user.ENTRY_POINT_GROUP}"
                         f"{', package ' + dist if dist else ''}): {exc}") from None


def _cmd_check(args) -> int:
    from .scene import SceneError, load_scene

    bad = 0
    for path in args.scenes:
        try:
            s = load_scene(path)
            print(f"{path}: ok ({s.model.name}, {s.n_points} points, outputs {', '.join(s.outputs)})")
            from .scene import solver_warnings
            for text in solver_warnings(s):
                print(f"{path}: warning: {text}", file=sys.stderr)
            if s.boundaries is not None:
                from .boundaries import warnings_for
                for text in warnings_for(s):
                    print(f"{path}: warning: {text}", file=sys.stderr)
        except SceneError as exc:
            bad += 1
            print(f"{path}: {exc}", file=sys.stderr)
    return EXIT_INVALID if bad else 0


def _cmd_examples(args) -> int:
    import shlex

    from . import examples
    from .errors import InputError

    if os.path.exists(args.folder) and not os.path.isdir(args.folder):
        raise InputError(f"{args.folder} exists and is not a folder; give a folder to copy the examples into")
    try:
        written = examples.copy(args.folder)
    except FileExistsError as exc:
        raise InputError(str(exc)) from None
    except OSError as exc:
        raise InputError(f"cannot copy the examples into {args.folder}: {exc.strerror or exc}") from None
    root = Path(args.folder)
    print(f"copied {len(written)} files into {root / 'sweeps'}; run the quickstart there:")
    print(f"  cd {shlex.quote(str(root))} && mechsweep run sweeps/quickstart.toml && mechsweep plot data/runs/quickstart.h5")
    return 0


# ----------------------------------------------------------------------------- text helpers
def _status_counts(ds) -> dict[str, int]:
    import numpy as np

    from . import status as st

    codes, counts = np.unique(ds["status"].values, return_counts=True)
    return {st.MEANINGS.get(int(c), str(c)): int(n) for c, n in zip(codes, counts)}


def describe(ds) -> str:
    import numpy as np

    from . import status as st

    lines = [f"{ds.attrs.get('title', '?')}  (model {ds.attrs.get('model', '?')})"]
    lines.append("dimensions:")
    for dim in ds.dims:
        c = ds[dim]
        vals = c.values
        rng = f"{vals[0]} .. {vals[-1]}" if vals.dtype.kind in "fiu" else ", ".join(map(str, vals[:6]))
        lines.append(f"  {dim:<12} {ds.sizes[dim]:>7}  [{c.attrs.get('units', '')}]  {rng}  "
                     f"({c.attrs.get('spacing', '')})  {c.attrs.get('long_name', '')}")
    fixed = [k for k in ds.coords if k not in ds.dims]
    if fixed:
        lines.append("fixed: " + ", ".join(f"{k} = {ds[k].values} {ds[k].attrs.get('units', '')}".strip()
                                           for k in fixed))
    lines.append("outputs:")
    status = ds["status"]
    ok = status == 0
    counts = _status_counts(ds)
    codes = status.values
    total = status.size
    for name in _outputs(ds):
        # the range over every finite value, whatever the point's status (a value at a point whose
        # status is not ok, e.g. an unstable point where a second output failed, is still shown),
        # and beside it the range over the ok points when that differs; chunk by chunk when lazy
        lo, hi = float(ds[name].min()), float(ds[name].max())
        v = ds[name].where(ok)
        lo_ok, hi_ok = float(v.min()), float(v.max())
        rng = f"{lo:.6g} .. {hi:.6g}" if np.isfinite(lo) else "no values"
        if np.isfinite(lo) and (lo_ok, hi_ok) != (lo, hi):
            rng += f" (at ok points {lo_ok:.6g} .. {hi_ok:.6g})" if np.isfinite(lo_ok) else " (none at an ok point)"
        lines.append(f"  {name:<20} [{ds[name].attrs.get('units', '')}]  {rng}  {ds[name].attrs.get('long_name', '')}")
        lines.append(f"  {'':<20} {_presence(ds, name, codes)}")
    verdicts = [n for n in _outputs(ds) if output_kind(ds, n) == "verdict"]
    for i, a in enumerate(verdicts):
        for b in verdicts[i + 1:]:
            lines.append("verdicts: " + verdict_agreement(ds, a, b))
    lines.append("status: " + ", ".join(f"{k} {n} ({100 * n / total:.3g}%)" for k, n in counts.items()))
    notes = _status_notes(ds)
    for meaning in counts:
        if meaning in notes:
            lines.append(f"  {meaning}: {notes[meaning]}")
    if "n_steps" in ds:
        computed = int((ds["status"] != st.PENDING).sum())  # an unfinished run's pending points took no steps
        mean = f"mean {float(ds['n_steps'].sum()) / computed:.1f} steps/point" if computed else "no point computed yet"
        if 0 < computed < ds["status"].size:
            mean += f" computed ({computed} of {ds['status'].size})"
        lines.append(f"cost: {int(ds['n_steps'].sum())} steps, {int(ds['n_rhs'].sum())} rhs evaluations, {mean}")
        solver = {k[len('solver_'):]: v for k, v in ds.attrs.items() if k.startswith("solver_")}
        lines.append("solver: " + ", ".join(f"{k}={v}" for k, v in solver.items()))
    where = ds.attrs.get("execution") or (f"{ds.attrs['threads']} threads" if "threads" in ds.attrs
                                          else "so far: an unfinished run")
    times = ", ".join(f"{k[:-7]} {float(ds.attrs[k]):.3f} s" for k in ("compile_time_s", "compute_time_s")
                      if k in ds.attrs)
    lines.append(f"wall time: {float(ds.attrs.get('wall_time_s', float('nan'))):.3f} s"
                 f"{f' ({times})' if times else ''} ({where})")
    lines.append("provenance: " + ", ".join(f"{k} {ds.attrs.get(k)}" for k in
                                             ("created", "mechsweep_version", "numba_version", "numpy_version")))
    return "\n".join(lines)


def _outputs(ds) -> list[str]:
    return ds.attrs.get("outputs", "").split()  # one not in the file: KeyError, "not laid out as" (_laid_out)


def _builtin_spec(ds):
    """The declaration of the dataset's model when it is a built-in one (for datasets written
    before an attribute existed), else None."""
    from .models import MODELS

    return MODELS.get(ds.attrs.get("model"))


def output_kind(ds, name: str) -> str:
    """What an output is (``Output.kind``): the variable's ``mechsweep_kind``; for a dataset written
    before kinds were stored, the built-in model's declaration."""
    kind = ds[name].attrs.get("mechsweep_kind")
    if kind is None and (spec := _builtin_spec(ds)) is not None and name in spec.output_names():
        kind = spec.output(name).kind
    return str(kind or "")


def _status_notes(ds) -> dict[str, str]:
    """The model's notes on its statuses, {meaning: text}: stored with the dataset, else (a dataset
    written before notes were stored) the built-in model's declaration."""
    from . import status as st

    notes = st.stored_notes(ds["status"].attrs)
    if not notes and "status_notes" not in ds["status"].attrs and (spec := _builtin_spec(ds)) is not None:
        notes = {st.MEANINGS.get(c, str(c)): t for c, t in spec.status_notes}
    return notes


def _presence(ds, name: str, codes) -> str:
    """'values at N of M points; missing: status k, ...': a point holds a value when the output is
    finite there (at every sample of its extra dimensions). ``codes``: the status array (grid order)."""
    import numpy as np

    from . import status as st

    v = ds[name]
    extra = [d for d in v.dims if d not in ds["status"].dims]
    held = np.isfinite(v).all(extra) if extra else np.isfinite(v)  # one pass, chunk by chunk when lazy
    held = np.asarray(held.transpose(*ds["status"].dims).values, dtype=bool)
    missing_codes, counts = np.unique(codes[~held], return_counts=True)
    missing = [f"{st.MEANINGS.get(int(c), str(c))} {int(n)}" for c, n in zip(missing_codes, counts)]
    text = f"values at {int(held.sum())} of {codes.size} points"
    text += f"; missing: {', '.join(missing)}" if missing else ""
    not_ok = int((held & (codes != st.OK)).sum())
    return text + (f"; {not_ok} held at points whose status is not ok" if not_ok else "")


def verdict_agreement(ds, a: str, b: str) -> str:
    """How often two verdict outputs (1 = stable, 0 = not) agree, over points where both exist."""
    import numpy as np

    x, y = ds[a].values.ravel(), ds[b].values.ravel()
    both = np.isfinite(x) & np.isfinite(y)
    agree = int((x[both] == y[both]).sum())
    return (f"{a} and {b} agree at {agree} of {int(both.sum())} points with both verdicts; "
            f"disagree at {int(both.sum()) - agree} ({a} 1, {b} 0: {int(((x == 1) & (y == 0)).sum())}; "
            f"{a} 0, {b} 1: {int(((x == 0) & (y == 1)).sum())}); {int((np.isfinite(x) & ~np.isfinite(y)).sum())} "
            f"points have {a} only, {int((~np.isfinite(x) & np.isfinite(y)).sum())} {b} only")


def model_text(spec) -> str:
    lines = [f"{spec.name}: {spec.description}", f"  source: {spec.source}", "  parameters:"]
    for p in spec.params:
        opt = "" if p.required else " (optional)"
        lines.append(f"    {p.name:<10} [{p.unit or '-'}] {p.long_name}; {p.allowed()}{opt}")
    lines.append("  outputs:")
    for o in spec.outputs:
        extra = " (integrated)" if o.integrated else ""
        dims = f" (per {', '.join(d.name for d in o.extra_dims)})" if o.extra_dims else ""
        lines.append(f"    {o.name:<20} [{o.unit}] {o.long_name}{extra}{dims}")
    if any(o.integrated for o in spec.outputs):
        from .ode import METHOD_HELP

        by_output = [(o.name, tuple(spec.methods_for(spec.closure((o.name,)))) if spec.methods_for else spec.methods)
                     for o in spec.outputs if o.integrated]
        offered = [m for m in spec.methods if any(m in ms for _, ms in by_output)]
        lines.append("  solver.method:")
        lines += [f"    {m:<12} {METHOD_HELP[m]}" for m in offered]
        narrower = [(n, ms) for n, ms in by_output if ms != tuple(offered)]
        if narrower:  # a scene asking for these outputs may choose only among their methods
            lines.append("    methods by output (a scene with several outputs gets the methods they all offer):")
            lines += [f"      {n:<20} {', '.join(m)}" for n, m in narrower]
    if spec.settings:
        lines.append("  solver settings (besides method, rtol, atol, max_steps):")
        for st in spec.settings:
            lines.append(f"    {st.name:<20} [{st.unit}] {st.long_name}; default {st.default:g}, "
                         f"allowed [{st.lo:g}, {st.hi:g}]")
    from . import status

    lines.append("  statuses: " + ", ".join(status.MEANINGS.get(c, str(c)) for c in spec.possible_statuses()))
    lines += [f"    {status.MEANINGS.get(c, str(c)):<20} {t}" for c, t in spec.status_notes]
    return "\n".join(lines)


def model_markdown(spec) -> str:
    """Glossary tables of one model (docs/glossary.md embeds them; a test keeps them in sync)."""
    from .docs import model_markdown as markdown

    return markdown(spec)

if __name__ == "__main__":
    sys.exit(main())
