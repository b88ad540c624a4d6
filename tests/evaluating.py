"""A model's outputs on rows of parameters, without a scene file or a run: the one way the tests
(and the measurement scripts of tests/data) evaluate points.

``evaluate`` hands the rows to ``spec.evaluate`` as the runner does (``execution/execute.py``):
NaN output arrays in their shapes (extra dimensions from the solver's settings), a status and the
step and rhs counts. It compiles nothing of its own: the engine keeps one kernel per model, outputs
and method in a process, so tests that ask for the same outputs with the same method share it.
Pass exactly the outputs a test is about (or ``spec.closure(outputs)`` where the test wants what
they need too): another tuple of outputs may be another kernel."""
from __future__ import annotations

import contextlib

import numpy as np


def blank_outputs(spec, solver, n, wanted) -> dict:
    """NaN arrays for ``wanted`` at ``n`` points, each with its extra dimensions."""
    return {k: np.full((n,) + tuple(len(d.values(solver.settings)) for d in spec.output(k).extra_dims), np.nan)
            for k in wanted}


def rows(spec, **params) -> np.ndarray:
    """Parameter rows in the model's order from ``name=value`` (values broadcast against one
    another); absent parameters at their defaults."""
    arrays = {k: np.atleast_1d(np.asarray(v, float)) for k, v in params.items()}
    n = max(a.size for a in arrays.values())
    P = np.empty((n, len(spec.params)))
    for j, prm in enumerate(spec.params):
        P[:, j] = np.broadcast_to(arrays[prm.name], (n,)) if prm.name in arrays else prm.default
    return P


def evaluate(spec, P, wanted, solver=None, *, status=None, quiet=False, **keys):
    """(out, status, n_steps, n_rhs) of ``spec.evaluate`` on the rows of ``P``.

    ``solver``: a :class:`mechsweep.scene.Solver` (a scene's ``scene.solver``, say), else one made
    from ``keys``, the scene's [solver] keys; ``status``: the statuses the points start from (the
    runner's, when it has flagged some already; copied); ``quiet``: numpy's floating-point warnings
    off (extreme points; otherwise numpy's settings as they are)."""
    from mechsweep.scene import Solver

    if solver is None:
        solver = Solver.for_model(spec, **keys)
    elif keys:
        raise TypeError(f"evaluate: solver keys {sorted(keys)} beside a Solver")
    P = np.ascontiguousarray(P, dtype=float)
    n = P.shape[0]
    out = blank_outputs(spec, solver, n, wanted)
    status = np.zeros(n, np.int8) if status is None else np.array(status, np.int8)
    ns, nr = np.zeros(n, np.int64), np.zeros(n, np.int64)
    with np.errstate(all="ignore") if quiet else contextlib.nullcontext():
        spec.evaluate(P, tuple(wanted), solver, out, status, ns, nr)
    return out, status, ns, nr
