"""Rigid transforms: the one pose check, pose inverse and rotation conversions.

Poses are 4×4 homogeneous `T_a_b` (DESIGN.md); quaternions are (w, x, y, z), MuJoCo's order.
`robots` and `sim` use these instead of their own copies (planning imports neither).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from paintcell.core.errors import PaintcellError

#: Default tolerance of `check_pose`: max |RᵀR − I| entry, |det R − 1| and last-row deviation.
#: Rotations built in float64 from unit vectors or products of a few rotations are orthonormal to
#: ~1e-15; 1e-6 accepts those and poses written with 7 significant digits, and rejects a scale
#: or shear that would move a point 1 m away by more than 1 µm.
POSE_TOL = 1e-6


class TransformError(PaintcellError):
    """A pose is not a finite rigid transform."""


def check_poses(T: npt.ArrayLike, name: str, tol: float = POSE_TOL,
                error: type[PaintcellError] = TransformError) -> np.ndarray:
    """Check a stack of poses T (..., 4, 4): finite, rotation orthonormal with det +1, last row
    [0 0 0 1], each within `tol`. Returns them as a float64 array; raises `error` (default
    `TransformError`) naming `name` (and the first bad pose's index for a stack)."""
    A = np.array(T, dtype=float)
    if A.ndim < 2 or A.shape[-2:] != (4, 4):
        raise error(f"{name} has shape {A.shape}; pass a finite 4x4 rigid transform"
                    + (" per pose" if A.ndim > 2 else ""))
    flat = A.reshape(-1, 4, 4)
    R = flat[:, :3, :3]
    finite = np.all(np.isfinite(flat), axis=(1, 2))
    with np.errstate(invalid="ignore", over="ignore"):
        ortho = np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3)).max(axis=(1, 2)) <= tol
        det = np.abs(np.linalg.det(np.where(finite[:, None, None], R, np.eye(3))) - 1.0) <= tol
        row = np.abs(flat[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1) <= tol
    checks = ((finite, "non-finite entries"),
              (ortho, "rotation block not orthonormal (scaled or sheared)"),
              (det, "rotation block has det != +1 (a reflection)"),
              (row, "last row not [0 0 0 1]"))
    for ok, why in checks:
        bad = np.flatnonzero(~ok)
        if len(bad):
            idx = tuple(int(i) for i in np.unravel_index(bad[0], A.shape[:-2]))
            where = (f" (pose {idx[0] if len(idx) == 1 else idx})" if A.ndim > 2 else "")
            raise error(f"{name}{where} is not a rigid transform: {why}; pass a finite 4x4 pose "
                        "with an orthonormal rotation (det +1) and last row [0 0 0 1]")
    return A


def check_pose(T: npt.ArrayLike, name: str, tol: float = POSE_TOL,
               error: type[PaintcellError] = TransformError) -> np.ndarray:
    """Check one pose T (4, 4) like `check_poses` and return it as a float64 (4, 4) array."""
    A = np.asarray(T, dtype=float)
    if A.shape != (4, 4):
        raise error(f"{name} has shape {A.shape}; pass a finite 4x4 rigid transform")
    return check_poses(A, name, tol, error)


def quat_wxyz_from_matrix(R: npt.ArrayLike) -> np.ndarray:
    """Unit quaternions (..., 4) (w, x, y, z), w ≥ 0, of rotation matrices R (..., 3, 3).

    scipy's `Rotation.from_matrix` does the conversion (Shepperd-style, no division by a small
    number); only the order (MuJoCo's and ABB RAPID's w-first) and the sign (w ≥ 0) are ours.
    """
    from scipy.spatial.transform import Rotation

    M = np.asarray(R, dtype=float)
    if M.ndim < 2 or M.shape[-2:] != (3, 3) or not np.all(np.isfinite(M)):
        raise TransformError(f"rotation has shape {M.shape} or non-finite entries; pass finite "
                             "3x3 rotation matrices")
    xyzw = Rotation.from_matrix(M.reshape(-1, 3, 3)).as_quat()
    q = np.column_stack([xyzw[:, 3], xyzw[:, :3]])
    q[q[:, 0] < 0] *= -1.0
    return q.reshape(*M.shape[:-2], 4)


def matrix_from_quat_wxyz(q: npt.ArrayLike) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions q (..., 4) (w, x, y, z).

    The closed-form product of a unit quaternion (what MuJoCo's `mju_quat2Mat` and scipy's
    `Rotation.as_matrix` compute); q is not renormalized: pass unit quaternions (e.g. MuJoCo's
    `framequat` sensor after dividing by its norm). q and −q give the same matrix.
    """
    Q = np.asarray(q, dtype=float)
    if Q.ndim < 1 or Q.shape[-1] != 4 or not np.all(np.isfinite(Q)):
        raise TransformError(f"quaternion has shape {Q.shape} or non-finite entries; pass finite "
                             "(..., 4) quaternions (w, x, y, z)")
    w, x, y, z = Q[..., 0], Q[..., 1], Q[..., 2], Q[..., 3]
    R = np.empty((*Q.shape[:-1], 3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


#: How far from 1 the norm of an axis given to `matrix_from_axis_angle` may be.
AXIS_UNIT_TOL = 1e-9


def matrix_from_axis_angle(axis: npt.ArrayLike, angle_rad: float) -> np.ndarray:
    """Rotation matrix (3, 3) by `angle_rad` [rad] about the unit vector `axis` (3,) (Rodrigues:
    I + sin θ K + (1 − cos θ) K², K the cross-product matrix of the axis; right-handed).

    The axis must already be unit (within `AXIS_UNIT_TOL`): it is used as given, not rescaled.
    """
    a = np.asarray(axis, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or not np.isfinite(angle_rad):
        raise TransformError(f"axis has shape {a.shape} or a non-finite entry or angle; pass a "
                             "finite unit (3,) axis and a finite angle [rad]")
    if abs(float(np.linalg.norm(a)) - 1.0) > AXIS_UNIT_TOL:
        raise TransformError(f"axis {a} is not a unit vector (norm {np.linalg.norm(a):.6g}); "
                             "divide it by its norm first")
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle_rad) * K + (1 - np.cos(angle_rad)) * K @ K


def inverse_pose(T: npt.ArrayLike) -> np.ndarray:
    """Inverse of rigid poses T (..., 4, 4): `T_b_a` from `T_a_b` (Rᵀ, −Rᵀ p), exact for a rigid
    transform (no general matrix inverse). The input is not checked: use `check_pose(s)` at the
    boundary where poses enter."""
    A = np.asarray(T, dtype=float)
    if A.ndim < 2 or A.shape[-2:] != (4, 4):
        raise TransformError(f"pose has shape {A.shape}; pass (..., 4, 4) rigid transforms")
    Rt = np.swapaxes(A[..., :3, :3], -1, -2)
    out = np.zeros(A.shape)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -(Rt @ A[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def half_turned(T: npt.ArrayLike) -> np.ndarray:
    """Poses (..., 4, 4) turned half a turn about their own z axis (x → −x, y → −y): the same
    position and z axis. A bell's spray pattern is even in x and y, so a pass whose TCP frames
    are half-turned lays the same film (`paintcell.paint.deposition`)."""
    out = np.array(T, float, copy=True)
    out[..., :3, :2] *= -1.0
    return out
