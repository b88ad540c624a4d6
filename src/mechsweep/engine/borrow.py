"""Arrays a kernel's inner loop uses without counting references to them.

numba counts the references to every array it hands to a function of its own (``NRT_incref`` on
entry, ``NRT_decref`` on exit, each an atomic instruction), and keeps the pair around any call that
may raise. A per-point function handed ten arrays pays twenty atomic instructions per point for
arrays that live as long as the whole loop. :func:`borrowed` gives the same array (same data, shape
and strides) without its memory owner (a NULL meminfo, as numba's ``carray`` views have): numba's
counting of it is then a test of a null pointer, which LLVM removes where it can see it.

The owner must outlive every use of the borrowed array: borrow a function's *arguments* (its caller
holds them until the call returns), never an array the same function allocates (numba frees an
array after the last use of its variable), and never return a borrowed array or keep it anywhere.
"""
from __future__ import annotations

from numba.core import cgutils, types
from numba.extending import intrinsic, overload


def _strip(context, builder, ty, value):
    if isinstance(ty, types.Array):
        ary = cgutils.create_struct_proxy(ty)(context, builder, value=value)
        ary.meminfo = cgutils.get_null_value(ary.meminfo.type)
        ary.parent = cgutils.get_null_value(ary.parent.type)
        return ary._getvalue()
    if isinstance(ty, types.BaseTuple):
        out = value
        for k, t in enumerate(ty):
            out = builder.insert_value(out, _strip(context, builder, t, builder.extract_value(value, k)), k)
        return out
    return value  # anything else as it is


@intrinsic
def _without_owner(typingctx, a):
    def codegen(context, builder, signature, args):
        return _strip(context, builder, signature.args[0], args[0])

    return a(a), codegen


def borrowed(a):
    """``a`` without the memory owner of any array in it (an array, or a tuple of arrays and other
    values, nested): see the module's docstring. In Python (a kernel's ``py_func``) it is ``a``."""
    return a


@overload(borrowed, jit_options={"nogil": True})
def _borrowed(a):
    return lambda a: _without_owner(a)
