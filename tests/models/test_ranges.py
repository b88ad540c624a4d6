"""Every built-in model over its declared parameter ranges, edges included (log-spaced magnitudes from
the smallest subnormal to the largest double where a range spans decades): a point with status ok has
finite outputs that agree with an independent reference (mpmath closed forms in 40 digits, with their
unbounded exponent range, for the Duffing, torsional-circuit and auto-balancer formulas; quadrature for
the exact-moment period; for the linkages the same design at ordinary magnitudes, scaled back by the
outputs' units, and the numpy reference implementation there). An overflow or underflow anywhere is
flagged (out_of_range, or nonfinite where an output itself is beyond double precision), never ok.

Agreement: |value - reference| <= tol |reference| + 4 * 2^-1074 (a value below double precision's
normal range can only be right to the resolution of zero); tol scales with the condition of the
formula at the point (cancellation in omega^2 + mu A^2, chi and xi, c - M Omega^2)."""
from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.models import autobalancer as ab
from mechsweep.models import duffing, fourbar_balancing, slidercrank_balancing
from mechsweep.models import torsional_circuit as tc
from mechsweep.models import _linkage_reference as LR
from tests import evaluating

U = 2.0**-53
TINY = 4 * 2.0**-1074
DBL_MAX = 1.7976931348623157e308
# magnitudes sampled on a range (0, inf): subnormal, the edges of the normal range, and decades between
EDGES = (5e-324, 1e-310, 2.2250738585072014e-308, 1e-300, 1e-200, 1e-154, 1e-100, 1e-30, 1e-8, 0.37, 1.0, 3.0,
         1e8, 1e30, 1e100, 1e154, 1e200, 1e300, 8.98846567431158e307, DBL_MAX)


def run(spec, P, outputs, **solver):
    """spec.evaluate as the runner applies it: an ok point with an output that is not finite is
    nonfinite (execute.evaluate_chunk)."""
    out, status, _, _ = evaluating.evaluate(spec, P, spec.closure(outputs), quiet=True, **solver)
    n = status.size
    out = {k: out[k] for k in outputs}
    finite = np.ones(n, dtype=bool)
    for values in out.values():
        finite &= np.isfinite(values.reshape(n, -1)).all(axis=1)
    status[(status == st.OK) & ~finite] = st.NONFINITE
    return out, status


def agrees(value, ref, tol):
    """value (a double) against ref (an mpf, or a float): within tol relative, or to the resolution of
    zero; a reference beyond double precision's range must not be given as a finite value."""
    if not mp.isfinite(ref):
        return not math.isfinite(value)
    if abs(ref) > DBL_MAX:
        return False  # an ok point never carries it: the output overflows
    return abs(mp.mpf(value) - ref) <= tol * abs(ref) + TINY


def beyond(ref):
    return not mp.isfinite(ref) or abs(ref) > DBL_MAX


def check_points(rows, status, out, refs, expected_status, tols, label):
    """Every ok point agrees with its reference (each output); every nonfinite point has an output whose
    reference is beyond double precision; statuses of the references' own (expected_status) match."""
    bad = []
    n_ok = 0
    for i, row in enumerate(rows):
        code, ref = int(status[i]), refs[i]
        want = expected_status[i]
        if want != st.OK:
            if code != want and code != st.OUT_OF_RANGE:
                bad.append((row, "status", st.MEANINGS[code], "expected", st.MEANINGS[want]))
            continue
        if code == st.OK:
            n_ok += 1
            for name, r in ref.items():
                if not agrees(out[name][i], r, tols[i].get(name, tols[i]["default"])):
                    bad.append((row, name, out[name][i], mp.nstr(r, 17)))
        elif code == st.NONFINITE:
            if not any(beyond(r) for r in ref.values()):
                bad.append((row, "nonfinite without an output beyond the range"))
        elif code not in (st.OUT_OF_RANGE, st.ILL_CONDITIONED):
            bad.append((row, "status", st.MEANINGS[code]))
    assert not bad, f"{label}: {len(bad)} of {len(rows)} points wrong, e.g. {bad[:5]}"
    return n_ok


# ----------------------------------------------------------------------------- Duffing (and the two-term forms)
def duffing_reference(o2, mu, A):
    """(status, outputs, condition) of the Duffing closed forms at omega^2 = o2, mu, A (mpf)."""
    if A == 0:
        return st.NO_MOTION, {}, 1
    if not o2 > 0:
        return st.INFEASIBLE, {}, 1
    q = mu * A * A
    s = o2 + q
    if not s > 0:
        return st.NOT_OSCILLATORY, {}, 1
    T = 4 * mp.ellipk(q / (2 * s)) / mp.sqrt(s)
    v = A * mp.sqrt(o2 + q / 2)
    acc = A * s if (mu >= 0 or 3 * (-mu) * A * A <= o2) else 2 * o2 * mp.sqrt(o2) / (3 * mp.sqrt(-3 * mu))
    out = {"period_exact": T, "v_max": v, "a_max": acc, "kv": v * T / A, "ka": acc * T * T / A, "epsilon": q / o2}
    return st.OK, out, (o2 + abs(q)) / s  # the rounding of omega^2 and mu A^2 against their sum


def duffing_rows(rng, n):
    signed = (0.0,) + EDGES + tuple(-x for x in EDGES)
    rows = [(1.0, 1e308, 1.0), (1.0, 1e308, 1e200), (1e-300, 1.0, 1.0), (1e300, 1.0, 1.0), (1.0, -0.5, 1.0),
            (1e-160, 1e-160, 1e-160), (1e160, -1e300, 1e-140), (5e-324, 5e-324, DBL_MAX)]
    with np.errstate(over="ignore"):
        for _ in range(n):
            rows.append((rng.choice(EDGES) * rng.uniform(0.5, 2.0), rng.choice(signed) * rng.uniform(0.5, 2.0),
                         rng.choice((0.0,) + EDGES) * rng.uniform(0.5, 2.0)))
    return [tuple(min(abs(float(x)), DBL_MAX) * math.copysign(1.0, x) for x in r) for r in rows]


def test_duffing_closed_forms_over_the_whole_declared_range():
    """400 points over omega in (0, inf), mu in (-inf, inf), A in [0, inf), edges included; the
    reported point (omega = 1, mu = 1e308, A = 1: period_exact was 18 % off with status ok)."""
    rng = np.random.default_rng(7)
    rows = duffing_rows(rng, 400)
    names = ("period_exact", "v_max", "a_max", "kv", "ka", "epsilon")
    out, status = run(duffing.SPEC, rows, names)
    refs, expected, tols = [], [], []
    with mp.workdps(40):
        for omega, mu, A in rows:
            code, ref, cond = duffing_reference(mp.mpf(omega) ** 2, mp.mpf(mu), mp.mpf(A))
            refs.append(ref)
            expected.append(code)
            tols.append({"default": 64 * U * cond})
    assert status[0] == st.OK and out["period_exact"][0] == pytest.approx(7.416298709205487e-154, rel=1e-14)
    n_ok = check_points(rows, status, out, refs, expected, tols, "duffing closed forms")
    assert n_ok >= 120


def test_duffing_integrated_period_over_the_whole_declared_range():
    """The integrated period at 60 points over the whole range: within 2 rtol of the closed form in
    40 digits wherever ok (out_of_range only where the period itself is beyond about 1e+-308 s)."""
    rng = np.random.default_rng(8)
    rows = [r for r in duffing_rows(rng, 200) if r[2] != 0.0][:60]
    out, status = run(duffing.SPEC, rows, ("period",))
    refs, expected, tols = [], [], []
    with mp.workdps(40):
        for omega, mu, A in rows:
            code, ref, cond = duffing_reference(mp.mpf(omega) ** 2, mp.mpf(mu), mp.mpf(A))
            refs.append({"period": ref["period_exact"]} if ref else {})
            expected.append(code)
            tols.append({"default": 2 * 5e-11})
            if code == st.OK and status[len(refs) - 1] == st.OUT_OF_RANGE:
                T = ref["period_exact"]
                assert T < 1e-290 or T > 1e290, (omega, mu, A, T)  # only a period beyond the normal range
    assert check_points(rows, status, out, refs, expected, tols, "duffing period") >= 30


# ----------------------------------------------------------------------------- torsional circuit
def torsional_reference(spring, lam1, lam2, s, R, c, I, A):
    """(status, outputs, tols) of chi, xi, the dimensional coefficients and the two-term closed forms."""
    sig = 1 if spring == 0.0 else -1
    l1, l2, S = mp.mpf(lam1), mp.mpf(lam2), mp.mpf(s)
    k = mp.mpf(R) ** 2 * mp.mpf(c) / mp.mpf(I)
    D0 = (1 - sig * l1) ** 2 + l2**2
    if D0 <= mp.mpf(1e-12) * (1 + 1e-9):
        return st.SINGULAR, {}, {}
    r = mp.sqrt(D0)
    if abs(r - sig * S) <= 1e-14 * (r + abs(S)):
        return None, {}, {}  # free length 0 within the rounding of D0: either verdict is right
    if r - sig * S <= 0:
        return st.INFEASIBLE, {}, {}
    chi = l1 * S / r
    G = D0 + 3 * sig * l1
    xi = l1 * (3 * l1 - S * G / r) / (6 * D0)
    xi_terms = l1 * (3 * l1 + abs(S * G / r)) / (6 * D0)  # cancellation in 3 lambda1 - s G / r
    out = {"chi": chi, "xi": xi, "omega2": k * chi, "mu": k * xi}
    tol_xi = 256 * U * xi_terms / abs(xi) if xi != 0 else mp.inf
    tols = {"chi": 64 * U, "xi": tol_xi, "mu": tol_xi, "omega2": 64 * U, "default": 64 * U}
    if A == A:  # the two-term closed forms where A is given
        code, duf, cond = duffing_reference(k * chi, k * xi, mp.mpf(A))
        out.update(duf)
        tols["default"] = 64 * U * cond * (1 + (tol_xi / (64 * U) if math.isfinite(tol_xi) else 1e300))
        return code, out, tols
    return st.OK, out, tols


def torsional_rows(rng, n, with_A=True):
    pos = EDGES + (0.3, 0.8, 1.5, 2e-3, 2000.0) * 3  # the edges, and as many ordinary values
    signed = (0.0,) + pos + tuple(-x for x in pos)
    amps = (0.0, 1e-300, 1e-160, 1e-100, 1e-8, 0.3, 2.0, math.pi) if with_A else (math.nan,)
    rows = [(0.0, 1.0, 2e-6, 1e-6, 0.05, 2000.0, 2e-3, 0.3), (0.0, 0.8, 0.5, 1e-310, 1.0, 1.0, 1.0, 0.5),
            (0.0, 1e200, 0.0, 0.1, 1.0, 1.0, 1.0, 0.5), (1.0, 0.8, 0.5, 1e300, 1e200, 1e-200, 1e100, 1.0),
            (0.0, 0.8, 0.5, 0.1, 1e-200, 1e-200, 1e200, 0.3)]
    for _ in range(n):
        rows.append((float(rng.integers(2)), rng.choice(pos + (0.8, 1.0, 1.2)), rng.choice((0.0,) + pos + (0.5,)),
                     rng.choice(signed + (0.1, -0.1)), rng.choice(pos), rng.choice(pos), rng.choice(pos),
                     rng.choice(amps)))
    return rows if with_A else [r[:7] + (math.nan,) for r in rows]


@pytest.mark.parametrize("with_A", [False, True], ids=["coefficients", "two-term"])
def test_torsional_closed_forms_over_the_whole_declared_range(with_A):
    """300 points over lambda1, lambda2, s0_over_r, R, c, I (0 to the largest double), both springs and
    A in [0, pi]: chi, xi, omega2, mu and the two-term Duffing closed forms agree with 40 digits
    wherever ok (chi, xi were 0 or NaN at lambda1 = 1e200 with status ok; k = R^2 c / I overflowed)."""
    rng = np.random.default_rng(11 + with_A)
    rows = torsional_rows(rng, 300, with_A)
    names = ("chi", "xi", "omega2", "mu") + (("period_exact", "v_max", "a_max", "kv", "ka", "epsilon") if with_A
                                             else ())
    out, status = run(tc.SPEC, rows, names)
    refs, expected, tols, keep = [], [], [], []
    with mp.workdps(700):  # lambda1 = 1e300: (1 - lambda1)^2 + lambda2^2 in full needs 600 digits
        for i, row in enumerate(rows):
            code, ref, tol = torsional_reference(*row)
            if code is not None:
                keep.append(i)
                refs.append(ref)
                expected.append(code)
                tols.append(tol)
    rows = [rows[i] for i in keep]
    out = {k: v[keep] for k, v in out.items()}
    assert check_points(rows, status[keep], out, refs, expected, tols, "torsional closed forms") >= 30


def test_torsional_exact_moment_period_where_its_quantities_are_in_range():
    """The exact-moment period at extreme R, c, I (k = R^2 c / I from 1e-600 to 1e600) and small A:
    ok and within 1e-10 of the quadrature, or out_of_range only where the period leaves the normal
    range."""
    rows = [("tension", 0.8, 0.5, 0.1, R, c, I, A)
            for (R, c, I) in ((1e200, 1.0, 1.0), (1e-200, 1.0, 1e100), (1e150, 1e300, 1e-300), (1.0, 5e-324, 1.0))
            for A in (1e-150, 0.3)]
    P = [(0.0 if r[0] == "tension" else 1.0, *r[1:]) for r in rows]
    out, status = run(tc.SPEC, P, ("period_exact_moment",))
    from .test_torsional_circuit import quadrature_period
    for row, T, code in zip(rows, out["period_exact_moment"], status):
        ref = quadrature_period(*row)
        if code == st.OK:
            assert T == pytest.approx(ref, rel=1e-10), row
        else:
            assert code == st.OUT_OF_RANGE and not 1e-300 < ref < 1e300, (row, code, ref)
    assert (status == st.OK).sum() >= 5


# ----------------------------------------------------------------------------- auto-balancer closed forms
def autobalancer_reference(p):
    """(status, outputs) of the auto-balancer's closed forms in mpmath (None: a point whose singularity at
    an undamped resonance is the model's own decision, not checked here)."""
    v = {n: p[i] for i, n in enumerate(ab.PARAM_NAMES)}
    M, m, a, IB, A0, Om = (mp.mpf(v[k]) for k in ("M", "m", "a", "I_B", "A0", "Omega"))

    def axis(om, c, b, zeta):
        om = mp.sqrt(mp.mpf(c) / M) if math.isnan(om) else mp.mpf(om)
        c = M * om * om if math.isnan(c) else mp.mpf(c)
        b = 2 * mp.mpf(zeta) * M * om if math.isnan(b) else mp.mpf(b)
        return om, c, b
    wx, cx, bx = axis(v["omega_xi"], v["c_xi"], v["b_xi"], v["zeta_xi"])
    wy, cy, by = axis(v["omega_eta"], v["c_eta"], v["b_eta"], v["zeta_eta"])
    if not (IB >= m * a * a * (1 - ab.IB_SLACK) and M > 2 * m):
        return st.INFEASIBLE, {}, {}
    two_ma = 2 * m * a
    out = {"theta": mp.acos(max(-1, min(1, -A0 / two_ma))), "omega_p": mp.sqrt((wx * wx + wy * wy) / 2)}
    lo, hi = min(wx, wy), max(wx, wy)
    out["stable_first_approx"] = mp.mpf(1 if (lo < Om < out["omega_p"]) or Om > hi else 0)
    total, cond = mp.mpf(0), mp.mpf(1)
    for c, b in ((cx, bx), (cy, by)):
        d = c - M * Om * Om
        if d == 0 and b == 0:
            return None, {}, {}
        total += d / (d * d + (b * Om) ** 2)
        cond = max(cond, (c + M * Om * Om) / abs(d) if d != 0 else 1)
    out["P_approx"] = total
    out["stable_damped_approx"] = mp.mpf(1 if total < 0 else 0)
    code = st.OK if A0 <= two_ma else st.NOT_BALANCEABLE
    tols = {"default": 64 * U, "P_approx": 64 * U * cond}
    if code != st.OK:
        out.pop("theta")
    return code, out, tols


def autobalancer_rows(rng, n):
    rows = []
    names = ab.PARAM_NAMES
    mixed = EDGES + (0.05, 1.0, 20.0, 300.0) * 4  # the edges, and as many ordinary values
    for _ in range(n):
        v = {k: math.nan for k in names}
        v["A1"] = 0.0
        m, a = rng.choice(mixed), rng.choice(mixed)
        v.update(m=m, a=a, M=m * rng.choice((2.5, 10.0, 1e30, 1e200)),
                 I_B=m * a * a * rng.choice((1.0, 1.3, 1e20)), A0=2 * m * a * rng.choice((0.0, 0.3, 0.99, 3.0)),
                 h=rng.choice((0.0,) + mixed), Omega=rng.choice(mixed))
        if rng.random() < 0.5:
            v.update(omega_xi=rng.choice(mixed), omega_eta=rng.choice(mixed), zeta_xi=rng.choice((0.0, 0.02, 1e-200)),
                     zeta_eta=rng.choice((0.0, 0.02, 1e100)))
        else:
            v.update(c_xi=rng.choice(mixed), c_eta=rng.choice(mixed), b_xi=rng.choice((0.0,) + mixed),
                     b_eta=rng.choice((0.0,) + mixed))
        row = tuple(min(float(v[k]), DBL_MAX) for k in names)
        if all(ab.PARAMS[j].problem(x) is None or math.isnan(x) for j, x in enumerate(row)):  # declared ranges
            rows.append(row)
    return rows


def test_autobalancer_closed_forms_over_the_whole_declared_range():
    """400 points, every parameter from the smallest subnormal to the largest double (omega_p was 0 at
    omega_xi = omega_eta = 1e-200 and P_approx 0 at c_xi = 1e160, status ok)."""
    rng = np.random.default_rng(13)
    rows = autobalancer_rows(rng, 400)
    names = ("theta", "balanceable", "omega_p", "stable_first_approx", "P_approx", "stable_damped_approx")
    out, status = run(ab.SPEC, rows, names)
    refs, expected, tols, keep = [], [], [], []
    with mp.workdps(40):
        for i, row in enumerate(rows):
            code, ref, tol = autobalancer_reference(row)
            if code is None or status[i] == st.SINGULAR:
                continue  # an undamped resonance: the model's singularity test decides it
            keep.append(i)
            refs.append(ref)
            expected.append(code)
            tols.append(tol)
    sel = [rows[i] for i in keep]
    sub = {k: v[keep] for k, v in out.items()}
    # theta is NaN (not_balanceable) where A0 > 2 m a: compare the balanced points' outputs
    assert check_points(sel, status[keep], sub, refs, expected, tols, "autobalancer closed forms") >= 30


# ----------------------------------------------------------------------------- linkages: similar designs
def unit_exponents(spec):
    """(kg, m, s) powers of each parameter and output, written out here (not read from the model)."""
    table = {"": (0, 0, 0), "1": (0, 0, 0), "%": (0, 0, 0), "rad": (0, 0, 0), "m": (0, 1, 0), "kg": (1, 0, 0),
             "kg m": (1, 1, 0), "kg m2": (1, 2, 0), "N": (1, 1, -2), "N m": (1, 2, -2), "m s-2": (0, 1, -2),
             "rad s-1": (0, 0, -1)}
    return ({p.name: table["" if p.categorical else p.unit] for p in spec.params},
            {o.name: table[o.unit] for o in spec.outputs})


LINKAGE_BASE = {
    "fourbar_balancing": dict(a1=0.1, a2=0.35, a3=0.3, a4=0.4, m1=1.0, r1=0.03, I1=0.002, m2=2.0, r2=0.15,
                              theta2=0.2, I2=0.02, m3=1.5, r3=0.12, I3=0.01, omega=10.0, delta=0.1, g=9.81,
                              M_load=2.0, cw1_mr=0.05, cw1_angle=3.0, cw3_mr=0.02, cw3_angle=2.5),
    "slidercrank_balancing": dict(r=0.1, l=0.35, e=0.02, m1=1.0, r1=0.03, I1=0.002, m2=2.0, r2=0.15, theta2=0.1,
                                  I2=0.02, m3=1.5, omega=10.0, delta=0.1, g=9.81, F_load=5.0, k=0.5),
}


def linkage_row(spec, values):
    return [values.get(p.name, p.default if p.default is not None else math.nan) for p in spec.params]


@pytest.mark.parametrize("model", ["fourbar_balancing", "slidercrank_balancing"])
def test_linkage_design_at_any_scale_is_the_design_at_unit_scale(model):
    """A design scaled by powers of two in mass, length and time (to 2^+-1000: masses of 1e-300 kg or
    1e300, links of 1e-300 m) gives every output of the same design at ordinary scale, scaled by the
    output's units; where that would leave double precision the point is out_of_range or nonfinite,
    never ok. (Before, loads of 1e-160 N squared to 0: RMS values 0 with status ok.)"""
    spec = {"fourbar_balancing": fourbar_balancing.SPEC, "slidercrank_balancing": slidercrank_balancing.SPEC}[model]
    pw, ow = unit_exponents(spec)
    rng = np.random.default_rng(17)
    base = LINKAGE_BASE[model]
    scalings = [(0, 0, 0), (1000, 0, 0), (-1000, 0, 0), (0, 480, 0), (0, -480, 0), (0, 0, 500), (0, 0, -480),
                (600, -200, 200)]
    scalings += [tuple(int(x) for x in rng.integers(-1000, 1001, 3) // (1, 3, 3)) for _ in range(40)]
    rows, ref_rows, kept = [], [], []
    for a, c, t in scalings:
        values = {}
        for name, x in base.items():
            e = a * pw[name][0] + c * pw[name][1] + t * pw[name][2]
            values[name] = float(np.ldexp(x, e))
        if not values.get("g", 0.0) <= 100.0:  # g is declared in [0, 100]: slow the design's clock instead
            values["g"] = 0.0
        if not all(2.2250738585072014e-308 <= abs(x) <= DBL_MAX
                   for n, x in values.items() if base[n] != 0.0 and n != "g"):
            continue  # an input itself beyond double precision (an inertia of 2^2000 kg m2): not a similar design
        rows.append(linkage_row(spec, values))
        ref_rows.append(linkage_row(spec, {**base, "g": base["g"] if values["g"] else 0.0}))
        kept.append((a, c, t))
    names = tuple(o.name for o in spec.outputs if not o.extra_dims) + ("M_phi",)
    out, status = run(spec, rows, names)
    ref, ref_status = run(spec, ref_rows, names)
    assert (ref_status == st.OK).all()
    n_ok = 0
    for i, (a, c, t) in enumerate(kept):
        if status[i] != st.OK:
            assert status[i] in (st.OUT_OF_RANGE, st.NONFINITE), (kept[i], st.MEANINGS[int(status[i])])
            if status[i] == st.NONFINITE:  # some output itself beyond the range
                assert any(np.ldexp(np.nanmax(np.abs(ref[name][i])), a * ow[name][0] + c * ow[name][1]
                                    + t * ow[name][2]) > 1e300 for name in names), kept[i]
            continue
        n_ok += 1
        for name in names:
            e = a * ow[name][0] + c * ow[name][1] + t * ow[name][2]
            want = np.ldexp(ref[name][i], e)
            got = out[name][i]
            scale = np.ldexp(np.nanmax(np.abs(ref[name][i])), e) if name == "M_phi" else 0.0
            ok = np.abs(got - want) <= 1e-12 * np.abs(want) + 1e-12 * scale + TINY
            assert ok.all(), (model, kept[i], name, got, want)
    assert n_ok >= 20


@pytest.mark.parametrize("model", ["fourbar_balancing", "slidercrank_balancing"])
def test_linkage_extreme_design_against_the_numpy_reference(model):
    """The independent numpy implementation (models/_linkage_reference.py) at the design's ordinary
    scale, scaled by units, against the model at the extreme scale."""
    spec = {"fourbar_balancing": fourbar_balancing.SPEC, "slidercrank_balancing": slidercrank_balancing.SPEC}[model]
    pw, ow = unit_exponents(spec)
    base = dict(LINKAGE_BASE[model], g=0.0)
    if model == "fourbar_balancing":
        base = dict(base, delta=0.0)
        numpy_ref = LR.numpy_fourbar
        names = ("M_rms_static", "M_max_static", "axis_x", "axis_y", "dM_rms_axis", "dM_max_axis", "R_axis")
    else:
        base = dict(base, e=0.0, F_load=0.0)
        numpy_ref = LR.numpy_slider
        names = ("F_max", "Fx_rms", "F_tb_error_rel")
    ref = numpy_ref(np.array([linkage_row(spec, base)]), 360)
    for a, c, t in ((300, -200, 100), (-300, 200, -100), (600, -300, 0), (-600, 300, 0), (0, 0, 450)):
        values = {n: float(np.ldexp(x, a * pw[n][0] + c * pw[n][1] + t * pw[n][2])) for n, x in base.items()}
        out, status = run(spec, [linkage_row(spec, values)], names)
        assert status[0] == st.OK, (a, c, t, st.MEANINGS[int(status[0])])
        for name in names:
            want = float(np.ldexp(ref[name][0], a * ow[name][0] + c * ow[name][1] + t * ow[name][2]))
            assert out[name][0] == pytest.approx(want, rel=1e-9, abs=TINY), (a, c, t, name)


@pytest.mark.parametrize("model", ["fourbar_balancing", "slidercrank_balancing"])
def test_linkage_single_parameters_at_their_edges(model):
    """One parameter at a time at its declared edges (subnormal, 1e-300, 1e300, the largest double),
    the others ordinary: ok points are finite and, where the parameter only adds a negligible term
    (a tiny mass, distance or inertia), equal to the design with that parameter 0; out_of_range
    where the design's lengths or masses spread beyond 2^300."""
    spec = {"fourbar_balancing": fourbar_balancing.SPEC, "slidercrank_balancing": slidercrank_balancing.SPEC}[model]
    base = LINKAGE_BASE[model]
    names = tuple(o.name for o in spec.outputs if not o.extra_dims)
    zeroable = [p.name for p in spec.params if not p.categorical and p.lo == 0.0 and not p.lo_open
                and p.name in base and p.name != "g"]
    rows, zero_rows, which = [], [], []
    for p in spec.params:
        if p.categorical or p.name not in base or p.name in ("delta", "k", "g") or p.name.startswith(("theta", "cw")):
            continue
        for x in (5e-324, 1e-300, 1e-60, 1e60, 1e300, DBL_MAX):
            rows.append(linkage_row(spec, {**base, p.name: x}))
            zero_rows.append(linkage_row(spec, {**base, p.name: 0.0}) if (x < 1 and p.name in zeroable) else None)
            which.append((p.name, x))
    out, status = run(spec, rows, names)
    zr = [r for r in zero_rows if r is not None]
    zout, zstatus = run(spec, zr, names)
    j = 0
    for i, (name, x) in enumerate(which):
        assert status[i] in (st.OK, st.OUT_OF_RANGE, st.INFEASIBLE, st.SINGULAR, st.NONFINITE), (name, x)
        if zero_rows[i] is None:
            continue
        if status[i] == st.OK and zstatus[j] == st.OK:
            for n in names:
                got, want = out[n][i], zout[n][j]
                if "angle" in n:  # an angle of +-pi is one angle
                    got, want = math.remainder(got - want, 2 * math.pi), 0.0
                assert got == pytest.approx(want, rel=1e-12, abs=1e-12 * abs(want) + TINY), (name, x, n)
        j += 1
    assert (status == st.OUT_OF_RANGE).any() and (status == st.OK).sum() >= 10


def test_ellipk_over_its_whole_argument_range():
    """special.ellipk, which every Duffing period goes through, from m = -1.8e308 (a soft spring at its
    separatrix gives m -> -inf) to 1 - 2^-53: within 8 ulps of mpmath (the AGM needs no scaling:
    sqrt(1 - m) is at most 1.3e154)."""
    from mechsweep.special import ellipk

    for m in (-DBL_MAX, -1e300, -1e100, -1e10, -3.0, -1.0, -1e-300, 0.0, 5e-324, 1e-300, 0.5, 0.9, 1 - 1e-10,
              1 - 2.0**-53):
        with mp.workdps(40):
            ref = mp.ellipk(mp.mpf(m))
        assert agrees(ellipk(m), ref, 8 * U), m


def test_autobalancer_floquet_of_a_design_at_any_scale():
    """The Floquet multiplier depends on the scaled groups of the equations of motion only: a design
    scaled by powers of two in mass, length and time gives bitwise the same floquet_max (the groups are
    quotients of the scaled inputs: exact), down to masses of 1e-200 kg and speeds of 1e90 rad/s; a
    design whose groups leave 2^+-300 (c_xi / (m Omega^2) at Omega = 1e-200) is out_of_range, never ok."""
    names = ab.PARAM_NAMES
    units = {"Omega": (0, 0, -1), "M": (1, 0, 0), "m": (1, 0, 0), "a": (0, 1, 0), "I_B": (1, 2, 0), "A0": (1, 1, 0),
             "h": (1, 2, -1), "omega_xi": (0, 0, -1), "omega_eta": (0, 0, -1), "zeta_xi": (0, 0, 0),
             "zeta_eta": (0, 0, 0)}
    base = dict(Omega=25.0, M=10.0, m=1.0, a=0.1, I_B=0.012, A0=0.1, h=0.05, omega_xi=20.0, omega_eta=30.0,
                zeta_xi=0.02, zeta_eta=0.02)

    def row(a, c, t, **over):
        v = {k: math.nan for k in names}
        v["A1"] = 0.0
        v.update({k: math.ldexp(x, a * units[k][0] + c * units[k][1] + t * units[k][2]) for k, x in base.items()})
        v.update(over)
        return [v[k] for k in names]
    scalings = ((0, 0, 0), (-660, 0, 0), (300, -200, 100), (-200, 300, -300))
    rows = [row(*k) for k in scalings] + [row(0, 0, 0, Omega=1e-200)]
    out, status = run(ab.SPEC, rows, ("floquet_max",), rtol=1e-8, atol=1e-10)
    assert (status[:4] == st.OK).all(), status
    assert (out["floquet_max"][1:4] == out["floquet_max"][0]).all(), out["floquet_max"]
    assert status[4] == st.OUT_OF_RANGE
