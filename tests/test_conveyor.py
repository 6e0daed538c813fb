"""Conveyor tracking (paintcell.booth.conveyor) and the booth cell's carrier
(paintcell.booth.booth_cell): programs that
follow the moving part (FK round trip), exact rail tracking, and a conveyor at speed 0 that is
the static cell."""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.app.scenario_files import load_scenario
from paintcell.booth.booth_cell import build_booth_cell
from paintcell.booth.booth_film import gun_in_body
from paintcell.booth.booth_run import combined_program
from paintcell.booth.conveyor import Conveyor, ConveyorError, track_program
from paintcell.core.placement import pose
from paintcell.execution.cell import build_cell
from paintcell.execution.execute import execute
from paintcell.motion.joint_trajectory import PAINT, JointTrajectory
from paintcell.paint.deposition import thickness
from paintcell.robots import load_robot
from paintcell.robots.rail import load_rail_robot
from paintcell.validation.validate_samples import executed_gun_samples
from tests.helpers import FK_AGREEMENT_ATOL_M


def _synthetic_program(robot, q0, amp, seconds=2.0, dt=1e-3) -> JointTrajectory:
    """A smooth program q0 + amp·sin(2π t / T) with exact derivatives and FK TCP."""
    t = np.arange(int(seconds / dt)) * dt
    w = 2 * np.pi / seconds
    q = q0 + amp * np.sin(w * t)[:, None]
    qd = amp * w * np.cos(w * t)[:, None]
    qdd = -amp * w * w * np.sin(w * t)[:, None]
    T = robot.fk_many(q)
    K = len(t)
    return JointTrajectory(t_s=t, q=q, qd=qd, qdd=qdd, tcp_pos_world=T[:, :3, 3],
                           tcp_rot_world=T[:, :3, :3], v_tcp_planned=np.zeros(K),
                           paint_on=np.ones(K, bool), pass_index=np.zeros(K, int),
                           segment=np.full(K, PAINT), s_pass_m=np.zeros(K),
                           robot_name=robot.name, joint_names=robot.joint_names)


def test_fixed_robot_follows_the_moving_target_by_ik():
    """IK on the moving target: the tracked TCP is the static TCP moved by d(t) (FK round trip,
    independent of the closed form), and the velocities are the derivatives of the positions."""
    robot = load_robot("irb5500", T_world_base=pose((0.0, 0.0, 0.5)))
    q0 = np.array([0.2, 0.4, -0.3, 0.5, 0.9, -0.4])
    traj = _synthetic_program(robot, q0, np.array([0.2, 0.1, 0.1, 0.3, 0.2, 0.3]))
    conv = Conveyor(speed_m_s=0.1, direction=(1.0, 0.5, 0.0))
    tracked = track_program(robot, traj, conv)
    t_ref = tracked.meta["conveyor"]["t_ref_s"]
    d = conv.displacement(traj.t_s, t_ref)
    T = robot.fk_many(tracked.q)
    assert np.abs(T[:, :3, 3] - (traj.tcp_pos_world + d)).max() < FK_AGREEMENT_ATOL_M
    assert np.abs(T[:, :3, :3] - traj.tcp_rot_world).max() < FK_AGREEMENT_ATOL_M
    assert np.abs(tracked.q - traj.q).max() > 1e-3          # the arm really moved
    dt = traj.dt_s
    fd = (tracked.q[2:] - tracked.q[:-2]) / (2 * dt)
    assert np.abs(fd - tracked.qd[1:-1]).max() < 1e-3 * np.abs(tracked.qd).max()
    # The tracked TCP speed is the static one plus the line speed (vector sum).
    v_static = np.gradient(traj.tcp_pos_world, dt, axis=0)
    v_tracked = np.gradient(T[:, :3, 3], dt, axis=0)
    assert np.abs(v_tracked - v_static - conv.speed_m_s * conv.unit).max() < 1e-6


def test_rail_along_the_line_tracks_exactly_with_the_rail_alone():
    rail_robot = load_rail_robot("irb5500", T_world_rail=pose((0.0, -2.0, 0.3),
                                                               (0.0, 0.0, np.pi / 2)))
    q0 = np.array([0.0, 0.2, 0.4, -0.3, 0.5, 0.9, -0.4])
    amp = np.array([0.3, 0.2, 0.1, 0.1, 0.3, 0.2, 0.3])
    traj = _synthetic_program(rail_robot, q0, amp)
    conv = Conveyor(speed_m_s=0.05, direction=(1.0, 0.0, 0.0))
    tracked = track_program(rail_robot, traj, conv)
    assert np.array_equal(tracked.q[:, 1:], traj.q[:, 1:])     # the arm's program unchanged
    t_ref = tracked.meta["conveyor"]["t_ref_s"]
    # The rail frame's +y is world −x here: the carriage runs against the line's direction.
    assert np.allclose(tracked.q[:, 0] - traj.q[:, 0], -0.05 * (traj.t_s - t_ref), atol=1e-12)
    T = rail_robot.fk_many(tracked.q)
    d = conv.displacement(traj.t_s, t_ref)
    assert np.abs(T[:, :3, 3] - (traj.tcp_pos_world + d)).max() < FK_AGREEMENT_ATOL_M


def test_speed_zero_leaves_the_program_bit_for_bit():
    robot = load_robot("irb5500")
    traj = _synthetic_program(robot, np.array([0.1, 0.3, -0.2, 0.4, 0.8, 0.1]), 0.1)
    tracked = track_program(robot, traj, Conveyor(speed_m_s=0.0))
    for name in ("q", "qd", "qdd", "tcp_pos_world"):
        assert np.array_equal(getattr(tracked, name), getattr(traj, name))


def test_tracking_refuses_out_of_range_programs_and_bad_conveyors():
    robot = load_robot("irb5500")
    traj = _synthetic_program(robot, np.array([0.1, 0.3, -0.2, 0.4, 0.8, 0.1]), 0.1)
    with pytest.raises(ConveyorError, match="out of reach|joint limits|jump"):
        track_program(robot, traj, Conveyor(speed_m_s=5.0))   # ±5 m of travel
    with pytest.raises(ConveyorError, match="direction"):
        Conveyor(direction=(0.0, 0.0, 0.0))
    with pytest.raises(ConveyorError, match="speed_m_s"):
        Conveyor(speed_m_s=-1.0)


@pytest.fixture(scope="module")
def door_program():
    from paintcell.app.pipeline import load_robot_for, load_surface, make_plan, make_trajectory

    scn = load_scenario("scenarios/door.toml")
    surface = load_surface(scn, fast=True)
    plan = make_plan(scn, surface, fast=True)
    robot = load_robot_for(scn)
    return scn, surface, plan, robot, make_trajectory(scn, robot, plan)


@pytest.mark.parametrize("mode", ["kinematic", "servo"])
def test_conveyor_at_speed_zero_is_the_static_cell(door_program, mode):
    """The booth cell with the part on a carrier at speed 0 executes the door program as the
    static `paintcell.execution.cell` does: the same TCP trace and the same film in the part
    frame."""
    scn, surface, plan, robot, traj = door_program
    T_wp = scn.part_placement.matrix
    static = execute(build_cell(robot, surface, T_wp), traj, mode=mode)
    conv = Conveyor(speed_m_s=0.0)
    bcell = build_booth_cell([robot], surface, T_wp, conv)
    tracked = track_program(robot, traj, conv)
    booth = execute(bcell.cell, combined_program(bcell, [tracked], 0.0), mode=mode)
    assert np.all(booth.q[:, -1] == 0.0)                     # the carrier never moved
    # Same dynamics: the carrier's DOF is decoupled from the arms (round-off of the solver).
    assert np.abs(booth.q[:, :6] - static.q).max() < 1e-9
    assert np.abs(booth.tcp_pos_world - static.tcp_pos_world).max() < 1e-9
    film_static = thickness(plan.applicator,
                            executed_gun_samples(static, np.linalg.inv(T_wp)),
                            surface.vertices, surface.normals)
    g = gun_in_body(booth.t_s, booth.tcp_pos_world, booth.tcp_rot_world, traj.paint_on, T_wp,
                     booth.q[:, -1], conv.unit, brush=traj.flow)
    film_booth = thickness(plan.applicator, g, surface.vertices, surface.normals)
    assert np.abs(film_booth - film_static).max() < 1e-9 * film_static.max()
    assert booth.contacts == static.contacts == ()
