"""Two equations of one model and a refined measurement (tests/model/test_model_layer_systems.py).
p = (w, A, tighten | stiff_scaled): the model's own equation x'' = -w^2 x (measurement "period",
quarter period times 4: 2 pi / w), a System x'' = -4 w^2 x of its own (measurement "half",
period pi / w; its prepare refuses w > 5 with INFEASIBLE), and a FirstEvent "refined" on the
model's equation whose refine asks for rtol / tighten (inf: ILL_CONDITIONED). A closed form
"inverse" = 1 / A that does not apply where A < 0 (classify: NO_MOTION)."""
from mechsweep.model import ClosedForm, FirstEvent, OdeModel, Param, System

OK, INFEASIBLE, NO_MOTION = 0, 4, 7


def initial(p, y0):
    y0[0] = p[1]
    y0[1] = 0.0


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * p[0] * y[0]


def stiff_prepare(p, rtol):
    if p[0] > 5.0:
        return INFEASIBLE
    p[3] = 2.0 * p[0]
    return OK


def stiff_initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


def stiff_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[3] * p[3] * y[0]


def down(t, y, p):
    return y[0]


def quarter_to_period(p, t):
    return 4.0 * t


def tighten(p, rtol, value):
    return p[2]


def inverse(p):
    return 1.0 / p[1]


def positive_release(p):
    return NO_MOTION if p[1] < 0.0 else OK


SYSTEMS = OdeModel(
    name="layer_systems",
    description="x'' = -w^2 x and, as a second system, x'' = -4 w^2 x",
    params=(Param("w", "w", "rad/s", "angular frequency", lo=0.0, lo_open=True),
            Param("A", "A", "1", "release"),
            Param("tighten", "f", "1", "the refine factor", lo=0.0)),
    internal=("stiff_scaled",),
    states=("x", "v"),
    rhs=rhs,
    initial=initial,
    measurements=(
        FirstEvent("period", down, t_max=1e3, value=quarter_to_period, unit="s"),
        FirstEvent("half", down, t_max=1e3, value=quarter_to_period, unit="s",
                   system=System(rhs=stiff_rhs, initial=stiff_initial, prepare=stiff_prepare)),
        FirstEvent("refined", down, t_max=1e3, value=quarter_to_period, unit="s", refine=tighten),
    ),
    closed_forms=(ClosedForm("inverse", inverse, "1/A", "1", classify=positive_release),),
)
