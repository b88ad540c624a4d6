"""The engine's entry points: a model's chunk kernel for a choice of outputs, a method and a route.

Routes of an OdeModel's measurements (other than the sampled trajectories, engine/trajectory.py):

- ``"point"``: one point at a time per thread (engine/point.py): every measurement, every method;
- ``"lanes"``: LANES points side by side per thread in SIMD lanes (engine/lanes.py), bitwise the
  same results: one measurement integrated on its own (a first root, down), by dop853, of an rhs the
  engine can rewrite in lane form (engine/lane_rhs.py), without switch times, a status order or a
  measurement's classify. :func:`lanes_apply` says whether it applies.

A run names the route its plan chose (execution/plan.py, ``choose_route``: the lanes for a run of at
least LANES_FROM_POINTS points, or once :func:`lanes_recorded` says the lane kernel is compiled, or once
the model's runs computed LANES_AFTER_POINTS points one at a time, :func:`points_tallied`).
Each kernel is built once per process and its machine code is cached on disk through its binding
module (engine/binding.py), named by :func:`binding_name`.
"""
from __future__ import annotations

import atexit
import functools
import hashlib
import os
import threading
from pathlib import Path

from .. import _jit
from ..model import load, sources
from ..ode import methods
from . import binding, lane_rhs, lanes, point
from .point import Threaded

ROUTES = ("point", "lanes")
# kernel_for's route where the lanes apply and the caller names none (``lanes=None``): True the lanes,
# False or None one point at a time. A run names the route its plan chose (execution/plan.py,
# ``choose_route``, which reads this as an override: the benches and tests set True or False to compare
# the two routes). The results are bitwise the same either way (tests/engine/test_model_lanes.py).
USE_LANES: bool | None = None
# The lane kernel compiles in about twice the CPU time of the one-point kernel and integrates about
# twice as fast (Duffing period, sweeps/quickstart.toml; `python benchmarks/startup.py --only routes`
# measures both and prints the crossover): its extra compile, about 5-5.5 s of CPU, is repaid at
# 5.4e6-6.0e6 points. A plan takes the lanes for a run of at least this many points, or when they are
# compiled already (``lanes_recorded``).
LANES_FROM_POINTS = 6 * 10**6
# Once the one-point kernel is compiled, the lanes cost their whole compile, about twice their extra
# compile (the same command prints the points that repay it: 1.1e7 on a 2-core Zen 3). The points a
# model's runs computed one at a time are tallied (``tally_points``), and a plan takes the lanes once
# that tally with its own run reaches this many points.
LANES_AFTER_POINTS = 11 * 10**6
_BY_OBJECTS: dict[tuple, tuple] = {}  # names()' memo by the objects' ids: (the objects kept alive, names)
_KERNELS: dict[str, object] = {}  # binding name -> kernel, in this process
_RECORDED: set[str] = set()  # lane kernels compiled (or loaded from the disk cache) in this process
_TALLY: dict[str, int] = {}  # points computed one at a time in this process, by lane record name
_FLUSH_AT_EXIT: list = []  # write_tallies, once registered with atexit
_CPU: list[str] = []
_LOCK = threading.RLock()


def _functions(model, chosen, closed) -> list[tuple[str, object]]:
    """(role, function) of everything a kernel of this choice may call: what its name is keyed by."""
    f = [("rhs", model.rhs), ("initial", model.initial)]
    for role in ("forcing", "jac", "accel", "classify", "prepare", "symplectic_step"):
        func = getattr(model, "forcing_period" if role == "forcing" else role, None)
        if func is not None:
            f.append((role, func))
    if callable(getattr(model, "switch_times", None)):
        f.append(("switch_times", model.switch_times))
    for k, m in enumerate(chosen):
        for role, func in getattr(m, "functions", lambda: ())():
            f.append((f"{role}{k}", func))
        if getattr(m, "classify", None) is not None:
            f.append((f"mclassify{k}", m.classify))
    for j, c in enumerate(closed):
        f.append((f"closed{j}", c.func))
        if getattr(c, "classify", None) is not None:
            f.append((f"cfclassify{j}", c.classify))
    return f


def _switch_key(model) -> str:
    sw = getattr(model, "switch_times", None)
    if sw is None:
        return ""
    from ..model.switches import SIDE, constants
    return repr(("switch_times", constants(model) or "function", SIDE))


def binding_name(model, chosen, closed, method, route: str, extra: str = "") -> str:
    """The name of a kernel's binding module: a digest of the model's dependency record (its sources
    and every module they import, mechsweep's own), the functions' names, the layout of p, the
    measurements' settings, the closed forms, the method and the route (``extra``: e.g. the lane rhs)."""
    key = hashlib.sha256()
    for role, func in _functions(model, chosen, closed):
        ref = load.function_ref(func, role, model.name)
        key.update(role.encode())
        key.update(repr(ref).encode())
        key.update(load.module_source(ref[0], ref[1]))
    key.update(sources.record(model).digest.encode())
    key.update(_switch_key(model).encode())
    key.update(repr((model.name, len(model.params), len(model.settings), len(model.internal), len(model.states),
                     getattr(model, "symplectic_order", 0), tuple(getattr(m, "key", lambda: m)() for m in chosen),
                     tuple((c.name, c.needs) for c in closed), method.name, route,
                     tuple(getattr(model, "status_order", ())))).encode())
    key.update(extra.encode())
    return binding.PREFIXES[route] + key.hexdigest()[:20]


def point_kernel(model, chosen, closed, method):
    """The one-point kernel of this choice (engine/point.py), threaded (point.Threaded)."""
    method = point.integration_method(chosen, methods.method(method) if isinstance(method, str) else method)
    name = binding_name(model, chosen, closed, method, "point")
    mod = binding.bind(name, f"model {model.name!r}, one point at a time, method {method.name}",
                       {"kernel": point.ARGS}, lambda: point.build(model, chosen, closed, method))
    return Threaded(mod.kernel, name)


def lanes_apply(model, chosen, method) -> str | None:
    """The lane form of the rhs when the lane kernel serves this choice, else None: one measurement
    integrated on its own (a FirstEvent, possibly of a System, or a lone first Crossing) to its first
    root downwards, without refine or a classify of its own, by a method that runs in lanes (dop853),
    for a model without switch times or a status order, of an rhs the rewrite covers."""
    method = _method(method)
    if not method.lanes or len(chosen) != 1 or getattr(model, "switch_times", None) is not None:
        return None  # a model with switch times integrates one point at a time (engine/switches.py)
    if getattr(model, "status_order", ()):
        return None
    m = chosen[0]
    if (not point.is_direct(chosen) or getattr(m, "refine", None) is not None or getattr(m, "classify", None)
            or getattr(m, "n", 1) != 1 or getattr(m, "direction", "down") != "down" or not hasattr(m, "point")):
        return None
    system = getattr(m, "system", None)
    return lane_rhs.lane_rhs_source(model.rhs if system is None else system.rhs)


def _lane_binding(model, chosen, closed, method, source: str) -> str:
    return binding_name(model, chosen, closed, method, "lanes",
                        repr((lanes.lanes_for(len(model.states)), lanes.QUEUE)) + source)


def lane_kernel(model, chosen, closed, method, source: str):
    """The lane kernel of this choice (engine/lanes.py); ``source``: lanes_apply's lane rhs."""
    name = _lane_binding(model, chosen, closed, method, source)
    extra = lane_rhs.binding_text(source)
    mod = binding.bind(name, f"model {model.name!r}, {lanes.lanes_for(len(model.states))} points side by side, "
                             f"method {method.name}",
                       {"kernel": lanes.ARGS}, lambda rhs_lanes: lanes.build(model, chosen, closed, rhs_lanes),
                       extra=extra, lane_names=("rhs_lanes",))
    tails = functools.partial(lanes.shared_counter, lanes=lanes.lanes_for(len(model.states)))
    return _Recorded(Threaded(mod.kernel, name, tails), name)


def _method(method):
    return methods.method(method) if isinstance(method, str) else method


def names(model, chosen, closed=(), method="dop853") -> dict:
    """{route: binding name} of the routes that serve this choice (the lanes only where they apply;
    the lane rhs's source under "lane_rhs"), memoised by the objects (every chunk of a run asks)."""
    chosen, closed, method = tuple(chosen), tuple(closed), _method(method)
    memo = (id(model), tuple(map(id, chosen)), tuple(map(id, closed)), method.name)
    known = _BY_OBJECTS.get(memo)
    if (known is not None and known[0] is model and all(a is b for a, b in zip(known[1], chosen))
            and all(a is b for a, b in zip(known[2], closed))):
        return known[3]
    out = {"point": binding_name(model, chosen, closed, point.integration_method(chosen, method), "point")}
    source = lanes_apply(model, chosen, method)
    if source is not None:
        out["lanes"] = _lane_binding(model, chosen, closed, method, source)
        out["lane_rhs"] = source
    with _LOCK:
        _BY_OBJECTS[memo] = (model, chosen, closed, out)  # the objects kept alive: their ids stay theirs
    return out


def lane_name(model, chosen, *, origin: str = "", closed=(), method="dop853") -> str | None:
    """The name of the lane kernel that ``kernel_for(model, chosen, closed=closed, method=method,
    lanes=True)`` returns (the key of its record, ``lanes_recorded``), or None when the lanes do not
    serve this choice (then every route is one point at a time). Cheap: nothing is built or imported."""
    return names(model, chosen, closed, method).get("lanes")


# ----------------------------------------------------------------------------- the record of compiled lanes
def _cpu_tag() -> str:
    """What numba's machine code is specific to: the target triple, the host CPU and its features (and
    numba's variables that override them). A record of a lane kernel compiled on another CPU that shares
    the cache folder (a home directory on a network disk) does not count here."""
    if not _CPU:
        import llvmlite.binding as llvm

        parts = (llvm.get_process_triple(), llvm.get_host_cpu_name(), llvm.get_host_cpu_features().flatten(),
                 os.environ.get("NUMBA_CPU_NAME", ""), os.environ.get("NUMBA_CPU_FEATURES", ""))
        _CPU.append(hashlib.sha256("|".join(parts).encode()).hexdigest()[:12])
    return _CPU[0]


def _record_path(name: str) -> Path:
    return binding.folder() / f"{name}.{_cpu_tag()}.compiled"


def lanes_recorded(name: str) -> bool:
    """Whether the lane kernel ``name`` (``lane_name``, or engine/sampling.py's lane_name) is compiled
    for this CPU: in this process, or by an earlier process that left its record in the cache folder
    (written by ``record_compiled`` once the kernel had run, i.e. once numba had compiled it and saved
    its machine code: ``cache=True`` saves at compile time). The record is mechsweep's own, next to the
    kernel's binding module; it lives and goes with the cache folder, which is keyed by mechsweep's sources."""
    if name in _RECORDED:
        return True
    return _jit.cache_dir is not None and _record_path(name).exists()


def record_compiled(name: str) -> None:
    """Note that the lane kernel ``name`` has run in this process (compiled, or loaded from the disk
    cache), in this process and, when caching is on, as a file in the cache folder."""
    if name in _RECORDED:
        return
    _RECORDED.add(name)
    if _jit.cache_dir is None:
        return
    path = _record_path(name)
    if not path.exists():
        _write_quietly(path, b"")


def _write_quietly(path: Path, data: bytes) -> None:
    """``data`` into ``path`` at once (a temporary file renamed), or nothing: a record that cannot be
    written costs a later run the faster route, nothing else."""
    tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError:
        try:
            tmp.unlink()
        except OSError:
            pass


def _tally_path(name: str) -> Path:
    return binding.folder() / f"{name}.{_cpu_tag()}.points"


def points_tallied(name: str) -> int:
    """The points computed one at a time by earlier runs on this CPU where the lane kernel ``name``
    serves (``tally_points``): in the cache folder, and those of this process not yet written there."""
    pending = _TALLY.get(name, 0)
    if _jit.cache_dir is None:
        return pending
    try:
        return max(0, int(_tally_path(name).read_text())) + pending
    except (OSError, ValueError):
        return pending


def tally_points(name: str, n: int) -> None:
    """Add a run's ``n`` points computed one at a time to the tally of the lane kernel ``name``, which a
    later plan reads (execution/plan.py, ``choose_route``): small runs of one model that add up to what
    repays the lanes' whole compile make the next run take them. Kept in this process and written to the
    cache folder when it exits (``write_tallies``), so that a run pays no file write for it."""
    with _LOCK:
        if not _FLUSH_AT_EXIT:
            _FLUSH_AT_EXIT.append(atexit.register(write_tallies))
            if hasattr(os, "register_at_fork"):  # a forked child does not write its parent's points again
                os.register_at_fork(after_in_child=_TALLY.clear)
        _TALLY[name] = _TALLY.get(name, 0) + int(n)


def write_tallies() -> None:
    """Add this process's tallies to those in the cache folder (nothing when caching is off: they stay
    this process's). Two processes writing at once may lose one's points: the lanes then come a run
    later."""
    with _LOCK:
        if _jit.cache_dir is None:
            return
        for name in _TALLY:
            _write_quietly(_tally_path(name), str(points_tallied(name)).encode())  # the stored tally and this one
        _TALLY.clear()


class _Recorded:
    """A lane kernel that records itself (``record_compiled``) after its first call returns."""

    def __init__(self, kernel, name: str):
        self.kernel, self.name = kernel, name

    def __getattr__(self, attr):
        return getattr(self.kernel, attr)

    def __call__(self, *args):
        self.kernel(*args)
        record_compiled(self.name)


# ----------------------------------------------------------------------------- the entry point
def kernel_for(model, chosen, *, origin: str = "", module: str = "", attr: str = "", closed=(), method="dop853",
               lanes: bool | None = None, route: str | None = None):
    """The compiled chunk kernel ``kernel(P, S, need, rtol, atol, max_steps, table, status, n_steps,
    n_rhs)`` of ``model`` for the measurements ``chosen`` and the closed forms ``closed`` (dependency
    order; closed form j is computed where ``need[j]``, a run-time choice) by ``method`` (a name or an
    ode/methods.py method). S: the model's settings in declared order.
    ``lanes``: where the lanes apply (``lanes_apply``), True the kernel integrates LANES points side by
    side (bitwise the same results; ``lane_name`` names it), False one at a time, None as USE_LANES says
    (one at a time unless it is True). A run passes the route its plan chose. ``route`` ("point",
    "lanes") names the route outright (an error where it does not apply).
    Built once per process (memoised), compiled once (numba's disk cache through the binding module).
    ``origin``, ``module``, ``attr``: unused (the binding imports the model's functions by module path)."""
    chosen, closed, method = tuple(chosen), tuple(closed), _method(method)
    found = names(model, chosen, closed, method)
    if route is None:
        route = "lanes" if bool(USE_LANES if lanes is None else lanes) and "lanes" in found else "point"
    if route not in found:
        raise ValueError(f"route {route!r} does not serve this choice (routes: {', '.join(r for r in found if r in ROUTES)})")
    name = found[route]
    with _LOCK:
        kernel = _KERNELS.get(name)
        if kernel is None:
            if route == "lanes":
                kernel = lane_kernel(model, chosen, closed, method, found["lane_rhs"])
            else:
                kernel = point_kernel(model, chosen, closed, method)
            _KERNELS[name] = kernel
    return kernel
