"""Record a model's values on small reference grids: ``python tests/data/record_reference.py``.

The .npz files next to this script were written by this script on the code BEFORE the built-in
Duffing and torsional circuit moved onto the model layer (commit 28a0ab7, hand-written chunk
kernels); tests/model/test_model_layer_builtin.py asserts the current code reproduces them bit for bit
(values, status, n_steps, n_rhs) for every method, output subset and edge case listed here.
Re-running it on the current code must write identical files.
"""
from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
METHODS = ("dop853", "radau", "symplectic", "auto")


def duffing_points() -> np.ndarray:
    rows = [(o, m, a) for o, m, a in itertools.product((0.5, 2.0), np.linspace(-0.5, 20.0, 9), (0.0, 0.1, 0.55, 1.0))]
    rows += [(1.0, m, a) for m, a in itertools.product((1e-3, 1.0, 1e3), (0.01, 1.0))]
    for a in (0.5, 1.0):  # soft springs up to, at and beyond the separatrix, and the saddle formulation
        for delta in (0.5, 1e-2, 3e-3, 1e-3, 1e-5, 1e-9, 1e-13, 0.0, -1e-3):
            rows.append((1.0, -(1.0 - delta) / (a * a), a))
    rows += [(0.0, 1.0, 1.0), (-1.0, 1.0, 1.0), (1.0, math.nan, 1.0), (1.0, 1.0, -0.5)]
    return np.array(rows, dtype=float)


DUFFING_WANTED = (
    ("period", "period_exact", "period_error", "v_max", "a_max", "kv", "ka", "epsilon"),
    ("period",),
    ("period_exact", "v_max"),
    ("kv", "ka", "epsilon", "a_max"),
    ("period", "period_exact", "period_error"),
)


def torsional_points() -> np.ndarray:
    rows = []
    for spring, l1, l2, s, A in itertools.product((0.0, 1.0), (0.3, 1.0, 2.0), (0.0, 0.5), (-0.5, 0.2, 0.8),
                                                   (math.nan, 0.3, 1.0)):
        rows.append((spring, l1, l2, s, 1.0, 1.0, 1.0, A))
    rows += [(0.0, 0.7, 0.3, 0.4, 2.0, 3.0, 0.5, 0.6), (1.0, 1.5, 0.2, 0.3, 0.1, 50.0, 2.0, 2.5),
             (0.0, 1.0, 0.0, 0.5, 1.0, 1.0, 1.0, 0.5)]  # the last: D0 = 0, SINGULAR
    return np.array(rows, dtype=float)


TORSIONAL_WANTED = (
    ("chi", "xi", "omega2", "mu", "hardness", "period", "period_exact", "period_error", "v_max", "a_max", "kv",
     "ka", "epsilon", "period_exact_moment", "truncation_error"),
    ("chi", "xi", "hardness"),
    ("period",),
    ("period_exact", "period_exact_moment", "truncation_error"),
    ("period", "period_exact", "period_error", "epsilon"),
)


def cases(name):
    """(label, P, wanted, solver keywords) of a model's reference grid."""
    if name == "duffing":
        P, wanted_sets = duffing_points(), DUFFING_WANTED
    else:
        P, wanted_sets = torsional_points(), TORSIONAL_WANTED
    out = []
    for method in METHODS:
        for w, wanted in enumerate(wanted_sets):
            out.append((f"{method}-w{w}-tight", P, wanted, dict(method=method, rtol=1e-10, atol=1e-12)))
        out.append((f"{method}-w0-loose", P, wanted_sets[0], dict(method=method, rtol=1e-6, atol=1e-9)))
        out.append((f"{method}-w1-maxsteps", P, ("period",), dict(method=method, rtol=1e-10, atol=1e-12,
                                                                   max_steps=20)))
        out.append((f"{method}-w1-horizon", P, ("period",), dict(method=method, rtol=1e-10, atol=1e-12,
                                                                  t_max_periods=0.1)))
    return out


def evaluate_case(spec, P, wanted, solver_kw):
    from mechsweep.scene import Solver

    solver = Solver.for_model(spec, **solver_kw)
    n = P.shape[0]
    out = {name: np.full(n, np.nan) for name in wanted}
    status = np.zeros(n, dtype=np.int8)
    n_steps = np.zeros(n, dtype=np.int64)
    n_rhs = np.zeros(n, dtype=np.int64)
    with np.errstate(all="ignore"):
        spec.evaluate(P, wanted, solver, out, status, n_steps, n_rhs)
    return out, status, n_steps, n_rhs


def record(name) -> dict:
    from mechsweep.models import MODELS

    spec = MODELS[name]
    arrays = {}
    for label, P, wanted, kw in cases(name):
        out, status, n_steps, n_rhs = evaluate_case(spec, P, wanted, kw)
        for k, v in out.items():
            arrays[f"{label}/{k}"] = v
        arrays[f"{label}/status"] = status
        arrays[f"{label}/n_steps"] = n_steps
        arrays[f"{label}/n_rhs"] = n_rhs
    return arrays


if __name__ == "__main__":
    import sys

    for name in sys.argv[1:] or ("duffing", "torsional_circuit"):
        np.savez_compressed(HERE / f"{name}_reference.npz", **record(name))
        print("wrote", HERE / f"{name}_reference.npz")
