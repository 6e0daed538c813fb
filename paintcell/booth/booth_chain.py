"""A booth robot with more than one job (`Booth.max_jobs_per_robot`): its program is its jobs'
programs one after the other (`chain_programs`), each built, and kept clear of the body, on its
own (`paintcell.booth.booth_programs`): each ends at rest at its home and the next starts at
rest at its own, so the move between two jobs is the retract home of the first and the approach
of the next — both already checked against the joint limits and the whole body. Where the two
homes differ (the body clearance may put a job's home on the passes' wrist branch), a
time-optimal jerk-limited joint move joins them, with the first program's joint limits
(`paintcell.motion.moves.plan_move`); the booth then checks that move against the body like
any other sample of the program.

The allocation's search over jobs-lists (`assign_job_lists`) is here too.

The film of a robot is credited per job at the job's part flow (`job_windows`: which samples
belong to which job on the booth clock).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from paintcell.motion.joint_trajectory import RETRACT, JointTrajectory

#: homes closer than this [rad or m] are one pose (no transfer move).
SAME_POSE_TOL = 1e-9


def chain_programs(trajs: list[JointTrajectory], robot: Any) -> JointTrajectory:
    """One program of `robot` (its `fk_many` gives a joining move's TCP): `trajs` (each at rest
    at both ends, one dt) back to back, a joint move between two that end and start at
    different poses. meta: the first's, with
    `job_starts_s` (when each job's program starts in the chained one [s]) and
    `transfer_moves_s` (duration of each joining move [s], 0 where none was needed) and
    `job_first_pass_index` (pass indices run on across the jobs: job k's passes start at
    this index) and `job_reachability` (each job's IK report, in order)."""
    if len(trajs) == 1:
        return trajs[0]
    dt = trajs[0].dt_s
    if any(abs(t.dt_s - dt) > 1e-12 for t in trajs):
        raise ValueError("chained programs need one sample step")
    pieces: list[JointTrajectory] = [trajs[0]]
    starts, transfers, first_pass = [0.0], [], [0]
    k = len(trajs[0].t_s)
    for nxt in trajs[1:]:
        prev = pieces[-1]
        gap = np.abs(prev.q[-1] - nxt.q[0]).max()
        if gap > SAME_POSE_TOL:
            move = _transfer(prev, nxt, robot)
            pieces.append(move)
            transfers.append(float(len(move.t_s) * dt))
            k += len(move.t_s)
        else:
            transfers.append(0.0)
        starts.append(k * dt)
        # pass indices run on across the jobs (RAPID names its targets by them)
        shift = int(max(p.pass_index.max() for p in pieces)) + 1
        pieces.append(dataclasses.replace(nxt, pass_index=np.where(
            nxt.pass_index >= 0, nxt.pass_index + shift, -1)))
        first_pass.append(shift)
        k += len(nxt.t_s)
    arrays = {name: np.concatenate([getattr(p, name) for p in pieces])
              for name in JointTrajectory._ARRAYS if name != "t_s"}
    arrays["t_s"] = trajs[0].t_s[0] + dt * np.arange(k)
    first = trajs[0]
    return JointTrajectory(**arrays, robot_name=first.robot_name, joint_names=first.joint_names,
                           slowdowns=tuple(s for t in trajs for s in t.slowdowns),
                           pass_summary=tuple(s for t in trajs for s in t.pass_summary),
                           meta={**first.meta, "job_starts_s": starts,
                                 "transfer_moves_s": transfers,
                                 "job_first_pass_index": first_pass,
                                 "job_reachability": [t.meta.get("reachability")
                                                      for t in trajs]})


def _transfer(a: JointTrajectory, b: JointTrajectory, robot: Any) -> JointTrajectory:
    """Samples strictly between a's last pose and b's first, both at rest (brush off)."""
    from paintcell.motion.moves import plan_move

    lim = a.meta["limits"]
    n = a.q.shape[1]
    z = np.zeros(n)
    move = plan_move(a.q[-1], z, z, b.q[0], z, z, lim["v_used_rad_s"], lim["a_used_rad_s2"],
                     lim["j_used_rad_s3"])
    dt = a.dt_s
    t = dt * np.arange(1, max(int(np.ceil(move.duration_s / dt)), 1))
    q, qd, qdd = move.sample(t)
    q, qd, qdd = (np.asarray(x, float) for x in (q, qd, qdd))
    m = len(t)
    T = robot.fk_many(q)
    pos, rot = T[:, :3, 3], T[:, :3, :3]
    return JointTrajectory(t_s=t, q=q, qd=qd, qdd=qdd, tcp_pos_world=pos, tcp_rot_world=rot,
                           v_tcp_planned=np.zeros(m), paint_on=np.zeros(m, bool),
                           pass_index=np.full(m, -1), segment=np.full(m, RETRACT),
                           s_pass_m=np.full(m, np.nan), robot_name=a.robot_name,
                           joint_names=a.joint_names)


#: allocations kept by the multi-job search of `rank_allocations`.
KEEP_RANKED = 512


def assign_job_lists(n_robots: int, jobs: list[Any], est_of: dict[Any, float],
                     reachable: Any, max_jobs: int, heap: list[Any], serial: Any) -> int:
    """Depth-first assignment of `jobs` (`paintcell.booth.booth.Job`s of one cut of the
    parts) to robots — each robot 1..max_jobs jobs, each job reachable(robot, job) — for
    `paintcell.booth.booth.rank_allocations`: each complete one, entry = (its robots' summed
    estimates `est_of` [s] sorted longest first, next(serial), {robot: jobs}), is pushed on
    `heap` (a heapq of (negated key, negated serial, entry): the worst kept on top) while it
    holds fewer than KEEP_RANKED, else replaces the worst when better (a partial assignment
    whose longest program already exceeds the worst kept is not completed). A robot never gets
    two adjacent pieces of one part (dominated by their union, which `job_options` also offers:
    APPROACH_RETRACT_S − TURN_S more); pieces apart (one wing of each patch) it may.
    Returns the number of complete assignments considered."""
    import heapq

    load = [0.0] * n_robots
    got: list[list[Any]] = [[] for _ in range(n_robots)]
    n = [0]

    def bound() -> float:
        return float("inf") if len(heap) < KEEP_RANKED else float(heap[0][2][0][0])

    def dfs(k: int) -> None:
        if k == len(jobs):
            if any(not g for g in got):
                return
            n[0] += 1
            key = tuple(sorted(load, reverse=True))
            entry = (key, next(serial), {r: tuple(g) for r, g in enumerate(got)})
            item = (tuple(-x for x in key), -entry[1], entry)
            if len(heap) < KEEP_RANKED:
                heapq.heappush(heap, item)
            elif key < heap[0][2][0]:
                heapq.heapreplace(heap, item)
            return
        # robots still without a job must all be served by the jobs left
        if sum(1 for g in got if not g) > len(jobs) - k:
            return
        j = jobs[k]
        for r in range(n_robots):
            if len(got[r]) >= max_jobs or load[r] + est_of[j] > bound():
                continue
            # Two adjacent pieces of a part to one robot: their union as one job (enumerated
            # too) has the same passes with one turn-around instead of a retract and an
            # approach, so its estimate is always the smaller; not worth building.
            if any(g.part == j.part and (g.end == j.first or j.end == g.first)
                   for g in got[r]):
                continue
            if not reachable(r, j):
                continue
            got[r].append(j)
            load[r] += est_of[j]
            dfs(k + 1)
            load[r] -= est_of[j]
            got[r].pop()

    dfs(0)
    return n[0]


def robot_plan(plans: list[Any], jobs: tuple[Any, ...]) -> Any:
    """The `CoveragePlan` a robot runs: its jobs' pass slices (`Job.part`, `first`, `end`) in
    program order (its chained program's pass indices run on across the jobs in that order)."""
    passes = tuple(p for j in jobs for p in plans[j.part].passes[j.first:j.end])
    return dataclasses.replace(plans[jobs[0].part], passes=passes)


def robot_reachability(plans: list[Any], jobs: tuple[Any, ...], static: JointTrajectory,
                       tracked: JointTrajectory, trace: Any) -> dict[str, Any] | None:
    """A robot's honest reachability (`paintcell.validation.honest_reach`): its jobs' plan
    (`robot_plan`), its own static program with its jobs' IK reports, its share of the booth's
    trace (`trace`: its bodies' contacts) on the booth clock its `tracked` program ran on."""
    from paintcell.validation.honest_reach import honest_reachability

    reports = static.meta.get("job_reachability") or static.meta.get("reachability")
    return honest_reachability(robot_plan(plans, jobs), static, trace, reports, clock=tracked)


def job_record(jobs: tuple[Any, ...]) -> list[int] | list[list[int]]:
    """A robot's jobs (`paintcell.booth.booth.Job`s) for records and reports: [part, first,
    end] for one job, a list of them for several."""
    if len(jobs) == 1:
        return [jobs[0].part, jobs[0].first, jobs[0].end]
    return [[j.part, j.first, j.end] for j in jobs]


def job_windows(traj: JointTrajectory, n_jobs: int) -> list[np.ndarray]:
    """(K,) boolean masks of `traj`'s samples (booth clock: its start delay included) that belong
    to each of its n_jobs jobs (all samples for one job): a partition of the samples, the hold
    before the start in the first job's, the hold after the end in the last one's."""
    if n_jobs == 1:
        return [np.ones(len(traj.t_s), bool)]
    starts = np.asarray(traj.meta["job_starts_s"], float) \
        + float(traj.meta.get("start_delay_s", 0.0))
    k = np.arange(len(traj.t_s))
    first = np.round(starts / traj.dt_s).astype(int)
    first[0] = 0                  # the start delay's hold belongs to the first job (brush off)
    edges = np.append(first, len(traj.t_s) + 1)
    return [(k >= edges[i]) & (k < edges[i + 1]) for i in range(n_jobs)]
