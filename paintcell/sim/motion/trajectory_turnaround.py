"""Moves that back the tool off the part: via poses backed off along −z of the tool [m], the
turn-around between two passes (direct, through a backed-off midpoint, or stopping behind each
end; the fastest whose TCP dip toward the part stays within the limit [m]), and the dip measured
on the sampled program.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from paintcell.sim.motion.joint_trajectory import TURNAROUND, JointTrajectory, TrajectoryError
from paintcell.sim.motion.moves import JointMove
from paintcell.sim.motion.trajectory_paths import _move_tcp_to
from paintcell.sim.motion.trajectory_settings import RobotLike, TrajectorySettings


def _backed_off(robot: RobotLike, q: np.ndarray, clearance_m: float) -> np.ndarray:
    """Via joint position (n,) [rad]: the TCP of FK(q) moved by `clearance_m` [m] along −z of the
    tool (away from the part), same orientation."""
    T = robot.fk(q)
    target = T[:3, 3] - clearance_m * T[:3, 2]
    q_via = _move_tcp_to(robot, q, target, T[:3, :3], iters=40)
    miss = float(np.linalg.norm(robot.fk(q_via)[:3, 3] - target))
    if miss > 1e-3 or np.any(q_via < robot.q_lower) or np.any(q_via > robot.q_upper):
        raise TrajectoryError("a backed-off via pose is not reachable within the joint limits; "
                              "lower the approach/retract/turnaround clearance")
    return q_via


def _turnaround(robot: RobotLike, move: Any, end: tuple[np.ndarray, ...],
                nxt: tuple[np.ndarray, ...], T_end: np.ndarray, T_next: np.ndarray,
                settings: TrajectorySettings, dt: float) -> tuple[list[JointMove],
                                                                  dict[str, Any]]:
    """Moves from the state `end` of one pass to the state `nxt` of the next (see the module
    docstring), tried in order of speed until the TCP dip is within `turnaround_max_dip_m`:

    1. direct: one joint-space move;
    2. via: through the midpoint of the two ends backed off by `turnaround_clearance_m`, passed
       at the mean joint velocity of the direct move (no stop);
    3. backed-off: stop at a via pose behind each end, reconfigure between them.
    If none is within the limit, the candidate with the smallest dip is used. Returns the moves
    and a record (mode, dip [m], duration [s], the direct move's dip and duration).
    """
    zero = np.zeros_like(end[0])
    c = settings.turnaround_clearance_m
    direct = move(end, nxt)
    direct_dip = _move_dip(robot, direct, T_end, T_next, dt)

    def via_moving() -> list[JointMove] | None:
        Ta, Tb = robot.fk(end[0]), robot.fk(nxt[0])
        z = Ta[:3, 2] + Tb[:3, 2]
        z = z / max(float(np.linalg.norm(z)), 1e-12)
        q_mid = 0.5 * (end[0] + nxt[0])
        target = 0.5 * (Ta[:3, 3] + Tb[:3, 3]) - c * z
        q_via = _move_tcp_to(robot, q_mid, target, robot.fk(q_mid)[:3, :3], iters=40)
        if np.linalg.norm(robot.fk(q_via)[:3, 3] - target) > 1e-3:
            return None
        v_cap = 0.8 * np.asarray(settings.velocity_margin * np.asarray(robot.v_max))
        qd_via = np.clip((nxt[0] - end[0]) / direct.duration_s, -v_cap, v_cap)
        return [move(end, (q_via, qd_via, zero)), move((q_via, qd_via, zero), nxt)]

    def backed_off() -> list[JointMove] | None:
        vias = _backed_off_pair(robot, end[0], nxt[0], c)
        if vias is None:
            return None
        states = [end, (vias[0], zero, zero), (vias[1], zero, zero), nxt]
        return [move(x, y) for x, y in zip(states[:-1], states[1:], strict=True)]

    best: tuple[float, str, list[JointMove]] = (direct_dip, "direct", [direct])
    if direct_dip > settings.turnaround_max_dip_m:
        for name, make in (("via", via_moving), ("backed-off", backed_off)):
            try:
                moves = make()
            except TrajectoryError:  # a via outside the joint limits: try the next candidate
                moves = None
            if moves is None:
                continue
            dip = max(_move_dip(robot, m, T_end, T_next, dt) for m in moves)
            if dip < best[0]:
                best = (dip, name, moves)
            if dip <= settings.turnaround_max_dip_m:
                break
    dip, name, moves = best
    return moves, {"mode": name, "dip_m": dip,
                   "duration_s": float(sum(m.duration_s for m in moves)),
                   "direct_dip_m": direct_dip, "direct_duration_s": direct.duration_s}


def _backed_off_pair(robot: RobotLike, q_a: np.ndarray, q_b: np.ndarray, clearance_m: float
                     ) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Via poses backed off from both turn-around ends by `clearance_m`, or by 1/2, 1/4 of it
    when that leaves the joint limits: (q_via_a, q_via_b, clearance used [m]), or None."""
    for c in clearance_m * np.array([1.0, 0.5, 0.25]):
        try:
            return _backed_off(robot, q_a, float(c)), _backed_off(robot, q_b, float(c)), float(c)
        except TrajectoryError:
            continue
    return None


def _move_dip(robot: RobotLike, move: JointMove, T_end: np.ndarray, T_next: np.ndarray,
              dt: float) -> float:
    """How much closer to the part [m] the TCP comes during `move` than the deeper of its two
    end poses T_end, T_next (4, 4), along their mean spray axis (sampled every `dt` [s])."""
    q, _, _ = move.sample(np.arange(0.0, move.duration_s + dt, dt))
    p = robot.fk_many(q)[:, :3, 3]
    z = T_end[:3, 2] + T_next[:3, 2]
    z = z / max(float(np.linalg.norm(z)), 1e-12)
    deepest_end = max(0.0, float((T_next[:3, 3] - T_end[:3, 3]) @ z))
    return max(0.0, float(np.max((p - T_end[:3, 3]) @ z)) - deepest_end)


def _turnaround_dip(traj: JointTrajectory, T_world_tcp: list[np.ndarray]) -> float:
    """Deepest excursion of the TCP toward the part during turn-arounds [m], beyond the deeper
    of the two pass ends it joins: displacement along the mean spray axis of the two ends
    (≤ 0: the turn-around stays behind both standoff points)."""
    dip = 0.0
    seg = traj.segment
    for i in range(len(T_world_tcp) - 1):
        after = np.flatnonzero(traj.pass_index == i)
        if len(after) == 0:
            continue
        k0 = after[-1] + 1
        rest = np.flatnonzero(seg[k0:] != TURNAROUND)
        k1 = k0 + (int(rest[0]) if len(rest) else len(seg) - k0)
        if k1 == k0:
            continue
        z = T_world_tcp[i][-1, :3, 2] + T_world_tcp[i + 1][0, :3, 2]
        z = z / max(float(np.linalg.norm(z)), 1e-12)
        p_end, p_next = T_world_tcp[i][-1, :3, 3], T_world_tcp[i + 1][0, :3, 3]
        deepest_end = max(0.0, float((p_next - p_end) @ z))
        dip = max(dip, float(np.max((traj.tcp_pos_world[k0:k1] - p_end) @ z)) - deepest_end)
    return dip
