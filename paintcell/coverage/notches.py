"""Notches: close a deep bay of the outline, plan across it as across an opening.

A fender's wheel arch, a U-shaped bracket, a door skin cut down for its mirror: the outline bays
deep into the part. Algorithm 1's offsets sweep across such a bay; where the surface splits into
two tongues on either side of it, the sweep follows one of them and the other is left to its
neighbours' overspray (a generated fender arch: one leg with a double film, the other with a
tenth of it, σ/μ 26 %). A painter flies straight across the bay and keeps the gun on only where
the paint lands on the part, as over a window. So, with the part's outline seen in its best-fit
plane:

- `find_notches`: each stretch of the outer boundary between two consecutive corners of its
  convex hull whose farthest vertex lies at least `min_depth_m` in from the hull's edge (the
  bay's mouth), and at least `NOTCH_MIN_ASPECT` of the mouth's width, is a `Notch`: that chain
  of boundary vertices, its mouth and depth;
- `closed_surface`: the surface with every notch closed by a fan of triangles from the bay's
  centroid over the chain and points spaced along the mouth; the planner plans on it, the film
  is still judged on the real mesh;
- `notch_samples`: points, normals and areas over the fill, with which
  `paintcell.coverage.openings.brush_off_openings` switches the gun off where most of its paint
  would land in the bay.

A bay whose fan would fold over itself in the plane (a bay not star-shaped from its centroid),
or whose rim's normals stand far from the fill's (`MAX_RIM_TILT_RAD`: a bay of the projection
of a part that wraps, not of its surface), is left open.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from paintcell.coverage.openings import boundary_loops, lattice_samples
from paintcell.surface.surface_data import Surface, surface_from_triangles

#: a bay is closed when it reaches this fraction of the spray footprint radius in from its mouth
#: (the default bell: 0.115 m; a scalloped or wavy edge, tens of millimetres, stays as it is).
NOTCH_DEPTH_FRACTION = 0.25
#: a bay is closed only when the part's normals along its rim lie within this of the fill's
#: normal (median) [rad]: a bay of the outline seen in the best-fit plane of a part that wraps
#: (a cowling whose normals turn ±70°) is the projection's, not the surface's (57° there; a
#: fender's wheel arch: 16°).
MAX_RIM_TILT_RAD = float(np.radians(30.0))
#: … and only when it is at least this fraction of its mouth's width deep. A shallower bay is an
#: edge that curves in (a hood's rear edge: 1.39 m across, 0.18 m deep, its rim turning 71°; a
#: circular arc this shallow turns at most 2·2·atan(2 · 0.25) = 106°): Algorithm 1's offsets
#: follow it, while passes flown straight across its mouth with the gun off over the fill leave
#: the curved edge between them short (σ/μ 6.4 → 10.2 % there). A wheel arch is about half as
#: deep as its mouth is wide, a slot or a U-cut deeper.
NOTCH_MIN_ASPECT = 0.25


@dataclass(frozen=True, eq=False)
class Notch:
    """A bay of the outer boundary: chain (L,) boundary vertex indices from one mouth corner to
    the other, in the boundary's order; mouth (C, 3) points strictly between the corners along
    the straight mouth [m]; centroid (3,) [m]; mouth_m, depth_m [m]; area_m2 [m²] of the fill."""

    chain: np.ndarray
    mouth: np.ndarray
    centroid: np.ndarray
    mouth_m: float
    depth_m: float
    area_m2: float


def _plane_frame(vertices: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid (3,) and two in-plane axes (2, 3) of the best-fit plane, its normal on the
    painted side."""
    c = vertices.mean(axis=0)
    _, _, wt = np.linalg.svd(vertices - c, full_matrices=False)
    n = wt[2] if wt[2] @ normals.mean(axis=0) >= 0 else -wt[2]
    u = wt[0]
    return c, np.stack([u, np.cross(n, u)])


def _fan(poly: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Signed doubled areas (P,) of the fan triangles (poly[i], poly[i+1], centre) in 2-D."""
    a, b = poly - centre, np.roll(poly, -1, axis=0) - centre
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def find_notches(surface: Surface, min_depth_m: float) -> list[Notch]:
    """The bays of the outer boundary (the longest loop) at least `min_depth_m` [m] deep and
    `NOTCH_MIN_ASPECT` of their mouth, seen in the surface's best-fit plane (module
    docstring)."""
    loops = boundary_loops(surface.faces, len(surface.vertices))
    if not loops:
        return []
    V = surface.vertices

    def perimeter(lp: np.ndarray) -> float:
        return float(np.linalg.norm(V[np.roll(lp, -1)] - V[lp], axis=1).sum())

    loop = max(loops, key=perimeter)
    if len(loop) < 4:
        return []
    c, axes = _plane_frame(V, surface.normals)
    xy = (V[loop] - c) @ axes.T
    try:
        hull = np.sort(ConvexHull(xy).vertices)        # positions along the loop
    except QhullError:
        return []
    spacing = float(np.median(np.linalg.norm(np.diff(V[loop], axis=0), axis=1)))
    out = []
    for k in range(len(hull)):                          # the hull's corners, a few dozen
        i, j = int(hull[k]), int(hull[(k + 1) % len(hull)])
        chain = loop[i:j + 1] if j > i else np.concatenate([loop[i:], loop[:j + 1]])
        if len(chain) < 3:
            continue
        chain = _trimmed(chain, (V[chain] - c) @ axes.T, spacing)
        p2 = (V[chain] - c) @ axes.T
        mouth2 = p2[-1] - p2[0]
        mouth_m = float(np.linalg.norm(mouth2))
        if len(chain) < 3 or mouth_m <= 0:
            continue
        side = np.array([-mouth2[1], mouth2[0]]) / mouth_m
        depth = float(np.abs((p2 - p2[0]) @ side).max())
        if depth < max(min_depth_m, NOTCH_MIN_ASPECT * mouth_m):
            continue
        a, b = V[chain[-1]], V[chain[0]]
        n_m = max(1, int(np.ceil(np.linalg.norm(b - a) / max(spacing, 1e-9))))
        t = np.arange(1, n_m)[:, None] / n_m
        mouth = a + t * (b - a)
        poly3 = np.vstack([V[chain], mouth])
        cen = poly3.mean(axis=0)
        fan = _fan((poly3 - c) @ axes.T, (cen - c) @ axes.T)
        if not (np.all(fan > 0) or np.all(fan < 0)):    # the fan would fold: left open
            continue
        cr = np.cross(poly3 - cen, np.roll(poly3, -1, axis=0) - cen)
        m = cr.sum(axis=0)
        m /= max(float(np.linalg.norm(m)), 1e-30)
        m *= 1.0 if m @ surface.normals[chain].sum(axis=0) >= 0 else -1.0
        tilt = np.arccos(np.clip(surface.normals[chain] @ m, -1.0, 1.0))
        if float(np.median(tilt)) > MAX_RIM_TILT_RAD:
            continue
        area = 0.5 * float(np.linalg.norm(cr, axis=1).sum())
        out.append(Notch(chain, mouth, cen, mouth_m, depth, area))
    return out


def _trimmed(chain: np.ndarray, p2: np.ndarray, tol_m: float) -> np.ndarray:
    """The chain without its end stretches that run along the mouth: steps more along the line
    between the chain's ends (the hull's edge) than across it, to points within `tol_m` [m] of
    that line, in the plane p2 (L, 2). A hull corner a little outside the bay's own corner (a
    slightly bulging edge beside it) would otherwise put a piece of that edge into the bay, and
    the mouth would run back over it. The line stays the hull's edge: judged against a line
    through the points trimmed so far, a bay side meshed in steps shorter than `tol_m` would be
    trimmed step by step down to its bottom."""
    d = p2[-1] - p2[0]
    u = d / max(float(np.linalg.norm(d)), 1e-12)
    n = np.array([-u[1], u[0]])
    near = np.abs((p2 - p2[0]) @ n) < tol_m
    step = np.diff(p2, axis=0)
    along = np.abs(step @ u) >= np.abs(step @ n)          # step k: from point k to point k + 1
    lo, hi = 0, len(chain) - 1
    while hi - lo >= 2 and near[lo + 1] and along[lo]:
        lo += 1
    while hi - lo >= 2 and near[hi - 1] and along[hi - 1]:
        hi -= 1
    return chain[lo:hi + 1]


def fill_triangles(surface: Surface, notches: list[Notch]) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (N + K, 3) (the surface's, then each notch's mouth points and centroid) and the
    fan faces (F', 3) closing the notches, wound like the surface (the chain's boundary edges
    run as its faces' edges do; the fill lies on their other side)."""
    V = [surface.vertices]
    n = len(surface.vertices)
    faces = []
    for o in notches:                                  # a notch or two per part
        mouth_ids = n + np.arange(len(o.mouth))
        cen = n + len(o.mouth)
        V += [o.mouth, o.centroid[None]]
        n = cen + 1
        ring = np.concatenate([o.chain, mouth_ids])       # the chain, then its mouth back
        faces.append(np.column_stack([np.roll(ring, -1), ring, np.full(len(ring), cen)]))
    F = np.concatenate(faces) if faces else np.zeros((0, 3), np.int64)
    return np.vstack(V), F.astype(np.int64)


def closed_surface(surface: Surface, notches: list[Notch]) -> Surface:
    """The surface with its notches closed by fans (same name; the first N vertices are the
    surface's own)."""
    if not notches:
        return surface
    V, F = fill_triangles(surface, notches)
    return surface_from_triangles(surface.name, V, np.vstack([surface.faces, F]))


def notch_samples(surface: Surface, notches: list[Notch]
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (P, 3), unit normals (P, 3) on the painted side and area weights (P,) [m²]
    spread over the notches' fill triangles (`paintcell.coverage.openings.lattice_samples`)."""
    return lattice_samples(*fill_triangles(surface, notches))
