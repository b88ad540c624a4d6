"""What a validated scene is: the frozen :class:`Scene` and its parts (:class:`Axis`,
:class:`Solver`, :class:`Storage`, :class:`Execution`, :class:`Boundaries`), the limits a scene's
values are checked against, and :class:`SceneError`. Made by :mod:`mechsweep.scene.load`, after
every section was checked (:mod:`mechsweep.scene.sections`)."""
from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from ..errors import InputError
from ..model.spec import ModelSpec

SECTIONS = ("scene", "axes", "fixed", "solver", "storage", "execution", "boundaries")
MAX_POINTS = 2**40  # beyond this a flat int64 index and any disk are hopeless
# Values per axis. The grid itself is never expanded (a chunk is computed from the axes' ranges),
# but a reader of the dataset (xarray) loads each axis's coordinate in full when it opens it:
# 8 bytes per value, 80 MB at this limit. Grids beyond it are built from more axes.
MAX_AXIS_POINTS = 10**7


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
NORM_OVERFLOW = math.sqrt(sys.float_info.max)  # 1.34e154
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
    """The scene's [boundaries] section: where a criterion crosses along one axis (mechsweep.boundaries).

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
        the model is not named by a file path); stored with a run and sent to dask workers, so
        that the stored text is read again against it from any working directory.
    model_key : str
        sha256 of a user model's source ("" for a built-in model): part of the canonical form (two
        files declaring a model of one name are two scenes, the same file is the same scene).
    boundaries : Boundaries or None
        The ``[boundaries]`` section (docs/boundaries.md), or None; not part of the canonical form
        (boundaries are located in a separate pass and do not change the grid's dataset).

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
    solver: Solver | None
    storage: Storage
    text: str
    execution: Execution = Execution()
    base: str = ""
    model_key: str = ""
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
