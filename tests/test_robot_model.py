"""Robot models: MuJoCo vs Pinocchio agreement, model health, Jacobian, OPW forward kinematics."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from paintcell.robots import RobotError, bell_tool_offset, load_robot
from paintcell.robots.opw import forward
from tests.helpers import FK_AGREEMENT_ATOL_M, FK_AGREEMENT_ATOL_ROT, JACOBIAN_FD_ATOL

T_BASE = np.array([[0.0, -1.0, 0.0, 0.3], [1.0, 0.0, 0.0, -0.2], [0.0, 0.0, 1.0, 0.5],
                   [0.0, 0.0, 0.0, 1.0]])


def _mj_tcp(model: mujoco.MjModel, data: mujoco.MjData, q: np.ndarray, site: str) -> np.ndarray:
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    T = np.eye(4)
    T[:3, :3] = data.site(site).xmat.reshape(3, 3)
    T[:3, 3] = data.site(site).xpos
    return T


def _mj_model_at(robot) -> mujoco.MjModel:
    """The robot's MJCF with its root body moved to T_world_base (what sim does with MjSpec)."""
    spec = mujoco.MjSpec.from_file(str(robot.mjcf_path))
    body = spec.body(robot.base_body_name)
    body.pos = robot.T_world_base[:3, 3]
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, robot.T_world_base[:3, :3].reshape(9))
    body.quat = quat
    return spec.compile()


@pytest.mark.parametrize("name", ["abb_paint", "irb5500", "irb5500_rail", "ur10"])
def test_mujoco_and_pinocchio_tcp_agree(name):
    robot = load_robot(name, T_world_base=T_BASE)
    model = _mj_model_at(robot)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(1)
    for q in rng.uniform(robot.q_lower, robot.q_upper, (200, robot.nq)):
        T_mj = _mj_tcp(model, data, q, robot.tcp_site_name)
        T_pin = robot.fk(q)
        assert np.abs(T_mj[:3, 3] - T_pin[:3, 3]).max() < FK_AGREEMENT_ATOL_M
        assert np.abs(T_mj[:3, :3] - T_pin[:3, :3]).max() < FK_AGREEMENT_ATOL_ROT


@pytest.mark.parametrize("name", ["abb_paint", "irb5500", "irb5500_rail", "ur10"])
def test_gravity_torques_agree(name):
    """Same dynamics in both engines: Pinocchio RNEA at rest == MuJoCo's bias force."""
    robot = load_robot(name)
    model = mujoco.MjModel.from_xml_path(str(robot.mjcf_path))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(2)
    for q in rng.uniform(robot.q_lower, robot.q_upper, (20, robot.nq)):
        data.qpos[:] = q
        data.qvel[:] = 0
        mujoco.mj_forward(model, data)
        g = pin.rnea(robot.pin_model, robot.pin_data, q, np.zeros(robot.nq), np.zeros(robot.nq))
        assert np.allclose(g, data.qfrc_bias, atol=1e-6 * (1 + np.abs(g).max()))


@pytest.mark.parametrize("name", ["abb_paint", "irb5500", "irb5500_rail", "ur10"])
def test_model_steps_under_random_torques_without_warnings(name):
    robot = load_robot(name)
    model = mujoco.MjModel.from_xml_path(str(robot.mjcf_path))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    rng = np.random.default_rng(3)
    lo, hi = model.actuator_ctrlrange.T
    for step in range(int(1.0 / model.opt.timestep)):
        if step % 20 == 0:
            data.ctrl[:] = rng.uniform(lo, hi) * 0.5
        mujoco.mj_step(model, data)
    assert all(w.number == 0 for w in data.warning), [w.number for w in data.warning]
    assert np.all(np.isfinite(data.qpos))


@pytest.mark.parametrize("name", ["abb_paint", "irb5500", "irb5500_rail", "ur10"])
def test_jacobian_matches_finite_differences(name):
    robot = load_robot(name, T_world_base=T_BASE)
    rng = np.random.default_rng(4)
    h = 1e-6
    for q in rng.uniform(robot.q_lower, robot.q_upper, (5, robot.nq)):
        J = robot.jacobian(q)
        T0 = robot.fk(q)
        J_fd = np.zeros_like(J)
        for i in range(robot.nq):
            dq = np.zeros(robot.nq)
            dq[i] = h
            Tp, Tm = robot.fk(q + dq), robot.fk(q - dq)
            J_fd[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
            dR = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ T0[:3, :3].T   # skew(ω)
            J_fd[3:, i] = [dR[2, 1], dR[0, 2], dR[1, 0]]
        assert np.abs(J - J_fd).max() < JACOBIAN_FD_ATOL


def test_opw_forward_matches_pinocchio():
    """The closed-form parameters describe the MJCF: OPW flange FK · tool offset == Pinocchio."""
    robot = load_robot("abb_paint", T_world_base=T_BASE)
    Q = np.random.default_rng(5).uniform(robot.q_lower, robot.q_upper, (300, 6))
    T_opw = robot.T_world_base @ forward(robot.opw, Q) @ robot.T_flange_tcp
    assert np.abs(T_opw - robot.fk_many(Q)).max() < FK_AGREEMENT_ATOL_M


def test_datasheet_values():
    robot = load_robot("abb_paint")
    # the model's range (its hard stops, as MuJoCo reads them) is the datasheet's; paintcell
    # plans 0.001 rad inside it
    hard = np.rad2deg(mujoco.MjModel.from_xml_path(str(robot.mjcf_path)).jnt_range)
    assert np.allclose(hard, np.column_stack([[-180, -90, -180, -400, -125, -400],
                                              [180, 150, 75, 400, 120, 400]]))
    assert np.allclose(robot.q_lower - np.deg2rad(hard[:, 0]), 0.001)
    assert np.allclose(np.deg2rad(hard[:, 1]) - robot.q_upper, 0.001)
    assert np.allclose(np.rad2deg(robot.v_max), [175, 175, 175, 250, 250, 360])
    assert robot.joint_names == tuple(f"joint{i}" for i in range(1, 7))
    assert np.all(robot.armature > 0) and np.all(robot.damping > 0)


def test_static_gravity_within_torque_limits():
    """Torque limits leave headroom: gravity alone never needs more than half of tau_max."""
    robot = load_robot("abb_paint")
    Q = np.random.default_rng(6).uniform(robot.q_lower, robot.q_upper, (500, 6))
    z = np.zeros(6)
    G = np.array([pin.rnea(robot.pin_model, robot.pin_data, q, z, z) for q in Q])
    assert np.all(np.abs(G).max(axis=0) < 0.5 * robot.tau_max)


def test_tcp_offset_moves_the_site():
    T_off = bell_tool_offset(0.2, 0.1, 0.5)
    robot = load_robot("abb_paint", tcp_offset=T_off)
    assert np.allclose(robot.T_flange_tcp, T_off, atol=1e-12)
    q = robot.q_home
    T_flange = forward(robot.opw, q[None])[0]
    assert np.allclose(robot.fk(q), T_flange @ T_off, atol=FK_AGREEMENT_ATOL_M)


def test_bad_input_raises():
    with pytest.raises(RobotError, match="unknown robot"):
        load_robot("kuka")
    robot = load_robot("abb_paint")
    with pytest.raises(RobotError, match="joint vector"):
        robot.fk(np.zeros(5))
    with pytest.raises(RobotError, match="rigid transform"):
        load_robot("abb_paint", T_world_base=np.diag([2.0, 1, 1, 1]))


def test_placed_robot_moves_fk_and_jacobian_with_the_base():
    robot = load_robot("abb_paint")
    moved = robot.placed(T_BASE)
    q = np.array([0.2, 0.1, -0.3, 0.4, 0.9, -0.5])
    assert np.allclose(moved.fk(q), T_BASE @ robot.fk(q), atol=FK_AGREEMENT_ATOL_M)
    R = T_BASE[:3, :3]
    J, Jm = robot.jacobian(q), moved.jacobian(q)
    assert np.allclose(Jm[:3], R @ J[:3], atol=1e-12) and np.allclose(Jm[3:], R @ J[3:], atol=1e-12)
    assert np.allclose(robot.T_world_base, np.eye(4))          # the original is untouched
    assert np.allclose(robot.fk(q), forward(robot.opw, q[None])[0] @ robot.T_flange_tcp,
                       atol=FK_AGREEMENT_ATOL_M)


def test_generated_mjcf_write_leaves_no_temp_file_on_failure(tmp_path, monkeypatch):
    """`write_generated_mjcf` writes through `paintcell.core.atomic_io`: a failed rename removes
    the
    temp file instead of leaking it."""
    import os

    from paintcell.robots.robot import write_generated_mjcf

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))

    def fail(*_args, **_kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="disk full"):
        write_generated_mjcf("<mujoco/>", "leak")
    assert list((tmp_path / "paintcell" / "robots").iterdir()) == []
    monkeypatch.undo()
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    path = write_generated_mjcf("<mujoco/>", "leak")
    assert path.read_text() == "<mujoco/>"
    assert [p.name for p in (tmp_path / "paintcell" / "robots").iterdir()] == [path.name]


def test_tcp_offset_must_be_rigid():
    with pytest.raises(RobotError, match="tcp_offset is not a rigid transform"):
        load_robot("abb_paint", tcp_offset=np.diag([1.0, 1.0, 2.0, 1.0]))
