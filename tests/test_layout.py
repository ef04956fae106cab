"""The package's floors: data flows one way, no module imports from a floor above its own.

The import graph is read from the syntax tree of every module (imports inside functions
count too: a lazy import upwards is still an upward dependency), with the same resolver the
kernel cache uses (:func:`sweep.kernels._jit.package_imports`). What the graph cannot follow
is checked apart: imports by name at run time (importlib), a low floor's ``import sweep.x``
(the package then loads any module as an attribute) and the registry's kernel paths.
"""
import ast
from pathlib import Path

import pytest

import sweep
from sweep.kernels import _jit

#: Floors from the ground. A module may import its own floor and those below. The README's
#: contributor section shows this table.
FLOORS = {
    "sweep._version": 0,
    "sweep._format": 0,
    "sweep.registry": 0,
    "sweep.kernels": 1,
    "sweep.store": 1,
    "sweep._arrays": 2,
    "sweep.model": 2,
    "sweep.api": 2,
    "sweep.auto": 2,
    "sweep.materials": 2,
    "sweep.critical": 3,
    "sweep.xr": 3,
    "sweep.tables": 3,
    "sweep.sweeps": 4,
    "sweep.reports": 5,
    "sweep.examples": 5,
    "sweep.cli": 6,
    "sweep.__main__": 6,
}
#: The package ``__init__`` re-exports the public API (api, critical, model, registry, and
#: sweep.run from the sweeps floor, lazily): it sits on the floor of the highest module it
#: imports.
PACKAGE_FLOOR = 4
ROOT = Path(sweep.__file__).resolve().parent


def _floor(module):
    if module == "sweep":
        return PACKAGE_FLOOR
    parts = module.split(".")
    for i in range(len(parts), 0, -1):
        key = ".".join(parts[:i])
        if key in FLOORS:
            return FLOORS[key]
    return None


def _graph():
    known = _jit._module_files(ROOT)
    return {m: _jit.package_imports(m, path, known) for m, path in known.items()}


def test_every_module_has_a_floor():
    missing = [m for m in _graph() if _floor(m) is None]
    assert not missing, f"modules without a floor in FLOORS: {missing}"


def test_no_import_from_a_floor_above():
    upward = []
    for module, imports in _graph().items():
        for target in imports:
            if _floor(target) > _floor(module):
                upward.append(f"{module} (floor {_floor(module)}) -> {target} "
                              f"(floor {_floor(target)})")
    assert not upward, "imports from a floor above:\n" + "\n".join(sorted(upward))


def test_no_import_cycles():
    graph = _graph()
    state = {}
    cycles = []

    def visit(node, path):
        state[node] = "open"
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                cycles.append(path[path.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert not cycles, f"import cycles: {cycles}"


@pytest.mark.parametrize("module", ["sweep.kernels", "sweep.store"])
def test_lower_floors_know_nothing_of_the_other(module):
    # The kernels know nothing of files, the store nothing of numba (LAYOUT).
    other = {"sweep.kernels": "sweep.store", "sweep.store": "sweep.kernels"}[module]
    bad = [(m, t) for m, imports in _graph().items() if m.startswith(module)
           for t in imports if t.startswith(other)]
    assert not bad


#: Modules that import by name at run time, which the syntax tree does not show: the
#: package's lazy public names (its _OWNERS) and a method's kernel path (Method.resolve).
DYNAMIC_IMPORTERS = {"sweep", "sweep.registry"}


def _trees():
    return {m: ast.parse(path.read_text(encoding="utf-8"))
            for m, path in _jit._module_files(ROOT).items()}


def _is_dynamic_import(node):
    if not isinstance(node, ast.Call):
        return False
    f = node.func
    name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
    return name in ("import_module", "__import__")


def test_imports_by_name_only_where_the_graph_knows_them():
    bad = [m for m, tree in _trees().items() if m not in DYNAMIC_IMPORTERS
           and any(_is_dynamic_import(node) for node in ast.walk(tree))]
    assert not bad, f"importlib.import_module / __import__ outside {DYNAMIC_IMPORTERS}: {bad}"


def test_no_low_floor_binds_the_package_name():
    # `import sweep.x` binds `sweep`, whose PEP 562 __getattr__ loads any module on first
    # use: `sweep.cli.main` from the store would be an upward import the graph misses.
    bad = [m for m, tree in _trees().items() if _floor(m) < PACKAGE_FLOOR
           for node in ast.walk(tree) if isinstance(node, ast.Import)
           for alias in node.names if alias.name.startswith("sweep") and not alias.asname]
    assert not bad, f"modules below floor {PACKAGE_FLOOR} that `import sweep...`: {bad}"


def test_method_kernels_live_where_their_callers_may_import():
    # Method.kernel is a module path resolved by the api (and auto, its floor): the
    # registry's pointer must not lead above them.
    from sweep import registry

    top = FLOORS["sweep.api"]
    for m in registry.METHODS.values():
        if isinstance(m.kernel, str):
            module = m.kernel.partition(":")[0]
            assert _floor(module) is not None and _floor(module) <= top, (m.name, module)
