"""engine/borrow.py: a borrowed array is the same memory, shape and strides as its owner, and numba
counts no reference to it (its meminfo is NULL)."""
from __future__ import annotations

import numpy as np
from numba import njit
from numba.core import cgutils, types
from numba.extending import intrinsic

from mechsweep.engine.borrow import borrowed


@intrinsic
def _has_owner(typingctx, a):
    """Whether the array ``a`` has a memory owner (a meminfo)."""
    def codegen(context, builder, signature, args):
        ary = cgutils.create_struct_proxy(signature.args[0])(context, builder, value=args[0])
        return cgutils.is_not_null(builder, ary.meminfo)

    return types.boolean(a), codegen


@njit
def _write_through(a, m):
    b = borrowed(a)
    v = b[1:, ::2]  # a view of a borrowed array: no owner either
    v[0, 1] = 7.0
    return _has_owner(a), _has_owner(b), _has_owner(v), b.shape, b.strides == a.strides, b.sum()


@njit
def _nested(t):
    u = borrowed(t)
    u[0][0] = 1.5
    u[1][1][0] = 2
    return _has_owner(t[0]), _has_owner(u[0]), _has_owner(u[1][1]), u[1][0], u[2]


def test_a_borrowed_array_is_its_owners_memory_without_an_owner():
    a = np.zeros((3, 4))
    owned, b_owned, v_owned, shape, same_strides, total = _write_through(a, 0)
    assert owned and not b_owned and not v_owned
    assert shape == (3, 4) and same_strides and total == 7.0 and a[1, 2] == 7.0


def test_a_tuple_is_borrowed_member_by_member_and_other_values_pass_unchanged():
    x, k = np.zeros(2), np.zeros(3, dtype=np.int64)
    owned, x_owned, k_owned, scalar, last = _nested((x, (3.0, k), 5))
    assert owned and not x_owned and not k_owned and scalar == 3.0 and last == 5
    assert x[0] == 1.5 and k[0] == 2


def test_in_python_a_borrowed_array_is_the_array():
    a, t = np.zeros(3), (np.zeros(2), 4)
    assert borrowed(a) is a and borrowed(t) is t
