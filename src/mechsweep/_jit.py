"""The only place where numba options are set.

Every kernel in mechsweep is decorated with :func:`jit` (serial) or :func:`pjit`
(``parallel=True``, for the chunk kernels that ``prange`` over grid points).

Options and why:
- ``fastmath=False``: results must be bitwise reproducible and IEEE-correct
  (NaN checks are part of the status logic).
- ``nogil=True``: kernels may run in worker threads (e.g. a Dask worker).
- ``cache=True`` with a cache directory keyed by a hash of the package sources:
  numba's own cache only checks the file of the decorated function, so a kernel
  that calls an integrator from another module would keep stale machine code
  after that module changed. Keying the directory on all sources makes any edit
  start a fresh cache. ``MECHSWEEP_NO_CACHE=1`` turns caching off.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numba
from numba.core import config as _numba_config

__all__ = ["jit", "pjit", "prange", "cache_dir"]

prange = numba.prange

_OPTIONS = dict(fastmath=False, nogil=True, error_model="numpy")


def _source_hash() -> str:
    root = Path(__file__).resolve().parent
    h = hashlib.sha256(numba.__version__.encode())
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _make_cache_dir() -> str | None:
    if os.environ.get("MECHSWEEP_NO_CACHE", "") not in ("", "0"):
        return None
    base = os.environ.get("MECHSWEEP_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache"), "mechsweep"
    )
    path = os.path.join(base, "numba-" + _source_hash())
    try:
        os.makedirs(path, exist_ok=True)
        probe = os.path.join(path, ".write-test")
        with open(probe, "w"):
            pass
        os.remove(probe)
    except OSError:
        return None  # read-only home: compile every time rather than fail
    return path


cache_dir = _make_cache_dir()


def _decorate(func, **extra):
    if cache_dir is None:
        return numba.njit(**_OPTIONS, **extra)(func)
    # numba reads config.CACHE_DIR when the dispatcher is created; set it only
    # for our own functions so the user's numba code keeps its own cache.
    previous = _numba_config.CACHE_DIR
    _numba_config.CACHE_DIR = cache_dir
    try:
        return numba.njit(cache=True, **_OPTIONS, **extra)(func)
    finally:
        _numba_config.CACHE_DIR = previous


def jit(func):
    """Compile a serial kernel (no parallel loops)."""
    return _decorate(func)


def pjit(func):
    """Compile a chunk kernel whose outer loop is a ``prange`` over points."""
    return _decorate(func, parallel=True)
