"""The public API: every name of `paintcell.__all__` imports from the package, `import paintcell`
stays light, and the package docstring's example runs and reports the figure its results folder
holds."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import paintcell
from tests.test_structure import LAYERS, _stage

ROOT = Path(__file__).resolve().parents[1]


def _python(code: str, cwd: Path = ROOT) -> str:
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=cwd, timeout=600)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-2000:]
    return proc.stdout


def test_every_public_name_imports_from_the_package() -> None:
    names = [n for n in paintcell.__all__ if n != "__version__"]
    assert sorted(names) == sorted(paintcell._WHERE)
    assert {"load_scenario", "run_scenario", "load_surface", "make_plan", "RunResult",
            "CoveragePlan", "JointTrajectory", "ExecutedTrace", "Surface",
            "Scenario"} <= set(names)
    # a fresh interpreter: `from paintcell import X` for each, and each is what its module defines
    out = _python("import importlib, paintcell\n"
                  f"for n in {names!r}:\n"
                  "    exec(f'from paintcell import {n} as v')\n"
                  "    m = importlib.import_module(paintcell._WHERE[n])\n"
                  "    assert v is getattr(m, n) and v.__module__ == m.__name__, n\n"
                  "    print(n, m.__name__)\n")
    rows = dict(line.split() for line in out.splitlines())
    assert sorted(rows) == sorted(names)
    # the API sits above every module it names (tests/test_structure.py's layers)
    for n, mod in rows.items():
        assert _stage(mod) < LAYERS.index("paintcell"), (n, mod)


def test_version_is_the_distribution_version() -> None:
    with open(ROOT / "pyproject.toml", "rb") as f:
        assert paintcell.__version__ == tomllib.load(f)["project"]["version"]
    assert _python("from paintcell import __version__; print(__version__)").strip() == \
        paintcell.__version__


def test_unknown_name_is_an_attribute_error() -> None:
    out = _python("import paintcell\n"
                  "try:\n    paintcell.run_scenarios\nexcept AttributeError as e:\n    print(e)\n")
    assert "run_scenarios" in out


def test_import_paintcell_loads_no_stage() -> None:
    """The `paintcell` command imports the package first: its names load on first use, so
    `import paintcell` brings in neither numpy nor any stage module."""
    out = _python("import sys, paintcell\n"
                  "print(sorted(m for m in sys.modules if m.split('.')[0] in "
                  "('numpy', 'mujoco', 'pinocchio', 'numba') or m.startswith('paintcell.')))")
    assert out.strip() == "[]"


def test_the_package_example_runs_and_reports_its_results_folder(tmp_path: Path) -> None:
    """The example of `paintcell.__doc__` (door.toml at fast resolution), run as written with its
    results folder in tmp: the executed σ/μ it prints is the one metrics.json holds."""
    block = re.search(r"::\n\n((?:    .*\n)+)", paintcell.__doc__ or "")
    assert block, "paintcell's docstring has no example block"
    code = "\n".join(line[4:] for line in block.group(1).splitlines())
    assert code.startswith("from paintcell import load_scenario, run_scenario\n")
    assert 3 <= len(code.splitlines()) <= 5
    out_dir = tmp_path / "door"
    assert '"results/door"' in code
    printed = _python(code.replace('"results/door"', repr(str(out_dir))))
    passed, nsd, *_ = printed.split()
    metrics = json.loads((out_dir / "metrics.json").read_text())
    assert float(nsd) == metrics["executed_nsd_pct"]
    assert passed == str(metrics["passed"]) == str(all(c["passed"] for c in metrics["checks"]))
    assert metrics["run"]["fast"] is True and 0 < float(nsd) < 8.0
