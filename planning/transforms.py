"""Rigid transforms: the one pose check and the one rotation → quaternion conversion.

Poses are 4×4 homogeneous `T_a_b` (DESIGN.md); quaternions are (w, x, y, z), MuJoCo's order.
`robots` and `sim` use these instead of their own copies (planning imports neither).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from planning.errors import PaintcellError

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
    """Unit quaternion (4,) (w, x, y, z), w ≥ 0, of a rotation matrix R (3, 3).

    Shepperd's method: the largest of the four squared components is taken from the diagonal,
    the others from off-diagonal sums, so no branch divides by a small number.
    """
    M = np.asarray(R, dtype=float)
    if M.shape != (3, 3) or not np.all(np.isfinite(M)):
        raise TransformError(f"rotation has shape {M.shape} or non-finite entries; pass a "
                             "finite 3x3 rotation matrix")
    tr = float(np.trace(M))
    d = np.array([tr, M[0, 0], M[1, 1], M[2, 2]])
    k = int(np.argmax(d))
    if k == 0:
        s = 2.0 * np.sqrt(max(1.0 + tr, 0.0))
        q = np.array([0.25 * s, (M[2, 1] - M[1, 2]) / s, (M[0, 2] - M[2, 0]) / s,
                      (M[1, 0] - M[0, 1]) / s])
    elif k == 1:
        s = 2.0 * np.sqrt(max(1.0 + M[0, 0] - M[1, 1] - M[2, 2], 0.0))
        q = np.array([(M[2, 1] - M[1, 2]) / s, 0.25 * s, (M[0, 1] + M[1, 0]) / s,
                      (M[0, 2] + M[2, 0]) / s])
    elif k == 2:
        s = 2.0 * np.sqrt(max(1.0 - M[0, 0] + M[1, 1] - M[2, 2], 0.0))
        q = np.array([(M[0, 2] - M[2, 0]) / s, (M[0, 1] + M[1, 0]) / s, 0.25 * s,
                      (M[1, 2] + M[2, 1]) / s])
    else:
        s = 2.0 * np.sqrt(max(1.0 - M[0, 0] - M[1, 1] + M[2, 2], 0.0))
        q = np.array([(M[1, 0] - M[0, 1]) / s, (M[0, 2] + M[2, 0]) / s,
                      (M[1, 2] + M[2, 1]) / s, 0.25 * s])
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q
