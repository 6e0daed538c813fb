"""`Scenario`: everything that defines one car-part painting job, declared once per part.

Scenarios are data: a TOML file (`scenarios/door.toml`, format in docs/interfaces.md and
`paintcell.app.scenario_data`) maps one-to-one onto the `Scenario` fields and is read without
running any
code. A Python script that builds one `Scenario` named `SCENARIO` is still accepted for users who
want code (and `raise SystemExit(run_script(SCENARIO))`, with `run_script` from
`paintcell.cli.main`, lets
`python script.py` run it); only scenario files the user names on the command line are ever
imported, never a file named in a results folder (`paintcell.app.scenario_files` loads them).
`paintcell check scenarios/` loads every `*.toml` and `*.py` file of the folder.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from paintcell.core.errors import ScenarioError
from paintcell.core.placement import Placement
from paintcell.surface.part_spec import MeshPart
from paintcell.validation.paint_spec import PaintSpec
from paintcell.validation.validate_report import Thresholds, check_thresholds

__all__ = ["MAX_NAME_CHARS", "Scenario", "facing_robot"]

#: Longest scenario name: it names the results folder and its hidden siblings (a file name holds
#: at most 255 bytes).
MAX_NAME_CHARS = 100


def facing_robot() -> tuple[float, float, float]:
    """Roll-pitch-yaw [rad] that stands a part upright facing a robot at the world origin.

    The part frame's painted side (+z) faces −x (toward a robot base at the origin looking along
    +x), the part's y axis points up (+z) and its x axis runs along −y.
    """
    return (np.pi / 2, 0.0, -np.pi / 2)


@dataclass(frozen=True)
class Scenario:
    """One painting job: part, placement, robot, applicator, settings and thresholds.

    name: short identifier (names the results folder and the CI row).
    part: a library part name (`paintcell.surface.parts.PART_NAMES`), a path to a mesh or CAD
        file (relative to the scenario file; read with every `[part]` setting at its default:
        units auto, pieces auto, side auto), or a mesh/CAD part
        (`paintcell.surface.part_spec.MeshPart`, or its TOML `[part]` table as a dict,
        converted on construction).
    part_placement: where the part frame sits in the world.
    base: where the robot base sits in the world.
    robot: robot name for `paintcell.robots.catalog.load_robot`.
    resolution_m: mesh resolution of a full run [m].
    fast_resolution_m: mesh resolution of a `--fast` run [m].
    applicator: path to an applicator TOML file, or None for the default bell.
    planner: keyword arguments for `paintcell.coverage.algorithm.PlannerSettings` (only what
        differs from the defaults).
    fast_planner: planner settings applied over `planner` in `--fast` runs.
    trajectory: keyword arguments for `paintcell.motion.trajectory.TrajectorySettings`.
    servo: keyword arguments for `paintcell.execution.execute.ServoSettings`.
    disturbances: keyword arguments for `paintcell.execution.execute.Disturbances` (seeded part
        placement error, TCP calibration offset, gain scaling, …) to study robustness; empty:
        the nominal cell.
    thresholds: what `paintcell run` and `paintcell check` hold the run to
        (`paintcell.validation.validate_report.Thresholds`: reachability, collisions, executed
        σ/μ, loss, cycle time, and optionally tracking error, speed error, torque and
        joint-range utilization).
    spec: the paint spec the executed film is judged against
        (`paintcell.validation.paint_spec.PaintSpec`: target film, window, least share of the
        judged area inside it, largest σ/μ; its defaults when the scenario sets none;
        `thresholds.max_executed_nsd_pct` can only tighten its σ/μ).
    sweep: the robustness sweep of `paintcell sweep`
        (`paintcell.validation.sweep_spec.spec_from_scenario`): factors {disturbance name:
        distribution string}, samples, fast_samples, method ("lhs" | "mc"), seed, workers
        (local Dask processes; 0: in-process), and limits on quantiles and yield that
        `paintcell check` holds the scenario to (`paintcell.sweeps.sweep_stats`), e.g.
        {"max_p95_executed_nsd_pct": 12.0}.
    source: the file the scenario was declared in (filled in by `load_scenario`).
    """

    name: str
    part: str | MeshPart
    part_placement: Placement
    base: Placement = Placement()
    robot: str = "abb_paint"
    resolution_m: float = 0.01
    fast_resolution_m: float = 0.025
    applicator: str | None = None
    planner: dict[str, Any] = field(default_factory=dict)
    fast_planner: dict[str, Any] = field(default_factory=dict)
    trajectory: dict[str, Any] = field(default_factory=dict)
    servo: dict[str, Any] = field(default_factory=dict)
    disturbances: dict[str, Any] = field(default_factory=dict)
    thresholds: Thresholds = Thresholds()
    spec: PaintSpec = PaintSpec()
    sweep: dict[str, Any] = field(default_factory=dict)
    source: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or len(self.name) > MAX_NAME_CHARS \
                or not all(c.isalnum() or c in "_-" for c in self.name):
            shown = self.name if len(str(self.name)) <= 40 else f"{str(self.name)[:40]}…"
            raise ScenarioError(f"scenario name {shown!r} must be 1 to {MAX_NAME_CHARS} letters, "
                                "digits, '_' or '-' (it names the results folder)")
        if isinstance(self.part, dict):
            object.__setattr__(self, "part", MeshPart.from_dict(self.part))
        if not self.part or not isinstance(self.part, str | MeshPart):
            raise ScenarioError("scenario part is empty; give a library part name, a mesh path "
                                "or a [part] table")
        for name in ("resolution_m", "fast_resolution_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v) \
                    or v <= 0:
                raise ScenarioError(f"Scenario.{name} = {v!r} must be a positive length [m]")
        for name in ("planner", "fast_planner", "trajectory", "servo", "disturbances", "sweep"):
            if not isinstance(getattr(self, name), dict):
                raise ScenarioError(f"Scenario.{name} must be a dict of setting names to values")
        if not isinstance(self.thresholds, Thresholds):
            raise ScenarioError("Scenario.thresholds must be a Thresholds "
                                "(paintcell.app.scenario)")
        check_thresholds(self.thresholds)
        if isinstance(self.spec, dict):
            object.__setattr__(self, "spec", PaintSpec.from_table(self.spec, "Scenario.spec"))
        if not isinstance(self.spec, PaintSpec):
            raise ScenarioError("Scenario.spec must be a PaintSpec "
                                "(paintcell.validation.paint_spec)")

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description of the scenario (for reports); `scenario_from_dict` inverts it."""
        return asdict(self)
