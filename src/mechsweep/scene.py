"""Scene files: TOML (or an equivalent dict) -> a validated, frozen :class:`Scene`.

Validation happens once, here. Every problem is reported with its key path, the bad
value and what is allowed; all problems of a scene are reported together.
"""
from __future__ import annotations

import difflib
import json
import math
import re
import reprlib
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from .errors import InputError
from .models import MODELS, ModelSpec

SECTIONS = ("scene", "axes", "fixed", "solver", "storage", "execution", "boundaries")
MAX_POINTS = 2**40  # beyond this a flat int64 index and any disk are hopeless
# Values per axis. The grid itself is never expanded (a chunk is computed from the axes' ranges),
# but a reader of the dataset (xarray) loads each axis's coordinate in full when it opens it:
# 8 bytes per value, 80 MB at this limit. Grids beyond it are built from more axes.
MAX_AXIS_POINTS = 10**7
MAX_KEY_DEPTH = 32  # dotted keys a.b.c...: tomllib's time grows with the square of the depth
_DEEP_KEY = re.compile(r"(?<![A-Za-z0-9_-])(?:(?:[A-Za-z0-9_-]++|\"[^\"\n]*+\"|'[^'\n]*+')[ \t]*+\.[ \t]*+)"
                       + "{" + str(MAX_KEY_DEPTH) + ",}")


class SceneError(InputError):
    """An invalid scene (the command line's exit code 2).

    ``problems`` lists one message per bad key, each naming the key, the bad value and what is
    allowed; ``source`` is the scene's file (or ``"scene"`` for a dict)."""

    def __init__(self, problems: list[str], source: str = "scene"):
        self.problems = list(problems)
        self.source = source
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"invalid {source}:\n{lines}")


@dataclass(frozen=True)
class Axis:
    """One axis of the grid.

    A range axis is kept as the user wrote it, ``(start, stop, num, spacing)``, and never expanded
    here: ``array(lo, hi)`` computes any stretch of its values on demand, so a scene, its
    canonical form and the chunk plan stay small whatever ``num`` is. Its values are those of
    ``numpy.linspace(start, stop, num)`` (``spacing = "linear"``) or ``numpy.geomspace`` (``"log"``),
    bit for bit, with both ends exactly as written. A list axis keeps its values as written.
    """

    name: str
    spacing: str  # "linear", "log" or "list"
    start: float | None = None  # range axes
    stop: float | None = None
    num: int = 0
    items: tuple = ()  # list axes: floats, or strings for a categorical parameter

    @classmethod
    def of_list(cls, name: str, values) -> "Axis":
        return cls(name, "list", items=tuple(values))

    @classmethod
    def of_range(cls, name: str, start: float, stop: float, num: int, spacing: str = "linear") -> "Axis":
        return cls(name, spacing, start=float(start), stop=float(stop), num=int(num))

    @property
    def size(self) -> int:
        return len(self.items) if self.spacing == "list" else self.num

    @property
    def ends(self) -> tuple:
        """First and last value (of a range: its extremes, a range being monotone)."""
        return (self.items[0], self.items[-1]) if self.spacing == "list" else (self.start, self.stop)

    def array(self, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """Values ``lo`` to ``hi - 1`` (float64; a categorical list gives its strings as objects).
        Memory is that of the stretch asked for, not of the axis."""
        n = self.size
        hi = n if hi is None else hi
        lo, hi = max(0, min(lo, n)), max(0, min(hi, n))
        if self.spacing == "list":
            part = self.items[lo:hi]
            return np.array(part, dtype=object if part and isinstance(part[0], str) else float)
        return _range_values(self.start, self.stop, self.num, self.spacing, lo, hi)

    @property
    def values(self) -> np.ndarray:
        """All values at once: 8 bytes per value. The engine itself uses ``array(lo, hi)``."""
        return self.array()

    def spec(self):
        """JSON form: a list axis as its list, a range axis as its four numbers."""
        if self.spacing == "list":
            return list(self.items)
        return {"start": self.start, "stop": self.stop, "num": self.num, "spacing": self.spacing}


def _range_values(start: float, stop: float, num: int, spacing: str, lo: int, hi: int) -> np.ndarray:
    """Values lo..hi-1 of numpy.linspace(start, stop, num) or numpy.geomspace(start, stop, num),
    computed as numpy does (value i = i * step + start, the last one = stop; log: 10 ** that in
    log10), without making the others."""
    div = num - 1
    if spacing == "log":
        a, b = float(np.log10(start)), float(np.log10(stop))
    else:
        a, b = start, stop
    i = np.arange(lo, hi, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        delta = np.float64(b) - np.float64(a)
        if div > 0:
            step = delta / div
            if step == 0:  # numpy's path for subnormal steps
                y = (i / div) * delta
            else:
                y = i * step
        else:
            y = i * delta
        y += a
        if spacing == "log":
            y = np.power(10.0, y)
    if lo == 0 and hi > 0 and spacing == "log":
        y[0] = start
    if num > 1 and hi == num and hi > lo:
        y[-1] = stop
    return y


@dataclass(frozen=True)
class Solver:
    """Numerical settings: common ones, plus the model's own :class:`Setting` values."""

    method: str = "dop853"
    rtol: float = 5e-11  # measured: period error <= 5.7e-11 for epsilon in [-0.99, 1e4];
    atol: float = 1e-12  # rtol = 1e-10 reaches 1.2e-10 near the soft separatrix
    max_steps: int = 100_000
    settings: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))

    @classmethod
    def for_model(cls, model: ModelSpec, **overrides) -> "Solver":
        """Defaults for ``model``; keyword overrides may name common or model settings."""
        settings = {st.name: st.default for st in model.settings}
        common = {k: v for k, v in overrides.items() if k not in settings}
        settings.update({k: v for k, v in overrides.items() if k in settings})
        return cls(**common, settings=MappingProxyType(settings))

    def as_dict(self) -> dict:
        return {"method": self.method, "rtol": self.rtol, "atol": self.atol, "max_steps": self.max_steps,
                **dict(self.settings)}


SOLVER_LIMITS = {
    "rtol": (1e-15, 0.1),
    "atol": (1e-300, 1.0),
    "max_steps": (1, 10**9),
}

# Usable ranges of the tolerances by method, measured on every shipped scene with each method it
# offers (tests/data/solver_limits.py; docs/scenes.md, "Solver settings: usable ranges"). The adaptive
# methods scale each error by atol + rtol |y| and square it: where a state is zero (a start from rest)
# that is (rate / atol)^2, beyond the largest float64 (1.8e308) once rate / atol > 1.3e154. Below
# ATOL_FLOOR that happens for any rate above 1.3e4; every integrated point of every shipped scene
# ended nonfinite with radau from atol 1e-160 (most from 1e-155), with dop853 and auto from 1e-200
# (some from 1e-170); the Duffing and torsional scenes' points are at 1e-150 as at the default
# (the others fail earlier, see ATOL_WARN).
# The symplectic method takes a fixed step from rtol and never reads atol.
ADAPTIVE_METHODS = ("dop853", "radau", "auto")
ATOL_FLOOR = 1e-150
_NORM_OVERFLOW = math.sqrt(sys.float_info.max)  # 1.34e154
# Below ATOL_WARN the error control is purely relative near a state that passes through or stays
# at zero, and asks there for errors below float64 rounding: points of shipped scenes ended
# max_steps or step_underflow from atol 1e-20 (vibrating_pendulum, radau) and 1e-30 (autobalancer).
ATOL_WARN = 1e-20
# radau raises a smaller rtol to 100 eps, as scipy's Radau does (ode/radau.py, MIN_RTOL)
RADAU_MIN_RTOL = 100.0 * float(np.finfo(np.float64).eps)


@dataclass(frozen=True)
class Storage:
    path: str
    chunk_size: int | None = None  # grid points per chunk; None = chosen by the runner


@dataclass(frozen=True)
class Execution:
    scheduler: str | None = None  # dask.distributed scheduler address; None = local threads
    # seconds a cluster run waits for a lost scheduler, or with no worker, before it stops
    worker_timeout: float = 120.0
    # the kernels' route where SIMD lanes apply: "auto" (where they pay), "always" or "never";
    # the results are bitwise the same either way, so it is not part of the scene's identity
    lanes: str = "auto"

    def use_lanes(self) -> bool | None:
        """The route as the kernels take it: True (lanes), False (one point at a time) or None (auto)."""
        return LANES_CHOICES[self.lanes]


# [execution] lanes -> the kernels' route (True, False, None: automatic; plan.choose_route decides with it first)
LANES_CHOICES = {"auto": None, "always": True, "never": False}


@dataclass(frozen=True)
class Boundaries:
    """The scene's [boundaries] section: where a criterion crosses along one axis (boundaries.py).

    Either ``criterion`` (an output of the scene) crossing ``level``, or ``status_change`` (two
    status names: the boundary between points of the first and of the second). ``rtol``: relative
    tolerance in the parameter; ``criterion_accuracy``: absolute accuracy of the criterion in its
    unit (None: from the solver, see boundaries.criterion_accuracy)."""

    along: str
    criterion: str | None = None
    level: float = math.nan
    status_change: tuple[str, str] | None = None
    rtol: float = 1e-10
    criterion_accuracy: float | None = None
    continue_in: str | None = None  # a second axis: follow each located boundary in (along, continue_in)

    def as_dict(self) -> dict:
        d = {"along": self.along, "rtol": self.rtol}
        if self.continue_in is not None:
            d["continue_in"] = self.continue_in
        if self.criterion is not None:
            d.update(criterion=self.criterion, level=self.level)
            if self.criterion_accuracy is not None:
                d["criterion_accuracy"] = self.criterion_accuracy
        else:
            d["status_change"] = list(self.status_change)
        return d


BOUNDARY_KEYS = ("along", "criterion", "level", "status_change", "rtol", "criterion_accuracy", "continue_in")
BOUNDARY_RTOL = (1e-15, 1e-2)


@dataclass(frozen=True)
class Scene:
    """A validated scene: what to sweep, how to compute it and where to store it (frozen).

    Made by :func:`load_scene` from a TOML file or a dict, after every key and value was checked;
    :func:`mechsweep.run` accepts it wherever it accepts a path or a dict. Its fields are the
    scene's sections (docs/scenes.md lists every key).

    Attributes
    ----------
    name : str
        ``[scene] name``: the dataset's title and default file name.
    model : ModelSpec
        The model's declaration (built-in or a user's), with its parameters, outputs and kernels.
    outputs : tuple of str
        The outputs asked for; only these are stored (:attr:`computed_outputs` adds what they
        depend on).
    axes : tuple of Axis
        The grid's axes in order: each becomes a dimension of the dataset.
    fixed : Mapping[str, Any]
        The parameters given one value.
    solver : Solver or None
        The ``[solver]`` settings; None when no requested output needs integration.
    storage : Storage
        ``[storage]``: the dataset's path (relative to the working directory) and chunk size.
    text : str
        The scene as written (TOML), stored with the dataset.
    execution : Execution
        ``[execution]``: a dask scheduler, its timeout, and the kernels' route (``lanes``).
    base : str
        The absolute folder a model file path (``"file.py:NAME"``) was resolved against ("" when
        the model is not named by a file path).
    model_key : str
        sha256 of a user model's source ("" for a built-in model): part of the scene's identity.
    boundaries : Boundaries or None
        The ``[boundaries]`` section (docs/boundaries.md), or None.

    Examples
    --------
    >>> import mechsweep
    >>> scene = mechsweep.load_scene({"scene": {"name": "s", "model": "duffing", "outputs": ["period_exact"]},
    ...                               "axes": {"A": {"start": 0.1, "stop": 1.0, "num": 10}},
    ...                               "fixed": {"mu": 1.0, "omega": 1.0}})
    >>> scene.shape, scene.n_points, scene.solver is None
    ((10,), 10, True)
    """

    name: str
    model: ModelSpec
    outputs: tuple[str, ...]
    axes: tuple[Axis, ...]
    fixed: Mapping[str, Any]
    solver: Solver | None  # None when no requested output needs integration
    storage: Storage
    text: str  # the scene as the user wrote it (TOML), stored with the dataset
    execution: Execution = Execution()
    # absolute folder a user model file path of ``model`` ("file.py:NAME") was resolved against;
    # "" when the model is not named by a file path. Stored with a run and sent to dask workers,
    # so the stored text is re-read against it from any working directory.
    base: str = ""
    # sha256 of the source a user model is declared in (its model file or module; see
    # _model_source_key); "" for a built-in model. Part of the canonical form: two files declaring
    # a model of one name are two scenes, the same file is the same scene.
    model_key: str = ""
    # the [boundaries] section, None without one; not part of the canonical form (it does not
    # change the grid's dataset: boundaries are located in a separate pass, boundaries.py)
    boundaries: Boundaries | None = None

    @property
    def shape(self) -> tuple[int, ...]:
        """The grid's shape: the number of values of each axis, in order."""
        return tuple(a.size for a in self.axes)

    def __repr__(self) -> str:
        """One line: name, model, grid, outputs, method (the dataclass's would print the model's
        whole declaration and the scene's text)."""
        grid = " x ".join(f"{a.name} {a.size}" for a in self.axes) or "one point"
        method = f", method {self.solver.method}" if self.solver is not None else ""
        return (f"<Scene {self.name!r}: model {self.model.name}, {self.n_points:,} points ({grid}), "
                f"outputs {', '.join(self.outputs)}{method}>")

    def _repr_html_(self) -> str:
        """A table for notebooks: the model, each axis with its values and unit, the fixed values,
        the outputs with their units, the solver settings and where the dataset goes."""
        from html import escape

        def unit(u):
            return f" [{escape(u)}]" if u and u != "1" else ""

        def values(a: Axis) -> str:
            if a.spacing == "list":
                shown = ", ".join(str(v) for v in a.items[:6]) + (", ..." if a.size > 6 else "")
                return f"{escape(shown)} ({a.size} values)"
            return f"{a.start:g} .. {a.stop:g}, {a.num} values ({a.spacing})"

        rows = [("model", f"<code>{escape(self.model.name)}</code>: {escape(self.model.description or '')}"),
                ("grid", f"{self.n_points:,} points")]
        rows += [(f"axis <code>{escape(a.name)}</code>", values(a) + unit(self.model.param(a.name).unit))
                 for a in self.axes]
        if self.fixed:
            rows.append(("fixed", ", ".join(f"<code>{escape(k)}</code> = {escape(str(v))}"
                                            f"{unit(self.model.param(k).unit)}" for k, v in self.fixed.items())))
        rows.append(("outputs", ", ".join(f"<code>{escape(o)}</code>{unit(self.model.output(o).unit)}"
                                          for o in self.outputs)))
        if self.solver is not None:
            rows.append(("solver", escape(", ".join(f"{k} = {v}" for k, v in self.solver.as_dict().items()))))
        rows.append(("dataset", f"<code>{escape(self.storage.path)}</code>"))
        body = "".join(f"<tr><th style=\"text-align:left\">{k}</th><td style=\"text-align:left\">{v}</td></tr>"
                       for k, v in rows)
        return (f"<div><strong>mechsweep Scene</strong> <code>{escape(self.name)}</code>"
                f"<table>{body}</table></div>")

    @property
    def n_points(self) -> int:
        """The number of grid points (1 for a scene without axes)."""
        return int(np.prod(self.shape, dtype=np.int64)) if self.axes else 1

    @property
    def computed_outputs(self) -> tuple[str, ...]:
        """Requested outputs plus what they depend on."""
        return self.model.closure(self.outputs)

    def canonical(self) -> str:
        """A normalised JSON form: two scenes that compute the same dataset compare equal.

        A range axis appears as its (start, stop, num, spacing), never expanded, so the form
        stays a few kB for any grid; a list axis as its list."""
        return json.dumps(self._canonical_dict(), sort_keys=True)

    def _canonical_dict(self) -> dict:
        form = {
            "model": self.model.name,
            "outputs": list(self.outputs),
            "axes": [[a.name, a.spec()] for a in self.axes],
            "fixed": {k: self.fixed[k] for k in sorted(self.fixed)},
            "solver": None if self.solver is None else self.solver.as_dict(),
        }
        if self.model_key:  # a user model (a built-in's form is unchanged, so older datasets match)
            form["model_source_sha256"] = self.model_key
        return form

    def same_as(self, stored: str) -> bool:
        """Whether the canonical form ``stored`` (of a journal or a dataset) describes this scene.
        Also accepts the older form, in which range axes were written out value by value (journals
        and datasets of older versions keep it; compared here axis by axis, as floats, bit for bit)."""
        if stored == self.canonical():
            return True
        if not isinstance(stored, str) or not stored.startswith("{"):
            return False
        try:
            old = json.loads(stored)
        except ValueError:
            return False
        aliases = self.model.aliases()  # a form written when a parameter had its former name
        if aliases and isinstance(old, dict) and isinstance(old.get("axes"), list) and isinstance(old.get("fixed"), dict):
            old["axes"] = [[aliases.get(a[0], a[0]), *a[1:]] if isinstance(a, list) and a and isinstance(a[0], str)
                           else a for a in old["axes"]]
            old["fixed"] = {aliases.get(k, k): v for k, v in old["fixed"].items()}
            if json.dumps(old, sort_keys=True) == self.canonical():
                return True
        new = self._canonical_dict()
        if not isinstance(old, dict) or set(old) != set(new) or not isinstance(old.get("axes"), list):
            return False
        if any(json.dumps(old[k], sort_keys=True) != json.dumps(new[k], sort_keys=True) for k in new if k != "axes"):
            return False
        if len(old["axes"]) != len(self.axes):
            return False
        for item, axis in zip(old["axes"], self.axes):
            if not (isinstance(item, list) and len(item) == 2 and item[0] == axis.name and isinstance(item[1], list)):
                return False
            if axis.spacing == "list":
                if item[1] != list(axis.items):
                    return False
            elif len(item[1]) != axis.size or not all(isinstance(v, (int, float)) for v in item[1]):
                return False
            elif not np.array_equal(np.array(item[1], dtype=float), axis.array()):
                return False
        return True


# ----------------------------------------------------------------------------- loading
def load_scene(source: str | Path | Mapping, models: Mapping | None = None) -> Scene:
    """Load and validate a scene from a TOML file or a dict with the same structure.

    Every problem is collected and reported at once; nothing runs and nothing is written.

    Parameters
    ----------
    source : str, pathlib.Path or Mapping
        The scene file's path, or a dict with its sections (``{"scene": {...}, "axes": {...},
        ...}``). A model file named in a file's ``[scene] model`` is relative to the file's folder;
        in a dict, to the working directory.
    models : Mapping, optional
        Model name -> :class:`~mechsweep.model.OdeModel` (or a ``ModelSpec``) defined in Python,
        for a scene whose ``model`` is that name.

    Returns
    -------
    Scene
        The validated, frozen scene.

    Raises
    ------
    SceneError
        The scene is not valid: its ``problems`` list one message per bad key, each naming the
        key, the bad value and what is allowed.
    """
    if isinstance(source, Mapping):
        source = _plain(source)
        if (why := _unstorable_in(source)) is not None:
            raise SceneError([why], "scene")
        text = to_toml(source)
        if len(text) > MAX_SCENE_BYTES:
            raise SceneError([f"the scene's TOML form is {_mib(len(text))}; a scene is at most "
                              f"{_mib(MAX_SCENE_BYTES)} ({SCENE_TOO_BIG_ADVICE})"], "scene")
        return validate(source, text=text, label="scene", models=models)
    path = Path(source)
    label = str(path)
    raw = read_scene_file(path)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError([f"{label!r} is not UTF-8 text (byte {exc.start})"], label) from None
    return load_scene_text(text, label, base=path.resolve().parent, models=models)


# A scene is a page of TOML: a few kB, and a list axis of a million values is about 13 MiB (about 3 s
# to parse). Nothing beyond this is read: a device, a dataset or a log given as the scene by mistake
# is refused before its bytes fill the memory.
MAX_SCENE_BYTES = 16 * 2**20
SCENE_TOO_BIG_ADVICE = "give a long axis as a range { start, stop, num }, not as a list of values"


def _mib(n: int) -> str:
    return f"{n / 2**20:.3g} MiB" if n >= 2**20 else f"{n:,} bytes"


def _file_kind(mode: int) -> str:
    """What a file system entry of this st_mode is, for a message."""
    import stat

    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISREG, "a regular file")):
        if test(mode):
            return name
    return "not a regular file"


def read_scene_file(path: Path) -> bytes:
    """The bytes of the scene file ``path``: a regular file of at most MAX_SCENE_BYTES. A folder,
    a pipe, a socket or a device is refused without reading it (a pipe nobody writes would block,
    /dev/zero never ends), as is a larger file; every refusal names what the path is."""
    import errno
    import os
    import stat

    label = str(path)

    def refuse(why: str):
        raise SceneError([why], "scene")

    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        if os.path.islink(path):
            refuse(f"{label!r} is a broken symbolic link (to {os.readlink(path)!r}); a scene is a TOML file")
        refuse(f"file {label!r} does not exist")
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            refuse(f"{label!r} is a symbolic link loop (it leads back to itself); a scene is a TOML file")
        refuse(f"cannot read {label!r}: {_os_reason(exc)}")
    if stat.S_ISDIR(mode):
        refuse(f"{label!r} is a directory, not a scene file")
    if not stat.S_ISREG(mode):
        refuse(f"{label!r} is {_file_kind(mode)}, not a scene file; a scene is a regular TOML file")
    try:  # O_NONBLOCK: should the path have become a pipe since, the open does not wait for a writer
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as exc:
        refuse(f"cannot read {label!r}: {_os_reason(exc)}")
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            refuse(f"{label!r} is {_file_kind(info.st_mode)}, not a scene file; a scene is a regular TOML file")
        if info.st_size > MAX_SCENE_BYTES:
            refuse(f"{label!r} is {_mib(info.st_size)}; a scene file is at most {_mib(MAX_SCENE_BYTES)} "
                   f"({SCENE_TOO_BIG_ADVICE}); is it a scene?")
        parts, size = [], 0
        while size <= MAX_SCENE_BYTES:  # a file that grows, or that says it is empty (/proc), is read up to the cap
            block = os.read(fd, min(2**20, MAX_SCENE_BYTES + 1 - size))
            if not block:
                break
            parts.append(block)
            size += len(block)
        if size > MAX_SCENE_BYTES:
            refuse(f"{label!r} holds more than {_mib(MAX_SCENE_BYTES)}; a scene file is at most that "
                   f"({SCENE_TOO_BIG_ADVICE}); is it a scene?")
        return b"".join(parts)
    except OSError as exc:
        refuse(f"cannot read {label!r}: {_os_reason(exc)}")
    finally:
        os.close(fd)


def _os_reason(exc: OSError) -> str:
    from .errors import why_os_error

    return why_os_error(exc.errno, exc.strerror or str(exc))


def _plain(value):
    """A scene dict with numpy scalars and arrays made plain Python values (np.float64(2.0) is a
    number, like 2.0), as a TOML file would give them."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()] if value.ndim else _plain(value.item())
    if isinstance(value, np.generic):
        return value.item()
    return value


def load_scene_text(text: str, label: str = "scene", base: Path | str | None = None,
                    models: Mapping | None = None) -> Scene:
    """Load and validate a scene from its TOML text (e.g. the copy stored with a run).
    ``base``: the folder a user model file path ("my_models.py:NAME") is relative to (default: cwd)."""
    if len(text) > MAX_SCENE_BYTES:  # e.g. the scene text stored in a dataset someone made or edited
        raise SceneError([f"{label!r}: the scene text is {_mib(len(text))}; a scene is at most "
                          f"{_mib(MAX_SCENE_BYTES)} ({SCENE_TOO_BIG_ADVICE})"], label)
    if text.startswith("\ufeff"):
        raise SceneError([(f"{label!r} starts with a byte-order mark (BOM, bytes EF BB BF); "
                           "save it as UTF-8 without BOM")], label)
    deep = _DEEP_KEY.search(text)
    if deep:
        line = text.count("\n", 0, deep.start()) + 1
        raise SceneError([(f"TOML nesting too deep: a dotted key at line {line} has more than {MAX_KEY_DEPTH} "
                           "levels")], label)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError([f"TOML syntax error: {exc}"], label) from None
    except RecursionError:
        raise SceneError(["TOML nesting too deep"], label) from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise SceneError([f"TOML value not readable ({str(exc).split(';')[0]})"], label) from None
    return validate(data, text=text, label=label, base=base, models=models)


def validate(data: Mapping, *, text: str, label: str = "scene", base: Path | str | None = None,
             models: Mapping | None = None) -> Scene:
    p = _Problems()
    if not isinstance(data, Mapping):
        raise SceneError([f"a scene is a table of sections, got {type(data).__name__}"], label)
    for key in data:
        if key not in SECTIONS:
            p.unknown(key, key, SECTIONS, "section")
    head = _table(data, "scene", p, required=True)
    name = head.get("name")
    if not isinstance(name, str) or not name.strip():
        p.add("scene.name", f"{_short(name)} is not allowed; expected a non-empty string")
    elif (why := unstorable(name)) is not None:  # the dataset's title
        p.add("scene.name", f"{_short(name)} {why}; a dataset's title must be text HDF5 can store")
    for key in head:
        if key not in ("name", "model", "outputs", "description"):
            p.unknown(f"scene.{key}", key, ("name", "model", "outputs", "description"), "key")
    model = _model(head.get("model"), p, base, models)
    if model is None:
        raise SceneError(p.items, label)
    outputs = _outputs(head.get("outputs"), model, p)
    axes_table, fixed_table = _table(data, "axes", p), _table(data, "fixed", p)
    axes_table, fixed_table = _current_names(axes_table, model, "axes", p), _current_names(fixed_table, model, "fixed", p)
    axes = _axes(axes_table, model, p)
    fixed = _fixed(fixed_table, model, set(axes_table), p)
    given = set(axes_table) | set(fixed_table)  # a bad value is reported as bad, not as missing
    for prm in model.params:
        if prm.required and prm.name not in given:
            p.add(f"fixed.{prm.name}", f"missing; {model.name} needs {prm.name} "
                  f"({prm.long_name}, {prm.allowed()}) as an axis or a fixed value")
    if model.check is not None and not p.items:
        # list axes give their values; a range axis its two ends (a range is monotone: its extremes)
        values = {a.name: a.items if a.spacing == "list" else a.ends for a in axes} | {k: (v,) for k, v in fixed.items()}
        with np.errstate(all="ignore"):  # extreme values are judged by the check, not warned about
            p.items.extend(model.check(values))
    for out in outputs:
        missing = [q for q in model.output(out).needs_params if q not in given]
        if missing:
            p.add("scene.outputs", f"output {out!r} needs parameter(s) {', '.join(missing)}; "
                  "give them in [axes] or [fixed]")
    # [solver] is checked whether or not an output needs it: garbage there is refused either way
    solver = _solver(_table(data, "solver", p), model, p)
    if not model.needs_integration(outputs):
        solver = None
    elif (why := atol_problem(solver, model)) is not None:
        p.add("solver.atol", why)
    elif model.methods_for is not None and not p.items:
        allowed = model.methods_for(model.closure(outputs))
        if solver.method not in allowed:
            p.add("solver.method", f"{solver.method!r} is not offered by model {model.name!r} for the outputs "
                  f"{', '.join(outputs)} (allowed for them: {', '.join(allowed)})")
    storage = _storage(_table(data, "storage", p), name if isinstance(name, str) else "scene", p)
    execution = _execution(_table(data, "execution", p), p)
    refused = set(axes_table) - {a.name for a in axes}  # axes whose own values were refused (reported already)
    boundaries = (_boundaries(_current_axis_names(_table(data, "boundaries", p), model), model, axes, outputs, p, refused)
                  if "boundaries" in data else None)
    if axes:
        n = math.prod(a.size for a in axes)
        if n > MAX_POINTS:
            p.add("axes", f"the grid has {n:.3g} points; at most {MAX_POINTS:.3g} are allowed")
        elif storage.chunk_size is not None:
            _check_chunk_count(tuple(a.size for a in axes), storage.chunk_size, p)
    if not p.items:
        _check_storable(model, outputs, axes, fixed, solver, p)
    if p.items:
        raise SceneError(p.as_written(), label)
    return Scene(
        name=name.strip(),
        model=model,
        outputs=outputs,
        axes=tuple(axes),
        fixed=MappingProxyType(fixed),
        solver=solver,
        storage=storage,
        text=text,
        execution=execution,
        base=_model_folder(head.get("model"), base),
        model_key=_model_source_key(head.get("model"), model, base, models),
        boundaries=boundaries,
    )


# ----------------------------------------------------------------------------- text HDF5 can store
def unstorable(text: str) -> str | None:
    """Why ``text`` cannot be stored in an HDF5 (netCDF-4) dataset as a string, or None: HDF5 keeps
    strings as UTF-8 without NUL characters. A lone surrogate (e.g. from a file name whose bytes are
    not UTF-8) has no UTF-8 form."""
    if "\0" in text:
        return "contains a NUL character (\\x00)"
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as exc:
        return f"contains {text[exc.start]!r}, a lone surrogate that is not Unicode text (no UTF-8 form)"
    return None


def unstorable_name(name: str) -> str | None:
    """Why ``name`` cannot name a variable, dimension or attribute of a netCDF-4 dataset, or None."""
    if not isinstance(name, str) or not name:
        return "is empty"
    if (why := unstorable(name)) is not None:
        return why
    if "/" in name:
        return "contains '/', HDF5's path separator"
    if name in (".", ".."):
        return "is a path, not a name"
    return None


def _unstorable_in(value, key: str = "") -> str | None:
    """The first key or string of a scene dict that has no UTF-8 form (a lone surrogate): its TOML
    text, stored with the dataset, could not be read back. None when there is none."""
    if isinstance(value, Mapping):
        for k, v in value.items():
            where = f"{key}.{k}" if key else str(k)
            if isinstance(k, str) and (why := unstorable(k.replace("\0", ""))) is not None:
                return f"{_short_key(where)}: the key {_short(k)} {why}"
            if (why := _unstorable_in(v, where)) is not None:
                return why
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            if (why := _unstorable_in(v, f"{key}[{i}]")) is not None:
                return why
    elif isinstance(value, str) and (why := unstorable(value.replace("\0", ""))) is not None:
        return f"{_short_key(key)}: {_short(value)} {why}"
    return None


def _check_storable(model: ModelSpec, outputs, axes, fixed, solver, p: "_Problems") -> None:
    """Every string of the model's declaration and of the scene that a run writes into its dataset
    (names of variables, dimensions and attributes, units, long names, symbols, the values of
    categorical parameters, the model's name, source, references and status notes) must be text HDF5
    can store, and the names distinct (the path of a model file is checked in _model, before loading). A problem here would only show
    at the end of the run, when the file is written: it is reported now, naming what to fix."""
    where = f"model {model.name!r}"

    def text(what: str, value, advice: str = "fix the model's declaration") -> None:
        if isinstance(value, str) and (why := unstorable(value)) is not None:
            p.add("scene.model", f"{where}: {what} {_short(value)} {why}, which HDF5 cannot store in a dataset; "
                  + advice)

    def name(what: str, value) -> None:
        if (why := unstorable_name(value)) is not None:
            p.add("scene.model", f"{where}: {what} {_short(value)} {why}, which cannot name a variable or "
                  "attribute of a dataset; fix the model's declaration")

    text("name", model.name)
    text("source", model.source, "it names where the model was loaded from: move the model file (or module) to a "
         "path whose name is UTF-8 text")
    for ref in model.references:
        text("reference", ref)
    for code, note in model.status_notes:
        text(f"status note of code {code}", note)
    given = [a.name for a in axes] + list(fixed)
    for pname in given:
        prm = model.param(pname)
        name("parameter", prm.name)
        for attr in ("unit", "long_name", "symbol"):
            text(f"parameter {prm.name!r} {attr}", getattr(prm, attr))
    for axis in axes:
        if model.param(axis.name).categorical:
            for item in axis.items:
                text(f"choice of parameter {axis.name!r}", item)
    for pname, value in fixed.items():
        if model.param(pname).categorical:
            text(f"choice of parameter {pname!r}", value)
    dims, first = {}, {}
    settings = solver.settings if solver is not None else {}
    for oname in outputs:
        out = model.output(oname)
        name("output", out.name)
        for attr in ("unit", "long_name", "symbol", "kind"):
            text(f"output {out.name!r} {attr}", getattr(out, attr))
        for dim in out.extra_dims:
            if dim.name in dims and dims[dim.name] is not dim and not _same_values(dims[dim.name], dim, settings):
                # the file holds one coordinate per dimension name: the second would be written on the first's
                p.add("scene.model", f"{where}: outputs {first[dim.name]!r} and {out.name!r} both have a dimension "
                      f"{dim.name!r}, with other values; a dataset has one coordinate per dimension: give them "
                      "different names in the model's declaration")
            dims.setdefault(dim.name, dim)
            first.setdefault(dim.name, out.name)
    for dim in dims.values():
        name("dimension", dim.name)
        text(f"dimension {dim.name!r} unit", dim.unit)
        text(f"dimension {dim.name!r} long_name", dim.long_name)
    if solver is not None:
        for k in solver.settings:
            name("solver setting", k)
    # every variable of the dataset has a name of its own (an output named like a parameter, or
    # "status", would meet another variable of that name in the file)
    seen: dict[str, str] = {}
    own = ["status"] + (["n_steps", "n_rhs"] if solver is not None else [])
    for kind, names in (("the run's own variable", own), ("parameter", given), ("dimension", list(dims)),
                        ("output", list(outputs))):
        for n in names:
            if n in seen:
                p.add("scene.model", f"{where}: {kind} {n!r} has the name of {seen[n]} in the dataset; each "
                      "variable of a dataset needs a name of its own: rename it in the model's declaration")
            else:
                seen[n] = f"{kind} {n!r}"


def _same_values(a, b, settings) -> bool:
    """Whether two extra dimensions of one name have the same coordinate values."""
    try:
        return bool(np.array_equal(np.asarray(a.values(settings), dtype=float),
                                   np.asarray(b.values(settings), dtype=float)))
    except Exception:  # a declaration's own function failed: the run would say so; no claim here
        return True


# ----------------------------------------------------------------------------- sections
def _current_names(table: Mapping, model: ModelSpec, section: str, p: "_Problems") -> Mapping:
    """``table`` with each former name of a parameter (``Param.aliases``, e.g. the slider-crank's
    ``lambda``, now ``lam``) replaced by the parameter's name; both given is a problem."""
    aliases = model.aliases()
    if not aliases or not any(isinstance(k, str) and k in aliases for k in table):
        return table
    out = {}
    for key, value in table.items():
        name = aliases.get(key, key) if isinstance(key, str) else key
        if name != key and name in table:
            p.add(f"{section}.{key}", f"{key} is the former name of {name}, which is given too; keep one ({name})")
            continue
        if name != key:
            p.written[f"{section}.{name}"] = f"{section}.{key}"  # messages name the key as the scene wrote it
        out[name] = value
    return out


def _current_axis_names(table: Mapping, model: ModelSpec) -> Mapping:
    """The [boundaries] section with a former parameter name in along / continue_in made current."""
    aliases = model.aliases()
    renamed = {k: aliases[v] for k in ("along", "continue_in") if isinstance(v := table.get(k), str) and v in aliases}
    return {**table, **renamed} if renamed else table


class _Problems:
    def __init__(self):
        self.items: list[str] = []
        self._listed: set[str] = set()  # allowed lists already printed in full
        self.written: dict[str, str] = {}  # "fixed.lam" -> "fixed.lambda": a key given by a former name

    def as_written(self) -> list[str]:
        """The problems, each key as the scene wrote it."""
        out = []
        for item in self.items:
            key, sep, rest = item.partition(":")
            out.append(self.written.get(key, key) + sep + rest)
        return out

    def add(self, key: str, message: str) -> None:
        self.items.append(f"{key}: {message}")

    def unknown(self, key: str, name, allowed, what: str) -> None:
        word = name[:100] if isinstance(name, str) else _short(name)
        hint = difflib.get_close_matches(word, [str(a) for a in allowed], n=1, cutoff=0.5)
        tip = f"; did you mean {hint[0]!r}?" if hint else ""
        listed = ", ".join(map(str, allowed))
        # a long list printed once: a scene written for another model repeated 50 outputs per error
        text = "as above" if listed in self._listed and len(listed) > 80 else listed
        self._listed.add(listed)
        self.add(_short_key(key), f"unknown {what} {_short(name)}{tip} (allowed: {text})")


_REPR = reprlib.Repr()
_REPR.maxstring, _REPR.maxother, _REPR.maxlong, _REPR.maxlevel = 60, 60, 40, 3


def _short(value) -> str:
    """repr(value) cut to a readable length: a scene may hold huge or deeply nested values."""
    return _REPR.repr(value)


def _short_key(key: str) -> str:
    return key if len(key) <= 120 else key[:60] + "..." + key[-40:]


class _Shown:
    """Stands in for a value whose repr is too long to show in a message."""

    def __init__(self, value):
        self.text = _short(value)

    def __repr__(self) -> str:
        return self.text


def _value_problem(item, value) -> str | None:
    """``item.problem(value)`` of a Param or Setting, safe for values it cannot show or convert."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > sys.float_info.max:
        allowed = item.allowed() if hasattr(item, "allowed") else f"a number in [{item.lo:g}, {item.hi:g}]"
        return f"{_short(value)} is too large for a float (at most {sys.float_info.max:.4g}); expected {allowed}"
    if isinstance(value, (list, Mapping)) or (isinstance(value, str) and len(value) > 60):
        value = _Shown(value)
    return item.problem(value)


def _table(data: Mapping, key: str, p: _Problems, required: bool = False) -> Mapping:
    value = data.get(key)
    if value is None:
        if required:
            p.add(key, "missing section [" + key + "]")
        return {}
    if not isinstance(value, Mapping):
        p.add(key, f"expected a table [{key}], got {type(value).__name__} {_short(value)}")
        return {}
    return value


def _model(name, p: _Problems, base: Path | str | None = None, models: Mapping | None = None) -> ModelSpec | None:
    from .model import load

    if name is None:
        p.add("scene.model", f"missing; expected one of {', '.join(MODELS)}")
        return None
    if models and isinstance(name, str) and name in models:  # given from Python: run(scene, models={...})
        try:
            return load.from_object(name, models[name])
        except InputError as exc:
            p.add("scene.model", str(exc))
            return None
    if isinstance(name, str) and ":" in name:  # a user model: "file.py:NAME" or "package.module:NAME"
        where = str(Path(base or Path.cwd()) / name.rpartition(":")[0]) if load.is_file_ref(name) else name
        if (why := unstorable(where)) is not None:  # a run stores where the model came from with its dataset
            p.add("scene.model", f"the model's path {_short(where)} {why}; a dataset stores where its model came "
                  "from as UTF-8 text: move the model file (and the scene) to a path whose name is UTF-8 text")
            return None
        try:
            return load.resolve(name, Path(base) if base else None)
        except InputError as exc:
            p.add("scene.model", str(exc))
            return None
    if isinstance(name, str) and name not in MODELS:
        try:
            points = load.entry_points()
        except InputError as exc:
            p.add("scene.model", str(exc))
            return None
        if name in points:  # registered by an installed package (entry-point group mechsweep.models)
            try:
                return load.resolve(points[name].value)
            except InputError as exc:
                p.add("scene.model", f"entry point {name!r} ({load.ENTRY_POINT_GROUP}): {exc}")
                return None
    if not isinstance(name, str) or name not in MODELS:
        known = tuple(MODELS) + tuple(sorted(set(load.entry_points(quiet=True)) - set(MODELS)))
        known += tuple(sorted(set(models or ()) - set(known)))
        p.unknown("scene.model", name, known, "model")
        return None
    return MODELS[name]


def _model_source_key(name, spec: ModelSpec, base, models) -> str:
    """sha256 of the source file a user model is declared in: the model file ("file.py:NAME",
    resolved as load.resolve does), the module ("package.module:NAME", an entry point's target) or,
    for a model given from Python, the module its rhs (an OdeModel) or evaluate (a ModelSpec) is
    defined in; followed by the declaration (parameters, outputs, settings, methods; and the
    ``source`` of a ModelSpec given from Python, whose evaluate may live in mechsweep itself).
    Nothing that depends on where the file lies: the same file is the same model from any folder.
    "" for a built-in model."""
    import hashlib

    from .model import load

    if not isinstance(name, str) or (name in MODELS and MODELS[name] is spec and not (models and name in models)):
        return ""
    file, module = "", ""
    if models and name in models:
        obj = models[name]
        func = getattr(obj, "rhs", None) or getattr(obj, "evaluate", None)
        module = getattr(getattr(func, "py_func", func), "__module__", "") or ""
    elif ":" in name:
        left = name.rpartition(":")[0]
        if load.is_file_ref(name):
            path = Path(left)
            file = str((path if path.is_absolute() else Path(base or Path.cwd()) / path).resolve())
        else:
            module = left
    else:
        ep = load.entry_points(quiet=True).get(name)
        module = ep.value.rpartition(":")[0] if ep is not None else ""
    if module:
        file = load._FILES.get(module) or getattr(sys.modules.get(module), "__file__", "") or ""
    try:
        data = Path(file).read_bytes() if file else b""
    except OSError:
        data = b""
    given_spec = bool(models and name in models and isinstance(models[name], ModelSpec))
    data += repr((spec.name, spec.params, spec.outputs, spec.settings, spec.methods,
                  spec.source if given_spec else "")).encode()
    return hashlib.sha256(data).hexdigest()


def _model_folder(name, base) -> str:
    """The absolute folder a file-path model reference is relative to ("" for other models)."""
    from .model import load

    if isinstance(name, str) and load.is_file_ref(name):
        return str(Path(base).resolve() if base else Path.cwd())
    return ""


def _outputs(value, model: ModelSpec, p: _Problems) -> tuple[str, ...]:
    names = model.output_names()
    if not isinstance(value, list) or not value:
        p.add("scene.outputs", f"{_short(value)} is not allowed; expected a non-empty list of output names "
              f"from {', '.join(names)}")
        return ()
    good = []
    for item in value:
        if not isinstance(item, str) or item not in names:
            p.unknown("scene.outputs", item, names, f"output of model {model.name!r}")
        elif item in good:
            p.add("scene.outputs", f"{item!r} is listed twice")
        else:
            good.append(item)
    return tuple(good)


def _axes(table: Mapping, model: ModelSpec, p: _Problems) -> list[Axis]:
    axes = []
    # refuse a hopeless grid before validating its axes one by one, naming every axis size
    sizes = [spec.get("num") if isinstance(spec, Mapping) else len(spec) if isinstance(spec, list) else 1
             for spec in table.values()]
    n = math.prod(k if isinstance(k, int) and not isinstance(k, bool) and k >= 1 else 1 for k in sizes)
    if n > MAX_POINTS:
        p.add("axes", f"the grid would have {n:.3g} points "
              f"({' x '.join(f'{name} {k}' for name, k in zip(table, sizes))}); at most {MAX_POINTS:.3g} are allowed")
        return axes
    for name, spec in table.items():
        key = f"axes.{name}"
        if name not in model.param_names():
            p.unknown(key, name, model.param_names(), f"parameter of model {model.name!r}")
            continue
        prm = model.param(name)
        if isinstance(spec, list):
            axis = _list_axis(key, name, spec, prm, p)
        elif isinstance(spec, Mapping):
            axis = _range_axis(key, name, spec, prm, p)
        else:
            p.add(_short_key(key), f"{_short(spec)} is not allowed; expected a list of values or a table "
                  "{ start, stop, num, spacing }")
            axis = None
        if axis is not None:
            axes.append(axis)
    return axes


def _list_axis(key, name, values, prm, p) -> Axis | None:
    if not values:
        p.add(key, "an empty list gives an empty grid; give at least one value")
        return None
    if len(values) > MAX_AXIS_POINTS:
        p.add(key, f"{len(values)} values; at most {MAX_AXIS_POINTS} per axis")
        return None
    bad = [(i, _value_problem(prm, v)) for i, v in enumerate(values)]
    bad = [(i, msg) for i, msg in bad if msg]
    for i, msg in bad[:3]:
        p.add(f"{key}[{i}]", msg)
    if bad:
        return None
    if len(set(values)) != len(values):
        p.add(key, "values repeat; each grid value must be distinct")
        return None
    vals = tuple(values) if prm.categorical else tuple(float(v) for v in values)
    if len(set(vals)) != len(vals):  # e.g. 2**53 and 2**53 + 1: distinct integers, one float
        same = next(i for i, v in enumerate(vals) if vals.index(v) != i)
        p.add(key, f"{_short(values[vals.index(vals[same])])} and {_short(values[same])} are the same value "
              f"at float precision ({vals[same]!r}); each grid value must be distinct")
        return None
    return Axis.of_list(name, vals)


def _range_axis(key, name, spec, prm, p) -> Axis | None:
    if prm.categorical:
        p.add(key, f"{name} is categorical; give a list of values, e.g. {list(prm.choices)!r}")
        return None
    allowed_keys = ("start", "stop", "num", "spacing")
    for k in spec:
        if k not in allowed_keys:
            p.unknown(f"{key}.{k}", k, allowed_keys, "axis key")
    ok = True
    for end in ("start", "stop"):
        if end not in spec:
            p.add(f"{key}.{end}", "missing")
            ok = False
        else:
            msg = _value_problem(prm, spec[end])
            if msg:
                p.add(f"{key}.{end}", msg)
                ok = False
    num = spec.get("num")
    if isinstance(num, bool) or not isinstance(num, int) or not 1 <= num <= MAX_AXIS_POINTS:
        p.add(f"{key}.num", f"{_short(num)} is not allowed; expected a whole number in [1, {MAX_AXIS_POINTS}]")
        ok = False
    spacing = spec.get("spacing", "linear")
    if spacing not in ("linear", "log"):
        p.unknown(f"{key}.spacing", spacing, ("linear", "log"), "spacing")
        ok = False
    if not ok:
        return None
    start, stop = float(spec["start"]), float(spec["stop"])
    if num > 1 and start == stop:
        p.add(key, f"start = stop = {start:g} with num = {num}: the values would repeat")
        return None
    if spacing == "log" and (start <= 0 or stop <= 0):
        p.add(key, f"log spacing needs start > 0 and stop > 0, got start = {start:g}, stop = {stop:g}")
        return None
    axis = Axis.of_range(name, start, stop, num, spacing)
    ends = (math.log10(start), math.log10(stop)) if spacing == "log" else (start, stop)
    if not all(math.isfinite(v) for v in (start, stop) + ends) or not math.isfinite(ends[1] - ends[0]):
        p.add(key, f"start = {start:g}, stop = {stop:g}: the span overflows a float; narrow the range")
        return None
    if num > 1 and _repeats(axis):
        p.add(key, f"start = {start!r}, stop = {stop!r} with num = {num}: the values repeat at float precision; "
              "widen the range or lower num")
        return None
    return axis


_BLOCK = 2**20  # values per block when an axis is scanned


def _repeats(axis: Axis) -> bool:
    """Whether two neighbouring values of a range axis are equal at float precision. Decided from
    the step when it is far above the rounding of the values (always, for sensible grids); else by
    scanning the values block by block (memory of one block, whatever num is)."""
    a, b = (float(np.log10(axis.start)), float(np.log10(axis.stop))) if axis.spacing == "log" else (axis.start, axis.stop)
    step = abs(b - a) / (axis.num - 1)
    # each value i * step + a is within 2 ulp of max(|a|, |b|) of exact (product, sum); 10 ** y adds
    # 1 ulp relative and turns an error e in y into a relative error e ln 10
    rounding = 4 * math.ulp(max(abs(a), abs(b)))
    if axis.spacing == "log":
        if step * math.log(10) > 8 * (rounding * math.log(10) + 4 * sys.float_info.epsilon):
            return False
    elif step > 2 * rounding:
        return False
    last = None
    for lo in range(0, axis.num, _BLOCK):
        v = axis.array(lo, min(axis.num, lo + _BLOCK))
        if (last is not None and v[0] == last) or (v.size > 1 and not (np.diff(v) != 0).all()):
            return True
        last = v[-1]
    return False


def _fixed(table: Mapping, model: ModelSpec, axis_names: set, p: _Problems) -> dict:
    fixed = {}
    for name, value in table.items():
        key = f"fixed.{name}"
        if name not in model.param_names():
            p.unknown(key, name, model.param_names(), f"parameter of model {model.name!r}")
            continue
        if name in axis_names:
            p.add(key, f"{name} is given both as an axis and as a fixed value; keep one")
            continue
        msg = _value_problem(model.param(name), value)
        if msg:
            p.add(key, msg)
            continue
        fixed[name] = value if model.param(name).categorical else float(value)
    return fixed


def _solver(table: Mapping, model: ModelSpec, p: _Problems) -> Solver:
    defaults = Solver()
    values = {}
    own = {st.name: st for st in model.settings}
    settings = {st.name: st.default for st in model.settings}
    for k, v in table.items():
        key = f"solver.{k}"
        if k == "method":
            if v not in model.methods:
                p.unknown(key, v, model.methods, f"method of {model.name!r}")
            else:
                values[k] = v
        elif k in SOLVER_LIMITS:
            lo, hi = SOLVER_LIMITS[k]
            want_int = k == "max_steps"
            kind = "a whole number" if want_int else "a number"
            if isinstance(v, bool) or not isinstance(v, (int, float)) or (want_int and not isinstance(v, int)):
                p.add(key, f"{_short(v)} is not allowed; expected {kind} in [{lo:g}, {hi:g}]")
            elif not lo <= v <= hi or not math.isfinite(v):  # compares a huge int without float()
                p.add(key, f"{_short(v)} is outside the allowed range [{lo:g}, {hi:g}]")
            else:
                values[k] = int(v) if want_int else float(v)
        elif k in own:
            msg = _value_problem(own[k], v)
            if msg:
                p.add(key, msg)
            else:
                settings[k] = int(v) if own[k].integer else float(v)
        else:
            p.unknown(key, k, ("method",) + tuple(SOLVER_LIMITS) + tuple(own), f"solver setting of {model.name!r}")
    return Solver(**{**defaults.__dict__, **values, "settings": MappingProxyType(settings)})


def atol_problem(solver: Solver, model: ModelSpec) -> str | None:
    """Why ``solver.atol`` can never work with ``solver.method`` (see ATOL_FLOOR), or None."""
    if solver.method not in ADAPTIVE_METHODS or solver.atol >= ATOL_FLOOR:
        return None
    other = (" (method 'symplectic', which this model offers, does not use atol)"
             if "symplectic" in model.methods else "")
    return (f"{solver.atol:g} is below the usable range of method {solver.method!r}, [{ATOL_FLOOR:g}, 1]: where a "
            f"state is zero (a start from rest) its error norm is (rate / atol)^2, which overflows a float64 once "
            f"rate / atol > {_NORM_OVERFLOW:.2g}, here for any rate above {_NORM_OVERFLOW * solver.atol:.2g}, and the "
            f"points end nonfinite; give atol >= {ATOL_FLOOR:g}{other}")


def solver_warnings(scene: "Scene") -> list[str]:
    """Settings a run accepts but whose results deserve suspicion, one sentence each (the CLI
    prints them; ``mechsweep.run`` warns with SettingsWarning)."""
    s = scene.solver
    if s is None:
        return []
    found = []
    if s.method in ADAPTIVE_METHODS and s.atol < ATOL_WARN:
        found.append(f"solver.atol = {s.atol:g} is below {ATOL_WARN:g}: near a state that passes through or stays at "
                     "zero the error control is then purely relative and asks for errors below float64 rounding; "
                     "points may end max_steps or step_underflow (as points of the shipped scenes did from atol "
                     "1e-20 to 1e-30); usual is atol about 1e-12 times the size of the states")
    if s.method in ("radau", "auto") and s.rtol < RADAU_MIN_RTOL:
        which = "every point" if s.method == "radau" else "a point found stiff (integrated again by radau)"
        found.append(f"solver.rtol = {s.rtol:g} is below {RADAU_MIN_RTOL:.3g} (100 x float64 eps), to which radau "
                     f"raises it, as scipy's Radau does: {which} is integrated to rtol {RADAU_MIN_RTOL:.3g}, not "
                     f"{s.rtol:g}")
    return found


def _storage(table: Mapping, name: str, p: _Problems) -> Storage:
    path = table.get("path", f"data/runs/{_slug(name)}.h5")
    chunk = table.get("chunk_size")
    for k in table:
        if k not in ("path", "chunk_size"):
            p.unknown(f"storage.{k}", k, ("path", "chunk_size"), "storage key")
    if not isinstance(path, str) or not path.strip():
        p.add("storage.path", f"{_short(path)} is not allowed; expected a file path string")
        path = "invalid"
    elif "\0" in path:
        p.add("storage.path", f"{_short(path)} contains a NUL character; expected a file path")
    elif path.endswith(("/", "\\")):
        p.add("storage.path", f"{_short(path)} ends with a path separator; give a file path such as "
              f"{path.rstrip('/')}/run.h5, not a folder")
    if chunk is not None and (isinstance(chunk, bool) or not isinstance(chunk, int) or not 1 <= chunk <= 2**31):
        p.add("storage.chunk_size", f"{_short(chunk)} is not allowed; expected a whole number in [1, 2147483648]")
        chunk = None
    return Storage(path=path, chunk_size=chunk)


def _check_chunk_count(shape: tuple[int, ...], chunk_size: int, p: _Problems) -> None:
    from .grid import MAX_CHUNKS, ChunkPlan, least_target

    n = len(ChunkPlan(shape, chunk_size))
    if n > MAX_CHUNKS:
        p.add("storage.chunk_size", f"{chunk_size:,} points per chunk cut the grid of {math.prod(shape):,} points "
              f"({' x '.join(map(str, shape))}) into {n:,} chunks; at most {MAX_CHUNKS:,} are allowed (each is "
              f"a file written and synced): give chunk_size >= {least_target(shape):,}, or leave it out")


SCHEDULER_FORMS = "an address such as 'tcp://10.0.0.5:8786' or 'localhost:8786'"


def check_scheduler(address) -> str | None:
    """Why ``address`` is not a dask scheduler address, or None."""
    if not isinstance(address, str) or not address.strip():
        return f"{_short(address)} is not allowed; expected {SCHEDULER_FORMS}"
    if any(c.isspace() for c in address) or unstorable(address) is not None or len(address) > 512:
        return f"{_short(address)} is not an address; expected {SCHEDULER_FORMS}"
    return None


WORKER_TIMEOUT_RANGE = (1.0, 86400.0)


def check_worker_timeout(value) -> str | None:
    """Why ``value`` is not a worker timeout in seconds, or None."""
    lo, hi = WORKER_TIMEOUT_RANGE
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
        return f"{_short(value)} is not allowed; expected a number of seconds in [{lo:g}, {hi:g}]"
    return None


def _execution(table: Mapping, p: _Problems) -> Execution:
    for k in table:
        if k not in ("scheduler", "worker_timeout", "lanes"):
            p.unknown(f"execution.{k}", k, ("scheduler", "worker_timeout", "lanes"), "execution key")
    scheduler = table.get("scheduler")
    if scheduler is not None and (why := check_scheduler(scheduler)) is not None:
        p.add("execution.scheduler", why)
        scheduler = None
    timeout = table.get("worker_timeout", Execution.worker_timeout)
    if (why := check_worker_timeout(timeout)) is not None:
        p.add("execution.worker_timeout", why)
        timeout = Execution.worker_timeout
    lanes = table.get("lanes", Execution.lanes)
    if not isinstance(lanes, str) or lanes not in LANES_CHOICES:
        p.add("execution.lanes", f"{_short(lanes)} is not allowed; expected one of "
                                 f"{', '.join(repr(c) for c in LANES_CHOICES)}")
        lanes = Execution.lanes
    return Execution(scheduler=scheduler, worker_timeout=float(timeout), lanes=lanes)


def _not_a_range(name, axes, model) -> str | None:
    """Why a known parameter cannot be swept across for boundaries (None: not a known parameter)."""
    axis = next((a for a in axes if a.name == name), None)
    if axis is not None and model.param(name).categorical:
        return "is a list of names (boundaries need a numeric axis)"
    if axis is not None:
        return f"has {axis.size} value{'s' if axis.size != 1 else ''} in this scene"
    if isinstance(name, str) and name in [q.name for q in model.params]:
        return "is a fixed parameter in this scene, not an axis"
    return None


def _boundaries(table: Mapping, model: ModelSpec, axes: list, outputs: tuple, p: _Problems,
                refused=frozenset()) -> Boundaries | None:
    """The [boundaries] section; every problem names its key and what is allowed. ``refused``: axes
    given with values already refused (their error stands; not also an unknown ``along``)."""
    from . import status as st

    n0 = len(p.items)
    for k in table:
        if k not in BOUNDARY_KEYS:
            p.unknown(f"boundaries.{k}", k, BOUNDARY_KEYS, "boundaries key")
    ranged = [a.name for a in axes if a.size >= 2 and not model.param(a.name).categorical]
    along = table.get("along")
    if along is None:
        p.add("boundaries.along", f"missing; expected the name of an axis of at least 2 numeric values "
              f"({', '.join(ranged) or 'this scene has none'})")
    numeric = ", ".join(q.name for q in model.params if not q.categorical)
    if along is not None and along not in ranged and along not in refused:
        if (why := _not_a_range(along, axes, model)) is not None:
            p.add("boundaries.along", f"{along!r} {why}; expected an axis of at least 2 numeric values "
                  f"({', '.join(ranged) or 'this scene has none'})")
        else:
            p.unknown("boundaries.along", along, ranged or (f"(none in this scene: give an axis of at least 2 values "
                                                            f"of a numeric parameter: {numeric})",),
                      "axis to locate boundaries along")
    crit, change = table.get("criterion"), table.get("status_change")
    level, criterion_accuracy, pair = math.nan, None, None
    if (crit is None) == (change is None):
        p.add("boundaries", "give exactly one of criterion (an output crossing a level) and status_change "
              "(a pair of status names)")
    scalar = [o for o in outputs if not model.output(o).extra_dims]
    if crit is not None:
        if crit not in scalar:
            p.unknown("boundaries.criterion", crit, scalar or ("(none: request a scalar output)",),
                      "criterion (a scalar output in scene.outputs)")
            crit = None
        lv = table.get("level")
        if lv is None:
            if crit is not None and model.output(crit).kind == "floquet_max":
                lv = 1.0  # the unit circle
            else:
                p.add("boundaries.level", f"missing; the value of {crit or 'the criterion'} at the boundary "
                      "(a finite number)")
        if lv is not None:
            if isinstance(lv, bool) or not isinstance(lv, (int, float)) or not math.isfinite(lv):
                p.add("boundaries.level", f"{_short(lv)} is not allowed; expected a finite number")
            else:
                level = float(lv)
        acc = table.get("criterion_accuracy")
        if acc is not None:
            if isinstance(acc, bool) or not isinstance(acc, (int, float)) or not (math.isfinite(acc) and acc >= 0):
                p.add("boundaries.criterion_accuracy", f"{_short(acc)} is not allowed; expected a finite number >= 0 "
                      "(absolute, in the criterion's unit)")
            else:
                criterion_accuracy = float(acc)
    else:
        for k in ("level", "criterion_accuracy"):
            if k in table:
                p.add(f"boundaries.{k}", "is only allowed with criterion, not with status_change")
    if change is not None:
        names = tuple(v for k, v in sorted(st.MEANINGS.items()) if k != st.PENDING)
        if not isinstance(change, list) or len(change) != 2:
            p.add("boundaries.status_change", f"{_short(change)} is not allowed; expected two status names, "
                  f"e.g. [\"ok\", \"not_oscillatory\"], from {', '.join(names)}")
        else:
            for item in change:
                if item not in names:
                    p.unknown("boundaries.status_change", item, names, "status")
            if change[0] == change[1]:
                p.add("boundaries.status_change", f"{change[0]!r} twice; expected two different statuses")
            pair = (change[0], change[1])
    cont = table.get("continue_in")
    if cont is not None:
        if cont not in ranged and (why := _not_a_range(cont, axes, model)) is not None:
            p.add("boundaries.continue_in", f"{cont!r} {why}; expected an axis of at least 2 numeric values other "
                  f"than along ({', '.join(a for a in ranged if a != along) or 'this scene has none'})")
        elif cont not in [a for a in ranged if a != along]:
            p.unknown("boundaries.continue_in", cont, [a for a in ranged if a != along] or
                      (f"(none in this scene: give a second axis of at least 2 values of a numeric parameter: "
                       f"{numeric})",), "axis to continue boundaries in")
        elif change is not None and crit is None:
            p.add("boundaries.continue_in", "needs a criterion: a change of status cannot be continued")
    rtol = table.get("rtol", Boundaries.rtol)
    lo, hi = BOUNDARY_RTOL
    if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not lo <= rtol <= hi:
        p.add("boundaries.rtol", f"{_short(rtol)} is not allowed; expected a number in [{lo:g}, {hi:g}] "
              "(relative tolerance in the parameter)")
        rtol = Boundaries.rtol
    if len(p.items) > n0:
        return None
    return Boundaries(along=along, criterion=crit, level=level, status_change=pair, rtol=float(rtol),
                      criterion_accuracy=criterion_accuracy, continue_in=cont)


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "-" for c in name.strip()) or "scene"


# ----------------------------------------------------------------------------- dict -> TOML
def to_toml(data: Mapping) -> str:
    """Write a scene dict as TOML (the subset scenes use), so a dict scene is stored as text too."""
    lines = []
    for section, table in data.items():
        if not isinstance(table, Mapping):
            lines.append(f"{_key(section)} = {_value(table)}")
            continue
        lines.append(f"[{_key(section)}]")
        lines.extend(f"{_key(k)} = {_value(v)}" for k, v in table.items())
        lines.append("")
    return "\n".join(lines)


def _key(k) -> str:
    k = str(k)
    return k if k.replace("_", "").replace("-", "").isalnum() else json.dumps(k)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        v = float(v)
        return "nan" if v != v else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return json.dumps(str(v))
