"""Honest reachability: a plan pose counts as reached only if the program really painted it.

The IK report (`paintcell.robots.reachability`) says whether each plan pose has a joint solution
within
tolerance and limits. That alone let a run print "reachability 100 %" beside 20 joint jumps or 14
collisions. Here a pose is *reached* only when all of these hold:

- IK reached it (position and orientation residuals, joint limits);
- no joint jump into it from the previous pose of its pass (the IK report's `joint_jump_rad`
  above its threshold: the arm cannot follow the path between the two poses);
- no configuration flip into it: the wrist joint's sin changes sign between the previous pose and
  this one along the executed joint path (the wrist went through its singularity mid-pass), or,
  on the ABB arms (`paintcell.robots.opw.configuration_signs`) and the UR10
  (`paintcell.robots.ur_kinematics.ur_configuration_signs`), the elbow
  (the arm through its stretched pose) or the shoulder (the wrist centre across the J1 axis);
- no contact: the executed trace touched nothing (part, booth, itself) while painting it — a
  contact during a move between passes counts against the last pose before it and the first pose
  after it (the move that links them is not executable);
- no slowdown: on the part, the paint the program sends over the stretch of path nearest the
  pose (its control samples' time × the flow it commands there, `paintcell.motion.flow`) is
  within `slowdown_fraction` of the plan's time for the same travel (a slower TCP lays a
  thicker film by the inverse of the speed ratio; a slowdown the brush table's lower flow makes
  up for lays the planned film). The
  overspray ends of a pass are not counted: a scenario may start and end its passes at rest there
  (`join_at_speed = False`), off the part, by design.

`reachability_pct` = reached poses ÷ plan poses; with any failing pose it is at most 99.99 %, so a
run with a jump, a flip, a contact or a slowdown never prints 100 %.

A cell of N robots (`paintcell.booth`) judges each robot's program alike: its plan is its jobs'
passes in program order (`paintcell.booth.booth_chain.robot_plan`), its IK report its jobs'
reports joined (`joined_reachability`), its program its own static one (the TCP speed along the
part, not the conveyor's added), and its contacts come from its share of the cell's run, moved
from the cell's clock to its program's by the start offset (`clock_offset_s`). The cell's figure
is its least robot's.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from paintcell.coverage.offset_polyline import arc_length
from paintcell.coverage.plan import CoveragePlan
from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.joint_trajectory import PAINT, JointTrajectory
from paintcell.robots.arms import arm_configuration_signs
from paintcell.robots.rail import RAIL_JOINT


@dataclass(frozen=True)
class HonestReachSettings:
    """What counts against reachability.

    slowdown_fraction: a pose whose TCP speed, as the film sees it (÷ the commanded flow) and
        averaged over the stretch of path nearest it, falls more than this fraction below the
        planned speed is not painted as planned (0.10: the film's ±10 % window) [-].
    wrist_joint_index: the arm joint whose sin changes sign at the wrist singularity (J5 of the
        ABB arms and of the UR10; counted after the rail axis when the trajectory's first joint
        is `paintcell.robots.rail.RAIL_JOINT`); None: flips are not counted.
    """

    slowdown_fraction: float = 0.10
    wrist_joint_index: int | None = 4


def pose_arc_lengths(plan: CoveragePlan) -> list[np.ndarray]:
    """Per pass, the arc length [m] of every plan pose along the pass's TCP polyline."""
    return [arc_length(p.positions) for p in plan.passes]


def nearest_pose(s_poses: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Index of the pose nearest to each arc length in `s`."""
    mid = 0.5 * (s_poses[1:] + s_poses[:-1])
    return np.searchsorted(mid, s)


def joined_reachability(reports: Sequence[dict[str, Any] | None]) -> dict[str, Any] | None:
    """A program's jobs' IK reports as one: counts summed, per-pose arrays concatenated (dropped
    when a job has none, so the honest figure falls back to its count-based bound). None if any
    is."""
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


def clock_offset_s(traj: JointTrajectory, clock: JointTrajectory) -> float:
    """Run-clock time − own-program time of the same sample [s]: `clock` is `traj` on the clock
    its execution ran on (0 for a program that never paints: its contacts are then counted at
    the run's clock, which only moves them between moves)."""
    a = np.flatnonzero(traj.paint_on)
    b = np.flatnonzero(clock.paint_on)
    if len(a) == 0 or len(b) == 0:
        return 0.0
    return float(clock.t_s[b[0]] - traj.t_s[a[0]])


def honest_reachability(plan: CoveragePlan, traj: JointTrajectory, trace: ExecutedTrace,
                        reachability: dict[str, Any] | Sequence[dict[str, Any] | None] | None,
                        settings: HonestReachSettings | None = None,
                        clock: JointTrajectory | None = None) -> dict[str, Any] | None:
    """Per-pose accounting of what the run really reached (see the module docstring).

    plan: the coverage plan the trajectory was built from; traj: its joint program (1 kHz
    samples with `pass_index`, `segment`, `s_pass_m`); trace: the execution (its contacts);
    reachability: the IK summary (`ReachabilityReport.to_dict()`, optionally with the per-pose
    `poses` arrays `reachable` and `joint_jump_rad`; without them the IK shortfall and the other
    causes are added, an upper bound on the poses lost), or a chained program's per-job
    summaries in order (`joined_reachability`). None: no IK report, returns None.
    clock: `traj` on the clock `trace` ran on (a robot of a cell started late: its contacts are
    moved back by `clock_offset_s`); None: the trace ran on `traj`'s own clock.
    Returns a JSON-safe dict: `reachability_pct` (honest), `ik_reachability_pct`, counts of poses
    lost to each cause (`n_unreachable`, `n_joint_jumps`, `n_config_flips`, `n_contact_poses`,
    `n_slowed_poses`), `n_lost` (their union) and a one-line `verdict`.
    """
    if reachability is not None and not isinstance(reachability, dict):
        reachability = joined_reachability(list(reachability))
    if reachability is None:
        return None
    if clock is not None:
        off = clock_offset_s(traj, clock)
        trace = dataclasses.replace(trace, contacts=tuple(
            dataclasses.replace(c, time_s=c.time_s - off) for c in trace.contacts))
    st = settings or HonestReachSettings()
    s_poses = pose_arc_lengths(plan)
    counts = [len(s) for s in s_poses]
    offsets = np.concatenate([[0], np.cumsum(counts)])
    n = int(offsets[-1])
    jump = np.zeros(n, bool)
    flip = np.zeros(n, bool)
    contact = np.zeros(n, bool)
    slow = np.zeros(n, bool)

    poses = reachability.get("poses") or {}
    th_jump = float(reachability.get("thresholds", {}).get("max_joint_jump_rad", 0.2))
    have_poses = len(poses.get("reachable", ())) == n
    if have_poses:
        unreachable = ~np.asarray(poses["reachable"], bool)
        jj = np.asarray([np.nan if x is None else x for x in poses.get("joint_jump_rad",
                                                                       [0.0] * n)], float)
        jump = np.nan_to_num(jj, nan=0.0) > th_jump
    else:
        unreachable = np.zeros(n, bool)

    paint = np.asarray(traj.segment) == PAINT
    pidx = np.asarray(traj.pass_index)
    # the TCP's travel per step [m] and the paint the program sends per step (time × the flow it
    # commands) [s], against the plan's time for that travel, on paint samples
    dt = np.gradient(np.asarray(traj.t_s, float))
    travel = np.linalg.norm(np.gradient(traj.tcp_pos_world, traj.t_s, axis=0), axis=1) * dt
    sent = dt * np.asarray(traj.flow, float)
    v_plan = np.asarray(traj.v_tcp_planned, float)
    signs_of = arm_configuration_signs(traj.robot_name)
    arm0 = 1 if traj.joint_names and traj.joint_names[0] == RAIL_JOINT else 0
    n_kind = [0, 0, 0]                # poses after a shoulder, elbow, wrist flip
    for i, s in enumerate(s_poses):
        sel = np.flatnonzero(paint & (pidx == i))
        if len(sel) == 0:
            continue
        k = nearest_pose(s, traj.s_pass_m[sel])
        ok = v_plan[sel] > 1e-9
        # per pose, over the samples nearest it: the plan's time for the travel against the
        # program's paint time (the film's dwell there)
        plan_t = np.bincount(k[ok], travel[sel][ok] / v_plan[sel][ok], minlength=len(s))
        film_t = np.bincount(k[ok], sent[sel][ok], minlength=len(s))
        with np.errstate(invalid="ignore", divide="ignore"):
            deficit = 1.0 - plan_t / film_t
        ks = np.flatnonzero((film_t > 0) & (deficit > st.slowdown_fraction))
        on_part = np.asarray(plan.passes[i].on_part, bool)
        slow[offsets[i] + ks[on_part[ks]]] = True
        wi = st.wrist_joint_index
        if wi is not None and traj.joint_names and traj.joint_names[0] == RAIL_JOINT:
            wi += 1          # a rail's prismatic axis comes first: the arm's wrist is one later
        if wi is not None and wi < traj.q.shape[1]:
            sg = np.sign(np.sin(traj.q[sel, wi]))
            change = np.flatnonzero(sg[1:] * sg[:-1] < 0) + 1
            flip[offsets[i] + np.unique(k[change])] = True
            n_kind[2] += len(np.unique(k[change]))
        if signs_of is not None and traj.q.shape[1] >= arm0 + 6:
            sg = signs_of(traj.q[sel, arm0:arm0 + 6])
            for c in (0, 1):              # shoulder, elbow
                change = np.flatnonzero(sg[1:, c] * sg[:-1, c] < 0) + 1
                flip[offsets[i] + np.unique(k[change])] = True
                n_kind[c] += len(np.unique(k[change]))

    # contacts: during a pass the pose painted then; during a move the poses it links (all
    # contact times at once: a run in contact throughout records one per 1 kHz step)
    t = np.asarray(traj.t_s)
    paint_idx = np.flatnonzero(paint)
    tc = np.unique(np.fromiter((c.time_s for c in trace.contacts), float))
    if len(tc) and len(paint_idx):
        j = np.clip(np.searchsorted(t, tc - 1e-9), 0, len(t) - 1)
        on = paint[j]
        for i in np.unique(pidx[j[on]]):              # during a pass: the poses painted then
            ji = j[on][pidx[j[on]] == i]
            contact[offsets[i] + nearest_pose(s_poses[i], traj.s_pass_m[ji])] = True
        jm = j[~on]                                    # during a move: the poses it links
        b = np.searchsorted(paint_idx, jm) - 1         # last paint sample before
        a = b + 1                                      # first paint sample after
        ok = b >= 0
        pb = pidx[paint_idx[b[ok]]]
        contact[offsets[pb] + np.asarray(counts)[pb] - 1] = True
        ok = a < len(paint_idx)
        contact[offsets[pidx[paint_idx[a[ok]]]]] = True

    lost = unreachable | jump | flip | contact | slow
    n_ik = int(reachability.get("n_poses") or 0)
    n_ik_ok = int(reachability.get("n_reachable") or 0)
    ik_pct = 100.0 * n_ik_ok / n_ik if n_ik else float("nan")
    if have_poses:
        n_lost = int(np.count_nonzero(lost))
        frac_ok = 1.0 - n_lost / n
    else:
        n_lost = int(np.count_nonzero(lost)) + (n_ik - n_ik_ok)
        frac_ok = max(0.0, (ik_pct / 100.0 if n_ik else 1.0) - np.count_nonzero(lost) / max(n, 1))
    pct = 100.0 * frac_ok
    if n_lost > 0:                       # never print 100 % with a pose lost
        pct = min(pct, math.floor(pct * 100.0) / 100.0, 99.99)
    causes = {"n_unreachable": (n_ik - n_ik_ok) if not have_poses
              else int(np.count_nonzero(unreachable)),
              "n_joint_jumps": int(np.count_nonzero(jump)),
              "n_config_flips": int(np.count_nonzero(flip)),
              "n_contact_poses": int(np.count_nonzero(contact)),
              "n_slowed_poses": int(np.count_nonzero(slow))}
    words = {"n_unreachable": "unreachable", "n_joint_jumps": "after a joint jump",
             "n_config_flips": "after a configuration flip", "n_contact_poses": "in contact",
             "n_slowed_poses": f"slowed > {100 * st.slowdown_fraction:.0f} %"}
    why = ", ".join(f"{v} {words[k]}" for k, v in causes.items() if v)
    kinds = [f"{v} {w}" for v, w in zip(n_kind, ("shoulder", "elbow", "wrist"), strict=True)
             if v]
    if kinds:
        why = why.replace("configuration flip", "configuration flip [" + ", ".join(kinds) + "]")
    verdict = (f"{pct:.2f} % of {n} poses painted as planned"
               + (f" ({why})" if why else ""))
    return {"reachability_pct": pct, "ik_reachability_pct": ik_pct, "n_poses": n,
            "n_lost": n_lost, **causes, "n_shoulder_flips": n_kind[0],
            "n_elbow_flips": n_kind[1], "n_wrist_flips": n_kind[2],
            "slowdown_fraction": st.slowdown_fraction, "per_pose": have_poses, "verdict": verdict}
