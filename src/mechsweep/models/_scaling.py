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
normal range. The scaled forms of the models rely on this: bitwise the plain formulas' results in
the usual range, right results beyond it.
"""
from __future__ import annotations

import math

import numpy as np

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
def product_in_range(x, y):
    """x * y is a normal number, or an exact 0 from a zero factor (not an underflow)."""
    return x == 0.0 or y == 0.0 or normal(x * y)


@jit_noalloc
def quotient_in_range(x, y):
    """x / y is a normal number, or an exact 0 from x = 0 (not an underflow)."""
    return x == 0.0 or normal(x / y)


@jit_noalloc
def times_pow2(x, e):
    """x 2^e (math.ldexp), without the library call for e = 0 (the usual range)."""
    return x if e == 0 else math.ldexp(x, e)


@jit_noalloc
def exponent(x):
    """e with |x| = f 2^e, 0.5 <= f < 1 (math.frexp's); 0 for 0, inf and NaN."""
    return math.frexp(x)[1]


# ----------------------------------------------------------------------------- closed-form models in SI units
# A mechanism's loads are products of masses, lengths and rates of up to about a dozen factors (an RMS
# squares them, the 2x2 normal equations of a moved counterweight axis multiply four such squares):
# at 1e30 kg or 1e-20 m they leave double precision's range although every output is representable.
# UnitScaling evaluates each design in units of its own mass, length and time (powers of two chosen per
# design: the largest of each kind becomes O(1)) and scales the outputs back by their units; a design
# whose lengths or masses spread over more than SPREAD (2^300) from the largest of their kind is
# OUT_OF_RANGE. Exact: the same bits as the unscaled evaluation wherever that stays in the normal range.
_BASE_UNITS = {"kg": (1, 0, 0), "m": (0, 1, 0), "s": (0, 0, 1), "N": (1, 1, -2), "rad": (0, 0, 0), "1": (0, 0, 0),
               "%": (0, 0, 0)}
SPREAD = 300  # log2 of the spread of lengths or masses within a design beyond which it is OUT_OF_RANGE


def unit_powers(unit: str) -> tuple[int, int, int]:
    """(kg, m, s) powers of a unit string of the built-in closed-form models ("N m", "kg m2", "m s-2",
    "rad s-1", "1", "%"); ValueError for anything else (a new unit must be taught here)."""
    total = [0, 0, 0]
    for token in unit.split():
        name = token if token in _BASE_UNITS else token.rstrip("-0123456789")
        power = int(token[len(name):] or 1)
        if name not in _BASE_UNITS:
            raise ValueError(f"unit {unit!r}: {token!r} is not one of {sorted(_BASE_UNITS)}")
        for k in range(3):
            total[k] += _BASE_UNITS[name][k] * power
    return tuple(total)


def log2_floor(x):
    """frexp exponent of |x| (ints; 0 where x is 0 or not finite): |x| in [2^(e-1), 2^e)."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(np.isfinite(x) & (x != 0.0), np.frexp(x)[1], 0).astype(np.int64)


NONE = -10**6  # largest_exponent where no column has a nonzero finite entry


def largest_exponent(*columns):
    """Per row the largest frexp exponent over the nonzero finite entries of the columns, each given
    as an array or as (array, shift) for the exponent minus shift (an int or an int array); NONE
    where there is none."""
    best = None
    for col in columns:
        col, shift = col if isinstance(col, tuple) else (col, 0)
        col = np.asarray(col, dtype=np.float64)
        if best is None:
            best = np.full(col.shape[0], NONE, dtype=np.int64)
        has = np.isfinite(col) & (col != 0.0)
        best = np.where(has, np.maximum(best, log2_floor(col) - shift), best)
    return best


class UnitScaling:
    """Per-design units of mass (2^a kg), length (2^c m) and time (2^t s) for a closed-form model whose
    parameters and outputs carry SI units (unit_powers).

    ``choose(P) -> (a, c, t)`` int arrays (one per design); ``spread``: the names of the parameters
    that multiply (lengths, masses, inertias) and must lie within 2^+-SPREAD of 1 in those units
    (0 and NaN, an absent optional parameter, pass); ``wrap(evaluate)`` the model's evaluate in them."""

    def __init__(self, params, outputs, choose, spread):
        self.names = [p.name for p in params]
        self.powers = np.array([(0, 0, 0) if p.categorical else unit_powers(p.unit) for p in params], dtype=np.int64)
        self.out_powers = {o.name: np.array(unit_powers(o.unit), dtype=np.int64) for o in outputs}
        self.choose = choose
        self.spread = [self.names.index(n) for n in spread]

    def scaled(self, P):
        """(P in the designs' units, exponents (n, 3), rows beyond the spread)."""
        P = np.asarray(P, dtype=np.float64)
        k = np.stack(self.choose(P), axis=1).astype(np.int64)
        Ps = np.ldexp(P, -(k @ self.powers.T))
        cols = np.abs(Ps[:, self.spread])
        beyond = ((cols != 0.0) & np.isfinite(cols) & ((cols < 2.0 ** -SPREAD) | (cols > 2.0 ** SPREAD))).any(axis=1)
        return Ps, k, beyond

    def wrap(self, evaluate):
        from .. import status as st

        def scaled_evaluate(P, wanted, solver, out, status, n_steps=None, n_rhs=None, size=None):
            Ps, k, beyond = self.scaled(P)
            if size is None:
                evaluate(Ps, wanted, solver, out, status, n_steps, n_rhs)
            else:
                evaluate(Ps, wanted, solver, out, status, n_steps, n_rhs, size)
            flag = beyond & (status == st.OK)
            status[flag] = st.OUT_OF_RANGE
            for name in wanted:
                values = out[name]
                e = (k @ self.out_powers[name]).reshape((-1,) + (1,) * (values.ndim - 1))
                values[...] = np.ldexp(values, e)
                values[flag] = np.nan

        scaled_evaluate.__doc__ = evaluate.__doc__
        return scaled_evaluate
