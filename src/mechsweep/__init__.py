"""mechsweep: numba-accelerated parameter sweeps for the dynamics of machine mechanisms.

Public API::

    ds = mechsweep.run("sweeps/quickstart.toml")        # or a dict with the same structure
    ds = mechsweep.open_dataset("data/runs/quickstart.h5")
    scene = mechsweep.load_scene("sweeps/quickstart.toml")
"""
from __future__ import annotations

__version__ = "0.1.0"

from .errors import ClusterLost  # noqa: E402
from .models import MODELS  # noqa: E402
from .runner import OutOfSpace, RunInterrupted, run  # noqa: E402
from .scene import Scene, SceneError, load_scene  # noqa: E402
from .store import StoreError, open_dataset  # noqa: E402

__all__ = [
    "ClusterLost",
    "MODELS",
    "OutOfSpace",
    "RunInterrupted",
    "Scene",
    "SceneError",
    "StoreError",
    "__version__",
    "load_scene",
    "open_dataset",
    "run",
]
