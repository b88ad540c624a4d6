"""The built-in auto-balancer is the model layer's declaration (models/autobalancer.py); its values
against the hand-written kernels' recorded before any change (tests/data/autobalancer_reference.npz,
tests/data/record_autobalancer.py) and against the kernels themselves, kept as a reference
implementation in tests/reference/autobalancer_kernels.py: every status bitwise, the simulated outputs the
same bits except residual_amplitude (1 ulp), floquet_max and its n_steps/n_rhs bitwise (the model's
Floquet integrates its own variational system, the 64 equations about the exact orbit, as the old
kernel); docs/model-layer.md."""
import sys
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.models import MODELS
from tests.reference import autobalancer_kernels as K
from mechsweep.models import autobalancer as ab
from tests.evaluating import evaluate

DATA = Path(__file__).resolve().parents[1] / "data"


def _rec():
    sys.path.insert(0, str(DATA))
    import record_autobalancer as rec
    return rec


def _evaluate(spec, P, wanted, **kw):
    return evaluate(spec, P, wanted, quiet=True, **kw)


def test_the_registered_autobalancer_is_the_layer_declaration():
    # no hand-written chunk kernel or method switch behind the model: its evaluate is the layer's
    spec = MODELS["autobalancer"]
    assert spec is ab.SPEC and spec.evaluate.__module__ == "mechsweep.model.ode"
    assert K.SPEC is not spec and K.SPEC.evaluate is K.evaluate


def test_the_model_layer_imports_first_in_a_fresh_process():
    # a user's model file starts with `from mechsweep.model import OdeModel`: mechsweep.model imports
    # mechsweep.models (Param), whose autobalancer declaration must not need mechsweep.model finished
    import subprocess
    code = "from mechsweep.model import OdeModel, Floquet\nimport mechsweep.engine.sampling\nprint('ok')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


@pytest.mark.slow  # compiles the model's kernels for the 9 dop853 design-grid cases (minutes cold)
def test_the_autobalancer_gives_the_reference_statuses_and_values():
    # the model's classify (INFEASIBLE), its measurements' classify (NOT_BALANCEABLE), status_order
    # (the old SEVERITY) and the Recheck (NOT_REPRODUCIBLE): every status of the dop853 design-grid
    # cases as the hand-written model's (UNDECIDED, NO_EVENT, SINGULAR, MAX_STEPS, STIFF among them)
    rec = _rec()
    r = rec.compare(lambda label: label.startswith("grid-dop853"))
    assert len({label for label, _ in r}) >= 8
    bad = {key: v for key, v in r.items() if v[0] == "DIFFERENT"}
    assert not bad, bad
    assert all(r[(label, "status")][0] == "bitwise" for label, _ in r)
    # n_steps/n_rhs bitwise where Floquet is not asked for; floquet_max and the counts of the cases
    # that ask for it bitwise too (the same 64 variational equations and floats as the old kernel)
    assert r[("grid-dop853-norecheck", "n_steps")][0] == "bitwise"
    floquet = [label for label, key in r if key == "floquet_max"]
    assert len(floquet) >= 3, floquet
    for label in floquet:
        for key in ("floquet_max", "n_steps", "n_rhs"):
            assert r[(label, key)][0] == "bitwise", (label, key, r[(label, key)])
    assert r[("grid-dop853-all", "stable_sim")][0] == "bitwise"
    ref = np.load(rec.FILE)
    codes = set(ref["grid-dop853-all/status"].tolist()) | set(ref["grid-dop853-maxsteps/status"].tolist())
    assert {st.INFEASIBLE, st.SINGULAR, st.NOT_BALANCEABLE, st.NOT_REPRODUCIBLE, st.MAX_STEPS} <= codes


@pytest.mark.slow  # Floquet and the sampled trajectory, each alone and together (two more kernels)
def test_floquet_and_the_simulation_asked_together_give_what_each_gives_alone():
    rec = _rec()
    P = rec.design_points()
    kw = dict(rtol=1e-8, atol=1e-10, horizon_revolutions=rec.HORIZON)
    both = _evaluate(ab.SPEC, P, ("floquet_max", "stable_floquet", "stable_sim", "residual_amplitude"), **kw)
    f = _evaluate(ab.SPEC, P, ("floquet_max", "stable_floquet"), **kw)
    g = _evaluate(ab.SPEC, P, ("stable_sim", "residual_amplitude"), **kw)
    for k, v in both[0].items():
        assert np.array_equal(v, (f if k in f[0] else g)[0][k], equal_nan=True), k
    assert np.array_equal(both[2], f[2] + g[2]) and np.array_equal(both[3], f[3] + g[3])
    assert np.array_equal(both[1], K._worse(f[1], g[1]))


@pytest.mark.slow  # compiles a closed-form kernel per output (about 15 s in all)
def test_each_closed_form_alone_gives_the_reference_value_and_the_hand_written_status():
    # theta (NOT_BALANCEABLE), balanceable, m_k, omega_p, stable_first_approx, P_approx (SINGULAR),
    # stable_damped_approx, each asked for alone on every point of the design grid
    rec = _rec()
    ref = np.load(rec.FILE)
    P = rec.design_points()
    seen = set()
    for c in ab.MODEL.closed_forms:
        wanted = ab.SPEC.closure((c.name,))
        out, status, _, _ = _evaluate(ab.SPEC, P, wanted, rtol=1e-8, atol=1e-10)
        assert np.array_equal(out[c.name], ref[f"grid-dop853-all/{c.name}"], equal_nan=True), c.name
        _, old, _, _ = _evaluate(K.SPEC, P, wanted, rtol=1e-8, atol=1e-10)
        assert np.array_equal(status, old), c.name
        seen |= set(status.tolist())
    assert {st.INFEASIBLE, st.NOT_BALANCEABLE, st.SINGULAR} <= seen


def test_the_autobalancer_has_the_reference_outputs_metadata_and_cross_parameter_rules():
    # every output of the hand-written model under its name (the measurements' output_meta and the
    # closed forms' metadata come from ab.OUTPUTS), with its symbol, unit, long name, kind, needs and
    # extra dimension; the same scene check
    new = MODELS["autobalancer"]
    for o in K.SPEC.outputs:
        n = new.output(o.name)
        # one difference: the layer's Floquet labels its modulus kind "floquet_max" (for the generic
        # figures); the old output has no kind
        kind = "floquet_max" if o.name == "floquet_max" else o.kind
        assert (n.symbol, n.unit, n.long_name, n.kind, n.needs, n.needs_params, n.integrated) == (
            o.symbol, o.unit, o.long_name, kind, o.needs, o.needs_params, o.integrated), o.name
        assert [(d.name, d.unit, d.long_name) for d in n.extra_dims] == [(d.name, d.unit, d.long_name)
                                                                         for d in o.extra_dims], o.name
    # the old outputs keep their order; the layer adds Steady's first harmonic, Floquet's kind and angle
    old_names = K.SPEC.output_names()
    assert tuple(x for x in new.output_names() if x in old_names) == old_names
    assert sorted(set(new.output_names()) - set(old_names)) == [
        "floquet_max_angle", "floquet_max_kind", "residual_amplitude_h1", "residual_amplitude_phase"]
    assert new.methods == K.SPEC.methods and new.settings[:len(K.SPEC.settings)] == K.SPEC.settings
    given = {"omega_xi": (10.0,), "c_xi": (1.0,), "A1": (0.0, 0.1)}
    assert new.check(given) == K.check(given) and len(new.check(given)) == 6  # 4 pairs, l3, l4


@pytest.mark.slow  # compiles a kernel for the subset alone (the comparison): about a minute cold
def test_the_one_sampled_kernel_gives_a_subset_what_its_own_kernel_gives(monkeypatch):
    # the model's one sampled-trajectory kernel (Kick, Steady, four Histories; the asked-for ones
    # chosen per call) against a kernel compiled for the subset alone, as before: residual_amplitude
    # and xi_history with the re-check (the Kick observed for its skip_settled rule without its
    # classify, the lock test, measured units) and without it; values, statuses, counts bitwise
    import functools

    from mechsweep.engine import sampling as trajectory
    rec = _rec()
    P = rec.design_points()
    wanted = ("residual_amplitude", "xi_history")
    seen = set()
    for factor in (1000.0, 0.0):
        kw = dict(rtol=1e-8, atol=1e-10, horizon_revolutions=rec.HORIZON, reproducibility_factor=factor)
        a = _evaluate(ab.SPEC, P, wanted, **kw)
        with monkeypatch.context() as m:
            m.setattr(trajectory, "evaluate", functools.partial(trajectory.evaluate, per_subset=True))
            b = _evaluate(ab.SPEC, P, wanted, **kw)
        for x, y in zip(a[1:], b[1:]):  # status, n_steps, n_rhs
            assert np.array_equal(x, y)
        for k in wanted:
            assert np.array_equal(a[0][k], b[0][k], equal_nan=True), k
        seen |= set(a[1].tolist())
    assert {st.OK, st.NOT_REPRODUCIBLE, st.INFEASIBLE} <= seen, seen
