"""Stitching: pieces of a part that lie a gap apart planned as one surface.

A door delivered in pieces (the lower panel, and its window frame's members a few centimetres
from it) is one part to a painter: the passes run on across the gaps, and the window the pieces
enclose is an opening, flown straight across with the gun off. The planner's offsets, though,
walk one connected mesh; a piece apart from the others gets only their overspray, and the window
between them is no hole of any piece. So:

- `stitched_surface`: the surface with a strip of triangles across every stretch of boundary
  where two of its connected components come within `gap_m` of each other. Each strip zips the
  boundary stretch of one component to the facing stretch of the other (no new vertices: the
  first N vertices, and every face, are the surface's own), wound like the surface, so that the
  stitched surface is one piece whose boundary loops are its outline and the openings the pieces
  enclose. The planner plans on it; the film is still judged on the real mesh.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from paintcell.coverage.offset_polyline import unit
from paintcell.coverage.openings import boundary_loops, file_pieces, vertex_pieces
from paintcell.surface.surface_data import Surface, surface_from_triangles

#: pieces whose boundaries come within this fraction of the spray footprint radius of each other
#: are planned as one surface (the default bell: 46 mm, beyond the part import's 40 mm for
#: pieces painted as one part; a gap this narrow gets the film of both sides' passes).
STITCH_GAP_FRACTION = 0.1
#: A boundary vertex is bridged only to a point of the other piece at least this far from its
#: own boundary's tangent [deg] (across the gap, not along the edge).
ACROSS_DEG = 45.0
#: Points sampled along each boundary edge for the nearest point of another piece.
_EDGE_SAMPLES = 8


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Positions of the maximal runs of True in a cyclic mask (L,), each in loop order."""
    n = len(mask)
    if mask.all():
        return [np.arange(n)]
    start = int(np.flatnonzero(~mask)[0])                  # begin after a False: no run wraps
    order = (start + np.arange(n)) % n
    m = mask[order]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], m.astype(np.int8), [0]])))
    return [order[s:e] for s, e in zip(edges[::2], edges[1::2], strict=True)]


def _zip(p: np.ndarray, q: np.ndarray, V: np.ndarray) -> list[tuple[int, int, int]]:
    """Triangles of the strip between two facing chains of vertex ids, both in the direction
    the first runs along its own boundary: p's edges are boundary half-edges p[i] → p[i+1] of
    its piece, q's run q[j + 1] → q[j] in its own; each step adds the triangle over the next
    edge of the chain whose new diagonal is shorter."""
    tri: list[tuple[int, int, int]] = []
    i = j = 0
    while i < len(p) - 1 or j < len(q) - 1:       # one step per boundary edge of the strip
        take_p = j == len(q) - 1 or (i < len(p) - 1 and np.linalg.norm(V[p[i + 1]] - V[q[j]])
                                      <= np.linalg.norm(V[q[j + 1]] - V[p[i]]))
        if take_p:
            tri.append((int(p[i + 1]), int(p[i]), int(q[j])))
            i += 1
        else:
            tri.append((int(q[j]), int(q[j + 1]), int(p[i])))
            j += 1
    return tri


def stitched_surface(surface: Surface, gap_m: float) -> Surface:
    """The surface with strips across the gaps between its connected components of different
    pieces of the part file (`paintcell.coverage.openings.file_pieces`: a patch of one region
    cut off from the rest of its piece by another region is left as it is) (module docstring);
    the surface itself when it is one piece or no two pieces come that close.

    A boundary vertex is bridged when the nearest point of another piece's boundary (its edges
    sampled at `_EDGE_SAMPLES` points each) lies within `gap_m` [m] and across from it: at
    least `ACROSS_DEG` from the vertex's own boundary tangent. Where a member's end meets a
    panel's edge, the panel's edge beside the member's corner is near the corner but runs
    toward it, not across to it; a strip there would be a sliver along the panel's edge, off
    the part, that the passes' sections follow (a 70° turn)."""
    V, F = surface.vertices, surface.faces
    comp = vertex_pieces(F, len(V))
    piece = file_pieces(surface)
    if piece[np.unique(F)].max(initial=0) == piece[np.unique(F)].min(initial=0):
        return surface
    loops = boundary_loops(F, len(V))
    if len(loops) < 2:
        return surface
    loop_of = np.full(len(V), -1)                  # boundary vertex → its loop, position
    pos_of = np.full(len(V), -1)
    for k, lp in enumerate(loops[::-1]):           # a loop per piece and opening; a pinch
        loop_of[lp] = len(loops) - 1 - k           # vertex keeps its first loop
        pos_of[lp] = np.arange(len(lp))
    a = np.concatenate(loops)                      # boundary edges a → b, sampled
    b = np.concatenate([np.roll(lp, -1) for lp in loops])
    t = (np.arange(_EDGE_SAMPLES) + 0.5) / _EDGE_SAMPLES
    pts = V[a][:, None] + t[None, :, None] * (V[b] - V[a])[:, None]
    end = np.where(t[None, :] < 0.5, a[:, None], b[:, None])        # the nearer end vertex
    cos_across = np.cos(np.radians(ACROSS_DEG))
    new: list[tuple[int, int, int]] = []
    for lp in loops:                               # each loop against the pieces after its own
        later = (comp[a] > comp[lp[0]]) & (piece[a] != piece[lp[0]])
        if not later.any():
            continue
        cand_p, cand_v = pts[later].reshape(-1, 3), end[later].ravel()
        d, nn = cKDTree(cand_p).query(V[lp])
        tan = unit(V[np.roll(lp, -1)] - V[np.roll(lp, 1)])
        to = unit(cand_p[nn] - V[lp])
        near = (d <= gap_m) & (np.abs(np.sum(tan * to, axis=1)) <= cos_across)
        for run in _runs(near):
            if len(run) < 2:
                continue
            p = lp[run]
            m0, m1 = cand_v[nn[run[0]]], cand_v[nn[run[-1]]]
            k0, j0, j1 = loop_of[m0], pos_of[m0], pos_of[m1]
            if loop_of[m1] != k0:
                continue
            other = loops[k0]
            n_o = len(other)
            back = (j0 - j1) % n_o                 # facing boundaries run opposite ways
            if back > 3 * len(run) + 4:
                continue
            q = other[(j0 - np.arange(back + 1)) % n_o]
            new += _zip(p, q, V)
    if not new:
        return surface
    T = np.asarray(new, np.int64)
    # wound like the surface: each strip triangle's normal on the side of its vertices' normals
    nrm = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    flip = np.einsum("ij,ij->i", nrm, surface.normals[T].sum(axis=1)) < 0
    T[flip] = T[flip][:, ::-1]
    area = 0.5 * np.linalg.norm(nrm, axis=1)
    T = T[area > 1e-12]
    return surface_from_triangles(surface.name, V, np.vstack([F, T]))
