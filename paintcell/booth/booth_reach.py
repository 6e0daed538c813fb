"""Honest reachability of each booth robot.

A booth robot's program is its jobs' programs back to back (`paintcell.booth.booth_chain`),
each built from a slice of a part's plan. Its honest reachability is the single-robot one
(`paintcell.validation.honest_reach.honest_reachability`: a pose counts only if IK reached
it, no joint jump or configuration flip led into it, nothing was in contact and the time law kept
≥ 90 % of the planned speed) on:

- the robot's plan: its jobs' passes in program order (the chained program's pass indices run on
  across the jobs in that order);
- its own static program (`BoothPrograms.static`: the static cell, not delayed, not tracking the
  conveyor), so the TCP speed it measures is the speed along the part, not the conveyor's added;
- its IK report: the jobs' reports joined (pose counts summed, per-pose arrays concatenated);
- its contacts in the booth run (robot–part, robot–booth and robot–robot events of its bodies),
  moved from the booth clock to its own program's clock by its start offset (the time its
  first brush-on sample is run at in the booth less the time it has in its own program).

The booth's `reachability_pct` is the least robot's honest figure, so a booth with any jump, flip,
contact or slowdown cannot print 100 %.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from paintcell.coverage.plan import CoveragePlan
from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.validation.honest_reach import honest_reachability


def robot_plan(plans: list[CoveragePlan], jobs: tuple[Any, ...]) -> CoveragePlan:
    """The plan a robot ran: its jobs' pass slices (`Job.part`, `first`, `end`) in order."""
    passes = tuple(p for j in jobs for p in plans[j.part].passes[j.first:j.end])
    return dataclasses.replace(plans[jobs[0].part], passes=passes)


def joined_reachability(reports: list[dict[str, Any] | None]) -> dict[str, Any] | None:
    """The jobs' IK reports as one: counts summed, per-pose arrays concatenated (dropped when a
    job has none, so the honest figure falls back to its count-based bound). None if any is."""
    if not reports or any(r is None for r in reports):
        return None
    rs = [r for r in reports if r is not None]
    if len(rs) == 1:
        return rs[0]
    out: dict[str, Any] = {"n_poses": sum(int(r.get("n_poses") or 0) for r in rs),
                           "n_reachable": sum(int(r.get("n_reachable") or 0) for r in rs),
                           "thresholds": rs[0].get("thresholds", {})}
    poses = [r.get("poses") or {} for r in rs]
    if all("reachable" in p for p in poses):
        out["poses"] = {"reachable": [x for p in poses for x in p["reachable"]]}
        if all("joint_jump_rad" in p for p in poses):
            out["poses"]["joint_jump_rad"] = [x for p in poses for x in p["joint_jump_rad"]]
    return out


def clock_offset_s(static: JointTrajectory, tracked: JointTrajectory) -> float:
    """Booth time − own-program time of the same sample [s] (0 for a program that never paints:
    its contacts are then counted at the booth clock, which only moves them between moves)."""
    a = np.flatnonzero(static.paint_on)
    b = np.flatnonzero(tracked.paint_on)
    if len(a) == 0 or len(b) == 0:
        return 0.0
    return float(tracked.t_s[b[0]] - static.t_s[a[0]])


def robot_honest_reach(plans: list[CoveragePlan], jobs: tuple[Any, ...],
                       static: JointTrajectory, tracked: JointTrajectory,
                       trace: ExecutedTrace) -> dict[str, Any] | None:
    """One robot's honest reachability (module doc). static: its own program; tracked: the same
    on the booth clock; trace: its share of the booth run (`contacts` its bodies' events)."""
    reports = static.meta.get("job_reachability") or [static.meta.get("reachability")]
    reach = joined_reachability(list(reports))
    off = clock_offset_s(static, tracked)
    own = dataclasses.replace(trace, contacts=tuple(
        dataclasses.replace(c, time_s=c.time_s - off) for c in trace.contacts))
    return honest_reachability(robot_plan(plans, jobs), static, own, reach)
