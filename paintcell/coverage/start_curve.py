"""Start-curve selection (paper §2.3): orientation by minimal altitude, position by the geodesic
Gaussian-curvature divider.

The start curve approximates a geodesic by a planar section. The section plane's normal d (the
indexing direction) is orthogonal to the area-weighted average surface normal n̄; among the
rotations of d about n̄ the one that minimizes the surface altitude max(x·d) − min(x·d) gives the
fewest passes (Fig. 3(b)). The plane's offset along d splits ∫K dA equally between the two sides
(eq. 1: it minimizes the geodesic curvature of the bounding passes); where |∫K dA| is negligible
(plane, cylinder, extruded sheet) every position is equal by that rule and the area median is
used instead. Both rules and any user override are recorded in `StartCurve.rule`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.core.errors import PlanError
from paintcell.coverage.offset_polyline import resample
from paintcell.coverage.offset_sections import SurfaceGeometry, plane_sections

#: Angular step of the orientation sweep [rad] (the paper sweeps the section-plane rotation).
SWEEP_STEP_RAD = np.deg2rad(1.0)
#: |∫K dA| below this [rad] counts as "no Gaussian curvature" (the Gauss–Bonnet divider is then
#: undefined). Discrete K of a developable mesh integrates to ~1e-4 rad; a crowned hood to ~0.1.
TOTAL_K_NEGLIGIBLE_RAD = 1e-2

ORIENTATIONS = ("auto", "zero-curvature", "max-curvature")


@dataclass(frozen=True, eq=False)
class StartCurve:
    """The start curve and how it was chosen.

    points: (M, 3) foot points on the surface, ordered along `pass_dir` [m].
    normals: (M, 3) unit surface normals (painted side).
    plane_normal: (3,) unit section-plane normal = the indexing direction ("right" of the pass is
        ±plane_normal; see `paintcell.coverage.algorithm`).
    plane_offset_m: the plane is {x : x · plane_normal = plane_offset_m} [m].
    pass_dir: (3,) unit direction of travel along the start curve (n̄ × plane_normal).
    average_normal: (3,) area-weighted mean unit normal n̄.
    angle_rad: angle of `pass_dir` about n̄ measured from the part x axis projected [rad].
    altitude_m: extent of the surface along plane_normal [m].
    total_k_rad: ∫K dA over the surface [rad].
    rule: one line: orientation rule and position rule used.
    """

    points: np.ndarray
    normals: np.ndarray
    plane_normal: np.ndarray
    plane_offset_m: float
    pass_dir: np.ndarray
    average_normal: np.ndarray
    angle_rad: float
    altitude_m: float
    total_k_rad: float
    rule: str


def average_normal(surface: Any) -> np.ndarray:
    """(3,) area-weighted mean unit normal of the surface (painted side)."""
    n = np.asarray(surface.vertex_areas, float) @ np.asarray(surface.normals, float)
    norm = np.linalg.norm(n)
    if norm < 1e-9 * float(np.sum(surface.vertex_areas)):
        raise PlanError("the surface's normals cancel out (closed or folded part); plan it as "
                        "separate open patches")
    return n / norm


def tangent_basis(nbar: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(e1, e2): orthonormal basis of the plane ⟂ n̄; e1 = part x projected (y if x ∥ n̄)."""
    ref = np.array([1.0, 0.0, 0.0])
    if abs(ref @ nbar) > 0.9:
        ref = np.array([0.0, 1.0, 0.0])
    e1 = ref - (ref @ nbar) * nbar
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(nbar, e1)


def altitude_sweep(vertices: npt.ArrayLike, nbar: np.ndarray,
                   step_rad: float = SWEEP_STEP_RAD) -> tuple[np.ndarray, np.ndarray]:
    """Altitude of the surface across passes of each direction about n̄.

    vertices: (N, 3) [m]; nbar: (3,) unit average normal.
    Returns angles (A,) [rad] in [0, π) of the pass direction (from e1 toward e2) and the
    altitude (A,) [m]: the extent of the vertices along the indexing direction n̄ × pass_dir.
    """
    e1, e2 = tangent_basis(nbar)
    ang = np.arange(0.0, np.pi, step_rad)
    pass_dirs = np.outer(np.cos(ang), e1) + np.outer(np.sin(ang), e2)     # (A, 3)
    index_dirs = np.cross(nbar, pass_dirs)
    proj = np.asarray(vertices, float) @ index_dirs.T                      # (N, A)
    return ang, proj.max(axis=0) - proj.min(axis=0)


def principal_direction_angle(surface: Any, nbar: np.ndarray, which: str) -> float:
    """Area-weighted mean angle [rad] about n̄ of the zero- or max-curvature principal direction.

    which: "zero-curvature" (the principal direction whose |k| is smaller at each vertex) or
    "max-curvature" (the one with larger |k|). Directions are axial (±), so they are averaged as
    doubled angles; the result is in [0, π).
    """
    k = np.asarray(surface.principal_curvatures, float)
    dirs = np.asarray(surface.principal_directions, float)
    pick_small = np.abs(k[:, 1]) < np.abs(k[:, 0])          # index of the smaller |k|
    small = np.where(pick_small[:, None], dirs[:, 1], dirs[:, 0])
    large = np.where(pick_small[:, None], dirs[:, 0], dirs[:, 1])
    d = small if which == "zero-curvature" else large
    e1, e2 = tangent_basis(nbar)
    phi = np.arctan2(d @ e2, d @ e1)
    # weight by area and by how distinct the two curvatures are (umbilic points carry no axis)
    w = np.asarray(surface.vertex_areas, float) * np.abs(np.abs(k[:, 0]) - np.abs(k[:, 1]))
    if w.sum() <= 0:
        raise PlanError(f"orientation {which!r} is undefined: the surface has no distinct "
                        "principal directions (plane or sphere); use 'auto' or an angle")
    c, s = w @ np.cos(2 * phi), w @ np.sin(2 * phi)
    angle = float(np.mod(0.5 * np.arctan2(s, c), np.pi))
    return 0.0 if np.pi - angle < 1e-9 else angle    # −0 wraps to π: same axis as 0


def divider_offset(proj: np.ndarray, weights: np.ndarray) -> float:
    """Offset t where the cumulative sum of `weights` sorted by `proj` reaches half its total.

    proj: (N,) vertex coordinates along the indexing direction [m]; weights: (N,) (K·A or A).
    Linear interpolation between sorted vertices.
    """
    order = np.argsort(proj, kind="stable")
    c = np.cumsum(weights[order])
    half = 0.5 * c[-1]
    if c[-1] < 0:
        c, half = -c, -half
    i = int(np.clip(np.searchsorted(c, half), 0, len(c) - 1))
    if i == 0:
        return float(proj[order[0]])
    c0, c1 = c[i - 1], c[i]
    t = 0.0 if c1 == c0 else (half - c0) / (c1 - c0)
    return float(proj[order[i - 1]] + t * (proj[order[i]] - proj[order[i - 1]]))


def select_start_curve(surface: Any, orientation: float | str = "auto",
                       position: float | None = None, spacing_m: float = 0.02,
                       geom: SurfaceGeometry | None = None) -> StartCurve:
    """Choose and build the start curve of `surface` (paper §2.3).

    surface: a `paintcell.surface.analytic.Surface` (part frame).
    orientation: "auto" (minimal altitude), "zero-curvature" / "max-curvature" (passes along the
        area-weighted principal direction), or an angle [rad] of the pass direction about n̄
        measured from the part x axis projected onto the plane ⟂ n̄.
    position: None (Gaussian-curvature divider, else area median) or a fraction in [0, 1] of
        the altitude along the indexing direction (0 = the low end).
    spacing_m: sample spacing of the returned polyline [m].
    geom: precomputed mesh connectivity (built when None).
    """
    if isinstance(orientation, str) and orientation not in ORIENTATIONS:
        raise PlanError(f"orientation {orientation!r} is unknown; use one of {ORIENTATIONS} or an "
                        "angle in radians")
    if position is not None and not (0.0 <= float(position) <= 1.0):
        raise PlanError(f"start position {position} must be a fraction in [0, 1] of the altitude "
                        "(or None for the curvature divider)")
    geom = SurfaceGeometry.from_surface(surface) if geom is None else geom
    nbar = average_normal(surface)
    e1, e2 = tangent_basis(nbar)
    v = np.asarray(surface.vertices, float)
    if isinstance(orientation, str) and orientation == "auto":
        ang, alt = altitude_sweep(v, nbar)
        angle = float(ang[int(np.argmin(alt))])
        orient_rule = "orientation: minimal altitude"
    elif isinstance(orientation, str):
        angle = principal_direction_angle(surface, nbar, orientation)
        orient_rule = f"orientation: along {orientation} direction"
    else:
        angle = float(orientation)
        if not np.isfinite(angle):
            raise PlanError(f"orientation angle {orientation} is not finite; give radians")
        orient_rule = f"orientation: user angle {np.rad2deg(angle):.1f} deg"
    pass_dir = np.cos(angle) * e1 + np.sin(angle) * e2
    index_dir = np.cross(nbar, pass_dir)
    proj = v @ index_dir
    altitude = float(proj.max() - proj.min())
    areas = np.asarray(surface.vertex_areas, float)
    kdA = np.asarray(surface.gaussian_curvature, float) * areas
    total_k = float(kdA.sum())
    if position is not None:
        offset = float(proj.min() + float(position) * altitude)
        pos_rule = f"position: user fraction {float(position):.3f} of the altitude"
    elif abs(total_k) > TOTAL_K_NEGLIGIBLE_RAD:
        offset = divider_offset(proj, kdA)
        pos_rule = f"position: gaussian-curvature divider (integral K dA = {total_k:.4f} rad)"
    else:
        offset = divider_offset(proj, areas)
        pos_rule = f"position: area median (integral K dA = {total_k:.1e} rad is negligible)"
    # keep the plane off the exact extremes so the section is not empty
    margin = 0.5 * geom.edge_length_m
    offset = float(np.clip(offset, proj.min() + margin, proj.max() - margin))
    secs = plane_sections(geom, offset * index_dir, index_dir)
    if not secs:
        raise PlanError("the start-curve plane misses the surface; give a position in (0, 1)")
    sec = secs[0]
    pts, nrm = sec.points, sec.normals
    if np.dot(pts[-1] - pts[0], pass_dir) < 0:
        pts, nrm = pts[::-1], nrm[::-1]
    pts, nrm, _ = resample(pts, nrm, spacing_m)
    return StartCurve(points=pts, normals=nrm, plane_normal=index_dir, plane_offset_m=offset,
                      pass_dir=pass_dir, average_normal=nbar, angle_rad=angle,
                      altitude_m=altitude, total_k_rad=total_k,
                      rule=f"{orient_rule}; {pos_rule}")
