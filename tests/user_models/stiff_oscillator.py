"""A damped oscillator driven slowly, started on its steady motion (tests/engine/test_stiff.py):
x'' + 2 zeta w x' + w^2 x = F cos(W t), p = (w, zeta, F, W), x(0), x'(0) on
x = A cos(W t - phi), A = F / sqrt((w^2 - W^2)^2 + (2 zeta w W)^2), phi = atan2(2 zeta w W, w^2 - W^2),
so x(t) is that closed form at every t. With W << w the motion is slow while the free modes decay at
w (zeta -/+ sqrt(zeta^2 - 1)) (zeta >= 1): at zeta = 5 an explicit step is held at the stability limit
of the fast mode (about 6.4 / (9.9 w)) for the whole slow period, a stiff problem. Outputs on every
integration route: ``t_down`` (a lone first Crossing: the one-point kernel or the lanes), ``x_hist``
(History: the sampled trajectory), ``x_at`` (StateAt: the shared trajectory) and ``mu`` (Floquet:
the largest multiplier exp(-w (zeta - sqrt(zeta^2 - 1)) T), T = 2 pi / W, for zeta >= 1)."""
import math

from mechsweep.model import Crossing, Floquet, History, OdeModel, Param, StateAt


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = p[2] * math.cos(p[3] * t) - 2.0 * p[1] * p[0] * y[1] - p[0] * p[0] * y[0]


def steady(w, zeta, F, W):
    """(A, phi) of the steady motion x = A cos(W t - phi)."""
    return F / math.hypot(w * w - W * W, 2.0 * zeta * w * W), math.atan2(2.0 * zeta * w * W, w * w - W * W)


def initial(p, y0):
    w, zeta, F, W = p[0], p[1], p[2], p[3]
    A = F / math.hypot(w * w - W * W, 2.0 * zeta * w * W)
    phi = math.atan2(2.0 * zeta * w * W, w * w - W * W)
    y0[0] = A * math.cos(phi)
    y0[1] = A * W * math.sin(phi)


def period(p):
    return 2.0 * math.pi / p[3]


STIFF_OSCILLATOR = OdeModel(
    name="stiff_oscillator",
    description="x'' + 2 zeta w x' + w^2 x = F cos(W t), started on its steady motion",
    params=(Param("w", "w", "rad/s", "natural frequency", lo=0.0, lo_open=True),
            Param("zeta", "zeta", "1", "damping ratio", lo=0.0),
            Param("F", "F", "m/s^2", "forcing amplitude"),
            Param("W", "W", "rad/s", "forcing frequency", lo=0.0, lo_open=True)),
    states=("x", "v"),
    rhs=rhs,
    initial=initial,
    forcing_period=period,
    measurements=(
        Crossing("t_down", "x", level=0.0, direction="down", t_max=1e7),
        History("x_hist", "x", horizon=0.5, samples=3),
        StateAt("x_at", "x", t=2e5),
        Floquet("mu"),
    ),
)
