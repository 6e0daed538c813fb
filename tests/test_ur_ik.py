"""The UR arms' closed-form inverse kinematics (paintcell.robots.ur_ik) against the DH forward
kinematics and the shipped model: every solution of every branch maps back to its pose (FK round
trip), the joints a pose was made from are among them, and the eight branches of a generic pose
are the eight configurations (distinct shoulder / elbow / wrist sign triples)."""

from __future__ import annotations

import numpy as np

from paintcell.robots.catalog import load_robot
from paintcell.robots.ur_ik import ur_inverse
from paintcell.robots.ur_kinematics import ur_configuration_signs, ur_dh_fk


def _angle_gap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)


def test_every_branch_round_trips_and_the_source_joints_are_found() -> None:
    rng = np.random.default_rng(0)
    Q0 = rng.uniform(-np.pi, np.pi, (300, 6))
    T = ur_dh_fk(Q0)
    Q, reach = ur_inverse(T)
    assert Q.shape == (300, 8, 6) and reach.any(axis=1).all()
    for b in range(8):
        ok = reach[:, b]
        assert np.abs(ur_dh_fk(Q[ok, b]) - T[ok]).max() < 1e-9
        assert np.isnan(Q[~ok, b]).all()
    gap = _angle_gap(Q, Q0[:, None]).max(axis=2)
    assert (np.nanmin(gap, axis=1) < 1e-7).all()
    generic = reach.all(axis=1)
    assert generic.mean() > 0.5
    for k in np.flatnonzero(generic)[:40]:
        signs = ur_configuration_signs(Q[k])
        assert len({tuple(r) for r in signs}) == 8


def test_out_of_reach_and_the_model_frames() -> None:
    T = np.eye(4)[None].repeat(2, axis=0)
    T[0, :3, 3] = [3.0, 0.0, 0.5]               # 3 m out: no branch
    T[1, :3, 3] = [0.0, 0.05, 0.5]              # on the J1 axis, inside the shoulder offset
    _, reach = ur_inverse(T)
    assert not reach.any()
    ur = load_robot("ur10")                      # its own base and flange frames
    rng = np.random.default_rng(3)
    Qm = rng.uniform(-np.pi, np.pi, (40, 6))
    flange = np.stack([np.linalg.inv(ur.T_world_base) @ ur.fk(q) @ np.linalg.inv(ur.T_flange_tcp)
                       for q in Qm])
    Q, reach = ur.closed_form_inverse(flange)
    for k in range(40):
        sols = Q[k][reach[k]]
        assert np.nanmin(_angle_gap(sols, Qm[k]).max(axis=1)) < 1e-7
        for q in sols:                           # each solution is the pose, in the model's FK
            assert np.abs(ur.fk(q) - ur.fk(Qm[k])).max() < 1e-9
