"""A model's outputs on rows of parameters, without a scene or a file: the output arrays in their
shapes (extra dimensions from the solver settings), the status and the step/rhs counts. Shared by
the tests and the measurement scripts here (tests import it with tests/data on sys.path)."""
import numpy as np


def blank_outputs(spec, solver, n, wanted) -> dict:
    """NaN arrays for ``wanted`` at ``n`` points, each with its extra dimensions."""
    return {k: np.full((n,) + tuple(len(d.values(solver.settings)) for d in spec.output(k).extra_dims), np.nan)
            for k in wanted}


def evaluate(spec, P, wanted, *, quiet=False, **solver):
    """(out, status, n_steps, n_rhs) of ``spec.evaluate`` on the rows of ``P``; ``solver``: the
    scene's [solver] keys; ``quiet``: numpy's floating-point warnings off (extreme points)."""
    from mechsweep.scene import Solver

    slv = Solver.for_model(spec, **solver)
    n = P.shape[0]
    out = blank_outputs(spec, slv, n, wanted)
    status, ns, nr = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
    with np.errstate(all="ignore" if quiet else "warn"):
        spec.evaluate(P, tuple(wanted), slv, out, status, ns, nr)
    return out, status, ns, nr
