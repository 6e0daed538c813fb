"""Robot-aware speeds: feed the time law's joint-limit slowdowns back into the speed QP.

The planner (`paintcell.coverage.coverage`) optimizes each pass's TCP speeds for the film,
knowing nothing of
the robot. Along the IK path, joint velocity and acceleration limits can make TOPP-RA slower than
planned; the film then differs from the plan (the "time-law share" of the loss). The loop the
paper leaves open:

    plan → joint program → where the executed TCP speed falls short of the plan, cap the speed of
    those samples at what the robot reached (minus a margin) → re-plan the passes' speeds with
    the caps as per-sample upper bounds of eq. 2 → rebuild the joint program → repeat

The re-plan reproduces the same pass geometry (the planner is deterministic), so the caps of one
plan fit the next. Caps only shrink from one round to the next.

The speed is measured twice: at the plan samples (ds/dt of the program there, `pass_speeds`) and
between them (|dp/dt| at every control sample, `lag_caps`). A robot whose acceleration a joint
takes up can meet the plan at two samples and still lag between them where the plan's speed
climbs steeply out of a slow sample (measured on cad_fender at 10 mm: 14–19 % for 16 ms after a
capped sample, the one pose honest reachability lost); the faster end of such an interval is
capped so that the planned v² rise stays under what the robot reached. A pass gets these caps
once its samples are met within `MET_REL` (in the first rounds its deep slowdowns would cap the
plan far harder than needed).
One robot or N (a booth, `paintcell.booth.booth_speeds`) are measured alike: `part_speeds`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np

from paintcell.core.errors import PaintcellError
from paintcell.coverage.coverage import PlannerSettings, plan_coverage
from paintcell.coverage.plan import CoveragePlan
from paintcell.paint.applicator import Applicator
from paintcell.surface.surface import Surface

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
#: The bell's x axis counts as followed when the program holds it within this of the plan [deg].
SPIN_TOL_DEG = 1.0


@dataclass
class FeedbackResult:
    """Outcome of the robot-aware loop.

    plan / trajectory: the final plan and its joint program.
    rounds: per round, {"capped_samples", "max_deficit_pct", "cycle_s"} of the program that was
        measured (round 0 = the robot-free plan).
    caps_m_s: the final caps {pass side: (M,) [m/s]} in each pass's generation direction.
    """

    plan: CoveragePlan
    trajectory: Any
    rounds: list[dict[str, Any]] = field(default_factory=list)
    caps_m_s: dict[int, np.ndarray] = field(default_factory=dict)


def pass_speeds(p: Any, traj: Any, index: int) -> np.ndarray:
    """The TCP speed a joint program reaches at each sample of pass `p` [m/s] ((M,)).

    traj: `paintcell.motion.joint_trajectory.JointTrajectory` whose samples with
    pass_index == index run `p` (s_pass_m along the plan samples' arc length). The speed is ds/dt
    of the program's samples, interpolated at the plan samples; the plan's own speeds where the
    program has fewer than 3 samples of the pass.
    """
    s_plan = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                             axis=1))])
    idx = np.flatnonzero(traj.pass_index == index)
    if len(idx) < 3:
        return np.asarray(p.speeds_m_s, float).copy()
    s = traj.s_pass_m[idx]
    v = np.gradient(s, traj.t_s[idx])
    order = np.argsort(s, kind="stable")
    return np.interp(s_plan, s[order], v[order])


def lag_caps(p: Any, traj: Any, index: int, lag_rel: float = LAG_REL,
             margin: float = CAP_MARGIN) -> np.ndarray:
    """Caps [m/s] ((M,), inf where none) that bring the plan of pass `p` under what the joint
    program reached BETWEEN its samples.

    traj: the `JointTrajectory` whose samples with pass_index == index run `p`. The program's TCP
    speed v = |dp/dt| at every control sample is compared with the planned speed there
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
    s_plan = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                             axis=1))])
    caps = np.full(len(s_plan), np.inf)
    idx = np.flatnonzero(traj.pass_index == index)
    if len(idx) < 3 or len(s_plan) < 2:
        return caps
    v_a = np.linalg.norm(np.gradient(traj.tcp_pos_world[idx], traj.t_s[idx], axis=0), axis=1)
    v_p = np.asarray(traj.v_tcp_planned, float)[idx]
    s = traj.s_pass_m[idx]
    lag = np.isfinite(s) & (v_p > 1e-9) & (v_a < (1.0 - lag_rel) * v_p)
    # as honest reach judges them: a control sample counts for its nearest plan pose, and the
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
                programs: Sequence[Any], lags: bool = False, margin: float = CAP_MARGIN
                ) -> list[list[np.ndarray]]:
    """Per part, per pass of its plan, the TCP speed its robot reaches at each sample [m/s]
    (`pass_speeds`; jobs: {robot: its jobs, passes [first, end) of plan `part`, run on in its
    program from `meta["job_first_pass_index"]`, default 0}); the plan's own speeds for a pass
    no robot runs. lags: instead, the caps between samples (`lag_caps`; inf where none) [m/s]."""
    out = [[np.full(len(p.speeds_m_s), np.inf) if lags else np.asarray(p.speeds_m_s, float)
            for p in pl.passes] for pl in plans]
    for r, js in jobs.items():
        traj = programs[r]
        firsts = traj.meta.get("job_first_pass_index", [0])
        for k, job in enumerate(js):
            for m in range(job.end - job.first):
                p = plans[job.part].passes[job.first + m]
                out[job.part][job.first + m] = (lag_caps(p, traj, firsts[k] + m, margin=margin)
                                                if lags else pass_speeds(p, traj, firsts[k] + m))
    return out


def _one_robot(plan: CoveragePlan) -> dict[int, tuple[Any, ...]]:
    """The jobs of a one-robot cell: its robot runs every pass of its one part."""
    return {0: (SimpleNamespace(part=0, first=0, end=len(plan.passes)),)}


def achieved_speeds(plan: CoveragePlan, traj: Any) -> list[np.ndarray]:
    """Per pass, the TCP speed the joint program reaches at each plan sample [m/s] ((M,) each;
    `pass_speeds` of pass i at pass_index i)."""
    return part_speeds([plan], _one_robot(plan), [traj])[0]


def speed_caps(plan: CoveragePlan, traj: Any, previous: dict[int, np.ndarray] | None = None,
               slow_rel: float = SLOW_REL, margin: float = CAP_MARGIN
               ) -> tuple[dict[int, np.ndarray], int, float]:
    """Caps {side: (M,) [m/s]} where the program is slower than the plan, in generation direction.

    Returns (caps, number of newly capped samples, largest speed deficit [%]; the samples capped
    include those of `lag_caps`, the deficit is the one at the samples).
    """
    lags = part_speeds([plan], _one_robot(plan), [traj], lags=True, margin=margin)[0]
    return caps_from_speeds(plan, achieved_speeds(plan, traj), None, previous, slow_rel, margin,
                            lags)


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
        s_plan = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                                 axis=1))])
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


def with_targets(plan: CoveragePlan, targets: CoveragePlan) -> CoveragePlan:
    """`plan` with the travel directions (TCP x axes, the robot's orientation targets) of
    `targets`, a plan of the same passes (same sides and sample counts; otherwise `plan` as it
    is): the program of a spin-fed re-plan is built from the targets the robot's spin came from,
    while the plan's own travel directions stay the film model's (`tool_x`)."""
    from dataclasses import replace

    same = len(plan.passes) == len(targets.passes) and all(
        a.side == b.side and len(a.travel_dirs) == len(b.travel_dirs)
        for a, b in zip(plan.passes, targets.passes, strict=True))
    if not same:
        return plan
    passes = tuple(replace(a, travel_dirs=b.travel_dirs)
                   for a, b in zip(plan.passes, targets.passes, strict=True))
    return replace(plan, passes=passes)


def robot_aware_plan(surface: Surface, app: Applicator, settings: PlannerSettings,
                     plan: CoveragePlan, traj: Any, build: Any, rounds: int = 3,
                     T_world_part: np.ndarray | None = None) -> FeedbackResult:
    """Re-plan the speeds under the robot's reachable speeds until no new slowdown appears.

    surface, app, settings: what `plan` was planned with; traj: its joint program;
    build: callable plan → joint program (`paintcell.motion.trajectory.build_program` bound to
    the robot and
    placement); rounds: re-plans at most; T_world_part: the part placement — when given, the bell
    x axes the program holds are fed back too (`tool_axes`), so the plan's film model uses the
    orientation the robot really holds about the spray axis.
    Returns the final plan and program; a round whose program is slower than the first by more
    than 5 % ends the loop with the previous round's plan.
    """
    res = FeedbackResult(plan, traj)
    cycle0 = float(traj.t_s[-1])
    caps: dict[int, np.ndarray] = {}
    tool_x: dict[int, np.ndarray] = {}
    for _ in range(rounds):
        caps, n_new, worst = speed_caps(res.plan, res.trajectory, caps)
        turn = 0.0
        if T_world_part is not None:
            new_x = tool_axes(res.plan, res.trajectory, T_world_part)
            for i, p in enumerate(res.plan.passes):
                if p.side in new_x:
                    x_plan = p.travel_dirs[::-1] * -1 if i % 2 == 1 else p.travel_dirs
                    cosang = np.clip(np.einsum("ij,ij->i", x_plan, new_x[p.side]), -1, 1)
                    turn = max(turn, float(np.degrees(np.arccos(cosang)).max()))
            tool_x = new_x
        res.rounds.append({"capped_samples": float(n_new), "max_deficit_pct": worst,
                           "cycle_s": float(res.trajectory.t_s[-1]), "max_spin_deg": turn})
        if n_new == 0 and turn < SPIN_TOL_DEG:
            break
        finite = {k: np.where(np.isfinite(v), v, settings.v_max_m_s) for k, v in caps.items()}
        got = None
        # with the bell's spin fed back first; if that program fails or runs > 5 % longer (the
        # IK seeds follow the new target orientation to another branch), with the caps alone
        for use_spin in ([True, False] if tool_x else [False]):
            new_plan = plan_coverage(surface, app, settings, speed_caps_m_s=finite,
                                     tool_x=tool_x if use_spin else None)
            try:
                # the robot keeps the orientation targets of the first program (the free-spin
                # IK found the spin the film now assumes from them); targets equal to that spin
                # send the IK's seeds to other branches
                new_traj = build(with_targets(new_plan, plan) if use_spin else new_plan)
            except PaintcellError as e:      # the re-plan's program failed: try without spin
                res.rounds.append({"failed": str(e), "spin": use_spin})
                if use_spin:
                    tool_x, T_world_part = {}, None
                continue
            if float(new_traj.t_s[-1]) <= 1.05 * cycle0:
                got = (new_plan, new_traj)
                break
            res.rounds.append({"rejected_cycle_s": float(new_traj.t_s[-1]), "spin": use_spin})
            if use_spin:
                tool_x = {}
                T_world_part = None              # the robot cannot hold the plan's spin: stop
        if got is None:
            break
        new_plan, new_traj = got
        res.plan, res.trajectory, res.caps_m_s = new_plan, new_traj, finite
    else:
        _, _, worst = speed_caps(res.plan, res.trajectory, caps)
        res.rounds.append({"capped_samples": 0.0, "max_deficit_pct": worst,
                           "cycle_s": float(res.trajectory.t_s[-1])})
    return res
