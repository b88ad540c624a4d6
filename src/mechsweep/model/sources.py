"""What a model's results are computed from: its dependency record.

A model's numbers depend on more than its scene: on the model file and every module of the user's
it imports (a helper's function is compiled into the kernel, its constants frozen into it), on the
third-party packages it uses, and on mechsweep itself. :func:`record` gathers them once per model
and process, and the record serves

- the kernel caches: a kernel's binding module name carries :attr:`Record.digest`, and every user
  function the engine compiles carries its module's :func:`module_digest` (load.jitted), so an
  edited helper gives a new compile, never the old machine code from numba's disk cache (whose
  index checks only the decorated function's own file);
- the journal and the dataset: ``provenance`` stores :meth:`Record.stored` as the attributes
  ``dependencies`` (JSON) and ``source_files`` (``sha256sum`` lines), and a resume refuses a record
  that differs, naming what changed (:func:`differences`).

What counts (found without importing anything, located as Python's path finder would): the modules
that define the declaration's functions and, from each module of the user's, recursively, the
modules its source imports, those its globals come from and its parent packages. A *user's* module
(outside the standard library, mechsweep and site-packages) counts by the sha256 of its file and
of the values of its global constants (numba freezes them; a value read from a data file at import
changes with no edit); a module in site-packages by its distribution's version, except the model's
own package, hashed as a user's. Also mechsweep's version and a hash of its sources
(_jit.package_hash), and the versions of numba and numpy.

A file's hash is taken once per process, when first needed (the model file's bytes when it is
imported): the record describes the code the process imported, even if the file is edited since.
"""
from __future__ import annotations

import ast
import dataclasses
import functools
import hashlib
import importlib.machinery
import importlib.util
import json
import os
import site
import sys
import sysconfig
import types
from dataclasses import dataclass
from pathlib import Path

FORMAT = 1  # of the stored form (Record.stored)
FILES: dict[str, str] = {}  # module name -> path of a user model file imported by its path (load.import_module)
_HASHES: dict[str, str] = {}  # absolute path -> sha256 of the file, first seen in this process
_EDGES: dict[tuple, tuple[str, ...]] = {}  # (module name, its file) -> the modules it refers to
_DIGESTS: dict[tuple, str] = {}  # (module name, its file) -> module_digest
_VALUES: dict[tuple, tuple] = {}  # (module name, its file) -> _values
_RECORDS: dict[int, tuple[object, "Record"]] = {}  # id(model or spec) -> (it, its record)
_DISTS: dict[str, tuple[str, str] | None] = {}  # top-level import name -> (distribution, version)
_WALK_LIMIT = 20_000  # objects visited when collecting a declaration's functions
_GENERATED = ("mechsweep_gen_", "mechsweep_closed_", "mechsweep_traj_")  # kernel bindings (engine/binding.py)


# ----------------------------------------------------------------------------- the record
@dataclass(frozen=True)
class Source:
    """One file the results depend on."""

    module: str  # the module's name (a model file mechsweep loaded by path: its generated name)
    path: str  # absolute path of the file
    sha256: str
    role: str  # "model": defines the model's functions; "module": imported by them
    by_path: bool = False  # a model file loaded by its path (keyed by the path, not the module name)
    values: tuple[tuple[str, str], ...] = ()  # (global name, hash of its value): the constants numba may freeze


@dataclass(frozen=True)
class Record:
    files: tuple[Source, ...]
    packages: tuple[tuple[str, str], ...]  # (distribution, version), sorted; numba and numpy always
    mechsweep: str  # mechsweep's version
    mechsweep_sources: str  # _jit.package_hash()

    @functools.cached_property
    def digest(self) -> str:
        """sha256 (hex) of everything in the record that can change the code: the kernel caches'
        key. It does not depend on where the files lie, except for a model file loaded by path
        (its module name is made from its path)."""
        form = {"files": sorted((s.module, s.sha256, s.values) for s in self.files), "packages": list(self.packages),
                "mechsweep": [self.mechsweep, self.mechsweep_sources]}
        return hashlib.sha256(json.dumps(form, sort_keys=True).encode()).hexdigest()

    def stored(self, base: str | os.PathLike | None = None) -> dict:
        """The form stored in a journal and a dataset (JSON-able): paths relative to ``base`` (the
        scene's folder) where they lie under it, absolute otherwise."""
        return {"format": FORMAT, "mechsweep": self.mechsweep, "mechsweep_sources": self.mechsweep_sources,
                "packages": dict(self.packages),
                "files": [{"module": "" if s.by_path else s.module, "path": _shown(s.path, base),
                           "sha256": s.sha256, "role": s.role, "values": dict(s.values)} for s in self.files]}

    def attrs(self, base: str | os.PathLike | None = None) -> dict[str, str]:
        """The dataset attributes: ``dependencies`` (the stored form as JSON) and ``source_files``
        (one ``sha256  path`` line per file, as ``sha256sum`` prints them: ``sha256sum -c`` checks
        them from the scene's folder)."""
        form = self.stored(base)
        return {"dependencies": json.dumps(form, sort_keys=True),
                "source_files": "\n".join(f"{f['sha256']}  {f['path']}" for f in form["files"])}


def record(model) -> Record:
    """The dependency record of ``model`` (a ModelSpec, an OdeModel or a ClosedFormModel), computed
    once per model object and process."""
    known = _RECORDS.get(id(model))
    if known is not None and known[0] is model:
        return known[1]
    target = getattr(model, "declaration", None) or model
    starts = _functions_modules(target)
    main = _main_module(target)
    own = {name.split(".")[0] for name in starts if _kind(name) == "package"}
    files, packages = _closure(starts, own)
    sources = tuple(sorted(
        (Source(name, path, sha, "model" if name == main else "module", _by_path(name), values)
         for name, (path, sha, values) in files.items()), key=lambda s: (s.role != "model", s.module)))
    from .. import __version__, _jit

    toolchain = {"numba": _version_of("numba"), "numpy": _version_of("numpy")}
    packages = {**packages, **{k: v for k, v in toolchain.items() if v}}
    rec = Record(sources, tuple(sorted(packages.items())), __version__, _jit.package_hash())
    _RECORDS[id(model)] = (model, rec)
    return rec


def module_digest(module: str) -> str:
    """A hash of what the code of ``module`` depends on (its file, the user modules it imports,
    recursively, and the third-party packages they use); "" for mechsweep's own modules, the standard
    library and modules that cannot be found. load.jitted names the functions it compiles with it."""
    memo = (module, _file(module))
    if memo in _DIGESTS:
        return _DIGESTS[memo]
    kind = _kind(module)
    if kind in ("mechsweep", "python", None):
        digest = ""
    else:
        files, packages = _closure({module}, {module.split(".")[0]} if kind == "package" else set())
        form = {"files": sorted((name, sha, values) for name, (_, sha, values) in files.items()),
                "packages": sorted(packages.items())}
        digest = hashlib.sha256(json.dumps(form).encode()).hexdigest()
    _DIGESTS[memo] = digest
    return digest


def seen(path: str | os.PathLike, data: bytes) -> None:
    """Note the bytes a file had when it was imported (the first hash of it in this process)."""
    _HASHES.setdefault(str(Path(path).resolve()), hashlib.sha256(data).hexdigest())


# ----------------------------------------------------------------------------- comparing
def differences(stored, current: Record, base=None, since: str = "this run began") -> list[str]:
    """What differs between a stored record (the JSON form of :meth:`Record.stored`, as a dict or
    a string) and ``current``, one phrase each; [] when they agree. Files are matched by module
    name (a model file loaded by path: by its path relative to the scene's folder)."""
    if isinstance(stored, str):
        try:
            stored = json.loads(stored)
        except ValueError:
            return ["its dependency record is not readable JSON"]
    if not isinstance(stored, dict) or not isinstance(stored.get("files"), list) \
            or not isinstance(stored.get("packages"), dict):
        return ["its dependency record is damaged"]
    now = current.stored(base)
    out = []
    if (stored.get("mechsweep"), stored.get("mechsweep_sources")) != (now["mechsweep"], now["mechsweep_sources"]):
        out.append(f"mechsweep changed since {since} (version {stored.get('mechsweep')} -> {now['mechsweep']}, "
                   f"sources {stored.get('mechsweep_sources')} -> {now['mechsweep_sources']})")

    def keyed(files):
        return {str(f.get("module") or f.get("path")): f for f in files if isinstance(f, dict)}

    def values(entry):
        found = entry.get("values")
        return found if isinstance(found, dict) else {}

    before, after = keyed(stored["files"]), keyed(now["files"])
    edited = any(before[k].get("sha256") != after[k].get("sha256") for k in set(before) & set(after))
    for key in sorted(set(before) | set(after), key=str):
        old, new = before.get(key), after.get(key)
        if old is not None and new is not None:
            if old.get("sha256") != new.get("sha256"):
                out.append(f"{_what(new)} changed since {since} (sha256 {_short(old.get('sha256'))} -> "
                           f"{_short(new.get('sha256'))})")
            # a value changed with no edit of its file (a data file read at import); named only when no
            # file was edited: a value imported from an edited module changes with it
            # (compared where both sides hold them: a module the process never loaded has none)
            elif not edited and values(old) and values(new) and values(old) != values(new):
                a, b = values(old), values(new)
                names = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
                where = _what(new).removeprefix("the ")
                out.append(f"the value of {', '.join(names[:5])}{' ...' if len(names) > 5 else ''} in {where} "
                           f"changed since {since}, its source did not (is it read from a file or the "
                           "environment at import?)")
        elif new is not None:
            out.append(f"{_what(new)} is a new dependency (not used when {since})")
        else:
            out.append(f"{_what(old)}, used when {since}, is no longer a dependency")
    pk_old, pk_new = stored["packages"], now["packages"]
    for name in sorted(set(pk_old) | set(pk_new)):
        if pk_old.get(name) != pk_new.get(name):
            out.append(f"package {name} changed since {since} ({pk_old.get(name, 'absent')} -> "
                       f"{pk_new.get(name, 'absent')})")
    return out


def _what(entry: dict) -> str:
    path = entry.get("path", "?")
    if entry.get("role") == "model":
        return f"the model file {path}"
    return f"the module {entry['module']} ({path})" if entry.get("module") else f"the file {path}"


def _short(sha) -> str:
    return f"{sha[:12]}..." if isinstance(sha, str) and len(sha) > 12 else str(sha)


def _shown(path: str, base) -> str:
    if base:
        try:
            return Path(path).relative_to(Path(base).resolve()).as_posix()
        except ValueError:
            pass
    return path


# ----------------------------------------------------------------------------- the walk
def _closure(starts, own: set[str]) -> tuple[dict[str, tuple], dict[str, str]]:
    """({module: (path, sha256, values)} of the user modules reached from ``starts``, {distribution: version}
    of the third-party packages reached). ``own``: top-level packages hashed as a user's even in
    site-packages (the model's own)."""
    files: dict[str, tuple[str, str]] = {}
    packages: dict[str, str] = {}
    todo, done = list(starts), set()
    while todo:
        name = todo.pop()
        if name in done:
            continue
        done.add(name)
        kind = _kind(name)
        if kind == "package" and name.split(".")[0] not in own:
            dist = _distribution(name.split(".")[0])
            if dist is not None:
                packages[dist[0]] = dist[1]
                continue
            kind = "user"  # no distribution says what it is: its files are hashed
        if kind not in ("user", "package"):
            continue
        path = _file(name)
        if path is None:  # a namespace package: its modules count one by one
            todo.extend(_edges(name))
            continue
        files[name] = (path, _hash(path), _values(name, path))
        todo.extend(_edges(name))
    return files, packages


def _edges(name: str) -> tuple[str, ...]:
    """The modules ``name``'s code refers to: imports in its source, the modules its globals come
    from, its parent packages."""
    path = _file(name)
    if (name, path) in _EDGES:
        return _EDGES[name, path]
    out = set()
    parts = name.split(".")
    out.update(".".join(parts[:k]) for k in range(1, len(parts)))
    module = sys.modules.get(name)
    named = set()
    if path is not None and path.endswith(".py"):
        package = getattr(module, "__package__", None) if module is not None else name.rpartition(".")[0]
        if module is not None and path.endswith("__init__.py"):
            package = name
        named = _imports(path, package or "")
        out.update(named)
    if module is not None:
        for value in list(vars(module).values()):
            # a package's loaded submodules are its attributes (set by the import system, whoever
            # imported them): they count only where its source imports them
            out.update(m for m in _origins(value) if m in named or not (isinstance(value, types.ModuleType)
                                                                         and m.startswith(name + ".")))
    out.discard(name)
    _EDGES[name, path] = tuple(sorted(m for m in out if m and _exists(m)))
    return _EDGES[name, path]


def _values(name: str, path: str) -> tuple[tuple[str, str], ...]:
    """(name, hash) of the module's global constants: numbers, strings, numpy arrays and tuples of them.
    numba freezes such a global into the machine code of a function that reads it, so a value computed
    at import (read from a data file, the environment) is part of the kernel as its source is. Hashed
    once per module and process (with the file)."""
    memo = (name, path)
    if memo not in _VALUES:
        module = sys.modules.get(name)
        out = []
        items = [(k, v) for k, v in vars(module).items() if isinstance(k, str)] if module is not None else []
        for key, value in sorted(items, key=lambda kv: kv[0]):
            if key.startswith("__"):
                continue
            data = _value_bytes(value)
            if data is not None:
                out.append((key, hashlib.sha256(data).hexdigest()[:16]))
        _VALUES[memo] = tuple(out)
    return _VALUES[memo]


def _value_bytes(value, depth: int = 0) -> bytes | None:
    """The bytes that identify a constant numba can freeze, None for anything else."""
    if isinstance(value, (bool, int, float, complex, str, bytes)):
        return f"{type(value).__name__}:{value!r}".encode()
    if type(value).__module__ == "numpy" and hasattr(value, "dtype") and hasattr(value, "tobytes"):
        try:
            import numpy as np

            array = np.ascontiguousarray(value)
            if array.dtype.hasobject:
                return None
            return f"{array.dtype.str}{array.shape}:".encode() + array.tobytes()
        except Exception:
            return None
    if isinstance(value, tuple) and depth < 4:
        parts = [_value_bytes(v, depth + 1) for v in value]
        if any(p is None for p in parts):
            return None
        return b"(" + b",".join(hashlib.sha256(p).digest() for p in parts) + b")"
    return None


def _imports(path: str, package: str) -> set[str]:
    """The modules an ``import`` or ``from ... import`` anywhere in the file names (with their
    parents; for ``from M import x`` also ``M.x``, which may be a submodule)."""
    try:
        tree = ast.parse(Path(path).read_bytes(), filename=path)
    except (OSError, SyntaxError, ValueError):
        return set()
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                out.add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                try:
                    base = importlib.util.resolve_name("." * node.level + (node.module or ""), package)
                except (ImportError, ValueError):
                    continue
            else:
                base = node.module or ""
            if base:
                out.add(base)
                out.update(f"{base}.{alias.name}" for alias in node.names if alias.name != "*")
    return out


def _origins(value) -> set[str]:
    """The module a global value comes from (a module, a function, a numba dispatcher, a class, or
    the class of an object)."""
    if isinstance(value, types.ModuleType):
        return {value.__name__}
    func = getattr(value, "py_func", None)
    if isinstance(func, types.FunctionType):
        return {func.__module__ or ""}
    if isinstance(value, (types.FunctionType, types.BuiltinFunctionType, type)):
        return {getattr(value, "__module__", "") or ""}
    if isinstance(value, (int, float, complex, str, bytes, bool, type(None))):
        return set()
    return {getattr(type(value), "__module__", "") or ""}


def _functions_modules(target) -> set[str]:
    """The modules defining the functions of a declaration (or a ModelSpec): its fields walked
    recursively (measurements, closed forms, systems; closures and defaults of its functions)."""
    out: set[str] = set()
    seen_ids: set[int] = set()
    stack = [target]
    while stack and len(seen_ids) < _WALK_LIMIT:
        obj = stack.pop()
        if id(obj) in seen_ids or isinstance(obj, (int, float, complex, str, bytes, bool, type(None))):
            continue
        seen_ids.add(id(obj))
        if isinstance(obj, types.ModuleType):
            out.add(obj.__name__)
            continue
        func = getattr(obj, "py_func", None)
        func = func if isinstance(func, types.FunctionType) else obj
        if isinstance(func, types.FunctionType):
            out.add(func.__module__ or "")
            stack.extend(cell.cell_contents for cell in func.__closure__ or () if _full(cell))
            stack.extend(func.__defaults__ or ())
            continue
        if isinstance(obj, (types.BuiltinFunctionType, type)):
            out.add(getattr(obj, "__module__", "") or "")
            continue
        if isinstance(obj, functools.partial):
            stack.extend((obj.func, *obj.args, *obj.keywords.values()))
            continue
        if isinstance(obj, (tuple, list, set, frozenset)):
            stack.extend(obj)
            continue
        if isinstance(obj, dict):
            stack.extend(obj.values())
            continue
        if hasattr(obj, "dtype") and hasattr(obj, "shape"):  # an array: data, not code
            continue
        owner = getattr(type(obj), "__module__", "") or ""
        out.add(owner)
        if _kind(owner) not in ("mechsweep", "user"):  # a library's object (a numba dispatcher's context...)
            continue
        if dataclasses.is_dataclass(obj):
            stack.extend(getattr(obj, f.name, None) for f in dataclasses.fields(obj))
        elif hasattr(obj, "__dict__"):
            stack.extend(vars(obj).values())
    return {m for m in out if m and _exists(m)}


def _full(cell) -> bool:
    try:
        cell.cell_contents
    except ValueError:
        return False
    return True


def _main_module(target) -> str:
    """The module defining the model's main function (rhs, compute, or a ModelSpec's evaluate)."""
    for attr in ("rhs", "compute", "evaluate"):
        func = getattr(target, attr, None)
        if func is not None:
            func = getattr(func, "py_func", func)
            return getattr(func, "__module__", "") or ""
    return ""


def _by_path(name: str) -> bool:
    return name in FILES


# ----------------------------------------------------------------------------- modules and files
def _exists(name: str) -> bool:
    return name in sys.modules or _spec(name) is not None


def _spec(name: str):
    """The spec of a module not loaded, located without importing anything: a top-level module on
    sys.path, or a submodule found in its package's folders (the package loaded or not)."""
    parent, _, leaf = name.rpartition(".")
    if parent:
        package = sys.modules.get(parent)
        if package is not None:
            path = getattr(package, "__path__", None)
        else:
            found = _spec(parent)
            path = getattr(found, "submodule_search_locations", None) if found is not None else None
        if path is None:
            return None
        path = list(path)
    else:
        path = None
    try:
        return importlib.machinery.PathFinder.find_spec(name, path)
    except (ImportError, ValueError, AttributeError):
        return None


def _file(name: str) -> str | None:
    """The absolute path of a module's file (None: none, e.g. a namespace package)."""
    module = sys.modules.get(name)
    if module is not None:
        file = getattr(module, "__file__", None)
    else:
        spec = _spec(name)
        file = spec.origin if spec is not None and spec.has_location else None
    if not isinstance(file, str) or not os.path.isfile(file):
        return None
    return os.path.realpath(file)


def _kind(name: str) -> str | None:
    """"mechsweep", "python" (standard library, built in), "package" (site-packages), "user", or None
    (unknown)."""
    if name == "mechsweep" or name.startswith(("mechsweep.",) + _GENERATED):
        return "mechsweep"
    if name in sys.builtin_module_names:
        return "python"
    if name not in sys.modules and _spec(name) is None:
        return None
    path = _file(name)
    if path is None:
        module = sys.modules.get(name)
        spec = _spec(name) if module is None else getattr(module, "__spec__", None)
        # a namespace package (no file, a search path) holds user modules or others: its parts decide
        return "user" if getattr(spec, "submodule_search_locations", None) else "python"
    if _under(path, _mechsweep_dirs()):
        return "mechsweep"
    if _under(path, _site_dirs()) or any(part in ("site-packages", "dist-packages") for part in Path(path).parts):
        return "package"
    if _under(path, _stdlib_dirs()):
        return "python"
    return "user"


def _under(path: str, folders) -> bool:
    return any(path == f or path.startswith(f + os.sep) for f in folders)


@functools.lru_cache(maxsize=None)
def _mechsweep_dirs() -> tuple[str, ...]:
    return (os.path.realpath(Path(__file__).resolve().parent.parent),)


@functools.lru_cache(maxsize=None)
def _site_dirs() -> tuple[str, ...]:
    dirs = set()
    for get in (site.getsitepackages, lambda: [site.getusersitepackages()]):
        try:
            dirs.update(get())
        except Exception:  # a virtualenv's old site module may lack them
            pass
    paths = sysconfig.get_paths()
    dirs.update(paths[k] for k in ("purelib", "platlib") if k in paths)
    return tuple(sorted({os.path.realpath(d) for d in dirs if d}))


@functools.lru_cache(maxsize=None)
def _stdlib_dirs() -> tuple[str, ...]:
    paths = sysconfig.get_paths()
    dirs = {paths[k] for k in ("stdlib", "platstdlib") if k in paths}
    dirs.add(os.path.dirname(os.__file__))
    return tuple(sorted({os.path.realpath(d) for d in dirs if d}))


def _hash(path: str) -> str:
    if path not in _HASHES:
        h = hashlib.sha256()
        try:
            with open(path, "rb") as f:
                for block in iter(lambda: f.read(1 << 20), b""):
                    h.update(block)
            _HASHES[path] = h.hexdigest()
        except OSError as exc:  # removed or unreadable since it was imported: recorded as such
            return f"unreadable ({exc.strerror})"
    return _HASHES[path]


def _version_of(dist: str) -> str:
    from importlib import metadata

    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return ""


def _distribution(top: str) -> tuple[str, str] | None:
    """(distribution name, version) of an installed top-level package, None when no distribution
    declares it."""
    if top in _DISTS:
        return _DISTS[top]
    from importlib import metadata

    found = None
    try:
        dist = metadata.distribution(top)
        found = (dist.metadata["Name"] or top, dist.version)
    except metadata.PackageNotFoundError:
        names = _packages_distributions().get(top) or []
        for name in names:
            try:
                found = (name, metadata.version(name))
                break
            except metadata.PackageNotFoundError:
                continue
    _DISTS[top] = found
    return found


@functools.lru_cache(maxsize=1)
def _packages_distributions() -> dict:
    from importlib import metadata

    try:
        return metadata.packages_distributions()
    except Exception:  # a broken distribution's metadata
        return {}


def _forget() -> None:
    """Forget every hash and walk memoised in this process, as a new process would (for tests that
    edit files and import them anew in one process)."""
    for memo in (_HASHES, _EDGES, _DIGESTS, _VALUES, _RECORDS, _DISTS):
        memo.clear()
    _packages_distributions.cache_clear()
