"""The bell's roll about its spray axis: the plan keeps it from pass to pass
(`CoveragePlan.roll_signs`), the film does not see it, the program's wrist does not turn at the
turn-arounds, and a pass the arm cannot hold with the planned roll is solved half-turned
(`paintcell.robots.paths`, `paintcell.robots.rail`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from paintcell.core.transforms import half_turned
from paintcell.motion.joint_trajectory import PAINT, TURNAROUND
from paintcell.motion.trajectory import TrajectorySettings, build_program
from paintcell.paint.deposition import thickness
from paintcell.robots import load_robot
from paintcell.robots.paths import solve_paths
from tests.test_trajectory import N_PASSES, _plan


def _x_axes(plan, keep_roll: bool = True) -> list[np.ndarray]:
    return [plan.tcp_frames(i, keep_roll=keep_roll)[:, :3, 0] for i in range(len(plan.passes))]


def test_frames_keep_the_roll_across_every_turnaround() -> None:
    plan = _plan()
    x = _x_axes(plan)
    for i, p in enumerate(plan.passes):
        # x is the travel or its opposite on every sample, z the spray axis, as planned
        dots = np.einsum("ij,ij->i", x[i], p.travel_dirs)
        np.testing.assert_allclose(np.abs(dots), 1.0, atol=1e-12)
        np.testing.assert_allclose(plan.tcp_frames(i)[:, :3, 2], p.spray_axes, atol=1e-12)
    for i in range(len(plan.passes) - 1):
        # the strip's passes alternate: x = travel would turn half a turn at each turn-around
        assert float(plan.passes[i].travel_dirs[-1] @ plan.passes[i + 1].travel_dirs[0]) < -0.99
        assert float(x[i][-1] @ x[i + 1][0]) > 0.99
    np.testing.assert_array_equal(plan.roll_signs(), [1.0, -1.0, 1.0])
    # keep_roll=False: x = travel (a free-spin IK's start)
    for i, p in enumerate(plan.passes):
        np.testing.assert_allclose(_x_axes(plan, keep_roll=False)[i], p.travel_dirs, atol=1e-12)


def test_half_turned_bell_lays_the_same_film() -> None:
    plan = _plan()
    g = plan.gun_samples()
    flipped = dataclasses.replace(g, travel_dirs=-g.travel_dirs)
    # a grid under the strip, normals up toward the bell
    xs, ys = np.meshgrid(np.linspace(0.7, 1.5, 17), np.linspace(-0.5, 0.5, 21))
    pts = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, 0.75)])
    nrm = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    a = thickness(plan.applicator, g, pts, nrm)
    b = thickness(plan.applicator, flipped, pts, nrm)
    assert a.max() > 0
    np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("keep_roll", [True, False])
def test_program_wrist_holds_its_roll_through_turnarounds(keep_roll: bool) -> None:
    """With `keep_roll` (the default) the bell's x axis turns < 5° over every turn-around and
    J4/J6 move less than a quarter turn; with keep_roll = false it turns half a turn (x follows
    the travel): both re-measured by Pinocchio FK of the program's joints."""
    robot = load_robot("abb_paint")
    plan = _plan()
    T = np.eye(4)
    traj = build_program(robot, plan, T, TrajectorySettings(keep_roll=keep_roll))
    # re-measured: the bell's x axis by Pinocchio FK of the program's joints
    m, d, fid = robot.pin_model, robot.pin_data, robot.tcp_frame_id

    def x_axis(q: np.ndarray) -> np.ndarray:
        pin.forwardKinematics(m, d, q)
        return pin.updateFramePlacement(m, d, fid).rotation[:, 0].copy()

    turns = 0
    for i in range(N_PASSES - 1):
        end = np.flatnonzero((traj.pass_index == i) & (traj.segment == PAINT))[-1]
        start = np.flatnonzero((traj.pass_index == i + 1) & (traj.segment == PAINT))[0]
        assert np.all(traj.segment[end + 1:start] == TURNAROUND)
        angle = np.degrees(np.arccos(np.clip(x_axis(traj.q[end]) @ x_axis(traj.q[start]),
                                             -1, 1)))
        if not keep_roll:
            assert angle > 175.0, f"turn-around {i}: the bell turns only {angle:.1f}°"
            turns += 1
            continue
        assert angle < 5.0, f"turn-around {i}: the bell turns {angle:.1f}° about its axis"
        # the wrist joints (J4, J6) move less than a quarter turn over the turn-around
        span = np.ptp(traj.q[end:start + 1, [3, 5]], axis=0)
        assert np.all(span < np.pi / 2), span
        turns += 1
    assert turns == N_PASSES - 1


def test_pass_out_of_reach_with_its_roll_is_solved_half_turned() -> None:
    robot = load_robot("abb_paint")
    plan = _plan()
    frames = plan.tcp_frames(1)
    # the arm's own solution half-turned, then J4 and J6 held to ±0.6 rad around it: the planned
    # roll needs them half a turn away, out of these limits
    (half,) = solve_paths(robot, [half_turned(frames)], q_seed=robot.q_home)
    assert half.reachability.all_reachable
    lo, hi = robot.q_lower.copy(), robot.q_upper.copy()
    for j in (3, 5):
        lo[j], hi[j] = half.q[:, j].min() - 0.6, half.q[:, j].max() + 0.6
    narrow = dataclasses.replace(robot, q_lower=lo, q_upper=hi)
    (res,) = solve_paths(narrow, [frames], q_seed=half.q[0])
    assert res.reachability.all_reachable and res.reachability.continuous
    # re-measured by FK: the positions and spray axes of the plan, the bell half-turned
    fk = narrow.fk_many(res.q)
    np.testing.assert_allclose(fk[:, :3, 3], frames[:, :3, 3], atol=1e-6)
    np.testing.assert_allclose(fk[:, :3, 2], frames[:, :3, 2], atol=1e-6)
    np.testing.assert_allclose(np.einsum("ij,ij->i", fk[:, :3, 0], frames[:, :3, 0]), -1.0,
                               atol=1e-6)


@pytest.mark.parametrize("flip", [False, True])
def test_half_turned_keeps_position_and_axis(flip: bool) -> None:
    rng = np.random.default_rng(3)
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    R *= np.sign(np.linalg.det(R))
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, rng.normal(size=3)
    H = half_turned(T)
    if flip:
        H = half_turned(H)
        np.testing.assert_allclose(H, T, atol=1e-15)
        return
    np.testing.assert_allclose(H[:3, 2:], T[:3, 2:], atol=1e-15)
    np.testing.assert_allclose(H[:3, :2], -T[:3, :2], atol=1e-15)
    np.testing.assert_allclose(H[:3, :3] @ H[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(H[:3, :3]) == pytest.approx(1.0)
