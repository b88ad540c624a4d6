"""`mechsweep bench period-error`: worst period error over epsilon for a ladder of tolerances.

T omega of the Duffing oscillator depends on epsilon = mu A^2 / omega^2 alone, so a fine scan
of epsilon in [-0.99, 1e4] (omega = A = 1) covers every (omega, mu, A). Prints, per (rtol, atol),
the largest relative error of the integrated period against the elliptic closed form, where it
occurs, and the mean number of steps: the evidence behind the default tolerances.
"""
from __future__ import annotations

import numpy as np

from ..models import duffing
from ..scene import Solver

LADDER = ((1e-8, 1e-10), (1e-9, 1e-11), (1e-10, 1e-12), (1e-10, 1e-13), (5e-11, 1e-12), (2e-11, 1e-13),
          (1e-12, 1e-14))


def epsilon_scan(n_soft: int = 20_000, n_hard: int = 20_000) -> np.ndarray:
    return np.concatenate([np.linspace(-0.99, -0.001, n_soft), [0.0], np.geomspace(1e-6, 1e4, n_hard)])


def worst_error(eps: np.ndarray, rtol: float, atol: float) -> dict:
    n = eps.size
    P = np.stack([np.ones(n), eps, np.ones(n)], axis=1)
    wanted = duffing.SPEC.closure(("period_error",))
    out = {name: np.full(n, np.nan) for name in wanted}
    status = np.zeros(n, np.int8)
    n_steps = np.zeros(n, np.int64)
    n_rhs = np.zeros(n, np.int64)
    duffing.evaluate(P, wanted, Solver.for_model(duffing.SPEC, rtol=rtol, atol=atol), out, status, n_steps, n_rhs)
    err = out["period_error"]
    worst = int(np.nanargmax(err))
    return {"rtol": rtol, "atol": atol, "max_error": float(err[worst]), "at_epsilon": float(eps[worst]),
            "mean_steps": float(n_steps.mean()), "not_ok": int((status != 0).sum())}


def main(ladder=LADDER) -> list[dict]:
    eps = epsilon_scan()
    print(f"mechsweep bench period-error: {eps.size} values of epsilon in [-0.99, 1e4], DOP853; "
          f"defaults rtol={Solver.rtol:g}, atol={Solver.atol:g}")
    print(f"  {'rtol':>8} {'atol':>8}  {'max rel. error':>14}  {'at epsilon':>11}  {'steps/pt':>8}  not ok")
    rows = []
    for rtol, atol in ladder:
        r = worst_error(eps, rtol, atol)
        rows.append(r)
        print(f"  {rtol:8.0e} {atol:8.0e}  {r['max_error']:14.3e}  {r['at_epsilon']:11.4g}  "
              f"{r['mean_steps']:8.2f}  {r['not_ok']}")
    return rows
