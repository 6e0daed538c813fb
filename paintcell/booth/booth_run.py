"""Run a `paintcell.booth.booth.Booth` end to end: plans, allocation, programs, conveyor
tracking, one MuJoCo booth with every robot at once, the film in the body frame, per-robot credit.

Films (all on the merged body surface, in the body frame; the body's film is the sum of the
robots' films):
- plan: each robot's passes at planned timing;
- trajectory: each robot's reference TCP (its tracked program, ideal kinematics) relative to
  the body where the conveyor nominally puts it;
- servo: the executed TCP relative to that nominal body position (the robots' servo error only);
- executed: the executed TCP relative to where the carrier really was (MuJoCo's carrier joint).
So loss = executed − plan σ/μ = time law (trajectory − plan) + servo (servo − trajectory)
+ conveyor tracking (executed − servo: the part not where the programs expect it).

The programs (plans, allocation, staggering, tracking) are built by
`paintcell.booth.booth_programs`; its
public names are re-exported here.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import mujoco
import numpy as np

from paintcell.booth.booth import Booth, Job
from paintcell.booth.booth_cell import BoothCell, build_booth_cell
from paintcell.booth.booth_film import booth_disturbances, judged_body_mask, robot_films
from paintcell.booth.booth_programs import booth_programs
from paintcell.coverage.plan import CoveragePlan
from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.surface.surface_data import Surface
from paintcell.validation.painted_side import parts_painted_side
from paintcell.validation.validate_motion import collision_events
from paintcell.validation.validate_report import ValidationReport

__all__ = ["BoothResult", "combined_program", "robot_tcp", "robot_traces", "run_booth"]


@dataclass
class BoothResult:
    """What a booth run produced. `report` is a `ValidationReport` (booth metrics and checks)."""

    scenario: Booth
    out_dir: Path | None
    surface: Surface
    plans: list[CoveragePlan]
    jobs: dict[int, tuple[Job, ...]]
    trajectories: list[JointTrajectory]
    traces: list[ExecutedTrace]
    report: ValidationReport
    films_m: dict[str, np.ndarray] = field(default_factory=dict)
    static_trajectories: list[JointTrajectory] = field(default_factory=list)
    """Each robot's own program in the static cell, before staggering and tracking."""
    timings_s: dict[str, float] = field(default_factory=dict)
    """Wall time of each stage [s] (plan, trajectory, execute, validate); on a pool of workers
    also workers_wait: of plan + trajectory, the time the client waited for the workers' tasks
    (the rest is its own work: reading parts, film refinement, seams, staggering)."""
    part_vertex_counts: list[int] = field(default_factory=list)
    """The parts' vertex counts, in the order they are stacked in `surface`."""
    judged: np.ndarray | None = None
    """(N,) bool: the body's vertices the film is judged on (None: every vertex)."""
    trace: ExecutedTrace | None = None
    """The booth's one execution: every robot's joints, then the conveyor carrier's."""
    fast: bool = False
    mode: str = "servo"

    @property
    def passed(self) -> bool:
        """Every booth threshold met."""
        return bool(self.report.passed)


def combined_program(bcell: BoothCell, trajs: list[JointTrajectory], t_ref_s: float
                     ) -> JointTrajectory:
    """One program for the whole booth cell: every robot's columns, then the carrier's."""
    t = trajs[0].t_s
    q = [tr.q for tr in trajs]
    qd = [tr.qd for tr in trajs]
    qdd = [tr.qdd for tr in trajs]
    if bcell.conveyor is not None:
        q.append(bcell.conveyor.position_m(t, t_ref_s)[:, None])
        qd.append(np.full((len(t), 1), bcell.conveyor.speed_m_s))
        qdd.append(np.zeros((len(t), 1)))
    first = trajs[0]
    a = {name: getattr(first, name) for name in JointTrajectory._ARRAYS}
    a.update(q=np.hstack(q), qd=np.hstack(qd), qdd=np.hstack(qdd),
             paint_on=np.any([tr.paint_on for tr in trajs], axis=0), flow=np.ones(len(t)))
    return JointTrajectory(**a, robot_name="booth", joint_names=bcell.cell.joint_names)


def robot_tcp(bcell: BoothCell, q_all: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per step, every robot's TCP from the booth's joint vector q_all (K, n):
    positions (R, K, 3) [m] and rotations (R, K, 3, 3) in the world (MuJoCo kinematics)."""
    m = bcell.cell.model
    d = mujoco.MjData(m)
    K, R = len(q_all), bcell.n_robots
    pos, rot = np.empty((R, K, 3)), np.empty((R, K, 3, 3))
    sites = np.asarray(bcell.tcp_site_ids)
    adr = bcell.cell.qpos_adr
    for k in range(K):
        d.qpos[adr] = q_all[k]
        mujoco.mj_kinematics(m, d)
        pos[:, k] = d.site_xpos[sites]
        rot[:, k] = d.site_xmat[sites].reshape(R, 3, 3)
    return pos, rot


def run_booth(booth: Booth, out_dir: str | Path | None = None, *, fast: bool = False,
              mode: Literal["servo", "kinematic"] = "servo", progress: bool = True,
              tasks: Any = None) -> BoothResult:
    """Run the booth (module doc); write results to `out_dir` if given. tasks: a
    `paintcell.booth.booth_tasks.TaskPool` (e.g. Dask workers) that plans the parts and builds
    the robots' programs at once (None: in this process; the results are the same)."""
    from paintcell.booth.booth_results import booth_metrics, write_booth_results
    from paintcell.core.results_dir import new_results

    waited0 = getattr(tasks, "waited_s", None)
    progs = booth_programs(booth, fast, tasks=tasks)
    timings = dict(progs.timings_s)
    if waited0 is not None:     # of plan + trajectory, the time spent waiting on the workers
        timings["workers_wait"] = tasks.waited_s - waited0
    robots = progs.robots
    assert robots is not None
    surfaces, body, plans, jobs = progs.surfaces, progs.body, progs.plans, progs.jobs
    trajs, static, t_ref = progs.trajs, progs.static, progs.t_ref_s

    t0 = time.perf_counter()
    bcell = build_booth_cell(robots, body, booth.body_placement.matrix, booth.conveyor)
    from paintcell.core.settings import settings_from
    from paintcell.execution.execute import ServoSettings, execute

    prog = combined_program(bcell, trajs, t_ref)
    trace = execute(bcell.cell, prog, mode=mode,
                    servo=settings_from(ServoSettings, booth.servo, "servo"),
                    disturbances=booth_disturbances(booth.disturbances))
    timings["execute"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    pos, rot = robot_tcp(bcell, trace.q)
    traces = robot_traces(bcell, trace, trajs, pos, rot)
    films = robot_films(booth, bcell, body, plans, jobs, progs.T_body_parts, trajs, traces, trace,
                        t_ref)
    judged = judged_body_mask(surfaces)
    report = booth_metrics(booth, bcell, body, films, static, trajs, traces, trace,
                           collision_events(trace), progs.record, jobs,
                           [len(x.vertices) for x in surfaces], plans, judged)
    report.metrics["film_build"] = progs.film_build
    report.metrics["seams"] = progs.seams
    # the mesh parts' pieces, painted and not (reported; a part's pieces are its [parts.part]
    # table's choice, as a one-robot run's [part] table's)
    report.metrics.update(parts_painted_side({f"{i}:{bp.part}": s for i, (bp, s)
                                              in enumerate(zip(booth.parts, surfaces,
                                                               strict=True))}))
    timings["validate"] = time.perf_counter() - t0
    result = BoothResult(booth, None, body, plans, jobs, trajs, traces, report, films, static,
                         timings, [len(x.vertices) for x in surfaces], judged, trace, fast, mode)
    with new_results(Path(out_dir) if out_dir is not None else None, "run") as tmp:
        if tmp is not None:
            write_booth_results(result, tmp, robots)
            result.out_dir = Path(out_dir)  # type: ignore[arg-type]
    return result


def robot_traces(bcell: BoothCell, trace: ExecutedTrace, trajs: list[JointTrajectory],
                 pos: np.ndarray, rot: np.ndarray) -> list[ExecutedTrace]:
    """Each robot's own `ExecutedTrace` cut from the booth's one trace: its joint columns, its
    TCP poses `pos` (R, K, 3) [m] and `rot` (R, K, 3, 3), its program's paint trigger and the
    contacts its bodies were in; under the trace's disturbances (`booth_film.disturbed_robot`:
    TCP offset, trigger delay, paint flow) as the one-robot execution applies them."""
    from paintcell.booth.booth_film import disturbed_robot

    out = []
    for i, (cols, tr) in enumerate(zip(bcell.columns, trajs, strict=True)):
        mine = tuple(c for c in trace.contacts
                     if bcell.robot_of_body(c.body1) == i or bcell.robot_of_body(c.body2) == i)
        p_i, on_i, brush, flow = disturbed_robot(trace, pos[i], rot[i], tr, bcell.cell)
        out.append(ExecutedTrace(
            t_s=trace.t_s, q=trace.q[:, cols], qd=trace.qd[:, cols], tau=trace.tau[:, cols],
            tcp_pos_world=p_i, tcp_rot_world=rot[i], paint_on=on_i,
            pass_index=tr.pass_index, mode=trace.mode, contacts=mine,
            meta={"robot": bcell.robots[i].name, **flow},
            tau_demand=None if trace.tau_demand is None else trace.tau_demand[:, cols],
            flow=brush))
    return out
