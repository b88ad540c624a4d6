"""Cost of the measurements of a user model with one shared trajectory per point versus one
integration per measurement (the first stage's kernel), on tests/user_models/oscillators.py LINEAR
(7 measurements). Prints times, steps and rhs calls; asserts nothing about time.

    python benchmarks/model_shared.py [path/to/oscillators.py] [n_points]
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

OSCILLATORS = Path(__file__).resolve().parents[1] / "tests" / "user_models" / "oscillators.py"


def main(path: str | Path = OSCILLATORS, n: int = 20000) -> None:
    from mechsweep import status as st
    from mechsweep.model import load
    from mechsweep.model.compile import kernel_for

    path = str(Path(path).resolve())
    model = load.import_module(load.module_name(Path(path)), path).LINEAR
    chosen = model.measurements
    P = np.column_stack([np.linspace(0.5, 10.0, n), np.full(n, 0.7)])
    rtol, atol, max_steps = 1e-10, 1e-12, 100_000
    results = {}
    for shared in (False, True):
        t0 = time.perf_counter()
        kernel = kernel_for(model, chosen, shared=shared)
        S, need = np.zeros(0), np.zeros(0, dtype=bool)  # no settings, no closed forms
        table = np.full((2, len(chosen)), np.nan)
        kernel(P[:2].copy(), S, need, rtol, atol, max_steps, table, np.zeros(2, st.DTYPE), np.zeros(2, np.int64),
               np.zeros(2, np.int64))
        t_compile = time.perf_counter() - t0
        best = np.inf
        for _ in range(3):
            table = np.full((n, len(chosen)), np.nan)
            status, ns, nr = np.zeros(n, st.DTYPE), np.zeros(n, np.int64), np.zeros(n, np.int64)
            t0 = time.perf_counter()
            kernel(P, S, need, rtol, atol, max_steps, table, status, ns, nr)
            best = min(best, time.perf_counter() - t0)
        results[shared] = table
        print(f"{'shared  ' if shared else 'separate'}: compile+first call {t_compile:6.1f} s, {n} points in "
              f"{best:.3f} s ({1e6 * best / n:.1f} us/point), steps/point {ns.mean():.1f}, rhs/point {nr.mean():.1f}")
    a, b = results[False], results[True]
    both = np.isfinite(a) & np.isfinite(b)
    assert (np.isfinite(a) == np.isfinite(b)).all()
    rel = np.abs(a - b)[both] / np.maximum(np.abs(a[both]), 1.0)
    print(f"largest difference shared vs separate: {rel.max():.2e} (relative, absolute below 1); "
          f"per output: " + ", ".join(f"{m.name} {np.nanmax(np.abs(a[:, j] - b[:, j])):.1e}" for j, m in enumerate(chosen)))


def cli(argv: list[str] | None = None) -> int:
    """``python benchmarks/model_shared.py [path/to/oscillators.py] [n_points]``."""
    if __package__ in (None, ""):  # run as a script: import from the repository's root, as -m does
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks import _cli

    p = _cli.parser("model_shared", __doc__)
    p.add_argument("path", nargs="?", default=str(OSCILLATORS), help="the model file (default: the tests' oscillators.py)")
    p.add_argument("n", nargs="?", type=int, default=20000, help="grid points (default 20000)")

    def command(a) -> int:
        main(a.path, a.n)
        return 0

    return _cli.run(p, command, argv)


if __name__ == "__main__":
    sys.exit(cli())
