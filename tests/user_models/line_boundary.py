"""A boundary that is a straight line, y = s x + c, as a closed form g = y - s x - c (level 0): its
continuation in the (x, y) chart is known exactly (tests/boundaries/test_boundaries.py)."""
from mechsweep.model import ClosedFormModel, Output, Param


def compute(p, want, row, curves, slot, scratch):
    row[0] = p[1] - p[3] * p[0] - p[2]
    return 0


LINE = ClosedFormModel(
    name="line_boundary", description="g = y - s x - c: its zero is the line y = s x + c",
    params=(Param("x", "x", "1", "abscissa"), Param("y", "y", "1", "ordinate"),
            Param("c", "c", "1", "intercept"), Param("s", "s", "1", "slope")),
    outputs=(Output("g", "g", "1", "y - s x - c"),),
    compute=compute,
)
