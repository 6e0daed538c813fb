"""The end-to-end run of one scenario: surface → plan → IK + trajectory → MuJoCo → validation.

Every stage's output is written into a temporary sibling of the results folder, which replaces the
results folder only when the run finished: a run that fails never leaves a half-written folder.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Literal

import numpy as np
from tqdm import tqdm

from planning.applicator import Applicator
from planning.atomic_io import atomic_write_text
from planning.errors import PaintcellError
from planning.plan import CoveragePlan
from planning.surface import Surface
from sim.scenario import Scenario, ScenarioError

STAGES = ("surface", "plan", "trajectory", "execute", "validate", "report")


@dataclass
class RunResult:
    """What a scenario run produced (objects in memory and the folder they were written to)."""

    scenario: Scenario
    out_dir: Path | None
    surface: Surface
    plan: CoveragePlan
    trajectory: Any
    trace: Any
    report: Any
    timings_s: dict[str, float] = field(default_factory=dict)
    fast: bool = False
    mode: str = "servo"

    @property
    def passed(self) -> bool:
        """True when every threshold of the scenario is met."""
        return bool(self.report.passed)


def load_surface(scn: Scenario, fast: bool = False) -> Surface:
    """The scenario's part surface in the part frame, at the full or fast resolution."""
    from planning import parts

    res = scn.fast_resolution_m if fast else scn.resolution_m
    if scn.part in parts.PART_NAMES:
        return parts.get_part(scn.part, resolution_m=res)
    mesh_path = Path(scn.part)
    if not mesh_path.is_absolute() and scn.source:
        mesh_path = Path(scn.source).parent / mesh_path
    if not mesh_path.exists():
        raise PaintcellError(f"part {scn.part!r} is neither a library part "
                             f"({', '.join(parts.PART_NAMES)}) nor an existing mesh file")
    return Surface.from_mesh(mesh_path)


def load_applicator(scn: Scenario) -> Applicator:
    """The scenario's applicator (TOML path relative to the script) or the default bell."""
    if scn.applicator is None:
        return Applicator.default()
    path = Path(scn.applicator)
    if not path.is_absolute() and scn.source:
        path = Path(scn.source).parent / path
    return Applicator.from_toml(path)


def settings_from(cls: type, values: dict[str, Any], what: str) -> Any:
    """An instance of the settings dataclass `cls` from a scenario's dict, with a clear error
    naming the valid keys when one is misspelt."""
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - names)
    if unknown:
        raise ScenarioError(f"unknown {what} setting(s) {unknown}; valid: {sorted(names)}")
    return cls(**values)


def planner_settings(scn: Scenario, fast: bool = False) -> Any:
    """`PlannerSettings` of the scenario (with the fast overrides when `fast`)."""
    from planning.coverage import PlannerSettings

    kw = dict(scn.planner)
    if fast:
        kw.update(scn.fast_planner)
    return settings_from(PlannerSettings, kw, "planner")


def make_plan(scn: Scenario, surface: Surface, fast: bool = False) -> CoveragePlan:
    """Run the coverage planner for the scenario."""
    from planning.coverage import plan_coverage

    return plan_coverage(surface, load_applicator(scn), planner_settings(scn, fast))


def load_robot_for(scn: Scenario) -> Any:
    """The scenario's robot at its base pose."""
    from robots import load_robot

    return load_robot(scn.robot, T_world_base=scn.base.matrix)


def make_trajectory(scn: Scenario, robot: Any, plan: CoveragePlan) -> Any:
    """IK + TOPP-RA + ruckig: the joint program for the plan at the scenario placement."""
    from sim.trajectory import TrajectorySettings, build_program

    return build_program(robot, plan, scn.part_placement.matrix,
                         settings_from(TrajectorySettings, scn.trajectory, "trajectory"))


#: Files that mark a folder as paintcell results (only such a folder may be replaced).
RESULT_MARKERS = ("scenario.json", "metrics.json")


def check_out_dir(out_dir: Path) -> None:
    """Refuse to replace an existing folder that is not empty and not paintcell results."""
    if out_dir.exists():
        if not out_dir.is_dir():
            raise PaintcellError(f"--out {out_dir} is a file; give a folder for the results")
        if any(out_dir.iterdir()) and not any((out_dir / m).exists() for m in RESULT_MARKERS):
            raise PaintcellError(f"--out {out_dir} exists and is not a paintcell results folder "
                                 "(no scenario.json); choose another folder or empty it")


@contextmanager
def staged_dir(out_dir: Path | None) -> Iterator[Path | None]:
    """Yield a temporary folder that replaces `out_dir` when the block succeeds.

    Only an empty folder or an earlier paintcell results folder is replaced (`check_out_dir`).
    """
    if out_dir is None:
        yield None
        return
    out_dir = Path(out_dir)
    check_out_dir(out_dir)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out_dir.parent, prefix=f".{out_dir.name}.tmp-"))
    mask = os.umask(0)
    os.umask(mask)
    tmp.chmod(0o777 & ~mask)  # mkdtemp makes 0700; results are meant to be shared
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if out_dir.exists():
        old = out_dir.parent / f".{out_dir.name}.old-{time.time_ns()}"
        out_dir.rename(old)
    tmp.rename(out_dir)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def run_scenario(scn: Scenario, out_dir: str | Path | None = None, *, fast: bool = False,
                 mode: Literal["servo", "kinematic"] = "servo", report: bool = True,
                 progress: bool = True) -> RunResult:
    """Run the scenario end to end; write its results into `out_dir` (atomically) if given.

    fast: coarse resolution and the scenario's fast planner overrides (CI checks).
    mode: "servo" (PD + inverse dynamics) or "kinematic" (ideal replay) execution.
    report: also write plots, renders and `report.html`.
    """
    timings: dict[str, float] = {}
    # disable=None: tqdm draws only on a terminal, so CI logs and pipes stay clean.
    bar = tqdm(total=len(STAGES), desc=f"{scn.name}", unit="stage",
               disable=None if progress else True, leave=False)
    try:
        return _run(scn, out_dir, fast, mode, report, bar, timings)
    finally:
        bar.close()


def _run(scn: Scenario, out_dir: str | Path | None, fast: bool,
         mode: Literal["servo", "kinematic"], report: bool,
         bar: tqdm, timings: dict[str, float]) -> RunResult:
    from sim.cell import build_cell
    from sim.execute import execute
    from sim.validate import validate

    def stage(name: str) -> None:
        bar.set_postfix_str(name)

    def done(name: str, t0: float) -> None:
        timings[name] = time.perf_counter() - t0
        bar.update(1)

    with staged_dir(Path(out_dir) if out_dir is not None else None) as tmp:
        t0 = time.perf_counter()
        stage("surface")
        surface = load_surface(scn, fast)
        done("surface", t0)

        t0 = time.perf_counter()
        stage("plan")
        plan = make_plan(scn, surface, fast)
        done("plan", t0)

        t0 = time.perf_counter()
        stage("trajectory")
        robot = load_robot_for(scn)
        traj = make_trajectory(scn, robot, plan)
        traj.meta["plan_digest"] = plan.content_digest()
        done("trajectory", t0)

        t0 = time.perf_counter()
        stage("execute")
        T_world_part = scn.part_placement.matrix
        cell = build_cell(robot, surface, T_world_part)
        trace = execute(cell, traj, mode=mode, servo=_servo(scn),
                        disturbances=_disturbances(scn))
        trace.meta["plan_digest"] = traj.meta["plan_digest"]
        done("execute", t0)

        t0 = time.perf_counter()
        stage("validate")
        rep = validate(plan, surface, traj, trace, T_world_part, scn.thresholds,
                       reachability=traj.meta.get("reachability"))
        done("validate", t0)

        result = RunResult(scn, None, surface, plan, traj, trace, rep, timings, fast, mode)
        if tmp is not None:
            t0 = time.perf_counter()
            stage("report")
            write_results(result, tmp, cell=cell if report else None)
            done("report", t0)
            result.out_dir = Path(out_dir)  # type: ignore[arg-type]
        else:
            bar.update(1)
    return result


def _servo(scn: Scenario) -> Any:
    from sim.execute import ServoSettings

    return settings_from(ServoSettings, scn.servo, "servo")


def _disturbances(scn: Scenario) -> Any:
    from sim.execute import Disturbances

    return settings_from(Disturbances, scn.disturbances, "disturbances") \
        if scn.disturbances else None


def scenario_json(scn: Scenario, fast: bool, mode: str) -> str:
    """`scenario.json`: the scenario and how it was run (what later stages need to reload it)."""
    return json.dumps({**scn.to_dict(), "run": {"fast": fast, "mode": mode}}, indent=2)


def metrics_dict(result: RunResult) -> dict[str, Any]:
    """`metrics.json` content: the validation report plus scenario, plan and timing context."""
    d = dict(result.report.to_dict())
    plan = result.plan
    d["scenario"] = {"name": result.scenario.name, "part": result.scenario.part,
                     "robot": result.scenario.robot, "source": result.scenario.source}
    d["plan_summary"] = {
        "passes": len(plan.passes),
        "start_rule": plan.start_rule,
        "index_widths_m": [None if not np.isfinite(w) else float(w)
                           for w in plan.index_widths_m],
        "paint_time_s": plan.paint_time_s,
        "settings": plan.settings,
    }
    d["stage_times_s"] = dict(result.timings_s)
    d["run"] = {"fast": result.fast, "mode": result.mode}
    return d


def write_results(result: RunResult, out: Path, cell: Any = None) -> None:
    """Write plan, trajectory, trace, metrics (and report files when `cell` is given) into `out`."""
    result.plan.save(out / "plan.json")
    result.trajectory.save_npz(out / "trajectory.npz")
    result.trajectory.save_csv(out / "trajectory.csv")
    result.trace.save_npz(out / "trace.npz")
    atomic_write_text(out / "scenario.json", scenario_json(result.scenario, result.fast,
                                                           result.mode))
    atomic_write_text(out / "metrics.json", json.dumps(metrics_dict(result), indent=2,
                                                       default=json_default))
    if cell is not None:
        from sim.report import make_figures, write_report

        make_figures(out, surface=result.surface, plan=result.plan, trajectory=result.trajectory,
                     trace=result.trace, report=result.report, cell=cell)
        write_report(out)


def json_default(o: Any) -> Any:
    """`json.dumps` default for numpy scalars and arrays."""
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serializable: {type(o).__name__}")
