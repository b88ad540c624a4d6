"""Scene files: TOML (or an equivalent dict) -> a validated, frozen :class:`Scene`.

Validation happens once, when the scene is loaded (:func:`load_scene`). Every problem is reported
with its key path, the bad value and what is allowed; all problems of a scene are reported
together. The package's parts: :mod:`.spec` (what a scene is), :mod:`.load` (reading it),
:mod:`.sections` (each section checked), :mod:`.text` (text a dataset can store).
"""
from __future__ import annotations

from .load import MAX_SCENE_BYTES, SCENE_TOO_BIG_ADVICE, load_scene, load_scene_text, read_scene_file, to_toml
from .sections import (SCHEDULER_FORMS, WORKER_TIMEOUT_RANGE, atol_problem, check_scheduler, check_worker_timeout,
                       solver_warnings, validate)
from .spec import (ADAPTIVE_METHODS, ATOL_FLOOR, ATOL_WARN, BOUNDARY_KEYS, BOUNDARY_RTOL, LANES_CHOICES, MAX_AXIS_POINTS,
                   MAX_POINTS, RADAU_MIN_RTOL, SECTIONS, SOLVER_LIMITS, Axis, Boundaries, Execution, Scene, SceneError,
                   Solver, Storage)
from .text import unstorable, unstorable_name

__all__ = ["ADAPTIVE_METHODS", "ATOL_FLOOR", "ATOL_WARN", "BOUNDARY_KEYS", "BOUNDARY_RTOL", "LANES_CHOICES",
           "MAX_AXIS_POINTS", "MAX_POINTS", "MAX_SCENE_BYTES", "RADAU_MIN_RTOL", "SCENE_TOO_BIG_ADVICE",
           "SCHEDULER_FORMS", "SECTIONS", "SOLVER_LIMITS", "WORKER_TIMEOUT_RANGE", "Axis", "Boundaries", "Execution",
           "Scene", "SceneError", "Solver", "Storage", "atol_problem", "check_scheduler", "check_worker_timeout",
           "load_scene", "load_scene_text", "read_scene_file", "solver_warnings", "to_toml", "unstorable",
           "unstorable_name", "validate"]
