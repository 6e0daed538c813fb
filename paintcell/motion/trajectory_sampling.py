"""The program on one clock: its segments (paint passes timed by TOPP-RA, ruckig moves) sampled
analytically at the control period [s], and the speed-following report of the passes (slowdown
runs with the limits active there, per-pass summary).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from paintcell.coverage.plan import CoveragePlan
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.motion.moves import JointMove
from paintcell.motion.time_law import PassTimeLaw, tcp_path_derivatives
from paintcell.motion.trajectory_settings import RobotLike, TrajectorySettings


@dataclass
class Segment:
    """One piece of the program in time order: a pass's time law or a joint move (`kind`: the
    `JointTrajectory` segment code) lasting `duration_s` [s]."""

    kind: int
    duration_s: float
    pass_index: int = -1
    move: JointMove | None = None
    law: PassTimeLaw | None = None


def sample_program(robot: RobotLike, plan: CoveragePlan, segments: list[Segment], dt: float,
                   knot_lists: list[np.ndarray], settings: TrajectorySettings, v_lim: np.ndarray,
                   a_lim: np.ndarray) -> JointTrajectory:
    """The whole program sampled every `dt` [s] from its segments: q, q̇, q̈, the TCP pose and
    speed and the paint trigger, with each pass's limit utilization (`knot_lists`: the passes'
    IK knots; v_lim, a_lim (n,): the joint limits handed to TOPP-RA)."""
    n = int(robot.nq)
    starts = np.concatenate([[0.0], np.cumsum([sg.duration_s for sg in segments])])
    total = float(starts[-1])
    k = int(np.ceil(total / dt - 1e-9)) + 1
    t = np.arange(k) * dt
    seg_of = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(segments) - 1)
    q = np.empty((k, n))
    qd = np.empty((k, n))
    qdd = np.empty((k, n))
    v_plan = np.zeros(k)
    paint = np.zeros(k, bool)
    pass_index = np.full(k, -1, np.int64)
    segment = np.empty(k, np.int64)
    s_pass = np.full(k, np.nan)
    sd_pass = np.full(k, np.nan)
    for j, sg in enumerate(segments):
        idx = np.flatnonzero(seg_of == j)
        if len(idx) == 0:
            continue
        tl = t[idx] - starts[j]
        segment[idx] = sg.kind
        if sg.move is not None:
            q[idx], qd[idx], qdd[idx] = sg.move.sample(tl)
            continue
        law = sg.law
        assert law is not None
        s, sd, q[idx], qd[idx], qdd[idx] = law.joint_state(tl)
        p = plan.passes[sg.pass_index]
        s_knots = knot_lists[sg.pass_index]
        s_pass[idx], sd_pass[idx] = s, sd
        pass_index[idx] = sg.pass_index
        v_plan[idx] = np.interp(s, s_knots, p.speeds_m_s**2) ** 0.5
        # Brush on over the knot intervals whose both ends the plan marks as painted.
        i0 = np.clip(np.searchsorted(s_knots, s, side="right") - 1, 0, len(s_knots) - 1)
        i1 = np.minimum(i0 + 1, len(s_knots) - 1)
        paint[idx] = p.paint_on[i0] & (p.paint_on[i1] | (s <= s_knots[i0]))
    T = robot.fk_many(q)
    slowdowns, summary = _speed_report(plan, segments, starts, t, s_pass, sd_pass, v_plan,
                                       pass_index, robot, settings, v_lim, a_lim)
    return JointTrajectory(t_s=t, q=q, qd=qd, qdd=qdd, tcp_pos_world=T[:, :3, 3],
                           tcp_rot_world=T[:, :3, :3], v_tcp_planned=v_plan, paint_on=paint,
                           pass_index=pass_index, segment=segment, s_pass_m=s_pass,
                           robot_name=str(robot.name), joint_names=tuple(robot.joint_names),
                           slowdowns=tuple(slowdowns), pass_summary=tuple(summary))


def _speed_report(plan: CoveragePlan, segments: list[Segment], starts: np.ndarray,
                  t: np.ndarray, s_pass: np.ndarray, sd_pass: np.ndarray, v_plan: np.ndarray,
                  pass_index: np.ndarray, robot: RobotLike, settings: TrajectorySettings,
                  v_lim: np.ndarray, a_lim: np.ndarray) -> tuple[list[dict[str, Any]],
                                                                 list[dict[str, Any]]]:
    """Slowdown runs and per-pass speed-following summary."""
    slowdowns: list[dict[str, Any]] = []
    summary: list[dict[str, Any]] = []
    names = tuple(robot.joint_names)

    def fk_pos(Q: np.ndarray) -> np.ndarray:
        return robot.fk_many(Q)[:, :3, 3]

    for j, sg in enumerate(segments):
        if sg.law is None:
            continue
        law, i = sg.law, sg.pass_index
        idx = np.flatnonzero(pass_index == i)
        s, sd = s_pass[idx], sd_pass[idx]
        v_act = np.interp(s, law.s_grid, law.tcp_speed_scale_grid) * sd
        deficit = 1.0 - v_act / v_plan[idx]
        slow = deficit > settings.slowdown_threshold
        util = _utilization(law, fk_pos, names, v_lim, a_lim, settings.tcp_a_max_m_s2)
        runs = _runs(slow)
        for r0, r1 in runs:
            s0, s1 = float(s[r0]), float(s[r1 - 1])
            g = (law.s_grid >= s0 - 1e-9) & (law.s_grid <= s1 + 1e-9)
            gi = np.flatnonzero(g)
            lo = max(int(gi[0]) - 1, 0) if len(gi) else int(np.searchsorted(law.s_grid, s0)) - 1
            hi = min(int(gi[-1]) + 2, len(law.s_grid)) if len(gi) else lo + 2
            peak = {name: float(u[max(lo, 0):hi].max()) for name, u in util.items()}
            active = sorted((nm for nm, u in peak.items() if u >= 0.99),
                            key=lambda nm: -peak[nm])
            if not active:
                active = [max(peak, key=lambda nm: peak[nm])]
            slowdowns.append({
                "pass": i, "s_start_m": s0, "s_end_m": s1,
                "t_start_s": float(t[idx[r0]]), "t_end_s": float(t[idx[r1 - 1]]),
                "duration_s": float(t[idx[r1 - 1]] - t[idx[r0]]),
                "max_speed_deficit_pct": float(100 * deficit[r0:r1].max()),
                "limiting": active,
            })
        free = ~slow
        err = np.abs(v_act[free] / v_plan[idx][free] - 1.0) if np.any(free) else np.zeros(1)
        summary.append({
            "pass": i,
            "t_start_s": float(starts[j]),
            "length_m": law.length_m,
            "planned_duration_s": plan.passes[i].duration_s,
            "duration_s": law.duration_s,
            "time_ratio": law.duration_s / max(plan.passes[i].duration_s, 1e-12),
            "slowed_fraction": float(np.mean(slow)) if len(slow) else 0.0,
            "max_speed_deficit_pct": float(100 * max(deficit.max(), 0.0)) if len(idx) else 0.0,
            "max_following_error_pct_unconstrained": float(100 * err.max()),
            "start_speed_clipped": law.sd_start_clipped,
            "end_speed_clipped": law.sd_end_clipped,
            "limit_shrink": law.limit_shrink,
            "n_slowdowns": len(runs),
        })
    return slowdowns, summary


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open index ranges [a, b) of the True runs of a boolean array."""
    if not np.any(mask):
        return []
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(),
                    strict=True))


def _utilization(law: PassTimeLaw, fk_pos: Any, names: tuple[str, ...], v_lim: np.ndarray,
                 a_lim: np.ndarray, a_tcp: float) -> dict[str, np.ndarray]:
    """Per grid point, the fraction of each limit (as handed to TOPP-RA) in use."""
    s, sd = law.s_grid, law.sd_grid
    q1, q2 = law.path(s, 1), law.path(s, 2)
    p1, p2 = tcp_path_derivatives(law.path, fk_pos, s)
    # Each grid point sees the s̈ of the intervals on both sides; take the larger use.
    u_l = np.concatenate([law.sdd[:1], law.sdd])
    u_r = np.concatenate([law.sdd, law.sdd[-1:]])
    x = sd**2
    sh = law.limit_shrink
    out: dict[str, np.ndarray] = {}
    for k, nm in enumerate(names):
        out[f"{nm} velocity"] = np.abs(q1[:, k]) * sd / (sh * v_lim[k])
        acc = np.maximum(np.abs(q1[:, k] * u_l + q2[:, k] * x), np.abs(q1[:, k] * u_r
                                                                        + q2[:, k] * x))
        out[f"{nm} acceleration"] = acc / (sh * a_lim[k])
    tcp = np.maximum(np.linalg.norm(p1 * u_l[:, None] + p2 * x[:, None], axis=1),
                     np.linalg.norm(p1 * u_r[:, None] + p2 * x[:, None], axis=1))
    # The TCP polygon is inscribed at cos(π/16) of the disc radius.
    out["TCP acceleration"] = tcp / (sh * a_tcp * np.cos(np.pi / 16))
    return out
