"""paintcell.core.transforms: the one rigid-pose check, pose inverse and rotation conversions,
held to
scipy's `Rotation` and MuJoCo's own conversions."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from paintcell.core.errors import PaintcellError
from paintcell.core.transforms import (
    TransformError,
    check_pose,
    check_poses,
    inverse_pose,
    matrix_from_axis_angle,
    matrix_from_quat_wxyz,
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


def _random_quats(n: int, seed: int) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_matrix_from_quat_matches_mujoco_and_scipy() -> None:
    q = np.concatenate([_random_quats(200, 2), np.eye(4)])  # w, x, y, z = 1: the π turns too
    R = matrix_from_quat_wxyz(q)
    assert R.shape == (len(q), 3, 3)
    for qk, Rk in zip(q, R, strict=True):
        ref = np.zeros(9)
        mujoco.mju_quat2Mat(ref, qk)
        np.testing.assert_allclose(Rk, ref.reshape(3, 3), atol=QUAT_ROUND_TRIP_ATOL)
    xyzw = np.column_stack([q[:, 1:], q[:, 0]])
    np.testing.assert_allclose(R, Rotation.from_quat(xyzw).as_matrix(), atol=QUAT_ROUND_TRIP_ATOL)
    # −q is the same rotation; any leading shape; the inverse of quat_wxyz_from_matrix.
    np.testing.assert_array_equal(matrix_from_quat_wxyz(-q), R)
    np.testing.assert_array_equal(matrix_from_quat_wxyz(q.reshape(3, -1, 4)),
                                  R.reshape(3, -1, 3, 3))
    np.testing.assert_allclose(matrix_from_quat_wxyz(quat_wxyz_from_matrix(R)), R,
                               atol=QUAT_ROUND_TRIP_ATOL)
    assert matrix_from_quat_wxyz([1.0, 0, 0, 0]).shape == (3, 3)
    with pytest.raises(TransformError, match="quaternion"):
        matrix_from_quat_wxyz(np.ones(3))
    with pytest.raises(TransformError, match="quaternion"):
        matrix_from_quat_wxyz([np.nan, 0, 0, 1])


def test_matrix_from_axis_angle_matches_scipy_and_mujoco() -> None:
    rng = np.random.default_rng(3)
    axes = rng.normal(size=(100, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = rng.uniform(-2 * np.pi, 2 * np.pi, 100)
    for a, th in zip(axes, angles, strict=True):
        R = matrix_from_axis_angle(a, th)
        np.testing.assert_allclose(R, Rotation.from_rotvec(th * a).as_matrix(),
                                   atol=QUAT_ROUND_TRIP_ATOL)
        q, ref = np.zeros(4), np.zeros(9)
        mujoco.mju_axisAngle2Quat(q, a, th)
        mujoco.mju_quat2Mat(ref, q)
        np.testing.assert_allclose(R, ref.reshape(3, 3), atol=QUAT_ROUND_TRIP_ATOL)
    # Right-handed: +90° about z takes x to y.
    np.testing.assert_allclose(matrix_from_axis_angle([0.0, 0, 1], np.pi / 2) @ [1.0, 0, 0],
                               [0.0, 1, 0], atol=1e-15)
    np.testing.assert_array_equal(matrix_from_axis_angle([1.0, 0, 0], 0.0), np.eye(3))
    with pytest.raises(TransformError, match="unit"):
        matrix_from_axis_angle([0.0, 0, 2], 0.1)
    with pytest.raises(TransformError, match="axis"):
        matrix_from_axis_angle([0.0, 1], 0.1)
    with pytest.raises(TransformError, match="finite"):
        matrix_from_axis_angle([0.0, 0, 1], np.inf)


def test_inverse_pose_matches_linalg_and_composes_to_identity() -> None:
    rng = np.random.default_rng(4)
    T = np.tile(np.eye(4), (50, 1, 1))
    T[:, :3, :3] = _random_rotations(50, 5)
    T[:, :3, 3] = rng.normal(scale=2.0, size=(50, 3))
    inv = inverse_pose(T)
    np.testing.assert_allclose(inv, np.linalg.inv(T), atol=1e-12)
    np.testing.assert_allclose(inv @ T, np.broadcast_to(np.eye(4), T.shape), atol=1e-12)
    check_poses(inv, "inverse")
    # One pose = the same as the stack's entry; a pose given as nested lists works too.
    np.testing.assert_array_equal(inverse_pose(T[7]), inv[7])
    np.testing.assert_array_equal(inverse_pose(T[7].tolist()), inv[7])
    # MuJoCo's own frame inverse (position + quaternion).
    pos, quat = np.zeros(3), np.zeros(4)
    mujoco.mju_negPose(pos, quat, T[7, :3, 3], quat_wxyz_from_matrix(T[7, :3, :3]))
    np.testing.assert_allclose(inv[7, :3, 3], pos, atol=1e-12)
    np.testing.assert_allclose(inv[7, :3, :3], matrix_from_quat_wxyz(quat), atol=1e-12)
    with pytest.raises(TransformError, match="shape"):
        inverse_pose(np.eye(3))
