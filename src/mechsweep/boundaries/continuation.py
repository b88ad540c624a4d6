"""A boundary followed in two parameters (:func:`continue_boundary`): from a point located along
one axis, along the curve where the criterion meets its level, through folds, to where it ends
(the chart's edge, a closed curve, another boundary, a step too small)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .search import CRITERION, PARAMETER, Criterion, Evaluator, Located, criterion_accuracy, encoded

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
    edge the curve crosses (Newton with that coordinate fixed; near a corner the other edge when
    the curve leaves through it), inside the box. Only criteria that change sign (not band edges or
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
    ev = Evaluator(scene, crit, np.asarray(row, dtype=float)[None, :], cx)
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
            # on the curve: |g| within the criterion's accuracy, or within what a move of tol (the
            # position's own tolerance) changes it by: a criterion of level 0 has an accuracy
            # relative to |g| itself (16 ulp |g| for a closed form), which its round-off never meets
            if np.abs(du).max() <= tol and abs(g0) <= max(eps_of(g0), tol * np.hypot(*G)):
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

    def on_edge(u, q, outside):
        """The point where the curve leaves the box between u (inside) and q: Newton with one
        coordinate held on its edge, the edge the chord u -> q reaches first; when the curve
        itself leaves through the other edge of a corner (the chord cut the corner), with that
        coordinate held instead. Clipped to the box (round-off of the held coordinate's corner);
        None when no correction lands in the box."""
        reach = [((0.0 if q[k] < 0 else 1.0) - u[k]) / (q[k] - u[k]) if outside[k] else np.inf for k in (0, 1)]
        order = [int(np.argmin(reach)), int(np.argmax(reach))]
        for k in order:
            edge = 0.0 if (q[k] < 0 if outside[k] else q[k] < u[k]) else 1.0
            f = min(1.0, (edge - u[k]) / (q[k] - u[k])) if q[k] != u[k] else 1.0
            e = u + f * (q - u)
            e[k] = edge
            got = correct(e, t, e, fixed=k)
            if got is None:
                continue
            p = got[0]
            if ((p >= -tol) & (p <= 1.0 + tol)).all():
                return np.clip(p, 0.0, 1.0)
        return None

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
            end = on_edge(u, q, outside)
            if end is not None:
                pts.append(end)
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
    # in the chart's own coordinates too (10 ** (log10 of an end) can miss the end by an ulp)
    xy = np.clip(to_xy(np.array(pts)), [min(box[0]), min(box[1])], [max(box[0]), max(box[1])])
    return Curve(points=xy, folds=folds, stop=stop, evaluations=ev.points, calls=ev.calls)


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


def continue_all(scene, crit, b, res: Located, rows: np.ndarray, others: tuple):
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
    width = np.moveaxis(res.width.reshape(sizes + [C]), ci, -2)
    R = np.moveaxis(rows.reshape(sizes + [rows.shape[1]]), ci, -2)
    cvals = encoded(scene, others[ci])
    rest = loc.shape[:-2]
    box = tuple(tuple(sorted(float(v) for v in next(a for a in scene.axes if a.name == n).ends)) for n in (along, cont))
    span = np.array([box[0][1] - box[0][0], box[1][1] - box[1][0]])
    found, n_eval, n_calls = {}, 0, 0
    for r in np.ndindex(*rest):
        curves = []
        for end in (0, -1):
            for x, w in zip(loc[r][end][ok[r][end]], width[r][end][ok[r][end]]):
                start = np.array([x, cvals[end]])
                # already on a curve followed from elsewhere (its last point is on this end line, where
                # the curve left the chart): within the located bracket, or 1e-6 of the chart
                near = max(1e-6, 2.0 * float(w) / span[0]) if np.isfinite(w) else 1e-6
                if any(np.min(np.hypot(*((c.points - start) / span).T)) < near for c in curves):
                    continue
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
