"""The UR10's configuration signs (`paintcell.robots.ur_kinematics`): its DH table is the shipped
model's forward kinematics, and the shoulder / elbow / wrist signs tell its inverse-kinematics
solutions of one pose apart — every distinct solution found by damped least squares from many
seeds (FK round trip to 1e-6) has its own sign triple, and equal triples are the same joints."""

from __future__ import annotations

import numpy as np

from paintcell.robots.catalog import load_robot
from paintcell.robots.ik import IKSettings, dls
from paintcell.robots.ur_kinematics import ur_configuration_signs, ur_dh_fk


def _wrapped(q: np.ndarray) -> np.ndarray:
    return (q + np.pi) % (2 * np.pi) - np.pi


def test_ur10_dh_table_is_the_shipped_models_forward_kinematics() -> None:
    robot = load_robot("ur10")
    rng = np.random.default_rng(1)
    Q = rng.uniform(-np.pi, np.pi, size=(30, 6))
    T_model, T_dh = robot.fk_many(Q), ur_dh_fk(Q)
    B = np.diag([-1.0, -1.0, 1.0, 1.0])            # the URDF base_link is the DH base turned π
    F = np.linalg.inv(B @ T_dh[0]) @ T_model[0]    # flange → TCP (bell), constant
    assert np.max(np.abs(B @ T_dh @ F - T_model)) < 1e-9


def test_ur10_configuration_signs_tell_its_ik_solutions_apart() -> None:
    robot = load_robot("ur10")
    st = IKSettings(pos_tol_m=1e-7, rot_tol_rad=1e-7)
    rng = np.random.default_rng(2)
    q_target = np.array([0.4, -1.2, 1.3, -1.0, -1.2, 0.3])
    T = robot.fk(q_target)
    sols: list[np.ndarray] = []
    for seed in rng.uniform(-np.pi, np.pi, size=(80, 6)):
        q, ok = dls(robot, T, seed, max_iters=200, settings=st)
        if not ok:
            continue
        assert np.linalg.norm(robot.fk(q)[:3, 3] - T[:3, 3]) < 1e-6      # FK round trip
        q = _wrapped(q)
        if not any(np.allclose(q, s, atol=1e-4) for s in sols):
            sols.append(q)
    signs = ur_configuration_signs(np.array(sols))
    assert len(sols) == 8 and np.all(signs != 0)     # a generic pose: 8 analytic branches
    # one configuration per sign triple: the triples label the solutions
    assert len({tuple(r) for r in signs}) == len(sols)
    assert {tuple(r) for r in signs} >= {tuple(ur_configuration_signs(q_target)[0])}
