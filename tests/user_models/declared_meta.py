"""A user model that names its multi-output measurements' outputs itself (``output_meta``) and
refuses a combination of parameters (``check``), written as a user would.

RENAMED: y' = -lam y from y0 (tests/user_models/forced.py's DECAY) with a Kick, a Steady, a History
and a Floquet whose outputs carry the declaration's names, symbols, units and long names; its
``check`` refuses a growing motion (lam < 0) started above y0 = 1.
"""
from mechsweep.model import ClosedForm, Floquet, History, Kick, OdeModel, Param, Steady


def rhs(t, y, p, dydt):
    dydt[0] = -p[0] * y[0]


def initial(p, y0):
    y0[0] = p[1]


def error(t, y, p):
    return abs(y[0])


def period(p):
    return 1.0


def kind_squared(p, kind):
    return kind * kind


def check(given):
    """lam < 0 (growing) only with y0 <= 1."""
    growing = [v for v in given.get("lam", ()) if v < 0.0]
    big = [v for v in given.get("y0", ()) if v > 1.0]
    if growing and big:
        return [f"y0: {big[-1]:g} > 1 with lam = {growing[0]:g} < 0; a growing motion (lam < 0) must start at "
                "y0 <= 1"]
    return []


KICK = dict(horizon=40.0, settle_threshold=0.01, monitor_per_period=8, dense_per_period=64)
RENAMED = OdeModel(
    name="decay_renamed",
    description="y' = -lam y from y0, its outputs named by the declaration",
    params=(Param("lam", "lam", "1/s", "decay rate"),
            Param("y0", "y0", "1", "kick", lo=0.0, lo_open=True)),
    states=("y",), rhs=rhs, initial=initial, forcing_period=period, check=check,
    measurements=(
        Kick("stable_sim", error, **KICK, output_meta={
            "stable_sim": dict(symbol="stable (simulation)", long_name="1 if the kick decays"),
            "stable_sim_settling": dict(name="settling_time", long_name="time until |y| < 0.01"),
            "stable_sim_final": dict(name="final_error", symbol="|y(end)|", unit="1")}),
        Steady("peak", "y", horizon=40.0, window=0.1, samples_per_period=8, settle_rtol=None, output_meta={
            "peak_h1": dict(name="peak_harmonic"), "peak_phase": dict(name="peak_lag", unit="degree")}),
        History("y_hist", "y", horizon=40.0, samples=9, dim="time", dim_long_name="time t",
                output_meta={"y_hist": dict(symbol="y(t)")}),
        Floquet("mu", stable_name="mu_stable_old", output_meta={
            "mu_kind": dict(name="mu_crit_kind"), "mu_angle": dict(name="mu_crit_angle", symbol="θ")}),
    ),
    closed_forms=(ClosedForm("kind_sq", kind_squared, needs=("mu_crit_kind",)),),
)
