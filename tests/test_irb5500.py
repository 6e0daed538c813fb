"""The IRB 5500-class paint robot: closed-form IK round trips, datasheet reach, paths, limits.

(MuJoCo vs Pinocchio FK, gravity, random-torque stepping and the Jacobian are checked for every
robot in tests/test_robot_model.py.)
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from paintcell.coverage.plan import tcp_frames
from paintcell.robots import load_robot
from paintcell.robots.ik import solve_path
from paintcell.robots.opw import forward, inverse, wrap_pi
from tests.helpers import FK_AGREEMENT_ATOL_M, IK_POS_TOL_M, OPW_ROUND_TRIP_ATOL

T_BASE = np.array([[0.0, -1.0, 0.0, 0.3], [1.0, 0.0, 0.0, -0.2], [0.0, 0.0, 1.0, 1.5],
                   [0.0, 0.0, 0.0, 1.0]])


@pytest.fixture(scope="module")
def robot():
    return load_robot("irb5500", T_world_base=T_BASE)


def test_opw_parameters_describe_the_mjcf(robot):
    Q = np.random.default_rng(20).uniform(robot.q_lower, robot.q_upper, (300, 6))
    T_opw = robot.T_world_base @ forward(robot.opw, Q) @ robot.T_flange_tcp
    assert np.abs(T_opw - robot.fk_many(Q)).max() < FK_AGREEMENT_ATOL_M


def test_opw_all_branches_round_trip(robot):
    Q = np.random.default_rng(21).uniform(robot.q_lower, robot.q_upper, (500, 6))
    T = robot.fk_many(Q)
    Qs, valid = inverse(robot.opw, robot.flange_poses(T))
    T_all = robot.T_world_base @ forward(robot.opw, Qs.reshape(-1, 6)).reshape(500, 8, 4, 4) \
        @ robot.T_flange_tcp
    err = np.abs(T_all - T[:, None]).max(axis=(2, 3))
    assert err[valid].max() < OPW_ROUND_TRIP_ATOL
    # The sampled configuration is among the branches (independent of the closed form's choice).
    assert np.all(np.abs(wrap_pi(Qs - Q[:, None])).max(axis=2).min(axis=1) < 1e-7)
    # Cross-check a subset with Pinocchio's own FK.
    for i in range(0, 500, 50):
        for b in np.flatnonzero(valid[i]):
            assert np.abs(robot.fk(Qs[i, b]) - T[i]).max() < OPW_ROUND_TRIP_ATOL


def test_reach_is_the_datasheet_reach():
    """Wrist-centre reach from the J1 axis, stretched horizontally: 2.975 m (README step 1),
    measured on the Pinocchio model (joint placements), not on the OPW parameters."""
    r = load_robot("irb5500")
    data = r.pin_model.createData()
    # Upper arm horizontal (q2 = 90°), elbow swept: the farthest wrist centre is the reach.
    reach = 0.0
    for q3 in np.linspace(-np.pi / 2 - 0.3, -np.pi / 2 + 0.3, 6001):
        pin.forwardKinematics(r.pin_model, data, np.array([0.0, np.pi / 2, q3, 0.0, 0.0, 0.0]))
        wrist = data.oMi[r.pin_model.getJointId("joint5")].translation
        reach = max(reach, float(np.hypot(wrist[0], wrist[1])))
    assert abs(reach - 2.975) < 1e-3
    # ... 45 % farther than the IRB 4600-class arm (2.05 m), which is what removes the roof hang.
    assert reach / 2.05 > 1.4


def test_ik_path_round_trip(robot):
    """A 2 m horizontal pass 1.6 m in front of the base, bell pointing down: IK along the path
    reproduces every pose (FK round trip) with continuous joints inside the limits."""
    x = np.linspace(-1.0, 1.0, 201)
    p = np.column_stack([np.full_like(x, 1.6), x, np.full_like(x, -0.6)])
    p_world = (T_BASE[:3, :3] @ p.T).T + T_BASE[:3, 3]
    n = np.tile([0.0, 0.0, 1.0], (len(x), 1))            # surface normal (toward the gun: up)
    travel = np.tile(T_BASE[:3, :3] @ [0.0, 1.0, 0.0], (len(x), 1))
    T = tcp_frames(p_world, -n, travel)
    res = solve_path(robot, T, q_seed=robot.q_home)
    assert res.reachability.all_reachable
    err = np.abs(robot.fk_many(res.q)[:, :3, 3] - T[:, :3, 3]).max()
    assert err < IK_POS_TOL_M
    assert np.all(res.q >= robot.q_lower) and np.all(res.q <= robot.q_upper)
    assert np.abs(np.diff(res.q, axis=0)).max() < 0.05


def test_static_gravity_within_torque_limits():
    """README step 6: gravity alone never needs more than half of tau_max."""
    r = load_robot("irb5500")
    Q = np.random.default_rng(22).uniform(r.q_lower, r.q_upper, (500, 6))
    z = np.zeros(6)
    G = np.array([pin.rnea(r.pin_model, r.pin_data, q, z, z) for q in Q])
    assert np.all(np.abs(G).max(axis=0) < 0.5 * r.tau_max)


def test_datasheet_values():
    r = load_robot("irb5500")
    # the model's range (its hard stops, as MuJoCo reads them) is the datasheet's; paintcell
    # plans 0.001 rad inside it
    hard = np.rad2deg(mujoco.MjModel.from_xml_path(str(r.mjcf_path)).jnt_range)
    assert np.allclose(hard, np.column_stack([[-150, -90, -180, -300, -125, -300],
                                              [150, 110, 65, 300, 125, 300]]))
    assert np.allclose(r.q_lower - np.deg2rad(hard[:, 0]), 0.001)
    assert np.allclose(np.deg2rad(hard[:, 1]) - r.q_upper, 0.001)
    assert np.allclose(np.rad2deg(r.v_max), [100, 130, 130, 460, 460, 600])
