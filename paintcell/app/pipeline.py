"""The end-to-end run of one scenario: surface → plan → IK + trajectory → MuJoCo → validation.

Every stage's output is written into a temporary sibling of the results folder, which replaces the
results folder only when the run finished (`paintcell.core.results_dir`: ownership marker,
writer lock, atomic swap): a run that fails or is interrupted never leaves a half-written folder.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from tqdm import tqdm

from paintcell.app.scenario import Scenario
from paintcell.core.atomic_io import atomic_write_text
from paintcell.core.errors import PaintcellError, ScenarioError
from paintcell.core.interrupts import raise_if_interrupted
from paintcell.core.json_values import json_default
from paintcell.core.results_dir import new_results
from paintcell.core.settings import settings_from
from paintcell.coverage.plan import CoveragePlan
from paintcell.paint.applicator import Applicator
from paintcell.surface.part_spec import MeshPart
from paintcell.surface.part_surface import part_surface
from paintcell.surface.surface_data import Surface

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
    return part_surface(scn.part, scn.fast_resolution_m if fast else scn.resolution_m,
                        scn.source, "fast_resolution_m" if fast else "resolution_m")


def load_applicator(scn: Scenario) -> Applicator:
    """The scenario's applicator (TOML path relative to the scenario file) or the default bell."""
    if scn.applicator is None:
        return Applicator.default()
    path = Path(scn.applicator)
    if not path.is_absolute() and scn.source:
        path = Path(scn.source).parent / path
    try:
        return Applicator.from_toml(path)
    except UnicodeDecodeError as exc:
        raise PaintcellError(f"applicator {path} is not a UTF-8 TOML file ({exc.reason})") \
            from exc
    except PaintcellError as exc:
        msg = str(exc)
        raise type(exc)(msg if str(path) in msg else f"applicator {path}: {msg}") from exc


def planner_settings(scn: Scenario, fast: bool = False) -> Any:
    """`PlannerSettings` of the scenario (with the fast overrides when `fast`)."""
    from paintcell.coverage.coverage_settings import PlannerSettings

    kw = dict(scn.planner)
    if fast:
        kw.update(scn.fast_planner)
    return settings_from(PlannerSettings, kw, "planner")


def make_plan(scn: Scenario, surface: Surface, fast: bool = False) -> CoveragePlan:
    """Run the coverage planner for the scenario."""
    from paintcell.core.budget import check_profile_budget
    from paintcell.coverage.algorithm import plan_coverage
    from paintcell.coverage.index_width import profile_size

    app = load_applicator(scn)
    check_profile_budget(*profile_size(app), app.footprint_radius_m,
                         scn.applicator or "the default bell")
    # A real part's planner covers its skin (hems, inner panels stay in the surface for the film).
    return plan_coverage(surface.region_surface(("skin",)), app, planner_settings(scn, fast))


def load_robot_for(scn: Scenario) -> Any:
    """The scenario's robot at its base pose."""
    from paintcell.robots import load_robot

    return load_robot(scn.robot, T_world_base=scn.base.matrix)


def make_trajectory(scn: Scenario, robot: Any, plan: CoveragePlan) -> Any:
    """IK + TOPP-RA + ruckig: the joint program for the plan at the scenario placement."""
    from paintcell.motion.trajectory import TrajectorySettings, build_program

    return build_program(robot, plan, scn.part_placement.matrix,
                         settings_from(TrajectorySettings, scn.trajectory, "trajectory"))


def run_scenario(scn: Any, out_dir: str | Path | None = None, *, fast: bool = False,
                 mode: Literal["servo", "kinematic"] = "servo", report: bool = True,
                 progress: bool = True, video: bool = False, tasks: Any = None) -> Any:
    """Run the scenario end to end; write its results into `out_dir` (atomically) if given.

    fast: coarse resolution and the scenario's fast planner overrides (CI checks).
    mode: "servo" (PD + inverse dynamics) or "kinematic" (ideal replay) execution.
    report: also write plots, renders and `report.html`.
    video: with `report`, also render the execution GIF and embed it in `report.html` (MBs).
    A `paintcell.booth.booth.Booth` (several robots) runs through
    `paintcell.booth.booth_run.run_booth` (its report is always written; it renders no video:
    `video` is refused) and returns its `BoothResult`; `tasks` (a
    `paintcell.booth.booth_tasks.TaskPool`, e.g. Dask workers) plans its parts and builds its
    robots' programs at once (the same results).
    """
    from paintcell.booth.booth import Booth

    if isinstance(scn, Booth):   # several robots: one cell of N robots on a conveyor
        from paintcell.booth.booth_run import run_booth

        if video:
            raise ScenarioError(f"{scn.name} is a booth of {len(scn.robots)} robot(s): its run "
                                "renders no execution video (one is made for a one-robot cell "
                                "only); run it without --video")
        return run_booth(scn, out_dir, fast=fast, mode=mode, progress=progress,  # type: ignore
                         tasks=tasks)
    if not isinstance(scn, Scenario):
        raise ScenarioError(f"run_scenario runs a Scenario or a Booth, got {type(scn).__name__}")
    if tasks is not None:
        raise ScenarioError("run_scenario's tasks (parallel workers) plan a booth's parts and "
                            "programs; a one-robot scenario runs in this process: drop tasks")
    timings: dict[str, float] = {}
    # disable=None: tqdm draws only on a terminal, so CI logs and pipes stay clean.
    bar = tqdm(total=len(STAGES), desc=f"{scn.name}", unit="stage",
               disable=None if progress else True, leave=False)
    try:
        return _run(scn, out_dir, fast, mode, report, bar, timings, video)
    finally:
        bar.close()


def _run(scn: Scenario, out_dir: str | Path | None, fast: bool,
         mode: Literal["servo", "kinematic"], report: bool,
         bar: tqdm, timings: dict[str, float], video: bool = False) -> RunResult:
    from paintcell.execution.cell import build_cell
    from paintcell.execution.execute import execute
    from paintcell.validation.validate import start_program_films, validate

    def stage(name: str) -> None:
        raise_if_interrupted()
        bar.set_postfix_str(name)

    def done(name: str, t0: float) -> None:
        timings[name] = time.perf_counter() - t0
        bar.update(1)

    with new_results(Path(out_dir) if out_dir is not None else None, "run") as tmp:
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
        plan, traj = robot_aware_run(scn, surface, robot, plan, traj, fast)
        traj.meta["plan_digest"] = plan.content_digest()
        done("trajectory", t0)

        t0 = time.perf_counter()
        stage("execute")
        from paintcell.core.budget import check_validation_budget

        # the validation's film maps are refused before any of them starts
        check_validation_budget(len(surface.vertices), int((traj.t_s[-1] - traj.t_s[0]) / 0.005),
                                "fast_resolution_m" if fast else "resolution_m")
        T_world_part = scn.part_placement.matrix
        # The planned and time-law films do not depend on the execution: computed meanwhile, on
        # the core MuJoCo's single-threaded stepping leaves idle.
        films = start_program_films(plan, surface, traj, T_world_part)
        cell = build_cell(robot, surface, T_world_part)
        trace = execute(cell, traj, mode=mode, servo=servo_settings(scn),
                        disturbances=_disturbances(scn))
        trace.meta["plan_digest"] = traj.meta["plan_digest"]
        done("execute", t0)

        t0 = time.perf_counter()
        stage("validate")
        rep = validate(plan, surface, traj, trace, T_world_part, scn.thresholds,
                       reachability=traj.meta.get("reachability"), films=films.result(),
                       spec=scn.spec)
        done("validate", t0)

        result = RunResult(scn, None, surface, plan, traj, trace, rep, timings, fast, mode)
        if tmp is not None:
            t0 = time.perf_counter()
            stage("report")
            write_results(result, tmp, cell=cell if report else None, video=video)
            done("report", t0)
            result.out_dir = Path(out_dir)  # type: ignore[arg-type]
        else:
            bar.update(1)
    return result


def robot_aware_run(scn: Any, surface: Surface, robot: Any, plan: CoveragePlan, traj: Any,
                    fast: bool = False) -> tuple[CoveragePlan, Any]:
    """Robot-aware speeds (`paintcell.motion.speed_feedback.robot_aware_plan`) with the
    scenario's applicator,
    planner settings and trajectory builder; the rounds are recorded in the program's
    meta["speed_feedback"]."""
    from paintcell.motion.speed_feedback import robot_aware_plan

    # the planner covers a real part's skin (as `paintcell.app.pipeline.make_plan` does)
    res = robot_aware_plan(surface.region_surface(("skin",)), load_applicator(scn),
                           planner_settings(scn, fast), plan, traj,
                           lambda p: make_trajectory(scn, robot, p),
                           T_world_part=scn.part_placement.matrix)
    res.trajectory.meta["speed_feedback"] = {
        "rounds": res.rounds,
        "capped_passes": sorted(int(k) for k in res.caps_m_s),
        "capped_samples": int(sum(int(np.sum(v < np.inf)) for v in res.caps_m_s.values())),
    }
    return res.plan, res.trajectory


def servo_settings(scn: Scenario) -> Any:
    """The scenario's servo settings (`[servo]` table) as `ServoSettings`."""
    from paintcell.execution.execute import ServoSettings

    return settings_from(ServoSettings, scn.servo, "servo")


def _disturbances(scn: Scenario) -> Any:
    from paintcell.execution.execute import Disturbances

    return settings_from(Disturbances, scn.disturbances, "disturbances") \
        if scn.disturbances else None


def scenario_json(scn: Any, fast: bool, mode: str) -> str:
    """`scenario.json`: the scenario as data (a snapshot that `validate`, `export` and `report`
    read instead of the scenario file, which may have changed or gone) and how it was run; a
    booth's snapshot for a `paintcell.booth.booth.Booth`."""
    from paintcell.booth.booth import Booth

    if isinstance(scn, Booth):
        from paintcell.booth.booth_data import booth_snapshot

        d = booth_snapshot(scn, {"fast": fast, "mode": mode})
    else:
        from paintcell.app.scenario_data import snapshot_dict

        d = {**snapshot_dict(scn), "run": {"fast": fast, "mode": mode}}
    return json.dumps(d, indent=2, default=json_default)


def cell_plans(scn: Any, fast: bool = False) -> dict[str, CoveragePlan]:
    """The plans of a scenario's cell, by file stem: a one-robot scenario's `plan` (its part's
    surface, `make_plan`); a booth's `plan_<part index>` for each part, as its robots get them
    before allocation (planned, reversed where asked, one film build, seams blended:
    `paintcell.booth.booth_plans`)."""
    from paintcell.booth.booth import Booth

    if isinstance(scn, Booth):
        from paintcell.booth.booth_plans import finish_plans, plan_parts

        pp = plan_parts(scn, fast)
        return {f"plan_{i}": pl for i, pl in enumerate(finish_plans(scn, pp, pp.plans).plans)}
    return {"plan": make_plan(scn, load_surface(scn, fast), fast)}


def metrics_dict(result: RunResult) -> dict[str, Any]:
    """`metrics.json` content: the validation report plus scenario, plan and timing context."""
    d = dict(result.report.to_dict())
    plan = result.plan
    part = result.scenario.part
    d["scenario"] = {"name": result.scenario.name,
                     "part": part.to_dict() if isinstance(part, MeshPart) else part,
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


def write_results(result: RunResult, out: Path, cell: Any = None, video: bool = False) -> None:
    """Write plan, trajectory, trace, metrics, the film (`film.npz`, `film.glb`) and, when `cell`
    is given, the report files (the execution GIF too with `video`) into `out`."""
    result.plan.save(out / "plan.json")
    result.trajectory.save_npz(out / "trajectory.npz")
    result.trajectory.save_csv(out / "trajectory.csv")
    result.trace.save_npz(out / "trace.npz")
    atomic_write_text(out / "scenario.json", scenario_json(result.scenario, result.fast,
                                                           result.mode))
    atomic_write_text(out / "metrics.json", json.dumps(metrics_dict(result), indent=2,
                                                       default=json_default))
    from paintcell.output.gltf_film import write_film_files

    write_film_files(out, *run_film(result.scenario, result.surface, result.plan, result.report))
    if cell is not None:
        from paintcell.output.report import write_report
        from paintcell.output.report_figures import make_figures

        make_figures(out, surface=result.surface, plan=result.plan, trajectory=result.trajectory,
                     trace=result.trace, report=result.report, cell=cell, video=video)
        write_report(out, video=video)


def run_film(scn: Scenario, surface: Surface, plan: CoveragePlan, report: Any
             ) -> tuple[Any, Any]:
    """A one-robot run's film (`paintcell.output.report_film.FilmData`: the arrays and the spec
    window) and its 3-D scene (`paintcell.output.gltf_film.FilmScene`: the part with the film,
    the passes and the robot base), for `paintcell.output.gltf_film.write_film_files`."""
    from paintcell.output.gltf_film import run_film_scene
    from paintcell.output.report_film import film_data

    film = film_data(surface, report)
    return film, run_film_scene(surface, film, plan, scn.part_placement.matrix, scn.robot,
                                scn.base.matrix)

