"""Figures read a stored Dataset and label themselves from its attributes; they never compute.

Which figures a dataset gets is decided from what it declares, never from variable names here:

1. figures for a model: each figure module lists ``FIGURES`` (:class:`~._registry.ModelFigure`
   entries) saying which ``model`` attribute (or benchmark ``mechsweep_kind``) it is for, which
   outputs it needs and which it draws, and what dimensions it fits;
2. generic figures for the outputs no fitting figure of step 1 draws (:func:`.generic.choose`:
   from the outputs' declared kinds, dimensions and the axes' spacing).

Step 2's figures are drawn by default when no figure of step 1 fits (a model the package has no
figures for, e.g. a user's own); otherwise they are listed as on request (``--kind NAME``), so the
figures of the built-in models' scenes stay the ones their modules draw.

``available(ds)`` lists the figures drawn by default, ``on_request(ds)`` the others;
``draw(ds, kind)`` returns one as a matplotlib Figure (made without pyplot; ``fig=`` draws it into a
Figure or SubFigure of the user's, ``ax=`` onto the user's Axes), ``artists(ds, kind)`` the same
with every artist drawn (a :class:`~._style.Drawn` dict); ``save(ds, path)`` writes them. Every
figure function of the modules here takes ``fig=`` / ``ax=`` and returns its artists. Both take
``boundaries=``: the located boundaries dataset of the same grid
(DATA.boundaries.h5, see :func:`sibling_boundaries`), drawn over the charts that declare they draw
boundaries; a boundaries dataset itself gets the figure of :mod:`.located`.
"""
from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

from . import generic, located
from ._registry import ModelFigure


def _discovered() -> tuple[ModelFigure, ...]:
    """The ``FIGURES`` of every figure module of this package (found, not named here), most
    specific first: a module whose figures are for benchmark or boundaries datasets, then those
    for one model, then those shared by several (the Duffing figures also fit the torsional
    circuit, whose own figures must come first); alphabetical within a rank."""
    modules = [importlib.import_module(f"{__name__}.{m.name}") for m in pkgutil.iter_modules(__path__)
               if not m.name.startswith("_")]
    found = [(m.__name__, m.FIGURES) for m in modules if getattr(m, "FIGURES", ())]
    rank = {name: min(len(f.models) for f in figs) for name, figs in found}
    return tuple(f for name, figs in sorted(found, key=lambda t: (rank[t[0]], t[0])) for f in figs)


MODEL_FIGURES: tuple[ModelFigure, ...] = _discovered()


def sibling_boundaries(path):
    """The located boundaries written beside the dataset ``path`` by ``mechsweep boundaries``
    (DATA.boundaries.h5), or None when there is no such file."""
    from ..boundaries import sibling_path

    target = sibling_path(path)
    return target if target.is_file() else None


def _fitting(ds, axes=None) -> tuple[list[ModelFigure], list]:
    """The model's figures that fit ``ds`` and the generic figures (:class:`.generic.Choice`) of the
    outputs they leave. ``axes`` = (x, y), either None: the generic figures only, on those axes."""
    given = axes is not None and any(a is not None for a in axes)
    model = [] if given else [f for f in MODEL_FIGURES if f.fits_dataset(ds)]
    drawn = set().union(*(f.drawn(ds) for f in model))
    x, y = axes if given else (None, None)
    return model, generic.choose(ds, drawn, x=x, y=y)


def _plan(ds, boundaries=None, axes=None) -> list[tuple[str, str, object, bool]]:
    """(name, description, draw(ds) -> Figure, drawn by default) for every figure that fits; the
    generic ones are drawn by default when no model's figure fits. The figures that draw boundaries
    get ``boundaries`` when they were located on the grid of ds (else None: the chart alone)."""
    model, choices = _fitting(ds, axes)
    fitting = boundaries if boundaries is not None and located.mismatch(ds, boundaries) is None else None
    plan = [(f.name, f.description, (lambda ds, f=f, **kw: f.draw(ds, boundaries=fitting, **kw)) if f.boundaries
             else f.draw, True) for f in model]
    return plan + [(c.name, c.description, (lambda ds, c=c, **kw: c.draw(ds, boundaries=fitting, **kw)), not model)
                   for c in choices]


def boundary_figures(ds, boundaries, axes=None) -> list[str]:
    """The figures of ``ds`` (drawn by default or on request, as :func:`available` and
    :func:`on_request` list them) that draw ``boundaries`` over their chart: a model's figure
    that declares it draws boundaries, a stability map or heatmap with the axis they were located
    along as one of its two axes. Empty when ``boundaries`` were not located on this grid."""
    if boundaries is None or located.mismatch(ds, boundaries) is not None:
        return []
    model, choices = _fitting(ds, axes)
    return [f.name for f in model if f.boundaries] + [c.name for c in choices if c.draws(boundaries)]


def boundaries_problem(ds, boundaries, kinds, axes=None, *, kind_arg="kind=NAME", axes_arg="axes=(x, y)"):
    """Why ``boundaries`` cannot be drawn with the figures ``kinds`` of ``ds`` (None: one of them
    draws them): not located on this grid, or none of those figures draws located boundaries (the
    text names the figures of ``ds`` that do, else which would). ``kind_arg`` / ``axes_arg``: how
    the caller chooses a figure and its axes (the command line's options, or the API's)."""
    why = located.mismatch(ds, boundaries)
    if why is not None:
        return f"not located on the grid of this dataset: {why}"
    can = boundary_figures(ds, boundaries, axes)
    if any(k in can for k in kinds):
        return None
    what = ", ".join(kinds) or "none"
    if can:
        return (f"none of the figures drawn ({what}) draws located boundaries; the figures of this dataset that "
                f"do: {', '.join(can)} ({kind_arg})")
    return (f"no figure of this dataset draws them (figures drawn: {what}): a stability map or heatmap with "
            f"{boundaries.attrs.get('along')!r} as one of its two axes does ({axes_arg} choose a heatmap's axes); "
            "a nomogram or curve has no place for them")


def available(ds, axes=None) -> dict[str, str]:
    """The figures drawn by default for a dataset (what ``mechsweep plot`` draws).

    Parameters
    ----------
    ds : xarray.Dataset
        A dataset mechsweep wrote (:func:`mechsweep.open_dataset`, :func:`mechsweep.run`).
    axes : tuple of (str or None, str or None), optional
        ``(x, y)``: the generic figures over those axes instead (``--x``/``--y``).

    Returns
    -------
    dict of str to str
        Figure name (a ``kind`` for :func:`draw`) -> a sentence saying what it shows.
    """
    return {name: text for name, text, _, default in _plan(ds, axes=axes) if default}


def on_request(ds, axes=None) -> dict[str, str]:
    """Generic figures that fit a dataset but are drawn only when asked for by name (its model has
    figures of its own that fit).

    Parameters
    ----------
    ds : xarray.Dataset
        A dataset mechsweep wrote.
    axes : tuple of (str or None, str or None), optional
        ``(x, y)``: the generic figures over those axes.

    Returns
    -------
    dict of str to str
        Figure name -> a sentence saying what it shows.
    """
    return {name: text for name, text, _, default in _plan(ds, axes=axes) if not default}


def artists(ds, kind: str, *, boundaries=None, fig=None, ax=None, axes=None):
    """Draw a figure and return every artist it made.

    Parameters
    ----------
    ds : xarray.Dataset
        A dataset mechsweep wrote.
    kind : str
        The figure's name, one of :func:`available` or :func:`on_request`.
    boundaries : xarray.Dataset, optional
        The located boundaries of the same grid (``mechsweep boundaries``, ``NAME.boundaries.h5``),
        drawn over the charts that draw boundaries.
    fig : matplotlib.figure.Figure or matplotlib.figure.SubFigure, optional
        Draw into this figure instead of a new one.
    ax : matplotlib.axes.Axes, optional
        Draw onto these axes (figures of one panel).
    axes : tuple of (str or None, str or None), optional
        ``(x, y)``: a generic figure over those axes.

    Returns
    -------
    dict
        The artists by name (a ``Drawn`` dict): ``["figure"]`` the Figure, ``["axes"]`` its axes,
        and the lines, images and labels the figure drew.

    Raises
    ------
    ValueError
        ``kind`` does not fit this dataset (the message lists those that do).
    """
    for name, _, fn, _ in _plan(ds, boundaries, axes):
        if name == kind:
            return fn(ds, fig=fig, ax=ax)
    raise ValueError(f"figure {kind!r} does not fit this dataset; it can draw: "
                     f"{', '.join(name for name, *_ in _plan(ds, axes=axes)) or 'nothing'}")


def draw(ds, kind: str, *, boundaries=None, fig=None, ax=None, axes=None):
    """Draw a figure and return it.

    The figure is made without pyplot (no global state, no window): in a notebook it shows once
    ``%matplotlib inline`` has run; elsewhere save it with ``fig.savefig(path)``.

    Parameters
    ----------
    ds : xarray.Dataset
        A dataset mechsweep wrote.
    kind : str
        The figure's name, one of :func:`available` or :func:`on_request`.
    boundaries : xarray.Dataset, optional
        The located boundaries of the same grid, drawn over the charts that draw boundaries.
    fig : matplotlib.figure.Figure or matplotlib.figure.SubFigure, optional
        Draw into this figure instead of a new one.
    ax : matplotlib.axes.Axes, optional
        Draw onto these axes (figures of one panel).
    axes : tuple of (str or None, str or None), optional
        ``(x, y)``: a generic figure over those axes.

    Returns
    -------
    matplotlib.figure.Figure
        The figure (see :func:`artists` for what was drawn on it).

    Examples
    --------
    >>> import mechsweep
    >>> from mechsweep import figures
    >>> ds = mechsweep.open_dataset("data/runs/quickstart.h5")          # doctest: +SKIP
    >>> figures.available(ds)                                          # doctest: +SKIP
    {'amplitude_period': 'T omega against epsilon: ...', 'kinematic_coefficients': '...'}
    >>> figures.draw(ds, "amplitude_period").savefig("period.png")    # doctest: +SKIP
    """
    return artists(ds, kind, boundaries=boundaries, fig=fig, ax=ax, axes=axes).figure


def source_files(ds, kind: str, *, boundaries=None) -> list[Path]:
    """The source files whose code draws figure ``kind`` of ``ds`` (its module, the shared style
    and registry, and the boundaries overlay when it draws one): what a committed figure's
    staleness is judged by (docs/figures/MANIFEST.json)."""
    here = Path(__file__).resolve().parent
    files = {here / "_style.py", here / "_registry.py", here / "__init__.py"}
    for f in MODEL_FIGURES:
        if f.name == kind and f.fits_dataset(ds):
            files.add(Path(__import__("sys").modules[f.draw.__module__].__file__).resolve())
            if f.boundaries and boundaries is not None:
                files.add(here / "located.py")
            return sorted(files)
    if kind not in {c.name for c in generic.choose(ds)}:
        raise ValueError(f"figure {kind!r} does not fit this dataset")
    return sorted(files | {here / "generic.py"})


def targets(ds, path, *, kind: str | None = None, fmt: str = "png", axes=None) -> list[Path]:
    """The files ``save`` writes: ``path`` with the format's suffix for one figure, or
    ``<stem>_<kind>.<fmt>`` beside it for each of several."""
    chosen = [kind] if kind else list(available(ds, axes))
    path = Path(path)
    return [path.with_suffix(f".{fmt}") if len(chosen) == 1 else path.with_name(f"{path.stem}_{k}.{fmt}")
            for k in chosen]


def check_kind(kind: str, names, axes=None) -> None:
    """Refuse (InputError) a figure ``kind`` that is not one of ``names``, the figures that fit the
    dataset (over ``axes`` when given: :func:`available` and :func:`on_request`), naming them."""
    from ..errors import InputError

    if kind in names:
        return
    given = axes is not None and any(a is not None for a in axes)
    raise InputError(f"figure {kind!r} does not fit this dataset{' with ' + _axes_text(axes) if given else ''}; "
                     f"it can draw: {', '.join(names) or 'nothing'}"
                     + (" (--x/--y choose the axes of the generic figures only)" if given else ""))


def save(ds, path, *, kind: str | None = None, fmt: str = "png", dpi: int = 150, boundaries=None,
         axes=None) -> list[Path]:
    """Write one figure, or every figure drawn by default, to files (what ``mechsweep plot`` does).

    Parameters
    ----------
    ds : xarray.Dataset
        A dataset mechsweep wrote.
    path : str or pathlib.Path
        The file; with several figures, each goes to ``<stem>_<kind>.<fmt>`` beside it.
    kind : str, optional
        One figure (any listed by :func:`available` or :func:`on_request`); None (default): every
        figure drawn by default.
    fmt : str, optional
        ``"png"`` (default), ``"svg"`` or ``"pdf"``.
    dpi : int, optional
        Resolution of a PNG.
    boundaries : xarray.Dataset, optional
        The located boundaries of the same grid, drawn over the charts that draw boundaries
        (refused when they were not located on this grid or no figure written draws them).
    axes : tuple of (str or None, str or None), optional
        ``(x, y)``: the generic figures over those axes instead.

    Returns
    -------
    list of pathlib.Path
        The files written.

    Raises
    ------
    InputError
        ``kind`` does not fit this dataset, or no figure does, or ``boundaries`` would not be drawn.
    """
    from ..errors import InputError

    plan = {name: fn for name, _, fn, _ in _plan(ds, boundaries, axes)}
    kinds = available(ds, axes)
    given = axes is not None and any(a is not None for a in axes)
    if kind is not None:
        check_kind(kind, plan, axes)
    if not kinds and kind is None:
        raise InputError(f"no generic figure of this dataset is over {_axes_text(axes)}" if given else
                         "no figure fits this dataset (a generic figure needs a float output over at least one "
                         "numeric axis with more than one value)")
    if boundaries is not None:
        why = boundaries_problem(ds, boundaries, [kind] if kind else list(kinds), axes)
        if why is not None:
            raise InputError(f"boundaries: {why}")
    written = []
    for k, out in zip([kind] if kind else list(kinds), targets(ds, path, kind=kind, fmt=fmt, axes=axes)):
        savefig(plan[k](ds).figure, out, format=fmt, dpi=dpi)
        written.append(out)
    return written


def savefig(fig, path, *, format: str = "png", dpi: int = 150) -> None:
    """Write ``fig`` to ``path``: the file of ``fig.savefig(path, format=format, dpi=dpi)``, byte for
    byte, in one pass over the figure's artists instead of two for a PNG of a figure laid out by a
    layout engine (constrained layout, as every figure of this package).

    matplotlib's savefig runs the engine inside a first draw that renders nothing, each artist
    drawn with drawing turned off, then draws the figure again into the file, on a canvas of its
    own. Here the PNG's canvas is the figure's for the time of the call: the engine runs alone at
    the file's resolution, measuring the texts with that canvas's renderer (which keeps their
    sizes and parsed mathtext for the draw that follows), and the figure is saved without its
    engine, so nothing is laid out again. The artists' places come from the layout alone, never
    from the first draw. The figure's canvas, resolution and engine are put back afterwards.
    Other formats, and figures without an engine or axes, go to ``fig.savefig`` as they are."""
    import matplotlib

    engine = fig.get_layout_engine()
    if engine is None or format != "png" or not fig.axes:
        fig.savefig(path, format=format, dpi=dpi)
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas, resolution = fig.canvas, fig.dpi
    FigureCanvasAgg(fig)  # the canvas savefig would draw a PNG on, the figure's until the file is written
    fig.dpi = dpi
    try:
        try:
            engine.execute(fig)
        except ValueError:  # as Figure.draw: a layout that cannot be made leaves the figure as it is
            pass
        # set_layout_engine(None) takes rcParams' default engine; under these, none
        with matplotlib.rc_context({"figure.autolayout": False, "figure.constrained_layout.use": False}):
            fig.set_layout_engine(None)
        try:
            fig.savefig(path, format=format, dpi=dpi)
        finally:
            fig.set_layout_engine(engine)
    finally:
        fig.dpi = resolution
        fig.set_canvas(canvas)


def _axes_text(axes) -> str:
    return " and ".join(f"--{k} {v}" for k, v in zip("xy", axes) if v is not None)
