"""A joint program's TCP speeds measured against its plan, and the speed caps that bring the
plan under what the robot reached (`paintcell.motion.speed_feedback` re-plans under them). The
speeds are taken as the caps see them (`paintcell.motion.flow.cap_speed`): ÷ the flow the
program's brush table commands, unless that flow sits at its lowest level.

The speed is measured twice: at the plan samples (ds/dt of the program there, `pass_speeds`) and
between them (|dp/dt| at every control sample, `lag_caps`: a robot can meet the plan at two
samples and lag between them, measured on cad_fender at 10 mm: 14–19 % for 16 ms after a capped
sample, the one pose honest reachability lost). A pass gets between-sample caps once its samples
are met within `MET_REL` (in the first rounds its deep slowdowns would cap the plan far harder
than needed). One robot or N are measured alike: each robot runs jobs (passes [first, end) of
one part's plan), `part_speeds` finds each part's passes in the programs that ran them,
`parts_caps` caps each part, `speed_caps` is the one-robot case.
"""

from __future__ import annotations

from collections.abc import Sequence
from types import SimpleNamespace
from typing import Any

import numpy as np

from paintcell.coverage.offset_polyline import arc_length
from paintcell.coverage.plan import CoveragePlan
from paintcell.motion.flow import cap_speed

#: A sample is capped where the robot's TCP speed is below the plan by more than this fraction.
SLOW_REL = 0.005
#: Between plan samples (`lag_caps`), the program's speed counts as short of the plan below this
#: fraction: the honest-reach window (10 %) less the caps' margin; a smaller lag is left alone
#: (capping it would change the film for no pose gained: cad_door's 6.8 % moved its σ/μ 0.1 pp).
LAG_REL = 0.07
#: A pass gets between-sample caps once its samples are met within this fraction.
MET_REL = 0.05
#: Caps sit this fraction below the speed the robot reached there (room for the re-planned
#: profile's own accelerations).
CAP_MARGIN = 0.03


def pass_speeds(p: Any, traj: Any, index: int, trust_floor: bool = False) -> np.ndarray:
    """The TCP speed a joint program reaches at each sample of pass `p` [m/s] ((M,)), as the
    caps see it (÷ the flow the program commands there, unless that flow is at its lowest level:
    `paintcell.motion.flow.cap_speed`).

    traj: `paintcell.motion.joint_trajectory.JointTrajectory` whose samples with
    pass_index == index run `p` (s_pass_m along the plan samples' arc length). The speed is ds/dt
    of the program's samples, interpolated at the plan samples; the plan's own speeds where the
    program has fewer than 3 samples of the pass.
    """
    s_plan = arc_length(p.positions)
    idx = np.flatnonzero(traj.pass_index == index)
    if len(idx) < 3:
        return np.asarray(p.speeds_m_s, float).copy()
    s = traj.s_pass_m[idx]
    v = cap_speed(np.gradient(s, traj.t_s[idx]), traj, idx, trust_floor)
    order = np.argsort(s, kind="stable")
    return np.interp(s_plan, s[order], v[order])


def lag_caps(p: Any, traj: Any, index: int, lag_rel: float = LAG_REL,
             margin: float = CAP_MARGIN, trust_floor: bool = False) -> np.ndarray:
    """Caps [m/s] ((M,), inf where none) that bring the plan of pass `p` under what the joint
    program reached BETWEEN its samples.

    traj: the `JointTrajectory` whose samples with pass_index == index run `p`. The program's TCP
    speed v = |dp/dt| at every control sample (as the caps see it,
    `paintcell.motion.flow.cap_speed`) is compared with the planned speed there
    (`v_tcp_planned`: v² linear in arc length between plan samples, constant tangential
    acceleration). Where the robot cannot accelerate (or brake) as fast as an interval asks —
    the plan's speed rising steeply out of a slow sample while a joint's acceleration is taken
    by the path's curvature — the program meets the plan at both samples and still lags between
    them, which caps at the samples alone do not see. At each control sample slower than the
    plan by more than `lag_rel`, a fraction μ of the way from the interval's slower end (planned
    speed v_l) to its faster end: if v ≥ v_l the faster end is capped at c with
    v_l² + μ (c² − v_l²) = v_l² + (1 − margin)² (v² − v_l²) (the planned v² line then rises
    under what the robot reached); else both ends are capped at v (1 − margin). A control
    sample whose nearest plan pose is off the part (`on_part`) is not looked at (honest reach
    does not count it: capping the rest-to-rest ends of hood's passes made its re-plan 28 %
    longer). Caps in the pass's own (execution) sample order.
    """
    s_plan = arc_length(p.positions)
    caps = np.full(len(s_plan), np.inf)
    idx = np.flatnonzero(traj.pass_index == index)
    if len(idx) < 3 or len(s_plan) < 2:
        return caps
    v_a = cap_speed(np.linalg.norm(np.gradient(traj.tcp_pos_world[idx], traj.t_s[idx],
                                                axis=0), axis=1), traj, idx, trust_floor)
    v_p = np.asarray(traj.v_tcp_planned, float)[idx]
    s = traj.s_pass_m[idx]
    lag = np.isfinite(s) & (v_p > 1e-9) & (v_a < (1.0 - lag_rel) * v_p)
    # as honest reach maps them: a control sample counts for its nearest plan pose, and the
    # overspray ends off the part do not count (a pass may start and end there at rest)
    near = np.searchsorted(0.5 * (s_plan[1:] + s_plan[:-1]), np.where(np.isfinite(s), s, 0.0))
    lag &= np.asarray(getattr(p, "on_part", np.ones(len(s_plan), bool)), bool)[near]
    if not lag.any():
        return caps
    s, v_a = s[lag], v_a[lag]
    v = np.asarray(p.speeds_m_s, float)
    j = np.clip(np.searchsorted(s_plan, s, side="right") - 1, 0, len(s_plan) - 2)
    lam = np.clip((s - s_plan[j]) / (s_plan[j + 1] - s_plan[j]), 0.0, 1.0)
    right = v[j + 1] >= v[j]                  # the faster end of the interval
    hi, lo = np.where(right, j + 1, j), np.where(right, j, j + 1)
    mu = np.maximum(np.where(right, lam, 1.0 - lam), 1e-6)   # the faster end's weight here
    v_l = v[lo]
    one_end = v_a >= v_l
    c = np.sqrt(v_l**2 + (1.0 - margin) ** 2 * np.maximum(v_a**2 - v_l**2, 0.0) / mu)
    np.minimum.at(caps, hi[one_end], c[one_end])
    both = ~one_end
    np.minimum.at(caps, hi[both], (1.0 - margin) * v_a[both])
    np.minimum.at(caps, lo[both], (1.0 - margin) * v_a[both])
    return caps


def part_speeds(plans: Sequence[CoveragePlan], jobs: dict[int, tuple[Any, ...]],
                programs: Sequence[Any], lags: bool = False, margin: float = CAP_MARGIN,
                trust_floor: bool | Sequence[bool] = False) -> list[list[np.ndarray]]:
    """Per part, per pass of its plan, the TCP speed its robot reaches at each sample [m/s]
    (`pass_speeds`; jobs: {robot: its jobs, passes [first, end) of plan `part`, run on in its
    program from `meta["job_first_pass_index"]`, default 0}); the plan's own speeds for a pass
    no robot runs. lags: instead, the caps between samples (`lag_caps`; inf where none) [m/s].
    trust_floor: the speeds as the film sees them also where the flow is at its lowest level
    (`paintcell.motion.flow.cap_speed`); one flag, or one per part."""
    trust = [bool(trust_floor)] * len(plans) if isinstance(trust_floor, bool) \
        else [bool(t) for t in trust_floor]
    out = [[np.full(len(p.speeds_m_s), np.inf) if lags else np.asarray(p.speeds_m_s, float)
            for p in pl.passes] for pl in plans]
    for r, js in jobs.items():
        traj = programs[r]
        firsts = traj.meta.get("job_first_pass_index", [0])
        for k, job in enumerate(js):
            for m in range(job.end - job.first):
                p = plans[job.part].passes[job.first + m]
                out[job.part][job.first + m] = (
                    lag_caps(p, traj, firsts[k] + m, margin=margin,
                             trust_floor=trust[job.part])
                    if lags else pass_speeds(p, traj, firsts[k] + m, trust[job.part]))
    return out


def one_robot_jobs(plan: CoveragePlan) -> dict[int, tuple[Any, ...]]:
    """The jobs of a one-robot cell (`part_speeds`' jobs): its robot runs every pass of its one
    part."""
    return {0: (SimpleNamespace(part=0, first=0, end=len(plan.passes)),)}


def achieved_speeds(plan: CoveragePlan, traj: Any) -> list[np.ndarray]:
    """Per pass, the TCP speed the joint program reaches at each plan sample [m/s] ((M,) each;
    `pass_speeds` of pass i at pass_index i: as the caps see it, ÷ the commanded flow)."""
    return part_speeds([plan], one_robot_jobs(plan), [traj])[0]


def speed_caps(plan: CoveragePlan, traj: Any, previous: dict[int, np.ndarray] | None = None,
               slow_rel: float = SLOW_REL, margin: float = CAP_MARGIN,
               trust_floor: bool = False) -> tuple[dict[int, np.ndarray], int, float]:
    """Caps {side: (M,) [m/s]} where the program is slower than the plan, in generation direction.

    Returns (caps, number of newly capped samples, largest speed deficit [%]; the samples capped
    include those of `lag_caps`, the deficit is the one at the samples): `parts_caps` of one
    robot running the whole plan.
    """
    caps, counts, worst = parts_caps([plan], [plan], [False], one_robot_jobs(plan), [traj],
                                     [previous or {}], slow_rel, margin, trust_floor)
    return caps[0], counts[0], worst


def parts_caps(plans0: Sequence[CoveragePlan], finished: Sequence[CoveragePlan],
               reverse: Sequence[bool], jobs: dict[int, tuple[Any, ...]],
               programs: Sequence[Any], previous: Sequence[dict[int, np.ndarray]],
               slow_rel: float = SLOW_REL, margin: float = CAP_MARGIN,
               trust_floor: bool | Sequence[bool] = False
               ) -> tuple[list[dict[int, np.ndarray]], list[int], float]:
    """Per part, the caps of `caps_from_speeds` on its planner's plan `plans0[i]` from what the
    robots reached on its finished plan `finished[i]` (the one they ran: passes reversed where
    `reverse[i]`; jobs, programs, trust_floor: `part_speeds`'); previous: each part's caps so
    far.
    Returns (caps per part {side: (M,) [m/s]}, newly capped samples per part, largest deficit
    over the parts [%])."""
    v_act = part_speeds(finished, jobs, programs, margin=margin, trust_floor=trust_floor)
    lags = part_speeds(finished, jobs, programs, lags=True, margin=margin,
                       trust_floor=trust_floor)
    caps, counts, worst = [], [], 0.0
    for i, rev in enumerate(reverse):
        asked = [np.asarray(p.speeds_m_s, float) for p in finished[i].passes]
        c, n, w = caps_from_speeds(plans0[i], planner_order(v_act[i], rev),
                                   planner_order(asked, rev), previous[i], slow_rel, margin,
                                   planner_order(lags[i], rev))
        caps.append(c)
        counts.append(n)
        worst = max(worst, w)
    return caps, counts, worst


def planner_order(arrays: list[Any], reverse: bool) -> list[Any]:
    """Per-pass sample arrays of a finished plan in its planner's order, or back (a part run
    backwards has its passes in reverse order, each reversed; the map is its own inverse)."""
    return [a[::-1] for a in arrays[::-1]] if reverse else list(arrays)


def stored_caps(plan: CoveragePlan, caps: dict[int, np.ndarray], reverse: bool
                ) -> list[np.ndarray | None]:
    """The caps {side: generation direction} of the planner's `plan` per pass of the finished
    plan (execution order, each pass's own sample order) [m/s], None where a pass has none."""
    per = [None if (c := caps.get(p.side)) is None else (c[::-1] if i % 2 == 1 else c)
           for i, p in enumerate(plan.passes)]
    return [None if c is None else c[::-1] for c in per[::-1]] if reverse else per


def caps_from_speeds(plan: CoveragePlan, v_act: list[np.ndarray],
                     v_plan: list[np.ndarray] | None = None,
                     previous: dict[int, np.ndarray] | None = None,
                     slow_rel: float = SLOW_REL, margin: float = CAP_MARGIN,
                     lags: list[np.ndarray] | None = None
                     ) -> tuple[dict[int, np.ndarray], int, float]:
    """`speed_caps` from speeds already measured: v_act, per pass of `plan` (execution order,
    odd passes run reversed), the speed the robot reached at each sample [m/s]; v_plan, the
    speeds it was asked for (default: the plan's own) [m/s]; lags: per pass, the caps of
    `lag_caps` (execution order, inf where none) [m/s]. Caps only shrink from `previous`.
    Returns (caps {side: (M,) [m/s], generation direction}, newly capped samples, largest
    deficit [%])."""
    caps = {k: v.copy() for k, v in (previous or {}).items()}
    n_new, worst = 0, 0.0
    asked = v_plan if v_plan is not None else [np.asarray(p.speeds_m_s, float)
                                               for p in plan.passes]
    for i, (p, v_a, v_p) in enumerate(zip(plan.passes, v_act, asked, strict=True)):
        deficit = 1.0 - np.asarray(v_a, float) / np.asarray(v_p, float)
        worst = max(worst, float(100 * deficit.max()))
        slow = deficit > slow_rel
        # between-sample caps only on a pass whose samples the robot already meets within
        # MET_REL: before that a deep slowdown's lag caps would cap the plan far harder than the
        # samples' own caps need (measured: a 51 % longer cycle on cad_fender's first round)
        lag = None if lags is None or deficit.max() > MET_REL else np.asarray(lags[i], float)
        if not slow.any() and (lag is None or not np.isfinite(lag).any()):
            continue
        # widen by one sample each side: the limit acts over the interval, not at the point
        slow = slow | np.r_[slow[1:], False] | np.r_[False, slow[:-1]]
        cap = np.where(slow, v_a * (1.0 - margin), np.inf)
        if lag is not None:
            cap = np.minimum(cap, lag)
        if i % 2 == 1:                      # plan.passes[i] runs reversed (boustrophedon)
            cap = cap[::-1]
        old = caps.get(p.side, np.full(len(cap), np.inf))
        new = np.minimum(old, cap)
        n_new += int(np.sum(new < old))
        caps[p.side] = new
    return caps, n_new, worst


def tool_axes(plan: CoveragePlan, traj: Any, T_world_part: np.ndarray) -> dict[int, np.ndarray]:
    """Per pass, the bell x axis the joint program holds at each plan sample, in the part frame
    and the pass's generation direction ({side: (M, 3)}): what a robot that frees the bell's spin
    about its axis really does (the plan's film assumed x = travel)."""
    R = np.asarray(T_world_part, float)[:3, :3]
    out = {}
    for i, p in enumerate(plan.passes):
        idx = np.flatnonzero(traj.pass_index == i)
        if len(idx) < 3:
            continue
        s_plan = arc_length(p.positions)
        s = traj.s_pass_m[idx]
        order = np.argsort(s, kind="stable")
        x_part = traj.tcp_rot_world[idx][:, :, 0] @ R          # world → part frame (Rᵀ x)
        x = np.stack([np.interp(s_plan, s[order], x_part[order, k]) for k in range(3)], axis=1)
        x /= np.linalg.norm(x, axis=1, keepdims=True)
        # the pattern is symmetric under x → −x (f is even in x and y): the first sample takes
        # the sign nearest the plan's travel axis and every later one the sign continuous with
        # its predecessor, so the IK is never asked to turn the bell half a turn (a sample-wise
        # choice flips where the free spin passes 90° off the travel)
        x[0] *= -1.0 if float(x[0] @ p.travel_dirs[0]) < 0 else 1.0
        step = np.where(np.einsum("ij,ij->i", x[1:], x[:-1]) < 0, -1.0, 1.0)
        x[1:] *= np.cumprod(step)[:, None]        # x[0] is already turned: steps chain from it
        out[p.side] = -x[::-1] if i % 2 == 1 else x       # generation direction
    return out
