"""Functions that write only what their role may write, in the ways that look like forbidden ones
(tests/model/test_model_writes.py: the write check finds nothing here): the output argument through an
alias, a slice or a helper, local arrays, a rebound argument name, an element read into a local
and updated in place, prepare's internal slots by index, through a view and through a helper,
arguments named otherwise than in the docs. x'' = -w^2 x from x = A at rest."""
import math

import numba
import numpy as np

from mechsweep.model import ClosedForm, ClosedFormModel, ExtraDim, FirstEvent, Floquet, OdeModel, Output, Param

W, A, W2, SIGN = 0, 1, 2, 3  # p = (w, A | w^2, sign of A)


@numba.njit
def spring(x, w2, out, k):
    out[k] = -w2 * x


@numba.njit
def fill_slots(p, at):
    p[at] = p[W] * p[W]
    p[at + 1] = 1.0 if p[A] >= 0.0 else -1.0


def rhs(time, state, params, out):
    d = out
    d[0] = state[1]
    spring(state[0], params[W2], out, 1)
    tmp = np.empty(2)
    tmp[:] = state
    tmp[0] += 1.0
    v = state[1]
    v *= 2.0


def initial(p, y0):
    y0[:] = 0.0
    y = y0
    y[0] = p[A]


def prepare(p, rtol):
    p[W2] = p[W] * p[W]
    q = p[W2:W2 + 2]
    q[1] = 1.0 if p[A] >= 0.0 else -1.0
    fill_slots(p, W2)
    return 0


def jac(t, y, p, J):
    J[:, :] = 0.0
    J[0, 1] = 1.0
    row = J[1]
    row[0] = -p[W2]


def event(t, y, p):
    z = y
    y = np.zeros(2)  # a new local array under the argument's name
    y[0] = z[0]
    return p[SIGN] * y[0]


def quarter_to_period(p, t):
    x = t
    x *= 4.0
    return x


def forcing_period(p):
    return 2.0 * math.pi / p[W]


def variational(t, Phi, p, dPhi):
    for c in range(2):
        col = dPhi[2 * c:2 * c + 2]
        col[0] = Phi[2 * c + 1]
        col[1] = -p[W2] * Phi[2 * c]


def period_exact(p):
    return 2.0 * math.pi / p[W]


ALLOWED = OdeModel(
    name="writes_allowed", description="x'' = -w^2 x from rest at x = A",
    params=(Param("w", "w", "rad s-1", "frequency", lo=0.0, lo_open=True, required=False, default=1.0),
            Param("A", "A", "m", "amplitude", required=False, default=1.0)),
    states=("x", "v"), rhs=rhs, initial=initial, jac=jac, prepare=prepare, internal=("w2", "sign"),
    forcing_period=forcing_period,
    measurements=(FirstEvent("period", event, t_max=100.0, value=quarter_to_period),
                  Floquet("mu", variational=variational)),
    closed_forms=(ClosedForm("period_exact", period_exact),),
)


# a closed-form model writing its row, curves and scratch, also through a helper
N = 5
U = ExtraDim("u", "1", "fraction", values=lambda settings: np.linspace(0.0, 1.0, N))


@numba.njit
def put(row, k, value):
    row[k] = value


def lift(p, want, row, curves, slot, scratch, u):
    for j in range(u.shape[0]):
        scratch[0, j] = p[0] * u[j]
    put(row, 0, scratch[0, -1])
    if slot[0] >= 0:
        curves[slot[0], :] = scratch[0, :]
    return 0


def samples(n):
    return (np.linspace(0.0, 1.0, n),)


ALLOWED_CLOSED = ClosedFormModel(
    name="writes_allowed_closed", description="a linear lift",
    params=(Param("h", "h", "m", "lift", lo=0.0, lo_open=True),),
    outputs=(Output("top", "top", "m", "top of the lift"), Output("s_u", "s", "m", "lift", extra_dims=(U,))),
    compute=lift, size=N, data=samples, scratch=1)
