"""mechsweep: numba-accelerated parameter sweeps for the dynamics of machine mechanisms.

Public API::

    ds = mechsweep.run("sweeps/quickstart.toml")        # or a dict with the same structure
    ds = mechsweep.run("sweeps/quickstart.toml", output=None)   # in memory, nothing written
    summary = mechsweep.compute("sweeps/quickstart.toml")       # to its file, without opening it
    ds = mechsweep.open_dataset("data/runs/quickstart.h5")
    scene = mechsweep.load_scene("sweeps/quickstart.toml")

The names are imported when first used (PEP 562): reading a dataset (``open_dataset``, ``mechsweep
plot``) does not import numba and the models' kernels.
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

_EXPORTS = {
    # the exceptions (errors.py draws their tree)
    "MechsweepError": "errors",
    "InputError": "errors",
    "SceneError": "scene",
    "StoreError": "errors",
    "FileBusy": "errors",
    "RunError": "errors",
    "OutOfSpace": "errors",
    "ClusterLost": "errors",
    "RunInterrupted": "errors",
    "MODELS": "models",
    "RunSummary": "execution.runner",
    "run": "execution.runner",
    "compute": "execution.runner",
    "Scene": "scene",
    "load_scene": "scene",
    "open_dataset": "store.read",
}

__all__ = sorted([*_EXPORTS, "__version__"])


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    if not name.startswith("_"):  # a submodule not imported yet (mechsweep.store, ...), as before
        try:
            return importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))
