"""What a booth run builds before it executes: the parts' plans (common film build, blended
seams), the allocation of passes to robots, each robot's program, staggered starts and conveyor
tracking (`booth_programs` -> `BoothPrograms`; `paintcell.booth.booth_run.run_booth` and
`paintcell.sweeps.sweep_worker`
execute them).
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from paintcell.booth.booth import (
    Booth,
    BoothError,
    Job,
    arm_points,
    estimate_s,
    pass_feasible,
    patch_pass_counts,
    rank_allocations,
)
from paintcell.booth.booth_chain import job_record
from paintcell.booth.booth_hold import delayed, held_to
from paintcell.booth.booth_job_programs import body_probe, load_robots, robot_programs
from paintcell.booth.booth_plans import PartPlans, finish_plans, plan_parts
from paintcell.booth.booth_stagger import stagger_starts
from paintcell.booth.conveyor import ConveyorError, track_program
from paintcell.core.errors import PaintcellError
from paintcell.coverage.plan import CoveragePlan
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.motion.speed_feedback import CellPrograms, robot_aware_parts
from paintcell.surface.surface_data import Surface

#: allocations tried, best first, before giving up (their programs are cached per robot and job).
MAX_ALLOCATIONS_TRIED = 8
#: how much shorter than its estimate (`paintcell.booth.booth.estimate_s`) a job's built
#: program may be, as a fraction of the estimate, when `_choose` skips a candidate on estimates
#: (measured: 25.47 s estimated, 25.03 s built, 1.7 %; the estimate's fixed turn-around and
#: approach/retract times are not a lower bound).
ESTIMATE_MARGIN = 0.10


@dataclass
class BoothPrograms:
    """What a booth run builds before it executes (`booth_programs`); a sweep
    (`paintcell.sweeps.sweep_worker`)
    builds it once and executes it under many disturbances.

    surfaces: the parts' surfaces (part frames); body: their merge in the body frame;
    T_body_parts: (4, 4) part placements in the body frame; jobs: robot index → its jobs;
    record: the allocation record; static: each robot's own program (static cell, not delayed);
    trajs: the programs delayed, padded to one clock and tracking the conveyor; t_ref_s: when the
    body passes its nominal placement [s]; robots: the loaded robot models (None once sent to a
    worker, which loads its own); film_build, seams: the records of
    `paintcell.booth.booth_build` and
    `paintcell.booth.booth_seams` (the plans already carry their effect).
    """

    surfaces: list[Surface]
    body: Surface
    plans: list[CoveragePlan]
    T_body_parts: list[np.ndarray]
    jobs: dict[int, tuple[Job, ...]]
    record: dict[str, Any]
    static: list[JointTrajectory]
    trajs: list[JointTrajectory]
    t_ref_s: float
    robots: list[Any] | None
    timings_s: dict[str, float] = field(default_factory=dict)
    film_build: dict[str, Any] = field(default_factory=dict)
    """How each part's flow was scaled to the common film build
    (`paintcell.booth.booth_build`)."""
    seams: dict[str, Any] = field(default_factory=dict)
    """How the seams between parts were blended (`paintcell.booth.booth_seams`)."""


def booth_programs(booth: Booth, fast: bool, part_plans: PartPlans | None = None,
                   tasks: Any = None) -> BoothPrograms:
    """Plans, allocation, each robot's program, staggering and conveyor tracking (module doc).
    part_plans: the parts as `plan_parts(booth, fast)` plans them, when already made (`paintcell
    init` checks several robot layouts of one plan). tasks: a
    `paintcell.booth.booth_tasks.TaskPool` that plans the parts, builds each allocation's
    robot programs and re-plans the robot-aware capped parts at once (None: in this process;
    the same plans and programs, `paintcell.core.tasks` says when bit for bit)."""
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    if part_plans is not None:
        pp = part_plans
    else:
        pp = plan_parts(booth, fast) if tasks is None else plan_parts(booth, fast, tasks)
    fin = finish_plans(booth, pp, pp.plans)
    surfaces, T_body_parts, body = pp.surfaces, pp.T_body_parts, fin.body
    T_wb = booth.body_placement.matrix
    robots = load_robots(booth)
    counts = tuple(len(x.vertices) for x in surfaces)
    probes = None if booth.body_clearance_m is None else \
        body_probes(booth, robots, body, counts, on_demand=tasks is not None)
    remote_of = None if tasks is None else _remote_programs(tasks, booth, body, counts,
                                                            probes is not None)
    timings["plan"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    ranked, record = _allocate(booth, robots, fin.plans, T_wb, T_body_parts)
    # Rail robots place their carriage for each pass inside a range shrunk by the travel the
    # conveyor tracking will add (half the line travel over the estimated cycle, +25 %); if the
    # staggered cycle came out longer and the tracking leaves a rail, once more with its cycle.
    shrink = 0.5 * booth.conveyor.speed_m_s * record.get("estimated_cycle_s", 0.0) * 1.25
    speeds: dict[str, Any] = {"rule": "off"}
    for attempt in range(2):
        built = CellPrograms(*_choose(booth, robots, fin.plans, ranked, T_wb, T_body_parts,
                                      shrink, probes, remote_of))
        if attempt == 0 and booth.robot_aware_speeds:
            def rebuild(pls: list[CoveragePlan], jobs: Any = built.jobs,
                        shrink_m: float = shrink) -> CellPrograms:
                return CellPrograms(*_choose(booth, robots, pls, [jobs], T_wb, T_body_parts,
                                             shrink_m, probes, remote_of))

            tried0 = built.tried          # the candidates of the allocation, as chosen
            fin, built, speeds = robot_aware_parts(
                [bp.part for bp in booth.parts], [bp.reverse for bp in booth.parts], pp, fin,
                built, lambda pls, caps: finish_plans(booth, pp, pls, caps), rebuild,
                pool=tasks, max_cycle_s=booth.thresholds.max_cycle_time_s)
            built.tried = tried0
        jobs, static, trajs0, tried = built.jobs, built.static, built.trajs, built.tried
        K = max(len(tr.t_s) for tr in trajs0)
        dt = trajs0[0].dt_s
        t_ref = 0.5 * (K - 1) * dt
        try:
            trajs = [track_program(r, held_to(tr, K), booth.conveyor, t_ref)
                     for r, tr in zip(robots, trajs0, strict=True)]
            break
        except ConveyorError:
            need = 0.5 * booth.conveyor.speed_m_s * (K - 1) * dt * 1.25
            if attempt == 1 or need <= shrink:
                raise
            shrink = need
    record["tried"] = tried
    record["rejected"] = [t for t in tried if "rejected" in t]
    record["chosen"] = {booth.robots[r].name: job_record(js) for r, js in jobs.items()}
    record["transfer_moves_s"] = {booth.robots[r].name: tr.meta["transfer_moves_s"]
                                  for r, tr in enumerate(static) if "transfer_moves_s" in tr.meta}
    record["start_delays_s"] = [float(tr.meta.get("start_delay_s", 0.0)) for tr in trajs0]
    record["rail_tracking_margin_m"] = shrink
    record["film_refine"] = fin.refine
    record["speed_feedback"] = speeds
    record["body_clearance"] = {booth.robots[r].name: tr.meta.get("body_clearance")
                                for r, tr in enumerate(static)}
    timings["trajectory"] = time.perf_counter() - t0
    return BoothPrograms(surfaces, body, fin.plans, T_body_parts, jobs, record, static, trajs,
                         t_ref, robots, timings, fin.film_build, fin.seams)


def _choose(booth: Booth, robots: list[Any], plans: list[CoveragePlan],
            ranked: list[dict[int, tuple[Job, ...]]], T_wb: np.ndarray, T_bp: list[np.ndarray],
            shrink_m: float, probes: Any = None,
            remote_of: Callable[[list[CoveragePlan], float], Any] | None = None
            ) -> tuple[dict[int, tuple[Job, ...]], list[JointTrajectory], list[JointTrajectory],
                       list[dict[str, Any]]]:
    """The allocation of the best ranked with the shortest REAL cycle (rails
    shrunk by shrink_m at both ends for the passes): its jobs, static programs, staggered
    programs and the record of every one tried.

    The ranking's cycle is an estimate (paint time + fixed turn-around and approach times, no
    start delays); the real one is the staggered programs' clock — max over the robots of start
    delay + own program — which a robot held back for a neighbour's retract can make much longer
    than estimated. So every candidate of the ranking whose programs can be built and staggered
    is built (programs are cached per robot and job) and the shortest real cycle is taken (ties:
    the better ranked). A candidate is not built when one of its robots' programs is already no
    shorter than the best real cycle: its jobs' programs as built when the cache holds them (no
    start delay makes a program shorter), else their estimates less ESTIMATE_MARGIN (a heuristic:
    the estimate is not a lower bound, the margin covers its measured over-estimate). One
    holding a job already refused is passed over (recorded, not counted: MAX_ALLOCATIONS_TRIED
    counts the others). probes:
    per robot, its `paintcell.booth.booth_clearance.BodyProbe` (None: no body clearance).
    remote_of(plans, shrink_m): the `paintcell.booth.booth_tasks.JobPrograms` that builds the
    programs of each allocation tried on a pool, all its robots' jobs at once (None: here)."""
    planners = load_robots(booth, shrink_m, stretch=True) \
        if shrink_m > 0 or any(r.carriage_m is not None for r in booth.robots) else robots
    remote = None if remote_of is None else remote_of(plans, shrink_m)
    cache: dict[tuple[int, Job], JointTrajectory | PaintcellError] = {}
    chained: dict[tuple[int, tuple[Job, ...]], int] = {}   # a robot's jobs as built [samples]
    tried: list[dict[str, Any]] = []
    best: tuple[int, dict[int, tuple[Job, ...]], list[JointTrajectory], list[int]] | None = None
    n_tried = 0
    for rank, jobs in enumerate(ranked):
        if n_tried == MAX_ALLOCATIONS_TRIED:
            break
        names = {booth.robots[r].name: job_record(js) for r, js in jobs.items()}
        known = next((got for r, js in jobs.items() for j in js
                      if isinstance(got := cache.get((r, j)), PaintcellError)), None)
        if known is not None:      # a job already refused: not built again, not counted
            tried.append({"rank": rank + 1, "jobs": names, "rejected": str(known),
                          "known_failure": True})
            continue
        n_tried += 1
        if best is not None:
            dt = best[2][0].dt_s
            longest = _longest_program_s(jobs, cache, plans, dt, chained)
            if longest >= (best[0] - 1) * dt:
                tried.append({"rank": rank + 1, "jobs": names,
                              "skipped": f"its longest program ({longest:.2f} s: built, or "
                                         f"estimated less {ESTIMATE_MARGIN:.0%}) is no shorter "
                                         "than the best real cycle"})
                continue
        try:
            trajs0 = robot_programs(booth, planners, plans, jobs, T_wb, T_bp, cache, probes,
                                    remote)
            chained.update({(r, jobs[r]): len(tr.t_s) for r, tr in enumerate(trajs0)})
            delays = start_delays(booth, robots, trajs0)
        except PaintcellError as exc:   # an unbuildable program, arms that cannot be kept apart
            tried.append({"rank": rank + 1, "jobs": names, "rejected": str(exc)})
            continue
        K = max(len(tr.t_s) + d for tr, d in zip(trajs0, delays, strict=True))
        dt = trajs0[0].dt_s
        tried.append({"rank": rank + 1, "jobs": names, "real_cycle_s": (K - 1) * dt,
                      "start_delays_s": [d * dt for d in delays],
                      "programs_s": [float(tr.duration_s) for tr in trajs0]})
        if best is None or K < best[0]:
            best = (K, jobs, list(trajs0), delays)
    if best is None:
        why = "; ".join(f"#{t['rank']}: {t['rejected'].split('; ')[0]}" for t in tried
                        if not t.get("known_failure"))
        if booth.allocation is not None:     # the user's pass ranges: say so, not "move"
            raise BoothError(f"the fixed [allocation] does not work ({why}); its pass ranges "
                             "name passes of the plan at this resolution (`--fast` plans at "
                             "fast_resolution_m): check them, or drop [allocation]")
        raise BoothError(f"none of the {len(tried)} best allocations works ({why}); move the "
                         "robots")
    _, jobs, trajs0, delays = best
    # static: the programs as the robots' controllers run them (RAPID)
    return jobs, trajs0, [delayed(tr, d) for tr, d in zip(trajs0, delays, strict=True)], tried


def _longest_program_s(jobs: dict[int, tuple[Job, ...]],
                       cache: dict[tuple[int, Job], JointTrajectory | PaintcellError],
                       plans: list[CoveragePlan], dt_s: float,
                       chained: dict[tuple[int, tuple[Job, ...]], int] | None = None) -> float:
    """A candidate's longest robot program [s] for `_choose`'s skip: a robot's jobs as built
    together when `chained` holds them (the moves between jobs included) [samples], else each
    job's program as built when the cache holds it, else its estimate less ESTIMATE_MARGIN."""
    chained = chained or {}

    def job_s(r: int, j: Job) -> float:
        got = cache.get((r, j))
        if isinstance(got, JointTrajectory):
            return (len(got.t_s) - 1) * dt_s
        return (1.0 - ESTIMATE_MARGIN) * estimate_s(np.array(
            [ps.duration_s for ps in plans[j.part].passes[j.first:j.end]]))

    return max((chained[(r, js)] - 1) * dt_s if (r, js) in chained
               else sum(job_s(r, j) for j in js) for r, js in jobs.items())


def body_probes(booth: Booth, robots: list[Any], body: Surface, part_counts: tuple[int, ...],
                on_demand: bool = False) -> Any:
    """Per robot (indexed), its `paintcell.booth.booth_clearance.BodyProbe` of the whole body
    (`booth_job_programs.body_probe`); on_demand: each built when first asked for (a run whose
    programs are built on workers asks here only for a robot with several jobs)."""
    if not on_demand:
        return [body_probe(booth, r, body, part_counts) for r in robots]
    return _OnDemand(lambda i: body_probe(booth, robots[i], body, part_counts))


class _OnDemand:
    """make(i) for index i, made on first use and kept."""

    def __init__(self, make: Callable[[int], Any]) -> None:
        self._make = make
        self._made: dict[int, Any] = {}

    def __getitem__(self, i: int) -> Any:
        if i not in self._made:
            self._made[i] = self._make(i)
        return self._made[i]


def _remote_programs(tasks: Any, booth: Booth, body: Surface, part_counts: tuple[int, ...],
                     probes: bool) -> Callable[[list[CoveragePlan], float], Any]:
    """`_choose`'s remote_of on the pool `tasks`: the body sent once, one key for the run."""
    from paintcell.booth.booth_tasks import JobPrograms, new_run_key

    key, shared = new_run_key(), tasks.share(body)

    def remote_of(plans: list[CoveragePlan], shrink_m: float) -> JobPrograms:
        return JobPrograms(tasks, key, booth, shared, part_counts, plans, shrink_m, probes)

    return remote_of


def _allocate(booth: Booth, robots: list[Any], plans: list[CoveragePlan], T_wb: np.ndarray,
              T_bp: list[np.ndarray]) -> tuple[list[dict[int, tuple[Job, ...]]], dict[str, Any]]:
    if booth.allocation is not None:
        names = [r.name for r in booth.robots]
        jobs = {}
        for rname, v in booth.allocation.items():
            if rname not in names:
                raise BoothError(f"allocation names robot {rname!r}; robots are {names}")
            triples = v if v and isinstance(v[0], (list, tuple)) else [v]
            jobs[names.index(rname)] = tuple(Job(int(p), int(a), int(b)) for p, a, b in triples)
        return [jobs], {"rule": "fixed in the booth script"}
    cache: dict[tuple[int, int, int], bool] = {}

    def pass_ok(r: int, p: int, i: int) -> bool:
        if (r, p, i) not in cache:
            T = T_wb @ T_bp[p] @ plans[p].tcp_frames(i)
            cache[(r, p, i)] = pass_feasible(robots[r], T)
        return cache[(r, p, i)]

    def reachable(r: int, job: Job) -> bool:
        allowed = booth.parts[job.part].robots
        if allowed is not None and booth.robots[r].name not in allowed:
            return False
        return all(pass_ok(r, job.part, i) for i in range(job.first, job.end))

    durations = [np.array([ps.duration_s for ps in pl.passes]) for pl in plans]
    return rank_allocations(len(robots), [len(pl.passes) for pl in plans], durations,
                            reachable, booth.max_jobs_per_robot,
                            [patch_pass_counts(pl) for pl in plans])


def start_delays(booth: Booth, robots: list[Any], trajs: list[JointTrajectory]) -> list[int]:
    """Start delays [samples] of `paintcell.booth.booth_stagger.stagger_starts` (none
    without a clearance limit)."""
    if booth.thresholds.min_bell_distance_m is None:
        return [0] * len(trajs)
    sub = max(1, int(round(0.02 / trajs[0].dt_s)))    # arm points every 20 ms
    pts = [arm_points(r, tr.q[::sub]) for r, tr in zip(robots, trajs, strict=True)]
    try:
        delays = stagger_starts(pts, sub * trajs[0].dt_s, booth.thresholds.min_bell_distance_m)
    except BoothError as exc:          # name the robots, not their indices
        msg = re.sub(r"robot (\d+)'s", lambda m: f"robot {booth.robots[int(m[1])].name!r}'s",
                     str(exc))
        raise BoothError(msg) from exc
    return [sub * d for d in delays]
