"""Plan on a smooth approximation, paint the real part (the paper's Fig. 8c practice).

A bell's spray pattern is ~0.3 m across: it cannot resolve a crease or a character line a few
millimetres wide, and a tool axis that follows the raw normal there whips the wrist (100–400 °/m
on real panels), so the time law slows the pass and the film comes out thick. The planner takes
its pass geometry, tool axis and standoff from a copy of the surface smoothed at the spray's
scale; the deposition model and the film metrics keep the real mesh.

- `smoothed_surface`: implicit heat-flow smoothing of the vertex positions, (M + t L) X = M X0 with
  L the cotangent Laplacian, M the lumped vertex areas and t = scale²/2 (a Gaussian of standard
  deviation `scale_m` on a flat sheet); boundary vertices are held, so the outline (and the area
  to paint) stays and a plane is unchanged.
- `smoothing_scale_m`: the default scale tied to the footprint (a quarter of its radius), and the
  rule that applies it only to surfaces with features finer than that scale (max |κ|·scale > 1):
  the smooth library parts are planned as before.
- `smooth_along`: on a smoothed surface, the pass's axes are also low-passed along the pass at
  half the smoothing scale (facet-to-facet wiggles of a scan's normals, magnified by the standoff,
  are lateral TCP jerks).
- `limit_turn_rate`: the bound on how fast the bell axis may turn along a pass [rad/m]: the
  axis field is diffused along the pass until its turning rate is under the bound.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from paintcell.core.errors import AxisTurnError, PlanError
from paintcell.surface.curvature import boundary_vertex_mask, corner_geometry
from paintcell.surface.surface_data import Surface, surface_from_triangles

#: the smoothing scale is this fraction of the spray footprint radius (a 0.33 m bell: 82 mm).
FOOTPRINT_FRACTION = 0.25


def cotan_laplacian(vertices: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """(N, N) positive semi-definite cotangent stiffness matrix L (L @ x = −2 H n · area)."""
    _, cot, _, _ = corner_geometry(vertices, faces)
    cot = np.nan_to_num(cot, nan=0.0, posinf=0.0, neginf=0.0)
    i = faces[:, [1, 2, 0]].ravel()         # edge (i+1, i+2) is opposite corner i
    j = faces[:, [2, 0, 1]].ravel()
    w = 0.5 * cot.ravel()
    n = len(vertices)
    W = sp.coo_matrix((np.concatenate([w, w]), (np.concatenate([i, j]), np.concatenate([j, i]))),
                      shape=(n, n)).tocsr()
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()


def check_smoothing_setting(setting: object) -> None:
    """Raise PlanError unless `setting` is "auto", None or a finite length >= 0 [m]."""
    if setting is None or setting == "auto":
        return
    if isinstance(setting, bool) or not isinstance(setting, int | float) \
            or not np.isfinite(setting) or setting < 0:
        raise PlanError(f"PlannerSettings.smoothing_m = {setting!r}: use 'auto', None or a "
                        "length >= 0 [m]")


def smoothing_scale_m(surface: Surface, footprint_radius_m: float,
                      setting: float | str | None) -> float:
    """The smoothing scale [m] a planner setting asks for: "auto" (the default) is
    FOOTPRINT_FRACTION × the footprint radius when the surface has features finer than that
    (max |principal curvature| × scale > 1), else 0; a number is used as given; None or 0: off."""
    check_smoothing_setting(setting)
    if setting is None:
        return 0.0
    if isinstance(setting, str):
        scale = FOOTPRINT_FRACTION * footprint_radius_m
        kmax = float(np.max(np.abs(surface.principal_curvatures)))
        return scale if kmax * scale > 1.0 else 0.0
    return float(setting)


def smoothed_surface(surface: Surface, scale_m: float) -> Surface:
    """The surface smoothed at `scale_m` [m] (same faces and vertex order, same name); 0: as is.

    Implicit heat flow of the interior positions for time t = scale²/2 with the boundary held
    (the outline and the painted area stay; a feature that reaches the boundary keeps its shape
    there, and `limit_turn_rate` bounds the axis on the passes that cross it)."""
    if scale_m <= 0:
        return surface
    V0, F = surface.vertices, surface.faces
    L = cotan_laplacian(V0, F)
    area = np.maximum(surface.vertex_areas, 1e-16)
    t = 0.5 * scale_m**2
    b = boundary_vertex_mask(F, len(V0))
    inner = np.flatnonzero(~b)
    bnd = np.flatnonzero(b)
    # Boundary held (Dirichlet): the outline stays, and a plane is a fixed point (linear
    # functions are discrete-harmonic with cotangent weights).
    A = (sp.diags(area[inner]) + t * L[inner][:, inner]).tocsc()
    rhs = area[inner, None] * V0[inner] - t * (L[inner][:, bnd] @ V0[bnd])
    solve = spla.factorized(A)
    V = V0.copy()
    V[inner] = np.column_stack([solve(rhs[:, k]) for k in range(3)])
    smooth = surface_from_triangles(surface.name, V, F)
    return dataclasses.replace(smooth, uv=surface.uv, grid_shape=surface.grid_shape)


def smooth_along(points: np.ndarray, vectors: np.ndarray, sigma_m: float) -> np.ndarray:
    """Unit `vectors` (M, 3) low-passed along the polyline `points` (M, 3) by a Gaussian of
    `sigma_m` [m] of arc length (ends: the kernel renormalized over what exists). A pass's spray
    axes taken from a faceted (scanned) surface wiggle from facet to facet; the TCP, a standoff
    away, magnifies each wiggle into a lateral jerk the time law must slow for."""
    if sigma_m <= 0 or len(vectors) < 3:
        return np.array(vectors, float)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    w = np.exp(-0.5 * ((s[:, None] - s[None, :]) / sigma_m) ** 2)      # (M, M), M ~ 100
    v = w @ vectors
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def turn_rate_rad_m(points: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """(M−1,) turning rate of unit `axes` (M, 3) between consecutive `points` (M, 3) [rad/m]."""
    ds = np.linalg.norm(np.diff(points, axis=0), axis=1)
    c = np.clip(np.sum(axes[1:] * axes[:-1], axis=1), -1.0, 1.0)
    return np.arccos(c) / np.maximum(ds, 1e-12)


def limit_turn_rate(foot: np.ndarray, axes: np.ndarray, max_rate_rad_m: float,
                    standoff_m: float = 0.0, max_rounds: int = 5000) -> np.ndarray:
    """Unit spray axes (M, 3) along a pass whose turning rate per metre of TCP travel stays
    ≤ `max_rate_rad_m` [rad/m]; the TCP is at `foot − standoff_m · axis` (foot (M, 3) [m]).
    Rounds of a [¼, ½, ¼] diffusion (ends held by reflection) of the axes that still turn too
    fast, until none does; axes already within the bound are returned unchanged. Raises
    AxisTurnError (a PlanError) if the bound cannot be met (e.g. a U-turn)."""
    a = np.array(axes, float)
    if len(a) < 3 or not np.isfinite(max_rate_rad_m):
        return a
    idx = np.arange(len(a))
    for r in range(max_rounds):        # each round is vectorized over the pass
        rate = turn_rate_rad_m(foot - standoff_m * a, a)
        if rate.max() <= max_rate_rad_m:
            return a
        # the axes within a window of the fast segments, the window widening as rounds go on
        # (a concave fold tighter than the standoff needs the turn spread over ~θ·(h + 1/bound))
        hot = np.flatnonzero(rate > max_rate_rad_m)
        reach = 2 + r // 4
        bad = _near(idx, hot) <= reach if len(hot) < 512 else np.ones(len(a), bool)
        pad = np.concatenate([a[1:2], a, a[-2:-1]])
        blur = 0.25 * pad[:-2] + 0.5 * pad[1:-1] + 0.25 * pad[2:]
        a[bad] = blur[bad] / np.linalg.norm(blur[bad], axis=1, keepdims=True)
    worst = turn_rate_rad_m(foot - standoff_m * a, a).max()
    raise AxisTurnError(f"the bell axis turns {worst:.2f} rad/m along a pass, above "
                    f"max_axis_turn_rad_m = {max_rate_rad_m:g}; raise the bound or smooth the "
                    "surface more (smoothing_m)")


def _near(idx: np.ndarray, hot: np.ndarray) -> np.ndarray:
    """(M,) distance of each index `idx` (0 … M−1) to the nearest of the sorted indices `hot`
    (non-empty), by a binary search (the limiter's rounds asked an (M, H) table for it)."""
    k = np.searchsorted(hot, idx)
    left = hot[np.maximum(k - 1, 0)]
    right = hot[np.minimum(k, len(hot) - 1)]
    return np.minimum(np.abs(idx - left), np.abs(right - idx))
