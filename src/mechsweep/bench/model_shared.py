"""Cost of the measurements of a user model with one shared trajectory per point versus one
integration per measurement (the first stage's kernel), on tests/user_models/oscillators.py LINEAR
(7 measurements). Prints times, steps and rhs calls; asserts nothing about time.

    python -m mechsweep.bench.model_shared [path/to/oscillators.py] [n_points]
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np


def main(argv=None) -> None:
    from mechsweep import status as st
    from mechsweep.model import load
    from mechsweep.model.compile import kernel_for

    argv = list(sys.argv[1:] if argv is None else argv)
    path = argv[0] if argv else str(Path(__file__).resolve().parents[3] / "tests" / "user_models" / "oscillators.py")
    n = int(argv[1]) if len(argv) > 1 else 20000
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


if __name__ == "__main__":
    main()
