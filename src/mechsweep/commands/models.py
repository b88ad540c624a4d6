"""`mechsweep models [MODEL]`: the models with their parameters and outputs (the text is describe.py's)."""
from __future__ import annotations


MODELS_EPILOG = """\
Lists the built-in models, then the models installed packages register (entry-point group
mechsweep.models), with their parameters and outputs. A user model comes in by one of four doors:
  model = "my_models.py:NAME"       in a scene: a file path relative to the scene file
  model = "mypkg.models:NAME"       in a scene: an importable module
  model = "NAME"                    registered by an installed package, in its pyproject.toml:
                                      [project.entry-points."mechsweep.models"]
                                      NAME = "mypkg.models:NAME"
  mechsweep.run(scene, models={"NAME": my_ode_model})   from Python (runs locally only)
`mechsweep models my_models.py:NAME` or `mechsweep models --scene S.toml` shows one user model;
`mechsweep models my_models.py` every model the file defines, with the names a scene uses.
Loading a model file or module executes it: only name code you trust. A model that fails to
load is reported with its file and line (exit 2).

examples:
  mechsweep models
  mechsweep models NAME                # one model, by a name the list above gives
  mechsweep models --scene sweeps/vibrating_pendulum_stability.toml
"""


def add_parser(sub, fmt) -> None:
    p = sub.add_parser("models", help="list models with their parameters and outputs (name, unit, range)",
                       description=MODELS_EPILOG, formatter_class=fmt)
    p.add_argument("model", nargs="?", help="one model only: a built-in or registered name, 'file.py:NAME' "
                   "(relative to the current directory) or 'package.module:NAME'; a bare 'file.py': "
                   "the models that file defines")
    p.add_argument("--scene", metavar="SCENE", help="the model the scene file SCENE names (a user model "
                   "file is found relative to the scene)")
    p.add_argument("--markdown", action="store_true", help="print the glossary page of the documentation "
                   "(built-in models and status codes), or one model's tables; `python -m mechsweep.docs "
                   "docs/glossary.md` rewrites it in place")
    p.set_defaults(func=command)


def command(args) -> int:
    from ..describe import model_text
    from ..docs import model_markdown
    from ..errors import InputError
    from ..model import user
    from ..models import MODELS

    if args.scene and args.model:
        raise InputError("give either a MODEL or --scene SCENE, not both")
    if args.scene:
        from ..scene import load_scene

        specs = [load_scene(args.scene).model]
    elif args.model:
        name = args.model
        if name in MODELS:
            specs = [MODELS[name]]
        elif ":" in name:
            specs = [user.resolve(name)]
        elif name.endswith(".py") or "/" in name or "\\" in name:  # a model file without :NAME
            found = _models_in_file(name)
            print(f"{name} defines {len(found)} model(s): {', '.join(found)}; a scene names one as "
                  f"{name}:NAME (e.g. model = \"{name}:{found[0]}\")\n")
            specs = [user.resolve(f"{name}:{n}") for n in found]
        else:
            points = user.entry_points()
            if name not in points:
                known = list(MODELS) + sorted(set(points) - set(MODELS))
                raise InputError(f"unknown model {name!r}; models: {', '.join(known)} (or 'file.py:NAME', "
                                 "'package.module:NAME')")
            specs = [_entry_point_model(name, points[name])]
    elif args.markdown:  # the docs' glossary page: the built-in models and the status codes
        from ..docs import glossary

        print(glossary(), end="")
        return 0
    else:
        points = user.entry_points()
        specs = list(MODELS.values()) + [_entry_point_model(n, ep) for n, ep in points.items() if n not in MODELS]
    for spec in specs:
        print(model_markdown(spec) if args.markdown else model_text(spec))
    return 0


def _models_in_file(name: str) -> list[str]:
    """The names of the OdeModel and ClosedFormModel objects a model file defines (InputError
    naming the file when it is missing, fails to import or defines none)."""
    from pathlib import Path

    from ..errors import InputError
    from ..model import load, user
    from ..model.closed import ClosedFormModel
    from ..model.ode import OdeModel

    path = Path(name).resolve()
    user.check_model_file(name, path)  # a regular .py file; its import's failures and exits are InputErrors
    mod = user.import_model(name, load.module_name(path), str(path), str(path))
    found = [k for k, v in vars(mod).items() if isinstance(v, (OdeModel, ClosedFormModel))]
    if not found:
        raise InputError(f"{name!r}: {path} defines no mechsweep.model.OdeModel or ClosedFormModel")
    return found


def _entry_point_model(name: str, ep):
    from ..errors import InputError
    from ..model import user

    dist = getattr(getattr(ep, "dist", None), "name", None)
    try:
        return user.resolve(ep.value)
    except InputError as exc:
        raise InputError(f"entry point {name!r} (group {user.ENTRY_POINT_GROUP}"
                         f"{', package ' + dist if dist else ''}): {exc}") from None
