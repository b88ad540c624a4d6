"""Small helpers shared by the integrators (none depends on a right-hand side)."""
from __future__ import annotations

import functools
import math

import numpy as np

from .._jit import jit_internal_noalloc, jit_llvm_inline


@jit_llvm_inline
def _all_finite(v):
    for i in range(v.size):
        if not math.isfinite(v[i]):
            return False
    return True


@jit_llvm_inline
def _copy(src, dst):
    for i in range(src.size):
        dst[i] = src[i]


@jit_llvm_inline
def _rms_scaled(v, y, rtol, atol):
    """RMS of v / (atol + rtol |y|), the norm of select_initial_step."""
    acc = 0.0
    for i in range(v.size):
        acc += (v[i] / (atol + abs(y[i]) * rtol)) ** 2
    return math.sqrt(acc / v.size)


@jit_llvm_inline
def _rms_scaled_difference(a, b, y, rtol, atol):
    acc = 0.0
    for i in range(a.size):
        acc += ((a[i] - b[i]) / (atol + abs(y[i]) * rtol)) ** 2
    return math.sqrt(acc / a.size)


@jit_llvm_inline
def _min_step(t):
    """Smallest step that still changes t meaningfully (scipy: 10 ulp of t)."""
    return 10.0 * abs(np.nextafter(t, np.inf) - t)


# Root finding on an interpolant: Brent's method, relative tolerance as in scipy.optimize.brentq;
# 100 iterations are far more than it ever needs.
ROOT_RTOL = 4.0 * np.finfo(np.float64).eps
ROOT_MAX_ITER = 100


@functools.cache
def make_brent(g):
    """Jitted ``brent(t_old, g_old, t_new, g_new, x_tol, ctx) -> t``: a root of ``g(t, ctx)`` in
    [t_old, t_new] where g_old > 0 >= g_new (g_old, g_new its values at the ends; x_tol an
    absolute floor of the tolerance, e.g. ROOT_RTOL |h|). Brent's method as scipy.optimize.brentq
    (bracketing, so bounded and robust), to a few ulp of t. ``ctx`` is whatever g needs (a tuple).
    """
    @jit_internal_noalloc
    def brent(t_old, g_old, t_new, g_new, x_tol, ctx):
        if g_new == 0.0:
            return t_new
        x_pre, f_pre = t_old, g_old
        x_cur, f_cur = t_new, g_new
        x_blk, f_blk = 0.0, 0.0
        s_pre, s_cur = 0.0, 0.0
        for _ in range(ROOT_MAX_ITER):
            if f_pre != 0.0 and f_cur != 0.0 and (f_pre < 0.0) != (f_cur < 0.0):
                x_blk, f_blk = x_pre, f_pre
                s_pre = s_cur = x_cur - x_pre
            if abs(f_blk) < abs(f_cur):  # keep the best estimate in x_cur
                x_pre, x_cur, x_blk = x_cur, x_blk, x_cur
                f_pre, f_cur, f_blk = f_cur, f_blk, f_cur
            delta = 0.5 * (x_tol + ROOT_RTOL * abs(x_cur))
            s_bis = 0.5 * (x_blk - x_cur)
            if f_cur == 0.0 or abs(s_bis) < delta:
                return x_cur
            if abs(s_pre) > delta and abs(f_cur) < abs(f_pre):
                if x_pre == x_blk:  # secant
                    s_try = -f_cur * (x_cur - x_pre) / (f_cur - f_pre)
                else:  # inverse quadratic interpolation
                    d_pre = (f_pre - f_cur) / (x_pre - x_cur)
                    d_blk = (f_blk - f_cur) / (x_blk - x_cur)
                    s_try = -f_cur * (f_blk * d_blk - f_pre * d_pre) / (d_blk * d_pre * (f_blk - f_pre))
                if 2.0 * abs(s_try) < min(abs(s_pre), 3.0 * abs(s_bis) - delta):
                    s_pre, s_cur = s_cur, s_try
                else:
                    s_pre = s_cur = s_bis
            else:
                s_pre = s_cur = s_bis
            x_pre, f_pre = x_cur, f_cur
            if abs(s_cur) > delta:
                x_cur += s_cur
            else:
                x_cur += delta if s_bis > 0.0 else -delta
            f_cur = g(x_cur, ctx)
        return x_cur

    return brent
