"""The shared trajectory (engine/shared.py ``make_shared``) called directly with a two-state rhs."""
import math

import numpy as np

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
