"""How late in its step budget a stiff integration shows it: ``python tests/data/stiff_window.py``.

Plain dop853 runs Hairer's stiffness test only on the last ode.dop853.STIFF_WINDOW attempts of its
step budget and reports STIFF instead of MAX_STEPS when the test counts STIFF_STEPS there. This
script integrates points attempt by attempt with dop853's own start and step (the solvers' floats),
computes the test's quotient h |f(y_new) - f(y_s)| / |y_new - y_s| on every accepted step, and prints
for windows of the last W attempts of a spent budget: the accepted steps, those above the threshold,
and the largest count of the test (its counters from zero at the window's start, as the solvers run
them). Points (the default solver settings, rtol 5e-11, atol 1e-12, max_steps 100,000):
- the auto-balancer's simulation (sweeps/extreme/autobalancer_damping_range.toml's fixed values,
  Omega = 25 rad/s, 300 revolutions, the 0.1 rad perturbation) at h / (m a^2 Omega) = 1e3 and 1e4
  (stiff), and the platform damping ratio zeta = 50 at h = 0.02 (not stiff: the steps are set by
  accuracy, the test stays quiet);
- x'' + 2 zeta w x' + w^2 x = 0 from (1, 0), w = 1, zeta = 5, to t = 1e5 (stiff once it has decayed).
Numbers from it: the comment of ode/dop853.py's STIFF_WINDOW.
"""
import math
import sys
from pathlib import Path

import numpy as np

from mechsweep import status as st
from mechsweep._jit import jit
from mechsweep.models.autobalancer import scaled_rhs
from mechsweep.ode import dop853 as d

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: tests.reference
from tests.reference import autobalancer_kernels as ab  # noqa: E402

BUDGET = 100_000
WINDOWS = (100, 200, 500, 1000, 5000)


@jit
def oscillator_rhs(t, y, p, dy):
    dy[0] = y[1]
    dy[1] = -2.0 * p[1] * p[0] * y[1] - p[0] * p[0] * y[0]


def tracer(rhs):
    start, advance = d._make_start(rhs), d._make_advance(rhs)

    @jit
    def trace(y, p, t_end, rtol, atol, budget, work, accepted, quotient):
        """Every attempt of the budget (one per advance): accepted or not, and the quotient."""
        status, h_abs, _ = start(0.0, y, p, t_end, rtol, atol, 0.0, work)
        t = 0.0
        k = 0
        while status == st.OK and t < t_end and k < budget:
            status, t_new, h_abs, _ = advance(t, y, p, t_end, h_abs, rtol, atol, work, 1)
            if status == st.MAX_STEPS:  # this attempt was rejected
                status = st.OK
                accepted[k] = 0
                k += 1
                continue
            if status != st.OK:
                break
            num = 0.0
            den = 0.0
            for i in range(y.size):
                num += (work[d.K_FSAL, i] - work[d.N_STAGES - 1, i]) ** 2
                den += (work[d.Y_NEW, i] - work[d.Y_STAGE, i]) ** 2
            quotient[k] = abs(t_new - t) * math.sqrt(num / den) if den > 0.0 else 0.0
            accepted[k] = 1
            d._commit(y, work)
            t = t_new
            k += 1
        return k, t

    return trace


def count(quotients) -> int:
    """The largest value of Hairer's stiff-step counter over these accepted steps."""
    stiff = nonstiff = best = 0
    for q in quotients:
        if q > d.STIFF_H_LAMBDA:
            stiff, nonstiff = stiff + 1, 0
        else:
            nonstiff += 1
            if nonstiff >= d.NONSTIFF_RESET:
                stiff = 0
        best = max(best, stiff)
    return best


def report(name, rhs, y, p, t_end, rtol=5e-11, atol=1e-12):
    accepted = np.zeros(BUDGET, np.int64)
    quotient = np.full(BUDGET, np.nan)
    k, t = tracer(rhs)(y, p, t_end, rtol, atol, BUDGET, d.workspace(y.size), accepted, quotient)
    spent = "budget spent" if k == BUDGET else "ended"
    print(f"{name}: {spent} at t = {t:.6g} of {t_end:.6g} ({k} attempts)")
    for w in WINDOWS:
        last = slice(max(k - w, 0), k)
        q = quotient[last][accepted[last] == 1]
        print(f"  last {w:5d} attempts: {accepted[last].sum():5d} accepted, {(q > d.STIFF_H_LAMBDA).sum():5d} above "
              f"{d.STIFF_H_LAMBDA}, largest count {count(q)}")


def autobalancer(h, zeta=0.05, Omega=25.0):
    M, m, a, I_B, A0, om_xi, om_eta = 20.0, 1.0, 0.1, 0.012, 0.1, 20.0, 30.0
    theta = math.acos(-A0 / (2.0 * m * a))
    p = ab.scaled_parameters(Omega, M, m, a, I_B, A0, 0.0, 0.0, M * om_xi**2, M * om_eta**2, 2 * zeta * M * om_xi,
                             2 * zeta * M * om_eta, h, theta, -theta)
    y = np.empty(8)
    ab.initial_state(p, 0.1, y)
    return y, p


def main():
    for h in (250.0, 2500.0):
        y, p = autobalancer(h)
        report(f"auto-balancer, h / (m a^2 Omega) = {h / 0.25:g}", scaled_rhs, y, p, 2 * math.pi * 300)
    y, p = autobalancer(0.02, zeta=50.0)
    report("auto-balancer, zeta = 50, h = 0.02", scaled_rhs, y, p, 2 * math.pi * 300)
    report("x'' + 2 zeta w x' + w^2 x = 0, w = 1, zeta = 5", oscillator_rhs, np.array([1.0, 0.0]),
           np.array([1.0, 5.0]), 1e5)


if __name__ == "__main__":
    main()
