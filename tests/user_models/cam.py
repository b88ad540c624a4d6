"""A closed-form user model (used by tests/model/test_closed_form.py): the rise of a cam follower.

A translating roller follower rises by h while the cam turns through the rise angle beta at
constant speed omega, by the cycloidal or the simple-harmonic law (x = theta / beta in [0, 1]):
  cycloidal: s = h (x - sin(2 pi x) / (2 pi)),  ds/dtheta = (h / beta)(1 - cos 2 pi x),
             d2s/dtheta2 = (2 pi h / beta^2) sin 2 pi x
  harmonic : s = (h / 2)(1 - cos pi x),         ds/dtheta = (pi h / (2 beta)) sin pi x,
             d2s/dtheta2 = (pi^2 h / (2 beta^2)) cos pi x
v = omega ds/dtheta, a = omega^2 d2s/dtheta2. Pressure angle of an inline follower on a cam of
base radius Rb: tan(alpha) = (ds/dtheta) / (Rb + s). A design whose largest pressure angle exceeds
alpha_max jams: status INFEASIBLE.
The maxima are taken over the n samples of the rise (the extra dimension u = x); with n = 101
they contain the extrema of both laws (x = 0, 1/4, 1/2), so they equal the closed forms
v_max = 2 h omega / beta, a_max = 2 pi h omega^2 / beta^2 (cycloidal),
v_max = pi h omega / (2 beta), a_max = pi^2 h omega^2 / (2 beta^2) (harmonic).
"""
import math

import numpy as np

from mechsweep import status as st
from mechsweep.model import ClosedFormModel, ExtraDim, Output, Param

N = 101
U = ExtraDim("u", "1", "fraction of the rise angle, theta / beta", values=lambda settings: np.linspace(0.0, 1.0, N))


def samples(n):
    """The data every design shares: the n sample points of the rise."""
    return (np.linspace(0.0, 1.0, n),)


def rise(p, want, row, curves, slot, scratch, u):
    h, beta, omega, law, rb, alpha_max = p[0], p[1], p[2], p[3], p[4], p[5]
    n = u.shape[0]
    v_max = 0.0
    a_max = 0.0
    tan_max = 0.0
    for j in range(n):
        x = u[j]
        if law == 0.0:  # cycloidal
            s = h * (x - math.sin(2.0 * math.pi * x) / (2.0 * math.pi))
            ds = h / beta * (1.0 - math.cos(2.0 * math.pi * x))
            dds = 2.0 * math.pi * h / (beta * beta) * math.sin(2.0 * math.pi * x)
        else:  # simple harmonic
            s = 0.5 * h * (1.0 - math.cos(math.pi * x))
            ds = math.pi * h / (2.0 * beta) * math.sin(math.pi * x)
            dds = math.pi * math.pi * h / (2.0 * beta * beta) * math.cos(math.pi * x)
        a = dds * omega * omega
        v_max = max(v_max, abs(ds * omega))
        a_max = max(a_max, abs(a))
        tan_max = max(tan_max, ds / (rb + s))
        scratch[0, j] = a
        if slot[0] >= 0:
            curves[slot[0], j] = s
    if math.atan(tan_max) > alpha_max:
        return st.INFEASIBLE  # the follower jams
    row[0] = v_max
    row[1] = a_max
    row[2] = math.atan(tan_max)
    if slot[1] >= 0:
        for j in range(n):
            curves[slot[1], j] = scratch[0, j]
    return st.OK


CAM = ClosedFormModel(
    name="cam_rise",
    description="rise of a translating roller follower: cycloidal or simple-harmonic law",
    params=(
        Param("h", "h", "m", "lift", lo=0.0, lo_open=True),
        Param("beta", "β", "rad", "rise angle", lo=0.0, hi=2.0 * math.pi, lo_open=True),
        Param("omega", "ω", "rad/s", "cam speed", lo=0.0, lo_open=True),
        Param("law", "law", "1", "motion law", choices=("cycloidal", "harmonic"), required=False, default=0.0),
        Param("rb", "R_b", "m", "base radius", lo=0.0, lo_open=True, required=False, default=0.05),
        Param("alpha_max", "α_max", "rad", "largest allowed pressure angle", lo=0.0, hi=math.pi / 2,
              lo_open=True, required=False, default=math.pi / 6),
    ),
    outputs=(
        Output("v_max", "v_max", "m/s", "largest follower speed over the rise"),
        Output("a_max", "a_max", "m/s^2", "largest |follower acceleration| over the rise"),
        Output("pressure_angle_max", "α", "rad", "largest pressure angle over the rise"),
        Output("s_u", "s", "m", "follower displacement", extra_dims=(U,)),
        Output("a_u", "a", "m/s^2", "follower acceleration", extra_dims=(U,)),
    ),
    compute=rise,
    size=N,
    data=samples,
    scratch=1,
)
