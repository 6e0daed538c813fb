"""Score a robot base by what the run will suffer, not by joint margin alone.

`paintcell.robots.placement.find_base_pose` used to rank bases by the worst joint-limit / wrist
margin; on a
real door it picked a base that lost 6.3 pp of film to time-law slowdowns. Here a candidate base
is scored on the subsampled paths with the IK the run will use
(`paintcell.robots.paths.solve_paths`: closed
form + DLS for the ABB arm, DLS for the UR10) by:

- reachability and joint jumps (infeasible when a pose is unreachable or a joint jumps);
- predicted time-law slowdown: the joint speed and acceleration the planned TCP speed demands
  between consecutive poses (finite differences over the TCP arc length at the planned speed),
  against the robot's limits; ratio r > 1 means the time law must slow the TCP by r there, and
  the film (∝ 1/speed) comes out r times thick — the predicted film excess is the RMS of
  max(r − 1, 0) over the poses [%];
- clearance of the arm (points along the chain of joint origins from the shoulder to the wrist,
  a capsule of `link_radius_m`, and the tool from the flange halfway to the TCP, `tool_radius_m`)
  from the part's points and the booth floor (infeasible when < 0),
  at the paint poses and along the moves between them — home → first pass, each turn-around,
  last pass → home — taken as straight lines in joint space (ruckig's time-synchronized moves
  stay close to them); a base whose paint poses all clear the part can still swing the wrist
  through it on the way home;
- joint margin (joint limit and asin|sin q5| [rad]), which only counts below a comfort margin.

cost = predicted film excess [%] + 10 × max(0, comfort − margin) [rad → %-equivalent]
       − 0.01 × margin (tie-break); inf when infeasible.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from scipy.spatial import cKDTree

from paintcell.robots.ik import IKSettings, combined_report
from paintcell.robots.paths import solve_paths
from paintcell.robots.robot import Robot

#: the time law uses this share of the joint speed / acceleration limits
#: (paintcell.motion.trajectory default).
VELOCITY_MARGIN = 0.95
#: weight of a margin shortfall below the comfort margin, per rad, in the cost's % units.
MARGIN_WEIGHT = 10.0


@dataclass(frozen=True)
class MotionScore:
    """How a base pose serves the paths (see the module docstring).

    reachable_fraction: share of poses with an IK solution [-]; n_jumps: joint jumps;
    margin_rad: worst joint-limit / wrist margin [rad]; speed_ratio: largest demanded / allowed
    joint speed (or √ acceleration) ratio [-]; slowed_fraction: share of poses with ratio > 1 [-];
    predicted_film_excess_pct: RMS predicted film excess from slowdowns [%];
    clearance_m: smallest arm-to-part / arm-to-floor clearance [m] (inf: nothing to hit);
    cost: the ranking cost (lower is better, inf when infeasible).
    """

    reachable_fraction: float
    n_jumps: int
    margin_rad: float
    speed_ratio: float
    slowed_fraction: float
    predicted_film_excess_pct: float
    clearance_m: float
    cost: float

    @property
    def feasible(self) -> bool:
        """Every pose reachable, no jump, no contact."""
        return bool(np.isfinite(self.cost))

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (inf → None)."""
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v)
                for k, v in asdict(self).items()}


def arm_points(robot: Robot, Q: np.ndarray, per_link: int = 4) -> np.ndarray:
    """(K, P, 3) points along the chain of joint origins from joint 2 (the shoulder) to the last
    joint, `per_link` per segment, for joint rows Q (K, n) [rad], in the world frame [m]."""
    m, d = robot.pin_model, robot.pin_data
    n = m.njoints
    out = np.empty((len(Q), n - 2, 3))
    for k, q in enumerate(Q):             # FK of every joint: a few poses per candidate
        pin.forwardKinematics(m, d, q)
        out[k] = [d.oMi[j].translation for j in range(2, n)]
    f = np.arange(per_link) / per_link
    seg = out[:, 1:] - out[:, :-1]
    pts = out[:, :-1, None, :] + f[None, None, :, None] * seg[:, :, None, :]
    return np.concatenate([pts.reshape(len(Q), -1, 3), out[:, -1:]], axis=1)


def tool_points(robot: Robot, Q: np.ndarray,
                fractions: tuple[float, ...] = (0.0, 0.25, 0.5)) -> np.ndarray:
    """(K, F, 3) points on the tool for joint rows Q (K, n) [rad], in the world [m]: the flange
    origin and points on the straight line from it toward the TCP at `fractions` of the way (the
    bell body and cup lie within the first half: the TCP sits a standoff beyond the cup)."""
    T = robot.fk_many(Q)                                  # (K, 4, 4) T_world_tcp
    flange = (T @ np.linalg.inv(robot.T_flange_tcp))[:, :3, 3]
    f = np.asarray(fractions, float)[None, :, None]
    return flange[:, None, :] + f * (T[:, None, :3, 3] - flange[:, None, :])


def move_joints(q_paths: Sequence[np.ndarray], q_home: np.ndarray, n: int) -> np.ndarray:
    """(K, nq) joint rows [rad] on the straight joint-space moves home → first pose, last pose
    of each path → first of the next, last pose → home; `n` interior samples per move (ends
    excluded: the paint poses are checked on their own). Paths without poses are skipped."""
    ends = [np.asarray(q_home, float)]
    for q in q_paths:
        if len(q):
            ends += [q[0], q[-1]]
    ends.append(np.asarray(q_home, float))
    a, b = np.array(ends[0::2]), np.array(ends[1::2])
    f = (np.arange(1, n + 1) / (n + 1))[None, :, None]
    return (a[:, None, :] + f * (b - a)[:, None, :]).reshape(-1, a.shape[1])


def motion_score(robot: Robot, paths: Sequence[np.ndarray], speeds_m_s: Sequence[np.ndarray],
                 *, part_points: cKDTree | None = None, floor_z_m: float | None = None,
                 link_radius_m: float = 0.12, tool_radius_m: float = 0.07,
                 free_spin: bool = False,
                 settings: IKSettings | None = None, q_home: np.ndarray | None = None,
                 move_samples: int = 12) -> MotionScore:
    """Score `robot` (at its base) on `paths` (list of (M, 4, 4) T_world_tcp) planned at
    `speeds_m_s` (list of (M,) TCP speeds [m/s]); part_points: a KD-tree of the part's points in
    the world [m] (None: not checked); floor_z_m: the booth floor height [m] (None: none);
    q_home: (n,) the program's home [rad] (default the robot's), start and end of the moves;
    move_samples: joint-space samples per move checked for clearance."""
    s = settings or IKSettings()
    res = solve_paths(robot, list(paths), free_spin=free_spin, settings=s)
    rep = combined_report(res)
    reach = rep.n_reachable / max(rep.n_poses, 1)
    wrist = (np.arcsin(np.clip(np.nanmin(rep.wrist_sin), 0.0, 1.0))
             if robot.wrist_joint_index is not None else np.inf)
    margin = float(min(np.nanmin(rep.limit_margin_rad), wrist))
    v_lim = VELOCITY_MARGIN * np.asarray(robot.v_max, float)
    a_lim = VELOCITY_MARGIN * np.asarray(robot.a_max, float)
    ratios = []
    for r, T, v in zip(res, paths, speeds_m_s, strict=True):
        q = r.q
        if len(q) < 3:
            ratios.append(np.zeros(len(q)))
            continue
        ds = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1)
        v_mid = 0.5 * (v[1:] + v[:-1])
        dt = np.maximum(ds / np.maximum(v_mid, 1e-6), 1e-6)
        qd = np.diff(q, axis=0) / dt[:, None]
        rv = np.max(np.abs(qd) / v_lim, axis=1)
        qdd = np.diff(qd, axis=0) / (0.5 * (dt[1:] + dt[:-1]))[:, None]
        ra = np.sqrt(np.max(np.abs(qdd) / a_lim, axis=1))
        per = np.concatenate([[rv[0]], np.maximum(np.maximum(rv[1:], rv[:-1]), ra), [rv[-1]]])
        ratios.append(per)
    ratio = np.concatenate(ratios) if ratios else np.zeros(1)
    excess = np.maximum(ratio - 1.0, 0.0)
    film = 100.0 * float(np.sqrt(np.mean(excess**2)))
    clearance = np.inf
    if part_points is not None or floor_z_m is not None:
        Q = np.concatenate([r.q for r in res] + [move_joints(
            [r.q for r in res], robot.q_home if q_home is None else q_home, move_samples)])
        Q = Q[np.isfinite(Q).all(axis=1)]
        for pts, rad in ((arm_points(robot, Q).reshape(-1, 3), link_radius_m),
                         (tool_points(robot, Q).reshape(-1, 3), tool_radius_m)):
            if part_points is not None:
                dist, _ = part_points.query(pts)
                clearance = min(clearance, float(dist.min()) - rad)
            if floor_z_m is not None:
                clearance = min(clearance, float(pts[:, 2].min() - floor_z_m) - rad)
    feasible = rep.all_reachable and rep.continuous and clearance >= 0.0
    cost = (film + MARGIN_WEIGHT * max(0.0, s.comfort_margin_rad - margin) - 0.01 * margin
            if feasible else np.inf)
    return MotionScore(reachable_fraction=float(reach), n_jumps=rep.n_jumps, margin_rad=margin,
                       speed_ratio=float(ratio.max()), slowed_fraction=float(np.mean(ratio > 1)),
                       predicted_film_excess_pct=film, clearance_m=float(clearance),
                       cost=float(cost))
