"""The plan of a run (plan.py): made once, before any chunk, from the scene and mechsweep's own cache
record; stored with the run; pickled as it is to a dask worker; the route of its kernels chosen by
one rule from the run's size and the record, never from the rows of a call."""
import pytest

from mechsweep import plan as planning


@pytest.mark.parametrize("facts,points,route", [
    ({"forced": None, "from_points": 100, "recorded": False}, 99, "point"),  # small, nothing compiled
    ({"forced": None, "from_points": 100, "recorded": False}, 100, "lanes"),  # large enough to repay the compile
    ({"forced": None, "from_points": 100, "recorded": True}, 1, "lanes"),  # compiled already: nothing to repay
    ({"forced": False, "from_points": 100, "recorded": True}, 10**9, "point"),  # the engine's override
    ({"forced": True, "from_points": 100, "recorded": False}, 1, "lanes"),
])
def test_one_rule_chooses_the_route(facts, points, route):
    assert planning.choose_route(points, facts) == route
