"""User models whose declarations hold strings a dataset cannot store (tests/test_hostile_scenes.py):
HDF5 keeps text as UTF-8 without NUL, and each variable of a dataset needs a name of its own. A
scene naming one is refused when it is loaded, before anything is computed."""
import math

from mechsweep.model import ClosedForm, History, OdeModel, Param


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * y[0]


def initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


def period(p):
    return 2.0 * math.pi / math.sqrt(p[0])


def model(name="linear", long_name="stiffness", unit="s-2", choices=("soft", "hard"), output="T",
          notes=(), references=()):
    return OdeModel(
        name=name, description="x'' + k x = 0", states=("x", "v"), rhs=rhs, initial=initial,
        params=(Param("k", "k", unit, long_name, lo=0.0, lo_open=True),
                Param("kind", "kind", "1", "a label", choices=choices)),
        closed_forms=(ClosedForm(output, period, unit="s", long_name="period"),),
        status_notes=notes, references=references)


FINE = model()
NUL_LONG_NAME = model(long_name="stiff\x00ness")
SURROGATE_UNIT = model(unit="s-2\udcff")
NUL_CHOICE = model(choices=("soft\x00", "hard"))
NUL_NAME = model(name="lin\x00ear")
SLASH_OUTPUT = model(output="T/2")
OUTPUT_NAMED_STATUS = model(output="status")
OUTPUT_NAMED_LIKE_PARAMETER = model(output="k")
NUL_REFERENCE = model(references=("a book\x00",))


def forcing_period(p):
    return 1.0


# two outputs with an extra dimension of one name and other values (a dataset has one coordinate
# per dimension name: the second would be written over the first's)
TWO_HISTORIES_ONE_DIMENSION = OdeModel(
    name="histories", description="x'' + k x = 0", states=("x", "v"), rhs=rhs, initial=initial,
    params=(Param("k", "k", "s-2", "stiffness", lo=0.0, lo_open=True),), forcing_period=forcing_period,
    measurements=(History("x_history", "x", horizon=2.0, samples=5), History("v_history", "v", horizon=3.0, samples=7)))
