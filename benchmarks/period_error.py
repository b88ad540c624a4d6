"""`python benchmarks/period_error.py`: worst period error over epsilon for a ladder of tolerances.

T omega of the Duffing oscillator depends on epsilon = mu A^2 / omega^2 alone, so a fine scan
of epsilon in [-0.99, 1e4] (omega = A = 1) covers every (omega, mu, A). Prints, per (rtol, atol),
the largest relative error of the integrated period against the elliptic closed form, where it
occurs, the largest over hard springs (epsilon >= 0) and over soft springs (epsilon < 0) apart
(soft springs reach larger errors at the same tolerance), and the mean number of steps: the
evidence behind the default tolerances and behind docs/numerics.md's advice for nomograms read
by eye (rtol 1e-6). The same scan with the symplectic method, whose fixed step is calibrated from
rtol (models/duffing.py, symplectic_step): its largest error as a fraction of rtol.

Then, towards the soft separatrix (1 + epsilon from 1e-3 to 1e-7), the error of the plain
quarter-period integration in x = phi / A divided by rtol (the saddle's amplification, the reason
the model switches to saddle coordinates there), and the error the model gives at the defaults.
"""
from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):  # run as `python benchmarks/NAME.py`: import from the repository's root, as -m does
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import math

import numpy as np

from mechsweep._jit import jit
from mechsweep.models import duffing
from mechsweep.ode import dop853
from mechsweep.scene import Solver

LADDER = ((1e-6, 1e-8), (1e-8, 1e-10), (1e-9, 1e-11), (1e-10, 1e-12), (1e-10, 1e-13), (5e-11, 1e-12), (2e-11, 1e-13),
          (1e-12, 1e-14))


def epsilon_scan(n_soft: int = 20_000, n_hard: int = 20_000) -> np.ndarray:
    return np.concatenate([np.linspace(-0.99, -0.001, n_soft), [0.0], np.geomspace(1e-6, 1e4, n_hard)])


def worst_error(eps: np.ndarray, rtol: float, atol: float, method: str = "dop853") -> dict:
    n = eps.size
    P = np.stack([np.ones(n), eps, np.ones(n)], axis=1)
    wanted = duffing.SPEC.closure(("period_error",))
    out = {name: np.full(n, np.nan) for name in wanted}
    status = np.zeros(n, np.int8)
    n_steps = np.zeros(n, np.int64)
    n_rhs = np.zeros(n, np.int64)
    duffing.evaluate(P, wanted, Solver.for_model(duffing.SPEC, rtol=rtol, atol=atol, method=method), out, status,
                     n_steps, n_rhs)
    err = out["period_error"]
    worst = int(np.nanargmax(err))
    hard = eps >= 0.0
    return {"rtol": rtol, "atol": atol, "max_error": float(err[worst]), "at_epsilon": float(eps[worst]),
            "max_error_hard": float(np.nanmax(err[hard])) if hard.any() else math.nan,
            "max_error_soft": float(np.nanmax(err[~hard])) if (~hard).any() else math.nan,
            "mean_steps": float(n_steps.mean()), "not_ok": int((status != 0).sum())}


# The plain quarter-period integration, without the model's saddle coordinates: x = phi / A,
# x'' = -(p0 x + p1 x^3 + p2 x^2) from x = 1 at rest to the event p7 (x - p6) = 0, with
# p = (a, b, 0, ., ., ., 0, 1) (x'' = -a x - b x^3, event x = 0).
@jit
def _scaled_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * y[0] - p[1] * y[0] * y[0] * y[0] - p[2] * y[0] * y[0]


@jit
def _phi_event(t, y, p):
    return p[7] * (y[0] - p[6])


quarter_period_solver = dop853.make_event_solver(_scaled_rhs, _phi_event)

SYMPLECTIC_LADDER = ((1e-6, 1e-8), (1e-8, 1e-10), (1e-10, 1e-12), (5e-11, 1e-12), (1e-12, 1e-14))
SEPARATRIX_GAPS = (1e-3, 1e-5, 1e-7)  # 1 + epsilon
SEPARATRIX_RTOLS = (5e-9, 5e-11, 5e-13)


def plain_period_error(gap: float, rtol: float) -> float:
    """Relative period error at epsilon = -(1 - gap) (omega = A = 1) of dop853 on the plain scaled
    equation x = phi / A with rtol, atol = rtol / 50 (not the saddle coordinates the model uses)."""
    omega2, mu, A = 1.0, -(1.0 - gap), 1.0
    w2 = omega2 + abs(mu)
    p = np.array([omega2 / w2, mu / w2, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])  # the plain formulation (above)
    y = np.array([1.0, 0.0])
    code, tq, _, _ = quarter_period_solver(0.0, y, p, 200 * math.pi, rtol, rtol / 50, 0.0, 10**6, dop853.workspace(2))
    exact = duffing.period_closed_form(omega2, mu, A)
    return abs(4.0 * tq / math.sqrt(w2) - exact) / exact if code == 0 else math.nan


def separatrix_table() -> list[dict]:
    print("  near the soft separatrix: error / rtol of the plain formulation (the saddle's amplification), "
          "and the model's error (saddle coordinates)")
    rows = []
    for gap in SEPARATRIX_GAPS:
        amp = [plain_period_error(gap, r) / r for r in SEPARATRIX_RTOLS]
        out = {k: np.full(1, np.nan) for k in ("period", "period_exact", "period_error")}
        status, ns = np.zeros(1, np.int8), np.zeros(1, np.int64)
        duffing.evaluate(np.array([[1.0, -(1.0 - gap), 1.0]]), tuple(out), Solver.for_model(duffing.SPEC), out,
                         status, ns, ns.copy())
        err = float(out["period_error"][0])
        rows.append({"gap": gap, "amplification": amp, "model_error": err,
                     "status": int(status[0])})
        verdict = f"error at the defaults {err:.2e}" if status[0] == 0 else "ill_conditioned at the defaults"
        print(f"    1 + eps = {gap:6.0e}: x" + ", x".join(f"{a:.3g}" for a in amp)
              + f" (rtol {', '.join(f'{x:g}' for x in SEPARATRIX_RTOLS)}); {verdict}")
    return rows


def main(ladder=LADDER) -> list[dict]:
    eps = epsilon_scan()
    print(f"benchmarks/period_error.py: {eps.size} values of epsilon in [-0.99, 1e4], DOP853; "
          f"defaults rtol={Solver.rtol:g}, atol={Solver.atol:g}")
    print(f"  {'rtol':>8} {'atol':>8}  {'max rel. error':>14}  {'at epsilon':>11}  {'hard (eps>=0)':>13}  "
          f"{'soft (eps<0)':>12}  {'steps/pt':>8}  not ok")
    rows = []
    for rtol, atol in ladder:
        r = worst_error(eps, rtol, atol)
        rows.append(r)
        print(f"  {rtol:8.0e} {atol:8.0e}  {r['max_error']:14.3e}  {r['at_epsilon']:11.4g}  "
              f"{r['max_error_hard']:13.3e}  {r['max_error_soft']:12.3e}  {r['mean_steps']:8.2f}  {r['not_ok']}")
    # the symplectic method's fixed step is calibrated from rtol (models/duffing.py, symplectic_step)
    print("  symplectic (fixed step set from rtol): largest error / rtol over the same scan")
    for rtol, atol in SYMPLECTIC_LADDER:
        r = worst_error(eps, rtol, atol, "symplectic")
        rows.append({**r, "method": "symplectic"})
        print(f"  {rtol:8.0e} {atol:8.0e}  {r['max_error']:14.3e}  {r['at_epsilon']:11.4g}  "
              f"{r['max_error'] / rtol:13.3f}  rtol  {r['mean_steps']:8.2f}  {r['not_ok']}")
    separatrix_table()
    return rows


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/period_error.py``."""
    from benchmarks import _cli

    p = _cli.parser("period_error", "worst Duffing period error over epsilon for a ladder of tolerances")

    def command(a) -> int:
        main()
        return 0

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
