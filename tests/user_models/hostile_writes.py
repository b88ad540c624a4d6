"""Models whose functions write into an argument their role may not write (tests/model/test_model_writes.py,
tests/hostile/model_*.toml): each must be refused when loaded, naming the function, the argument
and the line. A bouncing ball y'' = -g from y = h at rest; its events look for the apex (v from
> 0 to <= 0 after the bounce); EVENT_WRITES_STATE bounces by writing the state in its event, behind
the integrator's back: it was accepted, and its apex times came out wrong with status ok."""
import math  # tests/test_hostile_scenes.py names lines of this file: add new models at its end

import numba
import numpy as np

import hostile_helpers
from hostile_helpers import hidden, negate
from mechsweep.model import (ClosedForm, ClosedFormModel, Extremum, FirstEvent, Floquet, History, Invariant, Kick,
                             OdeModel, Output, Param, Steady, System)

PARAMS = (Param("g", "g", "m s-2", "gravity", lo=0.0, lo_open=True, required=False, default=9.81),
          Param("h", "h", "m", "drop height", lo=0.0, lo_open=True, required=False, default=1.0),
          Param("e", "e", "1", "restitution", lo=0.0, hi=1.0, required=False, default=0.8))


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0]


def initial(p, y0):
    y0[0] = p[1]
    y0[1] = 0.0


def apex(t, y, p):
    return y[1]


def bouncing_apex(t, y, p):
    if y[0] <= 0.0 and y[1] < 0.0:
        y[1] = -p[2] * y[1]  # the bounce, written into the integrator's state
    return y[1] + 1e-300


def aliased_event(t, y, p):
    z = y
    if z[0] < 0.0:
        z[0] = 0.0
    return y[1]


def helper_event(t, y, p):
    if y[0] < 0.0:
        negate(y, 1)
    return y[1]


def module_helper_event(t, y, p):
    if y[0] < 0.0:
        hostile_helpers.negate(y, 1)
    return y[1]


def hidden_helper_event(t, y, p):
    hidden(y)
    return y[1]


@numba.njit
def jitted_event(t, y, p):
    y[0] = max(y[0], 0.0)
    return y[1]


def rhs_writes_p(t, y, p, dydt):
    p[0] += 1e-9 * t
    dydt[0] = y[1]
    dydt[1] = -p[0]


def rhs_writes_state(t, y, p, dydt):
    np.copyto(y, np.maximum(y, -1.0))
    dydt[0] = y[1]
    dydt[1] = -p[0]


def energy_fill(t, y, p):
    y[:] = np.abs(y)
    return 0.5 * y[1] * y[1] + p[0] * y[0]


def kick_error(t, y, p):
    y.fill(0.0)
    return 0.0


def value_writes_p(p, t):
    q = p[2:]
    q[0] = t
    return t


def prepare_writes_parameter(p, rtol):
    p[0] = 2.0 * p[0]  # the gravity doubled: a parameter, not an internal slot
    p[3] = 1.0
    return 0


def prepare_writes_through_view(p, rtol):
    q = p[0:]
    q[1] = 0.5 * q[1]
    q[3] = 1.0
    return 0


def classify_writes_p(p):
    p[2] = min(p[2], 1.0)
    return 0


def forcing_writes_p(p):
    np.negative(p, p)
    return 1.0


def closed_writes_p(p):
    p[1] = 0.0
    return math.sqrt(2.0 * p[1] / p[0])


def floquet_initial_writes_p(p, y0):
    y0[0] = p[1]
    y0[1] = 0.0
    p[0] = 1.0


def system_rhs_writes_state(t, y, p, dydt):
    y[1] = min(y[1], 10.0)
    dydt[0] = y[1]
    dydt[1] = -p[0]


def jac_writes_state(t, y, p, J):
    J[0, 0], J[0, 1], J[1, 0], J[1, 1] = 0.0, 1.0, 0.0, 0.0
    y += 0.0


def variational_writes_phi(t, Phi, p, dPhi):
    Phi[0] = 1.0
    for c in range(2):
        dPhi[2 * c] = Phi[2 * c + 1]
        dPhi[2 * c + 1] = 0.0


def period(p):
    return 1.0


def _ball(name, event=apex, **kw):
    measurements = kw.pop("measurements", (FirstEvent("apex", event, t_max=10.0),))
    return OdeModel(name=name, description="a ball dropped from rest", params=PARAMS, states=("y", "v"),
                    rhs=kw.pop("rhs", rhs), initial=initial, measurements=measurements, **kw)


EVENT_WRITES_STATE = _ball("ball_event_writes_state", bouncing_apex)
EVENT_WRITES_ALIAS = _ball("ball_event_alias", aliased_event)
EVENT_SAME_FILE_HELPER = _ball("ball_event_helper", helper_event)
EVENT_MODULE_HELPER = _ball("ball_event_module_helper", module_helper_event)
EVENT_HIDDEN_HELPER = _ball("ball_event_hidden_helper", hidden_helper_event)
EVENT_JITTED = _ball("ball_event_jitted", jitted_event)
RHS_WRITES_P = _ball("ball_rhs_writes_p", rhs=rhs_writes_p)
RHS_WRITES_STATE = _ball("ball_rhs_writes_state", rhs=rhs_writes_state)
EXPRESSION_WRITES_STATE = _ball("ball_expression", measurements=(Extremum("e_max", energy_fill, 0.0, 1.0),))
KICK_ERROR_WRITES_STATE = _ball("ball_kick", measurements=(Kick("settles", kick_error, horizon=2.0),))
VALUE_WRITES_P = _ball("ball_value", measurements=(FirstEvent("apex", apex, t_max=10.0, value=value_writes_p),))
PREPARE_WRITES_PARAMETER = _ball("ball_prepare_parameter", internal=("s",), prepare=prepare_writes_parameter)
PREPARE_WRITES_THROUGH_VIEW = _ball("ball_prepare_view", internal=("s",), prepare=prepare_writes_through_view)
CLASSIFY_WRITES_P = _ball("ball_classify", classify=classify_writes_p)
FORCING_WRITES_P = _ball("ball_forcing", forcing_period=forcing_writes_p)
CLOSED_FORM_WRITES_P = _ball("ball_closed_form", closed_forms=(ClosedForm("t_fall", closed_writes_p),))
FLOQUET_INITIAL_WRITES_P = _ball("ball_floquet_initial", forcing_period=period,
                                 measurements=(Floquet("mu", initial=floquet_initial_writes_p),))
SYSTEM_RHS_WRITES_STATE = _ball("ball_system", measurements=(
    FirstEvent("apex", apex, t_max=10.0, system=System(system_rhs_writes_state, initial)),))
JAC_WRITES_STATE = _ball("ball_jac", jac=jac_writes_state)
VARIATIONAL_WRITES_PHI = _ball("ball_variational", forcing_period=period,
                               measurements=(Floquet("mu", variational=variational_writes_phi),))


# a closed-form model whose compute writes into its shared data
def rise(p, want, row, curves, slot, scratch, u):
    u[0] = p[0]
    row[0] = u[-1] * p[0]
    return 0


def samples(n):
    return (np.linspace(0.0, 1.0, n),)


COMPUTE_WRITES_DATA = ClosedFormModel(
    name="rise_writes_data", description="a lift that writes into the shared samples",
    params=(Param("h", "h", "m", "lift", lo=0.0, lo_open=True),),
    outputs=(Output("top", "top", "m", "top of the lift"),), compute=rise, size=5, data=samples)


# one more model per role: each function that may write nothing, writing into y or p
def steady_of_writes_state(t, y, p):
    y[0] = abs(y[0])
    return y[0]


def kick_response_writes_p(t, y, p):
    p[1] = 0.5 * p[1]
    return abs(y[1])


def window_start_writes_p(p):
    p[2] += 0.0
    return 0.0


def switch_times_writes_p(p):
    p[0] = 9.81
    return (0.25, 0.75)


def step_writes_p(p, rtol):
    p[1] = 1.0
    return 0.01


def accel(t, q, p, a):
    a[0] = -p[0]


def system_prepare_writes_parameter(p, rtol):
    p[2] = 1.0
    return 0


def measurement_classify_writes_p(p):
    p[1] = max(p[1], 0.1)
    return 0


def one(p):
    return 1.0


def closed_classify_writes_p(p):
    p[:] = 1.0
    return 0


def variational(t, Phi, p, dPhi):
    for c in range(2):
        dPhi[2 * c] = Phi[2 * c + 1]
        dPhi[2 * c + 1] = 0.0


def variational_jac_sorts_phi(t, Phi, p, JJ):
    JJ[:, :] = 0.0
    Phi.sort()


def energy_writes_state(y, p):
    y[1] = 0.0
    return p[0] * y[0]


STEADY_OF_WRITES_STATE = _ball("ball_steady", forcing_period=period,
                               measurements=(Steady("peak", steady_of_writes_state, horizon=2.0),))
HISTORY_OF_WRITES_STATE = _ball("ball_history", forcing_period=period,
                                measurements=(History("y_t", steady_of_writes_state, horizon=2.0, samples=3),))
KICK_RESPONSE_WRITES_P = _ball("ball_kick_response", measurements=(
    Kick("settles", "y", response=kick_response_writes_p, horizon=2.0),))
WINDOW_WRITES_P = _ball("ball_window", measurements=(Extremum("y_max", "y", window_start_writes_p, 1.0),))
SWITCH_TIMES_WRITES_P = _ball("ball_switch_times", forcing_period=period, switch_times=switch_times_writes_p)
SYMPLECTIC_STEP_WRITES_P = _ball("ball_symplectic", accel=accel, symplectic_step=step_writes_p)
SYSTEM_PREPARE_WRITES_PARAMETER = _ball("ball_system_prepare", internal=("s",), measurements=(
    FirstEvent("apex", apex, t_max=10.0, system=System(rhs, initial, prepare=system_prepare_writes_parameter)),))
MEASUREMENT_CLASSIFY_WRITES_P = _ball("ball_measurement_classify", measurements=(
    FirstEvent("apex", apex, t_max=10.0, classify=measurement_classify_writes_p),))
CLOSED_CLASSIFY_WRITES_P = _ball("ball_closed_classify",
                                 closed_forms=(ClosedForm("one", one, classify=closed_classify_writes_p),))
VARIATIONAL_JAC_WRITES_PHI = _ball("ball_variational_jac", forcing_period=period, measurements=(
    Floquet("mu", variational=variational, variational_jac=variational_jac_sorts_phi),))
INVARIANT_WRITES_STATE = _ball("ball_invariant", invariant=Invariant(energy_writes_state, at={"e": 0.5}))
