"""Compile-time switches for the reference kernels (tests/reference/autobalancer_kernels.py): one
cached kernel per method, resolved from a literal integer. The engine composes its kernels from
closures instead (mechsweep/engine/) and needs none of this."""
from numba import literally

from mechsweep._jit import _describe

__all__ = ["call_with_literal", "compile_time_switch", "literally"]


def compile_time_switch(name: str, cases: dict):
    """A numba-callable ``switch(code, *args) -> cases[code](*args)`` resolved at compile time.

    ``code`` must be a literal integer in the caller (a kernel makes its ``method`` argument
    one with ``literally(method)``); only the chosen case is compiled, and the kernel is cached
    per code. Used for solver.method: compiling every integrator into every kernel would cost a cold
    Duffing sweep several times the compile time of one method; the usual alternatives do not cache
    (a dispatcher passed as an argument, or a closure called from Python).
    """
    from numba.core import types
    from numba.extending import overload

    def switch(code, *args):
        raise NotImplementedError(f"{name} is only callable from numba code")

    switch.__name__ = switch.__qualname__ = name

    @overload(switch, prefer_literal=True)
    def _switch(code, *args):
        if not isinstance(code, types.IntegerLiteral):
            return None  # numba retries with the literal value
        case = cases[code.literal_value]

        def impl(code, *args):
            return case(*args)
        # one name per switch and case (see _distinct_qualname): the impls of different
        # switches with the same argument types must not share a symbol
        impl.__qualname__ = f"{name}__case{code.literal_value}__{_describe(case)}".replace(".", "_").replace("<", "").replace(">", "")
        return impl

    return switch


def call_with_literal(kernel, code: int, *args):
    """``kernel(code, *args)`` for a kernel that makes ``code`` literal with ``literally``.

    numba's dispatcher types a Python int as int64, attempts that signature, meets
    ``literally`` and only then retries with the literal: on every call, more than a short chunk's
    own work. The compiled literal overload is called directly when it exists.
    """
    from numba import typeof
    from numba.core import types

    signature = (types.literal(code),) + tuple(typeof(a) for a in args)
    compiled = kernel.overloads.get(signature)
    if compiled is None:
        return kernel(code, *args)  # compiles, or loads from the disk cache, once
    return compiled.entry_point(code, *args)
