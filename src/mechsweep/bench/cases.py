"""The work-precision bench's cases: a model found by its reference (built-in name, model file,
module or entry point), the built-in models that declare a report, the scene a declaration names,
the fixed sample of that scene's grid points every method is measured on, and the symbols the
report's figure names them by. Shared by the integrated models' report (workprecision.py) and the
closed-form models' (workprecision_linkage.py).
"""
from __future__ import annotations

import math
import re
import time
from pathlib import Path

import numpy as np

from ..grid import ParameterMatrix
from ..models import MODELS
from ..scene import Scene
from .. import examples

TIMED_POINTS = 1024  # our time per point: the sample repeated up to this many points ...
TIMED_CALL_S = 0.05  # ... or until one call takes this long


def all_cases() -> tuple[str, ...]:
    """Every built-in model that declares its work-precision report: an OdeModel's
    ``WorkPrecision`` (a ladder of tolerances) or a ClosedFormModel's ``SizeWorkPrecision`` (a ladder
    of its extra dimension's length, :mod:`mechsweep.bench.workprecision_linkage`)."""
    return tuple(name for name, spec in MODELS.items()
                 if getattr(spec.declaration, "workprecision", None) is not None)


def resolve_model(model):
    """The ModelSpec of a model reference: a built-in name, "file.py:NAME" (relative to the current
    folder), "package.module:NAME" or an entry-point name; an InputError naming what is allowed."""
    from ..errors import InputError
    from ..model import user

    if isinstance(model, str) and model in MODELS:
        return MODELS[model]
    if isinstance(model, str) and ":" in model:
        return user.resolve(model)
    if isinstance(model, str):
        points = user.entry_points(quiet=True)
        if model in points:
            return user.resolve(points[model].value)
    raise InputError(f"no work-precision case for model {model!r}; cases: {', '.join(all_cases())}, or a model "
                     "declared as a mechsweep.model.OdeModel or ClosedFormModel ('file.py:NAME', "
                     "'package.module:NAME' or an entry-point name)")


def declared_scene(declared) -> tuple[Path, str]:
    """(the scene file a WorkPrecision / SizeWorkPrecision names, the label the report gives it):
    relative to the folder of the file that declares it; a ``sweeps/NAME.toml`` not found there is
    the shipped ``sweeps/NAME.toml`` (mechsweep.examples: installed with the package), labelled so."""
    prefix = "sweeps/"
    path = Path(declared.scene)
    if not path.is_absolute():
        path = Path(declared.base or Path.cwd()) / path
    name = declared.scene[len(prefix):]
    if not path.is_file() and declared.scene.startswith(prefix) and "/" not in name and Path(name) in examples.files():
        return examples.path(name), declared.scene
    if not path.is_file():
        from ..errors import InputError
        raise InputError(f"the model's work-precision declaration names scene {declared.scene!r}, which is not a file: "
                         f"{path} (a path relative to the folder of the file that declares it, {declared.base}); "
                         "give --scene S.toml or correct the declaration")
    return path, str(path)


def sample(scene: Scene, points: int, seed: int = 0) -> np.ndarray:
    """`points` grid points of the scene, drawn without replacement with a fixed seed, in grid order."""
    pm = ParameterMatrix(scene)
    rng = np.random.default_rng(seed)
    idx = np.sort(rng.choice(scene.n_points, size=min(points, scene.n_points), replace=False))
    return np.vstack([pm(int(i), int(i) + 1) for i in idx])


def latex_symbols(spec) -> str:
    """{name: mathtext symbol} of the model's outputs and parameters that declare one, as JSON: the
    work-precision figure names the outputs by their symbols (it reads the dataset, not the model)."""
    import json

    return json.dumps({q.name: q.latex for q in spec.params + spec.outputs if getattr(q, "latex", "")})


def fastest(fn, repeats: int) -> float:
    """The shortest wall time of ``repeats`` calls of fn()."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def tiled(P, once_s: float):
    """The sample repeated until a call takes ~TIMED_CALL_S (at most TIMED_POINTS points), so that a
    call's fixed cost is spread as over a sweep's chunk; once_s: one call's time on P."""
    tiles = int(min(max(1, TIMED_POINTS // P.shape[0]), max(1, math.ceil(TIMED_CALL_S / max(once_s, 1e-9)))))
    return np.tile(P, (tiles, 1))


def write(ds, out_dir, model: str, table_dims) -> Path:
    """The report into out_dir/workprecision_MODEL.h5 and its variables of dims ``table_dims`` into
    the .csv beside it; returns the .h5 path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"workprecision_{re.sub(r'[^A-Za-z0-9_.-]', '_', model)}.h5"
    ds.to_netcdf(path, engine="h5netcdf")
    table = [name for name in ds.data_vars if ds[name].dims == table_dims]
    ds[table].to_dataframe().to_csv(path.with_suffix(".csv"))
    return path
