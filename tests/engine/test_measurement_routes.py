"""The engine picks a measurement's route from what the measurement declares, not from its class's
name: a subclass under another name takes the same route, a class merely named alike does not."""
from dataclasses import dataclass

from mechsweep.engine.point import is_direct
from mechsweep.engine.sampling import grid
from mechsweep.model import Crossing, FirstEvent, Kick, Period, Steady
from mechsweep.model.sampled import Recheck


class FirstDrop(Crossing):
    """A Crossing under another name."""


class Amplitude(Steady):
    """A Steady under another name."""


class Verdict(Kick):
    """A Kick under another name."""


@dataclass(frozen=True)
class _NotACrossing:
    name: str
    n: int = 1


_NotACrossing.__name__ = _NotACrossing.__qualname__ = "Crossing"


def _event(t, y, p):
    return y[0]


def test_a_first_crossing_alone_integrates_on_its_own_whatever_its_class_is_called():
    assert is_direct((Crossing("c", "x"),)) and is_direct((FirstDrop("c", "x"),))
    assert not is_direct((FirstDrop("c", "x", n=2),))  # the n-th crossing: a row of the shared trajectory
    assert not is_direct((FirstDrop("c", "x"), Period("T", "x")))  # with another: the shared trajectory
    assert not is_direct((_NotACrossing("c"),))  # named Crossing, declares nothing
    assert is_direct((FirstEvent("e", _event),)) and not is_direct(())


def test_the_first_harmonic_is_computed_only_when_asked_for_whatever_the_class_is_called():
    for cls in (Steady, Amplitude):
        m = cls("amp", "x", horizon=10.0)
        assert grid((m,), {})[2][0, 2] == 1.0  # every output
        assert grid((m,), {}, ("amp",))[2][0, 2] == 0.0  # the peak only: no cos/sin per sample
        assert grid((m,), {}, ("amp", "amp_phase"))[2][0, 2] == 1.0
        assert grid((m,), {}, ("amp_h1",))[2][0, :2].tolist() == grid((m,), {})[2][0, :2].tolist()


def test_recheck_skip_settled_names_a_kick_whatever_its_class_is_called():
    Recheck(skip_settled="k").validate((Verdict("k", _event),), ())


def test_a_steady_without_a_forcing_period_says_t_is_one_time_unit_whatever_its_class_is_called():
    from mechsweep.model import OdeModel
    for cls in (Steady, Amplitude):
        spec = OdeModel(name="x", description="", params=(), states=("y",), rhs=lambda t, y, p, d: None,
                        initial=lambda p, y: None, measurements=(cls("amp", "y", horizon=10.0),)).spec()
        assert spec.output("amp").long_name.endswith("(T = 1 time unit: the model declares no forcing period)")
