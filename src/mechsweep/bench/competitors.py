"""Other solvers on the Duffing quarter period, for `mechsweep bench duffing`: scipy always,
numbalsoda and diffrax when installed (``pip install mechsweep[compare]``).

Every competitor integrates the scaled equation x'' = -a x - b x^3 from x = 1, x' = 0 to the first
zero of x (a quarter period, tau_q; T = 4 tau_q / w), as the mechsweep kernel does, and returns
(T, ok) for given parameter rows (omega, mu, A):

- scipy: ``solve_ivp(method="DOP853")`` with a terminal event, one point at a time, one core.
- numbalsoda (the strongest driver of it we know, the one the bench's verdict uses): Hairer's
  DOP853 in Fortran through its ``dop853`` function, which has no events, with Henon's trick for
  the crossing, called from a ``numba.prange`` loop (rhs as ``cfunc`` pointers, parameters through
  the data array): all numba threads. Per point, one call integrates x'' = -a x - b x^3 to
  tau = pi/2, which is never past the crossing for a hard spring (a, b >= 0, a + b = 1: the
  restoring force a x + b x^3 is at most x for |x| <= 1, so the quarter period is at least the
  linear one, pi/2); a second call integrates the rest of the quarter with x as the independent
  variable (Henon 1982: dt/dx = 1/v, dv/dx = (-a x - b x^3)/v, from x(pi/2) to x = 0, where the
  velocity is far from 0), so the crossing time is the end of an ordinary integration, as
  accurate as the integration itself.
- numbalsoda_event: its ``solve_ivp`` (the same DOP853, with a terminal event located by Brent's
  method on the dense output) in the same prange loop. Its root finder's absolute tolerance is
  fixed at 1e-8 in its Fortran source, so its period error stops at about 1e-9 whatever the rtol:
  the bench prints it to show that, and matches it the other way (mechsweep loosened to its error).
- diffrax: ``diffeqsolve`` with Tsit5, a PID step-size controller and an ``Event`` on x (root by
  optimistix's Newton on the dense interpolant), ``jax.vmap`` over the points and ``jax.jit``
  (float64), on the CPU: XLA's own threads.
"""
from __future__ import annotations

import functools
import math

import numpy as np


def scaled(P):
    """(a, b, w) of the scaled equation per row (omega, mu, A), as models/duffing.py's plain
    formulation (the grid of the bench has hard springs only)."""
    omega, mu, A = P[:, 0], P[:, 1], P[:, 2]
    w2 = omega**2 + np.abs(mu) * A**2
    return omega**2 / w2, mu * A**2 / w2, np.sqrt(w2)


def available() -> dict[str, bool]:
    out = {}
    for name in ("numbalsoda", "numbalsoda_event", "diffrax"):
        try:
            __import__(PACKAGE.get(name, name))
            out[name] = True
        except Exception:  # not installed, or broken: the bench says so
            out[name] = False
    return out


def scipy_periods(P, rtol, atol):
    from scipy.integrate import solve_ivp

    a, b, w = scaled(P)
    T = np.full(P.shape[0], np.nan)
    for i in range(P.shape[0]):
        def rhs(t, y, a=a[i], b=b[i]):
            return [y[1], -a * y[0] - b * y[0] ** 3]

        def crossing(t, y):
            return y[0]

        crossing.terminal = True
        crossing.direction = -1
        sol = solve_ivp(rhs, (0.0, 200 * math.pi), [1.0, 0.0], method="DOP853", rtol=rtol, atol=atol,
                        events=crossing)
        if sol.status == 1:
            T[i] = 4.0 * sol.t_events[0][0] / w[i]
    return T


@functools.cache  # compiled once; the cfuncs stay alive with it
def _numbalsoda_kernel():
    import numba
    from numba import cfunc
    from numbalsoda import lsoda_sig, solve_ivp

    @cfunc(lsoda_sig)
    def rhs(t, u, du, p):
        du[0] = u[1]
        du[1] = -p[0] * u[0] - p[1] * u[0] * u[0] * u[0]

    @cfunc(lsoda_sig)
    def event(t, u, e, p):
        e[0] = u[0]

    rhs_ptr, event_ptr = rhs.address, event.address

    @numba.njit(parallel=True)
    def kernel(ab, rtol, atol, tq):
        span = np.array([0.0, 200.0 * np.pi])
        y0 = np.array([1.0, 0.0])
        none = np.empty(0)
        for i in numba.prange(ab.shape[0]):
            d = np.empty(2)
            d[0] = ab[i, 0]
            d[1] = ab[i, 1]
            sol = solve_ivp(rhs_ptr, span, y0, none, "DOP853", np.int32(1), event_ptr, d.ctypes.data, 0.0, 0.0,
                            rtol, atol)
            tq[i] = sol.t_event if (sol.success and sol.event_found) else np.nan

    return kernel, rhs, event


def numbalsoda_event_periods(P, rtol, atol):
    kernel = _numbalsoda_kernel()[0]
    a, b, w = scaled(P)
    tq = np.empty(P.shape[0])
    kernel(np.ascontiguousarray(np.column_stack([a, b])), rtol, atol, tq)
    return 4.0 * tq / w


@functools.cache  # compiled once; the cfuncs stay alive with it
def _numbalsoda_henon_kernel():
    import numba
    from numba import cfunc
    from numbalsoda import dop853, lsoda_sig

    @cfunc(lsoda_sig)
    def rhs(t, u, du, p):  # x'' = -a x - b x^3; p = (a, b)
        du[0] = u[1]
        du[1] = -p[0] * u[0] - p[1] * u[0] * u[0] * u[0]

    @cfunc(lsoda_sig)
    def henon(s, u, du, p):  # u = (t, v) against s, x = x1 - sigma s; p = (a, b, sigma, x1)
        x = p[3] - p[2] * s
        du[0] = -p[2] / u[1]  # dt/ds = (dt/dx)(dx/ds), dt/dx = 1 / v
        du[1] = -p[2] * (-p[0] * x - p[1] * x * x * x) / u[1]  # dv/ds = (dv/dx)(dx/ds), dv/dx = x'' / v

    rhs_ptr, henon_ptr = rhs.address, henon.address

    @numba.njit(parallel=True)
    def kernel(ab, rtol, atol, tq):
        # dop853 writes the state at each time of t_eval as its steps pass it, and integrates to the
        # last one; where its last step's end x + (xend - x) rounds below xend, the last row is never
        # written (garbage, with success: 80 of the bench's 19,910 points). So each call asks for one
        # time just past the one it needs, which every step then passes.
        past = 1.0 + 1e-6
        first = np.array([0.0, 0.5 * np.pi, 0.5 * np.pi * past])  # pi/2: never past a hard spring's quarter
        for i in numba.prange(ab.shape[0]):
            d = np.empty(4)
            d[0] = ab[i, 0]
            d[1] = ab[i, 1]
            y0 = np.array([1.0, 0.0])
            u, ok = dop853(rhs_ptr, y0, first, d, rtol, atol)
            x1, v1 = u[1, 0], u[1, 1]
            if not ok or v1 == 0.0:
                tq[i] = np.nan
                continue
            if x1 == 0.0:
                tq[i] = first[1]
                continue
            d[2] = 1.0 if x1 > 0.0 else -1.0
            d[3] = x1
            u0 = np.array([first[1], v1])
            span = np.array([0.0, abs(x1), abs(x1) * past])
            w, ok = dop853(henon_ptr, u0, span, d, rtol, atol)
            tq[i] = w[1, 0] if ok else np.nan

    return kernel, rhs, henon


def numbalsoda_periods(P, rtol, atol):
    """numbalsoda's dop853 with Henon's trick for the crossing (the module docstring)."""
    kernel = _numbalsoda_henon_kernel()[0]
    a, b, w = scaled(P)
    if (b < 0).any():
        raise ValueError("the numbalsoda driver's first leg to pi/2 holds for hard springs (mu >= 0) only")
    tq = np.empty(P.shape[0])
    kernel(np.ascontiguousarray(np.column_stack([a, b])), rtol, atol, tq)
    return 4.0 * tq / w


@functools.cache  # one traced solver per tolerance pair
def _diffrax_solver(rtol, atol):
    import jax

    jax.config.update("jax_enable_x64", True)
    import diffrax
    import jax.numpy as jnp
    import optimistix as optx

    def field(t, y, args):
        a, b = args
        return jnp.stack([y[1], -a * y[0] - b * y[0] ** 3])

    def cond(t, y, args, **kwargs):
        return y[0]

    event = diffrax.Event(cond, root_finder=optx.Newton(rtol=1e-14, atol=1e-14))

    def one(a, b):
        sol = diffrax.diffeqsolve(diffrax.ODETerm(field), diffrax.Tsit5(), 0.0, 200.0 * math.pi, None,
                                  jnp.array([1.0, 0.0]), args=(a, b),
                                  stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol), event=event,
                                  saveat=diffrax.SaveAt(t1=True), max_steps=65536, throw=False)
        found = sol.result == diffrax.RESULTS.event_occurred
        return jnp.where(found, sol.ts[-1], jnp.nan)

    return jax.jit(jax.vmap(one))


def diffrax_periods(P, rtol, atol):
    solver = _diffrax_solver(rtol, atol)
    a, b, w = scaled(P)
    tq = np.asarray(solver(a, b))
    return 4.0 * tq / w


FUNCTIONS = {"scipy": scipy_periods, "numbalsoda": numbalsoda_periods, "numbalsoda_event": numbalsoda_event_periods,
             "diffrax": diffrax_periods}
PACKAGE = {"numbalsoda_event": "numbalsoda"}  # the package a competitor needs, where it is not its name
