"""Shared named tolerances and assertions for the test suite.

Each tolerance carries a one-line justification. Append new entries; do not rewrite others'.
"""

from __future__ import annotations

import numpy as np

# --- geometry (surfaces, curvature) -------------------------------------------------------------
# Closed-form curvature of an analytic patch: only float64 round-off in the fundamental forms.
ANALYTIC_CURVATURE_ATOL = 1e-9
# Unit vectors built by normalization: round-off of a norm of O(1) components.
UNIT_NORM_ATOL = 1e-12
# Discrete K (angle defect) and H (cotan Laplacian) on a smooth mesh of ~1-2 cm edges: the spec
# asks for K ≈ 1/R² within 2 %; O(h²) truncation on regular meshes is ~0.1 % there.
DISCRETE_CURVATURE_RTOL = 0.02
# Sum of per-vertex areas against the closed-form area of the smooth surface, for a mesh of edge h
# on radius R: the chordal deficit is O((h/R)²) ≈ 1e-4 at h = 1-2 cm, R = 1 m.
MESH_AREA_RTOL = 1e-3
# Rigid-transform round trip of positions [m]: a few ulps of 1 m coordinates.
ROUND_TRIP_ATOL_M = 1e-12


def assert_unit(vectors: np.ndarray, atol: float = UNIT_NORM_ATOL) -> None:
    """Every row of `vectors` (..., 3) has unit length within `atol`."""
    norms = np.linalg.norm(vectors, axis=-1)
    assert np.allclose(norms, 1.0, atol=atol), f"max |norm - 1| = {np.abs(norms - 1).max():.3g}"


# --- speed QP (planning.speed_qp) ----------------------------------------------------------------
# Re-measured constraints of an accepted QP solution, relative to each bound: the module's own
# acceptance tolerance (planning.speed_qp.CONSTRAINT_RTOL); polished OSQP solutions meet ~1e-10.
QP_CONSTRAINT_RTOL = 1e-6
# Central finite differences of a quadratic objective at step 1e-5 on O(1) variables: exact up to
# round-off (~1e-16 · J / h ≈ 1e-12 relative), so 1e-6 is ample yet catches any wrong Hessian term.
FD_GRADIENT_RTOL = 1e-6


# --- robots (kinematics, IK) ---------------------------------------------------------------------
# MuJoCo vs Pinocchio TCP position of the same MJCF [m]: both compose the same float64 transforms;
# the issue asks for 1e-9 m (observed ~1e-15).
FK_AGREEMENT_ATOL_M = 1e-9
# ... and orientation (max entry of the rotation-matrix difference), same reasoning.
FK_AGREEMENT_ATOL_ROT = 1e-9
# Closed-form OPW IK round trip [m, rad-like matrix entries]: acos/atan2 round-off near 1 m links
# (observed ~5e-15); 1e-9 leaves room for poses near the workspace boundary.
OPW_ROUND_TRIP_ATOL = 1e-9
# Damped-least-squares IK targets of the issue: 1e-6 m position, 1e-5 rad orientation.
IK_POS_TOL_M = 1e-6
IK_ROT_TOL_RAD = 1e-5
# Jacobian vs central finite differences with step 1e-6 rad: truncation O(h²·|FK'''|) ≈ 1e-12,
# round-off ~1e-16/1e-6 = 1e-10; 1e-7 catches any wrong column or frame.
JACOBIAN_FD_ATOL = 1e-7
