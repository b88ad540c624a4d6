"""Special functions as numba kernels (no scipy inside kernels)."""
from __future__ import annotations

import math

import numpy as np

from llvmlite import ir as llvm_ir
from numba.core import types
from numba.extending import intrinsic

from ._jit import jit, jit_inline


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


# sincos: both functions of one argument for about the price of one libm call. The right-hand
# side of the autobalancer needs sin and cos of three angles per evaluation; with libm that is
# six calls, half the cost of an evaluation. Same algorithm as fdlibm/musl (__rem_pio2 medium
# case, __sin, __cos): Cody-Waite reduction by pi/2 in three parts, then the minimax kernels on
# [-pi/4, pi/4]. Accuracy is tested against libm (tests/test_special.py).
_TOINT = 6755399441055744.0  # 1.5 / eps: adding and subtracting rounds to an integer
_INVPIO2 = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e+00  # first 33 bits of pi/2
_PIO2_2 = 6.07710050630396597660e-11  # next 33 bits
_PIO2_2T = 2.02226624879595063154e-21  # pi/2 - (PIO2_1 + PIO2_2)
SINCOS_MAX = 1.0e6  # beyond this (and for inf/NaN) fall back to libm

_S1 = -1.66666666666666324348e-01
_S2 = 8.33333333332248946124e-03
_S3 = -1.98412698298579493134e-04
_S4 = 2.75573137070700676789e-06
_S5 = -2.50507602534068634195e-08
_S6 = 1.58969099521155010221e-10
_C1 = 4.16666666666666019037e-02
_C2 = -1.38888888888741095749e-03
_C3 = 2.48015872894767294178e-05
_C4 = -2.75573143513906633035e-07
_C5 = 2.08757232129817482790e-09
_C6 = -1.13596475577881948265e-11


@jit_inline
def sincos(x):
    """(sin x, cos x), each within about one ulp of libm (measured), for |x| <= 1e6;
    larger, infinite or NaN arguments go to libm."""
    if not abs(x) <= SINCOS_MAX:
        return math.sin(x), math.cos(x)
    return sincos_reduced(x)


@jit_inline
def sincos_reduced(x):
    """sincos for finite |x| <= 1e6 (SINCOS_MAX) only, without the libm fallback: no branch and
    no call, so that numba/LLVM can vectorise a loop that calls it (several trajectories side by
    side). The quadrant is selected by float comparisons, which LLVM turns into selects."""
    fn = (x * _INVPIO2 + _TOINT) - _TOINT  # nearest integer to x / (pi/2)
    r = x - fn * _PIO2_1  # exact: fn has at most 21 bits, PIO2_1 33
    w = fn * _PIO2_2
    t = r
    r = t - w
    w = fn * _PIO2_2T - ((t - r) - w)
    y0 = r - w  # reduced argument y0 + y1, |y0| <= pi/4 (a little more at round-off)
    y1 = (r - y0) - w
    z = y0 * y0
    zz = z * z
    # __sin(y0, y1)
    rs = _S2 + z * (_S3 + z * _S4) + z * zz * (_S5 + z * _S6)
    v = z * y0
    s = y0 - ((z * (0.5 * y1 - v * rs) - y1) - v * _S1)
    # __cos(y0, y1)
    rc = z * (_C1 + z * (_C2 + z * _C3)) + zz * zz * (_C4 + z * (_C5 + z * _C6))
    hz = 0.5 * z
    w = 1.0 - hz
    c = w + (((1.0 - w) - hz) + (z * rc - y0 * y1))
    q = fn - 4.0 * np.floor(fn * 0.25)  # quadrant 0..3, exact; np.floor stays a float (math.floor
    # is an int in numba, and AVX2 has no vector conversion to int64)
    odd = (q == 1.0) | (q == 3.0)
    a = c if odd else s
    b = s if odd else c
    return (a if q < 2.0 else -a), (b if (q == 0.0) | (q == 3.0) else -b)


@intrinsic
def _llvm_sqrt(typingctx, x):
    if x != types.float64:
        return None
    sig = types.float64(types.float64)

    def codegen(context, builder, signature, args):
        fn = builder.module.declare_intrinsic("llvm.sqrt", [llvm_ir.DoubleType()])
        return builder.call(fn, args)

    return sig, codegen


@jit_inline
def ieee_sqrt(x):
    """Correctly rounded sqrt of a float64 as LLVM's sqrt intrinsic (NaN below zero, as libm).

    numba's math.sqrt calls libm's sqrt behind a branch that sets errno for negative
    arguments; the call keeps LLVM from vectorising a loop around it. Same values. (A jitted
    function around the intrinsic, so that Python callers such as py_func tests can call it.)"""
    return _llvm_sqrt(float(x))
