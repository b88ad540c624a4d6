"""A pendulum on a vertically vibrating support: a user model (docs/your-own-model.md).

The pivot moves vertically as y_s(t) = a cos(w t) (up positive); theta is measured from the
hanging position. In the frame of the pivot the bob feels gravity plus the inertial force of the
pivot's acceleration, g + y_s'' = g - a w^2 cos(w t), so with a viscous damper c at the bob

    theta'' + (c/m) theta' + (g/L - (a w^2 / L) cos(w t)) sin(theta) = 0.

The motion is 2 pi / w periodic in t; theta = 0 (hanging) and theta = pi (inverted) are
equilibria for every a and w. Floquet gives the largest |multiplier| of the equation linearised
about the position chosen by ``position``: <= 1 stable, > 1 unstable (parametric resonance of the
hanging pendulum; Kapitza's stabilisation of the inverted one for large enough a w).
"""
import math

from mechsweep.model import Floquet, OdeModel, Param

# p[0] g, p[1] L, p[2] a, p[3] w, p[4] c, p[5] m, p[6] position (0 hanging, 1 inverted)


def rhs(t, y, p, dydt):
    g, L, a, w, c, m = p[0], p[1], p[2], p[3], p[4], p[5]
    dydt[0] = y[1]
    dydt[1] = -(c / m) * y[1] - (g / L - a * w * w / L * math.cos(w * t)) * math.sin(y[0])


def initial(p, y0):
    y0[0] = math.pi * p[6]  # at rest in the chosen position
    y0[1] = 0.0


def forcing_period(p):
    return 2.0 * math.pi / p[3]


VIBRATING_PENDULUM = OdeModel(
    name="vibrating_pendulum",
    description="pendulum on a vertically vibrating support: "
                "theta'' + (c/m) theta' + (g/L - (a w^2/L) cos(w t)) sin(theta) = 0",
    params=(
        Param("g", "g", "m s-2", "gravitational acceleration", lo=0.0, lo_open=True,
              required=False, default=9.81),
        Param("L", "L", "m", "pendulum length (pivot to bob)", lo=0.0, lo_open=True),
        Param("a", "a", "m", "support displacement amplitude", lo=0.0),
        # latex: the symbol as figures write it (matplotlib mathtext); without it they convert the symbol
        Param("w", "omega", "rad s-1", "support angular frequency", lo=0.0, lo_open=True, latex=r"$\omega$"),
        Param("c", "c", "N s m-1", "viscous damping coefficient at the bob", lo=0.0, required=False,
              default=0.0),
        Param("m", "m", "kg", "bob mass", lo=0.0, lo_open=True, required=False, default=1.0),
        Param("position", "position", "1", "equilibrium whose stability is measured",
              choices=("hanging", "inverted")),
    ),
    states=("theta", "omega"),
    rhs=rhs,
    initial=initial,
    forcing_period=forcing_period,
    measurements=(Floquet("max_multiplier"),),
)
