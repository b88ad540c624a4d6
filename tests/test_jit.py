"""The numba option layer: what the decorators promise."""
import os

import numba
import numpy as np
import pytest

from mechsweep._jit import jit, jit_inline, jit_internal, jit_noalloc


def test_noalloc_refuses_a_function_that_allocates():
    """jit_noalloc compiles without reference counting; an allocation must fail to compile
    rather than leak or crash at run time."""
    def allocating(n):
        return np.zeros(n).sum()

    with pytest.raises(numba.core.errors.TypingError):
        jit_noalloc(allocating)(3)


def test_internal_function_has_no_python_entry_yet_python_can_call_it():
    """jit_internal compiles without numba's CPython wrapper (its machine code has no Python entry: a
    call through it would crash); numba callers use it as any function, and a call from Python goes to
    a twin compiled with the wrapper."""
    def twice(v):
        return 2.0 * v[0]

    f = jit_internal(twice)

    @jit
    def caller(v):
        return f(v) + 1.0

    v = np.array([3.0])
    assert caller(v) == 7.0
    (compiled,) = f.overloads.values()
    assert compiled.library.get_pointer_to_function(compiled.fndesc.llvm_cpython_wrapper_name) == 0
    assert f(v) == 6.0


def test_noalloc_and_inline_functions_work_on_caller_arrays():
    def scaled_sum(v, a):
        acc = 0.0
        for i in range(v.size):
            acc += a * v[i]
        return acc

    f = jit_noalloc(scaled_sum)
    g = jit_inline(scaled_sum)
    v = np.arange(5.0)
    assert f(v, 2.0) == g(v, 2.0) == 20.0
    assert f(v[::2], 1.0) == 6.0  # views of caller arrays are fine


NAMES_CODE = """
from mechsweep.models import _autobalancer_kernels as ab  # the hand-written kernels (reference implementation)
from mechsweep.ode import dop853, radau
print(dop853._make_start(ab.rhs).py_func.__qualname__)
print(dop853._make_start(ab.variational_rhs).py_func.__qualname__)
print(dop853.make_solver(ab.variational_rhs).py_func.__qualname__)
print(dop853.make_solver(ab.variational_rhs, stiffness_test=True).py_func.__qualname__)
print(radau.make_trajectory_solver(ab.rhs, ab.jacobian).py_func.__qualname__)
"""


def test_closures_of_one_factory_get_distinct_names_the_same_in_every_process():
    """numba names compiled code by qualified name, argument types and a per-process counter: two
    closures of one factory (the solver of one right-hand side and of another) compiled into
    cached kernels by different processes could get the same symbol, and a process loading both
    kernels then ran one closure's code in the other kernel (the simulation lanes started with
    the Floquet system's first step after a Floquet run). Their names must differ, and be the
    same in every process (cached kernels are found by them)."""
    import subprocess
    import sys
    from pathlib import Path

    import mechsweep

    env = {**__import__("os").environ, "PYTHONPATH": str(Path(mechsweep.__file__).resolve().parents[1])}
    runs = [subprocess.run([sys.executable, "-c", NAMES_CODE], capture_output=True, text=True, env=env, check=True)
            .stdout.split() for _ in range(2)]
    assert runs[0] == runs[1]
    assert len(set(runs[0])) == len(runs[0]), runs[0]


def test_openmp_threads_wait_passively_unless_the_environment_chooses():
    """Idle OpenMP threads (numba's omp layer) sleep between a run's kernel launches instead of
    spinning on a core the run's writer thread needs (_jit._passive_openmp, set at import); a
    wait policy the user set is kept."""
    import os

    from mechsweep import _jit

    env = {}
    _jit._passive_openmp(env)
    assert env == {"OMP_WAIT_POLICY": "PASSIVE"}
    env = {"OMP_WAIT_POLICY": "active"}
    _jit._passive_openmp(env)
    assert env == {"OMP_WAIT_POLICY": "active"}
    assert os.environ.get("OMP_WAIT_POLICY")  # importing mechsweep set it (or the environment did)


def test_first_compile_of_a_process_does_not_import_scipy_linalg_and_linalg_still_works():
    """numba's CPU target imports numba.np.arraymath on a process's first compile or cache load, and
    arraymath asked for scipy's BLAS by importing scipy.linalg (0.2-0.4 s of every warm `mechsweep run`).
    _jit answers that from scipy's installed files: a function without linear algebra imports no
    scipy.linalg, the answer is numba's (BLAS found), numba's own ensure_blas is in place for later
    callers, and np.dot (typing imports scipy's BLAS then) still compiles and runs."""
    import subprocess
    import sys

    code = ("import sys, numpy as np, numba, mechsweep._jit as j\n"
            "@numba.njit\n"
            "def plus(x): return x + 1.0\n"
            "assert plus(1.0) == 2.0\n"
            "from numba.np import arraymath, linalg\n"
            "print('scipy.linalg' in sys.modules, arraymath._HAVE_BLAS, linalg.ensure_blas.__qualname__)\n"
            "@numba.njit\n"
            "def dot(a, b): return np.dot(a, b)\n"
            "print(dot(np.arange(3.0), np.arange(3.0)), 'scipy.linalg.cython_blas' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**__import__("os").environ, "PYTHONPATH": __import__("os").pathsep.join(sys.path)})
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "True", "ensure_blas", "5.0", "True"]


def test_cache_folders_of_other_versions_unused_for_30_days_are_removed(tmp_path):
    """Each version of the sources compiles into a folder of its own; a folder of another version not
    used for STALE_DAYS goes, a recently used one, this version's and anything not ours stay."""
    import time

    from mechsweep import _jit

    day = 86400.0
    now = time.time()
    folders = {name: tmp_path / name for name in ("numba-current", "numba-old", "numba-recent", "other-old")}
    for path in folders.values():
        (path / "sub").mkdir(parents=True)
        (path / "sub" / "x.nbi").write_bytes(b"index")
    for name, age in (("numba-current", 90), ("numba-old", 31), ("numba-recent", 29), ("other-old", 90)):
        os.utime(folders[name], (now - age * day, now - age * day))
    removed = _jit.prune_stale(str(tmp_path), str(folders["numba-current"]))
    assert removed == [str(folders["numba-old"])]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["numba-current", "numba-recent", "other-old"]
    assert folders["numba-current"].stat().st_mtime > now - 60  # marked used: kept by the next version's run
