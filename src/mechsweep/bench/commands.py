"""The `mechsweep bench` subcommands, what a user measures on their own machine: `workprecision
MODEL` (error against time for any model, ours and scipy's methods) and `duffing` (mechsweep
against the other ODE tools). The project's own benchmarks are in the repository's benchmarks/
folder, not in the package. The CLI only hands its subparsers here."""
from __future__ import annotations

import argparse


def add_parsers(bsub, fmt=argparse.RawDescriptionHelpFormatter) -> None:
    """Add every bench subcommand to ``bsub`` (the `bench` subparsers)."""
    b = bsub.add_parser("duffing", help="amplitude-period sweep: points/s, ratio to scipy solve_ivp, error")
    b.add_argument("--points", type=int, default=200_000, help="grid points for mechsweep (default 200000)")
    b.add_argument("--scipy-points", type=int, default=200, help="points solved with scipy (default 200)")
    b.add_argument("--compare-points", type=int, default=20_000,
                   help="points solved with numbalsoda (both drivers) and diffrax, when installed (default 20000)")
    b.add_argument("--repeats", type=int, default=3, help="interleaved repetitions of every timing (default 3)")
    b.add_argument("--threads", type=int, default=None, help="numba threads (default: all cores)")
    b.add_argument("--rtol", type=float, default=None, help="default: the solver default")
    b.add_argument("--atol", type=float, default=None, help="default: the solver default")
    b.set_defaults(func=run_duffing)
    b = bsub.add_parser("workprecision", formatter_class=fmt,
                        help="error against run time for every method, ours and scipy's (DOP853, Radau, LSODA)",
                        description="Integrate a fixed sample of a scene's grid points with every method the "
                                    "model offers and with scipy's solve_ivp (running the model's own rhs), over a "
                                    "ladder of tolerances; print error against time per point and write "
                                    "DIR/workprecision_MODEL.h5 and .csv (draw it with `mechsweep plot "
                                    "DIR/workprecision_MODEL.h5`). What is measured is declared by the model: "
                                    "OdeModel(workprecision=WorkPrecision(scene, output, reference)). A closed-form "
                                    "model that declares ClosedFormModel(workprecision=SizeWorkPrecision(...)) is "
                                    "evaluated over a ladder of its extra dimension's length instead (--positions, "
                                    "e.g. crank positions per cycle), against its declared reference, with its "
                                    "declared independent implementation timed alongside.")
    b.add_argument("model", help="a built-in model's name (an unknown name lists those that declare a report) or a "
                                 "model of your own: 'file.py:NAME' (relative to the current directory), "
                                 "'package.module:NAME' or an entry-point name; without a declared scene, give "
                                 "--scene S.toml naming the same model")
    b.add_argument("--scene", default=None, help="draw the sample from this scene (default: the scene the model declares)")
    b.add_argument("--points", type=int, default=64, help="sample points for mechsweep (default 64)")
    b.add_argument("--scipy-points", type=int, default=6, help="of those, solved with scipy (default 6)")
    b.add_argument("--rtol", type=float, nargs="+", default=None, metavar="RTOL",
                   help="tolerance ladder (default 1e-4 ... 1e-13, one per decade)")
    b.add_argument("--positions", type=int, nargs="+", default=None, metavar="N",
                   help="closed-form models: the ladder of the extra dimension's length, e.g. crank positions per "
                        "cycle (default: the model's declared sizes)")
    b.add_argument("--repeats", type=int, default=None,
                   help="timing repetitions, the fastest counts (default 3; closed-form models 5)")
    b.add_argument("--out", default="data/bench", help="output folder (default data/bench)")
    b.add_argument("--output", default=None, metavar="NAME",
                   help="the measured output to compare (default: the declared output, else the first measurement)")
    b.set_defaults(func=run_workprecision)
    for name, sub in bsub.choices.items():  # every bench's --help: what it measures, then an example
        sub.formatter_class = fmt
        if not sub.description:
            sub.description = _sentence(next(a.help for a in bsub._choices_actions if a.dest == name))
        sub.epilog = "example:\n  " + EXAMPLES[name]


# one example command per bench (small enough to finish in a minute or two)
EXAMPLES = {
    "duffing": "mechsweep bench duffing --points 20000 --repeats 1",
    "workprecision": "mechsweep bench workprecision duffing --points 16 --out /tmp/bench",
}


def _sentence(text: str) -> str:
    """A subcommand's one-line help as the first sentence of its description."""
    return text[:1].upper() + text[1:] + ("" if text.endswith(".") else ".")


def run_duffing(args) -> int:
    from ..scene import Solver
    from . import duffing as bench_duffing

    bench_duffing.main(points=args.points, scipy_points=args.scipy_points, threads=args.threads,
                       compare_points=args.compare_points, repeats=args.repeats,
                       rtol=Solver.rtol if args.rtol is None else args.rtol,
                       atol=Solver.atol if args.atol is None else args.atol)
    return 0


def run_workprecision(args) -> int:
    from ..errors import InputError
    from ..model.closed import ClosedFormModel
    from . import workprecision, workprecision_linkage

    # what the model declares decides the ladder: a ClosedFormModel's SizeWorkPrecision (--positions)
    # or an OdeModel's tolerances (--rtol)
    linkage = isinstance(workprecision.resolve_model(args.model).declaration, ClosedFormModel)
    if linkage and args.rtol:
        raise InputError(f"{args.model} is algebraic: it has no tolerance (--rtol); its ladder is --positions")
    if args.positions and not linkage:
        closed = [n for n in workprecision.all_cases()
                  if isinstance(workprecision.resolve_model(n).declaration, ClosedFormModel)]
        raise InputError(f"--positions is for closed-form models (a ladder of their extra dimension's length: "
                         f"{', '.join(closed)}), not {args.model}")
    if linkage:
        workprecision_linkage.main(args.model, args.scene, points=args.points,
                                   positions=tuple(args.positions) if args.positions else None,
                                   repeats=5 if args.repeats is None else args.repeats, out_dir=args.out)
        return 0
    workprecision.main(args.model, args.scene, points=args.points, scipy_points=args.scipy_points,
                       ladder=tuple(args.rtol) if args.rtol else workprecision.LADDER,
                       repeats=3 if args.repeats is None else args.repeats,
                       out_dir=args.out, output=args.output)
    return 0
