"""The models mechsweep knows, by name (an explicit table: no registration by import side effect)."""
from __future__ import annotations

from . import autobalancer, duffing, fourbar_balancing, slidercrank_balancing, torsional_circuit
from ..model.spec import ModelSpec, Output, Param

MODELS: dict[str, ModelSpec] = {
    duffing.SPEC.name: duffing.SPEC,
    torsional_circuit.SPEC.name: torsional_circuit.SPEC,
    autobalancer.SPEC.name: autobalancer.SPEC,
    fourbar_balancing.SPEC.name: fourbar_balancing.SPEC,
    slidercrank_balancing.SPEC.name: slidercrank_balancing.SPEC,
}

__all__ = ["MODELS", "ModelSpec", "Output", "Param"]
