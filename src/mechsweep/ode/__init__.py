"""Integrators: dop853 (explicit 8th order), radau (implicit Radau IIA 5th order),
symplectic (explicit fixed-step compositions of Stoermer-Verlet)."""

# solver.method as the integer the kernels branch on
DOP853, RADAU, SYMPLECTIC, AUTO = 0, 1, 2, 3
METHOD_CODES = {"dop853": DOP853, "radau": RADAU, "symplectic": SYMPLECTIC, "auto": AUTO}
METHOD_HELP = {
    "dop853": "explicit Dormand-Prince 8(5,3), adaptive (scipy's DOP853 step control)",
    "radau": "implicit Radau IIA order 5, adaptive, for stiff points; Jacobian: the model's own where it "
             "declares one, else central differences",
    "symplectic": "explicit symplectic composition of order 8 (McLachlan 1995), fixed step from rtol: "
                  "no energy drift, undamped models only",
    "auto": "dop853 with Hairer's stiffness test; a point found stiff is solved again by radau",
}
