"""`ReachabilityReport`: what the robot can do with a set of TCP paths, pose by pose.

Per pose (all passes concatenated, with `pass_index` / `pose_index`): reachable or not, position
and orientation residual of the IK solution, joint-limit margin, manipulability, distance to the
wrist singularity and the joint jump to the previous sample of the same pass. Unreachable poses are
reported, never dropped. `ReachabilityReport.measure(...)` re-measures everything from the joint
solution with forward kinematics, so the report does not trust the solver.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

if TYPE_CHECKING:
    from paintcell.robots.robot import Robot


@dataclass(frozen=True)
class ReachabilityThresholds:
    """Acceptance thresholds of a pose.

    pos_tol_m: largest position residual of a reachable pose [m].
    rot_tol_rad: largest orientation residual (angle of R_target^T R, or of the spray axes with
        free spin) [rad].
    wrist_sin_min: |sin q5| below this is reported as too close to the wrist singularity.
    max_joint_jump_rad: a larger jump between consecutive samples of one pass is a discontinuity.
    """

    pos_tol_m: float = 1e-6
    rot_tol_rad: float = 1e-5
    wrist_sin_min: float = 0.05
    max_joint_jump_rad: float = 0.2


@dataclass(frozen=True, eq=False)
class ReachabilityReport:
    """Per-pose arrays, all of shape (P,) over the concatenated passes, and a summary."""

    robot_name: str
    pass_index: np.ndarray          # (P,) int
    pose_index: np.ndarray          # (P,) int, index inside its pass
    reachable: np.ndarray           # (P,) bool: residuals within tolerance, joints within limits
    pos_residual_m: np.ndarray      # (P,) [m]
    rot_residual_rad: np.ndarray    # (P,) [rad]
    limit_margin_rad: np.ndarray    # (P,) smallest distance to a joint limit [rad]
    manipulability: np.ndarray      # (P,) sqrt(det(J Jᵀ)) of the 6×n TCP Jacobian
    wrist_sin: np.ndarray           # (P,) |sin q5| (distance to the wrist singularity); nan if none
    joint_jump_rad: np.ndarray      # (P,) max |q_i - q_{i-1}| within the pass (0 at a pass start)
    thresholds: ReachabilityThresholds
    free_spin: bool = False

    # --- construction -----------------------------------------------------------------------
    @classmethod
    def measure(cls, robot: Robot, Q: npt.ArrayLike, T_world_tcp: npt.ArrayLike,
                pass_index: npt.ArrayLike | None = None, free_spin: bool = False,
                thresholds: ReachabilityThresholds | None = None) -> ReachabilityReport:
        """Re-measure joint solutions Q (P, n) [rad] against targets T_world_tcp (P, 4, 4)."""
        Q = np.asarray(Q, float)
        T = np.asarray(T_world_tcp, float)
        th = thresholds or ReachabilityThresholds()
        P = len(Q)
        passes = np.zeros(P, int) if pass_index is None else np.asarray(pass_index, int)
        pose_index = np.zeros(P, int)
        for p in np.unique(passes):
            sel = np.flatnonzero(passes == p)
            pose_index[sel] = np.arange(len(sel))
        finite = np.all(np.isfinite(Q), axis=1)
        Qs = np.where(finite[:, None], Q, robot.q_home)
        T_q = robot.fk_many(Qs)
        pos_res = np.linalg.norm(T_q[:, :3, 3] - T[:, :3, 3], axis=1)
        if free_spin:
            c = np.clip(np.sum(T_q[:, :3, 2] * T[:, :3, 2], axis=1), -1.0, 1.0)
            rot_res = np.arccos(c)
        else:
            Rrel = np.swapaxes(T[:, :3, :3], 1, 2) @ T_q[:, :3, :3]
            c = np.clip((np.trace(Rrel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
            rot_res = np.arccos(c)
            # arccos loses precision near 0: use the skew part there.
            skew = np.stack([Rrel[:, 2, 1] - Rrel[:, 1, 2], Rrel[:, 0, 2] - Rrel[:, 2, 0],
                             Rrel[:, 1, 0] - Rrel[:, 0, 1]], axis=1) / 2.0
            small = rot_res < 1e-3
            rot_res[small] = np.arcsin(np.clip(np.linalg.norm(skew[small], axis=1), 0, 1))
        margin = robot.limit_margin(Qs)
        manip = np.empty(P)
        for i, q in enumerate(Qs):
            J = pin.computeFrameJacobian(robot.pin_model, robot.pin_data, q, robot.tcp_frame_id,
                                         pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            manip[i] = np.sqrt(max(np.linalg.det(J @ J.T), 0.0))
        wi = robot.wrist_joint_index
        wrist = np.abs(np.sin(Qs[:, wi])) if wi is not None else np.full(P, np.nan)
        jump = np.zeros(P)
        same = np.r_[False, passes[1:] == passes[:-1]]
        d = np.abs(np.diff(Qs, axis=0)).max(axis=1) if P > 1 else np.zeros(0)
        jump[1:] = np.where(same[1:], d, 0.0)
        reach = (finite & (pos_res <= th.pos_tol_m) & (rot_res <= th.rot_tol_rad)
                 & (margin >= -1e-12))
        for a in (pos_res, rot_res, margin, manip, wrist, jump):
            a[~finite] = np.nan
        return cls(robot.name, passes, pose_index, reach, pos_res, rot_res, margin, manip, wrist,
                   jump, th, free_spin)

    @classmethod
    def concatenate(cls, reports: list[ReachabilityReport]) -> ReachabilityReport:
        """One report of several passes; report k's passes become pass k."""
        if not reports:
            raise ValueError("no reports to concatenate")
        cat = {name: np.concatenate([getattr(r, name) for r in reports])
               for name in ("pose_index", "reachable", *_PER_POSE)}
        passes = np.concatenate([np.full(len(r.reachable), k) for k, r in enumerate(reports)])
        return cls(reports[0].robot_name, passes, thresholds=reports[0].thresholds,
                   free_spin=reports[0].free_spin, **cat)

    # --- summary ------------------------------------------------------------------------------
    @property
    def n_poses(self) -> int:
        """Number of poses."""
        return int(len(self.reachable))

    @property
    def n_reachable(self) -> int:
        """Number of reachable poses."""
        return int(np.count_nonzero(self.reachable))

    @property
    def all_reachable(self) -> bool:
        """Every pose reachable (residuals and limits); see `continuous` for jumps."""
        return bool(self.n_poses > 0 and self.n_reachable == self.n_poses)

    @property
    def n_near_singular(self) -> int:
        """Poses with |sin q5| below the threshold."""
        return int(np.count_nonzero(self.wrist_sin < self.thresholds.wrist_sin_min))

    @property
    def n_jumps(self) -> int:
        """Consecutive samples of one pass whose joints jump more than the threshold."""
        return int(np.count_nonzero(self.joint_jump_rad > self.thresholds.max_joint_jump_rad))

    @property
    def continuous(self) -> bool:
        """No joint jump above the threshold inside any pass."""
        return self.n_jumps == 0

    def worst_pose(self) -> tuple[int, int]:
        """(pass, index) of the worst pose: largest residual among unreachable poses, else the
        smallest margin (joint limit [rad] or wrist |sin q5|)."""
        if self.n_poses == 0:
            return (-1, -1)
        if not self.all_reachable:
            score = np.nan_to_num(self.pos_residual_m / self.thresholds.pos_tol_m
                                  + self.rot_residual_rad / self.thresholds.rot_tol_rad, nan=np.inf)
            score[self.reachable] = -np.inf
            i = int(np.argmax(score))
        else:
            m = np.fmin(self.limit_margin_rad, self.wrist_sin)
            i = int(np.nanargmin(m))
        return int(self.pass_index[i]), int(self.pose_index[i])

    @property
    def verdict(self) -> str:
        """One line: reachable or not, where it is worst and by how much, the margins (only
        finite numbers: a margin no pose has is left out)."""
        if self.n_poses == 0:
            return "no poses"
        p, i = self.worst_pose()
        k = int(np.flatnonzero((self.pass_index == p) & (self.pose_index == i))[0])
        if self.all_reachable:
            head = "all reachable"
            worst = f"worst pass {p} pose {i}"
        else:
            head = f"UNREACHABLE {self.n_poses - self.n_reachable}/{self.n_poses} poses"
            pos, rot = self.pos_residual_m[k], self.rot_residual_rad[k]
            worst = (f"worst pass {p} pose {i} is {pos:.3f} m out of reach (position residual), "
                     f"orientation residual {rot:.3f} rad" if np.isfinite(pos)
                     else f"worst pass {p} pose {i} has no joint solution")
        parts = [f"{self.robot_name}: {head} ({self.n_poses} poses, "
                 f"{len(np.unique(self.pass_index))} passes); {worst}"]
        if self.n_reachable:
            margin = _nanmin(self.limit_margin_rad[self.reachable])
            if margin is not None:
                parts.append(f"min joint-limit margin {margin:.3f} rad")
        wsin = _nanmin(self.wrist_sin)
        if wsin is not None:
            parts.append(f"min |sin q5| {wsin:.3f}")
        if self.n_near_singular:
            parts.append(f"{self.n_near_singular} poses near the wrist singularity")
        if self.n_jumps:
            parts.append(f"{self.n_jumps} joint jumps > {self.thresholds.max_joint_jump_rad:g} rad")
        return "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe summary plus the per-pose arrays as lists (nan → None)."""
        def lst(a: np.ndarray) -> list[Any]:
            return [None if not np.isfinite(x) else float(x) for x in np.asarray(a, float)]

        p, i = self.worst_pose()
        return {
            "robot": self.robot_name,
            "n_poses": self.n_poses,
            "n_reachable": self.n_reachable,
            "n_unreachable": self.n_poses - self.n_reachable,
            "n_near_singular": self.n_near_singular,
            "n_jumps": self.n_jumps,
            "all_reachable": self.all_reachable,
            "continuous": self.continuous,
            "worst_pass": p,
            "worst_index": i,
            "verdict": self.verdict,
            "free_spin": self.free_spin,
            "thresholds": {k: float(v) for k, v in self.thresholds.__dict__.items()},
            "max_pos_residual_m": _nanmax(self.pos_residual_m),
            "max_rot_residual_rad": _nanmax(self.rot_residual_rad),
            "min_limit_margin_rad": _nanmin(self.limit_margin_rad),
            "min_wrist_sin": _nanmin(self.wrist_sin),
            "max_joint_jump_rad": _nanmax(self.joint_jump_rad),
            "poses": {
                "pass_index": self.pass_index.tolist(),
                "pose_index": self.pose_index.tolist(),
                "reachable": self.reachable.tolist(),
                **{name: lst(getattr(self, name)) for name in _PER_POSE},
            },
        }


#: the per-pose float arrays of a report (NaN where the IK found no solution).
_PER_POSE = ("pos_residual_m", "rot_residual_rad", "limit_margin_rad", "manipulability",
             "wrist_sin", "joint_jump_rad")


def _nanmax(a: np.ndarray) -> float | None:
    return None if not np.any(np.isfinite(a)) else float(np.nanmax(a))


def _nanmin(a: np.ndarray) -> float | None:
    return None if not np.any(np.isfinite(a)) else float(np.nanmin(a))
