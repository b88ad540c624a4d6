"""Scene -> Plan: what a run computes and how, decided once, before any chunk runs.

A :class:`Plan` holds the outputs stored and those they need, the model's measurements and closed
forms behind them, the solver settings as plain values, the kernel route of each kernel family
("lanes": points side by side, or "point": one at a time; bitwise the same results) and the cut
of the grid into chunks. Every chunk is computed from it, here or on a dask worker (a plan pickles
without its Scene: a worker loads it again from the scene's text). ``Plan.text`` (JSON) is stored
in the journal and as the dataset's ``plan`` attribute.

The route is chosen by :func:`choose_route`, from the run's size and records mechsweep keeps
itself in the cache folder (engine/kernels.py): that a lane kernel has run (``record_compiled``), so
that a later process knows the faster route costs it no compile, and how many points earlier runs
computed one at a time where the lanes would serve (``tally_points``, added by :func:`tally` after
each run), so that small runs of one model that together repay the lanes' compile lead to them."""
from __future__ import annotations

import functools
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..chunks import ChunkPlan
from ..grid import ParameterMatrix, chunk_target

if TYPE_CHECKING:
    from ..scene import Scene

FORMAT = 1  # of Plan.text; a reader can tell plans of later versions apart
LANES, POINT = "lanes", "point"


def choose_route(points: int, facts: Mapping, chosen: bool | None = None) -> str:
    """The route of one kernel family of a run of ``points`` points: LANES or POINT. ``chosen``: the
    scene's ``[execution] lanes`` (True "always", False "never", None "auto"), which decides first.
    ``facts`` come from the model (ModelSpec.plan: ``forced``, the engine's override, which decides
    next; ``from_points``, the run size from which the lanes repay their longer compile; ``recorded``,
    whether the lane kernel is compiled for this CPU already; ``tallied``, the points earlier runs
    computed one at a time, and ``after_points``, what they and this run must reach to repay the
    lanes' whole compile). The lanes integrate about twice as fast and compile about twice as long
    (engine/kernels.py, LANES_FROM_POINTS): they are taken for a run large enough to repay the
    compile, when there is nothing left to compile, or once small runs have added up to what repays
    it (rent until the rent paid would have bought: at most about twice the CPU time of the best
    choice made knowing every later run)."""
    if chosen is not None:
        return LANES if chosen else POINT
    forced = facts.get("forced")
    if forced is not None:
        return LANES if forced else POINT
    if points >= int(facts["from_points"]) or facts.get("recorded"):
        return LANES
    after = facts.get("after_points")
    if after is not None and points + int(facts.get("tallied", 0)) >= int(after):
        return LANES
    return POINT


def extra_shape(scene: Scene, name: str) -> tuple[int, ...]:
    """Sizes of an output's dimensions beyond the grid's."""
    settings = scene.solver.settings if scene.solver is not None else {}
    return tuple(len(d.values(settings)) for d in scene.model.output(name).extra_dims)


def routes(scene: Scene, wanted: tuple[str, ...], points: int) -> dict[str, str]:
    """{kernel family: route} for computing ``wanted`` (closed under the outputs' needs) of ``scene``'s
    model on a run of ``points`` points; empty for a model without a choice of route."""
    hook = getattr(scene.model, "plan", None)
    if hook is None:
        return {}
    facts = hook(wanted, scene.solver).get("lanes", {})
    chosen = scene.execution.use_lanes()
    return {family: choose_route(points, f, chosen) for family, f in sorted(facts.items())}


@dataclass(frozen=True)
class Plan:
    """What a run of a scene computes and how (see the module's docstring). Make it with
    :func:`make_plan`."""

    name: str  # the scene's name
    model: str
    outputs: tuple[str, ...]  # stored
    computed: tuple[str, ...]  # the outputs and what they need, in the model's order
    extra: tuple[tuple[str, tuple[int, ...]], ...]  # (output, its sizes beyond the grid's), computed outputs
    solver: tuple[tuple[str, object], ...] | None  # method, rtol, atol, max_steps, model settings; None: no ODE
    measurements: tuple[str, ...]  # the model's measurements and closed forms behind ``computed``
    closed_forms: tuple[str, ...]
    route: tuple[tuple[str, str], ...]  # (kernel family, LANES or POINT)
    shape: tuple[int, ...]  # the grid
    chunk_target: int  # points per chunk (at most)
    scene_text: str = field(repr=False)
    base: str = ""  # the folder a user model file path in the scene is resolved against
    records: tuple[tuple[str, str], ...] = ()  # (kernel family, the name its lane kernel is recorded by)
    _scene: Scene | None = field(default=None, repr=False, compare=False)

    @property
    def scene(self) -> Scene:
        """The validated Scene: the one the plan was made from, or (a plan sent to another process)
        loaded again from its text, once per process."""
        if self._scene is None:
            object.__setattr__(self, "_scene", _loaded(self.scene_text, self.base)[0])
        return self._scene

    @functools.cached_property
    def params(self) -> ParameterMatrix:
        """The parameter rows of any range of the grid."""
        if self._scene is None:
            return _loaded(self.scene_text, self.base)[1]
        return ParameterMatrix(self.scene)

    @functools.cached_property
    def chunks(self) -> ChunkPlan:
        """The grid's chunks (made on demand from their index: O(1) memory, whatever their number)."""
        return ChunkPlan(self.shape, self.chunk_target)

    @property
    def n_points(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64)) if self.shape else 1

    @property
    def routes(self) -> dict[str, str]:
        """{kernel family: route}, as ``ModelSpec.evaluate(..., route=)`` takes it."""
        return dict(self.route)

    def extra_shape(self, name: str) -> tuple[int, ...]:
        return dict(self.extra)[name]

    def text(self) -> str:
        """The plan as stable JSON (sorted keys), as the journal and the dataset's ``plan`` attribute
        store it."""
        chunks = self.chunks
        return json.dumps({
            "format": FORMAT, "scene": self.name, "model": self.model, "outputs": list(self.outputs),
            "computed": list(self.computed), "measurements": list(self.measurements),
            "closed_forms": list(self.closed_forms),
            "solver": None if self.solver is None else dict(self.solver),
            "route": dict(self.route), "grid": list(self.shape), "points": self.n_points,
            "chunks": {"target": self.chunk_target, "count": len(chunks), "largest": chunks.max_size},
        }, sort_keys=True)

    def __getstate__(self):
        """Pickled without the Scene (its model's functions need not pickle) and what is made from it
        on demand: a dask worker loads the scene again from ``scene_text``."""
        state = dict(self.__dict__)
        state["_scene"] = None
        state.pop("params", None)
        state.pop("chunks", None)
        return state


def make_plan(scene: Scene, target: int | None = None) -> Plan:
    """The plan of a run of ``scene`` cut into chunks of at most ``target`` points (default: the
    grid's default cut, grid.chunk_target)."""
    computed = scene.computed_outputs
    hook = getattr(scene.model, "plan", None)
    parts = hook(computed, scene.solver) if hook is not None else {}
    chosen = scene.execution.use_lanes()  # the scene's [execution] lanes
    lanes = parts.get("lanes", {})
    route = {family: choose_route(scene.n_points, f, chosen) for family, f in sorted(lanes.items())}
    return Plan(
        name=scene.name,
        model=scene.model.name,
        outputs=tuple(scene.outputs),
        computed=tuple(computed),
        extra=tuple((name, extra_shape(scene, name)) for name in computed),
        solver=None if scene.solver is None else tuple(scene.solver.as_dict().items()),
        measurements=tuple(parts.get("measurements", ())),
        closed_forms=tuple(parts.get("closed_forms", ())),
        route=tuple(route.items()),
        shape=tuple(scene.shape),
        chunk_target=int(target if target is not None else chunk_target(scene)),
        scene_text=scene.text,
        base=scene.base,
        records=tuple((family, f["record"]) for family, f in sorted(lanes.items()) if f.get("record")),
        _scene=scene,
    )


def tally(plan: Plan, points: int) -> None:
    """After a run: its ``points`` computed one at a time go to the tally of each kernel family whose
    lanes the plan did not take (engine/kernels.py, ``tally_points``; read by a later plan)."""
    todo = [record for family, record in plan.records if plan.routes.get(family) == POINT]
    if todo and points > 0:
        from ..engine.kernels import tally_points

        for record in todo:
            tally_points(record, points)


@functools.lru_cache(maxsize=4)
def _loaded(text: str, base: str = ""):
    """A scene sent as text (to a dask worker) and its parameter rows, loaded once per process."""
    from ..scene import load_scene_text

    scene = load_scene_text(text, label="scene sent by the mechsweep client", base=base or None)
    return scene, ParameterMatrix(scene)
