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


def _internal_and_caller(func):
    """``func`` compiled by jit_internal, and a jit function that calls it: ``f(v) + 1``."""
    f = jit_internal(func)

    @jit
    def caller(v):
        return f(v) + 1.0

    return f, caller


def test_internal_function_has_no_python_entry_yet_python_can_call_it():
    """jit_internal compiles without numba's CPython wrapper (its machine code has no Python entry: a
    call through it would crash); numba callers use it as any function, and a call from Python goes to
    a twin compiled with the wrapper."""
    def twice(v):
        return 2.0 * v[0]

    f, caller = _internal_and_caller(twice)
    v = np.array([3.0])
    assert caller(v) == 7.0
    (compiled,) = f.overloads.values()
    assert compiled.library.get_pointer_to_function(compiled.fndesc.llvm_cpython_wrapper_name) == 0
    assert f(v) == 6.0


def test_internal_function_is_machine_code_only_inside_its_callers():
    """jit_internal's own LLVM module is neither optimised nor turned into machine code: its symbol is
    not in numba's execution engine after it compiled, yet a caller that links it runs it (the copy in
    the caller's machine code), and the Python twin gives the same value."""
    def cubed(v):
        return v[0] * v[0] * v[0]

    f = jit_internal(cubed)
    v = np.array([1.5])
    f.compile((numba.typeof(v),))
    (compiled,) = f.overloads.values()
    engine = compiled.library._codegen._engine
    assert not engine.is_symbol_defined(compiled.fndesc.llvm_func_name)

    @jit
    def caller(v):
        return f(v) - 1.0

    assert caller(v) == 1.5 ** 3 - 1.0
    assert f(v) == 1.5 ** 3
    assert not any(c.library._codegen._engine.is_symbol_defined(c.fndesc.llvm_cpython_wrapper_name)
                   for c in f.overloads.values())


def test_without_link_only_libraries_internal_functions_compile_as_numba_compiles_them(monkeypatch):
    """With a numba whose code library lacks what the link-only libraries need (_jit.LINK_ONLY False),
    an internal function is compiled by numba's own pipeline, with machine code of its own, and its
    callers work the same."""
    from mechsweep import _jit

    monkeypatch.setattr(_jit, "LINK_ONLY", False)

    def halved(v):
        return 0.5 * v[0]

    f, caller = _internal_and_caller(halved)
    v = np.array([3.0])
    assert caller(v) == 2.5
    (compiled,) = f.overloads.values()
    assert not isinstance(compiled.library, _jit._LinkOnlyLibrary)
    assert compiled.library._codegen._engine.is_symbol_defined(compiled.fndesc.llvm_func_name)


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
from tests.reference import autobalancer_kernels as ab  # the hand-written kernels (reference implementation)
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

    import os

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(mechsweep.__file__).resolve().parents[1]),
                                                        str(Path(__file__).resolve().parents[2])])}
    runs = [subprocess.run([sys.executable, "-c", NAMES_CODE], capture_output=True, text=True, env=env, check=True)
            .stdout.split() for _ in range(2)]
    assert runs[0] == runs[1]
    assert len(set(runs[0])) == len(runs[0]), runs[0]


def test_openmp_threads_wait_passively_unless_the_environment_chooses():
    """Idle OpenMP threads (numba's omp layer) sleep between a run's kernel launches instead of
    spinning on a core the run's writer thread needs (_jit._passive_openmp); a wait policy the user
    set is kept."""
    from mechsweep import _jit

    env = {}
    _jit._passive_openmp(env)
    assert env == {"OMP_WAIT_POLICY": "PASSIVE"}
    env = {"OMP_WAIT_POLICY": "active"}
    _jit._passive_openmp(env)
    assert env == {"OMP_WAIT_POLICY": "active"}


THREADS_CODE = """
import ctypes, os, sys
import mechsweep, mechsweep.model
print(os.environ.get("OMP_WAIT_POLICY"))
from mechsweep import _jit
_jit.num_threads()  # numba starts its threads (and loads libgomp) here
import numba
print(os.environ.get("OMP_WAIT_POLICY"), numba.threading_layer())
gomp = next((line.split()[-1] for line in open("/proc/self/maps") if "libgomp" in line), None)
display = getattr(ctypes.CDLL(gomp), "omp_display_env", None) if gomp else None
sys.stderr.flush()
if display is not None:
    display(1)  # libgomp's settings on stderr, as it read them when it was loaded
"""


@pytest.mark.parametrize("policy", [None, "active"])
def test_the_wait_policy_is_set_when_numba_starts_its_threads_and_libgomp_reads_it(policy):
    """Importing mechsweep sets nothing; the passive policy is set right before numba starts its
    threads (_jit.num_threads: a run asks for the thread count before it compiles), early enough for
    libgomp to read it (its spin count is 0 then); a policy of the environment is kept."""
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    env["PYTHONPATH"] = os.pathsep.join(sys.path)
    if policy:
        env["OMP_WAIT_POLICY"] = policy
    out = subprocess.run([sys.executable, "-c", THREADS_CODE], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.split("\n")
    assert lines[0] == str(policy)  # importing mechsweep (and its model layer) set nothing
    after, layer = lines[1].split()
    assert after == (policy or "PASSIVE")
    spin = [line.split("=")[1].strip(" '") for line in out.stderr.splitlines() if "GOMP_SPINCOUNT" in line]
    if layer != "omp" or not spin:
        pytest.skip(f"numba's threading layer is {layer} or libgomp cannot display its settings")
    assert spin == (["30000000000"] if policy == "active" else ["0"])


def test_first_compile_of_a_process_does_not_import_scipy_linalg_and_linalg_still_works():
    """numba's CPU target imports numba.np.arraymath on a process's first compile or cache load, and
    arraymath asked for scipy's BLAS by importing scipy.linalg (a large share of every warm
    `mechsweep run`: `python benchmarks/startup.py`). At mechsweep's first compile _jit answers that from
    scipy's installed files: a mechsweep function without linear algebra imports no scipy.linalg, the
    answer is numba's (BLAS found), numba's own ensure_blas is in place for later callers, and np.dot
    (typing imports scipy's BLAS then) still compiles and runs."""
    import subprocess
    import sys

    code = ("import sys, numpy as np, numba, mechsweep._jit as j\n"
            "def plus(x): return x + 1.0\n"
            "plus = j.jit(plus)\n"
            "assert plus(1.0) == 2.0\n"
            "from numba.np import arraymath, linalg\n"
            "print('scipy.linalg' in sys.modules, arraymath._HAVE_BLAS, linalg.ensure_blas.__qualname__)\n"
            "@numba.njit\n"
            "def dot(a, b): return np.dot(a, b)\n"
            "print(dot(np.arange(3.0), np.arange(3.0)), 'scipy.linalg.cython_blas' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "True", "ensure_blas", "5.0", "True"]


def test_a_users_numba_code_compiled_first_gets_numbas_own_blas_check():
    """Importing mechsweep leaves numba as it is: a process whose first compile is the user's own numba
    function makes numba's BLAS check as numba makes it (it imports scipy.linalg)."""
    import subprocess
    import sys

    code = ("import sys, numba, mechsweep, mechsweep.model\n"
            "@numba.njit\n"
            "def plus(x): return x + 1.0\n"
            "assert plus(1.0) == 2.0\n"
            "print('scipy.linalg' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True"]


TINY = """
import numba
from mechsweep._jit import jit


def plus_one(x):
    return x + 1.0


plus_one = jit(plus_one)


@numba.njit(cache=True)
def users_own(x):  # the user's numba code: numba's cache, where numba puts it
    return x + 2.0
"""

CACHE_CODE = """
import sys
sys.path.insert(0, sys.argv[1])
import tiny
from mechsweep import _jit
assert tiny.plus_one(1.0) == 2.0 and tiny.users_own(1.0) == 3.0
stats = tiny.plus_one.stats
print(_jit.cache_folder(), _jit.package_hash(), sum(stats.cache_hits.values()), sum(stats.cache_misses.values()))
"""


def _cache_run(tmp_path, **variables):
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "MECHSWEEP_CACHE_DIR", "MECHSWEEP_NO_CACHE", "XDG_CACHE_HOME")}
    env.update(variables, PYTHONPATH=os.pathsep.join(sys.path), HOME=str(tmp_path / "home"))
    out = subprocess.run([sys.executable, "-c", CACHE_CODE, str(tmp_path / "code")], capture_output=True,
                         text=True, env=env)
    assert out.returncode == 0, out.stderr
    folder, digest, hits, misses = out.stdout.split()
    return folder, digest, int(hits), int(misses)


def _indexes(folder):
    return sorted(p.name.split("-")[0] for p in folder.rglob("*.nbi"))


def test_the_cache_goes_where_numba_cache_dir_and_mechsweep_cache_dir_say(tmp_path):
    """mechsweep's kernels go to $MECHSWEEP_CACHE_DIR/numba-<hash>, else $NUMBA_CACHE_DIR/mechsweep/
    numba-<hash>, else $XDG_CACHE_HOME/mechsweep/numba-<hash>; a second process loads them from there
    (a cache hit, nothing compiled). The user's own numba code keeps numba's cache folder.
    MECHSWEEP_NO_CACHE=1 writes nothing."""
    (tmp_path / "code").mkdir()
    (tmp_path / "code" / "tiny.py").write_text(TINY)
    numba_dir, own_dir, xdg = tmp_path / "numba-cache", tmp_path / "own-cache", tmp_path / "xdg"

    folder, digest, hits, misses = _cache_run(tmp_path, NUMBA_CACHE_DIR=str(numba_dir))
    assert folder == str(numba_dir / "mechsweep" / f"numba-{digest}") and (hits, misses) == (0, 1)
    assert _indexes(numba_dir / "mechsweep") == ["tiny.plus_one"]
    assert _indexes(numba_dir) == ["tiny.plus_one", "tiny.users_own"]  # the user's: numba's own place
    assert _cache_run(tmp_path, NUMBA_CACHE_DIR=str(numba_dir))[2:] == (1, 0)  # loaded, not compiled

    folder, digest, hits, misses = _cache_run(tmp_path, NUMBA_CACHE_DIR=str(numba_dir), MECHSWEEP_CACHE_DIR=str(own_dir))
    assert folder == str(own_dir / f"numba-{digest}") and (hits, misses) == (0, 1)
    assert _indexes(own_dir) == ["tiny.plus_one"]
    assert _cache_run(tmp_path, MECHSWEEP_CACHE_DIR=str(own_dir))[2:] == (1, 0)

    folder, digest, hits, misses = _cache_run(tmp_path, XDG_CACHE_HOME=str(xdg))
    assert folder == str(xdg / "mechsweep" / f"numba-{digest}") and (hits, misses) == (0, 1)
    assert _indexes(xdg) == ["tiny.plus_one"]  # (the user's numba code: beside its file, numba's default)

    folder, digest, hits, misses = _cache_run(tmp_path, MECHSWEEP_NO_CACHE="1", NUMBA_CACHE_DIR=str(tmp_path / "n2"))
    assert folder == "None" and (hits, misses) == (0, 1)
    assert not (tmp_path / "n2" / "mechsweep").exists()


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
