"""Locate boundaries along one axis, for any model: where a criterion crosses a level, or where
the status changes from one value to another, for every combination of the other axes.

Built only on :attr:`ModelSpec.evaluate` (through ``execute.evaluate_rows`` for status changes):
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

import math
from dataclasses import dataclass

import numpy as np

from .. import status as st

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


class Evaluator:
    """Evaluates criterion classes and values at (line, x) pairs, in one call per round."""

    def __init__(self, scene, crit: Criterion, rows: np.ndarray, col: int):
        self.scene, self.crit, self.rows, self.col = scene, crit, rows, col
        self.model = scene.model
        self.calls = 0
        self.points = 0
        self.plan = None
        if crit.output is not None:
            want = (crit.output,) + ((crit.angle_output,) if crit.angle_output else ())
            self.wanted = self.model.closure(want)
            # the kernel route a run of the scene's grid takes (execution/plan.py), chosen once for every call
            from ..execution.plan import routes
            self.route = ({} if getattr(self.model, "plan", None) is None
                          else {"route": routes(scene, self.wanted, scene.n_points)})

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
            from ..execution.execute import evaluate_rows

            if self.plan is None:  # the kernels and route of a run of the scene, decided once
                from ..execution.plan import make_plan
                self.plan = make_plan(self.scene)
            _, status, _, _ = evaluate_rows(self.plan, P)
            return np.full(n, np.nan), status, kind
        solver = self.scene.solver
        out = {name: np.full((n,) + _extra(self.scene, name), np.nan) for name in self.wanted}
        status = np.zeros(n, dtype=st.DTYPE)
        ns, nr = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
        with np.errstate(all="ignore"):
            self.model.evaluate(P, self.wanted, solver, out, status, ns, nr, **self.route)
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
    ev = Evaluator(scene, crit, rows, col)
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
            idx = _retire(active, bis, A, B, n_eval, bound, tol_of)
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
            idx = _retire(active, ill, A, B, n_eval, bound, tol_of)
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


def _retire(active, which, A, B, n_eval, bound, tol_of) -> np.ndarray:
    """End the active brackets ``which[active]`` within the tolerance (PARAMETER) or out of budget
    (BUDGET); returns the positions still active."""
    idx = np.nonzero(active)[0]
    j = which[idx]
    done = (B[j] - A[j]) <= tol_of(A[j], B[j])
    bound[j[done]] = PARAMETER
    over = ~done & (n_eval[j] >= MAX_EVALUATIONS)
    bound[j[over]] = BUDGET
    active[idx[done | over]] = False
    return np.nonzero(active)[0]


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


def kind_of_angle(angle: np.ndarray) -> np.ndarray:
    """The crossing kind (+1, -1, 0 complex pair, NaN) of a critical multiplier's argument (exactly
    0 or pi for a real one: the Floquet measurement snaps it with the same test as its kind)."""
    angle = np.asarray(angle, dtype=float)
    return np.where(angle == 0.0, 1.0, np.where(angle == np.pi, -1.0, np.where(np.isnan(angle), np.nan, 0.0)))


def encoded(scene, axis) -> np.ndarray:
    prm = scene.model.param(axis.name)
    if axis.spacing == "list":
        return np.array([prm.encode(v) for v in axis.items], dtype=float)
    return axis.array()
