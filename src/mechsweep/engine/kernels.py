"""The engine's entry points: a model's chunk kernel for a choice of outputs, a method and a route.

Routes of an OdeModel's measurements (other than the sampled trajectories, engine/trajectory.py):

- ``"point"``: one point at a time per thread (engine/point.py): every measurement, every method;
- ``"lanes"``: LANES points side by side per thread in SIMD lanes (engine/lanes.py), bitwise the
  same results: one measurement integrated on its own (a first root, down), by dop853, of an rhs the
  engine can rewrite in lane form (engine/lane_rhs.py), without switch times, a status order or a
  measurement's classify. :func:`lanes_apply` says whether it applies.

``kernel_for(..., route=None)`` takes the lanes where they apply and pay (``LANES_FROM_POINTS``, or
compiled already: :func:`compiled`). Each kernel is built once per process and its machine code is
cached on disk through its binding module (engine/binding.py), named by :func:`binding_name`.
"""
from __future__ import annotations

import hashlib
import threading

from ..model import load, sources
from ..ode import methods
from . import binding, lane_rhs, lanes, point
from .point import Threaded

ROUTES = ("point", "lanes")
# kernel_for's default route where the lanes apply: True the lanes, False one point at a time, None (the
# default) the lanes only where they pay: for a run of at least LANES_FROM_POINTS points, or when the
# lane kernel is compiled already (in this process, or recorded on disk: binding.compiled). The results
# are bitwise the same either way (tests/test_model_lanes.py); the benches and tests set True or False.
USE_LANES: bool | None = None
# The lane kernel compiles in more CPU time than the one-point kernel and integrates about twice as
# fast: the crossover is measured by `mechsweep bench startup --only routes` (docs/performance-startup.md).
LANES_FROM_POINTS = 10**7
_PLAN = threading.local()  # the size of the run being computed in this thread (planned_points)
_MEMO: dict[tuple, tuple] = {}  # kernel_for's memo by the objects' ids: (the objects kept alive, names)
_KERNELS: dict[str, object] = {}  # binding name -> kernel, in this process
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


def lane_name(model, chosen, closed, method, source: str) -> str:
    return binding_name(model, chosen, closed, method, "lanes",
                        repr((lanes.lanes_for(len(model.states)), lanes.QUEUE)) + source)


def lane_kernel(model, chosen, closed, method, source: str):
    """The lane kernel of this choice (engine/lanes.py); ``source``: lanes_apply's lane rhs."""
    name = lane_name(model, chosen, closed, method, source)
    extra = lane_rhs.binding_text(source)
    mod = binding.bind(name, f"model {model.name!r}, {lanes.lanes_for(len(model.states))} points side by side, "
                             f"method {method.name}",
                       {"kernel": lanes.ARGS}, lambda rhs_lanes: lanes.build(model, chosen, closed, rhs_lanes),
                       extra=extra, lane_names=("rhs_lanes",))
    return binding.Marking(mod.kernel, name)


class planned_points:
    """``with planned_points(n):`` the kernels fetched in this thread serve a run of ``n`` points (the
    runner says so around each chunk: a chunk, or the warm-up's one point, is smaller than the run).
    kernel_for's automatic route (``route=None``) compares it with LANES_FROM_POINTS."""

    def __init__(self, n: int):
        self.n = int(n)

    def __enter__(self):
        self.before = getattr(_PLAN, "n", 0)
        _PLAN.n = self.n
        return self

    def __exit__(self, *exc):
        _PLAN.n = self.before


def _method(method):
    return methods.method(method) if isinstance(method, str) else method


def names(model, chosen, closed=(), method="dop853") -> dict:
    """{route: binding name} of the routes that serve this choice (the lanes only where they apply;
    the lane rhs's source under "lane_rhs"), memoised by the objects (every chunk of a run asks)."""
    chosen, closed, method = tuple(chosen), tuple(closed), _method(method)
    memo = (id(model), tuple(map(id, chosen)), tuple(map(id, closed)), method.name)
    known = _MEMO.get(memo)
    if (known is not None and known[0] is model and all(a is b for a, b in zip(known[1], chosen))
            and all(a is b for a, b in zip(known[2], closed))):
        return known[3]
    out = {"point": binding_name(model, chosen, closed, point.integration_method(chosen, method), "point")}
    source = lanes_apply(model, chosen, method)
    if source is not None:
        out["lanes"] = lane_name(model, chosen, closed, method, source)
        out["lane_rhs"] = source
    with _LOCK:
        _MEMO[memo] = (model, chosen, closed, out)  # the objects kept alive: their ids stay theirs
    return out


def compiled(model, chosen, closed=(), method="dop853", route: str = "point") -> bool:
    """Whether the kernel of this choice and route is compiled: built in this process, or recorded on
    disk by an earlier process (engine/binding.py ``compiled``); False for a route that does not
    apply. Cheap: no kernel is built or imported."""
    name = names(model, chosen, closed, method).get(route)
    return name is not None and binding.compiled(name)


def choose_route(model, chosen, closed=(), method="dop853", points: int = 0) -> str:
    """The route kernel_for takes by default: the lanes where they apply and USE_LANES says so, or
    (USE_LANES None) where they pay: a run of at least LANES_FROM_POINTS points (``points``, or the
    run's size: planned_points), or the lane kernel compiled already."""
    found = names(model, chosen, closed, method)
    if "lanes" not in found or USE_LANES is False:
        return "point"
    if USE_LANES:
        return "lanes"
    points = max(int(points), getattr(_PLAN, "n", 0))
    if points >= LANES_FROM_POINTS or binding.compiled(found["lanes"]):
        return "lanes"
    return "point"


def kernel_for(model, chosen, *, closed=(), method="dop853", route: str | None = None, points: int = 0, **_):
    """The compiled chunk kernel ``kernel(P, S, need, rtol, atol, max_steps, table, status, n_steps,
    n_rhs)`` of ``model`` for the measurements ``chosen`` and the closed forms ``closed`` (dependency
    order; closed form j is computed where ``need[j]``, a run-time choice) by ``method`` (a name or an
    ode/methods.py method), by ``route`` ("point", "lanes"; None: choose_route). S: the model's
    settings in declared order. Built once per process (memoised), compiled once (numba's disk cache
    through the binding module)."""
    chosen, closed, method = tuple(chosen), tuple(closed), _method(method)
    route = route or choose_route(model, chosen, closed, method, points)
    found = names(model, chosen, closed, method)
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
