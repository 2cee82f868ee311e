"""Imports point down only (cli -> study -> formats -> optimize -> analysis -> kinematics); no circles in core, studio.

Read from the source (every ``import``, also inside functions), so a lazy import cannot hide an upward arrow.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ["kinematics", "analysis", "optimize", "formats", "study", "cli"]  # low to high


def module_name(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")


def imports_of(path: Path) -> set[str]:
    """Every module named by an import in the file (``from a.b import c`` gives ``a.b`` and ``a.b.c``)."""
    tree = ast.parse(path.read_text(), str(path))
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found.update(f"{node.module}.{a.name}" for a in node.names)
    return found


def modules(package: str) -> dict[str, set[str]]:
    return {module_name(p): imports_of(p) for p in sorted((ROOT / package).rglob("*.py"))}


def layer(name: str) -> int | None:
    parts = name.split(".")
    return LAYERS.index(parts[1]) if len(parts) > 1 and parts[0] == "core" and parts[1] in LAYERS else None


def test_every_core_module_sits_in_a_layer():
    loose = [m for m in modules("core") if m != "core" and layer(m) is None]
    assert loose == []


@pytest.mark.parametrize("low", LAYERS[:-1])
def test_no_lower_layer_imports_a_higher_one(low):
    bad = [
        (m, i)
        for m, found in modules(f"core/{low}").items()
        for i in sorted(found)
        if (lay := layer(i)) is not None and lay > LAYERS.index(low)
    ]
    assert bad == []


def test_core_imports_no_studio_viser_or_plotly():
    headless = {"studio", "viser", "plotly"}
    bad = [(m, i) for m, found in modules("core").items() for i in found if i.split(".")[0] in headless]
    assert bad == []


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Import circles among the graph's own modules (Tarjan's strongly connected components)."""
    edges = {m: {i for i in found if i in graph and i != m} for m, found in graph.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in edges:
        if v not in index:
            visit(v)
    return out


def without_packages(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    # A package __init__ that re-exports its modules is not a circle with them.
    packages = {m for m in graph if (ROOT / m.replace(".", "/") / "__init__.py").exists()}
    return {m: found - packages for m, found in graph.items() if m not in packages}


@pytest.mark.parametrize("package", ["core", "studio"])
def test_no_import_circles(package):
    assert cycles(without_packages(modules(package))) == []


def test_the_cycle_finder_finds_a_circle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
