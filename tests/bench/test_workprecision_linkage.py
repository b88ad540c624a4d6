"""Linkage models at any number N of crank positions, and their work-precision report: kernels
against plain numpy at any N, the continuous-angle references against independent computations
(scipy quad, an FFT, the position functions), and the measured convergence: maxima ~ N^-2, RMS
values spectrally. Small samples; no wall-clock time is asserted."""
import math

import numpy as np
import pytest
import xarray as xr

from mechsweep import balancing as B
from mechsweep import cli, figures
from mechsweep import status as st
from benchmarks import linkage as bench_linkage
from mechsweep.bench import workprecision as wp
from mechsweep.bench import workprecision_linkage as wl
from mechsweep.models import _linkage as L
from mechsweep.models import _linkage_reference as R  # the references the linkage models declare
from mechsweep.models import fourbar_balancing as fb

SLIDER = dict(r=0.05, m1=2.0, r1=0.01, I1=0.002, m2=1.2, r2=0.05, I2=0.006, m3=1.5, omega=300.0)
FOURBAR = dict(a1=0.1, a2=0.35, a3=0.3, a4=0.4, m1=1.0, r1=0.05, I1=0.001, m2=2.0, r2=0.175, theta2=0.2,
               I2=0.02, m3=1.5, r3=0.15, I3=0.012, omega=20.0)
ORDER_LADDER = (90, 180, 360, 720, 1440)


# ============================================================================= kernels at any N
def test_default_positions_are_the_generic_positions_at_360():
    phi, c, s = L.crank_positions(L.N_POSITIONS)
    assert np.array_equal(phi, L.PHI) and np.array_equal(c, L.COS_PHI) and np.array_equal(s, L.SIN_PHI)
    assert np.array_equal(L.position_sums(c, s), L.SUMS)
    _, c45, s45 = L.crank_positions(45)  # odd N: no quarter points on the grid, sin(0) still exact
    assert s45[0] == 0.0 and np.all(c45 != 0.0)
    with pytest.raises(ValueError, match="at least 4"):
        L.crank_positions(3)


@pytest.mark.parametrize("n", [12, 45, 360, 1001])
def test_fourbar_kernel_at_any_n_is_the_numpy_computation(n):
    P = bench_linkage.design_family(70, seed=5)
    out = {k: np.full(70, np.nan) for k in bench_linkage.OUTPUTS}
    status = np.zeros(70, st.DTYPE)
    fb.evaluate(P, bench_linkage.OUTPUTS, None, out, status, None, None, n)
    ref = bench_linkage.numpy_fourbar(P, n_positions=n)
    assert (status == st.OK).all()
    for k in bench_linkage.OUTPUTS:
        np.testing.assert_allclose(out[k], ref[k], rtol=1e-11, atol=1e-11 * np.abs(ref[k]).max())


@pytest.mark.parametrize("n", [12, 45, 360, 1001])
def test_slider_kernel_at_any_n_is_the_numpy_computation(n):
    outputs = ("F_max", "Fx_rms", "F_tb_error_rel")
    # offset slider, non-constant speed, gravity, centres off the lines: every term of the loads
    params = dict(SLIDER, l=np.array([0.15, 0.2, 0.3]), e=0.01, theta1=0.3, theta2=0.1, delta=0.2, g=9.81, k=0.4,
                  branch=np.array(["right", "left", "right"], dtype=object))
    P, _ = B._matrix("slidercrank_balancing", params)
    out, status = B.evaluate("slidercrank_balancing", outputs, n_positions=n, **params)
    ref = R.numpy_slider(P, n)
    assert (status == st.OK).all()
    for k in outputs:
        np.testing.assert_allclose(out[k], ref[k], rtol=1e-12)


def test_curves_have_n_positions_and_360_stays_bitwise_the_default():
    out, _ = B.evaluate("fourbar_balancing", ["M_static_phi", "dM_rms_axis"], n_positions=90, **FOURBAR)
    assert out["M_static_phi"].shape == (90,)
    # the curve at N = 90 is the curve at 360 every 4th position (same positions, same expressions)
    full, _ = B.evaluate("fourbar_balancing", ["M_static_phi"], **FOURBAR)
    np.testing.assert_array_equal(out["M_static_phi"], full["M_static_phi"][::4])
    # the module's constant positions (the default) against positions built afresh, through the
    # engine's kernel of the closed-form model
    from mechsweep.model import closed

    P, _ = B._matrix("fourbar_balancing", FOURBAR)
    names = fb.SPEC.output_names()
    status = np.zeros(1, st.DTYPE)
    default = {k: np.full((1, 360) if fb.SPEC.output(k).extra_dims else 1, np.nan) for k in names}
    fb.SPEC.evaluate(P, names, None, default, status, None, None)
    c, s = L.crank_positions(360)[1:]
    table = np.full((1, len(fb.MODEL.scalars)), np.nan)
    curves = np.full((1, len(fb.MODEL.curves), 360), np.nan)
    kernel = closed.kernel_for(fb.MODEL, 4)
    kernel(P, np.ones(len(fb.MODEL.scalars), bool), np.arange(len(fb.MODEL.curves)), table, curves, status, c, s,
           L.position_sums(c, s), np.ones(360))
    np.testing.assert_array_equal(table[0], [default[k][0] for k in fb.MODEL.scalars])
    np.testing.assert_array_equal(curves[0], [default[k][0] for k in fb.MODEL.curves])


# ============================================================================= references
def test_slider_series_is_the_exact_force_and_its_coefficients_the_fft():
    lam = 0.45
    a = R.sqrt_series_coefficients(lam)
    n = 4096
    phi = 2 * np.pi * np.arange(n) / n
    fft = np.fft.rfft(np.sqrt(1 - lam**2 * np.sin(phi) ** 2)).real / n  # harmonic 2m at index 2m
    np.testing.assert_allclose(a[:12], np.r_[fft[0], 2 * fft[2:24:2]], rtol=0, atol=3e-16)
    for k in (0.0, 0.6, 1.0):
        p = B._row("slidercrank_balancing", dict(SLIDER, **{"lambda": lam}, k=k, g=9.81))
        series = R.SliderSeries(p)
        x = np.random.default_rng(1).uniform(0, 2 * np.pi, 50)
        curves, code = B.slidercrank_curves(x, 300.0, **dict(SLIDER, **{"lambda": lam}, k=k, g=9.81))
        fx, fy = series.force(x)
        assert code == st.OK
        scale = abs(series.amp)
        np.testing.assert_allclose(fx, curves["Fx"], rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(fy, curves["Fy"], rtol=0, atol=1e-13 * scale)
        from scipy.integrate import quad

        quad_rms = math.sqrt(quad(lambda t: series.force(np.array([t]))[0][0] ** 2, 0, 2 * np.pi, epsabs=0,
                                  epsrel=1e-13, limit=200)[0] / (2 * np.pi))
        assert series.fx_rms() == pytest.approx(quad_rms, rel=1e-12)
    with pytest.raises(ValueError, match="offset slider"):
        R.SliderSeries(B._row("slidercrank_balancing", dict(SLIDER, l=0.2, e=0.01, k=0.5)))


def test_fourbar_reference_against_scipy_quad_and_the_first_harmonic():
    from scipy.integrate import quad

    p = B._row("fourbar_balancing", FOURBAR)
    ref, estimate = R.fourbar_reference(p)
    f = R.FourbarContinuous(p)

    def mean(g):
        return quad(lambda t: g(np.array([t])), 0, 2 * np.pi, epsabs=0, epsrel=1e-13, limit=400)[0] / (2 * np.pi)
    M = lambda t: f.moment(t)[0]  # noqa: E731
    assert ref["M_rms_static"] == pytest.approx(math.sqrt(mean(lambda t: M(t) ** 2)), rel=1e-12)
    # constant speed: the moved axis cancels exactly the first harmonic (a1, b1) of M (physics.md section 3),
    # so the residual RMS is sqrt(RMS(M)^2 - (a1^2 + b1^2) / 2)
    a1 = 2 * mean(lambda t: M(t) * np.cos(t[0]))
    b1 = 2 * mean(lambda t: M(t) * np.sin(t[0]))
    assert ref["dM_rms_axis"] == pytest.approx(math.sqrt(ref["M_rms_static"] ** 2 - (a1 * a1 + b1 * b1) / 2), rel=1e-10)
    assert estimate < 1e-13
    # the continuous maximum is above every grid's maximum and within the grid bound of a fine grid's
    for n in (45, 360, 2880):
        out, _ = B.evaluate("fourbar_balancing", ["M_max_static", "dM_max_axis"], n_positions=n, **FOURBAR)
        assert out["M_max_static"] <= ref["M_max_static"] * (1 + 1e-14)
        assert out["dM_max_axis"] <= ref["dM_max_axis"] * (1 + 1e-12)  # axis fitted at N: spectrally close
    fine = np.abs(f.moment(2 * np.pi * np.arange(2**17) / 2**17)).max()
    assert fine <= ref["M_max_static"] <= fine * (1 + 1e-8)


# ============================================================================= the report and its convergence
@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    out = tmp_path_factory.mktemp("wpl")
    ladder = (12, 24, 36, 48) + ORDER_LADDER
    return {m: wl.main(m, points=8, positions=ladder, repeats=1, out_dir=out, quiet=True)
            for m in ("fourbar_balancing", "slidercrank_balancing")}, out


def test_report_is_written_reopens_identical_and_draws(reports):
    dss, out = reports
    for model, ds in dss.items():
        stored = xr.open_dataset(out / f"workprecision_{model}.h5", engine="h5netcdf")
        xr.testing.assert_identical(stored.load(), ds)
        rows = ds.sizes["implementation"] * ds.sizes["output"] * ds.sizes["n_positions"]
        assert (out / f"workprecision_{model}.csv").read_text().count("\n") == rows + 1
        assert (ds.time_per_point.values > 0).all()
        assert float(ds.numpy_difference.max()) < 1e-11  # numpy computes the same numbers
        assert "workprecision" in figures.available(ds)
        assert figures.save(ds, out / f"{model}.png")[0].stat().st_size > 10_000


def _peak(f):
    """(phi*, max f, -f''(phi*)) of a smooth periodic f with one highest peak."""
    from scipy.optimize import minimize_scalar

    phi = 2 * np.pi * np.arange(4096) / 4096
    j = int(np.argmax(f(phi)))
    g = lambda x: f(np.array([x]))[0]  # noqa: E731
    x = minimize_scalar(lambda x: -g(x), bounds=(phi[j] - 0.002, phi[j] + 0.002), method="bounded",
                        options={"xatol": 1e-12}).x
    h = 1e-3
    return x, g(x), -(g(x + h) - 2 * g(x) + g(x - h)) / (h * h)


@pytest.mark.parametrize("case", ["fourbar M_max_static", "slider F_max"])
def test_maxima_converge_as_n_to_the_minus_2_with_the_peak_curvature_constant(case):
    """A grid misses a smooth peak by delta <= pi / N, so the maximum's error is
    kappa delta^2 / 2 <= kappa (pi / N)^2 / 2 (kappa = -f'' at the peak): order exactly 2, the bound
    reached when the peak falls half-way between positions. 40 non-nested N from 100 to 3000."""
    if case.startswith("fourbar"):
        params, model, output = FOURBAR, "fourbar_balancing", "M_max_static"
        f = R.FourbarContinuous(B._row(model, params))
        curve = lambda phi: np.abs(f.moment(phi))  # noqa: E731
    else:
        params, model, output = dict(SLIDER, **{"lambda": 0.35}, k=0.8), "slidercrank_balancing", "F_max"
        series = R.SliderSeries(B._row(model, params))
        curve = lambda phi: np.hypot(*series.force(phi))  # noqa: E731
    _, top, kappa = _peak(curve)
    ref, _ = (R.fourbar_reference if model == "fourbar_balancing" else R.slider_reference)(B._row(model, params))
    assert ref[output] == pytest.approx(top, rel=1e-13)
    ratios = []
    for n in np.unique(np.geomspace(100, 3000, 40).astype(int)):
        out, _ = B.evaluate(model, [output], n_positions=int(n), **params)
        ratios.append((ref[output] - float(out[output])) / (0.5 * kappa * (np.pi / n) ** 2))
    ratios = np.array(ratios)
    assert ratios.min() > -1e-6 and ratios.max() < 1.0 + 1e-3  # never above the N^-2 bound ...
    assert ratios.max() > 0.8  # ... and reaching it: not a higher order either


def test_report_orders_of_the_maxima_are_near_2(reports):
    """The report's fitted order of the largest error over its (small) sample: about 2, erratic on a
    nested ladder (where a doubled grid may still miss a peak by as much)."""
    for model, output in (("fourbar_balancing", "dM_max_axis"), ("slidercrank_balancing", "F_max")):
        e = reports[0][model].error_max.sel(implementation="mechsweep", output=output, n_positions=list(ORDER_LADDER))
        assert 1.0 < wl.fitted_order(e.values, ORDER_LADDER) < 3.0
        assert (e.values > wl.ROUNDOFF).all()  # a discretisation error, not round-off


@pytest.mark.parametrize("model,output", [("fourbar_balancing", "M_rms_static"), ("fourbar_balancing", "dM_rms_axis"),
                                          ("slidercrank_balancing", "Fx_rms")])
def test_rms_converges_spectrally(reports, model, output):
    ds = reports[0][model]
    e = ds.error_max.sel(implementation="mechsweep", output=output).values
    N = ds.n_positions.values
    assert float(ds.roundoff_from.sel(output=output)) <= 360  # round-off at the default N at the latest
    assert e[-1] < wl.ROUNDOFF
    # faster than any power: on the way down, some rung shows an order far above a maximum's 2
    falling = np.flatnonzero(e[:-1] > wl.ROUNDOFF)
    assert np.nanmax(wl.observed_orders(e, N)[falling + 1]) > 6.0, e


def test_cli_checks_the_ladder_options(capsys):
    assert cli.main(["bench", "workprecision", "fourbar_balancing", "--rtol", "1e-6"]) == cli.EXIT_INVALID
    assert "no tolerance" in capsys.readouterr().err
    assert cli.main(["bench", "workprecision", "duffing", "--positions", "90"]) == cli.EXIT_INVALID
    assert "--positions is for closed-form models" in capsys.readouterr().err
    with pytest.raises(Exception, match="need at least 4 crank positions"):
        wl.main("slidercrank_balancing", points=2, positions=(3, 12), quiet=True)
    assert "fourbar_balancing" in wp.all_cases() and "duffing" in wp.all_cases()


@pytest.mark.slow
def test_maxima_errors_at_360_over_the_shipped_families_and_over_general_designs(tmp_path):
    """docs/numerics.md's linkage table: the largest error of a maximum at N = 360 depends on the
    designs sampled, so it is quoted for the shipped family and for general designs
    (sweeps/designs/*.toml) apart; the general four-bars' sharper peaks reach about 3 times the
    shipped family's."""
    from tests.conftest import REPO

    def largest(model, scene=None, points=64):
        ds = wl.main(model, None if scene is None else str(REPO / "sweeps" / "designs" / scene), points=points,
                     positions=(360,), repeats=1, out_dir=tmp_path, quiet=True)
        return {str(o): float(ds.error_max.values[0, i, 0]) for i, o in enumerate(ds.output.values)}, ds

    shipped, ds = largest("fourbar_balancing")
    general, dg = largest("fourbar_balancing", "fourbar_general.toml", 1024)
    assert ds.attrs["points"] == 45 and dg.attrs["points"] == 385
    assert shipped["M_max_static"] == pytest.approx(3.7e-4, rel=0.02)
    assert shipped["dM_max_axis"] == pytest.approx(5.3e-4, rel=0.02)
    assert general["M_max_static"] == pytest.approx(1.1e-3, rel=0.02)
    assert general["dM_max_axis"] == pytest.approx(1.5e-3, rel=0.02)
    assert max(general["M_rms_static"], general["dM_rms_axis"]) < 4e-15  # RMS values at round-off in both
    shipped, _ = largest("slidercrank_balancing")
    general, dg = largest("slidercrank_balancing", "slidercrank_general.toml", 256)
    assert dg.attrs["points"] == 256
    assert shipped["F_max"] == pytest.approx(7.5e-5, rel=0.02)
    assert general["F_max"] == pytest.approx(5.4e-5, rel=0.02)
