"""A user model for the status rules of the model layer: a measurement's own ``classify`` (where
it applies) and the model's ``status_order`` (a point's status = the most severe among those of
its asked-for outputs), written as a user would.

x'' + 2 zeta w x' + w^2 x = F cos(W t) from rest (as tests/user_models/forced.py), with:
- ``amp`` (Steady, the first-harmonic amplitude |F| / sqrt((w^2 - W^2)^2 + (2 zeta w W)^2)), which
  here applies only for F >= 0 (classify: SINGULAR for F < 0, a rule made up for the test);
- ``x_hist`` (History), which applies only below critical damping (NOT_OSCILLATORY for zeta >= 1);
- ``mu`` (Floquet: |mu| = exp(-zeta w T), T = 2 pi / W, for zeta < 1; UNDECIDED at zeta = 0),
  which applies only below critical damping (NOT_OSCILLATORY);
- ``amp_exact`` (ClosedForm), NO_MOTION for F = 0.
SEVERITY has status_order (SINGULAR > NOT_OSCILLATORY > NO_MOTION > NO_EVENT > UNDECIDED); FIRST is
the same model without it (first failure in the kernel's order).
"""
import math

from mechsweep import status as st
from mechsweep.model import ClosedForm, Floquet, History, OdeModel, Param, Setting, Steady


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = p[2] * math.cos(p[3] * t) - 2.0 * p[1] * p[0] * y[1] - p[0] * p[0] * y[0]


def initial(p, y0):
    y0[0] = 0.0
    y0[1] = 0.0


def period(p):
    return 2.0 * math.pi / p[3]


def amp_applies(p):
    return st.OK if p[2] >= 0.0 else st.SINGULAR


def underdamped(p):
    return st.OK if p[1] < 1.0 else st.NOT_OSCILLATORY


def amp_exact(p):
    return abs(p[2]) / math.hypot(p[0] * p[0] - p[3] * p[3], 2.0 * p[1] * p[0] * p[3])


def moving(p):
    return st.OK if p[2] != 0.0 else st.NO_MOTION


def _model(name, order):
    return OdeModel(
        name=name, description="forced damped oscillator with per-measurement classify",
        params=(Param("w", "w", "rad/s", "natural frequency", lo=0.0, lo_open=True),
                Param("zeta", "zeta", "1", "damping ratio", lo=0.0),
                Param("F", "F", "m/s^2", "forcing amplitude"),
                Param("W", "W", "rad/s", "forcing frequency", lo=0.0, lo_open=True)),
        states=("x", "v"), rhs=rhs, initial=initial, forcing_period=period,
        settings=(Setting("horizon_periods", 100.0, "1", "simulated forcing periods", 1.0, 1e5),),
        measurements=(
            Floquet("mu", classify=underdamped),
            Steady("amp", "x", horizon="horizon_periods", settle_rtol=None, classify=amp_applies),
            History("x_hist", "x", horizon="horizon_periods", samples=5, classify=underdamped),
        ),
        closed_forms=(ClosedForm("amp_exact", amp_exact, classify=moving),),
        status_order=order)


SEVERITY = _model("severity", (st.SINGULAR, st.NOT_OSCILLATORY, st.NO_MOTION, st.NO_EVENT, st.UNDECIDED))
FIRST = _model("severity_first", ())


# The re-check's lock test (Recheck.skip_locked): the forced oscillator with a phase ph' = 1 (it
# grows by T each forcing period: lock_rates subtract that); the kick error |x| stays above the
# settle threshold (a forced steady oscillation): never settled, so only the lock test can skip it.
def rhs3(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = p[2] * math.cos(p[3] * t) - 2.0 * p[1] * p[0] * y[1] - p[0] * p[0] * y[0]
    dydt[2] = 1.0


def initial3(p, y0):
    y0[0] = 0.0
    y0[1] = 0.0
    y0[2] = 0.0


def kick_error(t, y, p):
    return abs(y[0])


def _locked(name, **recheck):
    from mechsweep.model import Kick, Recheck
    return OdeModel(
        name=name, description="forced oscillator with a phase, the re-check's lock test",
        params=SEVERITY.params, states=("x", "v", "ph"), rhs=rhs3, initial=initial3, forcing_period=period,
        measurements=(Kick("kick", kick_error, horizon=60.0, settle_threshold=1e-3),),
        recheck=Recheck(factor=1000.0, skip_settled="kick", **recheck))


LOCKED = _locked("locked", skip_locked=True, lock_rates=(("ph", 1.0),))
UNLOCKED = _locked("unlocked", skip_locked=True)  # ph grows: never locked, always integrated again
