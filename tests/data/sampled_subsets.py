"""Every subset of sampled outputs, bitwise, before and after a change of the sampled-trajectory
kernel (model/trajectory.py): ``python tests/data/sampled_subsets.py record FILE.npz`` runs the
cases below (the auto-balancer with and without its re-check, lanes and one trajectory at a time,
dop853, radau and auto; user models with Steady, Kick, History, a measurement's classify, a status
order, first-failure statuses) and stores every output, status, n_steps and n_rhs;
``... compare FILE.npz`` runs them again and prints the arrays that differ in a single bit
(exit 1). Record with the old code, compare with the new one (e.g. PYTHONPATH=OLD/src, then the
new src): the cost is one compile per kernel of the old code (about 20 s each here, minutes under
load). A third argument ``quick`` runs the 17 cases of QUICK only, another text the cases whose
label starts with it."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import points  # noqa: E402
USER = HERE.parent / "user_models"


def _run(spec, model, P, wanted, lanes=True, **kw):
    from mechsweep.model import trajectory
    from mechsweep.model.ode import _outputs
    from mechsweep.scene import Solver
    slv = Solver.for_model(spec, **kw)
    n = P.shape[0]
    out = points.blank_outputs(spec, slv, n, wanted)
    status, ns, nr = np.zeros(n, np.int8), np.zeros(n, np.int64), np.zeros(n, np.int64)
    with np.errstate(all="ignore"):
        if lanes:
            spec.evaluate(P, tuple(wanted), slv, out, status, ns, nr)
        else:  # the sampled outputs alone, one trajectory at a time
            chosen = tuple(m for m in model.measurements if any(o.name in wanted for o in _outputs(m)))
            trajectory.evaluate(model, chosen, P, tuple(wanted), slv, out, status, ns, nr, lanes=False)
    return dict(out, status=status, n_steps=ns, n_rhs=nr)


def cases():
    import record_autobalancer as rec

    from mechsweep.model import user
    from mechsweep.models import autobalancer as ab

    P = rec.design_points()
    kw = dict(rtol=1e-8, atol=1e-10, horizon_revolutions=rec.HORIZON)
    hist = ("xi_history", "eta_history", "phase_error1_history", "phase_error2_history")
    sim = ("stable_sim", "settling_time", "phase_error", "residual_amplitude", "residual_amplitude_h1",
           "residual_amplitude_phase")
    ab_sets = {"kick": ("stable_sim",), "steady": ("residual_amplitude",),
               "steady_h1": ("residual_amplitude", "residual_amplitude_phase"), "xi": ("xi_history",),
               "pe2_kick": ("phase_error2_history", "settling_time"), "all": sim + hist,
               "floquet_sim": ("floquet_max", "stable_floquet", "stable_sim", "residual_amplitude", "theta")}
    for name, wanted in ab_sets.items():
        for recheck in (1000.0, 0.0):
            yield (f"ab-{name}-dop853-{recheck:g}",
                   (ab.SPEC, ab.MODEL, P, wanted, True, dict(kw, reproducibility_factor=recheck)))
        yield f"ab-{name}-onebyone", (ab.SPEC, ab.MODEL, P, wanted, False, kw)
    for method in ("radau", "auto"):
        for name in ("kick", "steady", "all"):
            yield f"ab-{name}-{method}", (ab.SPEC, ab.MODEL, P, ab_sets[name], True, dict(kw, method=method))
    decay = user.resolve(f"{USER / 'forced.py'}:DECAY")
    lam = np.array([0.5, 0.2, -0.05, 1e-6, 30.0, 0.3])
    Pd = np.column_stack([lam, np.array([0.1, 0.3, 0.1, 0.1, 0.1, 2.0])])
    d_sets = {"stable": ("stable", "stable_settling"), "hist": ("y_hist",), "rel": ("kick_rel_settling", "peak_rel"),
              "yrel_stable_final": ("y_rel", "stable_final"),
              "all": ("stable", "stable_settling", "stable_final", "y_hist", "kick_rel", "kick_rel_settling",
                      "kick_rel_final", "peak_rel", "y_rel")}
    for name, wanted in d_sets.items():
        yield f"decay-{name}", (decay, None, Pd, wanted, True, dict(rtol=1e-11, atol=1e-14, max_steps=10**7))
    yield "decay-all-radau", (decay, None, Pd, d_sets["all"], True, dict(method="radau", rtol=1e-9, atol=1e-14))
    Ps = np.array([[1.0, 0.1, 1.0, 0.5], [1.0, 0.2, -1.0, 0.9], [2.0, 1.5, 1.0, 1.0], [1.0, 2.0, -1.0, 1.0],
                   [1.0, 0.0, 0.0, 1.3], [1.5, 0.3, 0.0, 2.0]])
    for model in ("SEVERITY", "FIRST"):
        spec = user.resolve(f"{USER / 'severity.py'}:{model}")
        for name, wanted in {"amp": ("amp",), "hist": ("x_hist",), "amp_hist": ("amp", "x_hist"),
                             "all": ("mu", "amp", "x_hist", "amp_exact")}.items():
            yield f"{model}-{name}", (spec, None, Ps, wanted, True, dict(rtol=1e-9, atol=1e-12, horizon_periods=30.0))


QUICK = ("ab-kick-dop853-1000", "ab-kick-dop853-0", "ab-kick-onebyone", "ab-steady-dop853-1000", "ab-all-dop853-1000",
         "ab-pe2_kick-dop853-0", "ab-steady_h1-dop853-0", "ab-floquet_sim-dop853-1000", "ab-all-radau",
         "ab-steady-auto",
         "decay-rel", "decay-all", "decay-all-radau", "SEVERITY-hist", "SEVERITY-amp_hist", "FIRST-hist", "FIRST-all")


def run_all(only=None):
    res = {}
    for label, (spec, model, P, wanted, lanes, kw) in cases():
        if only == "quick" and label not in QUICK:
            continue
        if only and only != "quick" and not label.startswith(only):
            continue
        if model is None and not lanes:
            continue
        for key, v in _run(spec, model, P, wanted, lanes, **kw).items():
            res[f"{label}/{key}"] = v
        print(label, flush=True)
    return res


if __name__ == "__main__":
    what, file = sys.argv[1], sys.argv[2]
    only = sys.argv[3] if len(sys.argv) > 3 else None
    if what == "record":
        np.savez_compressed(file, **run_all(only))
    else:
        ref = np.load(file)
        new = run_all(only)
        bad = [k for k in ref.files if k.split("/")[0] in {x.split("/")[0] for x in new}
               and not (k in new and new[k].dtype == ref[k].dtype and np.array_equal(new[k], ref[k], equal_nan=True))]
        missing = [k for k in new if k not in ref.files]
        extra = f", missing in the record: {missing}" if missing else ""
        print(f"{len(new)} arrays compared, {len(bad)} differ{extra}")
        for k in bad:
            print("DIFFERENT", k)
        sys.exit(1 if bad or missing else 0)
