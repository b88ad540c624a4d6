"""The declarative model layer: declare an ODE model and what to measure; the engine writes the
chunk kernel. See docs/model-layer.md."""
from ..models._spec import Param, Setting
from .measure import ClosedForm, Crossing, Extremum, FirstEvent, Floquet, Period, StateAt
from .ode import OdeModel

__all__ = ["OdeModel", "Param", "Setting", "Crossing", "Period", "StateAt", "Extremum", "Floquet", "FirstEvent",
           "ClosedForm"]
