"""Text a dataset can store, and values shown in messages: HDF5 keeps strings as UTF-8 without
NUL characters, and names a netCDF-4 variable, dimension or attribute can have; every string a scene
or a model's declaration puts into a dataset is checked before a run (:func:`check_storable`), and a
bad value is shown cut to a readable length (:func:`short`)."""
from __future__ import annotations

import reprlib
from typing import Mapping

import numpy as np

from ..model.spec import ModelSpec

_REPR = reprlib.Repr()
_REPR.maxstring, _REPR.maxother, _REPR.maxlong, _REPR.maxlevel = 60, 60, 40, 3


def short(value) -> str:
    """repr(value) cut to a readable length: a scene may hold huge or deeply nested values."""
    return _REPR.repr(value)


def short_key(key: str) -> str:
    return key if len(key) <= 120 else key[:60] + "..." + key[-40:]


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


def unstorable_in(value, key: str = "") -> str | None:
    """The first key or string of a scene dict that has no UTF-8 form (a lone surrogate): its TOML
    text, stored with the dataset, could not be read back. None when there is none."""
    if isinstance(value, Mapping):
        for k, v in value.items():
            where = f"{key}.{k}" if key else str(k)
            if isinstance(k, str) and (why := unstorable(k.replace("\0", ""))) is not None:
                return f"{short_key(where)}: the key {short(k)} {why}"
            if (why := unstorable_in(v, where)) is not None:
                return why
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            if (why := unstorable_in(v, f"{key}[{i}]")) is not None:
                return why
    elif isinstance(value, str) and (why := unstorable(value.replace("\0", ""))) is not None:
        return f"{short_key(key)}: {short(value)} {why}"
    return None


def check_storable(model: ModelSpec, outputs, axes, fixed, solver, p) -> None:
    """Every string of the model's declaration and of the scene that a run writes into its dataset
    (names of variables, dimensions and attributes, units, long names, symbols, the values of
    categorical parameters, the model's name, source, references and status notes) must be text HDF5
    can store, and the names distinct (the path of a model file is checked in _model, before loading). A problem here would only show
    at the end of the run, when the file is written: it is reported now, naming what to fix."""
    where = f"model {model.name!r}"

    def text(what: str, value, advice: str = "fix the model's declaration") -> None:
        if isinstance(value, str) and (why := unstorable(value)) is not None:
            p.add("scene.model", f"{where}: {what} {short(value)} {why}, which HDF5 cannot store in a dataset; "
                  + advice)

    def name(what: str, value) -> None:
        if (why := unstorable_name(value)) is not None:
            p.add("scene.model", f"{where}: {what} {short(value)} {why}, which cannot name a variable or "
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
