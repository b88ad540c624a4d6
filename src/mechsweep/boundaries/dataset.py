"""A scene's boundaries: the criterion its [boundaries] section names, the lines of its grid's
dataset to search along, every boundary located on them (and continued in two parameters when
asked), written atomically to NAME.boundaries.h5 beside the grid's dataset (:func:`run_boundaries`,
the command `mechsweep boundaries`), with the warnings a user should read first."""
from __future__ import annotations

import datetime as _dt
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from .. import cf
from .. import status as st
from .continuation import continue_all
from .search import (BAND_EDGE, BOUND_DESCRIPTIONS, BOUND_MEANINGS, CRITERION, PARAMETER, Criterion, accuracy_text,
                     encoded, from_integration, locate)

def criterion_of(scene, spec=None) -> Criterion:
    """The :class:`Criterion` of a scene's [boundaries] section (or of ``spec``, a scene.Boundaries)."""
    b = spec if spec is not None else scene.boundaries
    if b.criterion is None:
        codes = {name: code for code, name in st.MEANINGS.items()}
        return Criterion(status_change=(codes[b.status_change[0]], codes[b.status_change[1]]))
    kind = None
    if scene.model.output(b.criterion).kind == "floquet_max" and f"{b.criterion}_angle" in scene.model.output_names():
        kind = f"{b.criterion}_angle"
    return Criterion(output=b.criterion, level=b.level, accuracy=b.criterion_accuracy, angle_output=kind)


def sibling_path(data: str | os.PathLike) -> Path:
    """Where the boundaries of the dataset ``data`` are written by default: DATA.boundaries.h5."""
    data = Path(data)
    return data.with_name(data.stem + ".boundaries.h5")


def base_rows(scene, along: str) -> tuple[np.ndarray, int, tuple]:
    """Parameter rows of every combination of the axes other than ``along`` (C order of the scene's
    axes), the column of ``along``, and the other axes."""
    others = [a for a in scene.axes if a.name != along]
    names = scene.model.param_names()
    grids = np.meshgrid(*[encoded(scene, a) for a in others], indexing="ij") if others else []
    L = int(np.prod([a.size for a in others], dtype=np.int64)) if others else 1
    rows = np.empty((L, len(names)))
    other_pos = {a.name: k for k, a in enumerate(others)}
    for c, prm in enumerate(scene.model.params):
        if prm.name in other_pos:
            rows[:, c] = grids[other_pos[prm.name]].ravel()
        elif prm.name in scene.fixed:
            rows[:, c] = prm.encode(scene.fixed[prm.name])
        elif prm.name == along:
            rows[:, c] = np.nan
        else:
            rows[:, c] = prm.default
    return rows, names.index(along), tuple(others)


def locate_dataset(scene, ds, spec=None):
    """Locate the boundaries a scene's [boundaries] section (or ``spec``) asks for, bracketed by the
    scene's finished dataset ``ds``. Returns a new xarray Dataset (dims: the other axes, crossing)."""
    import xarray as xr

    from .. import __version__

    b = spec if spec is not None else scene.boundaries
    crit = criterion_of(scene, b)
    along = b.along
    axis = next(a for a in scene.axes if a.name == along)
    rows, col, others = base_rows(scene, along)
    dims = [a.name for a in scene.axes]
    order = [d for d in dims if d != along] + [along]
    L, G = rows.shape[0], axis.size

    def grid_of(name):
        return np.asarray(ds[name].transpose(*order).values).reshape(L, G)

    t0 = time.perf_counter()
    if crit.output is not None:
        res = locate(scene, crit, rows, col, encoded(scene, axis), rtol=b.rtol,
                     grid_g=grid_of(crit.output) - crit.level,
                     grid_angle=grid_of(crit.angle_output) if crit.angle_output and crit.angle_output in ds else None)
    else:
        res = locate(scene, crit, rows, col, encoded(scene, axis), rtol=b.rtol, grid_status=grid_of("status"))
    wall = time.perf_counter() - t0
    shape = tuple(a.size for a in others) + (res.location.shape[1],)
    odims = tuple(a.name for a in others) + ("crossing",)
    prm = scene.model.param(along)
    coords = {a.name: ds[a.name] for a in others}
    coords["crossing"] = ("crossing", np.arange(shape[-1]), {"long_name": "index of the crossing along " + along,
                                                             "units": "1"})
    if crit.output is not None:
        what = f"{crit.output} = {crit.level:g}"
    else:
        what = f"status {b.status_change[0]} -> {b.status_change[1]}"

    def var(values, unit, long_name, **attrs):
        return (odims, values.reshape(shape), {"units": unit, "long_name": long_name, **attrs})

    codes = np.array(sorted(BOUND_MEANINGS), dtype=np.int8)
    rising = ("the criterion rises through its level" if crit.output else
              f"status {b.status_change[0]} below, {b.status_change[1]} above")
    data = {
        "boundary": var(res.location, prm.unit, f"{along} ({prm.long_name}) where {what}"),
        "boundary_width": var(res.width, prm.unit, f"width of the final bracket of {along} (both ends evaluated)"),
        "boundary_bound": var(res.bound, "1", "which accuracy bound applied (-1: no crossing)",
                              flag_values=codes, flag_meanings=" ".join(BOUND_MEANINGS[c] for c in codes),
                              comment="; ".join(f"{BOUND_MEANINGS[c]}: {BOUND_DESCRIPTIONS[c]}" for c in codes)),
        "boundary_direction": var(res.direction, "1", f"+1: {rising} as {along} grows; -1 the reverse; 0 no crossing"),
        "boundary_evaluations": var(res.evaluations, "1", "criterion evaluations spent locating this crossing "
                                    "(after the grid)"),
    }
    if crit.angle_output:
        data["boundary_kind"] = var(res.kind, "1", "critical Floquet multiplier on the unstable side: +1 real "
                                    "positive, -1 real negative, 0 complex pair")
        data["boundary_angle"] = var(res.angle, "rad", "argument of the critical Floquet multiplier on the unstable "
                                     "side, in [0, pi]: on the boundary the multiplier is exp(+-i angle)")
    located = res.bound[(res.bound == PARAMETER) | (res.bound == CRITERION) | (res.bound == BAND_EDGE)]
    ev = res.evaluations[res.bound >= 0]
    created = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    attrs = {
        "Conventions": cf.CONVENTIONS,
        "title": f"boundaries of {scene.name} along {along}",
        "source": cf.source(scene.model, __version__),
        "history": cf.history(created, f"mechsweep.boundaries.run_boundaries(scene {scene.name!r})", __version__),
        "references": cf.references(scene.model),
        "mechsweep_kind": "boundaries",
        "model": scene.model.name,
        "along": along,
        # the along axis's span (its encoded grid): the scale below which a bracket's width is read
        # as absolute (|x| <= ABS_FLOOR * span, as the locator's tolerance does; `mechsweep info`)
        "along_span": float(np.ptp(encoded(scene, axis))) if axis.size > 1 else 1.0,
        "criterion": crit.output or "status",
        **({"level": crit.level} if crit.output else {"status_change": " ".join(b.status_change)}),
        "rtol": b.rtol,
        "boundaries": str(b.as_dict()),
        "scene": scene.text,
        "scene_canonical": scene.canonical(),
        "created": created,
        "mechsweep_version": __version__,
        "wall_time_s": wall,
        "evaluate_calls": res.calls,
        "evaluated_points": res.points,
        "located": int(located.size),
        "evaluations_per_point_mean": float(ev.mean()) if ev.size else 0.0,
        "evaluations_per_point_max": int(ev.max()) if ev.size else 0,
    }
    if crit.output is not None:
        attrs["criterion_accuracy"] = accuracy_text(scene, crit)
    from ..model import sources

    attrs.update(sources.record(scene.model).attrs(scene.base or None))  # what the points were computed from
    if b.continue_in is not None:
        t0 = time.perf_counter()
        cdata, ccoords, n_eval, n_calls = continue_all(scene, crit, b, res, rows, others)
        data.update(cdata)
        coords.update(ccoords)
        attrs.update(continue_in=b.continue_in, continuation_wall_time_s=time.perf_counter() - t0,
                     continuation_evaluated_points=n_eval, continuation_calls=n_calls)
    if scene.solver is not None:
        for k, v in scene.solver.as_dict().items():
            attrs[f"solver_{k}"] = v
    return xr.Dataset(data, coords=coords, attrs=attrs)


def write_atomic(ds, target: str | os.PathLike) -> Path:
    """Write ``ds`` to ``target`` through a temporary file in the same folder and a rename: an
    existing file is replaced whole or not at all."""
    target = Path(target)
    fd, tmp = tempfile.mkstemp(prefix="." + target.name + ".", suffix=".tmp", dir=target.parent)
    os.close(fd)
    try:
        # strings (a categorical axis) as CF character arrays, as a run's dataset stores them (store/write.py)
        chars = {k: {"dtype": "S1"} for k, v in ds.variables.items() if v.dtype.kind in "OSUT"}
        ds.to_netcdf(tmp, engine="h5netcdf", encoding=chars)
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return target


def accuracy_warning(scene) -> str | None:
    """Why a given ``criterion_accuracy`` cannot be trusted (None: it can, or none was given): below
    about 100 rtol |level|, the accuracy the solver's rtol gives an integrated criterion, the band
    is narrower than the criterion's own error, and the search may lose boundaries or stop in the
    noise."""
    b = scene.boundaries
    if b is None or b.criterion_accuracy is None or b.criterion is None or scene.solver is None:
        return None
    if not from_integration(scene.model, b.criterion) or b.level == 0.0:
        return None
    floor = 100.0 * scene.solver.rtol * abs(b.level)
    if b.criterion_accuracy >= floor:
        return None
    return (f"boundaries.criterion_accuracy = {b.criterion_accuracy:g} is below the accuracy solver.rtol = "
            f"{scene.solver.rtol:g} gives the criterion (about 100 rtol |level| = {floor:g}): boundaries may be "
            f"lost or located in the noise; tighten solver.rtol to {b.criterion_accuracy / (100.0 * abs(b.level)):g} "
            "or less, or leave criterion_accuracy out")


def status_warning(scene) -> str | None:
    """Why a ``status_change`` criterion may locate nothing: it names a status the model does not
    list among those its points can get (``possible_statuses``: without this warning such a scene
    locates 0 boundaries with no word why). A warning, not a refusal: a model's list may be incomplete."""
    b = scene.boundaries
    if b is None or b.criterion is not None or b.status_change is None:
        return None
    listed = {st.MEANINGS[c] for c in scene.model.possible_statuses()}
    missing = [name for name in b.status_change if name not in listed]
    if not missing:
        return None
    return (f"boundaries.status_change names {', '.join(repr(m) for m in missing)}, which model "
            f"{scene.model.name!r} does not list among its statuses ({', '.join(sorted(listed))}): "
            "there may be no such boundary to locate")


def warnings_for(scene) -> list[str]:
    """What a [boundaries] section may get wrong without being invalid (accuracy, statuses)."""
    return [text for text in (accuracy_warning(scene), status_warning(scene)) if text]


def run_boundaries(scene_or_path, *, data=None, output=None, threads=None, progress=False, warn=True):
    """The scene's [boundaries] pass: its grid (computed, or completed with resume, unless finished),
    then the located boundaries, written atomically to ``output`` (default: DATA.boundaries.h5).
    The grid's dataset is only read. Returns (path written, the boundaries Dataset). ``warn``: a
    UserWarning for each of ``warnings_for`` (the CLI prints them itself)."""
    from ..errors import InputError
    from ..execution.execute import threads as _threads
    from ..execution.runner import compute
    from ..scene import Scene, load_scene
    from ..errors import StoreError
    from ..store.read import open_dataset

    scene = scene_or_path if isinstance(scene_or_path, Scene) else load_scene(scene_or_path)
    if scene.boundaries is None:
        raise InputError(f"scene {scene.name!r} has no [boundaries] section; add one, e.g. "
                         "[boundaries] along = \"AXIS\", criterion = \"OUTPUT\", level = 1.0")
    for text in warnings_for(scene) if warn else ():
        import warnings
        warnings.warn(text, UserWarning, stacklevel=2)
    data = Path(data if data is not None else scene.storage.path)
    target = Path(output) if output is not None else sibling_path(data)
    if target.resolve() == data.resolve():
        raise StoreError(f"boundaries output {target} is the grid's dataset itself; choose another path with -o")
    if not target.parent.is_dir():
        raise StoreError(f"the folder {target.parent} for output {target} does not exist; create it first")
    if target.exists() and not target.is_file():
        raise StoreError(f"{target} exists and is not a regular file; choose another path with -o")
    if target.is_file():
        with open(target, "rb") as f:
            head = f.read(8)
        if head and head != b"\x89HDF\r\n\x1a\n":
            raise StoreError(f"{target} exists and is not an HDF5 dataset; it would be overwritten: "
                             "choose another path with -o")
    compute(scene, output=data, resume=True, threads=threads, progress=progress)
    ds = open_dataset(data)
    with _threads(threads):
        out = locate_dataset(scene, ds)
    return write_atomic(out, target), out
