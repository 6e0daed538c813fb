"""Geodesic offsets by the heat method, for meshes where section-plane walking breaks.

`paintcell.coverage.offset.walk` offsets a pass by walking along plane sections (indexing
curves). On a
coarse or creased real mesh, neighbouring indexing curves cross, the offset reverses direction and
the planner refuses it as self-intersecting. An offset defined as a level set of the geodesic
distance from the pass cannot self-intersect (a distance function's level set has corners where
wavefronts meet, never a swallowtail), so the planner falls back to it there.

Distance: the heat method (Crane, Weischedel & Wardetzky 2013) as potpourri3d implements it
(`MeshHeatMethodDistanceSolver`, intrinsic Delaunay, factored once per surface), from the mesh
vertices nearest to the pass densely resampled; signed by the side of the pass (+ to the right,
along T × n, as `walk` measures). Level sets are extracted edge by edge with the section code
of `paintcell.coverage.offset`, so they come back as ordered polylines with interpolated
normals.
"""

from __future__ import annotations

import numpy as np
import potpourri3d as pp3d
from scipy.spatial import cKDTree

from paintcell.coverage.offset_polyline import unit
from paintcell.coverage.offset_sections import (
    SurfaceGeometry,
    dedupe_points,
    order_components,
    section_crossings,
)


class HeatGeodesics:
    """Heat-method geodesic distances on one surface mesh (factorization reused per query)."""

    def __init__(self, geom: SurfaceGeometry) -> None:
        self.geom = geom
        self.solver = pp3d.MeshHeatMethodDistanceSolver(np.asarray(geom.vertices, float),
                                                        np.asarray(geom.faces, np.int64))
        self.tree = cKDTree(geom.vertices)

    def signed_distance(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """(N,) geodesic distance [m] of every vertex from the polyline `points` (K, 3) on the
        surface, > 0 on its right (the side of T × n, n the `normals` (K, 3))."""
        pts = _dense(points, 0.5 * self.geom.edge_length_m)
        _, src = self.tree.query(pts)
        d = self.solver.compute_distance_multisource(np.unique(src).tolist())
        t = np.gradient(points, axis=0)
        side = unit(np.cross(unit(t), normals))
        _, near = cKDTree(points).query(self.geom.vertices)
        sgn = np.sign(np.einsum("ij,ij->i", self.geom.vertices - points[near], side[near]))
        return np.where(sgn == 0, 1.0, sgn) * np.asarray(d, float)

    def offset(self, points: np.ndarray, normals: np.ndarray, distance_m: float
               ) -> tuple[np.ndarray, np.ndarray]:
        """The level set at signed geodesic `distance_m` [m] from the pass (K, 3): its longest
        component as ordered points (M, 3) and unit normals (M, 3), running the same way as the
        pass (M = 0 when the level set misses the surface)."""
        phi = self.signed_distance(points, normals) - distance_m
        cross, pts, nrm = section_crossings(self.geom, phi)
        if len(cross) < 2:
            return np.zeros((0, 3)), np.zeros((0, 3))
        comps = []
        for order, _closed in order_components(self.geom, phi, cross):
            p, n = despike(*dedupe_points(pts[order], nrm[order]))
            if len(p) >= 2:
                comps.append((float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()), p, n))
        if not comps:
            return np.zeros((0, 3)), np.zeros((0, 3))
        _, p, n = max(comps, key=lambda c: c[0])
        # same direction as the pass: its ends' order along the pass's own chord
        chord = points[-1] - points[0]
        if float((p[-1] - p[0]) @ chord) < 0:
            p, n = p[::-1], n[::-1]
        return p, n


def despike(points: np.ndarray, normals: np.ndarray, max_turn_rad: float = 2.0 * np.pi / 3.0
            ) -> tuple[np.ndarray, np.ndarray]:
    """The polyline `points` (M, 3) without its spikes: interior vertices where it turns back by
    more than `max_turn_rad` [rad] are dropped, round after round, until none is left (a spike
    that goes out and retraces itself collapses from its apex inwards); `normals` (M, 3) follow.
    A level set extracted edge by edge on a coarse, creased mesh can run out along a dangling
    branch and back; a pass along it would make the bell reverse on the spot (an unbounded turn
    the TCP cannot follow). Corners below the bound (wavefronts meeting) are kept."""
    p, n = np.asarray(points, float), np.asarray(normals, float)
    cos_max = np.cos(max_turn_rad)
    while len(p) >= 3:
        d = np.diff(p, axis=0)
        length = np.linalg.norm(d, axis=1)
        dup = np.concatenate([[False], length <= 1e-12])      # a spike folded onto itself
        if dup.any():
            p, n = p[~dup], n[~dup]
            continue
        d = d / length[:, None]
        c = np.einsum("ij,ij->i", d[1:], d[:-1])            # cos of the turn at vertex i + 1
        apex = np.flatnonzero(c < cos_max) + 1
        if not len(apex):
            break
        # one round drops non-adjacent apices only (two neighbours judged on the same segment)
        keep_apex = apex[np.concatenate([[True], np.diff(apex) > 1])]
        mask = np.ones(len(p), bool)
        mask[keep_apex] = False
        p, n = p[mask], n[mask]
    return p, n


def _dense(points: np.ndarray, spacing_m: float) -> np.ndarray:
    """The polyline resampled at ≤ `spacing_m` [m] (its vertices kept)."""
    seg = np.diff(points, axis=0)
    n = np.maximum(1, np.ceil(np.linalg.norm(seg, axis=1) / max(spacing_m, 1e-9))).astype(int)
    base = np.repeat(np.arange(len(seg)), n)
    first = np.repeat(np.cumsum(n) - n, n)
    frac = (np.arange(int(n.sum())) - first) / np.repeat(n, n)     # per-segment fractions
    return np.vstack([points[base] + frac[:, None] * seg[base], points[-1:]])
