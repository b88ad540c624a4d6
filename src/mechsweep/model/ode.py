"""OdeModel: a declarative ODE model. The user writes the physics and what to measure; the engine
writes the chunk kernel (compile.py) and the ModelSpec the runner, store and scene read."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..models._spec import ModelSpec, Param, Setting
from .measure import FLOQUET_MARGIN, Floquet


def _outputs(m):
    """The outputs of one measurement (most have one; Floquet has three)."""
    return m.outputs() if hasattr(m, "outputs") else (m.output(),)


@dataclass(frozen=True)
class OdeModel:
    """A model y' = rhs(t, y, p) released from ``initial(p, y0)`` at t = 0.

    - ``params``: :class:`Param` declarations; ``p`` holds their values in this order (a
      categorical parameter as the index of its choice). ``p`` may be longer than the declared
      parameters (the engine keeps scratch after them): read only ``p[0] .. p[len(params) - 1]``.
    - ``states``: names of the components of y.
    - ``rhs(t, y, p, dydt)``: plain numba-compilable Python (no decorator needed) writing every
      ``dydt[i]``; returns nothing. ``initial(p, y0)``: writes every ``y0[i]``.
    - ``measurements``: instances of the classes in :mod:`mechsweep.model.measure`; each gives
      one output named by its ``name``.
    - ``forcing_period``: optional ``f(p) -> T`` of a T-periodic forcing (Floquet needs it).
    - ``jac``: optional ``jac(t, y, p, J)`` writing every ``J[i, j]`` = d dydt[i] / d y[j] (J is
      n x n); Floquet uses it instead of central differences of ``rhs``.
    """

    name: str
    description: str
    params: tuple[Param, ...]
    states: tuple[str, ...]
    rhs: Callable = field(repr=False)
    initial: Callable = field(repr=False)
    measurements: tuple = ()
    forcing_period: Callable | None = field(default=None, repr=False)
    jac: Callable | None = field(default=None, repr=False)
    source: str = ""
    settings: tuple[Setting, ...] = ()
    statuses: tuple[int, ...] = ()  # ModelSpec.statuses: empty = derived from the outputs
    status_notes: object = ()  # ModelSpec.status_notes: {code: what the status means for this model}

    def __post_init__(self):
        object.__setattr__(self, "params", tuple(self.params))
        object.__setattr__(self, "states", tuple(self.states))
        object.__setattr__(self, "measurements", tuple(self.measurements))
        notes = self.status_notes
        object.__setattr__(self, "status_notes", tuple(sorted(dict(notes).items())))
        if not self.states:
            raise ValueError(f"model {self.name!r}: states is empty")
        names = [o.name for m in self.measurements for o in _outputs(m)]
        if len(set(names)) != len(names):
            raise ValueError(f"model {self.name!r}: measurement (output) names repeat: {names}")
        for m in self.measurements:
            m.validate(self.states)
            if getattr(m, "needs_forcing", False) and self.forcing_period is None:
                raise ValueError(f"model {self.name!r}: measurement {m.name!r} needs forcing_period(p)")

    def spec(self, *, origin: str = "", module: str = "", attr: str = "") -> ModelSpec:
        """The ModelSpec the engine runs. ``module``/``attr`` say where the declaration can be
        imported from in another process (compile.py generates a module that imports it)."""
        from .compile import columns, kernel_for

        model = self

        def evaluate(P, wanted, solver, out, status, n_steps, n_rhs):
            chosen = tuple(m for m in model.measurements if any(o.name in wanted for o in _outputs(m)))
            if not chosen:
                return
            kernel = kernel_for(model, chosen, origin=origin, module=module, attr=attr)
            cols = columns(chosen)
            table = np.full((P.shape[0], cols[-1]), np.nan)
            kernel(np.ascontiguousarray(P, dtype=np.float64), solver.rtol, solver.atol, solver.max_steps, table,
                   status, n_steps, n_rhs)
            for j, m in enumerate(chosen):
                if hasattr(m, "finish"):
                    m.finish(table[:, cols[j]:cols[j + 1]], wanted, solver, out, status)
                else:
                    out[m.name][:] = table[:, cols[j]]

        return ModelSpec(
            name=self.name,
            description=self.description,
            params=self.params,
            outputs=tuple(o for m in self.measurements for o in _outputs(m)),
            evaluate=evaluate,
            source=self.source or origin,
            settings=self.settings + tuple(
                FLOQUET_MARGIN for _ in (0,) if any(isinstance(m, Floquet) for m in self.measurements)
                and FLOQUET_MARGIN.name not in {s.name for s in self.settings}),
            methods=("dop853",),
            statuses=self.statuses,
            status_notes=self.status_notes,
        )
