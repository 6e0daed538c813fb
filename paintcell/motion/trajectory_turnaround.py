"""Moves that back the tool off the part: via poses backed off along −z of the tool [m], the
turn-around between two passes (direct, through a backed-off midpoint, or stopping behind each
end; the fastest whose TCP dip toward the part stays within the limit [m]), approach and
retract through their backed-off via (passed moving where that is faster and comes no closer to
the part), and the dip measured on the sampled program.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from paintcell.motion.joint_trajectory import TURNAROUND, JointTrajectory, TrajectoryError
from paintcell.motion.moves import JointMove
from paintcell.motion.trajectory_paths import move_tcp_to
from paintcell.motion.trajectory_settings import RobotLike, TrajectorySettings


def backed_off_via(robot: RobotLike, q: np.ndarray, clearance_m: float) -> np.ndarray:
    """Via joint position (n,) [rad]: the TCP of FK(q) moved by `clearance_m` [m] along −z of the
    tool (away from the part), same orientation."""
    T = robot.fk(q)
    target = T[:3, 3] - clearance_m * T[:3, 2]
    q_via = move_tcp_to(robot, q, target, T[:3, :3], iters=40)
    miss = float(np.linalg.norm(robot.fk(q_via)[:3, 3] - target))
    if miss > 1e-3 or np.any(q_via < robot.q_lower) or np.any(q_via > robot.q_upper):
        raise TrajectoryError("a backed-off via pose is not reachable within the joint limits; "
                              "lower the approach/retract/turnaround clearance")
    return q_via


def turnaround(robot: RobotLike, move: Any, end: tuple[np.ndarray, ...],
               nxt: tuple[np.ndarray, ...], T_end: np.ndarray, T_next: np.ndarray,
               settings: TrajectorySettings, dt: float) -> tuple[list[JointMove],
                                                                  dict[str, Any]]:
    """Moves from the state `end` of one pass to the state `nxt` of the next (see the module
    docstring), tried in order of speed until the TCP dip is within `turnaround_max_dip_m`:

    1. direct: one joint-space move;
    2. via: through the midpoint of the two ends backed off by `turnaround_clearance_m` (or ¾,
       ½, ¼ of it), passed without stopping at ½, 1, 1.5 or 2 times the mean joint velocity of
       the direct move (capped at 0.8 of the usable joint velocity): the fastest of these whose
       dip is within the limit;
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
        v_cap = 0.8 * np.asarray(settings.velocity_margin * np.asarray(robot.v_max))
        fastest: tuple[float, float, list[JointMove]] | None = None  # within the dip limit
        shallowest: tuple[float, list[JointMove]] | None = None  # if none is
        for f in VIA_CLEARANCE_FRACTIONS:
            target = 0.5 * (Ta[:3, 3] + Tb[:3, 3]) - f * c * z
            q_via = move_tcp_to(robot, q_mid, target, robot.fk(q_mid)[:3, :3], iters=40)
            if np.linalg.norm(robot.fk(q_via)[:3, 3] - target) > 1e-3:
                continue
            for g in VIA_SPEED_FACTORS:
                qd_via = np.clip(g * (nxt[0] - end[0]) / direct.duration_s, -v_cap, v_cap)
                try:
                    moves = [move(end, (q_via, qd_via, zero)), move((q_via, qd_via, zero), nxt)]
                except TrajectoryError:
                    continue
                t = float(sum(m.duration_s for m in moves))
                if fastest is not None and t >= fastest[0]:
                    continue
                dip = max(_move_dip(robot, m, T_end, T_next, dt) for m in moves)
                if dip <= settings.turnaround_max_dip_m:
                    fastest = (t, dip, moves)
                elif shallowest is None or dip < shallowest[0]:
                    shallowest = (dip, moves)
        if fastest is not None:
            return fastest[2]
        return None if shallowest is None else shallowest[1]

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


#: How much nearer the part [m] a moving approach/retract via may bring the TCP than stopping
#: there does: none, beyond the sampling's round-off (a via exists to keep the bell away).
VIA_DIP_TOLERANCE_M = 1e-6


def through_via(robot: RobotLike, move: Any, a: tuple[np.ndarray, ...], q_via: np.ndarray,
                b: tuple[np.ndarray, ...], T_pass: np.ndarray, settings: TrajectorySettings,
                dt: float) -> tuple[list[JointMove], dict[str, Any]]:
    """Approach or retract moves from state `a` through the backed-off via `q_via` (n,) [rad] to
    state `b`, one of them a pass end whose TCP pose is `T_pass` (4, 4).

    Candidates: stop at the via (at rest), or pass it moving, at the mean joint velocity of
    either leg of the resting version or of both together, full or half (capped at 0.8 of the
    usable joint velocity, as a turn-around's midpoint via). The fastest moving one is used when
    it beats the stop and its TCP comes no closer to the part, along the pass end's spray axis,
    than the resting one does (`VIA_DIP_TOLERANCE_M`: the via exists to back the bell off before
    it turns toward the part). Returns the moves and a record (mode, dip [m] of the chosen moves,
    duration [s], the resting candidate's duration and dip).
    """
    zero = np.zeros_like(q_via)
    rest = [move(a, (q_via, zero, zero)), move((q_via, zero, zero), b)]
    dip_rest = max(_move_dip(robot, m, T_pass, T_pass, dt) for m in rest)
    t_rest = float(sum(m.duration_s for m in rest))
    record = {"mode": "via at rest", "dip_m": dip_rest, "duration_s": t_rest,
              "at_rest_duration_s": t_rest, "at_rest_dip_m": dip_rest}
    v_cap = 0.8 * settings.velocity_margin * np.asarray(robot.v_max, float)
    # Via velocities tried: the mean joint velocity of each leg at rest and of the two together
    # (full and half): the fastest candidate within the dip bound wins.
    mean_v = [(q_via - a[0]) / rest[0].duration_s, (b[0] - q_via) / rest[1].duration_s,
              (b[0] - a[0]) / t_rest]
    best: tuple[float, list[JointMove], float] | None = None
    for qd in [f * v for v in mean_v for f in (2.0, 1.5, 1.0, 0.5)]:
        qd_via = np.clip(qd, -v_cap, v_cap)
        try:
            moving = [move(a, (q_via, qd_via, zero)), move((q_via, qd_via, zero), b)]
        except TrajectoryError:  # this one would leave the joint limits
            continue
        t_moving = float(sum(m.duration_s for m in moving))
        if t_moving >= (t_rest if best is None else best[0]):
            continue
        dip = max(_move_dip(robot, m, T_pass, T_pass, dt) for m in moving)
        if dip <= dip_rest + VIA_DIP_TOLERANCE_M:
            best = (t_moving, moving, dip)
    if best is not None:
        record.update(mode="moving via", dip_m=best[2], duration_s=best[0])
        return best[1], record
    return rest, record


#: Turn-around midpoint vias tried: back-offs as fractions of `turnaround_clearance_m`, and via
#: joint velocities as multiples of the direct move's mean joint velocity.
VIA_CLEARANCE_FRACTIONS = (1.0, 0.75, 0.5, 0.25)
VIA_SPEED_FACTORS = (0.5, 1.0, 1.5, 2.0)


def _backed_off_pair(robot: RobotLike, q_a: np.ndarray, q_b: np.ndarray, clearance_m: float
                     ) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Via poses backed off from both turn-around ends by `clearance_m`, or by 1/2, 1/4 of it
    when that leaves the joint limits: (q_via_a, q_via_b, clearance used [m]), or None."""
    for c in clearance_m * np.array([1.0, 0.5, 0.25]):
        try:
            return (backed_off_via(robot, q_a, float(c)), backed_off_via(robot, q_b, float(c)),
                    float(c))
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


def turnaround_dip(traj: JointTrajectory, T_world_tcp: list[np.ndarray]) -> float:
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
