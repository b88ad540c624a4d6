"""The shared trajectory (engine/shared.py ``make_shared``) called directly with a two-state rhs."""
import math

import numba
import numpy as np
import pytest

from mechsweep import status as st
from mechsweep._jit import jit
from mechsweep.engine.shared import make_shared
from mechsweep.model.measure import K_CROSSING, K_EXTREMUM, K_STATE_AT
from mechsweep.ode import dop853


@jit
def _not_finite_at_start(t, y, p, out):
    out[0] = y[1]
    out[1] = math.nan  # f(0, y) is not finite: the integration fails at its first step


def test_a_failed_first_step_keeps_the_infeasible_status_of_a_window_that_is_not_one():
    # rows (kind, state, sign, level, n, t0 or horizon, t1): an Extremum whose window runs backwards
    # (INFEASIBLE before any step), a Crossing and a StateAt the failed integration leaves undone
    M = np.array([[K_EXTREMUM, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0],
                  [K_CROSSING, 0.0, 1.0, 0.5, 1.0, 10.0, 0.0],
                  [K_STATE_AT, 1.0, 1.0, 0.0, 0.0, 3.0, 0.0]])
    values, codes = np.zeros(3), np.zeros(3, dtype=np.int64)
    n_steps, n_rhs = make_shared(_not_finite_at_start)(
        np.array([1.0, 0.0]), np.zeros(1), M, 1e-6, 1e-9, 1000, dop853.workspace(2), values, codes)
    assert codes.tolist() == [st.INFEASIBLE, st.NONFINITE, st.NONFINITE]
    assert np.isnan(values).all()
    assert (n_steps, n_rhs) == (0, 1)


@jit
def _oscillator(t, y, p, out):
    out[0] = y[1]
    out[1] = -y[0]


@jit
def _down_through_zero(t, y, p):
    return y[0]


@pytest.mark.slow  # compiles two integrations outside the disk cache (about 9 s of CPU)
def test_the_stiffness_helpers_are_typed_once_whatever_integration_calls_them():
    """The step counters reach dop853's stiffness helpers as int64 from the first step: counters started
    as a literal 0 typed (and compiled) each helper a second time, for Literal[int](0). Both integrations
    are compiled here, not loaded from the disk cache, so that their calls to the helpers are typed."""
    M = np.array([[K_STATE_AT, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0]])
    values, codes = np.zeros(1), np.zeros(1, dtype=np.int64)
    numba.njit(make_shared(_oscillator).py_func)(np.array([1.0, 0.0]), np.zeros(1), M, 1e-8, 1e-10, 1000,
                                                 dop853.workspace(2), values, codes)
    assert codes[0] == st.OK and abs(values[0] - math.cos(1.0)) < 1e-7
    y = np.array([1.0, 0.0])
    status, t, _, _ = numba.njit(dop853.make_event_solver(_oscillator, _down_through_zero).py_func)(
        0.0, y, np.zeros(1), 10.0, 1e-10, 1e-12, 0.0, 1000, dop853.workspace(2))
    assert status == st.OK and abs(t - math.pi / 2) < 1e-8
    called = (dop853._tests_stiffness, dop853._stiffness_update, dop853._failure)  # typed by the compiles above
    assert all(helper.signatures for helper in called)
    for helper in called + (dop853._stiffness_count,):
        assert not [s for s in helper.signatures if "Literal[int]" in str(s)], helper
