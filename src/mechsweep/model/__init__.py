"""The declarative model layer: declare an ODE model and what to measure, or a closed-form model
and its per-design function; the engine writes the chunk kernel. See docs/model-layer.md."""
from ..models._spec import ExtraDim, Output, Param, Setting
from .closed import ClosedFormModel
from .measure import ClosedForm, Crossing, Extremum, FirstEvent, Floquet, Period, StateAt, System
from .sampled import *  # noqa: F401,F403 - the sampled measurements (its __all__)
from .sampled import __all__ as _sampled
from .ode import Invariant, OdeModel
from .workprecision import SizeWorkPrecision, WorkPrecision

__all__ = ["OdeModel", "ClosedFormModel", "Param", "Setting", "Output", "ExtraDim", "Crossing", "Period", "StateAt",
           "Extremum", "Floquet", "FirstEvent", "ClosedForm", "System", "Invariant", "WorkPrecision",
           "SizeWorkPrecision", *_sampled]
