"""A scene's sections, each checked and turned into its part of the :class:`~.spec.Scene`
(:func:`validate`): the model, its outputs, the axes, the fixed values, the solver, the storage, the
execution and the boundaries. Every problem is collected with its key path, the bad value and what
is allowed, and all of a scene's problems are reported together (:class:`~.spec.SceneError`)."""
from __future__ import annotations

import difflib
import math
import sys
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ..chunks import MAX_CHUNKS, ChunkPlan, least_target
from ..errors import InputError
from ..model.spec import ModelSpec
from ..models import MODELS
from .spec import (ADAPTIVE_METHODS, ATOL_FLOOR, ATOL_WARN, BOUNDARY_KEYS, BOUNDARY_RTOL, LANES_CHOICES,
                   MAX_AXIS_POINTS, MAX_POINTS, NORM_OVERFLOW, RADAU_MIN_RTOL, SECTIONS, SOLVER_LIMITS, Axis,
                   Boundaries, Execution, Scene, SceneError, Solver, Storage)
from .text import check_storable, short, short_key, unstorable

def validate(data: Mapping, *, text: str, label: str = "scene", base: Path | str | None = None,
             models: Mapping | None = None) -> Scene:
    p = _Problems()
    if not isinstance(data, Mapping):
        raise SceneError([f"a scene is a table of sections, got {type(data).__name__}"], label)
    p.unknown_keys(data, "", SECTIONS, "section")
    head = _table(data, "scene", p, required=True)
    name = head.get("name")
    if not isinstance(name, str) or not name.strip():
        p.add("scene.name", f"{short(name)} is not allowed; expected a non-empty string")
    elif (why := unstorable(name)) is not None:  # the dataset's title
        p.add("scene.name", f"{short(name)} {why}; a dataset's title must be text HDF5 can store")
    p.unknown_keys(head, "scene.", ("name", "model", "outputs", "description"), "key")
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
        check_storable(model, outputs, axes, fixed, solver, p)
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
        word = name[:100] if isinstance(name, str) else short(name)
        hint = difflib.get_close_matches(word, [str(a) for a in allowed], n=1, cutoff=0.5)
        tip = f"; did you mean {hint[0]!r}?" if hint else ""
        listed = ", ".join(map(str, allowed))
        # a long list printed once: a scene written for another model repeated 50 outputs per error
        text = "as above" if listed in self._listed and len(listed) > 80 else listed
        self._listed.add(listed)
        self.add(short_key(key), f"unknown {what} {short(name)}{tip} (allowed: {text})")

    def unknown_keys(self, table: Mapping, prefix: str, allowed, what: str) -> None:
        """Each key of ``table`` that is not ``allowed``, reported as ``prefix + key``."""
        for key in table:
            if key not in allowed:
                self.unknown(f"{prefix}{key}", key, allowed, what)


class _Shown:
    """Stands in for a value whose repr is too long to show in a message."""

    def __init__(self, value):
        self.text = short(value)

    def __repr__(self) -> str:
        return self.text


def _value_problem(item, value) -> str | None:
    """``item.problem(value)`` of a Param or Setting, safe for values it cannot show or convert."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > sys.float_info.max:
        allowed = item.allowed() if hasattr(item, "allowed") else f"a number in [{item.lo:g}, {item.hi:g}]"
        return f"{short(value)} is too large for a float (at most {sys.float_info.max:.4g}); expected {allowed}"
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
        p.add(key, f"expected a table [{key}], got {type(value).__name__} {short(value)}")
        return {}
    return value


def _model(name, p: _Problems, base: Path | str | None = None, models: Mapping | None = None) -> ModelSpec | None:
    from ..model import user

    if name is None:
        p.add("scene.model", f"missing; expected one of {', '.join(MODELS)}")
        return None
    if models and isinstance(name, str) and name in models:  # given from Python: run(scene, models={...})
        try:
            return user.from_object(name, models[name])
        except InputError as exc:
            p.add("scene.model", str(exc))
            return None
    if isinstance(name, str) and ":" in name:  # a user model: "file.py:NAME" or "package.module:NAME"
        where = str(Path(base or Path.cwd()) / name.rpartition(":")[0]) if user.is_file_ref(name) else name
        if (why := unstorable(where)) is not None:  # a run stores where the model came from with its dataset
            p.add("scene.model", f"the model's path {short(where)} {why}; a dataset stores where its model came "
                  "from as UTF-8 text: move the model file (and the scene) to a path whose name is UTF-8 text")
            return None
        try:
            return user.resolve(name, Path(base) if base else None)
        except InputError as exc:
            p.add("scene.model", str(exc))
            return None
    if isinstance(name, str) and name not in MODELS:
        try:
            points = user.entry_points()
        except InputError as exc:
            p.add("scene.model", str(exc))
            return None
        if name in points:  # registered by an installed package (entry-point group mechsweep.models)
            try:
                return user.resolve(points[name].value)
            except InputError as exc:
                p.add("scene.model", f"entry point {name!r} ({user.ENTRY_POINT_GROUP}): {exc}")
                return None
    if not isinstance(name, str) or name not in MODELS:
        known = tuple(MODELS) + tuple(sorted(set(user.entry_points(quiet=True)) - set(MODELS)))
        known += tuple(sorted(set(models or ()) - set(known)))
        p.unknown("scene.model", name, known, "model")
        return None
    return MODELS[name]


def _model_source_key(name, spec: ModelSpec, base, models) -> str:
    """sha256 of the source file a user model is declared in: the model file ("file.py:NAME",
    resolved as user.resolve does), the module ("package.module:NAME", an entry point's target) or,
    for a model given from Python, the module its rhs (an OdeModel) or evaluate (a ModelSpec) is
    defined in; followed by the declaration (parameters, outputs, settings, methods; and the
    ``source`` of a ModelSpec given from Python, whose evaluate may live in mechsweep itself).
    Nothing that depends on where the file lies: the same file is the same model from any folder.
    "" for a built-in model."""
    import hashlib

    from ..model import sources, user

    if not isinstance(name, str) or (name in MODELS and MODELS[name] is spec and not (models and name in models)):
        return ""
    file, module = "", ""
    if models and name in models:
        obj = models[name]
        func = getattr(obj, "rhs", None) or getattr(obj, "evaluate", None)
        module = getattr(getattr(func, "py_func", func), "__module__", "") or ""
    elif ":" in name:
        left = name.rpartition(":")[0]
        if user.is_file_ref(name):
            path = Path(left)
            file = str((path if path.is_absolute() else Path(base or Path.cwd()) / path).resolve())
        else:
            module = left
    else:
        ep = user.entry_points(quiet=True).get(name)
        module = ep.value.rpartition(":")[0] if ep is not None else ""
    if module:
        file = sources.FILES.get(module) or getattr(sys.modules.get(module), "__file__", "") or ""
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
    from ..model import user

    if isinstance(name, str) and user.is_file_ref(name):
        return str(Path(base).resolve() if base else Path.cwd())
    return ""


def _outputs(value, model: ModelSpec, p: _Problems) -> tuple[str, ...]:
    names = model.output_names()
    if not isinstance(value, list) or not value:
        p.add("scene.outputs", f"{short(value)} is not allowed; expected a non-empty list of output names "
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
            p.add(short_key(key), f"{short(spec)} is not allowed; expected a list of values or a table "
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
        p.add(key, f"{short(values[vals.index(vals[same])])} and {short(values[same])} are the same value "
              f"at float precision ({vals[same]!r}); each grid value must be distinct")
        return None
    return Axis.of_list(name, vals)


def _range_axis(key, name, spec, prm, p) -> Axis | None:
    if prm.categorical:
        p.add(key, f"{name} is categorical; give a list of values, e.g. {list(prm.choices)!r}")
        return None
    p.unknown_keys(spec, f"{key}.", ("start", "stop", "num", "spacing"), "axis key")
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
        p.add(f"{key}.num", f"{short(num)} is not allowed; expected a whole number in [1, {MAX_AXIS_POINTS}]")
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
            if v not in model.methods and not any(o.integrated for o in model.outputs):
                # a closed-form model: no method integrates anything there (its dop853 is a placeholder)
                p.add(key, f"{short(v)} is not allowed: model {model.name!r} integrates nothing (every output is a "
                      "closed form), so no integration method applies; leave solver.method out")
            elif v not in model.methods:
                p.unknown(key, v, model.methods, f"method of {model.name!r}")
            else:
                values[k] = v
        elif k in SOLVER_LIMITS:
            lo, hi = SOLVER_LIMITS[k]
            want_int = k == "max_steps"
            kind = "a whole number" if want_int else "a number"
            if isinstance(v, bool) or not isinstance(v, (int, float)) or (want_int and not isinstance(v, int)):
                p.add(key, f"{short(v)} is not allowed; expected {kind} in [{lo:g}, {hi:g}]")
            elif not lo <= v <= hi or not math.isfinite(v):  # compares a huge int without float()
                p.add(key, f"{short(v)} is outside the allowed range [{lo:g}, {hi:g}]")
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
            f"rate / atol > {NORM_OVERFLOW:.2g}, here for any rate above {NORM_OVERFLOW * solver.atol:.2g}, and the "
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
    p.unknown_keys(table, "storage.", ("path", "chunk_size"), "storage key")
    if not isinstance(path, str) or not path.strip():
        p.add("storage.path", f"{short(path)} is not allowed; expected a file path string")
        path = "invalid"
    elif "\0" in path:
        p.add("storage.path", f"{short(path)} contains a NUL character; expected a file path")
    elif path.endswith(("/", "\\")):
        p.add("storage.path", f"{short(path)} ends with a path separator; give a file path such as "
              f"{path.rstrip('/')}/run.h5, not a folder")
    if chunk is not None and (isinstance(chunk, bool) or not isinstance(chunk, int) or not 1 <= chunk <= 2**31):
        p.add("storage.chunk_size", f"{short(chunk)} is not allowed; expected a whole number in [1, 2147483648]")
        chunk = None
    return Storage(path=path, chunk_size=chunk)


def _check_chunk_count(shape: tuple[int, ...], chunk_size: int, p: _Problems) -> None:
    n = len(ChunkPlan(shape, chunk_size))
    if n > MAX_CHUNKS:
        p.add("storage.chunk_size", f"{chunk_size:,} points per chunk cut the grid of {math.prod(shape):,} points "
              f"({' x '.join(map(str, shape))}) into {n:,} chunks; at most {MAX_CHUNKS:,} are allowed (each is "
              f"a file written and synced): give chunk_size >= {least_target(shape):,}, or leave it out")


SCHEDULER_FORMS = "an address such as 'tcp://10.0.0.5:8786' or 'localhost:8786'"


def check_scheduler(address) -> str | None:
    """Why ``address`` is not a dask scheduler address, or None."""
    if not isinstance(address, str) or not address.strip():
        return f"{short(address)} is not allowed; expected {SCHEDULER_FORMS}"
    if any(c.isspace() for c in address) or unstorable(address) is not None or len(address) > 512:
        return f"{short(address)} is not an address; expected {SCHEDULER_FORMS}"
    return None


WORKER_TIMEOUT_RANGE = (1.0, 86400.0)


def check_worker_timeout(value) -> str | None:
    """Why ``value`` is not a worker timeout in seconds, or None."""
    lo, hi = WORKER_TIMEOUT_RANGE
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
        return f"{short(value)} is not allowed; expected a number of seconds in [{lo:g}, {hi:g}]"
    return None


def _execution(table: Mapping, p: _Problems) -> Execution:
    p.unknown_keys(table, "execution.", ("scheduler", "worker_timeout", "lanes"), "execution key")
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
        p.add("execution.lanes", f"{short(lanes)} is not allowed; expected one of "
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
    from .. import status as st

    n0 = len(p.items)
    p.unknown_keys(table, "boundaries.", BOUNDARY_KEYS, "boundaries key")
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
            elif crit is None:
                pass  # an unknown criterion (said above): whether it needs a level (a Floquet one not) is unknown
            else:
                p.add("boundaries.level", f"missing; the value of {crit or 'the criterion'} at the boundary "
                      "(a finite number)")
        if lv is not None:
            if isinstance(lv, bool) or not isinstance(lv, (int, float)) or not math.isfinite(lv):
                p.add("boundaries.level", f"{short(lv)} is not allowed; expected a finite number")
            else:
                level = float(lv)
        acc = table.get("criterion_accuracy")
        if acc is not None:
            if isinstance(acc, bool) or not isinstance(acc, (int, float)) or not (math.isfinite(acc) and acc >= 0):
                p.add("boundaries.criterion_accuracy", f"{short(acc)} is not allowed; expected a finite number >= 0 "
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
            p.add("boundaries.status_change", f"{short(change)} is not allowed; expected two status names, "
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
        p.add("boundaries.rtol", f"{short(rtol)} is not allowed; expected a number in [{lo:g}, {hi:g}] "
              "(relative tolerance in the parameter)")
        rtol = Boundaries.rtol
    if len(p.items) > n0:
        return None
    return Boundaries(along=along, criterion=crit, level=level, status_change=pair, rtol=float(rtol),
                      criterion_accuracy=criterion_accuracy, continue_in=cont)


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "-" for c in name.strip()) or "scene"
