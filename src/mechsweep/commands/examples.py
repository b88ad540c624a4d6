"""`mechsweep examples DIR`: copy the shipped example scenes into a folder, to run them there."""
from __future__ import annotations

import os
from pathlib import Path

EXAMPLES_DESCRIPTION = """\
Copy the example scenes that ship with mechsweep into DIR/sweeps/ (every study of the
documentation, and the user model they name, sweeps/models/vibrating_pendulum.py), with an empty
DIR/data/runs/ for the datasets they write: what a pip-installed mechsweep needs to run the
quickstart without a clone of the repository. DIR is made if missing; an existing file is never
replaced (nothing is copied then).

example:
  mechsweep examples my-study && cd my-study
  mechsweep run sweeps/quickstart.toml && mechsweep plot data/runs/quickstart.h5
"""


def add_parser(sub, fmt) -> None:
    p = sub.add_parser("examples", help="copy the shipped example scenes into a folder, to run them there",
                       description=EXAMPLES_DESCRIPTION, formatter_class=fmt)
    p.add_argument("folder", metavar="DIR", help="the folder to copy them into (made if missing)")
    p.set_defaults(func=command)


def command(args) -> int:
    import shlex

    from .. import examples
    from ..errors import InputError

    if os.path.exists(args.folder) and not os.path.isdir(args.folder):
        raise InputError(f"{args.folder} exists and is not a folder; give a folder to copy the examples into")
    try:
        written = examples.copy(args.folder)
    except FileExistsError as exc:
        raise InputError(str(exc)) from None
    except OSError as exc:
        raise InputError(f"cannot copy the examples into {args.folder}: {exc.strerror or exc}") from None
    root = Path(args.folder)
    print(f"copied {len(written)} files into {root / 'sweeps'}; run the quickstart there:")
    print(f"  cd {shlex.quote(str(root))} && mechsweep run sweeps/quickstart.toml && mechsweep plot data/runs/quickstart.h5")
    return 0
