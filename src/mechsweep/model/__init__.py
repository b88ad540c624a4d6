"""The declarative model layer: declare an ODE model and what to measure, or a closed-form model
and its per-design function; the engine writes the chunk kernel. See docs/model-layer.md."""
from .spec import ExtraDim, Output, Param, Setting
from .closed import ClosedFormModel
from .measure import ClosedForm, Crossing, Extremum, FirstEvent, Floquet, History, Kick, Period, Recheck, StateAt, Steady, System
from .ode import Invariant, OdeModel
from .workprecision import SizeWorkPrecision, WorkPrecision

__all__ = ["OdeModel", "ClosedFormModel", "Param", "Setting", "Output", "ExtraDim", "Crossing", "Period", "StateAt",
           "Extremum", "Floquet", "FirstEvent", "ClosedForm", "System", "Invariant", "Steady", "Kick", "History", "Recheck",
           "WorkPrecision", "SizeWorkPrecision"]
