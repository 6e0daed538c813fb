"""paintcell: plan spray-paint coverage on car-body parts and prove it on simulated paint robots.

The names a Python user needs, importable from the package itself::

    from paintcell import load_scenario, run_scenario
    scenario = load_scenario("scenarios/door.toml")
    result = run_scenario(scenario, "results/door", fast=True)
    print(result.passed, result.report.metrics["executed_nsd_pct"], "% executed σ/μ")

The plan step alone: `surface = load_surface(scenario)`, `plan = make_plan(scenario, surface)`.
A booth file (several robots, `Booth`) loads and runs the same way; its run is a `BoothResult`.
Each name is imported on first use, so `import paintcell` (and the `paintcell` command, which
starts by importing this package) stays light: the stages behind them import numpy, MuJoCo,
Pinocchio and numba.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

#: public name → the module that defines it.
_WHERE = {
    "load_scenario": "paintcell.app.scenario_files",
    "run_scenario": "paintcell.app.pipeline",
    "load_surface": "paintcell.app.pipeline",
    "make_plan": "paintcell.app.pipeline",
    "RunResult": "paintcell.app.pipeline",
    "Scenario": "paintcell.app.scenario",
    "Booth": "paintcell.booth.booth",
    "BoothResult": "paintcell.booth.booth_run",
    "Placement": "paintcell.core.placement",
    "PaintcellError": "paintcell.core.errors",
    "Surface": "paintcell.surface.surface_data",
    "CoveragePlan": "paintcell.coverage.plan",
    "JointTrajectory": "paintcell.motion.joint_trajectory",
    "ExecutedTrace": "paintcell.execution.trace",
    "ValidationReport": "paintcell.validation.validate_report",
}

__all__ = ["Booth", "BoothResult", "CoveragePlan", "ExecutedTrace", "JointTrajectory",
           "PaintcellError", "Placement", "RunResult", "Scenario", "Surface", "ValidationReport",
           "__version__", "load_scenario", "load_surface", "make_plan", "run_scenario"]

if TYPE_CHECKING:   # for type checkers and editors; at run time `__getattr__` imports them
    from paintcell.app.pipeline import RunResult, load_surface, make_plan, run_scenario
    from paintcell.app.scenario import Scenario
    from paintcell.app.scenario_files import load_scenario
    from paintcell.booth.booth import Booth
    from paintcell.booth.booth_run import BoothResult
    from paintcell.core.errors import PaintcellError
    from paintcell.core.placement import Placement
    from paintcell.coverage.plan import CoveragePlan
    from paintcell.execution.trace import ExecutedTrace
    from paintcell.motion.joint_trajectory import JointTrajectory
    from paintcell.surface.surface_data import Surface
    from paintcell.validation.validate_report import ValidationReport


def __getattr__(name: str) -> Any:
    """Import a public name from its module on first use (PEP 562) and keep it."""
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'paintcell' has no attribute {name!r}")
    value = getattr(importlib.import_module(where), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_WHERE})
