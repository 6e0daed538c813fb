"""planning.transforms: the one rigid-pose check and the one rotation → quaternion conversion."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from planning.errors import PaintcellError
from planning.transforms import (
    TransformError,
    check_pose,
    check_poses,
    quat_wxyz_from_matrix,
)

# Quaternion → matrix → quaternion in float64: a few ulps of O(1) entries.
QUAT_ROUND_TRIP_ATOL = 1e-12


def _random_rotations(n: int, seed: int) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    R = np.empty((n, 9))
    for k in range(n):
        mujoco.mju_quat2Mat(R[k], q[k])
    return R.reshape(n, 3, 3)


def test_check_pose_accepts_rigid_and_returns_float() -> None:
    T = np.eye(4, dtype=int)
    out = check_pose(T, "T")
    assert out.dtype == np.float64 and np.array_equal(out, np.eye(4))
    T = np.eye(4)
    T[:3, :3] = _random_rotations(1, 0)[0]
    T[:3, 3] = [1.0, -2.0, 3.0]
    assert np.array_equal(check_pose(T, "T"), T)


@pytest.mark.parametrize(("edit", "why"), [
    (lambda T: T.__setitem__((slice(0, 3), slice(0, 3)), 2 * np.eye(3)), "orthonormal"),
    (lambda T: T.__setitem__((0, 1), 0.1), "orthonormal"),
    (lambda T: T.__setitem__((2, 2), -1.0), "det"),
    (lambda T: T.__setitem__((3, 0), 0.5), "last row"),
    (lambda T: T.__setitem__((0, 3), np.nan), "non-finite"),
    (lambda T: T.__setitem__((1, 3), np.inf), "non-finite"),
])
def test_check_pose_rejects_non_rigid(edit, why: str) -> None:
    T = np.eye(4)
    edit(T)
    with pytest.raises(TransformError, match=f"T_world_part.*{why}"):
        check_pose(T, "T_world_part")


def test_check_pose_shape_tolerance_and_error_class() -> None:
    with pytest.raises(TransformError, match=r"T has shape \(3, 3\)"):
        check_pose(np.eye(3), "T")
    with pytest.raises(TransformError, match="shape"):
        check_pose(np.eye(4)[None], "T")
    T = np.eye(4)
    T[0, 0] = 1 + 1e-4
    check_pose(T, "T", tol=1e-3)
    with pytest.raises(TransformError):
        check_pose(T, "T")

    class MyError(PaintcellError):
        pass

    with pytest.raises(MyError, match="tcp_offset"):
        check_pose(np.diag([2.0, 1, 1, 1]), "tcp_offset", error=MyError)
    assert issubclass(TransformError, PaintcellError)


def test_check_poses_names_the_first_bad_pose() -> None:
    T = np.tile(np.eye(4), (5, 1, 1))
    assert check_poses(T, "path").shape == (5, 4, 4)
    T[3, :3, :3] *= 2.0
    with pytest.raises(TransformError, match=r"path \(pose 3\) is not a rigid"):
        check_poses(T, "path")


def test_quat_matches_mujoco_and_round_trips() -> None:
    Rs = _random_rotations(200, 1)
    # The hard cases of a trace-based formula: rotations by π about each axis and a diagonal.
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    Rs = np.concatenate([Rs, np.diag([1.0, -1, -1])[None], np.diag([-1.0, 1, -1])[None],
                         np.diag([-1.0, -1, 1])[None], (2 * np.outer(d, d) - np.eye(3))[None],
                         np.eye(3)[None]])
    for R in Rs:
        q = quat_wxyz_from_matrix(R)
        assert q[0] >= 0 and np.isclose(np.linalg.norm(q), 1.0, atol=QUAT_ROUND_TRIP_ATOL)
        ref = np.zeros(4)
        mujoco.mju_mat2Quat(ref, R.ravel())
        ref = ref if ref[0] >= 0 else -ref
        if abs(q[0]) > 1e-9:   # w = 0: q and −q are both canonical
            np.testing.assert_allclose(q, ref, atol=QUAT_ROUND_TRIP_ATOL)
        back = np.zeros(9)
        mujoco.mju_quat2Mat(back, q)
        np.testing.assert_allclose(back.reshape(3, 3), R, atol=QUAT_ROUND_TRIP_ATOL)
    with pytest.raises(TransformError, match="3x3"):
        quat_wxyz_from_matrix(np.eye(4))
