"""Plane sections of a triangle mesh: its connectivity precomputed once (`SurfaceGeometry`), the
crossings of a plane with the mesh edges (points [m] with normals interpolated linearly from the
vertex normals, renormalized), and their ordering into polylines, one per connected component
(`plane_sections`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, depth_first_order

from paintcell.coverage.offset_polyline import unit

#: Points of a section closer than this are merged [m] (a plane through a vertex gives repeats).
_MERGE_M = 1e-9
#: Signed vertex distances below this count as exactly on the plane [m] (float64 round-off of
#: differently associated dot products of ~1 m coordinates is ~1e-16).
_ZERO_D_M = 1e-12


@dataclass(frozen=True, eq=False)
class SurfaceGeometry:
    """Mesh connectivity precomputed once for repeated plane sections.

    vertices: (N, 3) [m]; normals: (N, 3) unit, painted side; faces: (F, 3) int;
    edges: (E, 2) unique vertex pairs; face_edges: (F, 3) index of each face's edges in `edges`;
    edge_faces: (E, 2) the faces on each edge (-1 where the edge is on the boundary);
    edge_length_m: median mesh edge length [m] (the mesh resolution);
    boundary_dir: (E, 3) unit direction of the boundary at each boundary edge (the chord from
        the previous to the next boundary vertex, so a staircase boundary reads as its trend),
        zero on interior edges; None: not computed (no boundary test).
    """

    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    edges: np.ndarray
    face_edges: np.ndarray
    edge_faces: np.ndarray
    edge_length_m: float
    boundary_dir: np.ndarray | None = None

    @classmethod
    def from_surface(cls, surface: Any) -> SurfaceGeometry:
        """Build from a `paintcell.surface.analytic.Surface` (uses its vertices, normals,
        faces, mesh)."""
        mesh = surface.mesh
        edges = np.asarray(mesh.edges_unique, dtype=np.int64)
        face_edges = np.asarray(mesh.faces_unique_edges, dtype=np.int64)
        v = np.asarray(surface.vertices, float)
        lengths = np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1)
        # invert face -> edge: each edge gets its (at most two, manifold) faces
        e_flat = face_edges.reshape(-1)
        f_flat = np.repeat(np.arange(len(face_edges)), 3)
        order = np.argsort(e_flat, kind="stable")
        e_sorted, f_sorted = e_flat[order], f_flat[order]
        first = np.ones(len(e_sorted), bool)
        first[1:] = e_sorted[1:] != e_sorted[:-1]
        edge_faces = np.full((len(edges), 2), -1, dtype=np.int64)
        edge_faces[e_sorted[first], 0] = f_sorted[first]
        edge_faces[e_sorted[~first], 1] = f_sorted[~first]
        faces = np.asarray(surface.faces, dtype=np.int64)
        normals = np.asarray(surface.normals, float)
        return cls(v, normals, faces, edges, face_edges, edge_faces,
                   float(np.median(lengths)), _boundary_directions(v, faces, edges, edge_faces))


def _boundary_directions(v: np.ndarray, faces: np.ndarray, edges: np.ndarray,
                         edge_faces: np.ndarray) -> np.ndarray:
    """(E, 3) unit boundary direction per boundary edge (zero elsewhere): the chord from the
    boundary vertex before the edge to the one after it, following the faces' winding."""
    out = np.zeros((len(edges), 3))
    bnd = np.flatnonzero(edge_faces[:, 1] < 0)
    if len(bnd) == 0:
        return out
    n = len(v)
    # the boundary half-edges, oriented as their face winds them: loops of consistent direction
    he = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key_he = np.minimum(he[:, 0], he[:, 1]) * n + np.maximum(he[:, 0], he[:, 1])
    key_b = edges[bnd, 0] * n + edges[bnd, 1]       # edges_unique rows are sorted pairs
    order = np.argsort(key_b)
    pos = np.searchsorted(key_b[order], key_he)
    pos = np.clip(pos, 0, len(bnd) - 1)
    hit = key_b[order][pos] == key_he
    a, b = he[hit, 0], he[hit, 1]
    eid = bnd[order][pos[hit]]
    nxt = np.arange(n)
    prv = np.arange(n)
    nxt[a] = b                                      # a manifold boundary vertex: one each way
    prv[b] = a
    chord = v[nxt[b]] - v[prv[a]]
    out[eid] = unit(chord)
    return out


@dataclass(frozen=True, eq=False)
class Section:
    """One connected, ordered component of a plane–mesh section.

    points: (K, 3) ordered points on mesh edges [m]; normals: (K, 3) unit surface normals;
    closed: True when the component is a loop (last point connects to the first).
    """

    points: np.ndarray
    normals: np.ndarray
    closed: bool


def signed_distances(geom: SurfaceGeometry, origin: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(N,) signed distances [m] of the surface vertices from the plane through `origin` with
    unit `normal`."""
    return (geom.vertices - origin) @ normal


def section_crossings(geom: SurfaceGeometry, d: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Crossing edges of the section with signed vertex distances d (N,).

    Returns (edge ids (C,), points (C, 3), normals (C, 3)). Zero distances count as positive, so
    a plane through a vertex crosses each edge at most once.
    """
    d = np.where(np.abs(d) < _ZERO_D_M, 0.0, d)      # round-off of a plane through vertices
    pos = d >= 0
    e = geom.edges
    cross = np.flatnonzero(pos[e[:, 0]] != pos[e[:, 1]])
    a, b = e[cross, 0], e[cross, 1]
    t = (d[a] / (d[a] - d[b]))[:, None]
    pts = geom.vertices[a] + t * (geom.vertices[b] - geom.vertices[a])
    nrm = unit(geom.normals[a] + t * (geom.normals[b] - geom.normals[a]))
    return cross, pts, nrm


def order_components(geom: SurfaceGeometry, d: np.ndarray, cross: np.ndarray,
                     wanted: np.ndarray | None = None) -> list[tuple[np.ndarray, bool]]:
    """Order crossing edges into polylines: each crossed face links its two crossed edges.

    Returns (indices into `cross` in order, closed) per component (only the components holding
    the `wanted` crossing indices when given). The crossing graph is built straight in CSR form
    (rows sorted, duplicates merged: the graph `coo + coo.T` gives) and, for `wanted`, only their
    components are searched (a depth-first search from each): an indexing curve wants one
    component of thousands of crossings, and the sparse-matrix arithmetic was 20 % of a plan.
    The graph holds both directions of every link, so the directed search (which skips the
    transpose an undirected one builds on every call) visits in the same order.
    """
    graph = _crossing_graph(geom, cross)
    degree = np.diff(graph.indptr)
    if wanted is None:
        n_comp, labels = connected_components(graph, directed=False)
        comps = [np.flatnonzero(labels == c) for c in range(n_comp)]
    else:
        comps, seen = [], np.zeros(len(cross), bool)
        for w in np.asarray(wanted, dtype=np.int64):
            if not seen[w]:
                members = np.sort(depth_first_order(graph, int(w), directed=True,
                                                    return_predecessors=False))
                seen[members] = True
                comps.append(members)
        comps.sort(key=lambda m: int(m[0]))       # the order of the components' labels
    out = []
    for members in comps:
        ends = members[degree[members] <= 1]
        start = int(ends[0]) if len(ends) else int(members[0])
        order = depth_first_order(graph, start, directed=True, return_predecessors=False)
        closed = len(ends) == 0 and len(members) > 2
        out.append((np.asarray(order), closed))
    return out


def _crossing_graph(geom: SurfaceGeometry, cross: np.ndarray) -> sp.csr_matrix:
    """(C, C) symmetric adjacency of the crossings (two crossed edges of one face are linked),
    CSR with sorted, unique column indices per row."""
    n_cross = len(cross)
    node = np.full(len(geom.edges), -1, dtype=np.int64)
    node[cross] = np.arange(n_cross)
    faces = np.unique(geom.edge_faces[cross])       # only faces touching a crossed edge
    faces = faces[faces >= 0]
    fn = node[geom.face_edges[faces]]               # (F', 3) crossing-node id or -1
    hit = fn >= 0
    two = hit.sum(axis=1) == 2
    pairs = fn[two][hit[two]].reshape(-1, 2)
    rows = np.concatenate([pairs[:, 0], pairs[:, 1]])
    cols = np.concatenate([pairs[:, 1], pairs[:, 0]])
    key = np.unique(rows * n_cross + cols)          # sorted by row, then column; merged
    rows, cols = key // n_cross, key % n_cross
    indptr = np.zeros(n_cross + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n_cross), out=indptr[1:])
    return sp.csr_matrix((np.ones(len(cols)), cols, indptr), shape=(n_cross, n_cross))


def dedupe_points(points: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A polyline's points (K, 3) and normals (K, 3) without consecutive points closer than
    `_MERGE_M`."""
    if len(points) < 2:
        return points, normals
    keep = np.ones(len(points), bool)
    keep[1:] = np.linalg.norm(np.diff(points, axis=0), axis=1) > _MERGE_M
    return points[keep], normals[keep]


def plane_sections(geom: SurfaceGeometry, origin: npt.ArrayLike,
                   plane_normal: npt.ArrayLike) -> list[Section]:
    """All components of the section of the mesh by a plane, each an ordered polyline.

    origin: (3,) a point of the plane [m]; plane_normal: (3,) its normal (any length).
    Returns the components (possibly none), longest first.
    """
    o = np.asarray(origin, float)
    nrm = unit(np.asarray(plane_normal, float))
    d = signed_distances(geom, o, nrm)
    cross, pts, nn = section_crossings(geom, d)
    if len(cross) < 2:
        return []
    secs = []
    for order, closed in order_components(geom, d, cross):
        p, n = dedupe_points(pts[order], nn[order])
        if len(p) >= 2:
            secs.append(Section(p, n, closed))
    secs.sort(key=lambda s: -float(np.linalg.norm(np.diff(s.points, axis=0), axis=1).sum()))
    return secs
