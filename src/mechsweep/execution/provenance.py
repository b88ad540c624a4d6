"""The attributes a run's dataset (and its journal) starts with: the scene, its plan, the versions of
what computed it, the sources its results depend on."""
from __future__ import annotations

import datetime as _dt
import functools
import platform
from importlib.metadata import version as _version

import numba
import numpy as np

from .. import __version__
from .. import cf
from .plan import Plan


@functools.lru_cache(maxsize=1)
def _xarray_version() -> str:
    """The installed xarray's version, looked up once per process: importlib.metadata reads the
    package's metadata files at every call (1-10 ms, before a run's first chunk)."""
    return _version("xarray")


def provenance(plan: Plan) -> dict:
    """The attributes a run's dataset (and its journal) starts with: the scene, its plan, versions."""
    scene = plan.scene
    created = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    attrs = {
        "title": scene.name,
        "model": scene.model.name,
        "model_source": scene.model.source,
        "outputs": " ".join(scene.outputs),
        "scene": scene.text,
        "scene_canonical": scene.canonical(),
        **({"scene_folder": scene.base} if scene.base else {}),
        "created": created,
        "mechsweep_version": __version__,
        "numba_version": numba.__version__,
        "numpy_version": np.__version__,
        "xarray_version": _xarray_version(),  # xarray is not imported by the command `mechsweep run` (0.3 s of CPU)
        "python_version": platform.python_version(),
        "chunk_size": plan.chunks.max_size,
        "wall_time_s": 0.0,
        "Conventions": cf.CONVENTIONS,
        "source": cf.source(scene.model, __version__),
        "history": cf.history(created, f"mechsweep.run(scene {scene.name!r})", __version__),
        "references": cf.references(scene.model),
    }
    if scene.solver is not None:
        for k, v in scene.solver.as_dict().items():
            attrs[f"solver_{k}"] = v
    from ..model import sources

    # what the results are computed from (model/sources.py): a resume checks it, a reader sees it
    attrs.update(sources.record(scene.model).attrs(scene.base or None))
    attrs["plan"] = plan.text()  # what is computed and how (plan.py)
    return attrs
