"""User models with closed forms for the sampled-trajectory measurements (Steady, Kick, History),
written as a user would (outside the package).

FORCED: x'' + 2 zeta w x' + w^2 x = F cos(W t) from rest; the steady motion is
x = A cos(W t - phi), A = F / sqrt((w^2 - W^2)^2 + (2 zeta w W)^2), phi = atan2(2 zeta w W, w^2 - W^2).
DECAY: y' = -lam y from y0: y = y0 exp(-lam t); |y| falls below thr at t = ln(y0 / thr) / lam.
"""
import math

from mechsweep.model import Floquet, History, Kick, OdeModel, Param, Recheck, Setting, Steady


def forced_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = p[2] * math.cos(p[3] * t) - 2.0 * p[1] * p[0] * y[1] - p[0] * p[0] * y[0]


def forced_initial(p, y0):
    y0[0] = 0.0
    y0[1] = 0.0


def forced_period(p):
    return 2.0 * math.pi / p[3]


def speed(t, y, p):
    return y[1]


def _forced(**kw):
    return OdeModel(
        name="forced_oscillator",
        description="x'' + 2 zeta w x' + w^2 x = F cos(W t) from rest",
        params=(Param("w", "w", "rad/s", "natural frequency", lo=0.0, lo_open=True),
                Param("zeta", "zeta", "1", "damping ratio", lo=0.0),
                Param("F", "F", "m/s^2", "forcing amplitude"),
                Param("W", "W", "rad/s", "forcing frequency", lo=0.0, lo_open=True)),
        states=("x", "v"),
        rhs=forced_rhs,
        initial=forced_initial,
        forcing_period=forced_period,
        settings=(Setting("horizon_periods", 200.0, "1", "simulated forcing periods", 1.0, 1e5),),
        measurements=(
            Steady("amp", "x", horizon="horizon_periods", window=0.1, samples_per_period=64, unit="m"),
            Steady("speed_amp", speed, horizon="horizon_periods", settle_rtol=None, unit="m/s"),
            History("x_hist", "x", horizon="horizon_periods", samples=11, unit="m"),
        ), **kw)


FORCED = _forced()


def decay_rhs(t, y, p, dydt):
    dydt[0] = -p[0] * y[0]


def decay_initial(p, y0):
    y0[0] = p[1]


def decay_error(t, y, p):
    return abs(y[0])


def per_rate(p, t):  # a time in units of 1 / lam: the settling time ln(y0 / thr) / lam becomes ln(y0 / thr)
    return t * p[0]


def per_kick(p, x):  # a value relative to the kick y0
    return x / p[1]


DECAY = OdeModel(
    name="decay",
    description="y' = -lam y from y0: a kick that decays (lam > 0) or grows (lam < 0)",
    params=(Param("lam", "lam", "1/s", "decay rate"),
            Param("y0", "y0", "1", "kick", lo=0.0, lo_open=True)),
    states=("y",),
    rhs=decay_rhs,
    initial=decay_initial,
    measurements=(
        Kick("stable", decay_error, horizon=40.0, settle_threshold=0.01, monitor_per_period=8, dense_per_period=64),
        History("y_hist", "y", horizon=40.0, samples=9, dim="time", dim_long_name="time t"),
        # the same measurements with their values transformed per point (value / time_value)
        Kick("kick_rel", decay_error, horizon=40.0, settle_threshold=0.01, monitor_per_period=8, dense_per_period=64,
             time_value=per_rate, time_unit="1"),
        Steady("peak_rel", "y", horizon=40.0, window=0.1, samples_per_period=8, settle_rtol=None, value=per_kick),
        History("y_rel", "y", horizon=40.0, samples=9, dim="time", dim_long_name="time t", value=per_kick),
    ),
)


def cubic_rhs(t, y, p, dydt):
    dydt[0] = -y[0] * y[0] * y[0]


def cubic_initial(p, y0):
    y0[0] = p[0]


def cubic_rest(p, y0):
    y0[0] = 0.0


def cubic_jac(t, y, p, J):
    J[0, 0] = -3.0 * y[0] * y[0]


def cubic_period(p):
    return p[1]


# y' = -y^3 from y0: y = y0 / sqrt(1 + 2 y0^2 t); linearised about it, phi' = -3 y^2 phi, so the
# multiplier over [0, T] is (1 + 2 y0^2 T)^(-3/2); about the rest state y = 0 it is exactly 1.
CUBIC = OdeModel(
    name="cubic_decay",
    description="y' = -y^3; Floquet about the motion from y0 and about rest",
    params=(Param("y0", "y0", "1", "initial value"), Param("T", "T", "s", "period", lo=0.0, lo_open=True)),
    states=("y",),
    rhs=cubic_rhs,
    initial=cubic_initial,
    forcing_period=cubic_period,
    jac=cubic_jac,
    measurements=(Floquet("mu"), Floquet("mu_rest", initial=cubic_rest, stable_name="rest_stable",
                                          kind_name="rest_kind")),
)


# The reproducibility re-check (Recheck): Lorenz's equations, chaotic at rho = 28 (a peak over
# t in [27, 30] moves by O(1) between rtol and rtol / 100), a stable focus at rho = 0.5 (it does not).
def lorenz_rhs(t, y, p, dydt):
    dydt[0] = p[0] * (y[1] - y[0])
    dydt[1] = y[0] * (p[1] - y[2]) - y[1]
    dydt[2] = y[0] * y[1] - p[2] * y[2]


def lorenz_initial(p, y0):
    y0[0] = 1.0
    y0[1] = 1.0
    y0[2] = 1.0


LORENZ = OdeModel(
    name="lorenz", description="Lorenz's equations from (1, 1, 1)",
    params=(Param("sigma", "sigma", "1", "Prandtl number"), Param("rho", "rho", "1", "Rayleigh number"),
            Param("beta", "beta", "1", "geometry")),
    states=("x", "y", "z"), rhs=lorenz_rhs, initial=lorenz_initial,
    settings=(Setting("reproducibility_factor", 1000.0, "1", "0: no re-check", 0.0, 1e9),),
    measurements=(Steady("xpeak", "x", horizon=30.0, window=0.1, samples_per_period=16, settle_rtol=None),),
    recheck=Recheck(factor="reproducibility_factor"),
)

# DECAY with the re-check, skipping the points whose kick settled within the first half
DECAY_CHECKED = OdeModel(
    name="decay_checked", description="DECAY with the reproducibility re-check",
    params=DECAY.params, states=DECAY.states, rhs=decay_rhs, initial=decay_initial,
    measurements=DECAY.measurements[:1], recheck=Recheck(factor=1000.0, skip_settled="stable"),
)


def decay_fd_jac(t, y, p, J):
    # the engine's own central differences, written out: the same floats as the Jacobian the engine
    # builds for DECAY, but a declared jac, whose calls n_rhs does not count
    h = 6.055454452393343e-06 * max(1.0, abs(y[0]))
    up = y[0] + h
    dn = y[0] - h
    J[0, 0] = (-p[0] * up - -p[0] * dn) / (up - dn)


DECAY_FD_JAC = OdeModel(
    name="decay", description=DECAY.description, params=DECAY.params, states=DECAY.states, rhs=decay_rhs,
    initial=decay_initial, jac=decay_fd_jac, measurements=DECAY.measurements,
)
