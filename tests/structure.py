"""Read a package's import graph and module sizes from its source (tests/test_structure.py)."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

#: Longest module the house allows [lines].
MAX_MODULE_LINES = 400


def _modules(pkg: Path) -> dict[str, Path]:
    """Dotted module name → file for every .py under `pkg` (a package folder)."""
    base = pkg.parent
    out = {}
    for p in sorted(pkg.rglob("*.py")):
        parts = p.relative_to(base).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the nodes under `if TYPE_CHECKING:` (never executed)."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            t = node.test
            name = (t.id if isinstance(t, ast.Name)
                    else t.attr if isinstance(t, ast.Attribute) else "")
            if name == "TYPE_CHECKING":
                for sub in node.body:
                    skip.update(id(n) for n in ast.walk(sub))
    return skip


def import_graph(pkg: Path) -> dict[str, set[str]]:
    """Module → the package modules it imports, at top level or inside functions."""
    mods = _modules(pkg)
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for mod, path in mods.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        skip = _type_checking_nodes(tree)
        here = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = here[: len(here) - (node.level - 1)]
                    base = ".".join(anchor + ([base] if base else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base
                           for a in node.names]
            for t in targets:
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t and t != mod:
                    graph[mod].add(t)
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Each strongly connected group of more than one module (a cycle), sorted."""
    g = nx.DiGraph([(a, b) for a, bs in graph.items() for b in bs])
    return sorted(sorted(c) for c in nx.strongly_connected_components(g) if len(c) > 1)


def long_modules(pkg: Path) -> dict[str, int]:
    """Files over MAX_MODULE_LINES lines, as path relative to the package's parent → lines."""
    out = {}
    for p in sorted(pkg.rglob("*.py")):
        n = len(p.read_text().splitlines())
        if n > MAX_MODULE_LINES:
            out[str(p.relative_to(pkg.parent))] = n
    return out
