"""Placement scored by what the run suffers (paintcell.robots.placement_score), checked against the
real time law: TOPP-RA on the program built at the chosen base
(paintcell.motion.trajectory.build_program), not
the score's own finite differences.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import pytest

from paintcell.motion.trajectory import build_program
from paintcell.robots.catalog import load_robot
from paintcell.robots.placement import facing_grid, find_base_pose
from paintcell.robots.placement_score import motion_score
from tests.test_trajectory import _plan


@functools.lru_cache(maxsize=1)
def _case() -> tuple[Any, Any, list[np.ndarray], list[np.ndarray], np.ndarray]:
    """Three 1 m passes planned at 2.5 m/s (beyond what the arm follows from most bases), and
    two bases on a 0.5 m pedestal facing them: 1.6 m behind their centre (the best joint margin,
    0.56 rad) and 1.2 m behind (0.54 rad)."""
    robot = load_robot("abb_paint")
    plan = _plan(2.5, x0=0.0, spacing=0.2)
    paths = [plan.tcp_frames(i) for i in range(len(plan.passes))]
    speeds = [p.speeds_m_s for p in plan.passes]
    centre = np.concatenate([p[:, :3, 3] for p in paths]).mean(axis=0)
    C = facing_grid(centre, dx=[-1.6, -1.2], dy=[0.0], heights=[0.5])
    return robot, plan, paths, speeds, C


def _real(robot: Any, plan: Any, T_base: np.ndarray) -> tuple[float, float]:
    """(largest pass time ratio, mean slowed fraction) of the real program at T_base."""
    tr = build_program(robot.placed(T_base), plan, np.eye(4))
    return (max(p["time_ratio"] for p in tr.pass_summary),
            float(np.mean([p["slowed_fraction"] for p in tr.pass_summary])))


@pytest.mark.slow
def test_motion_score_picks_the_base_the_time_law_slows_less() -> None:
    robot, plan, paths, speeds, C = _case()
    T_margin, rep_m = find_base_pose(robot, paths, candidates=C, score="margin")
    T_motion, rep = find_base_pose(robot, paths, candidates=C, score="motion",
                                   speeds_m_s=speeds, floor_z_m=0.0)
    assert rep_m.feasible and rep.feasible
    assert not np.allclose(T_margin, T_motion)     # margin alone picks the other base
    assert rep_m.scores[rep_m.best] > rep.scores[rep.best]
    ratio_m, slowed_m = _real(robot, plan, T_margin)
    ratio, slowed = _real(robot, plan, T_motion)
    assert ratio < ratio_m and slowed < slowed_m
    # the predicted slowdown is the real one within 5 % at the chosen base
    chosen = rep.motion[rep.best]
    assert chosen.speed_ratio == pytest.approx(ratio, rel=0.05)
    assert rep.to_dict()["motion_score"]["predicted_film_excess_pct"] > 0


def test_clearance_counts_the_part_and_the_floor() -> None:
    robot, _, paths, speeds, C = _case()
    r = robot.placed(C[1])
    free = motion_score(r, paths, speeds, floor_z_m=0.0)
    # a floor 0.3 m above the shoulder's lowest point: the arm is in it
    from paintcell.robots.paths import solve_paths
    from paintcell.robots.placement_score import arm_points, move_joints, tool_points

    qs = [x.q for x in solve_paths(r, paths)]
    # every joint row the score checks: the paint poses and the moves from home, between the
    # passes and back home (12 samples each); the arm is a 0.12 m capsule, the tool 0.07 m
    q = np.concatenate(qs + [move_joints(qs, r.q_home, 12)])
    low = min(float(arm_points(r, q)[:, :, 2].min()) - 0.12,
              float(tool_points(r, q)[:, :, 2].min()) - 0.07)
    hit = motion_score(r, paths, speeds, floor_z_m=low + 0.12 + 0.3)
    assert free.feasible and free.clearance_m > 0
    assert not hit.feasible and hit.clearance_m == pytest.approx(-0.3 - 0.12, abs=1e-9)


def test_clearance_counts_the_move_home() -> None:
    """A part point where the wrist passes halfway along the move from the last paint pose back
    home (FK of the joint-space midpoint) — clear of every paint pose by > 0.3 m — makes the
    base infeasible; the same point is harmless when home is the last pose (no move)."""
    from scipy.spatial import cKDTree

    from paintcell.robots.paths import solve_paths
    from paintcell.robots.placement_score import arm_points

    robot, _, paths, speeds, C = _case()
    r = robot.placed(C[1])
    qs = [x.q for x in solve_paths(r, paths)]
    q_home = np.asarray(r.q_home, float) + np.array([0.9, -0.3, 0.0, 0.0, 0.0, 0.0])
    q_mid = 0.5 * (qs[-1][-1] + q_home)
    wrist = arm_points(r, q_mid[None])[0, -1]                  # the last joint's origin
    paint = arm_points(r, np.concatenate(qs)).reshape(-1, 3)
    assert np.linalg.norm(paint - wrist, axis=1).min() > 0.3    # no paint pose comes near it
    obstacle = cKDTree(wrist[None])
    # 13 samples per move: the 7th is the midpoint, where the wrist sits on the point
    hit = motion_score(r, paths, speeds, part_points=obstacle, q_home=q_home, move_samples=13)
    assert not hit.feasible and hit.clearance_m == pytest.approx(-0.12, abs=1e-9)
    # with home at the last paint pose's joints, only the approach and turn-arounds move
    near = motion_score(r, paths, speeds, part_points=obstacle, q_home=qs[-1][-1],
                        move_samples=13)
    assert near.clearance_m > hit.clearance_m + 0.1


def test_ur10_placement_is_scored_too() -> None:
    """The UR10 (no closed form: DLS) is ranked by the same score: the panel of
    tests/test_reachability.py; the refined candidates that IK found feasible are motion-scored,
    the chosen one has the smallest cost and is feasible, clear of the floor and the part, and
    its predicted slowdown is reported."""
    from tests.test_reachability import _panel_raster

    ur = load_robot("ur10")
    T_part = np.eye(4)
    T_part[:3, :3] = np.array([[0, 1, 0], [0, 0, -1], [-1, 0, 0]], float).T   # faces -x world
    T_part[:3, 3] = [0.0, 0.0, 0.6]
    paths = _panel_raster(T_part, width=0.4, height=0.3, n_pass=3, step=0.02)
    speeds = [np.full(len(p), 0.8) for p in paths]
    part = np.concatenate([p[:, :3, 3] for p in paths]) + [0.25, 0.0, 0.0]  # the panel itself
    # the arm on a 1 m pedestal (the floor 1 m below its base), 1 m back from the panel: lower or
    # nearer, its elbow swings within a link's radius of the floor or the panel between passes
    cands = facing_grid([0.0, 0.0, 0.6], dx=[-1.0, -0.95], dy=[0.0], heights=[0.0])
    T, rep = find_base_pose(ur, paths, candidates=cands, n_refine=2, speeds_m_s=speeds,
                            part_points_world=part, floor_z_m=-1.0)
    assert rep.feasible, rep.verdict
    assert rep.motion and set(rep.motion) <= {0, 1}
    chosen = rep.motion[rep.best]
    assert chosen.feasible and 0 < chosen.clearance_m < np.inf
    assert chosen.cost == min(m.cost for m in rep.motion.values())
    assert chosen.speed_ratio > 0 and np.isfinite(chosen.predicted_film_excess_pct)
