"""Closed-form inverse kinematics of the UR arms: all eight solutions of every pose at once
(Hawkins, "Analytic inverse kinematics for the Universal Robots UR-5/UR-10 arms", 2013), in the
standard Denavit–Hartenberg frames of `paintcell.robots.ur_kinematics` (lengths in m, angles in
rad).

The UR arm is not ortho-parallel — its shoulder is offset by d4 from the J1 axis and its wrist
axes do not meet — so `paintcell.robots.opw` does not apply, but its geometry still has a closed
form: J1 from the wrist point p05 (the flange less d6 along its axis) lying d4 from the J1 axis
(two solutions: the shoulder), J5 from the flange's position across frame 1 (two: the wrist),
J6 from the flange's orientation, and J2, J3, J4 from the planar two-link arm a2, a3 (two: the
elbow). Branch b = 4·shoulder + 2·wrist + elbow. `ur_closed_form` wraps it for a loaded robot
whose base and flange frames differ from the DH ones by constant transforms (found once from the
model's own forward kinematics), so the placement search and the path IK use it as they use the
ortho-parallel solver.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.core.transforms import inverse_pose
from paintcell.robots.ur_kinematics import UR10_DH, ur_dh_fk, ur_dh_link

__all__ = ["ur_closed_form", "ur_inverse"]


def ur_inverse(T_base_flange: npt.ArrayLike, dh: Mapping[str, tuple[float, ...]] = UR10_DH,
               tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """All eight solutions of flange poses T_base_flange (M, 4, 4) in the DH base frame.

    Returns Q (M, 8, 6) [rad] in (−π, π] and reach (M, 8): the branch has a solution (the pose
    within the shoulder's lateral offset and the arm's reach; |sin q5| > tol so J6 is defined).
    Unreached entries of Q are NaN.
    """
    T = np.asarray(T_base_flange, float).reshape(-1, 4, 4)
    M = len(T)
    d1, d4, d5, d6 = dh["d"][0], dh["d"][3], dh["d"][4], dh["d"][5]
    a2, a3 = dh["a"][1], dh["a"][2]
    Q = np.full((M, 8, 6), np.nan)
    reach = np.zeros((M, 8), bool)
    p06 = T[:, :3, 3]
    p05 = p06 - d6 * T[:, :3, 2]
    r = np.hypot(p05[:, 0], p05[:, 1])
    ok1 = r > abs(d4) + tol
    phi = np.arccos(np.clip(d4 / np.where(ok1, r, 1.0), -1.0, 1.0))
    psi = np.arctan2(p05[:, 1], p05[:, 0])
    for sh, s1sign in enumerate((1.0, -1.0)):
        q1 = psi + s1sign * phi + np.pi / 2
        c1, s1 = np.cos(q1), np.sin(q1)
        arg5 = (p06[:, 0] * s1 - p06[:, 1] * c1 - d4) / d6
        ok5 = ok1 & (np.abs(arg5) <= 1.0)
        for wr, s5sign in enumerate((1.0, -1.0)):
            q5 = s5sign * np.arccos(np.clip(arg5, -1.0, 1.0))
            s5 = np.sin(q5)
            ok6 = ok5 & (np.abs(s5) > tol)
            s5s = np.where(ok6, s5, 1.0)
            q6 = np.arctan2(-(T[:, 0, 1] * s1 - T[:, 1, 1] * c1) / s5s,
                            (T[:, 0, 0] * s1 - T[:, 1, 0] * c1) / s5s)
            # frame 1 → frame 4: T14 = A1⁻¹ · T06 · (A5 A6)⁻¹
            A1 = ur_dh_link(q1, d1, 0.0, dh["alpha"][0])
            A56 = ur_dh_link(q5, d5, 0.0, dh["alpha"][4]) @ ur_dh_link(q6, d6, 0.0, dh["alpha"][5])
            T14 = inverse_pose(A1) @ T @ inverse_pose(A56)
            p13 = T14[:, :3, 3] - d4 * T14[:, :3, 1]
            n13 = np.linalg.norm(p13, axis=1)
            c3 = (n13 ** 2 - a2 ** 2 - a3 ** 2) / (2 * a2 * a3)
            ok3 = ok6 & (np.abs(c3) <= 1.0)
            for el, s3sign in enumerate((1.0, -1.0)):
                q3 = s3sign * np.arccos(np.clip(c3, -1.0, 1.0))
                q2 = -np.arctan2(p13[:, 1], -p13[:, 0]) + np.arcsin(
                    np.clip(a3 * np.sin(q3) / np.where(n13 > 0, n13, 1.0), -1.0, 1.0))
                A23 = (ur_dh_link(q2, 0.0, a2, dh["alpha"][1])
                       @ ur_dh_link(q3, 0.0, a3, dh["alpha"][2]))
                T34 = inverse_pose(A23) @ T14
                q4 = np.arctan2(T34[:, 1, 0], T34[:, 0, 0])
                b = 4 * sh + 2 * wr + el
                sol = np.column_stack([q1, q2, q3, q4, q5, q6])
                sol = (sol + np.pi) % (2 * np.pi) - np.pi
                Q[:, b] = np.where(ok3[:, None], sol, np.nan)
                reach[:, b] = ok3
    return Q, reach


#: the URDF's base_link is the DH base turned π about z (`tests/test_ur_kinematics.py`).
URDF_BASE_FROM_DH = np.diag([-1.0, -1.0, 1.0, 1.0])


def ur_closed_form(robot: Any, dh: Mapping[str, tuple[float, ...]] = UR10_DH
                   ) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """T_base_flange (M, 4, 4) of `robot` (its own base and flange frames) → (Q (M, 8, 6),
    reach (M, 8)) of `ur_inverse`. Its base is the DH base turned π (`URDF_BASE_FROM_DH`); the
    constant flange offset is measured once on the model's own forward kinematics and checked
    at a second pose (RobotError when the model is not this DH arm)."""
    from paintcell.robots.errors import RobotError

    def model_flange(q: np.ndarray) -> np.ndarray:
        return np.linalg.inv(robot.T_world_base) @ robot.fk(q) @ np.linalg.inv(robot.T_flange_tcp)

    B = URDF_BASE_FROM_DH
    q0, q1 = (np.array([0.3, -1.1, 1.2, -0.9, 1.1, 0.4]),
              np.array([-0.7, -1.9, 0.8, 0.5, -1.3, -0.6]))
    F = np.linalg.inv(B @ ur_dh_fk(q0[None], dh)[0]) @ model_flange(q0)
    if np.abs(B @ ur_dh_fk(q1[None], dh)[0] @ F - model_flange(q1)).max() > 1e-6:
        raise RobotError(f"{robot.name}'s forward kinematics is not the UR DH table's; its "
                         "closed-form IK does not apply")
    B_inv, F_inv = np.linalg.inv(B), np.linalg.inv(F)

    def solve(T_base_flange: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return ur_inverse(B_inv @ np.asarray(T_base_flange, float) @ F_inv, dh)

    return solve
