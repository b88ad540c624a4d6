"""The command line of a developer benchmark: ``python benchmarks/NAME.py [options]`` or
``python -m benchmarks.NAME [options]`` from the repository's root, with mechsweep importable
(installed, or ``PYTHONPATH=src``). A bad option is refused as mechsweep's own commands refuse one:
one line naming it and what is allowed, exit code 2, nothing started; Ctrl-C exits 130."""
from __future__ import annotations

import argparse
import signal
import sys


def parser(name: str, description: str) -> argparse.ArgumentParser:
    """The argument parser of ``benchmarks/NAME.py`` (its docstring's first paragraph as description)."""
    return argparse.ArgumentParser(prog=f"python benchmarks/{name}.py", description=description.split("\n\n")[0],
                                   formatter_class=argparse.RawDescriptionHelpFormatter)


def run(parser: argparse.ArgumentParser, command, argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default: the process's arguments) and return ``command(args)``'s exit code."""
    from mechsweep.errors import MechsweepError

    args = parser.parse_args(argv)
    try:
        return command(args)
    except (MechsweepError, FileNotFoundError) as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{parser.prog}: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT
