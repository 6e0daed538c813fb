"""MkDocs hooks of the paintcell site (mkdocs.yml `hooks:`).

- `on_files`: adds reference/scenario.md and reference/cli.md, written by
  docs/tools/gen_reference.py from the scenario key table and the argparse parsers.
- `on_pre_build`: a warning (an error under `mkdocs build --strict`) for every public module,
  class, function or method of the API pages (docs/api/*.md, `::: module` lines) without a
  docstring, and for every scenario key without a description, so neither is published blank.
"""

from __future__ import annotations

import functools
import importlib.util
import logging
import re
import sys
from pathlib import Path
from typing import Any

DOCS = Path(__file__).resolve().parents[1]
ROOT = DOCS.parent
log = logging.getLogger("mkdocs.plugins.paintcell")

_spec = importlib.util.spec_from_file_location("gen_reference", DOCS / "tools" / "gen_reference.py")
assert _spec is not None and _spec.loader is not None
gen = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("gen_reference", gen)
_spec.loader.exec_module(gen)

#: The generated pages: path under docs/ → the function that writes it.
PAGES = {"reference/scenario.md": gen.scenario_reference, "reference/cli.md": gen.cli_reference}


def api_modules() -> list[str]:
    """The modules the API pages render (`::: paintcell.x.y` lines of docs/api/*.md)."""
    found = []
    for page in sorted((DOCS / "api").glob("*.md")):
        found += re.findall(r"^:::\s+(paintcell[\w.]*)\s*$", page.read_text(), re.M)
    return found


@functools.cache
def _package(name: str, root: str) -> Any:
    """The package `name` under `root`, read once by griffe (as mkdocstrings reads it)."""
    import griffe

    return griffe.load(name, search_paths=[root], docstring_parser="google")


def missing_docstrings(module: str) -> list[str]:
    """Public objects of `module` that mkdocstrings would render without a docstring: the module,
    its public classes and functions (its `__all__` where it has one, names it imports from
    other modules included) and their public methods and properties. Other imported names are
    skipped: their own module documents them."""
    top, _, rest = module.partition(".")
    mod = _package(top, str(ROOT))
    if rest:
        mod = mod[rest]
    out = [] if mod.docstring else [module]

    exported = set(mod.exports or ())

    def walk(obj: Any) -> None:
        for name, m in obj.members.items():
            if name.startswith("_") or not m.is_public:
                continue
            if m.is_alias:   # rendered here only when the module exports it (`__all__`)
                if obj is not mod or name not in exported:
                    continue
                m = m.final_target
            if (m.kind.value in ("class", "function") or "property" in m.labels) \
                    and not m.docstring:
                out.append(m.path)
            if m.kind.value == "class":
                walk(m)

    walk(mod)
    return sorted(set(out))


def undescribed_keys() -> list[str]:
    """Scenario keys the reference would list without a description."""
    from paintcell.app.scenario_keys import scenario_keys

    out = []
    docs: dict[Any, dict[str, str]] = {}
    for k in scenario_keys():
        if k.table == "fast_planner" or k.doc:
            continue
        if k.owner not in docs:
            docs[k.owner] = gen.field_docs(k.owner) if k.owner is not None else {}
        if not docs[k.owner].get(k.name):
            out.append(f"[{k.table}] {k.name}" if k.table else k.name)
    return out


def on_pre_build(config: Any) -> None:
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    for module in api_modules():
        for path in missing_docstrings(module):
            log.warning(f"{path} has no docstring; the API reference would show it blank "
                        "(add one, with units)")
    for key in undescribed_keys():
        log.warning(f"scenario key {key} has no description in its settings class's docstring "
                    "(add a `name: text` entry)")


def on_files(files: Any, config: Any) -> Any:
    from mkdocs.structure.files import File

    for path, make in PAGES.items():
        files.append(File.generated(config, path, content=make()))
    return files
