"""Stability (and other) boundaries of a scene's grid, for any model: where a criterion crosses a
level, or the status changes, located along one axis for every combination of the others
(:mod:`.search`), followed in two parameters (:mod:`.continuation`), and a scene's boundaries from
its grid's dataset to their own dataset (:mod:`.dataset`, the command `mechsweep boundaries`).
See docs/boundaries.md.
"""
from __future__ import annotations

from .continuation import CURVE_STOPS, FOLD_TOL, Curve, continue_boundary
from .dataset import (accuracy_warning, base_rows, criterion_of, locate_dataset, run_boundaries, sibling_path,
                      status_warning, warnings_for, write_atomic)
from .search import (ABS_FLOOR, BAND_EDGE, BOUND_DESCRIPTIONS, BOUND_MEANINGS, BUDGET, CRITERION, INTERRUPTED,
                     MAX_EVALUATIONS, PARAMETER, STALL_ROUNDS, Criterion, Located, accuracy_text, criterion_accuracy,
                     from_integration, kind_of_angle, locate)

__all__ = ["ABS_FLOOR", "BAND_EDGE", "BOUND_DESCRIPTIONS", "BOUND_MEANINGS", "BUDGET", "CRITERION", "CURVE_STOPS",
           "FOLD_TOL", "INTERRUPTED", "MAX_EVALUATIONS", "PARAMETER", "STALL_ROUNDS", "Criterion", "Curve", "Located",
           "accuracy_text", "accuracy_warning", "base_rows", "continue_boundary", "criterion_accuracy",
           "criterion_of", "from_integration", "kind_of_angle", "locate", "locate_dataset", "run_boundaries",
           "sibling_path", "status_warning", "warnings_for", "write_atomic"]
