"""The kernel of a ClosedFormModel (model/closed.py): the model's ``compute`` per design.

    kernel(P, want, slot, table, curves, status, data, first, step)
        scratch (nscr x n) per thread                      (the blocks of BLOCK designs first,
        for i in the blocks first, first + step, ...:       first + step, ...: point.Threaded runs
            code = compute(P[i], want, table[i], curves[i],  one such stride per thread)
                           slot, scratch, *data)
            non-OK: that status, the design's row and curves NaN

An exception the user's compute raises at a design the load-time probe did not see must not escape
the kernel's threads: that design ends USER_ERROR, NaN (mechsweep's own computes never raise: no guard).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .. import status as st
from .._jit import jit_internal, jit_internal_noalloc, jit_into_caller
from .borrow import borrowed

BLOCK = 64  # consecutive designs of one thread (their rows of table and curves side by side in memory)
ARGS = "P, want, slot, table, curves, status, data, first, step"


@functools.cache
def _call(compute):
    """``call(p, want, row, crv, slot, scratch, data)``: ``compute`` with the data tuple spread. Without
    reference counting where ``compute`` has none (its author's jit_noalloc, model/load.jitted): its ten
    arrays come borrowed (``_designs``), and then not even the null tests of their counting are left; a
    ``compute`` that may allocate keeps numba's runtime, which its callers must have."""
    noalloc = getattr(compute, "targetoptions", {}).get("_nrt") is False
    decorate = jit_internal_noalloc if noalloc else jit_internal

    @decorate
    def call(p, want, row, crv, slot, scratch, data):
        return compute(p, want, row, crv, slot, scratch, *data)

    return call


@functools.cache
def _guarded(call):
    @jit_internal
    def compute(p, want, row, crv, slot, scratch, data):
        try:
            return call(p, want, row, crv, slot, scratch, data)
        except Exception:  # evaluate replays the design in plain Python to say why (model/diagnose.py)
            return st.USER_ERROR

    return compute


def build(compute, n_scr: int, guarded: bool):
    """The entry point ``kernel`` of a ClosedFormModel whose jitted ``compute`` needs ``n_scr`` scratch
    rows; ``guarded``: a user's function (an exception ends the design USER_ERROR)."""
    from . import binding

    call = _call(compute)
    return binding.Entries(kernel=_kernel(_guarded(call) if guarded else call, n_scr))


@functools.cache
def _kernel(compute, n_scr):
    designs = _designs(compute)

    @jit_into_caller  # compiled into the binding's cached trampoline (no link of its own)
    def kernel(P, want, slot, table, curves, status, data, first, step):
        # the blocks of designs first, first + step, ...; point.Threaded runs one such stride per thread
        # (nogil), without numba's parallel compile
        N = curves.shape[2]
        designs(P, want, slot, table, curves, status, data, first, step, np.empty((n_scr, N)), np.empty((0, N)))

    return kernel


@functools.cache
def _designs(compute):
    @jit_internal
    def designs(P, want, slot, table, curves, status, data, first, step, scratch, dummy):
        # compute takes the arrays borrowed (engine/borrow.py): the caller holds them for this call, and
        # numba then counts no reference at every design
        P, want, slot, table, curves, status, data = borrowed((P, want, slot, table, curves, status, data))
        scratch, dummy = borrowed((scratch, dummy))
        n = P.shape[0]
        use_curves = curves.shape[0] == n
        for b in range(first * BLOCK, n, step * BLOCK):
            for i in range(b, min(n, b + BLOCK)):
                crv = curves[i] if use_curves else dummy
                code = compute(P[i], want, table[i], crv, slot, scratch, data)
                if code != st.OK:
                    status[i] = code
                    table[i, :] = math.nan
                    if use_curves:
                        crv[:, :] = math.nan

    return designs
