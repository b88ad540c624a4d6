"""Checks of benchmark arguments, shared by the command line and the Python functions: a bad
value is an InputError (exit 2 on the command line) naming the option and what is allowed."""
from __future__ import annotations

import math
import numbers
from pathlib import Path

from ..errors import InputError

MAX_POINTS = 10**8  # beyond this a benchmark's arrays alone outgrow a workstation's memory


def _show(value) -> str:
    return str(value) if isinstance(value, numbers.Number) and not isinstance(value, bool) else repr(value)


def count(name: str, value, lo: int = 1, hi: int = MAX_POINTS) -> int:
    """A whole number in [lo, hi] (numpy integers accepted)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not lo <= value <= hi:
        raise InputError(f"{name} = {_show(value)} is not allowed; expected a whole number in [{lo}, {hi}]")
    return int(value)


def threads(name: str, value) -> int | None:
    """None (all cores) or a thread count this machine has."""
    import numba

    if value is None:
        return None
    return count(name, value, 1, numba.config.NUMBA_NUM_THREADS)


def tolerance(name: str, value, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)) \
            or not lo <= float(value) <= hi:
        raise InputError(f"{name} = {_show(value)} is not allowed; expected a number in [{lo:g}, {hi:g}]")
    return float(value)


def sequence(value) -> tuple:
    """A ladder given as one value or as a sequence of them."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        return (value,)
    return tuple(value)


def folder(name: str, value) -> Path:
    """An output folder: absent (it is created) or a folder, not a file."""
    path = Path(value)
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                raise InputError(f"{name} = {str(value)!r}: {p} is a file, not a folder")
            break
    return path

