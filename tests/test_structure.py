"""The house rules, found from the code: modules of at most 400 lines, no import cycles (lazy
imports inside functions count; `if TYPE_CHECKING:` blocks do not run and do not count), a folder
per stage, and a README "Where things live" table that matches the tree.

The checkers are also run on small synthetic packages that break each rule, so a checker that
stopped finding anything would fail here too.
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import pytest

from tests.structure import MAX_MODULE_LINES, import_cycles, import_graph, long_modules

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "paintcell"

#: The stages of the data flow and the folder each lives in (docs/architecture.md).
STAGE_FOLDERS = ["core", "surface", "paint", "coverage", "robots", "motion", "execution",
                 "validation", "output", "booth", "sweeps", "app", "cli"]


def test_no_module_over_the_line_limit() -> None:
    too_long = long_modules(PKG)
    assert not too_long, f"modules over {MAX_MODULE_LINES} lines: {too_long}"


def test_no_import_cycles() -> None:
    graph = import_graph(PKG)
    assert len(graph) > 50  # the whole package was parsed, not an empty folder
    cycles = import_cycles(graph)
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


#: The stages in data-flow order; a module may import its own stage and the ones before it.
#: booth, sweeps, app and cli sit on top of the chain (they use every stage and each other,
#: without cycles).
STAGE_ORDER = ["core", "surface", "paint", "coverage", "robots", "motion", "execution",
               "validation", "output"]
ON_TOP = ("paintcell.booth", "paintcell.sweeps", "paintcell.app", "paintcell.cli")


def _stage(mod: str) -> int | None:
    """Index in STAGE_ORDER of the longest stage prefix of `mod` (`core`'s modules, such as
    `errors`, are stage 0, shared by every stage after it)."""
    rest = mod.removeprefix("paintcell.")
    found = None
    for i, s in enumerate(STAGE_ORDER):
        if rest == s or rest.startswith(s + "."):
            found = i
    return found


def test_every_module_lives_in_a_stage() -> None:
    """No module outside the stage folders (a new `paintcell/x.py` would dodge the data-flow
    check): only the package roots and `paintcell/__main__.py` sit above them."""
    roots = {"paintcell", "paintcell.__main__"}
    stray = sorted(m for m in import_graph(PKG)
                   if m not in roots and _stage(m) is None and not m.startswith(ON_TOP))
    assert not stray, f"modules outside every stage folder: {stray}"


def test_data_flows_one_way_through_the_stages() -> None:
    graph = import_graph(PKG)
    upward = []
    for a, bs in graph.items():
        sa = _stage(a)
        if sa is None:
            continue
        for b in bs:
            sb = _stage(b)
            if b.startswith(ON_TOP) or (sb is not None and sb > sa):
                upward.append((a, b))
    assert not upward, f"imports against the data flow: {sorted(upward)}"


def test_every_stage_has_its_folder_and_every_folder_is_a_stage() -> None:
    folders = sorted({str(p.parent.relative_to(PKG)) for p in PKG.rglob("*.py")
                      if p.parent != PKG and "__pycache__" not in p.parts})
    for f in folders:   # a folder of modules without __init__.py would be a namespace package
        assert (PKG / f / "__init__.py").is_file(), f"{f} has modules but no __init__.py"
    for stage in STAGE_FOLDERS:
        assert (PKG / stage / "__init__.py").is_file(), stage
    extra = set(folders) - set(STAGE_FOLDERS)
    assert not extra, f"package folders not in the stage list: {sorted(extra)}"


def test_readme_where_things_live_matches_the_tree() -> None:
    text = (ROOT / "README.md").read_text()
    m = re.search(r"^## Where things live\n(.*?)(?=^## |\Z)", text, re.M | re.S)
    assert m, "README.md has no '## Where things live' section"
    rows = re.findall(r"^\| `([^`]+)` \|[^|]*\|([^\n]*)\|$", m.group(1), re.M)
    paths = [p for p, _ in rows]
    assert len(paths) >= len(STAGE_FOLDERS)
    for p, mods in rows:
        assert (ROOT / p).exists(), f"README names {p}, which is not in the tree"
        if p.startswith("paintcell/"):   # the modules column lists the folder's modules, all
            listed = set(re.findall(r"`(\w+\.py)`", mods))
            there = {q.name for q in (ROOT / p).glob("*.py") if q.name != "__init__.py"}
            assert listed == there, f"README row {p}: missing {there - listed}, " \
                                    f"not in the tree {listed - there}"
    # every folder that holds modules (other than __init__/__main__) has its row
    with_modules = {f"{q.parent.relative_to(ROOT)}/" for q in PKG.rglob("*.py")
                    if q.stem not in ("__init__", "__main__") and "__pycache__" not in q.parts}
    missing = with_modules - set(paths)
    assert not missing, f"README table lacks rows for {sorted(missing)}"
    for stage in STAGE_FOLDERS:
        assert f"paintcell/{stage}/" in paths, f"README table lacks paintcell/{stage}/"


# --- the checkers find what they must find ---------------------------------------------------

def _write(root: Path, files: dict[str, str]) -> Path:
    for name, body in files.items():
        p = root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(textwrap.dedent(body))
    return root / "paintcell"


def test_checker_finds_a_lazy_cycle_and_ignores_type_checking(tmp_path: Path) -> None:
    pkg = _write(tmp_path, {
        "paintcell/__init__.py": "",
        "paintcell/a/__init__.py": "",
        "paintcell/a/x.py": "from paintcell.a import y\n",
        "paintcell/a/y.py": "def f():\n    from paintcell.a.x import g\n",
        "paintcell/b.py": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                           "    from paintcell.c import C\n"),
        "paintcell/c.py": "from . import b\n",
    })
    cycles = import_cycles(import_graph(pkg))
    assert [sorted(c) for c in cycles] == [["paintcell.a.x", "paintcell.a.y"]]


def test_stage_of_a_module() -> None:
    assert _stage("paintcell.core.errors") == 0
    assert _stage("paintcell.surface.surface") == 1
    assert _stage("paintcell.coverage.plan") == 3
    assert _stage("paintcell.robots.ik") == 4
    assert _stage("paintcell.validation.validate") == 7
    assert _stage("paintcell.sim.foo") is None
    assert _stage("paintcell.cli.main") is None


def test_checker_finds_a_long_module(tmp_path: Path) -> None:
    pkg = _write(tmp_path, {"paintcell/__init__.py": "",
                            "paintcell/big.py": "x = 1\n" * (MAX_MODULE_LINES + 1),
                            "paintcell/ok.py": "x = 1\n" * MAX_MODULE_LINES})
    assert long_modules(pkg) == {"paintcell/big.py": MAX_MODULE_LINES + 1}


@pytest.mark.parametrize("stmt,target", [
    ("import paintcell.sim.b", "paintcell.sim.b"),
    ("from paintcell.sim import b", "paintcell.sim.b"),
    ("from .b import f", "paintcell.sim.b"),
    ("from ..top import f", "paintcell.top"),
])
def test_checker_resolves_every_import_form(tmp_path: Path, stmt: str, target: str) -> None:
    pkg = _write(tmp_path, {"paintcell/__init__.py": "", "paintcell/top.py": "",
                            "paintcell/sim/__init__.py": "", "paintcell/sim/b.py": "",
                            "paintcell/sim/a.py": stmt + "\n"})
    assert import_graph(pkg)["paintcell.sim.a"] == {target}


_HELP_ALL = """
import contextlib, io, runpy, sys
for path in sys.argv[1:]:
    sys.argv = [path, "--help"]
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out):
            runpy.run_path(path, run_name="__main__")
    except SystemExit as e:
        if e.code not in (0, None):
            raise SystemExit(f"{path}: --help exited {e.code}")
    if "usage" not in out.getvalue().lower():
        raise SystemExit(f"{path}: --help printed no usage")
    print("ok", path)
"""


def test_every_benchmark_imports_and_explains_itself() -> None:
    """Each benchmark script imports the package's current names and answers --help (running
    the benchmarks themselves is `make bench`, not a test). One interpreter for all of them."""
    import subprocess
    import sys

    scripts = sorted(str(p) for p in (ROOT / "benchmarks").glob("*.py"))
    assert len(scripts) >= 10
    proc = subprocess.run([sys.executable, "-c", _HELP_ALL, *scripts], capture_output=True,
                          text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-1500:]
    assert proc.stdout.count("ok ") == len(scripts)
