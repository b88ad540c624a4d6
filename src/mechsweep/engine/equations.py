"""A kernel's view of a model: its layout of ``p``, its functions as the route calls them, and the
equations (ode/methods.py ``Equation``) the methods integrate.

The layout of ``p`` (model/ode.py): parameters, settings, internal slots (written by ``prepare``),
then the point's user-error flag ``p[npi]`` and the engine's scratch from ``scr = npi + 1``.
"""
from __future__ import annotations

import functools

from .._jit import jit_internal
from ..ode.methods import Equation
from . import calls, switches

# how a route's guard treats each kind of function (calls.py)
_GUARDS = {"fill": calls.guard_fill, "fill2d": calls.guard_fill, "initial": calls.guard_initial}


class View:
    """A model as one route's kernel sees it. ``guarded``: the model's functions are called through
    guards (lane and trajectory kernels); else as they are, compiled into their callers (the
    one-point kernel catches an exception once per point)."""

    def __init__(self, model, guarded: bool):
        self.model = model
        self.guarded = guarded
        self.n_p, self.n_set, self.n_int = len(model.params), len(model.settings), len(model.internal)
        self.npi = self.n_p + self.n_set + self.n_int  # p[npi]: the point's user-error flag
        self.scr = self.npi + 1  # the engine's scratch
        self.n_s = len(model.states)
        self.order = tuple(getattr(model, "status_order", ()))
        self.fold = calls.folder(self.order)

    def fn(self, func, role: str, kind: str):
        """The model's (or a measurement's) ``func`` as this route calls it; ``kind`` its signature:
        "fill" (t, y, p, out), "fill2d" (a Jacobian), "initial" (p, y0), "status1" / "status2"
        (classify(p), prepare(p, rtol)), "p", "p,x", "p,x,y", "t,y,p" (a number)."""
        if func is None:
            return None
        if not self.guarded:
            return calls.user(self.model.name, func, role, inline=True)
        f = calls.user(self.model.name, func, role)
        if kind in _GUARDS:
            return _GUARDS[kind](f, self.npi)
        if kind.startswith("status"):
            return calls.guard_status(f, int(kind[-1]))
        return calls.guard_value(f, self.npi, kind)

    def raw(self, func, role: str):
        """The model's ``func`` compiled, without a guard (the caller guards it where it must)."""
        return calls.user(self.model.name, func, role, inline=not self.guarded)

    def switch_slot(self, n_scr: int) -> int:
        """Where the two slots of the switches' clamp lie in p, after ``n_scr`` slots of scratch."""
        return self.scr + n_scr


@functools.cache
def fd_jacobian(rhs, n: int, at: int, count: bool):
    """The engine's Jacobian ``jac(t, y, p, J)`` of ``rhs`` by central differences, step cbrt(eps)
    max(1, |y_j|) (exact up to round-off for an rhs linear in y), with the scratch p[at:at + 3 n]
    (y + h, f(y + h), f(y - h)); ``count``: its 2 n rhs calls are added to the counter p[at + 3 n]
    (the kernel adds it to n_rhs)."""
    two_n = 2.0 * n

    @jit_internal
    def jac(t, y, p, J):
        if count:
            p[at + 3 * n] += two_n  # its rhs calls, for n_rhs
        yp = p[at:at + n]
        fp = p[at + n:at + 2 * n]
        fm = p[at + 2 * n:at + 3 * n]
        for j in range(n):
            for i in range(n):
                yp[i] = y[i]
            h = 6.055454452393343e-06 * max(1.0, abs(y[j]))
            up = y[j] + h
            dn = y[j] - h
            yp[j] = up
            rhs(t, yp, p, fp)
            yp[j] = dn
            rhs(t, yp, p, fm)
            for i in range(n):
                J[i, j] = (fp[i] - fm[i]) / (up - dn)

    return jac


def equation(view: View, system=None, *, clamp_at: int = -1, fd_at: int = -1, fd_count: bool = False) -> Equation:
    """The model's equation (or a measurement's ``System``'s) as the methods integrate it: its rhs,
    its jac (the engine's central differences where it declares none, scratch at ``fd_at``), accel and
    symplectic_step; ``clamp_at`` >= 0: the switches' clamp of the time in p[clamp_at:clamp_at + 2]
    (engine/switches.py) around the model's rhs and jac."""
    src = system if system is not None else view.model
    rhs = view.fn(src.rhs, "rhs", "fill")
    jac = view.fn(getattr(src, "jac", None), "jac", "fill2d")
    if clamp_at >= 0 and system is None:  # a System's functions see the time as it is
        rhs = switches.clamped(rhs, clamp_at)
        if jac is not None:
            jac = switches.clamped(jac, clamp_at)
    if jac is None and fd_at >= 0:
        jac = fd_jacobian(rhs, view.n_s, fd_at, fd_count)
    accel = view.fn(getattr(src, "accel", None), "accel", "fill")
    step = view.fn(getattr(src, "symplectic_step", None), "symplectic_step", "p,x")
    return Equation(rhs, view.n_s, jac, accel, step, int(getattr(view.model, "symplectic_order", 8)))
