"""The numba option layer: what the decorators promise."""
import numba
import numpy as np
import pytest

from mechsweep._jit import jit_inline, jit_noalloc


def test_noalloc_refuses_a_function_that_allocates():
    """jit_noalloc compiles without reference counting; an allocation must fail to compile
    rather than leak or crash at run time."""
    def allocating(n):
        return np.zeros(n).sum()

    with pytest.raises(numba.core.errors.TypingError):
        jit_noalloc(allocating)(3)


def test_noalloc_and_inline_functions_work_on_caller_arrays():
    def scaled_sum(v, a):
        acc = 0.0
        for i in range(v.size):
            acc += a * v[i]
        return acc

    f = jit_noalloc(scaled_sum)
    g = jit_inline(scaled_sum)
    v = np.arange(5.0)
    assert f(v, 2.0) == g(v, 2.0) == 20.0
    assert f(v[::2], 1.0) == 6.0  # views of caller arrays are fine
