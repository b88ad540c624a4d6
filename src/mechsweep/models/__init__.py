"""The models mechsweep knows, by name: an explicit table of the modules that declare them (no
registration by import side effect). A built-in model's module is imported when the model is first
looked up (``MODELS[name]``), so that the table itself imports none of them: the generic layer
(scene validation, the model loader) can name it without importing the built-ins, which import it."""
from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping, MutableMapping

from ..model.spec import ModelSpec, Output, Param

# name -> the module whose SPEC declares it, in the order `mechsweep models` lists them
BUILT_IN: dict[str, str] = {
    "duffing": "mechsweep.models.duffing",
    "torsional_circuit": "mechsweep.models.torsional_circuit",
    "autobalancer": "mechsweep.models.autobalancer",
    "fourbar_balancing": "mechsweep.models.fourbar_balancing",
    "slidercrank_balancing": "mechsweep.models.slidercrank_balancing",
}


class Registry(MutableMapping):
    """The built-in models, name -> ModelSpec: a model's module is imported at its first lookup. An
    entry may also be set to a ModelSpec directly (as a dict's: tests put a model of their own in)."""

    def __init__(self, modules: Mapping[str, str]):
        self._entries: dict[str, str | ModelSpec] = dict(modules)  # a module's name until looked up

    def __getitem__(self, name: str) -> ModelSpec:
        entry = self._entries[name]
        if isinstance(entry, str):
            entry = self._entries[name] = importlib.import_module(entry).SPEC
        return entry

    def __setitem__(self, name: str, spec: ModelSpec) -> None:
        self._entries[name] = spec

    def __delitem__(self, name: str) -> None:
        del self._entries[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, name) -> bool:  # names only: no module imported
        return name in self._entries

    def __repr__(self) -> str:
        return f"Registry({', '.join(self._entries)})"


MODELS: MutableMapping[str, ModelSpec] = Registry(BUILT_IN)

__all__ = ["BUILT_IN", "MODELS", "ModelSpec", "Output", "Param", "Registry"]
