"""The package's import arrows all point down: no module imports one above it, and none imports
itself through others (a cycle).

Every module's ``feeder`` imports are read from its syntax tree, function-local imports included
(:func:`feeder.workflow.feeder_imports`), and each module belongs to a *unit*: a subpackage
(``feeder.sim``) or a top-level module (``feeder.io``). ``LAYERS`` lists the units from the
bottom up; a module may import its own unit and the units of lower layers, never a unit of its
own layer or of one above. Units that share a layer stand beside each other: the simulator
(``sim``) and the analytic mechanics (``mechanics``) both build on the lane's description
(``lane``) and know nothing of each other.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from feeder.workflow import feeder_imports

SRC = Path(__file__).resolve().parents[1] / "src"

LAYERS: tuple[tuple[str, ...], ...] = (
    ("feeder", "errors"),  # the package itself (its version) and its one exception
    ("io", "config", "circular", "cli", "fresh"),  # files, settings, angles; cli dispatches by name
    ("workflow", "__main__"),
    ("lane", "parts"),  # the lane (belt, walls, fences) and the parts
    ("mechanics", "sim"),  # analytic pushing and the simulator, side by side
    ("labels",),
    ("learn",),
    ("bench",),
    ("figures", "report"),
)
RANK = {unit: rank for rank, units in enumerate(LAYERS) for unit in units}


def package_modules(root: Path) -> list[str]:
    """Dotted names of every module of the ``feeder`` package under ``root``."""
    names = []
    for path in sorted((root / "feeder").rglob("*.py")):
        parts = path.relative_to(root).with_suffix("").parts
        names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def unit_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def import_graph(root: Path) -> dict[str, set[str]]:
    return {m: feeder_imports(m, root) for m in package_modules(root)}


def upward_arrows(graph: dict[str, set[str]], ranks: dict[str, int] = RANK) -> list[str]:
    """Imports of a unit in the module's own layer or above it (other than its own unit)."""
    bad = []
    for module, imports in sorted(graph.items()):
        unit = unit_of(module)
        for target in sorted(imports):
            other = unit_of(target)
            if other != unit and ranks.get(other, len(LAYERS)) >= ranks.get(unit, -1):
                bad.append(f"{module} -> {target}")
    return bad


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in graph.get(v, ()):
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


@pytest.fixture(scope="module")
def graph():
    return import_graph(SRC)


def test_every_unit_has_a_layer(graph):
    """A new subpackage or top-level module gets its place in ``LAYERS``."""
    assert {unit_of(m) for m in graph} - set(RANK) == set()


def test_no_import_runs_up_or_sideways(graph):
    assert upward_arrows(graph) == []


def test_no_import_cycle(graph):
    assert cycles(graph) == []


def test_the_checks_see_an_upward_arrow_and_a_cycle(tmp_path):
    """The same checks on a small package with one arrow up and one cycle."""
    files = {
        "__init__.py": "",
        "errors.py": "",
        "parts/__init__.py": "",
        "parts/shape.py": "from feeder.sim.drop import fall\n",  # parts -> sim: up
        "sim/__init__.py": "",
        "sim/drop.py": "def fall():\n    from feeder.sim import world\n",
        "sim/world.py": "import feeder.sim.drop\nfrom feeder.errors import FeederError\n",
    }
    for name, text in files.items():
        path = tmp_path / "feeder" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    toy = import_graph(tmp_path)
    ranks = {"feeder": 0, "errors": 0, "parts": 1, "sim": 2}
    assert upward_arrows(toy, ranks) == ["feeder.parts.shape -> feeder.sim.drop"]
    assert cycles(toy) == [["feeder.sim.drop", "feeder.sim.world"]]
