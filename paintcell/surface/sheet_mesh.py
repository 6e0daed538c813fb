"""Tessellate a sheet-metal panel given as a plane domain and a map onto 3-D.

A panel is a region of the (u, w) plane [mm] — a shapely polygon with holes, or several
polygons for a part delivered in pieces — and a vectorised map `(u, w) → (x, y, z)` [mm]. The
region is meshed as a CAD exporter would: a jittered grid of interior points plus points along
every boundary at a finer step, a Delaunay triangulation (scipy) of both, and only the triangles
whose centroid lies inside the region kept, so openings and narrow members keep their outline.
Each polygon is meshed on its own, so separate pieces are separate connected components.

`thin_solid` closes a sheet into a thin solid (outer skin, inner skin, rim), the way a part is
exported from a solid modeller.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from scipy.spatial import Delaunay

__all__ = ["Sheet", "boundary_edges", "tessellate", "thin_solid"]

@dataclass(frozen=True, eq=False)
class Sheet:
    """A tessellated panel: plane coordinates `uv` (N, 2) [mm], `faces` (F, 3), and `piece`
    (F,): the index of the domain polygon each face belongs to."""

    uv: np.ndarray
    faces: np.ndarray
    piece: np.ndarray


def _polygons(domain: shapely.Geometry) -> list[shapely.Polygon]:
    if isinstance(domain, shapely.Polygon):
        return [domain]
    return [g for g in getattr(domain, "geoms", []) if isinstance(g, shapely.Polygon)]


def _ring_points(poly: shapely.Polygon, step: float) -> np.ndarray:
    rings = [poly.exterior, *poly.interiors]
    pts = [np.asarray(shapely.segmentize(r, step).coords)[:-1] for r in rings]
    return np.concatenate(pts)


def tessellate(domain: shapely.Geometry, step_mm: float, boundary_step_mm: float,
               rng: np.random.Generator) -> Sheet:
    """Triangulate each polygon of `domain` [mm]: interior points on a grid of `step_mm` jittered
    by up to a quarter step (seeded by `rng`), boundary points every `boundary_step_mm`; faces
    wound counter-clockwise in (u, w)."""
    uvs, faces, piece = [], [], []
    n = 0
    for k, poly in enumerate(_polygons(domain)):
        minx, miny, maxx, maxy = poly.bounds
        gu = np.arange(minx + step_mm / 2, maxx, step_mm)
        gw = np.arange(miny + step_mm / 2, maxy, step_mm)
        U, W = np.meshgrid(gu, gw, indexing="ij")
        grid = np.stack([U.ravel(), W.ravel()], 1)
        grid = grid + rng.uniform(-0.25, 0.25, grid.shape) * step_mm
        inside = shapely.contains_xy(poly, grid[:, 0], grid[:, 1])
        grid = grid[inside]
        # Clear a band along the boundary, so no interior point sits on top of a boundary point.
        d = shapely.distance(poly.boundary, shapely.points(grid))
        grid = grid[d > 0.45 * boundary_step_mm]
        pts = np.concatenate([_ring_points(poly, boundary_step_mm), grid])
        tri = Delaunay(pts).simplices
        c = pts[tri].mean(axis=1)
        tri = tri[shapely.contains_xy(poly, c[:, 0], c[:, 1])]
        e1, e2 = pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]]
        cross = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        tri = np.where((cross < 0)[:, None], tri[:, ::-1], tri)[np.abs(cross) > 1e-9]
        uvs.append(pts)
        faces.append(tri + n)
        piece.append(np.full(len(tri), k))
        n += len(pts)
    return Sheet(np.concatenate(uvs), np.concatenate(faces).astype(np.int64),
                 np.concatenate(piece))


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """(E, 2) directed edges used by one face only (the sheet's outline and openings)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[cnt[inv.ravel()] == 1]


def thin_solid(points: np.ndarray, faces: np.ndarray, normals: np.ndarray,
               thickness_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Close a sheet (points [mm], faces wound with `normals` pointing out of the painted side)
    into a solid of `thickness_mm`: the inner skin is the sheet moved `thickness_mm` against its
    vertex normals and wound the other way, the rim joins the two outlines. Returns points,
    faces and a (F,) label: 0 outer skin, 1 inner skin, 2 rim."""
    n = len(points)
    inner = points - thickness_mm * normals
    be = boundary_edges(faces)
    a, b = be[:, 0], be[:, 1]
    # Outer edge a→b runs with the outer faces; the rim quad a, b, b', a' faces outward.
    rim = np.concatenate([np.stack([b, a, a + n], 1), np.stack([b, a + n, b + n], 1)])
    all_faces = np.concatenate([faces, faces[:, ::-1] + n, rim])
    label = np.concatenate([np.zeros(len(faces), int), np.ones(len(faces), int),
                            np.full(len(rim), 2)])
    return np.concatenate([points, inner]), all_faces, label
