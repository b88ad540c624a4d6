"""`mechsweep check SCENE...`: load and validate scene files without running them."""
from __future__ import annotations

import sys

from . import EXIT_INVALID

CHECK_DESCRIPTION = """\
Load and validate each scene file as `mechsweep run` would (model, axes, fixed values, outputs,
solver, storage, boundaries), without computing anything or touching a file. Prints one line per
valid scene (model, number of grid points, outputs) and every problem of an invalid one with its
key, the bad value and what is allowed; exit 2 if any scene is invalid.

examples:
  mechsweep check sweeps/quickstart.toml
  mechsweep check sweeps/*.toml
"""


def add_parser(sub, fmt) -> None:
    p = sub.add_parser("check", help="validate scene files without running them", description=CHECK_DESCRIPTION,
                       formatter_class=fmt)
    p.add_argument("scenes", nargs="+", metavar="SCENE", help="scene TOML files")
    p.set_defaults(func=command)


def command(args) -> int:
    from ..scene import SceneError, load_scene

    bad = 0
    for path in args.scenes:
        try:
            s = load_scene(path)
            print(f"{path}: ok ({s.model.name}, {s.n_points} points, outputs {', '.join(s.outputs)})")
            from ..scene import solver_warnings
            for text in solver_warnings(s):
                print(f"{path}: warning: {text}", file=sys.stderr)
            if s.boundaries is not None:
                from ..boundaries import warnings_for
                for text in warnings_for(s):
                    print(f"{path}: warning: {text}", file=sys.stderr)
        except SceneError as exc:
            bad += 1
            print(f"{path}: {exc}", file=sys.stderr)
    return EXIT_INVALID if bad else 0
