"""The only place where numba options are set.

Every kernel in mechsweep is serial code decorated with :func:`jit` or one of its variants below; the
chunk kernels run on Python threads (engine/point.py, ``Threaded``), which spares them numba's parallel
compile. :func:`pjit` (``parallel=True``) compiles a loop over ``prange`` for code outside the engine
(the tests' reference kernels).

Options and why:
- ``fastmath=False``: results must be bitwise reproducible and IEEE-correct
  (NaN checks are part of the status logic).
- ``nogil=True``: kernels may run in worker threads (e.g. a Dask worker).
- Hot-path helpers of the integrators (stage sums, error norm, right-hand sides) are compiled
  by :func:`jit_noalloc`, without numba's reference counting (``_nrt=False``): numba compiles
  every function separately and, across calls, increments and decrements the reference count
  of every array argument and view with atomic instructions, about 200 of them per DOP853 step
  (a measurable share of an autobalancer step: ``python benchmarks/autobalancer.py``). Such a function must
  not allocate arrays (numba refuses to compile it if it does).
- :func:`jit_inline` (``inline="always"`` at numba IR level, no reference counting) for small
  scalar helpers called in every right-hand side (sincos, the closed-form accelerations): LLVM
  inlines across separately compiled numba functions only below its size threshold, and every
  separately compiled function costs numba a compile of its own. numba analyses and types such a
  function again at every call site, so the integrators' small loops over a state (stage sums, error
  norm, interpolation, copies, the RMS norms of the first step; ode/dop853.py, ode/_common.py) are
  :func:`jit_llvm_inline` instead: typed once, inlined by LLVM (``alwaysinline``), bitwise the same
  and as fast. The integrator's large functions (the RK step, the adaptive step) stay separate
  functions: inlining them gains little speed for much more compile time.
- No cfunc wrapper (``no_cfunc_wrapper=True``): numba builds one for every function, for C callers
  and first-class function values; mechsweep's functions are called from Python and numba code only.
- :func:`jit_internal` for functions only numba code calls (the one-point kernel module's functions
  but the kernel, the integrators' internal steps): no CPython wrapper, and no machine code of their
  own (:class:`_LinkOnlyLibrary`): numba links a callee's LLVM module into its caller's, optimises the
  whole and makes machine code of it, so a callee's own optimised module and machine code were made
  for nothing, at every level of the call tree. They are optimised with the module of the top function
  (the binding's trampoline, :class:`_LinkingLibrary`) and are in its cached machine code; a call from
  Python goes to a twin compiled on first use.
- ``cache=True`` into a folder keyed by a hash of the package sources (:func:`package_hash`):
  numba's own cache only checks the file of the decorated function, so a kernel that calls an
  integrator from another module would keep stale machine code after that module changed. Keying
  the folder on all sources makes any edit start a fresh cache. The folder (:func:`cache_folder`) is
  ``$MECHSWEEP_CACHE_DIR/numba-<hash>`` when that variable is set, else
  ``$NUMBA_CACHE_DIR/mechsweep/numba-<hash>`` when numba's is, else
  ``~/.cache/mechsweep/numba-<hash>`` (``$XDG_CACHE_HOME`` for ``~/.cache``); ``MECHSWEEP_NO_CACHE=1``
  turns caching off. Each function gets its numba cache object (:class:`_LazyCache`) when it first
  compiles or loads: importing mechsweep reads no source file, computes no hash and creates no folder.
- Nothing is changed at import: what mechsweep's first compile or cache load needs is done then
  (:func:`_before_compile`), and what numba's threads need, right before they start
  (:func:`_before_threads`). The two such changes:
- OpenMP threads wait passively (``OMP_WAIT_POLICY=PASSIVE``, set by :func:`_passive_openmp` unless
  the environment chooses a policy): numba's ``omp`` threading layer (numba's choice where TBB is not installed)
  runs each ``prange`` on libgomp, whose idle threads otherwise spin for a while after every
  parallel region. A run launches its kernel once per chunk and between launches does its own work
  (the writer thread's journal and HDF5 writes, the Python around each chunk): the spinning worker
  took a core from it (docs/performance-duffing.md measures it). libgomp reads the variable once,
  when it is loaded, i.e. when numba starts its threads: the first ``numba.get_num_threads()`` or
  ``set_num_threads`` (a run asks the thread count before it compiles: mechsweep calls them through
  :func:`num_threads` and :func:`set_num_threads`) or the first parallel kernel. It is set then, only
  when libgomp is not loaded yet (later it would change nothing).
- numba's check for a BLAS is made without importing ``scipy.linalg`` (:func:`_defer_blas_check`, at
  mechsweep's first compile or cache load): numba imports ``scipy.linalg.cython_blas`` (with it all
  of ``scipy.linalg``, a large share of a warm ``mechsweep run``: ``python benchmarks/startup.py``) when its
  CPU target first loads ``numba.np.arraymath``, on the first compile or cache load of a process,
  only to learn whether scipy's BLAS exists (``arraymath._HAVE_BLAS``). The answer is read from
  scipy's installed files instead; ``scipy.linalg`` is imported when a kernel uses linear algebra
  (numba's own ``ensure_blas``, called when ``np.dot`` or ``np.linalg`` is typed: radau, Floquet), or
  by the compiled code itself when it first calls BLAS or LAPACK (numba finds the functions by
  importing scipy's modules then). A process whose first compile is not mechsweep's (the user's own
  numba code) makes numba's check as numba makes it.
- Closures made by a factory (a solver for one right-hand side) get a qualified name that
  says what they close over (:func:`_distinct_qualname`): numba's symbol names would otherwise
  coincide between cached kernels compiled by different processes, and one kernel would run
  another's closure (results would depend on what ran earlier in the process).
"""
from __future__ import annotations

import hashlib
import os
import threading
from pathlib import Path

import numba
from numba.core import caching as _caching
from numba.core.codegen import JITCodeLibrary
from numba.core.compiler import Compiler, DefaultPassBuilder
from numba.core.compiler_machinery import PassManager, register_pass
from numba.core.registry import CPUDispatcher
from numba.core.typed_passes import NativeLowering

__all__ = ["jit", "jit_noalloc", "jit_inline", "jit_into_caller", "jit_internal", "jit_internal_noalloc", "jit_llvm_inline", "pjit", "prange", "cache_folder", "num_threads", "set_num_threads"]

prange = numba.prange

_OPTIONS = dict(fastmath=False, nogil=True, error_model="numpy", no_cfunc_wrapper=True)

# Guards the once-per-process steps below: kernels may be built in several threads (a dask worker's).
_LOCK = threading.RLock()


def _passive_openmp(environ=os.environ) -> None:
    """Make OpenMP's idle threads sleep instead of spinning (see the module's docstring), unless
    ``environ`` already chooses a wait policy."""
    environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def _libgomp_loaded() -> bool:
    """Whether this process has loaded libgomp already (then it has read its wait policy); False where
    the process's mappings cannot be read (not Linux)."""
    try:
        with open("/proc/self/maps") as maps:
            return any("libgomp" in line for line in maps)
    except OSError:
        return False


_THREADS_READY: list[bool] = []


def _before_threads() -> None:
    """Once, before numba's threading layer starts: the passive wait policy, when libgomp is not
    loaded yet (by numba's threads started earlier, or by another library)."""
    if _THREADS_READY:
        return
    with _LOCK:
        if _THREADS_READY:
            return
        from numba.np.ufunc import parallel

        if not getattr(parallel, "_is_initialized", False) and not _libgomp_loaded():
            _passive_openmp()
        _THREADS_READY.append(True)


def num_threads() -> int:
    """``numba.get_num_threads()``: the first call starts numba's threads, so the wait policy is set
    before it (:func:`_before_threads`)."""
    _before_threads()
    return numba.get_num_threads()


def set_num_threads(n: int) -> None:
    """``numba.set_num_threads(n)``, with the wait policy set before numba's threads start."""
    _before_threads()
    numba.set_num_threads(n)


def _scipy_blas_installed() -> bool:
    """Whether ``scipy.linalg.cython_blas`` is installed, found without importing scipy (its
    package ``__init__`` is not run: ``find_spec`` of a top-level name only locates it)."""
    import importlib.machinery
    import importlib.util

    try:
        spec = importlib.util.find_spec("scipy")
    except (ImportError, ValueError):
        return False
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            if os.path.isfile(os.path.join(folder, "linalg", "cython_blas" + suffix)):
                return True
    return False


def _defer_blas_check() -> None:
    """Import ``numba.np.arraymath`` now, with numba's BLAS check answered by
    :func:`_scipy_blas_installed` instead of by importing ``scipy.linalg`` (see the module's
    docstring). ``arraymath`` calls ``numba.np.linalg.ensure_blas`` once, at its import, and keeps
    the answer (``_HAVE_BLAS``: which inner product ``np.correlate``/``np.convolve`` compile);
    ``ensure_blas`` is put back at once, so every later caller (the typing of ``np.dot`` and
    ``np.linalg``) gets numba's own, which imports scipy's BLAS and checks its integer width.
    Nothing is done when ``arraymath`` is imported already (the answer is numba's then) or numba
    has no such function (another numba version). Called with numba's compiler lock held (from
    :meth:`_LazyCache.load_overload`), where numba itself would import ``arraymath``."""
    import sys

    if "numba.np.arraymath" in sys.modules:
        return
    try:
        from numba.np import linalg as _linalg
    except ImportError:
        return
    own = getattr(_linalg, "ensure_blas", None)
    if own is None:
        return

    def ensure_blas():
        if not _scipy_blas_installed():
            raise ImportError("scipy 0.16+ is required for linear algebra")

    _linalg.ensure_blas = ensure_blas
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        _linalg.ensure_blas = own


_COMPILED: list[bool] = []


def _before_compile(parallel: bool) -> None:
    """What mechsweep's first compile or cache load in a process needs (see the module's docstring):
    numba's BLAS check without scipy.linalg; before a parallel kernel, the threads' wait policy."""
    if parallel:
        _before_threads()
    if not _COMPILED:
        with _LOCK:
            if not _COMPILED:
                _defer_blas_check()
                _COMPILED.append(True)


def _source_hash() -> str:
    root = Path(__file__).resolve().parent
    h = hashlib.sha256(numba.__version__.encode())
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


_PACKAGE_HASH: list[str] = []


def package_hash() -> str:
    """The hash of the package sources (and numba's version) that keys the cache folder, computed
    once per process, when first asked for (the first kernel build; model/sources.py records it with
    every run)."""
    if not _PACKAGE_HASH:
        with _LOCK:
            if not _PACKAGE_HASH:
                _PACKAGE_HASH.append(_source_hash())
    return _PACKAGE_HASH[0]


def cache_base() -> str:
    """The folder that holds mechsweep's cache folders (one ``numba-<hash>`` per version of the
    sources): ``$MECHSWEEP_CACHE_DIR``, else ``$NUMBA_CACHE_DIR/mechsweep`` (numba's setting, as numba
    read it: ``numba.config.CACHE_DIR``), else ``$XDG_CACHE_HOME/mechsweep`` or ``~/.cache/mechsweep``.
    A subfolder of numba's: mechsweep removes its stale folders (:func:`prune_stale`) and must not
    take the user's for its own."""
    own = os.environ.get("MECHSWEEP_CACHE_DIR")
    if own:
        return own
    numba_dir = numba.config.CACHE_DIR
    if numba_dir:
        return os.path.join(numba_dir, "mechsweep")
    return os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache"), "mechsweep")


def _make_cache_dir() -> str | None:
    if os.environ.get("MECHSWEEP_NO_CACHE", "") not in ("", "0"):
        return None
    base = cache_base()
    path = os.path.join(base, "numba-" + package_hash())
    try:
        os.makedirs(path, exist_ok=True)
        probe = os.path.join(path, ".write-test")
        with open(probe, "w"):
            pass
        os.remove(probe)
    except OSError:
        return None  # read-only home: compile every time rather than fail
    prune_stale(base, path)
    return path


STALE_DAYS = 30  # a cache folder of other sources not used for this long is removed


def prune_stale(base: str, current: str, days: float = STALE_DAYS) -> list[str]:
    """Mark ``current`` (this version's cache folder) used now, and remove the folders of other source
    versions (``numba-<hash>`` under ``base``) not used for ``days`` days: every edit or upgrade of the
    package makes a new folder, and nothing else ever removed the old ones. A folder's mtime is its last use (set here by
    each process of that version). Returns the folders removed; errors are ignored (another process
    may remove the same folder)."""
    import shutil
    import time

    try:
        os.utime(current)
        entries = list(os.scandir(base))
    except OSError:
        return []
    cutoff = time.time() - days * 86400.0
    removed = []
    for entry in entries:
        try:
            stale = (entry.name.startswith("numba-") and entry.path != current and entry.is_dir(follow_symlinks=False)
                     and entry.stat(follow_symlinks=False).st_mtime < cutoff)
        except OSError:
            continue
        if stale:
            shutil.rmtree(entry.path, ignore_errors=True)
            removed.append(entry.path)
    return removed


_CACHE_DIR: list[str | None] = []


def cache_folder() -> str | None:
    """This process's cache folder (see the module's docstring), made (and stale ones removed) on the
    first call; None when caching is off or the folder cannot be written."""
    if not _CACHE_DIR:
        with _LOCK:
            if not _CACHE_DIR:
                _CACHE_DIR.append(_make_cache_dir())
    return _CACHE_DIR[0]


def __getattr__(name: str):
    if name == "cache_dir":  # the folder as a module attribute (engine/binding.py), found when first read
        return cache_folder()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


_Locator = getattr(_caching, "UserProvidedCacheLocator", None) or getattr(_caching, "_UserProvidedCacheLocator")


class _FolderLocator(_Locator):
    """numba's locator for a user-provided cache folder (``numba.config.CACHE_DIR``), pointed at
    mechsweep's folder instead: the same layout inside, without setting numba's global option."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = os.path.join(cache_folder(), self.get_suitable_cache_subpath(py_file))

    @classmethod
    def from_function(cls, py_func, py_file):
        # numba's own check of its source file and folder (_SourceFileBackedLocatorMixin), not the
        # parent's test of numba.config.CACHE_DIR
        return super(_Locator, cls).from_function(py_func, py_file)


class _FolderCacheImpl(_caching.CompileResultCacheImpl):
    _locator_classes = [_FolderLocator]


class _FolderCache(_caching.FunctionCache):
    _impl_class = _FolderCacheImpl


class _LazyCache:
    """A mechsweep function's numba cache, made at its first compile or cache load (numba asks
    ``load_overload`` first): until then no folder, hash or source file is touched. It also runs
    :func:`_before_compile` there. Without a cache folder it is numba's NullCache."""

    def __init__(self, py_func, parallel: bool):
        self._py_func = py_func
        self._parallel = parallel
        self._made = None

    def _cache(self):
        if self._made is None:
            with _LOCK:
                if self._made is None:
                    made = None
                    if cache_folder() is not None:
                        try:
                            made = _FolderCache(self._py_func)
                        except RuntimeError:  # no locator: a function without a source file
                            made = None
                    self._made = made if made is not None else _caching.NullCache()
        return self._made

    def load_overload(self, sig, target_context):
        _before_compile(self._parallel)
        return self._cache().load_overload(sig, target_context)

    def save_overload(self, sig, data):
        return self._cache().save_overload(sig, data)

    def enable(self):
        self._cache().enable()

    def disable(self):
        self._cache().disable()

    def flush(self):
        self._cache().flush()

    @property
    def cache_path(self):
        return self._cache().cache_path

    def __getattr__(self, name):  # numba's private parts (_cache_file, _cache_path)
        if name.startswith("__") or name in ("_py_func", "_parallel", "_made"):
            raise AttributeError(name)
        return getattr(self._cache(), name)


def _describe(value) -> str:
    """A description of a closure variable that is the same in every process: what the
    function's machine code depends on (jitted functions by module and qualified name, which
    _distinct_qualname has already made distinct; plain values by repr; arrays by content)."""
    py_func = getattr(value, "py_func", None)
    if py_func is not None or callable(value) and hasattr(value, "__qualname__"):
        f = py_func if py_func is not None else value
        return f"{getattr(f, '__module__', '')}.{f.__qualname__}"
    if isinstance(value, (bool, int, float, complex, str, bytes, type(None))):
        return repr(value)
    if isinstance(value, (tuple, list)):
        return "(" + ",".join(_describe(v) for v in value) + ")"
    if hasattr(value, "tobytes") and hasattr(value, "dtype"):
        return f"array:{value.dtype}:{getattr(value, 'shape', '')}:{hashlib.sha256(value.tobytes()).hexdigest()}"
    return type(value).__qualname__


def _distinct_qualname(func) -> None:
    """Give a closure made by a factory (e.g. a solver made for one right-hand side) a qualified
    name that says what it closes over.

    numba names a compiled function by module, qualified name, argument types and a counter of
    the compiling process. Two closures from the same factory share the qualified name; when
    each was compiled into a cached kernel by a different process, the counters can coincide,
    and the two kernels then define the same symbol with different machine code. Loaded into one
    process, every reference binds to whichever kernel was loaded first: e.g. the simulation
    lanes would start their trajectories with the first-step selection of the Floquet variational
    system after a Floquet run, and results would depend on which outputs a scene asked for and on
    what ran earlier in the process (tests/models/test_autobalancer_reproducible.py checks they do not).
    A suffix from the closure's variables, identical in every process, keeps the symbols apart.
    """
    cells = func.__closure__
    if not cells or "__c" in func.__qualname__.rsplit(".", 1)[-1]:
        return
    parts = []
    for name, cell in zip(func.__code__.co_freevars, cells):
        try:
            parts.append(f"{name}={_describe(cell.cell_contents)}")
        except ValueError:  # an empty cell (a variable assigned later)
            parts.append(f"{name}=?")
    tag = hashlib.sha256("|".join(parts).encode()).hexdigest()[:12]
    func.__qualname__ = f"{func.__qualname__}__c{tag}"


def _decorate(func, **extra):
    _distinct_qualname(func)
    if not extra.get("parallel") and LINK_ONLY:
        extra.setdefault("pipeline_class", _LINKING)
    dispatcher = numba.njit(**_OPTIONS, **extra)(func)
    # numba's cache=True would make the cache object now (its folder, a hash of the source file) and
    # in numba.config.CACHE_DIR; this one is made at the first compile, in mechsweep's folder
    dispatcher._cache = _LazyCache(func, bool(extra.get("parallel")))
    return dispatcher


def jit(func):
    """Compile a serial kernel (no parallel loops)."""
    return _decorate(func)


def jit_noalloc(func):
    """Compile a serial hot-path function that allocates no arrays, without reference counting."""
    return _decorate(func, _nrt=False)


def jit_inline(func):
    """Compile a small scalar helper that numba inlines into every numba caller (still
    callable from Python); no reference counting, so it must not allocate."""
    return _decorate(func, _nrt=False, inline="always")


def jit_into_caller(func):
    """Compile a function that numba inlines into every numba caller (``inline="always"`` at numba IR
    level), with reference counting (it may allocate): the one-point kernel's guards take the model's
    functions so (model/load.py: inlined), each typed and lowered inside its guard instead of compiled
    as a function of its own that the guard links. Python callers get it compiled on its own."""
    return _decorate(func, inline="always")


# The wrapper numba builds for every compiled function to call it from Python (see jit_internal).
_NO_WRAPPERS = dict(no_cpython_wrapper=True)


class _NumbaOnly(CPUDispatcher):
    """A dispatcher compiled without the CPython wrapper and machine code of its own
    (:func:`jit_internal`): numba callers call it as any other. A call from Python goes to a twin
    compiled with the wrapper, on first use and without the disk cache (numba keys a cache entry by the
    function's file, name, types and code, not by these options)."""

    def __call__(self, *args, **kwargs):
        twin = self.__dict__.get("_python_twin")
        if twin is None:
            options = {k: v for k, v in self.targetoptions.items() if k not in _NO_WRAPPERS and k != "nopython"}
            twin = self.__dict__["_python_twin"] = numba.njit(**options)(self.py_func)
        return twin(*args, **kwargs)


class _LinkOnlyLibrary(JITCodeLibrary):
    """The code library of a :func:`jit_internal` function: its LLVM module is only linked into its
    callers' (numba links every callee's module into its caller's, optimises the whole and makes
    machine code of it), so it is neither optimised as a module nor turned into machine code of its
    own, which numba otherwise does for every function and again for every caller above it. Its
    functions have no address (nothing calls them but the callers that link them)."""

    def _optimize_final_module(self):
        pass  # optimised in the module of the caller that is turned into machine code (_LinkingLibrary)

    def _finalize_final_module(self):
        self._finalize_dynamic_globals()
        self._verify_declare_only_symbols()
        self._finalized = True

    def get_pointer_to_function(self, name):
        self._ensure_finalized()
        return 0

    @property
    def codegen(self):
        return _NoEnvironment(self._codegen)


class _LinkingLibrary(JITCodeLibrary):
    """The code library of mechsweep's other functions: a module that links :class:`_LinkOnlyLibrary`
    modules is optimised twice. numba optimised every callee's module before linking it, and LLVM's
    inliner decides on the optimised callees: optimised once, unoptimised callees and all, the lane
    kernel ran measurably slower; the second pass costs far less than the callees' own passes did."""

    def _optimize_final_module(self):
        super()._optimize_final_module()
        if any(isinstance(lib, _LinkOnlyLibrary) for lib in self._linking_libraries):
            super()._optimize_final_module()


class _NoEnvironment:
    """A codegen that does not set a function's environment pointer: numba sets it in the machine code
    of the function's own library, which a :class:`_LinkOnlyLibrary` has none of (the copies linked
    into callers never read it: a nopython function's environment is its CPython wrapper's)."""

    def __init__(self, codegen):
        self._codegen = codegen

    def set_env(self, env_name, env):
        pass

    def __getattr__(self, name):
        return getattr(self._codegen, name)


def _lowering(library_class):
    """numba's lowering pass, into a code library of ``library_class``."""

    class Lowering(NativeLowering):
        _name = f"mechsweep_lowering_{library_class.__name__.strip('_').lower()}"

        def run_pass(self, state):
            if state.library is None:
                state.library = library_class(state.targetctx.codegen(), state.func_id.func_qualname)
                state.library.enable_object_caching()
            return super().run_pass(state)

    Lowering.__qualname__ = Lowering.__name__ = f"Lowering_{library_class.__name__}"
    return Lowering


_LOWERINGS = {lib: _lowering(lib) for lib in (_LinkOnlyLibrary, _LinkingLibrary)}
_REGISTERED: list[bool] = []


def _compiler(library_class):
    """numba's nopython pipeline (its compiler class) with the lowering into ``library_class``."""
    lowering = _LOWERINGS[library_class]

    class Compiler_(Compiler):
        def define_pipelines(self):
            if not _REGISTERED:  # numba's registry of passes, at the first compile rather than at import
                with _LOCK:
                    if not _REGISTERED:
                        for cls in _LOWERINGS.values():
                            register_pass(mutates_CFG=True, analysis_only=False)(cls)
                        _REGISTERED.append(True)
            pm = PassManager(lowering._name)
            for passes in (DefaultPassBuilder.define_untyped_pipeline(self.state),
                           DefaultPassBuilder.define_typed_pipeline(self.state),
                           DefaultPassBuilder.define_nopython_lowering_pipeline(self.state)):
                pm.passes.extend((lowering if p is NativeLowering else p, d) for p, d in passes.passes)
            pm.finalize()
            return [pm]

    Compiler_.__qualname__ = Compiler_.__name__ = f"Compiler_{library_class.__name__}"
    return Compiler_


_LINK_ONLY, _LINKING = _compiler(_LinkOnlyLibrary), _compiler(_LinkingLibrary)
# The parts of numba's code library that the two classes above override or call (numba 0.59 to 0.68
# have them all): with a numba that lacks one, every function is compiled as numba compiles it.
LINK_ONLY = all(hasattr(JITCodeLibrary, name) for name in (
    "_optimize_final_module", "_finalize_final_module", "_finalize_dynamic_globals", "_verify_declare_only_symbols",
    "_ensure_finalized", "enable_object_caching"))


class _NoDiskCache(_caching.NullCache):
    """No disk cache (a :class:`_LinkOnlyLibrary` has no machine code to save; its callers' cached
    machine code holds it), with :func:`_before_compile` at the first compile, as :class:`_LazyCache`."""

    def load_overload(self, sig, target_context):
        _before_compile(False)
        return None


def _numba_only(func, **extra):
    dispatcher = _decorate(func, **_NO_WRAPPERS, **extra, pipeline_class=_LINK_ONLY if LINK_ONLY else Compiler)
    dispatcher._cache = _NoDiskCache()
    dispatcher.__class__ = _NumbaOnly
    return dispatcher


def jit_internal(func):
    """Compile a function that only numba code calls (the one-point kernel's parts, the integrators'
    steps): without the CPython wrapper numba otherwise builds, lowers and turns into machine code for
    every function it compiles (most of a trivial function's compile CPU, the largest part of one with a
    tuple argument: brent), and without machine code of its own (:class:`_LinkOnlyLibrary`: its callers'
    holds it). Called from Python it still works (see _NumbaOnly), through a twin compiled on first use."""
    return _numba_only(func)


def jit_internal_noalloc(func):
    """:func:`jit_internal` without reference counting (as :func:`jit_noalloc`)."""
    return _numba_only(func, _nrt=False)


def jit_llvm_inline(func):
    """Compile a small helper of the integrators (stage sums, error norm, interpolation, copies, the
    first step's norms) once per signature, for numba callers only (:func:`jit_internal`, no reference
    counting), with LLVM's ``alwaysinline`` (numba's ``forceinline``): LLVM inlines it into every caller
    when it links the caller's module, as the IR-level inlining of :func:`jit_inline` does, but numba
    analyses and types its body once instead of again at every call site: less compile CPU for the
    same machine code (bitwise the same results, the warm one-point kernel as fast; the cold compile:
    ``python benchmarks/startup.py``). ``alwaysinline`` is needed: as plain separate functions they are
    above LLVM's size threshold, stay out of line and slow the kernel down."""
    return _numba_only(func, _nrt=False, forceinline=True)


def pjit(func):
    """Compile a function whose outer loop is a ``prange`` (not the engine's chunk kernels: see the
    module's docstring)."""
    return _decorate(func, parallel=True)
