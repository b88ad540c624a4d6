"""What a model's work-precision report uses (``mechsweep bench workprecision MODEL``), declared by
the model itself: the bench keeps no table of models.

- :class:`WorkPrecision` (``OdeModel(workprecision=...)``): a ladder of tolerances; the model's
  methods and scipy's ``solve_ivp`` running the model's own rhs, against the model's closed form
  (``reference``) or scipy DOP853 at rtol 1e-13 (bench/workprecision.py, workprecision_ode.py).
- :class:`SizeWorkPrecision` (``ClosedFormModel(workprecision=...)``): a ladder of the extra
  dimension's length n (e.g. crank positions per cycle), the model's kernel and an independent
  implementation of the same outputs, against a reference on the continuous dimension
  (bench/workprecision_linkage.py).

``scene``: the scene the sample of points is drawn from, a path relative to the folder of the file
in which the declaration is written (an absolute path as it is); a path ``sweeps/NAME.toml`` that does
not exist there names mechsweep's shipped ``sweeps/NAME.toml`` (installed with the package:
mechsweep.examples). Empty: no default scene (``--scene`` is then required).
"""
from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

def _declaring_folder() -> str:
    """The folder of the file whose code constructs the declaration (the first frame outside this
    module and the dataclass machinery); "" where there is none (an interactive session)."""
    skip = {__file__, dataclasses.__file__}
    frame = sys._getframe(1)
    while frame is not None and (frame.f_code.co_filename in skip or frame.f_code.co_filename.startswith("<")):
        frame = frame.f_back
    if frame is None:
        return ""
    return str(Path(frame.f_code.co_filename).resolve().parent)


def _check_scene(where: str, scene) -> None:
    if not isinstance(scene, str):
        raise ValueError(f"{where}: scene must be a path (a string) to a scene file, got {scene!r}")
    if scene and not scene.endswith(".toml"):
        raise ValueError(f"{where}: scene = {scene!r}; expected a scene file ending in .toml")


@dataclass(frozen=True)
class WorkPrecision:
    """The work-precision report of an :class:`~mechsweep.model.OdeModel`.

    - ``scene``: the default scene of the sample (module docstring); empty: ``--scene`` required.
    - ``output``: the integrated output whose error is measured (one of the model's measurements
      the bench has a scipy version of); empty: the first such measured output.
    - ``reference``: the name of one of the model's ``closed_forms`` whose value is the exact value
      of ``output`` (a formula of the parameters alone: it may need other closed forms, no
      integrated output); the bench evaluates it by the engine and measures every method's error
      against it. Empty: the reference is scipy's DOP853 at rtol 1e-13 on the model's own rhs.
    """

    scene: str = ""
    output: str = ""
    reference: str = ""
    base: str = field(default="", init=False, compare=False)  # the declaring file's folder

    def __post_init__(self):
        object.__setattr__(self, "base", _declaring_folder())

    def validate(self, model) -> None:
        from .measure import ClosedForm

        where = f"model {model.name!r}: workprecision"
        _check_scene(where, self.scene)
        measured = [o.name for m in model.measurements
                    for o in (m.outputs() if hasattr(m, "outputs") else (m.output(),))]
        if not isinstance(self.output, str) or (self.output and self.output not in measured):
            raise ValueError(f"{where}: output = {self.output!r} is not a measured output of the model "
                             f"(measured: {', '.join(measured) or 'none'})")
        closed = [c.name for c in model.closed_forms if isinstance(c, ClosedForm)]
        if not isinstance(self.reference, str) or (self.reference and self.reference not in closed):
            raise ValueError(f"{where}: reference = {self.reference!r} is not one of the model's closed forms "
                             f"(closed_forms: {', '.join(closed) or 'none'}); it names the closed form giving "
                             "the exact value of the output")
        if self.reference:
            integrated, _ = model._plan((self.reference,))
            if integrated:
                needed = sorted(o.name for m in integrated
                                for o in (m.outputs() if hasattr(m, "outputs") else (m.output(),)))
                raise ValueError(f"{where}: reference {self.reference!r} needs the integrated outputs {needed}; "
                                 "a reference must be a closed form of the parameters alone")
            if not self.output:
                raise ValueError(f"{where}: reference = {self.reference!r} is given without the output it is "
                                 "the exact value of; give output= too")


@dataclass(frozen=True)
class SizeWorkPrecision:
    """The work-precision report of a :class:`~mechsweep.model.ClosedFormModel` whose outputs
    depend on the length n of its extra dimension (``size``, e.g. crank positions per cycle): the
    error of ``outputs`` against n over the ladder ``sizes``, with what each n costs, for the
    model's kernel and for an independent implementation of the same outputs.

    - ``scene``: the default scene of the sample (module docstring).
    - ``outputs``: {output name: what kind of quantity it is, for the report}, scalar outputs.
    - ``reference(p) -> ({output: exact value}, error estimate of the reference)``: plain Python
      of one design's parameter row (declared order), on the continuous dimension.
    - ``reference_name``: how the reference is computed, for the report.
    - ``compare(P, n) -> {output: values}``: the independent implementation (e.g. vectorised
      numpy) of the outputs at n for the rows P; timed on the same sample; its values must agree
      with the kernel's to round-off (the largest difference is reported).
    - ``compare_label`` / ``compare_name``: its name in the report and how it computes.
    - ``applies(p) -> str``: optional; "" where ``reference`` describes the row, else why not (those
      rows leave the sample, said in the report).
    - ``sizes``: the default ladder of n (whole numbers >= 4, increasing).
    """

    scene: str
    outputs: object
    reference: Callable = field(repr=False, compare=False)
    reference_name: str = ""
    compare: Callable = field(default=None, repr=False, compare=False)
    compare_label: str = "numpy"
    compare_name: str = ""
    applies: Callable | None = field(default=None, repr=False, compare=False)
    sizes: tuple = (12, 24, 45, 90, 180, 360, 720, 1440, 2880)
    base: str = field(default="", init=False, compare=False)  # the declaring file's folder

    def __post_init__(self):
        object.__setattr__(self, "base", _declaring_folder())
        object.__setattr__(self, "outputs", tuple(dict(self.outputs).items()))
        object.__setattr__(self, "sizes", tuple(self.sizes))

    def validate(self, model) -> None:
        where = f"model {model.name!r}: workprecision"
        _check_scene(where, self.scene)
        bad = [o for o, _ in self.outputs if o not in model.scalars]
        if not self.outputs or bad:
            raise ValueError(f"{where}: outputs {bad or '(none)'} are not scalar outputs of the model "
                             f"({', '.join(model.scalars)})")
        for name in ("reference", "compare") + (("applies",) if self.applies is not None else ()):
            if not callable(getattr(self, name)):
                raise ValueError(f"{where}: {name} must be a function (got {getattr(self, name)!r})")
        if (not self.sizes or any(isinstance(n, bool) or not isinstance(n, int) or n < 4 for n in self.sizes)
                or list(self.sizes) != sorted(set(self.sizes))):
            raise ValueError(f"{where}: sizes = {self.sizes!r}; expected increasing whole numbers >= 4")
