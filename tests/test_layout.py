"""The package's floors: data flows one way, no module imports from a floor above its own.

The import graph is read from the syntax tree of every module (imports inside functions
count too: a lazy import upwards is still an upward dependency), with the same resolver the
kernel cache uses (:func:`sweep.kernels._jit.package_imports`).
"""
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
