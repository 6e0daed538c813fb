"""The house rules, found from the code: no import cycles between modules nor between folders,
which follow one declared order with the command line on top (lazy imports inside functions
count; `if TYPE_CHECKING:` blocks do not run and do not count), a folder per stage, and a README
"Where things live" table that matches the tree. Modules are cut by concept, not by length: no
line cap.

Nor does a module use another's private (underscored) names, nor list in `__all__` names it
imports (a re-export facade; the few that remain are listed and may only go).

The checkers are also run on small synthetic packages that break each rule, so a checker that
stopped finding anything would fail here too.
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import pytest

from tests.structure import (
    against_order,
    folder_graph,
    folder_of,
    import_cycles,
    import_graph,
    private_imports,
    reexports,
)

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "paintcell"

#: The stages of the data flow and the folder each lives in (docs/architecture.md).
STAGE_FOLDERS = ["core", "surface", "paint", "coverage", "robots", "motion", "execution",
                 "validation", "output", "booth", "sweeps", "app", "cli"]


def test_no_import_cycles() -> None:
    graph = import_graph(PKG)
    assert len(graph) > 50  # the whole package was parsed, not an empty folder
    cycles = import_cycles(graph)
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


#: The folders in data-flow order: a module imports only its own folder and the ones before it
#: (lazy imports inside functions count). After the stages of one part's data flow come the
#: booth (several robots and a conveyor, built from those stages), the application (scenario
#: files of either kind, the pipeline, `init`), the sweeps (many runs of a scenario), the public
#: API (`paintcell/__init__.py`, shown as "paintcell") and, on top, the command line
#: (`paintcell/__main__.py` is the command line too).
LAYERS = ["core", "surface", "paint", "coverage", "robots", "motion", "execution", "validation",
          "output", "booth", "app", "sweeps", "paintcell", "cli"]


def _layer(folder: str) -> str:
    return "cli" if folder == "__main__" else folder


def _stage(mod: str) -> int | None:
    """Index in LAYERS of the folder `mod` lives in (`core`'s modules, such as `errors`, are 0,
    shared by every folder after it); None for a folder that is not a layer."""
    rest = mod.removeprefix("paintcell.")
    f = _layer(folder_of(mod)) if rest != mod or mod == "paintcell" else None
    return LAYERS.index(f) if f in LAYERS else None


def test_every_module_lives_in_a_stage() -> None:
    """No module outside the layer folders (a new `paintcell/x.py` would dodge the data-flow
    check): only the package root and `paintcell/__main__.py` sit above them."""
    stray = sorted(m for m in import_graph(PKG) if _stage(m) is None)
    assert not stray, f"modules outside every stage folder: {stray}"


def test_data_flows_one_way_through_the_stages() -> None:
    graph = import_graph(PKG)
    upward = sorted((a, b) for a, bs in graph.items() for b in bs
                    if (_stage(a) or 0) < (_stage(b) or 0))
    assert not upward, f"imports against the data flow: {upward}"


def test_folders_form_a_dag_in_the_declared_order() -> None:
    """The folder-level graph (every import of a module of one folder from another, lazy ones
    counted, `if TYPE_CHECKING:` blocks not) has no cycle and follows LAYERS, cli on top."""
    fgraph = {_layer(a): set() for a in folder_graph(import_graph(PKG))}
    for a, bs in folder_graph(import_graph(PKG)).items():
        fgraph[_layer(a)].update(_layer(b) for b in bs if _layer(b) != _layer(a))
    assert set(fgraph) == set(LAYERS), sorted(set(fgraph) ^ set(LAYERS))
    cycles = import_cycles(fgraph)
    assert not cycles, "folder cycles: " + "; ".join(" -> ".join(c) for c in cycles)
    assert not against_order(fgraph, LAYERS), against_order(fgraph, LAYERS)
    assert not any("cli" in bs for f, bs in fgraph.items() if f != "cli")   # cli is on top


def test_no_private_name_crosses_a_module() -> None:
    """A name with a leading underscore is its module's own: no other package module imports it
    (`from m import _x`) or reaches it (`m._x`), lazily or not. What modules share is public,
    named and documented."""
    found = private_imports(PKG)
    assert not found, "private names used across modules: " + "; ".join(
        f"{a} uses {b}.{n}" for a, b, n in found)


#: Modules whose `__all__` still lists names they import from elsewhere; callers should import
#: those names from the module that defines them. The list only shrinks.
REEXPORTING: set[str] = set()


def test_no_new_reexport_facade() -> None:
    """A module's `__all__` names what it defines; a module that gathers other modules' names
    (a facade) hides where they live. Package `__init__.py` files are the exception."""
    found = reexports(PKG)
    new = sorted(set(found) - REEXPORTING)
    assert not new, "modules re-exporting imported names: " + "; ".join(
        f"{m}: {found[m]}" for m in new)
    gone = sorted(REEXPORTING - set(found))
    assert not gone, f"no longer re-exporting, drop from REEXPORTING: {gone}"


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
    assert _stage("paintcell.surface.analytic") == 1
    assert _stage("paintcell.coverage.plan") == 3
    assert _stage("paintcell.robots.ik") == 4
    assert _stage("paintcell.validation.validate") == 7
    assert _stage("paintcell.sim.foo") is None
    assert _stage("paintcell.cli.main") == _stage("paintcell.__main__") == len(LAYERS) - 1
    assert _stage("paintcell") == LAYERS.index("paintcell")


def test_checker_finds_a_folder_cycle_that_no_module_cycle_shows(tmp_path: Path) -> None:
    """a.x → b.y at top level and b.z → a.w inside a function: no module cycle, but folders a and
    b import each other; a TYPE_CHECKING import from c to a adds no edge."""
    pkg = _write(tmp_path, {
        "paintcell/__init__.py": "",
        "paintcell/a/__init__.py": "", "paintcell/b/__init__.py": "", "paintcell/c/__init__.py": "",
        "paintcell/a/x.py": "from paintcell.b.y import f\n",
        "paintcell/a/w.py": "",
        "paintcell/b/y.py": "def f():\n    pass\n",
        "paintcell/b/z.py": "def g():\n    from paintcell.a import w\n",
        "paintcell/c/v.py": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                             "    from paintcell.a.x import f\n"),
    })
    graph = import_graph(pkg)
    assert not import_cycles(graph)
    fgraph = folder_graph(graph)
    assert fgraph["c"] == set()
    assert import_cycles(fgraph) == [["a", "b"]]
    assert against_order(fgraph, ["paintcell", "a", "b", "c"]) == [("a", "b")]
    assert against_order(fgraph, ["paintcell", "b", "a", "c"]) == [("b", "a")]
    assert folder_of("paintcell.a.x") == "a" and folder_of("paintcell") == "paintcell"


def test_checker_finds_private_names_across_modules(tmp_path: Path) -> None:
    """Each way of reaching another module's private name is found once; a module's own private
    names, dunders, public names and TYPE_CHECKING imports are not."""
    pkg = _write(tmp_path, {
        "paintcell/__init__.py": "",
        "paintcell/s/__init__.py": "",
        "paintcell/s/m.py": "_X = 1\n__version__ = '1'\nY = 2\ndef _f():\n    return _X\n",
        "paintcell/s/a.py": "from paintcell.s.m import _X, Y\n",
        "paintcell/s/b.py": "def g():\n    from .m import _f\n    return _f()\n",
        "paintcell/s/c.py": "import paintcell.s.m\nv = paintcell.s.m._X + paintcell.s.m.Y\n",
        "paintcell/s/d.py": "from paintcell.s import m as mm\nv = mm._f()\nw = mm.__version__\n",
        "paintcell/s/e.py": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                             "    from paintcell.s.m import _X\n_own = 3\nv = _own\n"),
    })
    assert private_imports(pkg) == [
        ("paintcell.s.a", "paintcell.s.m", "_X"),
        ("paintcell.s.b", "paintcell.s.m", "_f"),
        ("paintcell.s.c", "paintcell.s.m", "_X"),
        ("paintcell.s.d", "paintcell.s.m", "_f"),
    ]


def test_checker_finds_a_reexport(tmp_path: Path) -> None:
    """A name imported and listed in `__all__` is a re-export; a defined one is not, nor is an
    `__init__.py` gathering names."""
    pkg = _write(tmp_path, {
        "paintcell/__init__.py": "from paintcell.m import Y\n__all__ = ['Y']\n",
        "paintcell/m.py": "Y = 2\n__all__ = ['Y']\n",
        "paintcell/f.py": ("import os\nfrom paintcell.m import Y\nZ = 1\n"
                           "__all__ = ['Y', 'Z', 'os']\n"),
    })
    assert reexports(pkg) == {"paintcell.f": ["Y", "os"]}


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
