"""The declarative model layer: declare an ODE model and what to measure, or a closed-form model
and its per-design function; the engine writes the chunk kernel. See docs/model-layer.md.

The names are imported when first used (PEP 562): ``import mechsweep.model.spec`` (the
declarations' dataclasses) imports neither numba nor the engine."""
from __future__ import annotations

import importlib

_EXPORTS = {
    "OdeModel": "ode", "Invariant": "ode",
    "ClosedFormModel": "closed",
    "Param": "spec", "Setting": "spec", "Output": "spec", "ExtraDim": "spec",
    "Crossing": "measure", "Period": "measure", "StateAt": "measure", "Extremum": "measure",
    "Floquet": "measure", "FirstEvent": "measure", "ClosedForm": "measure", "System": "measure",
    "Steady": "measure", "Kick": "measure", "History": "measure", "Recheck": "measure",
    "WorkPrecision": "workprecision", "SizeWorkPrecision": "workprecision",
}

__all__ = ["OdeModel", "ClosedFormModel", "Param", "Setting", "Output", "ExtraDim", "Crossing", "Period", "StateAt",
           "Extremum", "Floquet", "FirstEvent", "ClosedForm", "System", "Invariant", "Steady", "Kick", "History", "Recheck",
           "WorkPrecision", "SizeWorkPrecision"]


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    if not name.startswith("_"):  # a submodule not imported yet (mechsweep.model.load, ...), as before
        try:
            return importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))
