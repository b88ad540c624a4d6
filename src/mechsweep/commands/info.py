"""`mechsweep info DATASET`: summarise a stored dataset (the text is describe.py's)."""
from __future__ import annotations


INFO_DESCRIPTION = """\
Summarise a dataset written by `mechsweep run` (or `mechsweep boundaries`): its dimensions and
fixed values, each output's unit and range, how many grid points ended with each status, the cost
(steps, wall and compile time), the solver settings and the provenance (creation time, versions).
An unfinished run (PATH.partial/) is summarised as far as it got. Reads the file only.

examples:
  mechsweep info data/runs/quickstart.h5
  mechsweep info data/runs/autobalancer_stability_chart.boundaries.h5
"""


def add_parser(sub, fmt) -> None:
    p = sub.add_parser("info", help="summarise a stored dataset: dims, outputs, status counts, cost, provenance",
                       description=INFO_DESCRIPTION, formatter_class=fmt)
    p.add_argument("dataset", metavar="DATASET", help="HDF5 file written by `mechsweep run` or `mechsweep boundaries`")
    p.set_defaults(func=command)


def command(args) -> int:
    from ..describe import describe, describe_boundaries
    from ..errors import InputError
    from ..store.read import is_run_dataset, open_dataset, reading

    ds = open_dataset(args.dataset, allow_partial=True, lazy=None)
    boundaries = ds.attrs.get("mechsweep_kind") == "boundaries" and "boundary" in ds
    if not boundaries and not is_run_dataset(ds):
        raise InputError(f"{args.dataset} is a mechsweep benchmark dataset ({ds.attrs.get('mechsweep_kind')}), "
                         "not a run; `mechsweep plot` draws it, `info` summarises runs")
    with reading(args.dataset):
        text = describe_boundaries(ds) if boundaries else describe(ds)
    print(text)
    return 0
