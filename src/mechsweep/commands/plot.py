"""`mechsweep plot DATASET`: draw the figures of a stored dataset into files (the figures are
figures/' modules'; this module chooses the files, checks them and selects a --point)."""
from __future__ import annotations

import math
import os
import sys
from contextlib import contextmanager
from pathlib import Path

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
  mechsweep plot data/runs/NAME.h5 --point AXIS=VALUE,AXIS=VALUE
"""


def add_parser(sub, fmt) -> None:
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
                   help="select one grid point (the nearest value on each axis with more than one); "
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
    p.set_defaults(func=command)


def command(args) -> int:
    with no_dask_probe():
        return _plot(args)


@contextmanager
def no_dask_probe():
    """While the body runs, xarray takes dask to be absent unless dask is already imported.

    xarray asks of every variable it makes whether the data is a dask array (and of every index
    whether it is a dask collection), and imports ``dask.array`` (with scipy.fft) or ``dask.base`` to
    find out when dask is installed, which cost a warm ``plot`` more than drawing a figure. ``plot``
    opens its datasets into memory (numpy arrays), so no dask object can occur in it. The answers
    are put into xarray's caches for the body only and taken out afterwards (a caller of ``main``
    that later opens a dataset lazily gets xarray's own probes); when xarray's internals differ,
    nothing is done."""
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


def _plot(args) -> int:
    from .. import figures
    from ..errors import InputError
    from ..figures import jobs
    from ..store.read import open_dataset, reading
    from . import started

    ds = whole = open_dataset(args.dataset)
    started()
    with reading(args.dataset):
        check_layout(ds)
        if args.point:
            ds = select_point(ds, args.point)
        axes = (args.x, args.y) if args.x or args.y else None
        kinds = figures.available(ds, axes)
        extra = figures.on_request(ds, axes) if args.list or args.kind is not None else {}
    if args.kind is not None and not args.list:  # before the boundaries: a figure that does not exist comes first
        figures.check_kind(args.kind, [*kinds, *extra], axes)
    bds = _boundaries_for(whole, args)
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
    drawing = [args.kind] if args.kind else list(kinds)  # (a --kind this dataset has not is refused above)
    can = figures.boundary_figures(ds, bds, axes) if bds is not None else []
    if bds is not None and args.boundaries:
        _check_boundaries_drawn(ds, bds, args, drawing, can, axes)
    elif not set(drawing) & set(can):
        bds = None  # found beside the dataset: drawn only when a figure shows them
    with _drawing(args.dataset), _writing_figures(out):
        kinds = list(figures.available(ds, axes)) if args.kind is None else []
        if len(kinds) > 1 and jobs.can_fork():  # several figures: side by side on the cores (the same files)
            written = figures.targets(ds, out, fmt=fmt, axes=axes)
            jobs.side_by_side([lambda k=k, path=path: figures.save(ds, path, kind=k, fmt=fmt, axes=axes,
                                                                   boundaries=bds if k in can else None)
                               for k, path in zip(kinds, written)])
        else:
            written = figures.save(ds, out, kind=args.kind, fmt=fmt, boundaries=bds, axes=axes)
    for path in written:
        print(f"wrote {path}")
    return 0


def _boundaries_for(ds, args):
    """The located boundaries to draw over a run's charts: --boundaries PATH (refused, exit 2, when
    they were not located on this dataset's grid), else DATASET.boundaries.h5 when it exists (left
    out with a note when it does not fit), else None."""
    from .. import figures
    from ..errors import InputError
    from ..store.read import is_run_dataset, open_dataset

    if args.no_boundaries or not is_run_dataset(ds):
        if args.boundaries and args.no_boundaries:
            raise InputError("give either --boundaries PATH or --no-boundaries, not both")
        return None
    path = Path(args.boundaries) if args.boundaries else figures.sibling_boundaries(args.dataset)
    if path is None:
        return None
    bds = open_dataset(path)
    why = figures.located.mismatch(ds, bds)
    if why is None:
        return bds
    if args.boundaries:
        raise InputError(f"--boundaries {path}: not located on the grid of {args.dataset}: {why}")
    print(f"note: {path} not drawn: {why}", file=sys.stderr)
    return None


def _check_boundaries_drawn(ds, bds, args, drawing, can, axes) -> None:
    """--boundaries PATH is drawn by some of the figures ``drawing`` (refused, exit 2, when by none:
    naming the figures of this dataset that draw them, ``can``, or saying which would); a note names
    the figures drawn without them (a nomogram, a curve: an output against one axis)."""
    from .. import figures
    from ..errors import InputError

    why = figures.boundaries_problem(ds, bds, drawing, axes, kind_arg="--kind NAME", axes_arg="--x, --y")
    if why is not None:
        raise InputError(f"--boundaries {args.boundaries}: {why}")
    left = [k for k in drawing if k not in can]
    if left:
        print(f"note: --boundaries {args.boundaries}: drawn on {', '.join(k for k in drawing if k in can)}; not on "
              f"{', '.join(left)} (only a stability map or heatmap with {bds.attrs.get('along')!r} as one of its "
              "axes draws them)", file=sys.stderr)


def check_layout(ds) -> None:
    """What drawing a run's figures reads of its layout, checked before anything is drawn (a
    ValueError, said by ``store.read.reading`` as a dataset not laid out as a run writes it): every
    grid dimension has one value per index (a 1-D coordinate), numeric ones finite and distinct."""
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
    from ..errors import MechsweepError

    try:
        yield
    except (MechsweepError, OSError, KeyboardInterrupt):
        raise
    except Exception as exc:
        exc.add_note(f"mechsweep plot: internal error while drawing the figures of {path}: a bug in mechsweep, not "
                     "a problem of the dataset (it passed the layout checks); please report it with the "
                     "command and the dataset")
        raise


@contextmanager
def _writing_figures(out: Path):
    """An OSError while the figures are written (the dataset is in memory by then: ``plot`` loads it)
    is the figure file's: say which file and why, with what to do."""
    from ..errors import InputError, os_error_text

    try:
        yield
    except OSError as exc:
        raise InputError(os_error_text(exc, out, writing="the figure")) from None


def _check_figure_path(target: Path, dataset: Path) -> None:
    """Refuse a figure path that would overwrite the dataset it is drawn from, another HDF5 file,
    or something that is not a regular file, or whose folder is missing or not writable."""
    from ..errors import InputError, why_os_error

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
        raise InputError(f"figure path {target} exists and cannot be read ({why_os_error(exc.errno, exc.strerror or str(exc))}), so it is not known what "
                         "drawing would overwrite; give another path with -o") from None
    if head == b"\x89HDF\r\n\x1a\n":
        raise InputError(f"figure path {target} is an HDF5 file (a dataset?); drawing would overwrite it: "
                         "give another figure path with -o")


def _entry_kind(path) -> str:
    from ..store.read import file_kind

    try:
        return file_kind(os.stat(path).st_mode)
    except OSError:
        return "a broken link"


def select_point(ds, text: str):
    """The sub-dataset at one grid point, from 'key=value,...' (nearest grid values)."""
    from ..errors import InputError

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
    missing = [d for d in ds["status"].dims if d not in wanted and ds.sizes[d] > 1]
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

    from ..errors import InputError

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
