"""Range helpers shared by the built-in models: is a float held to full relative precision, and
exact power-of-two rescaling.

Double precision holds a number to full relative precision (53 bits) only between DBL_MIN =
2^-1022 ~ 2.2e-308 and DBL_MAX ~ 1.8e308: above, a product overflows to inf; below, it is
subnormal (fewer bits) or 0. A model whose inputs may span that range (e.g. mu = 1e308) either
computes in a scaled form or flags the point (status OUT_OF_RANGE, docs/physics.md "Range of the
inputs").

Scaling by a power of two (math.ldexp) is exact as long as the result is a normal number, and
IEEE rounding commutes with it: a formula homogeneous in its inputs, evaluated on inputs scaled
by powers of two and scaled back, gives the very same bits wherever neither evaluation leaves the
normal range. The scaled forms of the models rely on this: bitwise the old results in the usual
range, right results beyond it.
"""
from __future__ import annotations

import math

from .._jit import jit_noalloc

DBL_MIN = 2.2250738585072014e-308  # smallest normal double, 2^-1022
DBL_MAX = 1.7976931348623157e308


@jit_noalloc
def full_precision(x):
    """x is 0 or a finite normal number (not NaN, not inf, not subnormal)."""
    a = abs(x)
    return a == 0.0 or (DBL_MIN <= a <= DBL_MAX)


@jit_noalloc
def normal(x):
    """x is a finite normal number (nonzero, not subnormal)."""
    a = abs(x)
    return DBL_MIN <= a <= DBL_MAX


@jit_noalloc
def exponent(x):
    """e with |x| = f 2^e, 0.5 <= f < 1 (math.frexp's); 0 for 0, inf and NaN."""
    return math.frexp(x)[1]
