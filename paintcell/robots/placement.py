"""Search the robot base pose that makes a set of TCP paths reachable with the best margin.

Candidates are base poses on the floor (x, y, height; the robot turned to face the paths). Each is
scored with the vectorized closed-form IK (`paintcell.robots.opw`, all 8 branches over every pose at
once):
a path is feasible on a branch when every pose is inside the joint limits, |sin q5| stays above the
threshold and no joint jumps; its margin is the smallest of the joint-limit margin [rad] and
asin|sin q5| [rad] along the path, maximized over branches. The candidate's score is the worst
path margin (−inf when a path is infeasible). Robots without closed-form IK are scored with DLS
`solve_paths` on subsampled paths (slower). The refined candidates are then ranked by what the run
will suffer (`paintcell.robots.placement_score`: predicted time-law slowdown and film excess, jumps,
clearance from the part and the floor, margin). The winner is verified with the full
`solve_paths`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from tqdm import tqdm

from paintcell.robots.errors import RobotError
from paintcell.robots.ik import (
    IKSettings,
    branch_feasibility,
    choose_branch,
    combined_report,
    continuous_branches,
    opw_branches,
)
from paintcell.robots.paths import solve_paths
from paintcell.robots.reachability import ReachabilityReport
from paintcell.robots.robot import Robot


@dataclass(frozen=True, eq=False)
class PlacementReport:
    """Outcome of `find_base_pose`.

    candidates: (C, 4, 4) base poses tried; scores: (C,) worst-case path margin [rad] (−inf:
    some path infeasible; coarse estimate except for the refined candidates); best: index of the
    chosen candidate; reachability: the full IK check at the chosen base.
    """

    candidates: np.ndarray
    scores: np.ndarray
    best: int
    reachability: ReachabilityReport
    #: `paintcell.robots.placement_score.MotionScore` of the refined candidates (index →
    #: score), when the search ranked them by motion (score="motion")
    motion: dict[int, Any] | None = None

    @property
    def T_world_base(self) -> np.ndarray:
        """(4,4) chosen base pose."""
        return self.candidates[self.best]

    @property
    def n_feasible(self) -> int:
        """Candidates where every path is feasible."""
        return int(np.count_nonzero(np.isfinite(self.scores)))

    @property
    def feasible(self) -> bool:
        """The chosen base makes every pose reachable."""
        return bool(np.isfinite(self.scores[self.best]) and self.reachability.all_reachable)

    @property
    def verdict(self) -> str:
        """One line."""
        p = self.T_world_base[:3, 3]
        head = "base found" if self.feasible else "NO fully reachable base"
        return (f"{head}: {self.n_feasible}/{len(self.scores)} candidates feasible; chosen base "
                f"at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m, worst margin "
                f"{self.scores[self.best]:.3f} rad; {self.reachability.verdict}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe summary."""
        s = float(self.scores[self.best])
        chosen = None if self.motion is None else self.motion.get(self.best)
        return {"T_world_base": self.T_world_base.tolist(), "n_candidates": len(self.scores),
                "n_feasible": self.n_feasible, "feasible": self.feasible,
                "worst_margin_rad": s if np.isfinite(s) else None, "verdict": self.verdict,
                "motion_score": None if chosen is None else chosen.to_dict(),
                "reachability": self.reachability.to_dict()}


DEFAULT_DX_M = tuple(np.round(np.arange(-2.0, -0.59, 0.1), 3))
DEFAULT_DY_M = tuple(np.round(np.arange(-0.8, 0.81, 0.1), 3))
DEFAULT_HEIGHTS_M = (0.0, 0.25, 0.5)


def facing_grid(target_world: npt.ArrayLike, dx: npt.ArrayLike = DEFAULT_DX_M,
                dy: npt.ArrayLike = DEFAULT_DY_M,
                heights: npt.ArrayLike = DEFAULT_HEIGHTS_M) -> np.ndarray:
    """(C, 4, 4) base poses at target + (dx, dy) on the floor raised by `heights` [m], each turned
    about z so that its x axis points at the target horizontally. Default: 15 x 17 x 3 poses,
    0.6-2.0 m behind the target, ±0.8 m aside, pedestal 0 / 0.25 / 0.5 m."""
    c = np.asarray(target_world, float)
    X, Y, Z = np.meshgrid(np.asarray(dx, float), np.asarray(dy, float), np.asarray(heights, float),
                          indexing="ij")
    X, Y, Z = X.ravel(), Y.ravel(), Z.ravel()
    yaw = np.arctan2(-Y, -X)
    T = np.zeros((len(X), 4, 4))
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = np.cos(yaw), -np.sin(yaw), np.sin(yaw), \
        np.cos(yaw)
    T[:, 2, 2] = T[:, 3, 3] = 1.0
    T[:, :3, 3] = np.stack([c[0] + X, c[1] + Y, Z], axis=1)
    return T


def path_margin(robot: Robot, Q: np.ndarray, reach: np.ndarray, settings: IKSettings,
                jump_scale: float = 1.0) -> float:
    """Best worst-case margin [rad] of one path over the 8 closed-form branches (−inf if none is
    feasible), from `paintcell.robots.opw.inverse` output Q (M, 8, 6), reach (M, 8). jump_scale: the
    path is
    subsampled by this factor, so the joint-jump threshold grows by it."""
    Qc, _, within = continuous_branches(robot, Q, reach, robot.q_home)
    st = branch_feasibility(robot, Qc, within, settings, jump_scale)
    return float(st.margin[st.feasible].max()) if st.feasible.any() else -np.inf


def find_base_pose(robot: Robot, paths: Sequence[npt.ArrayLike],
                   candidates: npt.ArrayLike | None = None, *, max_poses_per_path: int = 200,
                   coarse_poses_per_path: int = 25, n_refine: int = 20, free_spin: bool = False,
                   settings: IKSettings | None = None, score: str = "motion",
                   speeds_m_s: Sequence[npt.ArrayLike] | None = None,
                   part_points_world: npt.ArrayLike | None = None,
                   floor_z_m: float | None = None, q_home: npt.ArrayLike | None = None,
                   check_infeasible: bool = True) -> tuple[np.ndarray, PlacementReport]:
    """Best base pose T_world_base (4,4) for `paths` (list of (M,4,4) T_world_tcp, part placed).

    candidates: (C,4,4) base poses; default `facing_grid` around the centroid of the paths.
    coarse_poses_per_path, n_refine, max_poses_per_path: every candidate is scored on paths
    subsampled evenly (ends kept) to `coarse_poses_per_path` poses, the best `n_refine` again with
    `max_poses_per_path`; the winner is checked on the full paths.
    score: "motion" (default) ranks the refined candidates by `paintcell.robots.placement_score`
    (predicted time-law slowdown and film excess, jumps, clearance from `part_points_world`
    (K, 3) [m] and the floor at `floor_z_m` [m], joint margin); "margin": by the worst joint
    margin alone (the earlier rule). speeds_m_s: per path (M,) planned TCP speeds [m/s]
    (default 0.5 m/s everywhere). q_home: (n,) the program's home [rad] (default the robot's):
    the motion score also checks the clearance along the moves from and to it.
    check_infeasible: False skips the full (damped least squares) check when no candidate is
    feasible — the report is then that of the closed-form branch each pass would start on
    (`_branch_report`): the same verdict ("NO fully reachable base"), counted without the DLS's
    best-effort walk through every unreachable pose (4–5 s per arm on crs_cowling_creases, whose
    `init` refusal quotes only the counts).
    Returns (T_world_base, PlacementReport); the report says when no candidate is feasible (the
    one with the most reachable poses is returned then).
    """
    if score not in ("motion", "margin"):
        raise RobotError(f"score = {score!r}: use 'motion' or 'margin'")
    s = settings or IKSettings()
    P = [np.asarray(p, float) for p in paths]
    if not P or any(p.ndim != 3 or p.shape[1:] != (4, 4) or len(p) == 0 for p in P):
        raise RobotError("paths must be a non-empty list of (M, 4, 4) T_world_tcp arrays")
    if candidates is None:
        centroid = np.concatenate([p[:, :3, 3] for p in P]).mean(axis=0)
        C = facing_grid(centroid)
    else:
        C = np.asarray(candidates, float).reshape(-1, 4, 4)
    # Coarse pass over every candidate (the ends of each path and a few samples between), then the
    # best `n_refine` candidates again with up to `max_poses_per_path` poses per path.
    scores, fallback = _score(robot, C, _subsample(P, coarse_poses_per_path), free_spin, s)
    order = np.argsort(-np.where(np.isfinite(scores), scores, -1e9 + fallback))
    top = order[:n_refine]
    fine = _score(robot, C[top], _subsample(P, max_poses_per_path), free_spin, s)
    scores[top], fallback[top] = fine
    # The winner among the refined candidates (coarse scores overestimate the margin).
    key = np.where(np.isfinite(fine[0]), fine[0], -1e9 + fine[1])
    best = int(top[int(np.argmax(key))])
    motion = None
    if score == "motion":
        motion = _motion_ranked(robot, C, top[np.isfinite(fine[0])], P, speeds_m_s,
                                part_points_world, floor_z_m, max_poses_per_path, free_spin, s,
                                q_home)
        ok = {c: m for c, m in motion.items() if m.feasible}
        if ok:
            best = min(ok, key=lambda c: ok[c].cost)
    placed = robot.placed(C[best])
    if not check_infeasible and not np.isfinite(scores).any() and placed.has_closed_form \
            and not free_spin:
        rep = _branch_report(placed, P, s)
    else:
        rep = combined_report(solve_paths(placed, P, free_spin=free_spin, settings=s))
    report = PlacementReport(candidates=C, scores=scores, best=best, reachability=rep,
                             motion=motion)
    return C[best].copy(), report


def _branch_report(robot: Robot, P: list[np.ndarray], s: IKSettings) -> ReachabilityReport:
    """Reachability of `paths` on the closed-form branch `solve_path` starts each pass on (its
    `choose_branch`, seeded by the previous pass's end), measured as it is: joints clipped to
    their limits, a pose no branch solves holding the pass's last solved one (the first
    solved one before any)."""
    reports, seed = [], None
    for T in P:
        Qc, _, within = opw_branches(robot, T, seed if seed is not None else robot.q_home)
        q = np.clip(Qc[choose_branch(robot, Qc, within, seed, s)], robot.q_lower, robot.q_upper)
        fin = np.all(np.isfinite(q), axis=1)
        if fin.any():
            last = np.maximum.accumulate(np.where(fin, np.arange(len(q)), -1))
            q = q[np.where(last >= 0, last, int(np.argmax(fin)))]
        else:
            q = np.broadcast_to(robot.q_home, q.shape).copy()
        reports.append(ReachabilityReport.measure(robot, q, T, thresholds=s.thresholds()))
        seed = q[-1]
    return ReachabilityReport.concatenate(reports)


def _motion_ranked(robot: Robot, C: np.ndarray, idx: np.ndarray, P: list[np.ndarray],
                   speeds: Sequence[npt.ArrayLike] | None, part_points: npt.ArrayLike | None,
                   floor_z_m: float | None, n: int, free_spin: bool, s: IKSettings,
                   q_home: npt.ArrayLike | None = None) -> dict[int, Any]:
    """`MotionScore` of candidates C[idx] on the paths subsampled to ≤ n poses each."""
    from scipy.spatial import cKDTree

    from paintcell.robots.placement_score import motion_score

    V = [np.full(len(p), 0.5) if speeds is None else np.asarray(v, float)
         for p, v in zip(P, speeds if speeds is not None else P, strict=True)]
    if any(len(v) != len(p) for v, p in zip(V, P, strict=True)):
        raise RobotError("speeds_m_s must give one speed [m/s] per pose of each path")
    keep = [np.unique(np.linspace(0, len(p) - 1, min(len(p), n)).round().astype(int)) for p in P]
    sub = [p[k] for p, k in zip(P, keep, strict=True)]
    vs = [v[k] for v, k in zip(V, keep, strict=True)]
    tree = None if part_points is None else cKDTree(np.asarray(part_points, float))
    return {int(c): motion_score(robot.placed(C[c]), sub, vs, part_points=tree,
                                 floor_z_m=floor_z_m, free_spin=free_spin, settings=s,
                                 q_home=None if q_home is None else np.asarray(q_home, float))
            for c in idx}


def _subsample(paths: list[np.ndarray], n: int) -> list[tuple[np.ndarray, float]]:
    """Evenly subsampled paths (ends kept) with their stride (poses per kept pose)."""
    out = []
    for p in paths:
        idx = np.unique(np.linspace(0, len(p) - 1, min(len(p), n)).round().astype(int))
        out.append((p[idx], (len(p) - 1) / max(len(idx) - 1, 1)))
    return out


def _score(robot: Robot, C: np.ndarray, sub: list[tuple[np.ndarray, float]], free_spin: bool,
           s: IKSettings) -> tuple[np.ndarray, np.ndarray]:
    """(scores (C,) worst path margin [rad] or −inf, reachable fraction (C,)) of base poses C."""
    scores = np.full(len(C), -np.inf)
    fallback = np.zeros(len(C))
    T_tcp_flange = np.linalg.inv(robot.T_flange_tcp)
    allp = np.concatenate([p for p, _ in sub])
    starts = np.cumsum([0] + [len(p) for p, _ in sub])
    strides = [st for _, st in sub]
    first = 0           # the path that sank the previous candidate: the likeliest to sink this one
    # disable=None: a bar only on a terminal (CI logs and pipes stay clean)
    for c, T_base in enumerate(tqdm(C, desc="placement", unit="base", leave=False,
                                    disable=None if len(C) > 50 else True)):
        if robot.has_closed_form and not free_spin:
            # One closed-form call for all paths of the candidate, then path by path.
            flange = np.linalg.inv(T_base) @ allp @ T_tcp_flange
            Q, reach = robot.closed_form_inverse(flange)
            posed = np.asarray(reach.any(axis=1), bool)
            scores[c], first = _worst_margin(robot, Q, reach, posed, starts, strides, s, first)
            fallback[c] = 1.0 if np.isfinite(scores[c]) else posed.mean()
        else:
            paths = [p for p, _ in sub]
            thin = IKSettings(**{**s.__dict__, "max_joint_jump_rad": s.max_joint_jump_rad
                                 * max(st for _, st in sub)})
            rep = combined_report(solve_paths(robot.placed(T_base), paths, free_spin=free_spin,
                                              settings=thin))
            fallback[c] = rep.n_reachable / rep.n_poses
            if rep.all_reachable and rep.continuous:
                wrist = (float(np.arcsin(min(np.nanmin(rep.wrist_sin), 1.0)))
                         if robot.wrist_joint_index is not None else np.inf)
                scores[c] = min(float(np.nanmin(rep.limit_margin_rad)), wrist)
    return scores, fallback


def _worst_margin(robot: Robot, Q: np.ndarray, reach: np.ndarray, posed: np.ndarray,
                  starts: np.ndarray, strides: list[float], s: IKSettings, first: int
                  ) -> tuple[float, int]:
    """(the smallest `path_margin` over the paths, or −inf; the path to try first next time).

    Q (N, 8, 6), reach (N, 8): the closed-form IK of every path's poses, concatenated (path k is
    rows starts[k]:starts[k+1]); posed (N,): some branch reaches the pose. A single infeasible
    path makes the candidate's score −inf, so the search stops there: a path with a pose no branch
    reaches is infeasible on every branch (`branch_feasibility` wants every pose inside the
    limits), and the other paths are scored one by one, the one that sank the previous candidate
    first. The score is the one `min(path_margin(...) for every path)` gives."""
    if not posed.all():
        return -np.inf, int(np.searchsorted(starts, np.argmin(posed), side="right")) - 1
    n = len(strides)
    bounds = list(zip(starts[:-1], starts[1:], strict=True))
    worst = np.inf
    for k in (first, *(j for j in range(n) if j != first)):
        a, b = bounds[k]
        m = path_margin(robot, Q[a:b], reach[a:b], s, max(strides[k], 1.0))
        if not np.isfinite(m):
            return -np.inf, k
        worst = min(worst, m)
    return worst, first
