"""Floquet multipliers in the one-point kernel (model/measure.py ``Floquet``): the monodromy matrix over
one forcing period T from the variational equations, by the kernel's method (dop853, radau, auto).

Two forms: the state with its variational system, z = (y, Phi row by row), Phi' = J(t, y) Phi (J the
model's jac, or the engine's central differences of its rhs: 2 n + 1 rhs calls per evaluation, counted);
or the model's own variational system about a known orbit, z = Phi column by column (n*n equations).
radau's Newton matrix of the first form is block diagonal, J(t, y) on the state and on every column of
Phi (the second derivatives of the rhs only steer Newton's convergence, not the result); of the second,
the model's ``variational_jac`` or central differences of ``variational`` (counted).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .. import status as st
from .._jit import jit_internal, jit_into_caller
from . import equations, switches


def block(plan, m, k):
    """``block(i, p, y, rtol, atol, max_steps, ws, table, n_steps, n_rhs) -> (status, modulus)`` of
    Floquet measurement k; the kind and angle into the two columns after the modulus where it succeeds."""
    view = plan.view
    n = view.n_s
    forcing = plan.forcing
    method = plan.integrator()
    if m.variational is not None:
        N = n * n
        o_yp, o_cnt = view.scr, view.scr + 3 * N  # scratch: Phi + h, f(Phi + h), f(Phi - h), the counter
        var = view.fn(m.variational, f"variational{k}", "fill")
        var_jac = view.fn(m.variational_jac, f"variational_jac{k}", "fill2d")
        if plan.sw >= 0:
            var = switches.clamped(var, plan.sw)
            var_jac = None if var_jac is None else switches.clamped(var_jac, plan.sw)
        fd = var_jac is None and method.jacobian
        if var_jac is None:
            var_jac = equations.fd_jacobian(var, N, o_yp, True)
        eq = equations.Equation(var, N, var_jac)
        run = method.plain_pass(eq, _identity_start(n))
        return _columns(_known(run, method.workspace(N), forcing, n, o_cnt if fd else -1), plan.cols[k])
    N = n + n * n
    o_yp, o_J = view.scr, view.scr + 3 * n
    model_eq = plan.equation()
    has_jac = plan.model.jac is not None
    jac = model_eq.jac if has_jac else equations.fd_jacobian(model_eq.rhs, n, o_yp, False)
    var_rhs = _var_rhs(model_eq.rhs, jac, n, o_J)
    var_jac = _var_jac(jac, n, o_J, -1 if has_jac else o_J + n * n)
    eq = equations.Equation(var_rhs, N, var_jac)
    initial = plan.initial if m.initial is None else view.fn(m.initial, f"initial{k}", "initial")
    run = method.plain_pass(eq, _state_start(initial, n))
    per_eval = 1 if has_jac else 2 * n + 1
    counter = o_J + n * n if not has_jac and method.jacobian else -1
    return _columns(_full(run, method.workspace(N), forcing, n, per_eval, counter), plan.cols[k])


@functools.cache
def _identity_start(n):
    @jit_into_caller
    def start(p, z):
        z[:] = 0.0
        for i in range(n):
            z[i * n + i] = 1.0

    return start


@functools.cache
def _state_start(initial, n):
    """z = (y(0), I): the state from ``initial``, Phi the identity."""
    @jit_into_caller
    def start(p, z):
        z[:] = 0.0
        initial(p, z[:n])
        for i in range(n):
            z[n + i * n + i] = 1.0

    return start


@functools.cache
def _var_rhs(rhs, jac, n, o_J):
    """dz = (f(t, y), J Phi), J into p[o_J:o_J + n * n] row by row."""
    @jit_internal
    def var_rhs(t, z, p, dz):
        rhs(t, z[:n], p, dz[:n])
        J = p[o_J:o_J + n * n].reshape((n, n))
        jac(t, z[:n], p, J)
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for m in range(n):
                    acc += p[o_J + i * n + m] * z[n + m * n + j]
                dz[n + i * n + j] = acc

    return var_rhs


@functools.cache
def _var_jac(jac, n, o_J, counter):
    """radau's block-diagonal Newton matrix of the variational system; ``counter`` >= 0: the 2 n rhs
    calls of the engine's differences added to p[counter]."""
    two_n = 2.0 * n

    @jit_internal
    def var_jac(t, z, p, JJ):
        J = p[o_J:o_J + n * n].reshape((n, n))
        jac(t, z[:n], p, J)
        if counter >= 0:
            p[counter] += two_n  # its rhs calls
        JJ[:, :] = 0.0
        for i in range(n):
            for m in range(n):
                JJ[i, m] = p[o_J + i * n + m]
                for j in range(n):
                    JJ[n + i * n + j, n + m * n + j] = p[o_J + i * n + m]

    return var_jac


@jit_into_caller
def _eigen(M, ns, nr):
    """The largest modulus of M's eigenvalues, the critical multiplier's kind and angle."""
    n = M.shape[0]
    lam = np.linalg.eigvals(M)
    big = -1.0
    crit = lam[0]
    for i in range(n):
        if abs(lam[i]) > big:
            big = abs(lam[i])
            crit = lam[i]
    if abs(crit.imag) <= 1e-8 * big:
        kind = 1.0 if crit.real > 0.0 else -1.0
        angle = 0.0 if crit.real > 0.0 else math.pi
    else:
        kind = 0.0
        angle = abs(math.atan2(crit.imag, crit.real))
    return st.OK, big, kind, angle, ns, nr


@functools.cache
def _full(run, new_work, forcing, n, per_eval, counter):
    N = n + n * n

    @jit_internal
    def measure(p, y, rtol, atol, max_steps):
        T = forcing(p)
        if not (math.isfinite(T) and T > 0.0):
            return st.INFEASIBLE, math.nan, math.nan, math.nan, 0, 0
        z = np.zeros(N)
        code, ns, nr = run(p, z, T, rtol, atol, max_steps, new_work())
        nr = nr * per_eval
        if counter >= 0:
            nr += int(p[counter])  # radau's Jacobians by differences
            p[counter] = 0.0
        if code != st.OK:
            return code, math.nan, math.nan, math.nan, ns, nr
        M = np.empty((n, n), dtype=np.complex128)
        for i in range(n):
            for j in range(n):
                v = z[n + i * n + j]
                if not math.isfinite(v):
                    return st.NONFINITE, math.nan, math.nan, math.nan, ns, nr
                M[i, j] = v
        return _eigen(M, ns, nr)

    return measure


@functools.cache
def _known(run, new_work, forcing, n, counter):
    N = n * n

    @jit_internal
    def measure(p, y, rtol, atol, max_steps):
        # the model's variational system about its known orbit: Phi column-major, n*n equations
        T = forcing(p)
        if not (math.isfinite(T) and T > 0.0):
            return st.INFEASIBLE, math.nan, math.nan, math.nan, 0, 0
        z = np.zeros(N)
        code, ns, nr = run(p, z, T, rtol, atol, max_steps, new_work())
        if counter >= 0:
            nr += int(p[counter])  # radau's Jacobians by differences
            p[counter] = 0.0
        if code != st.OK:
            return code, math.nan, math.nan, math.nan, ns, nr
        M = np.empty((n, n), dtype=np.complex128)
        for i in range(n):
            for j in range(n):
                v = z[j * n + i]
                if not math.isfinite(v):
                    return st.NONFINITE, math.nan, math.nan, math.nan, ns, nr
                M[i, j] = v
        return _eigen(M, ns, nr)

    return measure


@functools.cache
def _columns(measure, col):
    """The block: the integration counted; where it succeeds the kind and angle into the table's two
    columns after the modulus (the link reads them back into the value row with the modulus)."""
    @jit_into_caller
    def block(i, p, y, rtol, atol, max_steps, ws, table, n_steps, n_rhs):
        c, val, kind, angle, a, b = measure(p, y, rtol, atol, max_steps)
        n_steps[i] += a
        n_rhs[i] += b
        if c == st.OK:
            table[i, col + 1] = kind
            table[i, col + 2] = angle
        return c, val

    return block
