"""mechsweep's modules import one another in one direction: no import circles.

The graph is read from the source (ast), not from a running process: every ``import`` and
``from ... import`` statement of every module counts, at module level, inside a function (an
import moved into a function to get past a circle is still the circle) or under
``if TYPE_CHECKING:`` (it never runs, but a module whose signatures name another's class depends on
it: a reader, a type checker and a tool drawing the imports all follow it). An edge that closes a
circle is allowed only in ``ALLOWED``, with the reason it is there; an entry whose import is gone
must be dropped.
"""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

import mechsweep

PACKAGE = Path(mechsweep.__file__).resolve().parent

# (importer, imported): why this import may close a circle. The engine reads the model layer's
# declarations (engine -> model); these are the calls back from a declaration into the engine that
# composes its kernels, each inside a function that runs only when a kernel is wanted.
ALLOWED = {
    ("mechsweep.model.ode", "mechsweep.engine.kernels"):
        "OdeModel.spec()'s evaluate runs the model's composed kernels (and its plan reads their lane record)",
    ("mechsweep.model.ode", "mechsweep.engine.point"):
        "OdeModel.methods_for and evaluate read which measurements integrate on their own and their columns",
    ("mechsweep.model.measure", "mechsweep.engine.floquet"):
        "Floquet's measurement builds its variational integration from the engine's factory",
}


def modules() -> dict[str, tuple[Path, bool]]:
    """Every module of the package: dotted name -> (file, is a package's __init__)."""
    found = {}
    for f in sorted(PACKAGE.rglob("*.py")):
        parts = list(f.relative_to(PACKAGE.parent).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        found[".".join(parts[:-1] if is_package else parts)] = (f, is_package)
    return found


def _absolute(module: str, is_package: bool, level: int, name: str | None) -> str:
    if level == 0:
        return name or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def lazy_exports(mods) -> dict[str, dict[str, str]]:
    """package -> {name: module} of the names a package's ``__init__`` imports when first used
    (PEP 562: its ``_EXPORTS`` table of name -> submodule): ``from package import name`` runs that
    module, as a plain import of it would."""
    out = {}
    for module, (path, is_package) in mods.items():
        if not is_package:
            continue
        for node in ast.parse(path.read_text(), str(path)).body:
            if (isinstance(node, ast.Assign) and [ast.unparse(t) for t in node.targets] == ["_EXPORTS"]
                    and isinstance(node.value, ast.Dict)):
                table = ast.literal_eval(node.value)
                out[module] = {name: f"{module}.{sub.lstrip('.')}" for name, sub in table.items()}
    return out


def import_edges() -> dict[tuple[str, str], list[str]]:
    """(importer, imported module) -> where ("file:line") for every import between the package's
    modules. Importing a.b.c runs a, a.b and a.b.c: an edge to each (but not to the importer's own
    parent packages, which are running already); ``from a import b`` also reaches module a.b, or
    the module a's ``_EXPORTS`` names for b (``lazy_exports``)."""
    mods = modules()
    lazy = lazy_exports(mods)
    edges: dict[tuple[str, str], list[str]] = {}
    for module, (path, is_package) in mods.items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _absolute(module, is_package, node.level, node.module)
                targets = [base] + [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in mods]
                targets += [lazy[base][a.name] for a in node.names if a.name in lazy.get(base, {})]
            else:
                continue
            for target in targets:
                parts = target.split(".")
                for i in range(1, len(parts) + 1):
                    reached = ".".join(parts[:i])
                    if reached in mods and reached != module and not module.startswith(reached + "."):
                        where = f"{path.relative_to(PACKAGE.parent)}:{node.lineno}"
                        edges.setdefault((module, reached), []).append(where)
    return edges


def circles(edges) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    graph: dict[str, set[str]] = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
    index, low, stack, on, out = {}, {}, [], set(), []
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circles():
    edges = {e: w for e, w in import_edges().items() if e not in ALLOWED}
    found = circles(edges)
    report = []
    for component in found:
        inside = sorted((a, b) for a, b in edges if a in component and b in component)
        report.append(", ".join(component) + ":\n" + "\n".join(
            f"    {a} -> {b} ({', '.join(edges[(a, b)])})" for a, b in inside))
    assert not found, "import circles between mechsweep's modules:\n" + "\n".join(report)


def test_every_allowed_circle_edge_still_exists():
    edges = import_edges()
    gone = [f"{a} -> {b}" for a, b in ALLOWED if (a, b) not in edges]
    assert not gone, "no longer imported, drop from ALLOWED: " + ", ".join(gone)


# (importer, imported; a package stands for its modules): the layers point one way. The run
# (execution/) writes through the store and is driven by the command line (cli.py and commands/); the
# store, the figures and the description of a dataset read and write datasets without knowing how they
# are computed. The engine composes kernels from the model layer and the integrators: the run, the
# store, the scene and the command line call it (through a model's evaluate), never the reverse.
FORBIDDEN = [
    ("mechsweep.engine", "mechsweep.execution"),
    ("mechsweep.engine", "mechsweep.store"),
    ("mechsweep.engine", "mechsweep.scene"),
    ("mechsweep.engine", "mechsweep.cli"),
    ("mechsweep.engine", "mechsweep.commands"),
    ("mechsweep.engine", "mechsweep.figures"),
    ("mechsweep.execution", "mechsweep.cli"),
    ("mechsweep.execution", "mechsweep.commands"),
    ("mechsweep.store", "mechsweep.cli"),
    ("mechsweep.store", "mechsweep.commands"),
    ("mechsweep.store", "mechsweep.execution"),
    ("mechsweep.figures", "mechsweep.execution"),
    ("mechsweep.figures", "mechsweep.cli"),
    ("mechsweep.figures", "mechsweep.commands"),
    ("mechsweep.describe", "mechsweep.execution"),
]


def _inside(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def test_the_layers_import_one_way():
    edges = import_edges()
    wrong = [f"{a} -> {b} ({', '.join(where)})" for (a, b), where in sorted(edges.items())
             for low, high in FORBIDDEN if _inside(a, low) and _inside(b, high)]
    assert not wrong, "imports against the layers' direction:\n" + "\n".join(wrong)


def test_the_layer_rules_name_packages_that_exist():
    # a rule about a package renamed or removed would pass without checking anything
    mods = modules()
    assert all(low in mods and high in mods for low, high in FORBIDDEN)


def test_the_graph_sees_function_level_imports_and_circles():
    # the reader of the graph itself: a function-level import is an edge, so is one under
    # TYPE_CHECKING, and two modules importing each other are a circle
    edges = import_edges()
    assert ("mechsweep.execution.runner", "mechsweep.execution.cluster") in edges  # runner imports cluster inside functions
    assert ("mechsweep.grid", "mechsweep.scene") in edges  # grid names Scene in its signatures (TYPE_CHECKING)
    # a name a package exports lazily (its __init__'s _EXPORTS) reaches the module that defines it
    assert lazy_exports(modules())["mechsweep.model"]["Steady"] == "mechsweep.model.sampled"
    assert circles({("a", "b"): [], ("b", "c"): [], ("c", "a"): [], ("c", "d"): []}) == [["a", "b", "c"]]


def _fresh(code: str) -> str:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_the_declarations_import_no_numba():
    """Param, Output, Setting, ExtraDim and ModelSpec are dataclasses: importing them (and the table
    of built-in models, which names their modules) loads neither numba nor a model's kernels."""
    loaded = _fresh("import sys; import mechsweep.model.spec; import mechsweep.models; "
                    "from mechsweep.model import Param, Output; "
                    "print(sorted(m for m in sys.modules if m == 'numba' or m.startswith('mechsweep.')))")
    assert loaded == str(["mechsweep.model", "mechsweep.model.spec", "mechsweep.models"])


def test_the_measurements_and_the_model_declaration_import_no_numba():
    """The measurements (model/measure.py, model/sampled.py) and OdeModel are declarations: importing
    them loads neither numba nor the engine (their kernels are composed when first wanted)."""
    loaded = _fresh("import sys; import mechsweep.model.measure, mechsweep.model.sampled, mechsweep.model.ode; "
                    "from mechsweep.model import OdeModel, Steady, RMS, FirstEvent; "
                    "print(sorted(m for m in sys.modules if m == 'numba' or m.startswith('mechsweep.engine')))")
    assert loaded == "[]"


def test_each_built_in_model_is_declared_by_the_module_the_table_names():
    from mechsweep.models import BUILT_IN, MODELS

    assert list(MODELS) == list(BUILT_IN)
    assert [(name, MODELS[name].name) for name in BUILT_IN] == [(name, name) for name in BUILT_IN]
    assert all(sys.modules[BUILT_IN[name]].SPEC is MODELS[name] for name in BUILT_IN)


@pytest.mark.parametrize("name", ["duffing", "autobalancer"])
def test_looking_up_a_built_in_model_imports_its_module_only(name):
    from mechsweep.models import BUILT_IN

    others = [module for other, module in BUILT_IN.items() if other != name]
    loaded = _fresh(f"import sys; from mechsweep.models import MODELS; MODELS[{name!r}]; "
                    f"print(sorted(m for m in {others!r} if m in sys.modules))")
    assert loaded == "[]"
