"""Special functions as numba kernels (no scipy inside kernels)."""
from __future__ import annotations

import math

from ._jit import jit


@jit
def ellipk(m):
    """Complete elliptic integral of the first kind K(m), parameter m = k^2 (as scipy.special.ellipk).

    Arithmetic-geometric mean: K(m) = pi / (2 AGM(1, sqrt(1 - m))), valid for every m < 1
    including m < 0 (the soft Duffing spring). Returns inf at m = 1 and NaN for m > 1.
    Quadratic convergence: at most a few dozen iterations even for 1 - m ~ 1e-300.
    """
    if m != m or m > 1.0:
        return math.nan
    if m == 1.0:
        return math.inf
    a = 1.0
    b = math.sqrt(1.0 - m)
    for _ in range(64):
        if abs(a - b) <= 2.220446049250313e-16 * a:
            break
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return math.pi / (a + b)
