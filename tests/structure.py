"""Read a package's import graph (module and folder level) and private-name uses from its source
(tests/test_structure.py)."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx


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


def private_imports(pkg: Path) -> list[tuple[str, str, str]]:
    """(module, other module, name) for each private name (`_x`, not a dunder) one package
    module takes from another: `from m import _x`, or `m._x` on a module imported as
    `import m` / `from pkg import m` (aliases followed), lazily or not (TYPE_CHECKING blocks
    skipped)."""
    mods = _modules(pkg)
    out = set()
    for mod, path in mods.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        skip = _type_checking_nodes(tree)
        here = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
        aliases: dict[str, str] = {}   # local name → package module it is bound to
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            if isinstance(node, ast.Import):
                for a in node.names:
                    if a.name in mods:
                        aliases[a.asname or a.name] = a.name
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = here[: len(here) - (node.level - 1)]
                    base = ".".join(anchor + ([base] if base else []))
                for a in node.names:
                    full = f"{base}.{a.name}"
                    if full in mods:
                        aliases[a.asname or a.name] = full
                        if _private(a.name) and full != mod:
                            out.add((mod, full, a.name))
                    elif base in mods and base != mod and _private(a.name):
                        out.add((mod, base, a.name))
        for node in ast.walk(tree):
            if id(node) in skip or not isinstance(node, ast.Attribute) or not _private(node.attr):
                continue
            target = _dotted(node.value)
            target = aliases.get(target, target if target in mods else None)
            if target is not None and target != mod:
                out.add((mod, target, node.attr))
    return sorted(out)


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _dotted(node: ast.AST) -> str:
    """`a.b.c` for a Name/Attribute chain, "" for anything else."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return ""
    return ".".join([node.id, *reversed(parts)])


def folder_of(mod: str) -> str:
    """The top folder a dotted module lives in (`paintcell.app.pipeline` → "app"); a module at
    the package root is its own name (`paintcell` → "paintcell", `paintcell.__main__` →
    "__main__")."""
    parts = mod.split(".")
    return parts[0] if len(parts) == 1 else parts[1]


def folder_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Folder → the other folders its modules import (the module graph, lumped by folder)."""
    out: dict[str, set[str]] = {folder_of(m): set() for m in graph}
    for a, bs in graph.items():
        out[folder_of(a)].update(folder_of(b) for b in bs if folder_of(b) != folder_of(a))
    return out


def against_order(fgraph: dict[str, set[str]], order: list[str]) -> list[tuple[str, str]]:
    """(a, b) for each folder a importing a folder b that `order` puts after it, or a folder
    `order` does not name (either end)."""
    rank = {f: i for i, f in enumerate(order)}
    return sorted((a, b) for a, bs in fgraph.items() for b in bs
                  if a not in rank or b not in rank or rank[b] > rank[a])



def reexports(pkg: Path) -> dict[str, list[str]]:
    """Module → the names its `__all__` lists that it only imports (a re-export facade), for
    every module but a package's `__init__.py` (a package's public face may gather names)."""
    out = {}
    for mod, path in _modules(pkg).items():
        if path.name == "__init__.py":
            continue
        tree = ast.parse(path.read_text(), filename=str(path))
        imported: set[str] = set()
        exported: list[str] = []
        for node in tree.body:
            if isinstance(node, ast.Import | ast.ImportFrom):
                imported.update((a.asname or a.name).split(".")[0] for a in node.names)
            elif isinstance(node, ast.Assign) and any(
                    isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
                exported = list(ast.literal_eval(node.value))
        found = sorted(n for n in exported if n in imported)
        if found:
            out[mod] = found
    return out
