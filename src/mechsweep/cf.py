"""CF metadata every dataset mechsweep writes carries (CF-1.8, the latest version the CF checker
``cfchecker`` knows; the tests run it on every shipped scene's dataset): ``Conventions``,
``source`` (mechsweep and the model that computed the data), ``history`` (what wrote it, when,
with which version) and ``references`` (the source documents of the model, from its declaration);
units are UDUNITS-2 strings declared with each parameter and output (``kg m2``, ``rad s-1``, ``1``
for dimensionless; strings, the values of a categorical parameter, have none). Each output names
the per-point ``status`` as its ``ancillary_variables``; ``status`` is a CF ``status_flag``
(``flag_values`` / ``flag_meanings``). A log-spaced axis says so in its ``spacing`` attribute (the
package's figures draw it on a log axis) and in a ``comment`` telling a user of xarray to plot it
with ``xscale="log"``.
"""
from __future__ import annotations

import contextvars
import shlex
import sys
from pathlib import Path

CONVENTIONS = "CF-1.8"
LOG_AXIS_COMMENT = ("log-spaced axis (equal ratios between neighbouring values): draw it on a log axis, "
                    "e.g. ds[VARIABLE].plot(x=AXIS, xscale=\"log\")")


# the command line while the CLI runs a command (set by cli.main for its duration; a context
# variable, not sys.argv: `python -m pytest` calling cli.main has pytest's argv)
CLI_ARGS: contextvars.ContextVar[tuple[str, ...] | None] = contextvars.ContextVar("mechsweep_cli_args", default=None)


def command(what: str) -> str:
    """The command that is writing a dataset: the ``mechsweep`` command line when the CLI runs,
    else the Python call ``what`` and the program that made it."""
    args = CLI_ARGS.get()
    if args is not None:
        return " ".join(shlex.quote(a) for a in ["mechsweep", *args])
    prog = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    return f"{what} (Python, {prog or 'interactive'})"


def history(created: str, what: str, version: str) -> str:
    """A CF ``history`` line: time stamp, command, and the mechsweep version that wrote the data.
    Text HDF5 can store: a lone surrogate (a command-line argument whose bytes are not UTF-8, e.g. a
    file name) is written as its escape, ``\\udcff``, and a NUL as ``\\x00``."""
    line = f"{created}: {command(what)} (mechsweep {version})"
    return line.encode("utf-8", "backslashreplace").decode("utf-8").replace("\0", "\\x00")


def references(spec) -> str:
    """The model's source documents (``references`` of its declaration; its ``source`` when it
    declares none), one per line."""
    refs = tuple(getattr(spec, "references", ()) or ())
    return "\n".join(refs) if refs else (spec.source or f"model {spec.name}")


def source(spec, version: str) -> str:
    """The CF ``source``: how the data was produced (mechsweep's version and the model, with its
    own source when it declares one)."""
    origin = f" ({spec.source})" if getattr(spec, "source", "") else ""
    return f"mechsweep {version}, model {spec.name}{origin}"


UNIT_EXAMPLES = "'m', 'kg m2', 'rad s-1', 'N m', 'm s-2', '1' for dimensionless"


def unit_problem(unit) -> str | None:
    """Why ``unit`` is not a unit string a CF dataset can carry (UDUNITS-2 must parse it), or None.
    "" is allowed: no unit declared, no ``units`` attribute written (CF: unknown)."""
    if unit == "":
        return None
    if not isinstance(unit, str):
        return f"{unit!r} is not a string; expected a UDUNITS-2 unit such as {UNIT_EXAMPLES}"
    import cf_units  # here: only loading a user model checks units (its import reads the unit database)

    try:
        parsed = cf_units.Unit(unit)
    except (ValueError, TypeError):
        parsed = None
    if parsed is None or parsed.is_unknown() or parsed.is_no_unit():
        return f"{unit!r} is not a unit UDUNITS-2 reads (CF units); expected e.g. {UNIT_EXAMPLES}"
    return None
