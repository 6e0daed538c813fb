"""Each booth robot's static program for its jobs (`booth_programs` builds them for every
allocation it tries): the booth's robot models (`load_robots`), a job's program kept clear of
the whole body (`paintcell.booth.booth_clearance`), a robot's jobs one after the other
(`paintcell.booth.booth_chain`); and a job's program as a worker of a task pool builds it
(`remote_job_program`, sent by `paintcell.booth.booth_tasks.JobPrograms`).
"""

from __future__ import annotations

import dataclasses
import threading
from typing import Any

import numpy as np

from paintcell.booth.booth import Booth, BoothError, Job
from paintcell.core.errors import PaintcellError
from paintcell.coverage.plan import CoveragePlan
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.surface.surface_data import Surface


def robot_settings(booth: Booth, i: int) -> Any:
    """Robot i's `TrajectorySettings`: the booth's `[trajectory]` with the robot's home."""
    from paintcell.core.settings import settings_from
    from paintcell.motion.trajectory import TrajectorySettings

    kw = dict(booth.trajectory)
    home = booth.robots[i].home
    if home is not None:
        kw["q_home"] = tuple(home)
    return settings_from(TrajectorySettings, kw, "trajectory")


def robot_programs(booth: Booth, robots: list[Any], plans: list[CoveragePlan],
              jobs: dict[int, tuple[Job, ...]],
              T_wb: np.ndarray, T_bp: list[np.ndarray],
              cache: dict[tuple[int, Job], JointTrajectory | PaintcellError],
              probes: Any = None, remote: Any = None) -> list[JointTrajectory]:
    """Each robot's static program for its jobs (cached per robot and job, failures too), kept
    `Booth.body_clearance_m` from the whole body (`paintcell.booth.booth_clearance`); a
    robot's jobs one after the other (`paintcell.booth.booth_chain.chain_programs`).
    remote: a `paintcell.booth.booth_tasks.JobPrograms` the jobs not in the cache are taken from
    (sent to its pool first; None: built here)."""
    from paintcell.booth.booth_chain import chain_programs

    if remote is not None:
        remote.submit({i: js for i, js in jobs.items() if js})
    out = []
    for i, (spec, robot) in enumerate(zip(booth.robots, robots, strict=True)):
        own = jobs.get(i)
        if not own:
            raise BoothError(f"robot {spec.name!r} got no job; remove it or give it one in "
                             "Booth.allocation")
        built = [_job_program(booth, i, robot, plans, job, T_wb, T_bp, cache, probes, remote)
                 for job in own]
        out.append(chain_programs(built, robot))
        if len(built) > 1 and probes is not None and booth.body_clearance_m is not None:
            _check_transfer(booth, spec.name, probes[i], out[-1])
    return out


def _job_program(booth: Booth, i: int, robot: Any, plans: list[CoveragePlan],
                 job: Job, T_wb: np.ndarray, T_bp: list[np.ndarray],
                 cache: dict[tuple[int, Job], JointTrajectory | PaintcellError],
                 probes: Any, remote: Any) -> JointTrajectory:
    """Robot i's program for one job (cached, failures too; taken from `remote` if given)."""
    if (i, job) not in cache:
        if remote is not None:
            cache[(i, job)] = remote.take(i, job)
        else:
            plan = dataclasses.replace(plans[job.part],
                                       passes=plans[job.part].passes[job.first:job.end])
            settings = robot_settings(booth, i)
            try:
                cache[(i, job)] = job_program(booth, i, robot, plan, T_wb @ T_bp[job.part],
                                              None if probes is None else probes[i], settings)
            except PaintcellError as exc:
                cache[(i, job)] = exc
    got = cache[(i, job)]
    if isinstance(got, PaintcellError):
        raise got
    return got


def job_program(booth: Booth, i: int, robot: Any, plan: CoveragePlan, T_world_part: np.ndarray,
                probe: Any, settings: Any) -> JointTrajectory:
    """Robot i's program (`robot`: its model, rails as planned) for `plan` (a job's passes) at
    `T_world_part` (4, 4) with its `settings` (`robot_settings`), kept clear of the body with
    its `probe` (None: not checked)."""
    return _clear_program(booth, booth.robots[i].name, robot, plan, T_world_part, settings,
                          probe)


def _check_transfer(booth: Booth, name: str, probe: Any, traj: JointTrajectory) -> None:
    """A chained program's moves between jobs keep `Booth.body_clearance_m` from the body."""
    moves = traj.meta["transfer_moves_s"]
    if not any(moves):
        return                                      # each piece was checked on its own
    assert booth.body_clearance_m is not None       # a probe only with a clearance to keep
    c = probe.clearance(traj.q, traj.t_s, float(booth.body_clearance_m))
    if not c.clear:
        raise BoothError(f"robot {name!r}'s move between two jobs comes within "
                         f"{c.min_distance_m * 1e3:.0f} mm of the body at t = {c.first_t_s:.2f} "
                         "s; give its jobs to one robot each")


def _clear_program(booth: Booth, name: str, robot: Any, plan: CoveragePlan,
                   T_world_part: np.ndarray, settings: Any, probe: Any) -> JointTrajectory:
    """The robot's program; with a probe (`booth_clearance.BodyProbe`), its rail positions
    keep the arm clear of the whole body, and a program that still comes closer than
    `Booth.body_clearance_m` is built again — approach and retract folded
    (`TrajectorySettings.fold_moves`), its home on the passes' wrist branch
    (`booth_clearance.wrist_flipped_home`), farther back-offs (`booth_clearance.clear_settings`)
    — until one keeps clear, else refused with the closest call named. The tries are in
    `meta["body_clearance"]`."""
    from paintcell.motion.trajectory import build_program

    if probe is None:
        return build_program(robot, plan, T_world_part, settings)
    from paintcell.booth import booth_clearance as bc

    ik = None
    q_home = np.asarray(robot.q_home if settings.q_home is None else settings.q_home, float)
    if getattr(robot, "rail", None) is not None:
        from paintcell.robots.rail import solve_rail_paths

        ik = solve_rail_paths(robot, [T_world_part @ plan.tcp_frames(k, settings.keep_roll)
                                      for k in range(len(plan.passes))],
                              q_seed=q_home, free_spin=settings.ik_free_spin,
                              penalty=probe.rail_penalty(bc.PLACEMENT_MARGIN_M,
                                                         bc.PLACEMENT_WEIGHT))
    assert booth.body_clearance_m is not None    # a probe only with a clearance to keep
    margin = float(booth.body_clearance_m)
    homes = [q_home]
    if ik is not None:   # the same home pose on the passes' wrist branch: no flip on the way
        flipped = bc.wrist_flipped_home(robot, q_home, ik[0].q[0])
        homes += [] if flipped is None else [flipped]
    # The ladder: as set; approach and retract folded; + home on the passes' wrist branch;
    # + farther back-offs.
    last = len(homes) - 1
    ladder = [(1.0, False, 0), (1.0, True, 0)] + [(1.0, True, 1)] * last \
        + [(f, True, last) for f in bc.CLEAR_FACTORS]
    tries: list[dict[str, Any]] = []
    failed: list[PaintcellError] = []
    for factor, fold, k in ladder:
        st = settings if factor == 1.0 else bc.clear_settings(settings, factor)
        st = dataclasses.replace(st, q_home=tuple(homes[k]), fold_moves=fold)
        try:
            traj = build_program(robot, plan, T_world_part, st, ik_results=ik)
        except PaintcellError as exc:     # a rung out of reach (a farther back-off): the next
            failed.append(exc)
            continue
        c = probe.clearance(traj.q, traj.t_s, margin)
        tries.append({"backoff_factor": factor, "fold_moves": fold,
                      "home_wrist_flipped": k == 1, **c.to_dict()})
        if c.clear:
            traj.meta["body_clearance"] = {"margin_m": margin, "tries": tries}
            return traj
    if not tries:                  # no rung could be built at all: the first one's reason
        raise failed[0]
    best = max(tries, key=lambda t: t["min_distance_m"])       # the closest call, said
    c = bc.Clearance(best["min_distance_m"], best["n_close"], best["first_t_s"],
                     tuple(best["bodies"]), tuple(best["parts"]))
    parts = ", ".join(booth.parts[p].part for p in c.parts)
    near = "touch" if c.min_distance_m <= 0 else f"come within {c.min_distance_m * 1e3:.0f} mm of"
    raise BoothError(f"robot {name!r}'s {', '.join(c.bodies[:2])} {near} the body ({parts}) "
                     f"at t = {c.first_t_s:.2f} s of its program, even with folded moves and "
                     f"{bc.CLEAR_FACTORS[-1]:g}x back-offs"
                     + (f" ({len(failed)} of those programs could not be built: {failed[0]})"
                        if failed else ""))


def load_robots(booth: Booth, rail_shrink_m: float = 0.0, stretch: bool = False) -> list[Any]:
    """The booth's robots; rail robots with their travel shrunk by rail_shrink_m at both ends
    (for planning the passes' carriage positions, leaving room for conveyor tracking) and, with
    `stretch`, limited to their `BoothRobot.carriage_m` (the planning models; without it, the
    models that execute, on their whole rail)."""
    from paintcell.robots import load_robot
    from paintcell.robots.rail import RailSpec, load_rail_robot

    out = []
    for r in booth.robots:
        keep = stretch and r.carriage_m is not None
        if r.rail_m is not None or keep or (rail_shrink_m > 0 and r.model.endswith("_rail")):
            if not r.model.endswith("_rail"):
                raise BoothError(f"robot {r.name!r} has rail_m but model {r.model!r} has no "
                                 "rail; use '<arm>_rail'")
            rng = r.rail_m if r.rail_m is not None else (-2.0, 2.0)
            lo, hi = rng[0] + rail_shrink_m, rng[1] - rail_shrink_m
            if keep:
                assert r.carriage_m is not None
                lo, hi = max(lo, r.carriage_m[0]), min(hi, r.carriage_m[1])
            if lo >= hi:
                raise BoothError(f"robot {r.name!r}: the conveyor tracking needs "
                                 f"{2 * rail_shrink_m:.2f} m of its rail"
                                 + (f" beyond its carriage stretch {list(r.carriage_m or ())} m"
                                    if keep else "")
                                 + "; lengthen rail_m or slow the line")
            out.append(load_rail_robot(r.model[:-5], T_world_rail=r.base.matrix,
                                       rail=RailSpec(lower_m=lo, upper_m=hi,
                                                     home_m=min(max(0.0, lo), hi))))
        else:
            out.append(load_robot(r.model, T_world_base=r.base.matrix))
    return out


def _stretched(booth: Booth) -> bool:
    """Whether a robot keeps its carriage to a stretch of its rail (`BoothRobot.carriage_m`)."""
    return any(r.carriage_m is not None for r in booth.robots)


def body_probe(booth: Booth, robot: Any, body: Surface, part_counts: tuple[int, ...]) -> Any:
    """The robot's `paintcell.booth.booth_clearance.BodyProbe` of the whole body (`body`: the
    parts stacked, part_counts: their vertex counts): its arm measured against every part."""
    from paintcell.booth.booth_clearance import BodyProbe

    part_of = np.concatenate([np.full(n, i) for i, n in enumerate(part_counts)])
    return BodyProbe(robot, body, booth.body_placement.matrix, part_of)


#: per worker thread: the last run's (key, robots, planners by rail shrink, probes).
_LOCAL = threading.local()


def _worker_state(run_key: str, booth: Booth, body: Surface, part_counts: tuple[int, ...],
                  shrink_m: float, r: int, probes: bool) -> tuple[Any, Any]:
    """Robot r's planning model (rails shrunk by shrink_m) and its body probe (None without
    `probes`) on this worker thread, built on first use and kept for the run's later tasks (one
    run at a time: a new key drops the older run's)."""
    st = getattr(_LOCAL, "state", None)
    if st is None or st["key"] != run_key:
        st = _LOCAL.state = {"key": run_key, "robots": load_robots(booth), "planners": {},
                             "probes": {}}
    if shrink_m not in st["planners"]:
        st["planners"][shrink_m] = load_robots(booth, shrink_m, stretch=True) \
            if shrink_m > 0 or _stretched(booth) else st["robots"]
    if probes and r not in st["probes"]:
        st["probes"][r] = body_probe(booth, st["robots"][r], body, part_counts)
    return st["planners"][shrink_m][r], st["probes"][r] if probes else None


def remote_job_program(run_key: str, booth: Booth, body: Surface, part_counts: tuple[int, ...],
                       shrink_m: float, probes: bool, r: int, plan: CoveragePlan,
                       T_world_part: np.ndarray) -> JointTrajectory | PaintcellError:
    """On a worker: robot r's program for `plan` (its job's passes) at `T_world_part` (4, 4),
    or the `PaintcellError` that refused it (returned, as the client caches refusals)."""
    robot, probe = _worker_state(run_key, booth, body, part_counts, shrink_m, r, probes)
    settings = robot_settings(booth, r)
    try:
        return job_program(booth, r, robot, plan, T_world_part, probe, settings)
    except PaintcellError as exc:
        return exc
