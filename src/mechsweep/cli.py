"""Command line: ``mechsweep run | plot | info | models | boundaries | check | examples | bench``.

Parsing, the exit codes and the one-line errors only: each command (its help text, arguments and
work) is a module of ``commands/``; ``bench`` is ``bench/commands.py``'s."""
from __future__ import annotations

import argparse
import os
import signal
import sys
import warnings

from .commands import EXIT_INVALID, boundaries, check, examples, held_collector, info, leave, models, plot, run

DESCRIPTION = """\
Parameter sweeps over the dynamics of machine mechanisms, compiled with numba.

A study is a scene: a TOML file naming a model, the axes of a grid, the fixed
parameters, the outputs wanted and (for integrated outputs) the solver settings.
`run` computes it on all cores into an HDF5 file (an xarray Dataset), `plot` draws
its nomogram, `info` summarises a stored run.

typical session:
  mechsweep run sweeps/quickstart.toml             # -> data/runs/quickstart.h5
  mechsweep plot data/runs/quickstart.h5           # -> data/runs/quickstart_<figure>.png
  mechsweep info data/runs/quickstart.h5
  mechsweep models                                 # every model, parameter and output
  mechsweep models my_models.py:NAME               # a model of your own (see `models --help`)

exit codes: 0 done, 1 unexpected error, 2 invalid input (nothing written) or a failed write
(disk full: the journal is kept for --resume), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM)
"""

BENCH_DESCRIPTION = """\
Benchmarks print measured numbers of this machine, with ratios against the alternatives measured
in the same run. `mechsweep bench BENCH --help` describes each.

examples:
"""


def main(argv: list[str] | None = None) -> int:
    with held_collector(argv):  # the command's own process: no full collections during its start-up
        return _main(argv)


def script() -> None:
    """The ``mechsweep`` program (its console script, ``python -m mechsweep``): :func:`main` on the
    command line, then the process ends with its exit code (at once after `plot`: ``commands.leave``)."""
    code = main()
    leave(sys.argv[1] if len(sys.argv) > 1 else None, code)
    sys.exit(code)


def _main(argv: list[str] | None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_INVALID
    from .errors import MechsweepError, RunInterrupted, os_error_text

    import threading

    main_thread = threading.current_thread() is threading.main_thread()  # only it may set handlers
    # SIGTERM stops like Ctrl-C (unless the process was started ignoring it: execution/stopping.Signals)
    handled = main_thread and signal.getsignal(signal.SIGTERM) is not signal.SIG_IGN
    previous = signal.signal(signal.SIGTERM, _terminate) if handled else None
    from . import cf

    cli_args = cf.CLI_ARGS.set(tuple(sys.argv[1:] if argv is None else argv))
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning(args.command, warnings.showwarning)
            return args.func(args)
    except RunInterrupted as exc:  # the journal is kept: the message says how to resume
        print(f"mechsweep {args.command}: {exc}", file=sys.stderr)
        return 128 + exc.signum
    except (MechsweepError, FileNotFoundError) as exc:
        # bad input (InputError) and a run that failed on the way (RunError: disk full, lost cluster) both
        # exit 2 with one line, as the exit codes above say; a bug (any other exception) exits 1 with its traceback.
        # A FileNotFoundError of the system (with an errno) is said as the others are; mechsweep's own say it all
        text = os_error_text(exc) if isinstance(exc, FileNotFoundError) and exc.errno is not None else exc
        print(f"mechsweep {args.command}: error: {text}", file=sys.stderr)
        return EXIT_INVALID
    except KeyboardInterrupt as exc:
        signum = exc.signum if isinstance(exc, _Terminated) else signal.SIGINT
        print(f"mechsweep {args.command}: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
        return 128 + signum
    except BrokenPipeError:  # `mechsweep models | head`: the reader left, nothing is wrong
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return 0
    except OSError as exc:  # a read or write the system refused: its cause and the file, in one line
        print(f"mechsweep {args.command}: error: {os_error_text(exc)}", file=sys.stderr)
        return EXIT_INVALID
    finally:
        cf.CLI_ARGS.reset(cli_args)
        if handled:
            signal.signal(signal.SIGTERM, previous if previous is not None else signal.SIG_DFL)


def _show_warning(command, default):
    """A user model's warning, or one on the scene's settings, as one line on stderr (no source line of
    mechsweep's); others as usual."""
    from .errors import SettingsWarning, UserModelWarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, (UserModelWarning, SettingsWarning)):
            print(f"mechsweep {command}: warning: {message}", file=sys.stderr)
        else:
            default(message, category, filename, lineno, file, line)
    return show


class _Terminated(KeyboardInterrupt):
    signum = signal.SIGTERM


def _terminate(signum, frame):
    raise _Terminated


def _parser() -> argparse.ArgumentParser:
    fmt = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(prog="mechsweep", description=DESCRIPTION, formatter_class=fmt)
    from . import __version__

    parser.add_argument("--version", action="version", version=f"mechsweep {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for command in (run, plot, info, models, boundaries, check, examples):  # the order --help lists them in
        command.add_parser(sub, fmt)

    from .bench import commands as bench_commands

    # the examples are the benches' own (the bench package names what it measures)
    bench_examples = "".join(f"  {text}\n" for text in bench_commands.EXAMPLES.values())
    p = sub.add_parser("bench", help="benchmarks: speed and accuracy against scipy / numpy, measured now",
                       formatter_class=fmt, description=BENCH_DESCRIPTION + bench_examples)
    bsub = p.add_subparsers(dest="bench", metavar="BENCH")
    bench_commands.add_parsers(bsub, fmt)
    p.set_defaults(func=lambda a: (p.print_help(), EXIT_INVALID)[1])
    return parser


if __name__ == "__main__":
    script()
