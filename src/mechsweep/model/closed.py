"""ClosedFormModel: a model whose outputs are closed forms of its parameters (no integration).

The user writes one per-design function, ``compute(p, want, row, curves, slot, scratch, *data) ->
status``, in plain numba-compilable Python (its contract: docs/your-own-model.md, section 11); the
engine owns the rest: the parallel loop over designs (engine/closed.py), the scratch per thread,
the statuses, the NaN fill of failed designs and the data every design shares. The kernel is
cached on disk through its binding module (engine/binding.py), keyed by the compute function's
module source and name, the model's dependency record and the kernel's shape."""
from __future__ import annotations

import hashlib
import math
import operator
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .. import status as st
from ..errors import InputError
from .spec import ExtraDim, ModelSpec, Output, Param, Setting, wanted_flags
from . import load, sources


@dataclass(frozen=True)
class ClosedFormModel:
    """A model whose outputs are closed forms of its parameters (no integration), computed per
    design by one function of yours; the engine owns the parallel loop, the scratch, the statuses
    and the NaN fill (docs/your-own-model.md, section 11).

    Parameters
    ----------
    name : str
        The model's name (how a scene names it; the dataset's ``model`` attribute).
    description : str
        One line saying what the model is.
    params : tuple of Param
        The parameters, in the order of ``p``.
    outputs : tuple of Output
        Scalars (no ``extra_dims``) and curves over ONE :class:`ExtraDim` shared by all curve
        outputs (``extra_dims=(dim,)``); ``row`` follows the scalars' order, ``slot`` the curves'.
    compute : callable
        ``compute(p, want, row, curves, slot, scratch, *data) -> status``: one design's outputs
        (numba-compilable): writes the wanted scalars into ``row`` and curves into
        ``curves[slot[k]]``; returns a status code.
    size : int, optional
        n, the length of the extra dimension (its ``values`` must have that length), of the
        scratch rows and ``data(n)``'s argument. A model without curves may use it too (e.g.
        sample points for maxima); default 1.
    data : callable, optional
        ``data(n) -> tuple of numpy arrays`` shared by every design (plain Python, run once per n);
        passed to ``compute`` after ``scratch``.
    scratch : int, optional
        Rows of the per-thread scratch array (``scratch`` x n floats).
    check : callable, optional
        ``check(given) -> list of problems``: the cross-parameter rules (as for
        :class:`OdeModel`).
    source : str, optional
        Where the formulas come from.
    settings : tuple of Setting, optional
        The model's own solver settings.
    statuses : tuple of int, optional
        Status codes its designs can get beyond those its outputs imply.
    status_notes : Mapping, optional
        Status code -> what that status means for this model.
    references : tuple of str, optional
        The documents the model implements (the dataset's ``references``).
    workprecision : SizeWorkPrecision, optional
        The error of outputs against ``size`` (``mechsweep bench workprecision MODEL``).
    """

    name: str
    description: str
    params: tuple[Param, ...]
    outputs: tuple[Output, ...]
    compute: Callable = field(repr=False)
    size: int = 1
    data: Callable | None = field(default=None, repr=False)
    scratch: int = 0
    check: Callable | None = field(default=None, repr=False)
    source: str = ""
    settings: tuple[Setting, ...] = ()
    statuses: tuple[int, ...] = ()  # ModelSpec.statuses: added to those derived from the outputs
    status_notes: object = ()  # ModelSpec.status_notes: {code: what the status means for this model}
    references: tuple[str, ...] = ()  # ModelSpec.references: the source documents
    workprecision: object = field(default=None, repr=False, compare=False)  # model.workprecision.SizeWorkPrecision

    def __post_init__(self):
        object.__setattr__(self, "params", tuple(self.params))
        object.__setattr__(self, "outputs", tuple(self.outputs))
        object.__setattr__(self, "status_notes", tuple(sorted(dict(self.status_notes).items())))
        names = [o.name for o in self.outputs]
        if len(set(names)) != len(names):
            raise ValueError(f"model {self.name!r}: output names repeat: {names}")
        names = [p.name for p in self.params]
        if len(set(names)) != len(names):  # a scene key and a dataset coordinate: one each
            raise ValueError(f"model {self.name!r}: parameter names repeat: {names}")
        dims = {o.extra_dims for o in self.outputs if o.extra_dims}
        if len(dims) > 1 or any(len(d) != 1 for d in dims):
            raise ValueError(f"model {self.name!r}: every curve output must have the same single extra "
                             f"dimension (got {sorted(tuple(x.name for x in d) for d in dims)})")
        if isinstance(self.size, bool) or not isinstance(self.size, int) or self.size < 1:
            raise ValueError(f"model {self.name!r}: size must be a whole number >= 1, got {self.size!r}")
        if isinstance(self.scratch, bool) or not isinstance(self.scratch, int) or self.scratch < 0:
            raise ValueError(f"model {self.name!r}: scratch must be a whole number >= 0, got {self.scratch!r}")
        if self.workprecision is not None:
            from .workprecision import SizeWorkPrecision
            if not isinstance(self.workprecision, SizeWorkPrecision):
                raise ValueError(f"model {self.name!r}: workprecision must be a mechsweep.model.SizeWorkPrecision "
                                 f"(got {self.workprecision!r})")
            self.workprecision.validate(self)

    @property
    def scalars(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.outputs if not o.extra_dims)

    @property
    def curves(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.outputs if o.extra_dims)

    @property
    def dim(self) -> ExtraDim | None:
        return next((o.extra_dims[0] for o in self.outputs if o.extra_dims), None)

    def shared_data(self, n: int) -> tuple:
        """``data(n)`` as contiguous arrays, built once per n in this process."""
        cache = _DATA.setdefault(id(self), (self, {}))[1]
        if n not in cache:
            arrays = () if self.data is None else self.data(n)
            cache[n] = tuple(np.ascontiguousarray(a) for a in arrays)
        return cache[n]

    def spec(self, *, origin: str = "") -> ModelSpec:
        """The ModelSpec the runner, store and scene read. Its ``evaluate`` takes an optional 8th
        argument ``size`` (the extra dimension's length; default ``self.size``)."""
        model = self
        scalars, curves = self.scalars, self.curves

        def evaluate(P, wanted, solver, out, status, n_steps=None, n_rhs=None, size=None):
            n_ext = model.size if size is None else operator.index(size)
            if n_ext < 1:
                raise ValueError(f"size must be >= 1, got {n_ext}")
            data = model.shared_data(n_ext)
            kernel = kernel_for(model, len(data), origin=origin)
            P = np.ascontiguousarray(P, dtype=np.float64)
            n = P.shape[0]
            want = wanted_flags(scalars, tuple(wanted))
            names = [c for c in curves if c in wanted]
            slot = np.array([names.index(c) if c in names else -1 for c in curves], dtype=np.int64)
            table = np.full((n, len(scalars)), np.nan)
            crv = np.full((n, len(names), n_ext) if names else (0, 0, n_ext), np.nan)
            kernel(P, want, slot, table, crv, status, *data)
            _warn_user_error(model, P, status, want, slot, crv.shape[1], n_ext, data)
            for name in wanted:
                if name in names:
                    out[name][:] = crv[:, names.index(name), :]
                elif name in scalars:
                    out[name][:] = table[:, scalars.index(name)]

        return ModelSpec(name=self.name, description=self.description, params=self.params, outputs=self.outputs,
                         evaluate=evaluate, source=self.source or origin, settings=self.settings, check=self.check,
                         statuses=self.statuses, status_notes=self.status_notes, references=self.references,
                         declaration=self)


_EXPLAINED: set = set()  # (model, explanation) already warned about in this process


def _warn_user_error(model: ClosedFormModel, P, status, want, slot, n_curves: int, n_ext: int, data) -> None:
    """Designs with status USER_ERROR (compute raised there): replay the first in plain Python and
    warn (once per model and cause in a process) with the exception, its file and line, and the
    design, as for an OdeModel (model/ode.py)."""
    bad = np.flatnonzero(status == st.USER_ERROR)
    if not bad.size:
        return
    from .diagnose import explain_closed, point_text

    why = explain_closed(model, P[bad[0]], want, slot, n_curves, n_ext, data)
    if (model.name, why) in _EXPLAINED:
        return
    _EXPLAINED.add((model.name, why))
    import warnings

    from ..errors import UserModelWarning
    warnings.warn(f"model {model.name!r}: its own code raised (status user_error; the run's status counts say how "
                  f"often); first seen at {point_text(model.params, P[bad[0]])}: {why}", UserModelWarning,
                  stacklevel=3)


_DATA: dict[int, tuple] = {}
_KERNELS: dict[str, object] = {}
_BY_MODEL: dict[tuple, tuple] = {}  # (id(model), number of data arrays) -> (model, kernel)


def _guarded(ref) -> bool:
    """A user's function gets an exception guard in the kernel; mechsweep's own never raise."""
    return not ref[0].startswith("mechsweep.")


class _Kernel:
    """``kernel(P, want, slot, table, curves, status, *data)``: the binding's entry point on threads
    (engine/point.py's Threaded), which takes the shared data as one tuple; ``stats`` and the like are
    its dispatcher's."""

    def __init__(self, entry):
        self.entry = entry

    def __getattr__(self, name):
        return getattr(self.entry, name)

    def __call__(self, P, want, slot, table, curves, status, *data):
        self.entry(P, want, slot, table, curves, status, tuple(data))


def kernel_for(model: ClosedFormModel, n_data: int, *, origin: str = ""):
    """The compiled chunk kernel of ``model`` (engine/closed.py; cached in-process and on disk through its
    binding module, engine/binding.py)."""
    known = _BY_MODEL.get((id(model), n_data))
    if known is not None and known[0] is model:  # no file read and hash per chunk
        return known[1]
    from ..engine import binding
    from ..engine import closed as engine
    from ..engine.point import Threaded

    ref = load.function_ref(model.compute, "compute", model.name)
    key = hashlib.sha256()
    key.update(repr(ref).encode())
    key.update(load.module_source(ref[0], ref[1]))
    key.update(sources.record(model).digest.encode())  # the user modules the model imports, recursively
    key.update(repr(("closed", model.name, len(model.params), n_data, model.scratch, engine.BLOCK)).encode())
    name = "mechsweep_closed_" + key.hexdigest()[:20]
    if name not in _KERNELS:
        compute = load.jitted(*ref)
        mod = binding.bind(name, f"model {model.name!r}, closed forms per design", {"kernel": engine.ARGS},
                           lambda: engine.build(compute, model.scratch, _guarded(ref)))
        _KERNELS[name] = _Kernel(Threaded(mod.kernel, name, block=engine.BLOCK))
    _BY_MODEL[(id(model), n_data)] = (model, _KERNELS[name])
    return _KERNELS[name]


# ============================================================================= checks of a user model
_SENTINEL = 12345.678


def _probe_arrays(model: ClosedFormModel, p, fill: float):
    n = model.size
    return (p, np.ones(len(model.scalars), dtype=np.bool_), np.full(len(model.scalars), fill),
            np.full((len(model.curves), n), fill), np.arange(len(model.curves), dtype=np.int64),
            np.zeros((model.scratch, n)))


def check(model: ClosedFormModel, ref: str, file: str) -> None:
    """The checks that make a bad closed-form model an InputError naming the file (and the line)
    at scene loading, before anything is written: ``data(n)`` that raises or returns no tuple of
    arrays, an extra dimension whose values are not n long, ``compute`` that raises, indexes
    beyond its arrays (an undeclared parameter, an output or curve beyond the declared ones, a
    scratch row beyond ``scratch``), returns no status code, or (status OK, every output wanted)
    leaves an output or a curve value unwritten, all found by running it once in plain Python at
    a probe point; then ``compute`` that numba cannot compile, or whose compiled result is not a
    status code on every path (a bare ``return``, or a float, on a path the probe did not take)."""
    label = f"{ref!r}: model {model.name!r} in {file}"
    dim = model.dim
    if dim is not None:
        settings = {s.name: s.default for s in model.settings}
        try:
            values = np.asarray(dim.values(settings))
        except Exception as exc:
            raise InputError(f"{label}: the values of extra dimension {dim.name!r} raised: "
                             f"{load.where(exc, file)}") from None
        if values.shape != (model.size,):
            raise InputError(f"{label}: extra dimension {dim.name!r} has {values.shape} values; expected "
                             f"size = {model.size} (the model's size)")
    try:
        data = () if model.data is None else model.data(model.size)
    except Exception as exc:
        raise InputError(f"{label}: data({model.size}) raised: {load.where(exc, file)}") from None
    if not isinstance(data, tuple) or not all(isinstance(a, np.ndarray) for a in data):
        raise InputError(f"{label}: data({model.size}) returned {type(data).__name__}; expected a tuple of "
                         "numpy arrays")
    data = tuple(np.ascontiguousarray(a) for a in data)
    p = load.probe_params(model)
    func = getattr(model.compute, "py_func", model.compute)
    sizes = (f"the model declares {len(model.params)} parameter(s), {len(model.scalars)} scalar output(s), "
             f"{len(model.curves)} curve(s) of {model.size} values and {model.scratch} scratch row(s)")
    results = []
    for fill in (math.nan, _SENTINEL):
        args = _probe_arrays(model, p.copy(), fill)
        code = load.probe_call(label, "compute", func, (*args, *[a.copy() for a in data]), p, sizes, file)
        if isinstance(code, (bool, np.bool_)) or not isinstance(code, (int, np.integer)) \
                or int(code) not in st.MEANINGS or int(code) < 0:
            raise InputError(f"{label}: compute returned {code!r} at the probe point p = {p.tolist()}; expected "
                             f"a status code of mechsweep.status ({', '.join(f'{c} {n}' for c, n in sorted(st.MEANINGS.items()) if c >= 0)})")
        results.append(args)
    if int(code) == st.OK:
        row, crv = results[1][2], results[1][3]
        unwritten = [model.scalars[k] for k in range(row.size) if row[k] == _SENTINEL]
        unwritten += [f"{model.curves[c]}[{', '.join(str(j) for j in np.flatnonzero(crv[c] == _SENTINEL)[:5])}"
                      f"{', ...' if (crv[c] == _SENTINEL).sum() > 5 else ''}]"
                      for c in range(crv.shape[0]) if (crv[c] == _SENTINEL).any()]
        if unwritten:
            raise InputError(f"{label}: compute returned OK without writing {', '.join(unwritten)} at the probe "
                             f"point p = {p.tolist()} with every output wanted (write row[k] for each wanted "
                             "scalar k and every value of curves[slot[c]] for each wanted curve c)")
    from . import writes  # compute writes only row, curves and scratch

    writes.check(writes.closed_calls(model, _probe_arrays(model, p.copy(), math.nan), data), label)
    module, path, qual = load.function_ref(model.compute, "compute", model.name)
    try:
        disp = load.jitted(module, path, qual)
        disp(*_probe_arrays(model, p.copy(), math.nan), *data)
    except Exception as exc:
        raise load.compile_failure(exc, file, label, "compute") from None
    # every path returns a status code, also those the probe point did not take (a bare return
    # there made the compiled kernel fail on None inside its parallel loop)
    problem = load.return_problem(disp, "compute", status=True)
    if problem is not None:
        raise InputError(f"{label}: {problem}")
