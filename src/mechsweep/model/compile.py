"""Declaration + wanted outputs + method -> one parallel chunk kernel, written as a real module file.

numba's disk cache misses, in every new process, for a parallel kernel that receives a user's
dispatcher as an argument or closes over it. So the kernel's source is generated as a module file
in the cache folder (``<mechsweep cache>/models/mechsweep_gen_<hash>.py``) that imports the model's
functions by module path and is compiled with ``cache=True`` (via ``_jit.jit``). The file name
is keyed by a hash of the model's module sources, the functions' names, the layout of ``p`` (number
of parameters, settings, internal slots, states), the wanted measurements (with all their settings),
the wanted closed forms and the method: a changed model or a different choice of outputs or method
gets a new file, an unchanged one the same file and, in a new process, numba's cached machine code.
The folder itself is keyed by the package sources (see _jit.py). Built-in models (mechsweep.models)
take the same route.

The kernel (one per choice; see docs/model-layer.md):

    for each of T threads (Threaded: numba.get_num_threads() Python threads, nogil; the points strided
    over the grid, first = thread, step = T):
        scratch of the thread: p, y, the method's workspace(s)
        for each point: p = (parameters, settings, internal slots = 0, scratch = 0)
            status = classify(p)                         -> non-OK: every output NaN, next point
            closed forms that need no measurement        (only those wanted or needed: need[j])
            status = prepare(p)                          -> non-OK: measurements NaN, closed forms kept
            measurements: a FirstEvent (or a lone first Crossing) calls the method's event solver
                          directly; the others observe one shared DOP853 trajectory (dop853 only)
            closed forms that need a measurement
"""
from __future__ import annotations

import ast
import hashlib
import importlib.util
import os
import re
import sys
import tempfile
import threading
from concurrent.futures import ThreadPoolExecutor, wait
from pathlib import Path

from .. import _jit
from . import lanes as lane_kernels
from . import load, sources

_KERNELS: dict[str, object] = {}
_BY_OBJECTS: dict[tuple, tuple] = {}  # kernel_for's memo: (model, chosen, closed, kernel name) by their ids
_LOADED: dict[str, object] = {}  # generated modules imported in this process (load_generated)
_LOAD_LOCK = threading.Lock()
_TMP: list[str] = []

BLOCK = 16  # the fewest points a thread of Threaded is given (fewer points: fewer threads)
# kernel_for's route where model/lanes.py applies and the caller names none (``lanes=None``): True the
# SIMD-lane kernel, False or None one point at a time. A run names the route its plan chose
# (mechsweep/plan.py, ``choose_route``, which reads this as an override: the benches and tests set True or
# False to compare the two routes). The results are bitwise the same either way (tests/test_model_lanes.py).
USE_LANES: bool | None = None
# The lane kernel compiles in about four times the CPU time of the one-point kernel and integrates
# about twice as fast (Duffing period, sweeps/quickstart.toml; `mechsweep bench startup --only routes`
# measures both): cold compile 22.2 s of CPU against 5.5 s, warm 931k against 428k points per CPU
# second, so the 16.6 s are repaid at about 1.3 * 10^7 points. A plan takes the lanes for a run of at
# least this many points, or when they are compiled already (``lanes_recorded``).
LANES_FROM_POINTS = 10**7
_RECORDED: set[str] = set()  # lane kernels compiled (or loaded from the disk cache) in this process


def _folder() -> Path:
    if _jit.cache_dir is not None:
        path = Path(_jit.cache_dir) / "models"
    else:  # caching off: a private folder for this process
        if not _TMP:
            _TMP.append(tempfile.mkdtemp(prefix="mechsweep-models-"))
        path = Path(_TMP[0])
    path.mkdir(parents=True, exist_ok=True)
    return path


# An exception the user's code raises inside the parallel loop (at a point the load-time probe did
# not see) must not escape the kernel: numba then either loses it or leaves the Python error
# indicator set (SystemError, a traceback). The guards catch it, write NaN (or return USER_ERROR
# from classify/prepare) and raise the point's flag p[NPI] (the slot after the internal ones); the
# kernel gives the point status USER_ERROR and computes the other points.
# The one-point kernel's module (kernel_source) keeps their text but not their try (_one_try): its kernel
# catches an exception once per point, around the function that computes the point; the lane and
# trajectory kernels keep the guards.
_GUARD = {
    "rhs": "@jit\ndef rhs(t, y, p, dydt):\n    try:\n        user_rhs(t, y, p, dydt)\n    except Exception:\n"
           "        dydt[:] = np.nan\n        p[NPI] = 1.0\n",
    "initial": "@jit\ndef initial(p, y0):\n    try:\n        user_initial(p, y0)\n    except Exception:\n"
               "        y0[:] = np.nan\n        p[NPI] = 1.0\n",
    "forcing": "@jit\ndef forcing(p):\n    try:\n        return user_forcing(p)\n    except Exception:\n"
               "        p[NPI] = 1.0\n        return np.nan\n",
    "jac": "@jit\ndef jac(t, y, p, J):\n    try:\n        user_jac(t, y, p, J)\n    except Exception:\n"
           "        J[:, :] = np.nan\n        p[NPI] = 1.0\n",
    "accel": "@jit\ndef accel(t, q, p, a):\n    try:\n        user_accel(t, q, p, a)\n    except Exception:\n"
             "        a[:] = np.nan\n        p[NPI] = 1.0\n",
    "classify": "@jit\ndef classify(p):\n    try:\n        return user_classify(p)\n    except Exception:\n"
                "        return st.USER_ERROR\n",
    "prepare": "@jit\ndef prepare(p, rtol):\n    try:\n        return user_prepare(p, rtol)\n    except Exception:\n"
               "        return st.USER_ERROR\n",
    "variational": "@jit\ndef variational(t, Phi, p, dPhi):\n    try:\n        user_variational(t, Phi, p, dPhi)\n"
                   "    except Exception:\n        dPhi[:] = np.nan\n        p[NPI] = 1.0\n",
    "variational_jac": "@jit\ndef variational_jac(t, Phi, p, J):\n    try:\n        user_variational_jac(t, Phi, p, J)\n"
                       "    except Exception:\n        J[:, :] = np.nan\n        p[NPI] = 1.0\n",
    "symplectic_step": "@jit\ndef symplectic_step(p, rtol):\n    try:\n        return user_symplectic_step(p, rtol)\n"
                       "    except Exception:\n        p[NPI] = 1.0\n        return np.nan\n",
}


_SYSTEM_ROLES = ("rhs", "initial", "jac", "accel", "symplectic_step", "prepare")


def _guard_numbered(name: str) -> str:
    """The guard of a numbered function: a measurement's System function (rhs0, prepare2, ...) or a
    closed form's classify (cfclassify1), as the model's own guard of that role."""
    base = name.rstrip("0123456789")
    role = "classify" if base in ("cfclassify", "mclassify") else base
    return _GUARD[role].replace(f"def {role}(", f"def {name}(").replace(f"user_{role}(", f"user_{name}(")


def _system(m):
    """The System a measurement integrates instead of the model's equation, or None."""
    return getattr(m, "system", None)


def _own(m) -> bool:
    """Whether a measurement's integration is a function pass<k> of its own (a System or refine)."""
    return _system(m) is not None or getattr(m, "refine", None) is not None


def _fd_jac(name: str, rhs: str, count: bool = False, n: str = "NS", at: str = "SCR") -> str:
    """The engine's Jacobian of ``rhs`` by central differences (scratch p[at:at + 3 n]: y + h, f(y + h),
    f(y - h); ``n`` and ``at`` are source text: names or numbers). ``count``: its 2 n rhs calls are
    added to the counter p[at + 3 n] (the kernel adds it to n_rhs; the caller must give p that slot)."""
    counter = f"\n    p[{at} + 3 * {n}] += 2.0 * {n}  # its rhs calls, for n_rhs" if count else ""
    return f"""

@jit
def {name}(t, y, p, J):
    # engine-built Jacobian: central differences of {rhs}, step cbrt(eps) max(1, |y_j|) (scratch in p){counter}
    yp = p[{at}:{at} + {n}]
    fp = p[{at} + {n}:{at} + 2 * {n}]
    fm = p[{at} + 2 * {n}:{at} + 3 * {n}]
    for j in range({n}):
        for i in range({n}):
            yp[i] = y[i]
        h = 6.055454452393343e-06 * max(1.0, abs(y[j]))
        up = y[j] + h
        dn = y[j] - h
        yp[j] = up
        {rhs}(t, yp, p, fp)
        yp[j] = dn
        {rhs}(t, yp, p, fm)
        for i in range({n}):
            J[i, j] = (fp[i] - fm[i]) / (up - dn)
"""


def _guard_call(name: str, args: str) -> str:
    return (f"@jit\ndef {name}({args}):\n    try:\n        return user_{name}({args})\n    except Exception:\n"
            f"        p[NPI] = 1.0\n        return np.nan\n")


def rank_source(order) -> str:
    """Generated module code of ``worse(a, b)``: the more severe of two status codes in a model's
    ``status_order`` (model/ode.py ranks), or "" for a model without one."""
    if not order:
        return ""
    from .ode import ranks
    return (f"\nRANK = np.array({ranks(order).tolist()!r}, dtype=np.int64)  # by status code: 0 most severe\n\n\n"
            "@jit\ndef worse(a, b):\n    return b if RANK[b] < RANK[a] else a\n")


def combine(order, a: str, c: str, indent: int) -> str:
    """Kernel code folding status ``c`` into ``a``: the first failure wins, or with a model's
    ``status_order`` the more severe (``worse``)."""
    pad = " " * indent
    if order:
        return f"\n{pad}{a} = worse({a}, {c})"
    return f"\n{pad}if {c} != st.OK and {a} == st.OK:\n{pad}    {a} = {c}"


def columns(chosen) -> list[int]:
    """First column of each chosen measurement in the kernel's table (a measurement with
    ``n_values`` > 1, Floquet, has that many columns)."""
    cols, c = [], 0
    for m in chosen:
        cols.append(c)
        c += getattr(m, "n_values", 1)
    return cols + [c]


def _describe(m) -> str:
    """A measurement as the generated source names it: the same text in every process (no
    function addresses, which would rewrite the file and void numba's cache index)."""
    return repr(m.key()) if hasattr(m, "key") else repr(m)


def is_direct(chosen) -> bool:
    """Whether the chosen measurements integrate on their own with any method: FirstEvents, or one
    Crossing with n = 1 alone (no shared trajectory to build for a single first crossing)."""
    if not chosen:
        return False
    if all(getattr(m, "direct", False) for m in chosen):
        return True
    return len(chosen) == 1 and type(chosen[0]).__name__ == "Crossing" and chosen[0].n == 1


def floquet_only(chosen) -> bool:
    """Whether the chosen measurements are Floquet measurements only (they offer dop853, radau and
    auto: their variational integration has its own method switch, Floquet._integrate)."""
    return bool(chosen) and all(type(m).__name__ == "Floquet" for m in chosen)


def layout(model) -> tuple[int, int, int]:
    """(parameters, settings, internal slots): p[0:a] parameters, p[a:a+b] settings, p[a+b:a+b+c]
    internal slots written by prepare, then scratch."""
    return len(model.params), len(model.settings), len(model.internal)


def _functions(model, chosen, closed) -> list[tuple[str, object]]:
    """(name in the generated module, user function) of everything the kernel calls."""
    f = [("rhs", model.rhs), ("initial", model.initial)]
    for role in ("forcing", "jac", "accel", "classify", "prepare", "symplectic_step"):
        func = getattr(model, "forcing_period" if role == "forcing" else role, None)
        if func is not None:
            f.append((role, func))
    if callable(getattr(model, "switch_times", None)):  # model/switches.py; constants go into the source
        f.append(("switch_times", model.switch_times))
    for k, m in enumerate(chosen):
        for role, func in getattr(m, "functions", lambda: ())():
            f.append((f"{role}{k}", func))
        if getattr(m, "classify", None) is not None:  # where the measurement applies (else skipped)
            f.append((f"mclassify{k}", m.classify))
    for j, c in enumerate(closed):
        f.append((f"closed{j}", c.func))
        if getattr(c, "classify", None) is not None:
            f.append((f"cfclassify{j}", c.classify))
    return f


def module_prologue(what: str, imports: tuple[str, ...], refs: dict, inline: bool = False) -> list[str]:
    """The head of a generated kernel module: docstring, imports, the user's functions (``refs``:
    name -> reference) and their guards (an exception in them flags the point, see _GUARD).
    ``inline``: the user's functions are compiled into their guards (load.inlined, numba IR inlining)
    instead of each as a function of its own that the guard calls."""
    how = "inlined" if inline else "jitted"
    lines = [f'"""Generated by {what}.\nDo not edit: a changed model gets a new file."""\n'
             "import math\n\nimport numpy as np\n\n"
             "from mechsweep import status as st\n"
             + "".join(f"{i}\n" for i in imports)
             + f"from mechsweep.model.load import {how}\n\n"]
    for name, ref in refs.items():
        lines.append(f"user_{name} = {how}{ref!r}\n")
    lines.append("\n")
    for name in refs:
        if name in _GUARD:
            lines.append(_GUARD[name] + "\n")
        elif (name.rstrip("0123456789") in _SYSTEM_ROLES + ("cfclassify", "mclassify", "variational", "variational_jac")
              and name[-1].isdigit()):  # a System's, a classify of a measurement or closed form, Floquet's variational
            lines.append(_guard_numbered(name) + "\n")
    return lines


def kernel_source(model, chosen, refs: dict, origin: str, shared: bool = True, closed=(), method: str = "dop853",
                  direct: bool | None = None) -> str:
    """Source of the generated module. ``refs``: name -> (module, path, qualname) of every function
    in _functions. ``closed``: the closed forms to compute, in dependency order."""
    n_p, n_set, n_int = layout(model)
    n_s = len(model.states)
    n_q = n_s // 2
    npi = n_p + n_set + n_int
    direct = is_direct(chosen) if direct is None else direct
    group = [] if direct else [k for k, m in enumerate(chosen) if shared and hasattr(m, "shared_row")]
    scr = [n_s]
    fd_own = [k for k, m in enumerate(chosen) if _system(m) is not None and _system(m).jac is None]
    fd_count = direct and method in ("radau", "auto") and ("jac" not in refs or bool(fd_own))
    if fd_count:  # the engine's Jacobian: 3 NS of scratch and the counter of its rhs calls
        scr.append(3 * n_s + 1)
    scr += [m.scratch(n_s) for m in chosen if hasattr(m, "scratch")]
    n_scr = max(scr)
    uses = {"dop853": bool(chosen) and (method in ("dop853", "auto") or not direct),
            "radau": direct and method in ("radau", "auto"),
            "symplectic": direct and method == "symplectic"}
    lines = module_prologue(f"mechsweep.model.compile for model {model.name!r}, method {method}",
                            ("from mechsweep._jit import jit, jit_internal, jit_into_caller, pjit, prange",
                             "from mechsweep.ode import dop853, radau, symplectic"), refs, inline=True)
    lines.append(f"NP = {n_p}\nNSET = {n_set}\nNPI = {npi}  # p[NPI]: the point's user-error flag\nSCR = NPI + 1\n"
                 f"NS = {n_s}\nNQ = {n_q}\nNSCR = {n_scr}\n"
                 f"BLOCK = {BLOCK}\n")
    switched = getattr(model, "switch_times", None) is not None
    if switched:  # steps end on the declared switch times; p gets two slots after the scratch (switches.SW)
        from .switches import source as switch_source
        lines.append(switch_source(model, "SCR + NSCR", refs, guarded=False))
    order = tuple(getattr(model, "status_order", ()))
    lines.append(rank_source(order))
    for j, c in enumerate(closed):
        args = ", ".join(["p"] + [f"x{i}" for i in range(len(c.needs))])
        lines.append("\n" + _guard_call(f"closed{j}", args))
    if direct and uses["radau"] and "jac" not in refs:
        lines.append(_fd_jac("jac", "rhs", count=True))
    if direct and uses["radau"]:
        for k in fd_own:
            lines.append(_fd_jac(f"jac{k}", f"rhs{k}", count=True))
    # ---- measurements
    # a FirstEvent beside shared-path measurements integrates on its own too (dop853, as alone)
    alone = [k for k, m in enumerate(chosen) if direct or getattr(m, "direct", False)]
    if alone:
        for k, m in ((k, chosen[k]) for k in alone):
            lines.append(f"\n# ---- measurement {k}: {_describe(m)}, direct, {method}\n")
            if type(m).__name__ == "Crossing":
                sign = 1.0 if m.direction == "down" else -1.0
                idx = model.states.index(m.state)
                lines.append(f"@jit\ndef event{k}(t, y, p):\n    return {sign!r} * (y[{idx}] - {float(m.level)!r})\n\n")
            else:
                ev = _guard_call(f"event{k}", "t, y, p")
                if getattr(m, "direction", "down") == "up":  # the roots where the event goes from < 0 to >= 0
                    ev = ev.replace(f"return user_event{k}(", f"return -user_event{k}(")
                lines.append(ev)
                if f"t_max{k}" in refs:
                    lines.append(_guard_call(f"t_max{k}", "p"))
                if f"value{k}" in refs:
                    lines.append(_guard_call(f"value{k}", "p, t"))
            if f"refine{k}" in refs:
                lines.append(_guard_call(f"refine{k}", "p, rtol, x"))
            own = "" if _system(m) is None else str(k)  # the suffix of this measurement's equation
            rhs, jac, accel = f"rhs{own}", f"jac{own}", f"accel{own}"
            nth = int(getattr(m, "n", 1)) if type(m).__name__ == "FirstEvent" else 1
            solvers = []  # (name, constructor with {ev} for the event function)
            if method == "dop853":
                solvers.append((f"solve{k}", f"dop853.make_event_solver({rhs}, {{ev}})"))
            elif method == "auto":
                solvers += [(f"solve{k}_st", f"dop853.make_event_solver({rhs}, {{ev}}, stiffness_test=True)"),
                            (f"solve{k}_r", f"radau.make_event_solver({rhs}, {jac}, {{ev}})")]
            elif method == "radau":
                solvers.append((f"solve{k}_r", f"radau.make_event_solver({rhs}, {jac}, {{ev}})"))
            elif method == "symplectic":
                for ev in ([f"event{k}", f"event{k}_b"] if nth > 1 else [f"event{k}"]):
                    if ev != f"event{k}":
                        lines.append(f"\n@jit\ndef {ev}(t, y, p):  # the other direction\n"
                                     f"    return -event{k}(t, y, p)\n")
                    lines.append(f"""

@jit
def q{ev}(t, q, v, p):  # the event on y = (q, v), copied into scratch
    yb = p[SCR:SCR + NS]
    for j in range(NQ):
        yb[j] = q[j]
        yb[NQ + j] = v[j]
    return {ev}(t, yb, p)
""")
                solvers.append((f"solve{k}_s", f"symplectic.make_event_solver({accel}, q{{ev}}, "
                                               f"{int(model.symplectic_order)})"))
            if nth == 1:
                lines += [f"{name} = {ctor.format(ev=f'event{k}')}\n" for name, ctor in solvers]
            else:
                if method != "symplectic":
                    lines.append(f"\n@jit\ndef event{k}_b(t, y, p):  # the other direction\n"
                                 f"    return -event{k}(t, y, p)\n\n")
                for name, ctor in solvers:
                    lines.append(_nth_root_source(name, ctor, f"event{k}", nth, method == "symplectic",
                                                  int(getattr(m, "since", 0))))
            if _own(m):
                lines.append(_pass_source(k, method, own, "t_max" + str(k) + "(p)" if f"t_max{k}" in refs
                                          else repr(float(m.t_max)), _scratch_args(uses)))
    if not direct:
        if group:
            rows, exprs = [], []
            for k in group:
                row = list(chosen[k].shared_row(model.states))
                if f"of{k}" in refs:  # an expression: its index in observe
                    row[1] = float(k)
                    exprs.append(k)
                rows.append("(" + ", ".join("math.nan" if x != x else repr(x) for x in row) + ")")
            rows = ",\n    ".join(rows)
            lines.append(f"\n# ---- measurements {group} on one shared trajectory\n"
                         "from mechsweep.model.measure import make_shared\n\n")
            for k in group:
                for role, args in (("of", "t, y, p"), ("t0", "p"), ("t1", "p")):
                    if f"{role}{k}" in refs:
                        lines.append(_guard_call(f"{role}{k}", args) + "\n")
            if exprs:
                lines.append("\n@jit\ndef observe(t, y, p, j):  # the expressions of the shared rows\n"
                             + "".join(f"    if j == {k}:\n        return of{k}(t, y, p)\n" for k in exprs)
                             + "    return math.nan\n\n\nshared = make_shared(rhs, observe"
                             + (", (next_switch, switch_check, switch_clamp))\n" if switched else ")\n"))
            else:
                lines.append("shared = make_shared(rhs, None, (next_switch, switch_check, switch_clamp))\n"
                             if switched else "shared = make_shared(rhs)\n")
            lines.append(f"SHARED_M = np.array([\n    {rows}])\nNSH = {len(group)}\n")
        for k, m in enumerate(chosen):
            if k in group or k in alone:
                continue
            lines.append(f"\n# ---- measurement {k}: {_describe(m)}\n")
            lines.append(m.source(k, model.states, npi + 1, "jac" in refs, method) if hasattr(m, "scratch")
                         else m.source(k, model.states))
    cols = columns(chosen)
    closed_col = {c.name: cols[-1] + j for j, c in enumerate(closed)}
    mnames = {m.name: k for k, m in enumerate(chosen)}
    # a measurement's further kernel values (Floquet's kind and angle), readable by closed forms
    mvalues = {x: f"m{k}_{e}" for k, m in enumerate(chosen) if hasattr(m, "values")
               for e, x in enumerate(m.values()) if e > 0}

    def closed_code(which):
        out = []
        for j, c in enumerate(closed):
            if which != any(x in mnames or x in mvalues for x in c.needs):
                continue
            args = ", ".join(["p"] + [f"m{mnames[x]}" if x in mnames else mvalues[x] if x in mvalues
                                      else f"cf{[d.name for d in closed].index(x)}" for x in c.needs])
            if f"cfclassify{j}" in refs:  # the formula applies only where its classify says OK
                fold = combine(order, "code", "cc", 20) if order else """
                    if code == st.OK:
                        code = cc"""
                out.append(f"""
            cf{j} = math.nan
            if need[{j}]:
                cc = cfclassify{j}(p)
                if cc != st.OK:{fold}
                else:
                    cf{j} = closed{j}({args})
                    table[i, {closed_col[c.name]}] = cf{j}""")
                continue
            out.append(f"""
            cf{j} = math.nan
            if need[{j}]:
                cf{j} = closed{j}({args})
                table[i, {closed_col[c.name]}] = cf{j}""")
        return "".join(out)

    # with switches: their two slots, then NS more (a measurement that takes the last NS slots of p as
    # scratch, Extremum's shared=False source, stays off them)
    scratch = ["\n        p = np.empty(SCR + NSCR + 2 + NS)" if switched else "\n        p = np.empty(SCR + NSCR)",
               "\n        y = np.empty(NS)"]
    if uses["dop853"]:
        scratch.append("\n        work = dop853.workspace(NS)")
    if uses["radau"]:
        scratch.append("\n        rwork = radau.workspace(NS)")
    if uses["symplectic"]:
        scratch.append("\n        q = np.empty(NQ)\n        v = np.empty(NQ)\n        swork = symplectic.workspace(NQ)")
    windows = [(j, k, role) for j, k in enumerate(group) for role in ("t0", "t1") if f"{role}{k}" in refs]
    if group:
        scratch.append("\n        svals = np.empty(NSH)\n        scodes = np.empty(NSH, dtype=np.int64)")
    if windows:  # the shared rows with per-point windows: a copy of the table per block
        scratch.append("\n        Msh = SHARED_M.copy()")
    body = []
    if "classify" in refs:
        body.append("""
            c = classify(p)
            if c != st.OK:
                status[i] = c
                continue""")
    body.append(closed_code(False))
    if chosen:
        for k in range(len(chosen)):
            body.append(f"\n            m{k} = math.nan")
        body += [f"\n            {v} = math.nan" for v in mvalues.values()]
        body.append("\n            c = prepare(p, rtol)" if "prepare" in refs else "\n            c = st.OK")
        body.append("""
            if c != st.OK:""" + (combine(order, "code", "c", 16) if order else """
                code = c""") + """
            else:""")
        meas = []
        if group:
            meas.append("""
                initial(p, y)""" + "".join(f"""
                Msh[{j}, {5 if role == "t0" else 6}] = {role}{k}(p)""" for j, k, role in windows) + f"""
                a, b_ = shared(y, p, {"Msh" if windows else "SHARED_M"}, rtol, atol, max_steps, work, svals, scodes)
                n_steps[i] += a
                n_rhs[i] += b_""")
        for k, m in enumerate(chosen):
            start = len(meas)
            direct = k in alone  # this measurement integrates on its own
            tm = ""
            if direct:
                tm = f"t_max{k}(p)" if f"t_max{k}" in refs else repr(float(m.t_max))
            if k in group:
                j = group.index(k)
                meas.append(f"""
                c = scodes[{j}]
                val = svals[{j}]""")
            elif direct and _own(m):
                meas.append(_own_body(k, refs, _scratch_args(uses)))
            elif direct and method == "dop853":
                meas.append(f"""
                initial(p, y)
                c, val, a, b_ = solve{k}(0.0, y, p, {tm}, rtol, atol, 0.0, max_steps, work)""")
            elif direct and method == "radau":
                meas.append(f"""
                initial(p, y)
                c, val, a, b_ = solve{k}_r(0.0, y, p, {tm}, rtol, atol, 0.0, max_steps, rwork)""")
            elif direct and method == "auto":
                meas.append(f"""
                tm = {tm}
                initial(p, y)
                c, val, a, b_ = solve{k}_st(0.0, y, p, tm, rtol, atol, 0.0, max_steps, work)
                if c == st.STIFF:  # a stiff point starts again with radau; the costs add up
                    initial(p, y)
                    c, val, a2, b2 = solve{k}_r(0.0, y, p, tm, rtol, atol, 0.0, max_steps, rwork)
                    a += a2
                    b_ += b2""")
            elif direct and method == "symplectic":
                meas.append(f"""
                initial(p, y)
                for j in range(NQ):
                    q[j] = y[j]
                    v[j] = y[NQ + j]
                h = symplectic_step(p, rtol)
                if not h > 0.0:
                    c, val, a, b_ = st.NONFINITE, math.nan, 0, 0
                else:
                    c, val, a, b_ = solve{k}_s(0.0, q, v, p, h, {tm}, max_steps, swork)""")
            elif getattr(m, "n_values", 1) > 1:  # the first value, then the others into their own columns
                extra = range(1, m.n_values)
                meas.append(f"""
                initial(p, y)
                c, val, {"".join(f"val_{e}, " for e in extra)}a, b_ = measure{k}(y, p, rtol, atol, max_steps, work)
                if c == st.OK:""" + "".join(f"""
                    table[i, {cols[k] + e}] = val_{e}""" for e in extra))
            else:
                meas.append(f"""
                initial(p, y)
                c, val, a, b_ = measure{k}(y, p, rtol, atol, max_steps, work)""")
            keep = "".join(f"\n                    {v} = val_{v.rsplit('_', 1)[1]}" for v in mvalues.values()
                           if v.startswith(f"m{k}_"))
            if not (k in group) and not (direct and _own(m)):
                meas.append("""
                n_steps[i] += a
                n_rhs[i] += b_""")
            if direct and f"value{k}" in refs and not _own(m):
                meas.append(f"""
                if c == st.OK:
                    val = value{k}(p, val)""")
            if f"mclassify{k}" in refs:  # the measurement only where its classify says OK
                inner = "".join(meas[start:]).replace("\n", "\n    ")
                meas[start:] = [f"""
                val = math.nan
                c = mclassify{k}(p)
                if c == st.OK:{inner}"""]
            meas.append(f"""
                if p[NPI] != 0.0:
                    c = st.USER_ERROR
                if c == st.OK and not math.isfinite(val):
                    c = st.NONFINITE
                if c == st.OK:
                    table[i, {cols[k]}] = val
                    m{k} = val{keep}""" + (f"""
                else:{combine(order, "code", "c", 20)}""" if order else """
                elif code == st.OK:
                    code = c"""))
        body.append("".join(meas))
        body.append(closed_code(True))
    fd_add = ("\n            n_rhs[i] += int(p[SCR + 3 * NS])  # the rhs calls of the engine's Jacobian"
              if fd_count else "")
    clamp_reset = "\n            switch_clamp(p, -math.inf, math.inf)" if switched else ""
    # every function above is called by the kernel only: compiled without numba's Python and C wrappers; the
    # guards lose their try (_one_try)
    lines = [_one_try("".join(lines).replace("\n@jit\ndef ", "\n@jit_internal\ndef "))]
    names = ", ".join(re.findall(r"^\s*(\w+) = ", "".join(scratch), re.M))
    point = (f"code = st.OK{''.join(body)}{fd_add}\n            if p[NPI] != 0.0 and code == st.OK:\n"
             "                code = st.USER_ERROR\n            return code\n")
    point = point.replace("\n                status[i] = c\n                continue", "\n                return c")
    point = "\n".join(line[8:] if line.startswith(" " * 12) else line for line in point.split("\n"))
    lines.append(f"""

@jit_internal
def point(i, P, S, need, rtol, atol, max_steps, table, n_steps, n_rhs, {names}):
    # one point, p filled: its status. An exception raised by the model's code ends it in the kernel's try
    {point}

@jit
def kernel(P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs, first, step):
    # the points first, first + step, ... (strided: cost varies along the grid); compile.Threaded runs
    # one such stride per thread (nogil), as a prange would, without numba's parallel compile
    n = P.shape[0]
    if first < n:{''.join(scratch)}
        for i in range(first, n, step):
            if status[i] != st.OK:
                continue
            for j in range(NP):
                p[j] = P[i, j]
            for j in range(NSET):
                p[NP + j] = S[j]
            for j in range(NP + NSET, SCR + NSCR):
                p[j] = 0.0{clamp_reset}
            try:  # the module's one try: what a point computes after its model code raised is not computed
                code = point(i, P, S, need, rtol, atol, max_steps, table, n_steps, n_rhs, {names})
            except Exception:
                code = st.USER_ERROR
            status[i] = code
""")
    return "".join(lines)


def strip_guards(source: str, decorator: str | None = None) -> str:
    """``source`` (generated module code) with every guard's ``try`` taken out: a top-level function whose
    body is one ``try: ... except Exception: ...`` (after comments or a docstring, which stay) keeps the
    body of its try, dedented, and loses the handler; ``decorator`` (e.g. ``"@jit_into_caller"``) then
    replaces its decorator line(s). The one mechanism behind the one-point module's _one_try and
    model/switches.py's ``source(guarded=False)``. It reads the parsed module (ast), not a pattern of the
    text: a comment or docstring before the try, a blank line or a comment inside it, a comment on the
    ``except`` line are no special cases (each of the two regexes it replaced missed some of them).
    ValueError where a ``try`` is left that is not such a guard (code after the handler, another handler,
    else/finally, a try nested in other code): the caller would otherwise keep a try it meant to remove."""
    lines = source.splitlines(keepends=True)
    edits = []  # (first line, end line (0-based, exclusive), replacement lines), in source order
    for node in ast.parse(source).body:
        if not isinstance(node, ast.FunctionDef):
            continue
        body = node.body
        if (len(body) == 2 and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            body = body[1:]  # after the docstring
        if len(body) != 1 or not isinstance(body[0], ast.Try):
            continue
        guard = body[0]
        if (len(guard.handlers) != 1 or guard.orelse or guard.finalbody or guard.handlers[0].name is not None
                or not isinstance(guard.handlers[0].type, ast.Name) or guard.handlers[0].type.id != "Exception"):
            continue
        cut = guard.body[0].col_offset - guard.col_offset
        kept = [line[cut:] if line.startswith(" " * cut) else line.lstrip(" ")
                for line in lines[guard.lineno:guard.handlers[0].lineno - 1]]
        edits.append((guard.lineno - 1, node.end_lineno, kept))
        if decorator is not None and node.decorator_list:
            edits.append((node.decorator_list[0].lineno - 1, node.lineno - 1, [decorator + "\n"]))
    for first, end, new in sorted(edits, reverse=True):
        lines[first:end] = new
    out = "".join(lines)
    left = [n.lineno for n in ast.walk(ast.parse(out)) if isinstance(n, ast.Try)]
    if left:
        raise ValueError(f"a try that is not a guard (a function's whole body: try, one except Exception) at "
                         f"line(s) {left} of the generated code")
    return out


def _one_try(source: str) -> str:
    """The one-point module's guards (_GUARD, _guard_call, switches.source: a model function's call in a
    ``try``) as plain calls that numba inlines into their callers (``jit_into_caller``; strip_guards): the
    kernel catches an exception once per point, around ``point`` (a function of its own: numba's try does
    not catch a raise inlined into its own body). numba types and lowers a ``try`` with every operation of
    its body split off to test for an exception: a guard cost several times the compile CPU of the
    one-line call inside it (docs/performance-startup.md); the quickstart's module had 14 guards."""
    return strip_guards(source, "@jit_into_caller")


def _nth_root_source(name: str, ctor: str, event: str, n: int, symplectic: bool, since: int = 0) -> str:
    """``name``: an event solver of the same signature as the method's that returns the ``n``-th
    root of ``event`` (from > 0 to <= 0) instead of the first: 2 n - 1 searches, alternating with
    the other direction's (``event``_b) so that a search never restarts on the root it just found;
    each search restarts the integrator at the previous root and gets what is left of max_steps
    after the accepted steps before it. A search without a root (NO_EVENT: fewer than n roots
    before t_max) or failing ends it with its status. ``since`` > 0: the time returned is from root
    ``since`` to root n (e.g. 1 and 2: the period of an autonomous oscillation)."""
    if symplectic:
        sig, nxt = "t0, q, v, p, h, tm, max_steps, work", "t, q, v, p, h, tm, max_steps - a, work"
    else:
        sig, nxt = ("t0, y, p, tm, rtol, atol, h0, max_steps, work",
                    "t, y, p, tm, rtol, atol, 0.0, max_steps - a, work")
    out = [f"{name}_f1 = {ctor.format(ev=event)}\n", f"{name}_b1 = {ctor.format(ev=event + '_b')}\n"]
    out.append(f"""

@jit
def {name}({sig}):  # root {n} of {event}
    c, t, a, b_ = {name}_f1({sig})
    ts = {"t" if since == 1 else "0.0"}  # the time the result is counted from
    for j in range({2 * (n - 1)}):
        if c != st.OK:
            break
        if a >= max_steps:
            c = st.MAX_STEPS
            break
        if j % 2 == 0:
            c, t, a2, b2 = {name}_b1({nxt})
        else:
            c, t, a2, b2 = {name}_f1({nxt})
        a += a2
        b_ += b2
        if j == {2 * since - 3}:  # root {since} found
            ts = t
    return c, t - ts, a, b_

""")
    return "".join(out)


def _scratch_args(uses) -> str:
    """The method workspaces a pass function receives (those the kernel allocates)."""
    return ", ".join((["work"] if uses["dop853"] else []) + (["rwork"] if uses["radau"] else [])
                     + (["q", "v", "swork"] if uses["symplectic"] else []))


def _pass_source(k: int, method: str, own: str, tm: str, args: str) -> str:
    """``pass<k>(p, y, rtol, atol, max_steps, <workspaces>) -> (status, t, n_steps, n_rhs)``: one
    integration of measurement k from its initial state by the method (auto: dop853 with the
    stiffness test, a stiff point again by radau, the costs added)."""
    head = f"\n\n@jit\ndef pass{k}(p, y, rtol, atol, max_steps, {args}):\n    tm = {tm}\n    initial{own}(p, y)\n"
    if method == "dop853":
        body = f"    return solve{k}(0.0, y, p, tm, rtol, atol, 0.0, max_steps, work)\n"
    elif method == "radau":
        body = f"    return solve{k}_r(0.0, y, p, tm, rtol, atol, 0.0, max_steps, rwork)\n"
    elif method == "auto":
        body = (f"    c, val, a, b_ = solve{k}_st(0.0, y, p, tm, rtol, atol, 0.0, max_steps, work)\n"
                f"    if c == st.STIFF:  # a stiff point starts again with radau; the costs add up\n"
                f"        initial{own}(p, y)\n"
                f"        c, val, a2, b2 = solve{k}_r(0.0, y, p, tm, rtol, atol, 0.0, max_steps, rwork)\n"
                f"        a += a2\n        b_ += b2\n    return c, val, a, b_\n")
    else:
        body = (f"    for j in range(NQ):\n        q[j] = y[j]\n        v[j] = y[NQ + j]\n"
                f"    h = symplectic_step{own}(p, rtol)\n    if not h > 0.0:\n"
                f"        return st.NONFINITE, math.nan, 0, 0\n"
                f"    return solve{k}_s(0.0, q, v, p, h, tm, max_steps, swork)\n")
    return head + body


def _own_body(k: int, refs: dict, args: str) -> str:
    """Kernel code of a measurement with its own pass function: its System's prepare, a pass, its
    value and, where refine asks for it, a second pass at the tightened tolerance."""
    value = f"value{k}" in refs
    out = "\n                val = math.nan"
    ind = "                "
    if f"prepare{k}" in refs:
        out += f"\n                c = prepare{k}(p, rtol)\n                if c == st.OK:"
        ind = "                    "
    out += f"""
{ind}c, val, a, b_ = pass{k}(p, y, rtol, atol, max_steps, {args})
{ind}n_steps[i] += a
{ind}n_rhs[i] += b_"""
    if value:
        out += f"\n{ind}if c == st.OK:\n{ind}    val = value{k}(p, val)"
    if f"refine{k}" in refs:
        out += f"""
{ind}if c == st.OK:
{ind}    f = refine{k}(p, rtol, val)
{ind}    if not f <= 1.0:  # NaN-safe: not a number is ILL_CONDITIONED below
{ind}        if not math.isfinite(f):
{ind}            c = st.ILL_CONDITIONED
{ind}        elif a >= max_steps:
{ind}            c = st.MAX_STEPS
{ind}        else:  # once more at the tightened tolerance, with what is left of the step budget
{ind}            c, val, a2, b2 = pass{k}(p, y, rtol / f, atol / f, max_steps - a, {args})
{ind}            n_steps[i] += a2
{ind}            n_rhs[i] += b2"""
        if value:
            out += f"\n{ind}            if c == st.OK:\n{ind}                val = value{k}(p, val)"
    return out


def _cpu_tag() -> str:
    """What numba's machine code is specific to: the target triple, the host CPU and its features (and
    numba's variables that override them). A record of a lane kernel compiled on another CPU that shares
    the cache folder (a home directory on a network disk) does not count here."""
    if not _CPU:
        import llvmlite.binding as llvm

        parts = (llvm.get_process_triple(), llvm.get_host_cpu_name(), llvm.get_host_cpu_features().flatten(),
                 os.environ.get("NUMBA_CPU_NAME", ""), os.environ.get("NUMBA_CPU_FEATURES", ""))
        _CPU.append(hashlib.sha256("|".join(parts).encode()).hexdigest()[:12])
    return _CPU[0]


_CPU: list[str] = []


def _record_path(name: str) -> Path:
    return _folder() / f"{name}.{_cpu_tag()}.compiled"


def lanes_recorded(name: str) -> bool:
    """Whether the lane kernel ``name`` (``lane_name``, or trajectory.lane_name) is compiled for this CPU:
    in this process, or by an earlier process that left its record in the cache folder (written by
    ``record_compiled`` once the kernel had run, i.e. once numba had compiled it and saved its machine
    code: ``cache=True`` saves at compile time). The record is mechsweep's own, next to the kernel's
    module file; it lives and goes with the cache folder, which is keyed by mechsweep's sources."""
    if name in _RECORDED:
        return True
    return _jit.cache_dir is not None and _record_path(name).exists()


def record_compiled(name: str) -> None:
    """Note that the lane kernel ``name`` has run in this process (compiled, or loaded from the disk
    cache), in this process and, when caching is on, as a file in the cache folder."""
    if name in _RECORDED:
        return
    _RECORDED.add(name)
    if _jit.cache_dir is None:
        return
    path = _record_path(name)
    if path.exists():
        return
    tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        tmp.write_bytes(b"")
        os.replace(tmp, path)
    except OSError:  # a record that cannot be written costs a later run the faster route, nothing else
        try:
            tmp.unlink()
        except OSError:
            pass


class _Recorded:
    """A lane kernel that records itself (``record_compiled``) after its first call returns."""

    def __init__(self, kernel, name: str):
        self.kernel, self.name = kernel, name

    def __getattr__(self, attr):
        return getattr(self.kernel, attr)

    def __call__(self, *args):
        self.kernel(*args)
        record_compiled(self.name)


def lane_name(model, chosen, *, origin: str = "", closed=(), method: str = "dop853") -> str | None:
    """The name of the lane kernel that ``kernel_for(model, chosen, closed=closed, method=method,
    lanes=True)`` returns (the key of its record, ``lanes_recorded``), or None when model/lanes.py does
    not apply to this choice (then every route is one point at a time)."""
    memo = (id(model), tuple(map(id, chosen)), tuple(map(id, closed)), method)
    known = _LANE_NAMES.get(memo)
    if known is not None and known[0] is model and all(a is b for a, b in zip(known[1], chosen)) and all(
            a is b for a, b in zip(known[2], closed)):
        return known[3]
    name, lanes = _kernel_name(model, chosen, origin, True, closed, method, True, build=False)
    _LANE_NAMES[memo] = (model, tuple(chosen), tuple(closed), name if lanes else None)
    return name if lanes else None


_LANE_NAMES: dict[tuple, tuple] = {}  # lane_name's memo, as kernel_for's


def kernel_for(model, chosen, *, origin: str = "", module: str = "", attr: str = "", shared: bool = True,
               closed=(), method: str = "dop853", lanes: bool | None = None):
    """The compiled chunk kernel ``kernel(P, S, need, rtol, atol, max_steps, table, status, n_steps,
    n_rhs)`` of ``model`` for the measurements ``chosen`` and the closed forms ``closed`` (dependency
    order; closed form j is computed where ``need[j]``, a run-time choice: one kernel serves every
    choice of closed forms) by ``method`` (cached in-process and on disk); S: the model's settings
    in declared order.
    ``shared=False``: every shared-path measurement integrates on its own (for comparison).
    ``lanes``: where model/lanes.py applies (a lone first event by dop853, an rhs it can rewrite), True
    the kernel integrates LANES points side by side (bitwise the same results; ``lane_name`` names it),
    False one at a time, None as USE_LANES says (one at a time unless it is True). A run passes the route
    its plan chose.
    A second call with the same objects returns the kernel without reading and hashing the model's
    source files again (every chunk of a run asks)."""
    use_lanes = bool(USE_LANES if lanes is None else lanes)
    memo = (id(model), tuple(map(id, chosen)), tuple(map(id, closed)), shared, method, use_lanes)
    known = _BY_OBJECTS.get(memo)
    if (known is not None and known[0] is model and all(a is b for a, b in zip(known[1], chosen))
            and all(a is b for a, b in zip(known[2], closed)) and known[3] in _KERNELS):
        return _KERNELS[known[3]]
    name, _ = _kernel_name(model, chosen, origin, shared, closed, method, use_lanes)
    _BY_OBJECTS[memo] = (model, tuple(chosen), tuple(closed), name)  # the objects kept alive: ids stay theirs
    return _KERNELS[name]


def _switch_key(model):
    """What the generated source depends on of the model's switch times beyond its functions' sources."""
    sw = getattr(model, "switch_times", None)
    if sw is None:
        return ""  # no bytes added: the kernels of a model without switch times keep their names
    from .switches import SIDE, constants
    return repr(("switch_times", constants(model) or "function", SIDE))


def _kernel_name(model, chosen, origin, shared, closed, method, use_lanes, build=True) -> tuple[str, bool]:
    """The kernel's module name (a hash of the model's sources and the choices), the kernel loaded into
    _KERNELS under it (unless not ``build``), and whether it is the lane kernel."""
    refs = {}
    for name, func in _functions(model, chosen, closed):
        refs[name] = load.function_ref(func, name, model.name)
    direct = is_direct(chosen)
    if not direct and not (floquet_only(chosen) and method in ("radau", "auto")):
        method = "dop853"  # the shared path integrates with dop853 only (ModelSpec.methods_for)
    first_root = all(getattr(m, "n", 1) == 1 and getattr(m, "direction", "down") == "down" for m in chosen
                     if type(m).__name__ == "FirstEvent")  # the lane kernel finds the first root of the event as given
    # the lane kernels (model/lanes.py) know neither a measurement's classify nor a status order
    plain = not getattr(model, "status_order", ()) and not any(getattr(m, "classify", None) for m in chosen)
    lane_rhs = lane_kernels.applies(model, chosen, method) if (use_lanes and first_root and plain) else None
    key = hashlib.sha256()
    for name, ref in refs.items():
        key.update(name.encode())
        key.update(repr(ref).encode())
        key.update(load.module_source(ref[0], ref[1]))
    key.update(sources.record(model).digest.encode())  # the user modules the model imports, recursively
    origin = origin or f"{refs['rhs'][0]}"
    key.update(_switch_key(model).encode())
    key.update(repr((model.name, layout(model), len(model.states), getattr(model, "symplectic_order", 0),
                     tuple(getattr(m, "key", lambda: m)() for m in chosen),
                     tuple((c.name, c.needs) for c in closed), shared, method,
                     lane_rhs and (lane_kernels.lanes_for(len(model.states)), lane_kernels.QUEUE))).encode())
    key.update((lane_rhs or "").encode())  # the inlined helpers may live in other modules
    name = "mechsweep_gen_" + key.hexdigest()[:20]
    if not build or name in _KERNELS:
        return name, bool(lane_rhs)
    if lane_rhs:
        _KERNELS[name] = _Recorded(load_generated(name, lane_kernels.kernel_source(model, chosen, refs, origin, closed,
                                                                                   lane_rhs)).kernel, name)
    else:
        _KERNELS[name] = Threaded(load_generated(name, kernel_source(model, chosen, refs, origin, shared, closed,
                                                                       method, direct)).kernel)
    return name, bool(lane_rhs)


_POOL: list[ThreadPoolExecutor] = []
_POOL_LOCK = threading.Lock()


def _pool() -> ThreadPoolExecutor:
    with _POOL_LOCK:
        if not _POOL:
            import numba
            _POOL.append(ThreadPoolExecutor(max_workers=max(1, numba.config.NUMBA_NUM_THREADS - 1),
                                            thread_name_prefix="mechsweep-kernel"))
        return _POOL[0]


class Threaded:
    """The one-point kernel ``kernel(P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs)``
    on numba.get_num_threads() threads: the generated serial ``kernel(..., first, step)`` (nogil) once per
    thread, thread t computing the points t, t + T, ... (strided: cost varies along the grid), the calling
    thread one of them. Not a ``prange`` over blocks of points (``pjit``): numba's parallel compile of
    that loop (parfor passes, the gufunc and its two wrappers, each linking and optimising the whole
    call tree again) costs a fifth of the quickstart's compile CPU (`mechsweep bench startup --only
    compile`, docs/performance-startup.md). Each point is computed alone (its scratch reset), so the
    results are the same whatever the split. Anything else (``py_func``, ``stats``, numba's cache) is the serial kernel's."""

    def __init__(self, serial):
        self.serial = serial

    def __getattr__(self, name):
        return getattr(self.serial, name)

    def __call__(self, P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs):
        import numba

        args = (P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs)
        n = P.shape[0]
        threads = max(1, min(_jit.num_threads(), (n + BLOCK - 1) // BLOCK))
        if threads == 1:
            self.serial(*args, 0, 1)
            return
        futures = [_pool().submit(self.serial, *args, t, threads) for t in range(1, threads)]
        try:
            self.serial(*args, 0, threads)
        finally:  # never return (nor raise, e.g. KeyboardInterrupt) while a thread still writes the arrays
            interrupted = None
            while not all(f.done() for f in futures):
                try:
                    wait(futures)
                except BaseException as e:  # noqa: BLE001 - raised once every thread has finished
                    interrupted = e
            if interrupted is not None:
                raise interrupted
        for f in futures:
            f.result()


def load_generated(name: str, source: str):
    """Write a generated kernel module ``name`` into the cache folder (only when absent or
    different: its mtime keys numba's cache index) and import it, once per process: threads that
    ask for the same kernel at once (dask's threaded scheduler) wait for the first and share its
    module instead of racing on the file and importing it twice."""
    with _LOAD_LOCK:
        if name in _LOADED:
            return _LOADED[name]
        path = _folder() / f"{name}.py"
        if not path.exists() or path.read_text() != source:
            tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
            tmp.write_text(source)
            os.replace(tmp, path)
        spec = importlib.util.spec_from_file_location(name, path)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
        _LOADED[name] = mod
        return mod
