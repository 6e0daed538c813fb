"""The UR10's kinematics in its standard Denavit–Hartenberg form (Universal Robots' published
parameters, which the example-robot-data URDF realizes) and its configuration: the shoulder,
elbow and wrist signs whose change along a path is a configuration flip (lengths in m, angles
in rad).

The UR arm is not ortho-parallel (its shoulder is offset by d4 from the J1 axis), so
`paintcell.robots.opw` does not apply; its analytic inverse has eight branches too, told apart
by (Hawkins, "Analytic inverse kinematics for the Universal Robots UR-5/UR-10 arms", 2013):
- shoulder: which of the two J1 angles puts the wrist point p05 (the flange minus d6 along its
  axis) at the fixed lateral offset d4 — the sign of p05's distance in front of the plane of the
  J1 and J2 axes (0: p05 at distance d4 from the J1 axis, the shoulder singularity);
- elbow: sin q3 (0: the arm stretched or folded, the elbow singularity);
- wrist: sin q5 (0: J4 and J6 aligned, the wrist singularity).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import numpy.typing as npt

from paintcell.robots.errors import RobotError

__all__ = ["UR10_DH", "ur_configuration_signs", "ur_dh_fk", "ur_dh_link"]

#: UR10 standard DH parameters (d [m], a [m], alpha [rad]) of joints 1..6 (Universal Robots).
UR10_DH: dict[str, tuple[float, ...]] = {
    "d": (0.1273, 0.0, 0.0, 0.163941, 0.1157, 0.0922),
    "a": (0.0, -0.612, -0.5723, 0.0, 0.0, 0.0),
    "alpha": (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0),
}


def ur_dh_link(theta: np.ndarray, d: float, a: float, alpha: float) -> np.ndarray:
    """(K, 4, 4) standard DH link transforms of joint angles theta (K,) [rad] (d, a [m], alpha
    [rad] of the link)."""
    c, s = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(alpha), np.sin(alpha)
    A = np.zeros((len(theta), 4, 4))
    A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 0, 3] = c, -s * ca, s * sa, a * c
    A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = s, c * ca, -c * sa, a * s
    A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = sa, ca, d
    A[:, 3, 3] = 1.0
    return A


def ur_dh_fk(Q: npt.ArrayLike, dh: Mapping[str, tuple[float, ...]] = UR10_DH) -> np.ndarray:
    """(K, 4, 4) T_base_flange of joint angles Q (K, 6) [rad] in the DH base frame [m]."""
    Q = np.atleast_2d(np.asarray(Q, float))
    if Q.shape[-1] != 6:
        raise RobotError(f"UR forward kinematics needs (K, 6) joint angles, got {Q.shape}")
    T = np.tile(np.eye(4), (len(Q), 1, 1))
    for j in range(6):
        T = T @ ur_dh_link(Q[:, j], dh["d"][j], dh["a"][j], dh["alpha"][j])
    return T


def ur_configuration_signs(Q: npt.ArrayLike, dh: Mapping[str, tuple[float, ...]] = UR10_DH
                           ) -> np.ndarray:
    """(K, 3) shoulder, elbow, wrist signs (+1, −1; 0 on the singularity) of joint angles
    Q (K, 6) [rad] (module doc); the same columns as `paintcell.robots.opw.configuration_signs`."""
    Q = np.atleast_2d(np.asarray(Q, float))
    T = ur_dh_fk(Q, dh)
    p05 = T[:, :3, 3] - dh["d"][5] * T[:, :3, 2]
    front = np.cos(Q[:, 0]) * p05[:, 0] + np.sin(Q[:, 0]) * p05[:, 1]   # along frame 1's x
    return np.sign(np.column_stack([front, np.sin(Q[:, 2]), np.sin(Q[:, 4])])).astype(int)
