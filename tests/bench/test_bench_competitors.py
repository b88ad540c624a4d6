"""`mechsweep bench duffing`'s competitors (bench/competitors.py) and its matched-accuracy choice."""
import numpy as np
import pytest

from mechsweep.bench import competitors
from mechsweep.bench import duffing as bench
from mechsweep.models import duffing

P = np.array([[1.0, 1e-3, 0.01], [1.0, 2.0, 0.7], [2.0, 1e3, 1.0]])
EXACT = np.array([duffing.period_closed_form.py_func(o * o, m, a) for o, m, a in P])


def test_scipy_gives_the_closed_form_period():
    T = competitors.scipy_periods(P, 1e-10, 1e-12)
    assert np.max(np.abs(T - EXACT) / EXACT) < 1e-9


def _fake(errors):
    """A competitor whose max relative error at rtol r is errors[r]."""
    def f(Q, r, a):
        return EXACT[: Q.shape[0]] * (1.0 + errors[r])
    return f


def test_matched_rtol_is_the_first_rung_reaching_our_error(monkeypatch):
    errors = {r: 10.0 * r for r in bench.LADDER}  # error 10 rtol
    monkeypatch.setitem(competitors.FUNCTIONS, "fake", _fake(errors))
    c = bench._competitor("fake", P, EXACT, 3.5e-10, 1e-10, 1e-12, 1)
    assert c["matched"] and c["rtol"] == 3e-11 and c["atol"] == pytest.approx(3e-13)
    assert [r for r, _ in c["ladder"]] == [1e-9, 3e-10, 1e-10, 3e-11]


def test_a_competitor_with_an_error_floor_is_marked_not_matched(monkeypatch):
    errors = {r: max(1.5e-9, 10.0 * r) for r in bench.LADDER}
    errors[1e-12] = 1.4e-9  # the smallest error; 1e-10 is the loosest rung within 10 % of it
    monkeypatch.setitem(competitors.FUNCTIONS, "fake", _fake(errors))
    c = bench._competitor("fake", P, EXACT, 5e-11, 1e-10, 1e-12, 1)
    assert not c["matched"] and c["rtol"] == 1e-10 and len(c["ladder"]) == len(bench.LADDER)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["numbalsoda", "numbalsoda_event", "diffrax"])
def test_optional_competitors_give_the_period(name):
    pytest.importorskip(competitors.PACKAGE.get(name, name))
    T = competitors.FUNCTIONS[name](P, 1e-11, 1e-13)
    assert np.max(np.abs(T - EXACT) / EXACT) < (1e-8 if name == "numbalsoda_event" else 1e-9)


def test_numbalsoda_is_timed_through_its_most_accurate_route():
    """The bench's numbalsoda is its dop853 with Henon's trick for the crossing: on the bench's own
    grid it reaches 1e-13 (its solve_ivp with an event stops at about 1.5e-9, the event's root
    tolerance), and no point comes back wrong (dop853 leaves the last row of its output unwritten
    where its final step ends an ulp short: the driver asks for a time just past it)."""
    pytest.importorskip("numbalsoda")
    from mechsweep.grid import parameter_matrix
    from mechsweep.scene import load_scene

    scene = load_scene(bench.grid_scene(20_000, 5e-11, 1e-12))
    Q = parameter_matrix(scene, 0, scene.n_points)
    exact = np.array([duffing.period_closed_form.py_func(o * o, m, a) for o, m, a in Q])
    henon = np.abs(competitors.FUNCTIONS["numbalsoda"](Q, 1e-13, 1e-15) - exact) / exact
    assert np.isfinite(henon).all() and henon.max() < 1e-13
    event = np.abs(competitors.FUNCTIONS["numbalsoda_event"](Q[::20], 1e-13, 1e-15) - exact[::20]) / exact[::20]
    assert event.max() > 1e-10  # the event route's floor: the reason it is not the one timed for the verdict


def test_matched_the_other_way_is_our_loosest_rung_still_as_accurate_as_the_competitors_best():
    """A competitor with an error floor (numbalsoda's event location): mechsweep is loosened
    instead, to the loosest rung whose error is no larger than the competitor's best."""
    seen = []

    def errors_of(r, a):
        seen.append((r, a))
        return 1.0 * r  # our error: about rtol

    r, a, err, tried = bench.ours_at_error(errors_of, 1.5e-9, 1e-10, 1e-12)
    assert r == pytest.approx(1e-9) and a == pytest.approx(1e-11) and err == pytest.approx(1e-9)
    assert [t for t, _ in tried] == pytest.approx([1e-10, 3e-10, 1e-9, 3e-9])  # stops at the first miss
    assert seen[-1] == pytest.approx((3e-9, 3e-11))
    # no rung reaches it: the tightest is returned, and the caller marks it not matched
    r, a, err, tried = bench.ours_at_error(lambda r, a: 1e-6, 1e-9, 1e-10, 1e-12)
    assert r == 1e-10 and err == 1e-6 and len(tried) == 1
