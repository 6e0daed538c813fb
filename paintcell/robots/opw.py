"""Closed-form inverse kinematics of ortho-parallel arms with a spherical wrist (OPW).

Parameters after Brandstötter, Angerer, Hofbaur, "An analytical solution of the inverse kinematics
problem of industrial serial manipulators with an ortho-parallel basis and a spherical wrist"
(2014): a1, a2, b, c1, c2, c3, c4 [m]. In the OPW zero pose the arm stands straight up; a robot's
own joint angles map as `q_opw = sign * q_robot + offset`.

The derivation here is our own (planar two-link for the arm, ZYZ Euler angles for the wrist) and is
checked against Pinocchio's forward kinematics in the tests. Everything is vectorized over poses:
(M, 4, 4) flange poses → (M, 8, 6) joint solutions + (M, 8) validity mask.
Branch index = 4·shoulder + 2·elbow + wrist (shoulder: J1 toward / away from the wrist centre;
elbow: sign of the elbow angle; wrist: sign of the OPW q5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from paintcell.robots.errors import RobotError

N_BRANCHES = 8


@dataclass(frozen=True)
class OPWParameters:
    """Ortho-parallel kinematic parameters [m] and the robot's joint-angle convention.

    a1: shoulder offset along x; a2: elbow offset (perpendicular to the forearm);
    b: lateral offset (must be 0 here); c1: shoulder height; c2: upper-arm length;
    c3: forearm length (elbow to wrist centre); c4: wrist centre to flange.
    offsets, signs: (6,) tuples, q_opw = signs * q_robot + offsets [rad].
    """

    a1: float
    a2: float
    b: float
    c1: float
    c2: float
    c3: float
    c4: float
    offsets: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    signs: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        if self.b != 0.0:
            raise RobotError("OPW with a lateral offset b != 0 is not implemented; set b = 0")
        if min(self.c2, self.c3, self.c4) <= 0 or len(self.offsets) != 6 or len(self.signs) != 6:
            raise RobotError("OPW parameters need c2, c3, c4 > 0 and 6 offsets/signs; fix them")


# IRB 4600-60/2.05 (datasheet dimensions, as in ROS-Industrial's opw parameters); this model's
# joint 3 is zero with the forearm horizontal, OPW's with the forearm vertical: offset +pi/2.
IRB4600_60_205 = OPWParameters(a1=0.175, a2=-0.175, b=0.0, c1=0.495, c2=0.900, c3=0.960,
                               c4=0.135, offsets=(0.0, 0.0, np.pi / 2, 0.0, 0.0, 0.0))

# IRB 5500-class paint arm (paintcell/robots/abb_irb5500/README.md step 1): lengths chosen so that
# the reach to the wrist centre, a1 + c2 + sqrt(a2² + c3²), is the datasheet's 2.975 m; same joint-3
# convention as above.
IRB5500_CLASS = OPWParameters(a1=0.300, a2=-0.150, b=0.0, c1=0.750, c2=1.200, c3=1.467,
                              c4=0.150, offsets=(0.0, 0.0, np.pi / 2, 0.0, 0.0, 0.0))


def _rz(t: np.ndarray) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    R = np.zeros(t.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1], R[..., 2, 2] = c, -s, s, c, 1.0
    return R


def _ry(t: np.ndarray) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    R = np.zeros(t.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 2], R[..., 2, 0], R[..., 2, 2], R[..., 1, 1] = c, s, -s, c, 1.0
    return R


def wrap_pi(q: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi) [rad]."""
    return (np.asarray(q) + np.pi) % (2 * np.pi) - np.pi


def forward(p: OPWParameters, Q: npt.ArrayLike) -> np.ndarray:
    """T_base_flange (K, 4, 4) for robot joint angles Q (K, 6) [rad] (vectorized)."""
    Q = np.atleast_2d(np.asarray(Q, float))
    if Q.shape[-1] != 6:
        raise RobotError(f"OPW forward needs (K, 6) joint angles, got {Q.shape}")
    t = Q * np.asarray(p.signs) + np.asarray(p.offsets)
    R01 = _rz(t[:, 0])
    R0c = R01 @ _ry(t[:, 1] + t[:, 2])
    upper = np.array([p.a1, 0.0, p.c1]) + _ry(t[:, 1]) @ np.array([0.0, 0.0, p.c2])   # (K, 3)
    C = np.einsum("kij,kj->ki", R01, upper) + R0c @ np.array([p.a2, 0.0, p.c3])
    R0e = R0c @ _rz(t[:, 3]) @ _ry(t[:, 4]) @ _rz(t[:, 5])
    T = np.zeros((len(Q), 4, 4))
    T[:, :3, :3] = R0e
    T[:, :3, 3] = C + p.c4 * R0e[:, :, 2]
    T[:, 3, 3] = 1.0
    return T


def configuration_signs(p: OPWParameters, Q: npt.ArrayLike) -> np.ndarray:
    """(K, 3) configuration of robot joint angles Q (K, 6) [rad]: the signs (+1, −1; 0 exactly on
    the singularity) of
    - shoulder: the wrist centre's distance in front of the J1 axis, measured in the arm's own
      plane (a1 + c2 sin t2 + a2 cos(t2 + t3) + c3 sin(t2 + t3); 0: the wrist centre on the J1
      axis, the shoulder singularity);
    - elbow: sin φ, φ = t3 + atan2(a2, c3) the elbow angle `inverse` branches on (0: the arm
      stretched, the elbow singularity);
    - wrist: sin t5 (0: J4 and J6 aligned, the wrist singularity).
    A sign change between two poses of a path means the arm went through that singularity: a
    configuration flip, which `inverse` lists as another branch."""
    Q = np.atleast_2d(np.asarray(Q, float))
    if Q.shape[-1] != 6:
        raise RobotError(f"OPW configuration needs (K, 6) joint angles, got {Q.shape}")
    t = Q * np.asarray(p.signs) + np.asarray(p.offsets)
    t23 = t[:, 1] + t[:, 2]
    front = p.a1 + p.c2 * np.sin(t[:, 1]) + p.a2 * np.cos(t23) + p.c3 * np.sin(t23)
    elbow = np.sin(t[:, 2] + np.arctan2(p.a2, p.c3))
    return np.sign(np.column_stack([front, elbow, np.sin(t[:, 4])])).astype(int)


def inverse(p: OPWParameters, T_base_flange: npt.ArrayLike,
            tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """All 8 closed-form solutions for flange poses T_base_flange (M, 4, 4) [m].

    Returns Q (M, 8, 6) robot joint angles [rad] wrapped to [-pi, pi) (not yet fitted to the joint
    limits, see `fit_to_limits`) and valid (M, 8): the arm can reach the wrist centre on that branch
    (no NaN rows). The wrist singularity (q5 = 0) gives an arbitrary q4/q6 split.
    """
    T = np.asarray(T_base_flange, float)
    if T.ndim == 2:
        T = T[None]
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise RobotError(f"OPW inverse needs (M, 4, 4) poses, got {T.shape}")
    M = len(T)
    R = T[:, :3, :3]
    C = T[:, :3, 3] - p.c4 * R[:, :, 2]
    k2 = p.a2 ** 2 + p.c3 ** 2
    k = np.sqrt(k2)
    psi3 = np.arctan2(p.a2, p.c3)

    t1a = np.arctan2(C[:, 1], C[:, 0])
    t1 = np.stack([t1a, t1a + np.pi], axis=1)                     # (M, 2) shoulder
    r = C[:, None, 0] * np.cos(t1) + C[:, None, 1] * np.sin(t1) - p.a1
    h = np.broadcast_to((C[:, 2] - p.c1)[:, None], r.shape)
    cphi = (r ** 2 + h ** 2 - p.c2 ** 2 - k2) / (2 * p.c2 * k)
    reach = np.abs(cphi) <= 1.0 + tol
    phi_abs = np.arccos(np.clip(cphi, -1.0, 1.0))
    phi = np.stack([phi_abs, -phi_abs], axis=2)                   # (M, 2, 2) elbow
    t2 = np.arctan2(r, h)[:, :, None] - np.arctan2(k * np.sin(phi), p.c2 + k * np.cos(phi))
    t3 = phi - psi3
    t1b = np.broadcast_to(t1[:, :, None], t2.shape)

    R0c = _rz(t1b) @ _ry(t2 + t3)                                 # (M, 2, 2, 3, 3)
    Rce = np.swapaxes(R0c, -1, -2) @ R[:, None, None]
    t5 = np.arctan2(np.hypot(Rce[..., 0, 2], Rce[..., 1, 2]), Rce[..., 2, 2])
    t4 = np.arctan2(Rce[..., 1, 2], Rce[..., 0, 2])
    t6 = np.arctan2(Rce[..., 2, 1], -Rce[..., 2, 0])
    wrist = np.stack([np.stack([t4, t5, t6], -1),
                      np.stack([t4 + np.pi, -t5, t6 + np.pi], -1)], axis=3)  # (M,2,2,2,3)
    arm = np.broadcast_to(np.stack([t1b, t2, t3], -1)[:, :, :, None, :], wrist.shape)
    Q_opw = np.concatenate([arm, wrist], axis=-1).reshape(M, N_BRANCHES, 6)
    Q = (Q_opw - np.asarray(p.offsets)) * np.asarray(p.signs)
    valid = np.broadcast_to(reach[:, :, None, None], (M, 2, 2, 2)).reshape(M, N_BRANCHES)
    return wrap_pi(Q), valid.copy()


def fit_to_limits(Q: npt.ArrayLike, q_lower: npt.ArrayLike, q_upper: npt.ArrayLike,
                  q_ref: npt.ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pick, joint by joint, the 2π-equivalent of Q (..., n) [rad] inside [q_lower, q_upper]
    closest to q_ref (..., n) (default: the middle of the range), e.g. J4/J6 with ±400°.

    Returns (Q_fitted, within (...,)): within is False where some joint has no equivalent in range
    (that joint is then left at the equivalent closest to the range).
    """
    Q = np.asarray(Q, float)
    lo, hi = np.asarray(q_lower, float), np.asarray(q_upper, float)
    ref = (lo + hi) / 2 if q_ref is None else np.asarray(q_ref, float)
    ks = np.arange(-3, 4) * 2 * np.pi
    cand = Q[..., None] + ks                                       # (..., n, 7)
    inside = (cand >= lo[:, None] - 1e-12) & (cand <= hi[:, None] + 1e-12)
    dist = np.abs(cand - np.asarray(ref)[..., None])
    out_dist = np.maximum(lo[:, None] - cand, cand - hi[:, None])
    score = np.where(inside, dist, 1e6 + out_dist)
    idx = np.argmin(score, axis=-1)
    Qf = np.take_along_axis(cand, idx[..., None], axis=-1)[..., 0]
    within = np.all(np.take_along_axis(inside, idx[..., None], axis=-1)[..., 0], axis=-1)
    return Qf, within
