"""Joint paths of the paint passes: IK of every pass (given or from `paintcell.robots.paths`) with
the
combined reachability summary, and the C² joint spline q(s) over the planned TCP arc length s [m],
refined with corrected knots (damped Newton steps on the TCP) until its FK stays within the path
tolerance [m] of the planned TCP polyline.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

import numpy as np
import pinocchio as pin

from paintcell.motion.joint_trajectory import TrajectoryError
from paintcell.motion.time_law import JointPath
from paintcell.motion.trajectory_settings import RobotLike, TrajectorySettings
from paintcell.robots.rail import RAIL_JOINT


def ik_paths(robot: RobotLike, T_world_tcp: list[np.ndarray], q_home: np.ndarray,
             settings: TrajectorySettings, ik_results: Sequence[Any] | None
             ) -> tuple[list[np.ndarray], dict[str, Any] | None]:
    """Joint paths (M_i, n) of every pass, from `ik_results` or `paintcell.robots.ik`, and the
    combined
    reachability summary (`ReachabilityReport.to_dict()` without per-pose arrays; None when the
    results carry no report)."""
    n = int(robot.nq)
    if ik_results is None:
        from paintcell.robots.paths import (
            solve_paths,  # robots/ is the only IK; imported when needed
        )

        # Each pass is seeded with the end of the previous one, the first with home.
        ik_results = solve_paths(cast(Any, robot), list(T_world_tcp), q_seed=q_home,
                                 free_spin=settings.ik_free_spin)
    if len(ik_results) != len(T_world_tcp):
        raise TrajectoryError(f"ik_results has {len(ik_results)} passes, the plan has "
                              f"{len(T_world_tcp)}; solve IK for the same plan")
    q_paths = []
    for i, (r, Tw) in enumerate(zip(ik_results, T_world_tcp, strict=True)):
        q = np.asarray(getattr(r, "q", r), float)
        if q.shape != (len(Tw), n) or not np.all(np.isfinite(q)):
            raise TrajectoryError(f"IK result of pass {i} has shape {q.shape}, expected "
                                  f"({len(Tw)}, {n}) finite joint values")
        q_paths.append(q)
    reports = [getattr(r, "reachability", None) for r in ik_results]
    summary = None
    if reports and all(r is not None for r in reports):
        from paintcell.robots.reachability import ReachabilityReport

        summary = ReachabilityReport.concatenate(cast(list[Any], reports)).to_dict()
        # per-pose flags that paintcell.validation.honest_reach needs (validate drops them from
        # its report)
        poses = summary.pop("poses", {})
        summary["poses"] = {k: poses[k] for k in ("reachable", "joint_jump_rad") if k in poses}
    return q_paths, summary


# --- joint path refinement -----------------------------------------------------------------------
def refined_path(robot: RobotLike, fk_pos: Any, s_plan: np.ndarray, p_plan: np.ndarray,
                 q_knots: np.ndarray, tol_m: float, max_rounds: int = 4) -> tuple[JointPath,
                                                                                   float]:
    """Spline through the IK samples, with corrected midpoint knots where its FK strays.

    Returns the path and its largest deviation [m] from the planned polyline (checked at the
    knots and at 3 points inside every knot interval).
    """
    if np.any(np.diff(s_plan) <= 1e-9):
        raise TrajectoryError("a pass repeats a TCP position (zero-length step); remove "
                              "duplicate samples from the plan")
    s, q = s_plan.copy(), q_knots.copy()
    frac = np.array([0.25, 0.5, 0.75])
    # A rail's carriage stays where `paintcell.robots.rail` put it for the pass: the inserted
    # knots move the arm only (moving the carriage too left it drifting at the pass's ends, out
    # through its travel's end when it sat there).
    hold = np.array([n == RAIL_JOINT for n in robot.joint_names])
    for _ in range(max_rounds + 1):
        path = JointPath(s, q)
        s_chk = (s[:-1, None] + np.diff(s)[:, None] * frac).ravel()
        dev_in = np.linalg.norm(fk_pos(path(s_chk)) - _lerp_rows(s_plan, p_plan, s_chk), axis=1)
        dev_in = dev_in.reshape(-1, len(frac)).max(axis=1)
        dev_knots = np.linalg.norm(fk_pos(q) - _lerp_rows(s_plan, p_plan, s), axis=1)
        dev = float(max(dev_in.max(), dev_knots.max()))
        # Refine only between IK samples that are themselves on the path (unreachable samples
        # cannot be corrected by more knots).
        on_path = dev_knots <= 0.5 * tol_m
        bad = np.flatnonzero((dev_in > 0.5 * tol_m) & on_path[:-1] & on_path[1:])
        if dev <= tol_m or len(bad) == 0 or len(s) > 8 * len(s_plan):
            return path, dev
        s_new = 0.5 * (s[bad] + s[bad + 1])
        q_new = path(s_new)
        p_target = _lerp_rows(s_plan, p_plan, s_new)
        for k in range(len(s_new)):  # loop over a few inserted knots, not samples
            q_new[k] = move_tcp_to(robot, q_new[k], p_target[k], hold=hold)
        s = np.concatenate([s, s_new])
        q = np.concatenate([q, q_new])
        order = np.argsort(s)
        s, q = s[order], q[order]
    return path, dev


def _lerp_rows(x: np.ndarray, Y: np.ndarray, xq: np.ndarray) -> np.ndarray:
    """Row-wise linear interpolation of Y (M, d) at xq (K,)."""
    return np.column_stack([np.interp(xq, x, Y[:, k]) for k in range(Y.shape[1])])


def move_tcp_to(robot: RobotLike, q: np.ndarray, p_target: np.ndarray,
                R_target: np.ndarray | None = None, iters: int = 8,
                hold: np.ndarray | None = None) -> np.ndarray:
    """Damped Newton steps moving the TCP to p_target (3,) [m], holding R_target (default: the
    orientation at q). hold: (n,) bool, joints kept where they are. Returns the new q (n,)."""
    q = np.array(q, float)
    T = robot.fk(q)
    R_target = T[:3, :3] if R_target is None else R_target
    for _ in range(iters):
        err = np.concatenate([p_target - T[:3, 3], pin.log3(R_target @ T[:3, :3].T)])
        if np.linalg.norm(err) < 1e-10:
            break
        J = robot.jacobian(q)
        if hold is not None:
            J = np.where(hold[None, :], 0.0, J)
        # Projected onto the joint limits: the other joints take over the remaining error.
        q = np.clip(q + J.T @ np.linalg.solve(J @ J.T + 1e-8 * np.eye(6), err), robot.q_lower,
                    robot.q_upper)
        T = robot.fk(q)
    return q
