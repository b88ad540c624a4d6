"""Locate boundaries along one axis, for any model: where a criterion crosses a level, or where
the status changes from one value to another, for every combination of the other axes.

Built only on :attr:`ModelSpec.evaluate` (through ``runner.evaluate_rows`` for status changes):
nothing here knows a model. The grid of the scene brackets every crossing between two neighbouring
grid values; each bracket is then refined, all brackets of a round in ONE evaluate call (the
chunk kernels run them in parallel):

- a sign change of g = criterion - level, with |g| above the criterion's accuracy ``eps`` at both
  ends: Illinois (modified regula falsi), kept at least tol / 2 inside the bracket and bisected
  when the bracket does not halve in three rounds, so the bracket itself shrinks to
  tol = rtol * |x|. A point inside the band |g| <= eps is a root within the criterion's accuracy:
  two probes around it, at twice the band's half width eps / |slope| plus 0.45 tol (widened
  fourfold while a probe is still in the band), close the bracket; the criterion's bound applied
  when that bracket is wider than tol.
- a criterion at its level within its accuracy over a stretch and leaving it (e.g. the largest
  Floquet multiplier of an undamped system: 1 on the stable side, 1 + C sqrt(distance) beyond):
  the edge of the band, predicted from the two nearest off-band values (|g|^2 linear for a
  Floquet criterion, |g| otherwise) and closed by two probes around the prediction, with
  bisection as the safeguard (``_band_edges``), down to tol.
- a change of status: bisection on the status, to tol.

Every located point stores its bracket width (a true bracket: both ends evaluated), which bound
applied (BOUND_MEANINGS), the direction of the crossing, the evaluations it cost and, for a
criterion of kind "floquet_max" whose model gives ``<name>_angle``, the critical multiplier on the
unstable side: its argument (on the boundary the multiplier is exp(+-i angle)) and the kind of
crossing that follows from it (+1, -1, complex pair). Two crossings within one grid cell (no sign change between grid
values) are not seen: the grid must resolve the boundaries it is asked to locate.
"""
from __future__ import annotations

import datetime as _dt
import math
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import cf
from . import status as st

# which bound stopped a located point (stored as the variable boundary_bound)
PARAMETER, CRITERION, BAND_EDGE, INTERRUPTED, BUDGET = 0, 1, 2, 3, 4
BOUND_MEANINGS = {
    PARAMETER: "parameter",  # bracket width <= rtol |x|
    CRITERION: "criterion",  # the criterion's own accuracy: bracket = the band |g| <= eps around the root
    BAND_EDGE: "band_edge",  # edge of a stretch where the criterion stays at its level within eps; width <= rtol |x|
    INTERRUPTED: "interrupted",  # a point in the bracket gave a third status or no value: NaN location
    BUDGET: "budget",  # MAX_EVALUATIONS spent before the tolerance was reached (width stored)
}
BOUND_DESCRIPTIONS = {
    PARAMETER: "the bracket is within the relative tolerance rtol of the parameter",
    CRITERION: "the criterion's own accuracy limits the bracket: it is the stretch where |criterion - level| "
               "<= criterion accuracy around the root, wider than rtol |x|",
    BAND_EDGE: "the criterion stays at its level within its accuracy on one side (e.g. a neutrally stable "
               "Floquet multiplier of modulus 1) and leaves it here; located to rtol |x|",
    INTERRUPTED: "a point inside the bracket had a third status or no finite criterion: not located (NaN)",
    BUDGET: "the evaluation budget ran out before the tolerance was reached; the stored width says how far",
}
MAX_EVALUATIONS = 80  # per located point
STALL_ROUNDS = 3  # Illinois rounds without halving the bracket before a bisection step
ABS_FLOOR = 1e-6  # tol never below rtol * ABS_FLOOR * (the axis's span): a boundary at x = 0


@dataclass(frozen=True)
class Criterion:
    """What a boundary is: ``output`` crossing ``level`` (accuracy ``accuracy``: absolute, None =
    from the solver), or ``status_change`` (a, b) between two status codes."""

    output: str | None = None
    level: float = math.nan
    status_change: tuple[int, int] | None = None
    accuracy: float | None = None
    angle_output: str | None = None  # "<output>_angle" of a floquet_max output, when the model has it:
    # the critical multiplier's argument (0 real positive, pi real negative, else a complex pair),
    # from which the kind of crossing follows


def from_integration(model, name: str) -> bool:
    """Whether output ``name``'s value comes from an integration: an integrated output, or a closed
    form of integrated outputs, however deep (its ``needs``; for a model-layer closed form also the
    outputs its formula reads when its declared output needs leave them out, e.g. ``output_needs=()``):
    such a value is only as accurate as the integration."""
    by_name = {o.name: o for o in model.outputs}
    forms = {c.name: c for c in getattr(getattr(model, "declaration", None), "closed_forms", ())}
    stack, seen = [name], set()
    while stack:
        n = stack.pop()
        if n in seen:
            continue
        seen.add(n)
        if n in by_name and by_name[n].integrated:
            return True
        stack.extend(by_name[n].needs if n in by_name else ())
        stack.extend(getattr(forms.get(n), "needs", ()))
    return False


def criterion_accuracy(model, solver, crit: Criterion, values: np.ndarray) -> np.ndarray:
    """Absolute accuracy of criterion values ``values`` (the band |g| <= eps that cannot be told from
    the level). Given in the scene, it is used as is. Else: an output of kind "floquet_max": the
    verdict margin of the Floquet measurement, max(solver.floquet_margin (default 1e-8), 100 rtol);
    another integrated output, or a closed form computed from integrated outputs (it inherits their
    accuracy: :func:`from_integration`): 100 rtol max(|value|, |level|); a closed form of the
    parameters alone: 16 ulp of the same."""
    if crit.accuracy is not None:
        return np.full(values.shape, crit.accuracy)
    out = model.output(crit.output)
    scale = np.maximum(np.abs(values), abs(crit.level))
    if out.kind == "floquet_max":
        margin = float(solver.settings.get("floquet_margin", 1e-8)) if solver is not None else 1e-8
        return np.full(values.shape, max(margin, 100.0 * (solver.rtol if solver is not None else 0.0)))
    if solver is not None and from_integration(model, crit.output):
        return 100.0 * solver.rtol * scale
    return 16.0 * np.finfo(float).eps * scale


def accuracy_text(scene, crit: Criterion) -> str:
    """The criterion accuracy used, in words (a dataset attribute)."""
    if crit.accuracy is not None:
        return f"{crit.accuracy:g} (given in [boundaries])"
    out, solver = scene.model.output(crit.output), scene.solver
    if out.kind == "floquet_max":
        eps = criterion_accuracy(scene.model, solver, crit, np.zeros(1))[0]
        return f"{eps:g}: the Floquet verdict margin max(floquet_margin, 100 rtol)"
    if solver is not None and from_integration(scene.model, crit.output):
        of = "" if out.integrated else " (a closed form of integrated outputs: their accuracy)"
        return f"100 rtol max(|value|, |level|) = {100 * solver.rtol:g} max(|value|, |level|){of}"
    return "16 ulp of max(|value|, |level|) (a closed form)"


@dataclass
class Located:
    """Results for L lines, up to C crossings each (NaN / -1 beyond a line's crossings)."""

    location: np.ndarray  # (L, C) parameter value of the boundary
    width: np.ndarray  # (L, C) achieved bracket width (both ends evaluated)
    bound: np.ndarray  # (L, C) int8: BOUND_MEANINGS, -1 for no crossing
    direction: np.ndarray  # (L, C) int8: +1 when the criterion rises above its level (status a -> b) with x
    kind: np.ndarray  # (L, C) Floquet crossing kind (+1, -1, 0) or NaN
    evaluations: np.ndarray  # (L, C) int32: criterion evaluations spent refining this crossing
    angle: np.ndarray | None = None  # (L, C) argument of the critical multiplier on the unstable side, rad
    calls: int = 0  # evaluate calls (rounds)
    points: int = 0  # points evaluated in refinement in all


class _Evaluator:
    """Evaluates criterion classes and values at (line, x) pairs, in one call per round."""

    def __init__(self, scene, crit: Criterion, rows: np.ndarray, col: int):
        self.scene, self.crit, self.rows, self.col = scene, crit, rows, col
        self.model = scene.model
        self.calls = 0
        self.points = 0
        if crit.output is not None:
            want = (crit.output,) + ((crit.angle_output,) if crit.angle_output else ())
            self.wanted = self.model.closure(want)

    def __call__(self, line: np.ndarray, x: np.ndarray):
        """(g or NaN, status, critical angle or NaN) at the points."""
        P = self.rows[line].copy()
        P[:, self.col] = x
        return self.at(P)

    def at(self, P: np.ndarray):
        """(g or NaN, status, critical angle or NaN) at the parameter rows P."""
        n = P.shape[0]
        self.calls += 1
        self.points += n
        kind = np.full(n, np.nan)
        if self.crit.output is None:
            from .runner import evaluate_rows

            _, status, _, _ = evaluate_rows(self.scene, P)
            return np.full(n, np.nan), status, kind
        solver = self.scene.solver
        out = {name: np.full((n,) + _extra(self.scene, name), np.nan) for name in self.wanted}
        status = np.zeros(n, dtype=st.DTYPE)
        ns, nr = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
        with np.errstate(all="ignore"):
            self.model.evaluate(P, self.wanted, solver, out, status, ns, nr)
        g = out[self.crit.output] - self.crit.level
        g[~np.isfinite(g)] = np.nan
        if self.crit.angle_output:
            kind = out[self.crit.angle_output]
        return g, status, kind


def _extra(scene, name):
    settings = scene.solver.settings if scene.solver is not None else {}
    return tuple(len(d.values(settings)) for d in scene.model.output(name).extra_dims)


def _sides(g: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """-1 below the level, +1 above, 0 within the accuracy band, -9 no value."""
    s = np.where(g > eps, 1, np.where(g < -eps, -1, 0)).astype(np.int8)
    s[np.isnan(g)] = -9
    return s


def _brackets_of_line(s: np.ndarray) -> list[tuple[int, int, int]]:
    """(i, j, mode) of one line's sides: a sign change between clean points with only band points
    between (mode 0), or an edge between the band and a clean point (mode 1). No value (-9) breaks."""
    out = []
    G = s.size
    prev = None  # the last clean point of the current stretch
    for i in range(G):
        if s[i] == -9:
            if prev is not None and prev + 1 < i and s[prev + 1] == 0:
                out.append((prev, prev + 1, 1))  # clean -> band, then no value
            prev = None
            continue
        if s[i] == 0:
            continue
        if prev is None:
            if i > 0 and s[i - 1] == 0:
                out.append((i - 1, i, 1))  # band -> clean at the start of a stretch
        elif s[prev] == -s[i]:
            out.append((prev, i, 0))
        elif i > prev + 1:  # clean, band, clean on the same side: two edges
            out.append((prev, prev + 1, 1))
            out.append((i - 1, i, 1))
        prev = i
    if prev is not None and prev + 1 < G and s[prev + 1] == 0:
        out.append((prev, prev + 1, 1))
    return out


def locate(scene, crit: Criterion, rows: np.ndarray, col: int, grid: np.ndarray, *, rtol: float = 1e-10,
           grid_g: np.ndarray | None = None, grid_status: np.ndarray | None = None,
           grid_angle: np.ndarray | None = None) -> Located:
    """Locate every crossing along ``grid`` (the axis's values, any order) for each of the L base
    parameter rows ``rows`` (float64 [L, n_params]; column ``col`` is the axis, overwritten).

    ``grid_g`` / ``grid_status`` (L, G): the criterion minus level / the status on the grid, when
    known (from a stored dataset); else the grid is evaluated here (one call). ``grid_angle`` (L, G):
    the critical multiplier's argument there (``<floquet>_angle``), if stored."""
    rows = np.asarray(rows, dtype=float)
    grid = np.asarray(grid, dtype=float)
    order = np.argsort(grid, kind="stable")
    xs = grid[order]
    L, G = rows.shape[0], xs.size
    ev = _Evaluator(scene, crit, rows, col)
    if grid_g is None and grid_status is None:
        line = np.repeat(np.arange(L), G)
        g, status, ang = ev(line, np.tile(xs, L))
        grid_g, grid_status, grid_angle = g.reshape(L, G), status.reshape(L, G), ang.reshape(L, G)
        ev.calls, ev.points = 0, 0  # the grid pass is not refinement
    else:
        grid_g = None if grid_g is None else np.asarray(grid_g, dtype=float)[:, order]
        grid_status = None if grid_status is None else np.asarray(grid_status)[:, order]
    if grid_angle is not None:
        grid_angle = np.asarray(grid_angle, dtype=float)[:, order]
    span = float(xs[-1] - xs[0]) if G > 1 else 1.0

    # brackets on the grid: (line, i, j) between xs[i] and xs[j]; mode 0 sign, 1 band edge, 2 status
    if crit.output is None:
        a, b = crit.status_change
        cls = np.where(grid_status == a, 0, np.where(grid_status == b, 1, -1))
        ii, jj = np.nonzero((cls[:, :-1] >= 0) & (cls[:, 1:] >= 0) & (cls[:, :-1] != cls[:, 1:]))
        br_line, br_lo, br_hi, br_mode = ii, jj, jj + 1, np.full(ii.size, 2)
        sides = None
    else:
        eps = criterion_accuracy(scene.model, scene.solver, crit, grid_g + crit.level)
        sides = _sides(grid_g, eps)
        found = [_brackets_of_line(sides[l]) for l in range(L)]
        br_line = np.array([l for l in range(L) for _ in found[l]], dtype=np.int64)
        br_lo, br_hi, br_mode = (np.array([t[k] for f in found for t in f], dtype=np.int64) for k in range(3))
    nb = len(br_line)
    per_line = np.bincount(br_line, minlength=L) if nb else np.zeros(L, dtype=np.int64)
    C = int(per_line.max()) if L and nb else 0
    res = Located(location=np.full((L, C), np.nan), width=np.full((L, C), np.nan),
                  bound=np.full((L, C), -1, dtype=np.int8), direction=np.zeros((L, C), dtype=np.int8),
                  kind=np.full((L, C), np.nan), evaluations=np.zeros((L, C), dtype=np.int32),
                  angle=np.full((L, C), np.nan))
    if nb == 0:
        return res
    srt = np.lexsort((br_lo, br_line))  # crossing index within each line, in order of x
    br_line, br_lo, br_hi, br_mode = br_line[srt], br_lo[srt], br_hi[srt], br_mode[srt]
    slot = np.arange(nb) - np.searchsorted(br_line, br_line, side="left")

    A, B = xs[br_lo].astype(float), xs[br_hi].astype(float)  # the bracket, refined in place
    ang_a = grid_angle[br_line, br_lo] if grid_angle is not None else np.full(nb, np.nan)
    ang_b = grid_angle[br_line, br_hi] if grid_angle is not None else np.full(nb, np.nan)
    n_eval = np.zeros(nb, dtype=np.int64)
    loc = np.full(nb, np.nan)
    bound = np.full(nb, -1, dtype=np.int8)
    if sides is not None:
        s_a, s_b = sides[br_line, br_lo], sides[br_line, br_hi]
        direction = np.sign(s_b.astype(int) - s_a.astype(int)).astype(np.int8)
        above_b, above_a = s_b == 1, s_a == 1  # which end has the criterion above its level
    else:
        direction = np.where(grid_status[br_line, br_lo] == crit.status_change[0], 1, -1).astype(np.int8)
        above_a = above_b = np.zeros(nb, dtype=bool)

    def tol_of(a, b):
        return rtol * np.maximum(np.maximum(np.abs(a), np.abs(b)), ABS_FLOOR * span)

    def accuracy(g):
        return criterion_accuracy(scene.model, scene.solver, crit, g + crit.level)

    # ---- band edges (mode 1): extrapolation from the side off the band, safeguarded
    edges = np.nonzero(br_mode == 1)[0]
    if edges.size:
        floquet = scene.model.output(crit.output).kind == "floquet_max"
        _band_edges(ev, br_line, edges, A, B, s_a, s_b, grid_g[br_line, br_lo], grid_g[br_line, br_hi],
                    ang_a, ang_b, n_eval, bound, loc, tol_of, accuracy, power=2.0 if floquet else 1.0)

    # ---- bisection: status changes (mode 2), on a class 0 (a's) / 1 (b's)
    bis = np.nonzero(br_mode == 2)[0]
    if bis.size:
        code_a = grid_status[br_line[bis], br_lo[bis]]
        code_b = grid_status[br_line[bis], br_hi[bis]]
        active = np.ones(bis.size, dtype=bool)
        while active.any():
            idx = np.nonzero(active)[0]
            j = bis[idx]
            done = (B[j] - A[j]) <= tol_of(A[j], B[j])
            bound[j[done]] = PARAMETER
            over = ~done & (n_eval[j] >= MAX_EVALUATIONS)
            bound[j[over]] = BUDGET
            active[idx[done | over]] = False
            idx = np.nonzero(active)[0]
            if not idx.size:
                break
            j = bis[idx]
            mid = 0.5 * (A[j] + B[j])
            _, status, _ = ev(br_line[j], mid)
            n_eval[j] += 1
            to_a, to_b = status == code_a[idx], status == code_b[idx]
            A[j[to_a]], B[j[to_b]] = mid[to_a], mid[to_b]
            bad = ~to_a & ~to_b  # a third status: two boundaries in one cell
            bound[j[bad]] = INTERRUPTED
            active[idx[bad]] = False
        j = bis[bound[bis] != INTERRUPTED]
        loc[j] = 0.5 * (A[j] + B[j])

    # ---- Illinois on sign brackets (mode 0)
    ill = np.nonzero(br_mode == 0)[0]
    if ill.size:
        ga = grid_g[br_line[ill], br_lo[ill]].copy()
        gb = grid_g[br_line[ill], br_hi[ill]].copy()
        sa, sb = np.sign(ga), np.sign(gb)
        Fa, Fb = ga.copy(), gb.copy()  # Illinois-weighted values
        last = np.zeros(ill.size, dtype=np.int8)  # which end moved last: -1 a, +1 b
        w_ref = B[ill] - A[ill]  # width at the last stall check
        rounds = np.zeros(ill.size, dtype=np.int64)
        probe_x = np.full(ill.size, np.nan)  # a point found inside the band: probe around it
        probe_h = np.full(ill.size, np.nan)
        active = np.ones(ill.size, dtype=bool)
        while active.any():
            idx = np.nonzero(active)[0]
            j = ill[idx]
            done = (B[j] - A[j]) <= tol_of(A[j], B[j])
            bound[j[done]] = PARAMETER
            over = ~done & (n_eval[j] >= MAX_EVALUATIONS)
            bound[j[over]] = BUDGET
            active[idx[done | over]] = False
            idx = np.nonzero(active)[0]
            if not idx.size:
                break
            probing = ~np.isnan(probe_x[idx])
            # Illinois points
            pi = idx[~probing]
            j = ill[pi]
            t = tol_of(A[j], B[j])
            with np.errstate(all="ignore"):
                x = B[j] - Fb[pi] * (B[j] - A[j]) / (Fb[pi] - Fa[pi])
            check = rounds[pi] >= STALL_ROUNDS
            stalled = check & ((B[j] - A[j]) > 0.5 * w_ref[pi])
            x = np.where(stalled | ~np.isfinite(x), 0.5 * (A[j] + B[j]), x)
            rounds[pi[check]] = 0
            w_ref[pi[check]] = (B[j] - A[j])[check]
            d = np.minimum(0.5 * t, 0.25 * (B[j] - A[j]))
            x = np.clip(x, A[j] + d, B[j] - d)
            # probe points around a point inside the band
            qi = idx[probing]
            jq = ill[qi]
            pl = np.maximum(probe_x[qi] - probe_h[qi], A[jq])  # at an end at worst: a clean side
            pr = np.minimum(probe_x[qi] + probe_h[qi], B[jq])
            g, _, ang = ev(np.concatenate([br_line[j], br_line[jq], br_line[jq]]), np.concatenate([x, pl, pr]))
            n_eval[j] += 1
            n_eval[jq] += 2
            m, q = pi.size, qi.size
            gx, ax_ = g[:m], ang[:m]
            gl, gr, al, ar = g[m:m + q], g[m + q:], ang[m:m + q], ang[m + q:]
            # -- Illinois updates
            eps_x = accuracy(gx)
            sx = _sides(gx, eps_x)
            nan = sx == -9
            bound[j[nan]] = INTERRUPTED
            active[pi[nan]] = False
            band = sx == 0
            if band.any():
                k = pi[band]
                slope = np.abs(gb[k] - ga[k]) / (B[j[band]] - A[j[band]])  # secant of the bracket
                with np.errstate(all="ignore"):
                    half = eps_x[band] / slope
                half = np.where(np.isfinite(half), half, 0.0)
                probe_x[k] = x[band]
                probe_h[k] = 2.0 * half + 0.45 * t[band]  # |g| ~ 2 eps at the probes: clean sides
            to_b = (sx == sb[pi])
            to_a = (sx == sa[pi])
            k = pi[to_b]
            B[ill[k]], gb[k], Fb[k], ang_b[ill[k]] = x[to_b], gx[to_b], gx[to_b], ax_[to_b]
            Fa[k[last[k] == 1]] *= 0.5
            last[k] = 1
            k = pi[to_a]
            A[ill[k]], ga[k], Fa[k], ang_a[ill[k]] = x[to_a], gx[to_a], gx[to_a], ax_[to_a]
            Fb[k[last[k] == -1]] *= 0.5
            last[k] = -1
            rounds[pi] += 1
            # -- probe updates
            if q:
                sl, sr = _sides(gl, accuracy(gl)), _sides(gr, accuracy(gr))
                closed = (sl == sa[qi]) & (sr == sb[qi])
                left = ~closed & (sl == sb[qi])  # the root is in (a, pl)
                right = ~closed & ~left & (sr == sa[qi])  # the root is in (pr, b)
                widen = ~closed & ~left & ~right  # a probe still in the band: it is wider
                move_a = closed | right | (widen & (sl == sa[qi]))
                move_b = closed | left | (widen & (sr == sb[qi]))
                new_a = np.where(right, pr, pl)
                new_b = np.where(left, pl, pr)
                k = qi[move_a]
                A[ill[k]] = new_a[move_a]
                ga[k] = Fa[k] = np.where(right, gr, gl)[move_a]
                ang_a[ill[k]] = np.where(right, ar, al)[move_a]
                k = qi[move_b]
                B[ill[k]] = new_b[move_b]
                gb[k] = Fb[k] = np.where(left, gl, gr)[move_b]
                ang_b[ill[k]] = np.where(left, al, ar)[move_b]
                last[qi] = 0
                k = qi[closed]
                # the parameter's bound if the probes' bracket is within tol, else the criterion's
                bound[ill[k]] = np.where(pr[closed] - pl[closed] <= tol_of(pl[closed], pr[closed]), PARAMETER, CRITERION)
                active[k] = False
                probe_x[qi[left | right]] = np.nan
                probe_h[qi[widen]] *= 4.0
                nanp = widen & ((sl == -9) | (sr == -9))
                bound[ill[qi[nanp]]] = INTERRUPTED
                active[qi[nanp]] = False
        ok = bound[ill] != INTERRUPTED
        a, b = A[ill], B[ill]
        with np.errstate(all="ignore"):  # the secant root within the final bracket
            xr = a - ga * (b - a) / (gb - ga)
        xr = np.where(np.isfinite(xr) & (xr >= a) & (xr <= b), xr, 0.5 * (a + b))
        loc[ill[ok]] = xr[ok]

    width = B - A
    width[bound == INTERRUPTED] = np.nan
    ang = np.where(above_b, ang_b, np.where(above_a, ang_a, np.nan))
    if crit.angle_output:
        missing = np.nonzero(np.isnan(ang) & (above_a | above_b) & ~np.isnan(loc))[0]
        if missing.size:  # an end never evaluated here (a grid value whose angle is not stored): one call
            _, _, k = ev(br_line[missing], np.where(above_b[missing], B[missing], A[missing]))
            n_eval[missing] += 1
            ang[missing] = k
    res.location[br_line, slot] = loc
    res.width[br_line, slot] = width
    res.bound[br_line, slot] = bound
    res.direction[br_line, slot] = direction
    res.angle[br_line, slot] = ang
    res.kind[br_line, slot] = kind_of_angle(ang)
    res.evaluations[br_line, slot] = n_eval
    res.calls, res.points = ev.calls, ev.points
    return res


def _band_edges(ev, br_line, idx, A, B, s_a, s_b, g_a, g_b, ang_a, ang_b, n_eval, bound, loc, tol_of, accuracy,
                power):
    """Refine band-edge brackets ``idx`` in place: one end E inside the band |g| <= eps, the other
    U off it. Near the edge the criterion leaves the band like |g| ~ C d^(1/power) (d the distance
    past the edge): a double Floquet multiplier splits like the square root of the parameter
    (power 2), anything else is taken as linear (power 1). So |g|^power - eps^power is nearly
    linear in x: its root through the two off-band points nearest the edge predicts the edge (two
    predictions in a row the probes missed switch to the other law), and
    two probes around the prediction close the bracket from both sides. The probes' half-width is
    r times the distance from the nearest off-band point (at least 0.45 tol): r shrinks tenfold
    after a prediction the probes closed, grows fourfold (to 0.5) after one they missed (measured
    on Mathieu's band edges: 16-25 evaluations from a 0.2-wide grid cell to 1e-10, where bisection
    takes 29-32). Safeguards: a bisection step while there is only one off-band point, when the
    prediction leaves the bracket, and when the bracket has not halved in STALL_ROUNDS rounds."""
    m = idx.size
    u_is_b = s_a[idx] == 0  # which end is off the band
    side_u = np.where(u_is_b, s_b[idx], s_a[idx])
    E = np.where(u_is_b, A[idx], B[idx])
    U = np.where(u_is_b, B[idx], A[idx])
    gU = np.abs(np.where(u_is_b, g_b[idx], g_a[idx]))
    U2, g2 = np.full(m, np.nan), np.full(m, np.nan)  # the off-band point before U
    pw = np.full(m, float(power))  # the law tried: switched after two predictions the probes missed
    misses = np.zeros(m, dtype=np.int64)
    r = np.full(m, 0.1)  # probe half-width / distance from U to the prediction: smaller after a success
    w_ref, rounds = np.abs(U - E), np.zeros(m, dtype=np.int64)
    angU = np.where(u_is_b, ang_b[idx], ang_a[idx])
    angE = np.where(u_is_b, ang_a[idx], ang_b[idx])
    active = np.ones(m, dtype=bool)
    while True:
        w = np.abs(U - E)
        t = tol_of(E, U)
        done = active & (w <= t)
        bound[idx[done]] = BAND_EDGE
        over = active & ~done & (n_eval[idx] >= MAX_EVALUATIONS)
        bound[idx[over]] = BUDGET
        active &= ~(done | over)
        k = np.nonzero(active)[0]
        if not k.size:
            break
        # the prediction: the root of the line through (U, hU), (U2, h2) at the band's own level
        eps, q = np.abs(accuracy(np.zeros(k.size))), pw[k]
        with np.errstate(all="ignore"):
            hU, h2 = gU[k] ** q, g2[k] ** q
            xs = U[k] - (hU - eps ** q) * (U2[k] - U[k]) / (h2 - hU)
        lo, hi = np.minimum(E[k], U[k]), np.maximum(E[k], U[k])
        check = rounds[k] >= STALL_ROUNDS
        stalled = check & (w[k] > 0.5 * w_ref[k])
        rounds[k[check]] = 0
        w_ref[k[check]] = w[k][check]
        pred = np.isfinite(xs) & (xs > lo) & (xs < hi) & ~stalled
        # no prediction where the secant has no root: the two off-band values tie (h2 == hU, e.g. a
        # plateau, or at a tongue tip) and xs is +-inf (NaN for 0/0); such a bracket bisects (pe is
        # the midpoint, pu unused below), and its probes are not computed from the infinity (inf -
        # inf was numpy's "invalid value encountered in add")
        xs = np.where(np.isfinite(xs), xs, 0.5 * (lo + hi))
        d = np.minimum(0.45 * t[k], 0.25 * w[k])
        delta = np.maximum(r[k] * np.abs(U[k] - xs), 0.45 * t[k])
        toward_u = np.sign(U[k] - E[k])
        pe = np.clip(xs - toward_u * delta, lo + d, hi - d)  # the probe on E's side
        pu = np.clip(xs + toward_u * delta, lo + d, hi - d)  # the probe on U's side
        mid = 0.5 * (E[k] + U[k])
        pe = np.where(pred, pe, mid)
        kp = k[pred]
        g, _, ang = ev(np.concatenate([br_line[idx[k]], br_line[idx[kp]]]), np.concatenate([pe, pu[pred]]))
        n_eval[idx[k]] += 1
        n_eval[idx[kp]] += 1
        rounds[k] += 1
        # the probe on E's side (or the midpoint), then the one on U's side
        ge, ange = g[:k.size], ang[:k.size]
        se = _sides(ge, accuracy(ge))
        gu = np.full(k.size, np.nan)
        gu[pred] = g[k.size:]
        angu = np.full(k.size, np.nan)
        angu[pred] = ang[k.size:]
        su = np.full(k.size, -8, dtype=np.int8)  # -8: not probed
        su[pred] = _sides(gu[pred], accuracy(gu[pred]))
        bad = ((se != 0) & (se != side_u[k])) | ((se == 0) & (su != -8) & (su != 0) & (su != side_u[k]))
        bound[idx[k[bad]]] = INTERRUPTED
        active[k[bad]] = False
        off_e = ~bad & (se == side_u[k])  # off the band already: U moves there, the U probe is the point before
        U2[k[off_e]] = np.where(su[off_e] == side_u[k][off_e], pu[off_e], U[k[off_e]])
        g2[k[off_e]] = np.where(su[off_e] == side_u[k][off_e], np.abs(gu[off_e]), gU[k[off_e]])
        U[k[off_e]], gU[k[off_e]], angU[k[off_e]] = pe[off_e], np.abs(ge[off_e]), ange[off_e]
        in_e = ~bad & (se == 0)
        E[k[in_e]], angE[k[in_e]] = pe[in_e], ange[in_e]
        off_u = in_e & (su == side_u[k])  # the edge is between the two probes
        U2[k[off_u]], g2[k[off_u]] = U[k[off_u]], gU[k[off_u]]
        U[k[off_u]], gU[k[off_u]], angU[k[off_u]] = pu[off_u], np.abs(gu[off_u]), angu[off_u]
        in_u = in_e & (su == 0)  # both in the band: the edge is beyond the U probe
        E[k[in_u]], angE[k[in_u]] = pu[in_u], angu[in_u]
        # a prediction closed by its probes: the next one is trusted closer; else wider probes
        hit = off_u[pred]
        r[kp] = np.where(hit, np.maximum(0.1 * r[kp], 1e-8), np.minimum(4.0 * r[kp], 0.5))
        misses[kp] = np.where(hit, 0, misses[kp] + 1)
        switch = kp[misses[kp] >= 2]
        pw[switch] = 3.0 - pw[switch]  # the other law (square root <-> linear)
        misses[switch] = 0
    A[idx] = np.where(u_is_b, E, U)
    B[idx] = np.where(u_is_b, U, E)
    ang_a[idx] = np.where(u_is_b, angE, angU)
    ang_b[idx] = np.where(u_is_b, angU, angE)
    ok = bound[idx] != INTERRUPTED
    loc[idx[ok]] = 0.5 * (E + U)[ok]


# ----------------------------------------------------------------------------- a scene's boundaries
def kind_of_angle(angle: np.ndarray) -> np.ndarray:
    """The crossing kind (+1, -1, 0 complex pair, NaN) of a critical multiplier's argument (exactly
    0 or pi for a real one: the Floquet measurement snaps it with the same test as its kind)."""
    angle = np.asarray(angle, dtype=float)
    return np.where(angle == 0.0, 1.0, np.where(angle == np.pi, -1.0, np.where(np.isnan(angle), np.nan, 0.0)))


def criterion_of(scene, spec=None) -> Criterion:
    """The :class:`Criterion` of a scene's [boundaries] section (or of ``spec``, a scene.Boundaries)."""
    b = spec if spec is not None else scene.boundaries
    if b.criterion is None:
        codes = {name: code for code, name in st.MEANINGS.items()}
        return Criterion(status_change=(codes[b.status_change[0]], codes[b.status_change[1]]))
    kind = None
    if scene.model.output(b.criterion).kind == "floquet_max" and f"{b.criterion}_angle" in scene.model.output_names():
        kind = f"{b.criterion}_angle"
    return Criterion(output=b.criterion, level=b.level, accuracy=b.criterion_accuracy, angle_output=kind)


def sibling_path(data: str | os.PathLike) -> Path:
    """Where the boundaries of the dataset ``data`` are written by default: DATA.boundaries.h5."""
    data = Path(data)
    return data.with_name(data.stem + ".boundaries.h5")


def _encoded(scene, axis) -> np.ndarray:
    prm = scene.model.param(axis.name)
    if axis.spacing == "list":
        return np.array([prm.encode(v) for v in axis.items], dtype=float)
    return axis.array()


def base_rows(scene, along: str) -> tuple[np.ndarray, int, tuple]:
    """Parameter rows of every combination of the axes other than ``along`` (C order of the scene's
    axes), the column of ``along``, and the other axes."""
    others = [a for a in scene.axes if a.name != along]
    names = scene.model.param_names()
    grids = np.meshgrid(*[_encoded(scene, a) for a in others], indexing="ij") if others else []
    L = int(np.prod([a.size for a in others], dtype=np.int64)) if others else 1
    rows = np.empty((L, len(names)))
    other_pos = {a.name: k for k, a in enumerate(others)}
    for c, prm in enumerate(scene.model.params):
        if prm.name in other_pos:
            rows[:, c] = grids[other_pos[prm.name]].ravel()
        elif prm.name in scene.fixed:
            rows[:, c] = prm.encode(scene.fixed[prm.name])
        elif prm.name == along:
            rows[:, c] = np.nan
        else:
            rows[:, c] = prm.default
    return rows, names.index(along), tuple(others)


def locate_dataset(scene, ds, spec=None):
    """Locate the boundaries a scene's [boundaries] section (or ``spec``) asks for, bracketed by the
    scene's finished dataset ``ds``. Returns a new xarray Dataset (dims: the other axes, crossing)."""
    import xarray as xr

    from . import __version__

    b = spec if spec is not None else scene.boundaries
    crit = criterion_of(scene, b)
    along = b.along
    axis = next(a for a in scene.axes if a.name == along)
    rows, col, others = base_rows(scene, along)
    dims = [a.name for a in scene.axes]
    order = [d for d in dims if d != along] + [along]
    L, G = rows.shape[0], axis.size

    def grid_of(name):
        return np.asarray(ds[name].transpose(*order).values).reshape(L, G)

    t0 = time.perf_counter()
    if crit.output is not None:
        res = locate(scene, crit, rows, col, _encoded(scene, axis), rtol=b.rtol,
                     grid_g=grid_of(crit.output) - crit.level,
                     grid_angle=grid_of(crit.angle_output) if crit.angle_output and crit.angle_output in ds else None)
    else:
        res = locate(scene, crit, rows, col, _encoded(scene, axis), rtol=b.rtol, grid_status=grid_of("status"))
    wall = time.perf_counter() - t0
    shape = tuple(a.size for a in others) + (res.location.shape[1],)
    odims = tuple(a.name for a in others) + ("crossing",)
    prm = scene.model.param(along)
    coords = {a.name: ds[a.name] for a in others}
    coords["crossing"] = ("crossing", np.arange(shape[-1]), {"long_name": "index of the crossing along " + along,
                                                             "units": "1"})
    if crit.output is not None:
        what = f"{crit.output} = {crit.level:g}"
    else:
        what = f"status {b.status_change[0]} -> {b.status_change[1]}"

    def var(values, unit, long_name, **attrs):
        return (odims, values.reshape(shape), {"units": unit, "long_name": long_name, **attrs})

    codes = np.array(sorted(BOUND_MEANINGS), dtype=np.int8)
    rising = ("the criterion rises through its level" if crit.output else
              f"status {b.status_change[0]} below, {b.status_change[1]} above")
    data = {
        "boundary": var(res.location, prm.unit, f"{along} ({prm.long_name}) where {what}"),
        "boundary_width": var(res.width, prm.unit, f"width of the final bracket of {along} (both ends evaluated)"),
        "boundary_bound": var(res.bound, "1", "which accuracy bound applied (-1: no crossing)",
                              flag_values=codes, flag_meanings=" ".join(BOUND_MEANINGS[c] for c in codes),
                              comment="; ".join(f"{BOUND_MEANINGS[c]}: {BOUND_DESCRIPTIONS[c]}" for c in codes)),
        "boundary_direction": var(res.direction, "1", f"+1: {rising} as {along} grows; -1 the reverse; 0 no crossing"),
        "boundary_evaluations": var(res.evaluations, "1", "criterion evaluations spent locating this crossing "
                                    "(after the grid)"),
    }
    if crit.angle_output:
        data["boundary_kind"] = var(res.kind, "1", "critical Floquet multiplier on the unstable side: +1 real "
                                    "positive, -1 real negative, 0 complex pair")
        data["boundary_angle"] = var(res.angle, "rad", "argument of the critical Floquet multiplier on the unstable "
                                     "side, in [0, pi]: on the boundary the multiplier is exp(+-i angle)")
    located = res.bound[(res.bound == PARAMETER) | (res.bound == CRITERION) | (res.bound == BAND_EDGE)]
    ev = res.evaluations[res.bound >= 0]
    created = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    attrs = {
        "Conventions": cf.CONVENTIONS,
        "title": f"boundaries of {scene.name} along {along}",
        "source": cf.source(scene.model, __version__),
        "history": cf.history(created, f"mechsweep.boundaries.run_boundaries(scene {scene.name!r})", __version__),
        "references": cf.references(scene.model),
        "mechsweep_kind": "boundaries",
        "model": scene.model.name,
        "along": along,
        # the along axis's span (its encoded grid): the scale below which a bracket's width is read
        # as absolute (|x| <= ABS_FLOOR * span, as the locator's tolerance does; `mechsweep info`)
        "along_span": float(np.ptp(_encoded(scene, axis))) if axis.size > 1 else 1.0,
        "criterion": crit.output or "status",
        **({"level": crit.level} if crit.output else {"status_change": " ".join(b.status_change)}),
        "rtol": b.rtol,
        "boundaries": str(b.as_dict()),
        "scene": scene.text,
        "scene_canonical": scene.canonical(),
        "created": created,
        "mechsweep_version": __version__,
        "wall_time_s": wall,
        "evaluate_calls": res.calls,
        "evaluated_points": res.points,
        "located": int(located.size),
        "evaluations_per_point_mean": float(ev.mean()) if ev.size else 0.0,
        "evaluations_per_point_max": int(ev.max()) if ev.size else 0,
    }
    if crit.output is not None:
        attrs["criterion_accuracy"] = accuracy_text(scene, crit)
    from .model import sources

    attrs.update(sources.record(scene.model).attrs(scene.base or None))  # what the points were computed from
    if b.continue_in is not None:
        t0 = time.perf_counter()
        cdata, ccoords, n_eval, n_calls = _continue_all(scene, crit, b, res, rows, others)
        data.update(cdata)
        coords.update(ccoords)
        attrs.update(continue_in=b.continue_in, continuation_wall_time_s=time.perf_counter() - t0,
                     continuation_evaluated_points=n_eval, continuation_calls=n_calls)
    if scene.solver is not None:
        for k, v in scene.solver.as_dict().items():
            attrs[f"solver_{k}"] = v
    return xr.Dataset(data, coords=coords, attrs=attrs)


def write_atomic(ds, target: str | os.PathLike) -> Path:
    """Write ``ds`` to ``target`` through a temporary file in the same folder and a rename: an
    existing file is replaced whole or not at all."""
    target = Path(target)
    fd, tmp = tempfile.mkstemp(prefix="." + target.name + ".", suffix=".tmp", dir=target.parent)
    os.close(fd)
    try:
        # strings (a categorical axis) as CF character arrays, as a run's dataset stores them (store.py)
        chars = {k: {"dtype": "S1"} for k, v in ds.variables.items() if v.dtype.kind in "OSUT"}
        ds.to_netcdf(tmp, engine="h5netcdf", encoding=chars)
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return target


def accuracy_warning(scene) -> str | None:
    """Why a given ``criterion_accuracy`` cannot be trusted (None: it can, or none was given): below
    about 100 rtol |level|, the accuracy the solver's rtol gives an integrated criterion, the band
    is narrower than the criterion's own error, and the search may lose boundaries or stop in the
    noise."""
    b = scene.boundaries
    if b is None or b.criterion_accuracy is None or b.criterion is None or scene.solver is None:
        return None
    if not from_integration(scene.model, b.criterion) or b.level == 0.0:
        return None
    floor = 100.0 * scene.solver.rtol * abs(b.level)
    if b.criterion_accuracy >= floor:
        return None
    return (f"boundaries.criterion_accuracy = {b.criterion_accuracy:g} is below the accuracy solver.rtol = "
            f"{scene.solver.rtol:g} gives the criterion (about 100 rtol |level| = {floor:g}): boundaries may be "
            f"lost or located in the noise; tighten solver.rtol to {b.criterion_accuracy / (100.0 * abs(b.level)):g} "
            "or less, or leave criterion_accuracy out")


def status_warning(scene) -> str | None:
    """Why a ``status_change`` criterion may locate nothing: it names a status the model does not
    list among those its points can get (``possible_statuses``: without this warning such a scene
    locates 0 boundaries with no word why). A warning, not a refusal: a model's list may be incomplete."""
    b = scene.boundaries
    if b is None or b.criterion is not None or b.status_change is None:
        return None
    listed = {st.MEANINGS[c] for c in scene.model.possible_statuses()}
    missing = [name for name in b.status_change if name not in listed]
    if not missing:
        return None
    return (f"boundaries.status_change names {', '.join(repr(m) for m in missing)}, which model "
            f"{scene.model.name!r} does not list among its statuses ({', '.join(sorted(listed))}): "
            "there may be no such boundary to locate")


def warnings_for(scene) -> list[str]:
    """What a [boundaries] section may get wrong without being invalid (accuracy, statuses)."""
    return [text for text in (accuracy_warning(scene), status_warning(scene)) if text]


def run_boundaries(scene_or_path, *, data=None, output=None, threads=None, progress=False, warn=True):
    """The scene's [boundaries] pass: its grid (computed, or completed with resume, unless finished),
    then the located boundaries, written atomically to ``output`` (default: DATA.boundaries.h5).
    The grid's dataset is only read. Returns (path written, the boundaries Dataset). ``warn``: a
    UserWarning for each of ``warnings_for`` (the CLI prints them itself)."""
    from .errors import InputError
    from .runner import _threads, compute
    from .scene import Scene, load_scene
    from .store import StoreError, open_dataset

    scene = scene_or_path if isinstance(scene_or_path, Scene) else load_scene(scene_or_path)
    if scene.boundaries is None:
        raise InputError(f"scene {scene.name!r} has no [boundaries] section; add one, e.g. "
                         "[boundaries] along = \"AXIS\", criterion = \"OUTPUT\", level = 1.0")
    for text in warnings_for(scene) if warn else ():
        import warnings
        warnings.warn(text, UserWarning, stacklevel=2)
    data = Path(data if data is not None else scene.storage.path)
    target = Path(output) if output is not None else sibling_path(data)
    if target.resolve() == data.resolve():
        raise StoreError(f"boundaries output {target} is the grid's dataset itself; choose another path with -o")
    if not target.parent.is_dir():
        raise StoreError(f"the folder {target.parent} for output {target} does not exist; create it first")
    if target.exists() and not target.is_file():
        raise StoreError(f"{target} exists and is not a regular file; choose another path with -o")
    if target.is_file():
        with open(target, "rb") as f:
            head = f.read(8)
        if head and head != b"\x89HDF\r\n\x1a\n":
            raise StoreError(f"{target} exists and is not an HDF5 dataset; it would be overwritten: "
                             "choose another path with -o")
    compute(scene, output=data, resume=True, threads=threads, progress=progress)
    ds = open_dataset(data)
    with _threads(threads):
        out = locate_dataset(scene, ds)
    return write_atomic(out, target), out


# ----------------------------------------------------------------------------- continuation in two parameters
@dataclass
class Curve:
    """A boundary followed in two parameters: points (x, y) in order, the folds met (where the
    curve turns back along x or along y: two boundaries of a one-axis search meet there), why it
    stopped, and its cost."""

    points: np.ndarray  # (n, 2)
    folds: list  # (x, y, axis name, located): the tangent's component along that axis vanishes there
    stop: str  # "edge", "closed", "max_points", "step_too_small", "no_value"
    evaluations: int
    calls: int


def continue_boundary(scene, crit: Criterion, row: np.ndarray, x_name: str, y_name: str, start, *,
                      box=None, step: float = 0.02, step_min: float = 1e-7, step_max: float = 0.05,
                      max_points: int = 2000, tol: float = 1e-10, direction: int = 0, log=None) -> Curve:
    """Follow g(x, y) = criterion - level = 0 from ``start`` (a point on it, e.g. located along one
    axis) by pseudo-arclength continuation, through folds, until it leaves ``box`` ((x_lo, x_hi),
    (y_lo, y_hi); default: the scene's axes) or closes.

    Works in the box's scaled coordinates (both spans 1; log10 of a coordinate whose scene axis is
    log-spaced, or as ``log`` = (bool, bool) says). Predictor: a step ``step`` along the unit
    tangent; corrector: Newton on (g = 0, tangent . (p - predicted) = 0) with the gradient by forward
    differences (step 1e-7 of the span), its three evaluations in one call; converged when the
    Newton step is below ``tol`` (of the span) and |g| within the criterion's accuracy. The step grows
    1.5x after a corrector of at most 2 iterations, and halves (down to ``step_min``) when the
    corrector fails or the tangent turns by more than 30 degrees. The last point is on the box's
    edge (Newton with that coordinate fixed). Only criteria that change sign (not band edges or
    status changes) can be continued this way. ``direction``: +1 / -1 along the tangent (-g_y, g_x),
    0 (default) away from the box's nearest edge."""
    names = scene.model.param_names()
    cx, cy = names.index(x_name), names.index(y_name)
    if box is None:
        box = tuple(tuple(sorted(float(v) for v in next(a for a in scene.axes if a.name == n).ends))
                    for n in (x_name, y_name))
    if log is None:  # log coordinates along an axis the scene spaces logarithmically
        log = tuple(any(a.name == n and a.spacing == "log" for a in scene.axes) for n in (x_name, y_name))
    logs = np.array(log, dtype=bool)
    edges = np.array(box, dtype=float)
    edges[logs] = np.log10(edges[logs])
    lo, span = edges[:, 0], edges[:, 1] - edges[:, 0]
    ev = _Evaluator(scene, crit, np.asarray(row, dtype=float)[None, :], cx)
    h = 1e-7

    def to_xy(us):
        xy = lo + np.asarray(us) * span
        return np.where(logs, 10.0 ** np.where(logs, xy, 0.0), xy)  # no power of a linear coordinate (overflow)

    def evaluate(us):
        P = np.repeat(ev.rows, len(us), axis=0)
        xy = to_xy(us)
        P[:, cx], P[:, cy] = xy[:, 0], xy[:, 1]
        g, _, _ = ev.at(P)
        return g

    def g_grad(u):
        g = evaluate([u, u + [h, 0.0], u + [0.0, h]])
        return g[0], np.array([(g[1] - g[0]) / h, (g[2] - g[0]) / h])

    def eps_of(g):
        return criterion_accuracy(scene.model, scene.solver, crit, np.array([g + crit.level]))[0]

    def correct(u, t, pred, fixed=None):
        """Newton from u; returns (point, gradient, iterations) or None."""
        for it in range(1, 9):
            g0, G = g_grad(u)
            if not (np.isfinite(g0) and np.isfinite(G).all()):
                return None
            if fixed is None:
                J = np.array([G, t])
                rhs = -np.array([g0, t @ (u - pred)])
            else:  # one coordinate held on the box's edge
                J = np.array([G, [1.0, 0.0] if fixed == 0 else [0.0, 1.0]])
                rhs = -np.array([g0, 0.0])
            try:
                du = np.linalg.solve(J, rhs)
            except np.linalg.LinAlgError:
                return None
            u = u + du
            if np.abs(du).max() <= tol and abs(g0) <= eps_of(g0):
                return u, G, it
        return None

    def tangent(G, previous):
        t = np.array([-G[1], G[0]]) / np.hypot(*G)
        return t if previous @ t >= 0 else -t

    def fold_between(u, t, q, tq, k):
        """The fold between the curve points u and q (tangents t, tq; component k changes sign):
        the point of the curve where the tangent's k-th component vanishes, i.e. the curve's
        extremum in coordinate k. Illinois on that component over the chord u -> q, each trial
        point corrected onto the curve in the plane normal to the chord. The component comes from
        forward-difference gradients (noise ~ criterion accuracy / h), so the bracket stops at
        FOLD_TOL of the chart; the extremal coordinate, quadratic in the position along the curve
        there, is then exact to the corrector's tolerance. None where a correction fails."""
        d = q - u
        chord = d / np.hypot(*d)
        f0, s0, f1, s1 = 0.0, t[k], 1.0, tq[k]
        at = None
        for _ in range(60):
            f = f1 - s1 * (f1 - f0) / (s1 - s0)
            if not 0.0 < f < 1.0 or not np.isfinite(f):
                f = 0.5 * (f0 + f1)
            pred = u + f * d
            got = correct(pred.copy(), chord, pred)
            if got is None:
                return None
            at, G, _ = got
            sf = tangent(G, chord)[k]
            if sf == 0.0:
                return at
            if sf * s1 < 0:  # the fold lies between f and f1
                f0, s0 = f1, s1
            else:  # Illinois: the end kept has its value halved
                s0 *= 0.5
            f1, s1 = f, sf
            if abs(f1 - f0) * np.hypot(*d) <= FOLD_TOL:
                return at
        return at

    start = np.asarray(start, dtype=float)
    # no logarithm of a linear coordinate (a start at 0 on a linear axis warned of a division by zero)
    u = (np.where(logs, np.log10(np.where(logs, np.abs(start), 1.0)), start) - lo) / span
    g0, G = g_grad(u)
    t = np.array([-G[1], G[0]]) / np.hypot(*G)
    if direction == 0:  # into the box: away from the nearest edge
        near = np.where(u - 0.5 > 0, 1.0 - u, u)
        k = int(np.argmin(near))
        inward = -1.0 if u[k] > 0.5 else 1.0
        direction = 1 if t[k] * inward >= 0 else -1
    t = t * (1 if direction > 0 else -1)
    pts, folds, stop = [u.copy()], [], "max_points"
    s = step
    while len(pts) < max_points:
        pred = u + s * t
        got = correct(pred.copy(), t, pred)
        if got is not None:
            q, Gq, it = got
            tq = tangent(Gq, t)
            if tq @ t < math.cos(math.radians(30)):
                got = None
        if got is None:
            s *= 0.5
            if s < step_min:
                stop = "step_too_small" if g_grad(u)[0] == g_grad(u)[0] else "no_value"
                break
            continue
        outside = (q < 0) | (q > 1)
        if outside.any():
            k = int(np.argmax(outside))  # the coordinate that left the box first
            edge = 0.0 if q[k] < 0 else 1.0
            f = (edge - u[k]) / (q[k] - u[k])
            e = u + f * (q - u)
            e[k] = edge
            got = correct(e, t, e, fixed=k)
            if got is not None:
                pts.append(got[0])
            stop = "edge"
            break
        for k, name in ((0, x_name), (1, y_name)):
            if tq[k] * t[k] < 0:  # the curve turned back along this axis between u and q
                at = fold_between(u, t, q, tq, k)
                if at is None:  # a correction failed: between the two points, as their tangents say
                    f = t[k] / (t[k] - tq[k])
                    folds.append(tuple(to_xy(u + f * (q - u))) + (name, False))
                else:
                    folds.append(tuple(to_xy(at)) + (name, True))
        if len(pts) > 3 and np.hypot(*(q - pts[0])) < s:
            pts.append(q)
            stop = "closed"
            break
        pts.append(q)
        u, t = q, tq
        if it <= 2:
            s = min(1.5 * s, step_max)
    return Curve(points=to_xy(np.array(pts)), folds=folds, stop=stop, evaluations=ev.points, calls=ev.calls)


CURVE_STOPS = ("edge", "closed", "max_points", "step_too_small", "no_value")
# where a fold's bracket stops, in the chart's scaled coordinates (both spans 1): the tangent there
# comes from forward differences, so its zero is not known better; the fold's extremal coordinate
# moves by the square of this (times the curve's curvature)
FOLD_TOL = 1e-7


def _crosses_near(points: np.ndarray, x: float, y: float, span_x: float) -> bool:
    """Whether the polyline ``points`` (n, 2) crosses the line at ``y`` within 1e-3 of the span plus
    the crossing segment's own extent along x of ``x`` (the start lies on a curve already followed)."""
    px, py = points[:, 0], points[:, 1]
    for k in np.flatnonzero((py[:-1] - y) * (py[1:] - y) <= 0):
        dy = py[k + 1] - py[k]
        xc = px[k] if dy == 0 else px[k] + (y - py[k]) / dy * (px[k + 1] - px[k])
        if abs(xc - x) <= 1e-3 * span_x + abs(px[k + 1] - px[k]):
            return True
    return False


def _continue_all(scene, crit, b, res: Located, rows: np.ndarray, others: tuple):
    """Follow, for every combination of the axes other than (along, continue_in), each boundary
    located (by a sign change) on the lines at both ends of the continue_in axis, skipping a start
    that lies on a curve already followed; then, both ways, each one located on an inner line that
    no curve followed so far crosses (a boundary touching neither end line, e.g. an island).
    Returns (variables, coordinates, points, calls)."""
    along, cont = b.along, b.continue_in
    names = [a.name for a in others]
    ci = names.index(cont)
    sizes = [a.size for a in others]
    C = res.location.shape[1]
    loc = np.moveaxis(res.location.reshape(sizes + [C]), ci, -2)
    ok = np.moveaxis(np.isin(res.bound, (PARAMETER, CRITERION)).reshape(sizes + [C]), ci, -2)
    R = np.moveaxis(rows.reshape(sizes + [rows.shape[1]]), ci, -2)
    cvals = _encoded(scene, others[ci])
    rest = loc.shape[:-2]
    box = tuple(tuple(sorted(float(v) for v in next(a for a in scene.axes if a.name == n).ends)) for n in (along, cont))
    span = np.array([box[0][1] - box[0][0], box[1][1] - box[1][0]])
    found, n_eval, n_calls = {}, 0, 0
    for r in np.ndindex(*rest):
        curves = []
        for end in (0, -1):
            for x in loc[r][end][ok[r][end]]:
                start = np.array([x, cvals[end]])
                if any(np.min(np.hypot(*((c.points - start) / span).T)) < 1e-6 for c in curves):
                    continue  # already on a curve followed from elsewhere
                c = continue_boundary(scene, crit, R[r][end], along, cont, start, box=box)
                n_eval += c.evaluations
                n_calls += c.calls
                curves.append(c)
        # then a boundary touching neither end line (e.g. an island): from a crossing located on an
        # inner line that no curve followed so far passes through, both ways
        for j in range(1, len(cvals) - 1):
            for x in loc[r][j][ok[r][j]]:
                if any(_crosses_near(c.points, x, cvals[j], span[0]) for c in curves):
                    continue
                for d in (1, -1):
                    c = continue_boundary(scene, crit, R[r][j], along, cont, np.array([x, cvals[j]]), box=box,
                                          direction=d)
                    n_eval += c.evaluations
                    n_calls += c.calls
                    curves.append(c)
        found[r] = curves
    K = max([len(c) for c in found.values()] + [0])
    N = max([len(c.points) for cs in found.values() for c in cs] + [0])
    F = max([len(c.folds) for cs in found.values() for c in cs] + [0])
    cx, cy = np.full(rest + (K, N), np.nan), np.full(rest + (K, N), np.nan)
    stop = np.full(rest + (K,), -1, dtype=np.int8)
    fx, fy = np.full(rest + (K, F), np.nan), np.full(rest + (K, F), np.nan)
    faxis = np.full(rest + (K, F), -1, dtype=np.int8)
    flocated = np.full(rest + (K, F), -1, dtype=np.int8)
    for r, cs in found.items():
        for k, c in enumerate(cs):
            cx[r + (k, slice(0, len(c.points)))] = c.points[:, 0]
            cy[r + (k, slice(0, len(c.points)))] = c.points[:, 1]
            stop[r + (k,)] = CURVE_STOPS.index(c.stop)
            for j, (x, y, ax, located) in enumerate(c.folds):
                fx[r + (k, j)], fy[r + (k, j)], faxis[r + (k, j)] = x, y, 0 if ax == along else 1
                flocated[r + (k, j)] = int(located)
    rest_dims = tuple(n for n in names if n != cont)
    pa, pc = scene.model.param(along), scene.model.param(cont)
    codes = np.arange(len(CURVE_STOPS), dtype=np.int8)
    data = {
        f"curve_{along}": (rest_dims + ("curve", "point"), cx,
                           {"units": pa.unit, "long_name": f"{along} along the continued boundary (NaN after its end)"}),
        f"curve_{cont}": (rest_dims + ("curve", "point"), cy,
                          {"units": pc.unit, "long_name": f"{cont} along the continued boundary (NaN after its end)"}),
        "curve_stop": (rest_dims + ("curve",), stop,
                       {"units": "1", "long_name": "why the continuation stopped (-1: no curve)", "flag_values": codes,
                        "flag_meanings": " ".join(CURVE_STOPS),
                        "comment": "edge: it left the chart (last point on its edge); closed: it came back to its "
                                   "start; step_too_small: the boundary ends or has a corner here (two boundaries "
                                   "ending at one point meet there)"}),
        f"fold_{along}": (rest_dims + ("curve", "fold"), fx, {"units": pa.unit, "long_name": f"{along} at a fold"}),
        f"fold_{cont}": (rest_dims + ("curve", "fold"), fy, {"units": pc.unit, "long_name": f"{cont} at a fold"}),
        "fold_axis": (rest_dims + ("curve", "fold"), faxis,
                      {"units": "1", "long_name": f"the axis the curve turns back along at the fold: 0 {along}, "
                                                  f"1 {cont} (-1: no fold)"}),
        "fold_located": (rest_dims + ("curve", "fold"), flocated,
                         {"units": "1", "long_name": "whether the fold was located on the curve (1), or, where a "
                                                     "correction failed there, interpolated between the two curve "
                                                     "points around it (0); -1: no fold"}),
    }
    coords = {"curve": ("curve", np.arange(K), {"units": "1", "long_name": "index of the continued boundary"}),
              "point": ("point", np.arange(N), {"units": "1", "long_name": "index of the point along the curve"}),
              "fold": ("fold", np.arange(F), {"units": "1", "long_name": "index of the fold along the curve"})}
    return data, coords, n_eval, n_calls
