"""Regions of a real part: the paintable skin, hems and flanges folded behind it, inner panels,
the back side; openings (windows, handle holes) as boundary loops of the skin.

The classification needs only the geometry and the painted direction d (part frame), so it works
on any part a paint shop sends, not on known shapes:
- a face whose normal has a component along the local painted direction (the mean orientation of
  the surface around it) is on the front; back-facing faces are grouped
  into connected regions, and a region whose mean width 2·area/boundary length is below
  `HEM_WIDTH_M` is a hem or flange (a strip folded round an edge), a wider one is the back side of
  a closed or double-sided shell;
- front faces turned more than 30° from it, in strips that reach the boundary or the back faces,
  are turned edges and lips (a hem's bend, a turned-down lip); inside the skin (a recess wall)
  they stay skin;
- a piece whose front faces are mostly hidden behind another piece seen along d (rays cast toward
  the painter) is an inner panel;
- the skin's boundary loops other than its outline are holes; an equivalent diameter
  (perimeter/π) at or above the scenario's `fill_holes_m` makes an opening.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import trimesh

from paintcell.surface.mesh_repair import boundary_loops, loop_size

__all__ = ["BACK", "EDGE", "HEM", "HEM_WIDTH_M", "INNER", "Opening", "PartRegions", "REGION_NAMES",
           "SKIN", "classify_faces", "find_openings"]

SKIN, HEM, INNER, BACK, EDGE = 0, 1, 2, 3, 4
REGION_NAMES = ("skin", "hem", "inner", "back", "edge")
#: A front face turned more than this from the local painted direction, in a strip that reaches
#: the part's boundary or its back-facing faces, is a turned edge or lip (the bend of a hem, a
#: turned-down lip), not skin a pass can follow [rad] (30°).
EDGE_TURN_RAD = np.pi / 6
#: A back-facing strip narrower than this (mean width) is a hem/flange, wider is a back side [m].
#: Hems and flanges of car panels are 5–25 mm wide; the back of a double-sided panel is its size.
HEM_WIDTH_M = 0.04
#: Voxel size of the local painted direction (a face is judged against the mean orientation of
#: the surface within ±1.5 voxels, i.e. a 0.15 m cube: wide against hems, narrow against the
#: bend of a fender wrapping round) [m].
LOCAL_VOXEL_M = 0.05
#: A connected patch of one label smaller than this is an island of classification noise (a
#: fragment of a bend, a face tilted by the tessellation) and takes its neighbours' label [m²]
#: (10 cm²: far below any hem strip, inner panel or skin a paint shop cares about).
ISLAND_M2 = 1e-3
#: Front faces sampled per piece for the inner-panel ray test [-].
_RAY_SAMPLES = 256


@dataclass(frozen=True)
class Opening:
    """An opening of the part (a window, a handle hole): its loop where the skin turns away from
    the painter, its spanned area and where it is (part frame)."""

    perimeter_m: float
    area_m2: float
    centre_m: tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class PartRegions:
    """Per-face region labels of a Surface, its openings, and what the film is judged on.

    face_labels: (F,) int8 in SKIN/HEM/INNER/BACK, one per Surface face.
    face_piece: (F,) int32 piece index of each face (pieces numbered by decreasing area).
    painted_direction: (3,) unit direction toward the painted side in the part frame.
    openings: boundary loops of the skin other than its outline.
    judged: region names the film metrics are judged on (default the skin).
    pieces: what the import painted and left out, one JSON-safe record each (piece, area_m2,
        painted, why, on_painted_side), a closed solid's dropped back skin among them
        (`paintcell.surface.part_import`).
    """

    face_labels: np.ndarray
    face_piece: np.ndarray
    painted_direction: np.ndarray
    openings: tuple[Opening, ...] = ()
    judged: tuple[str, ...] = ("skin",)
    info: dict[str, float] = field(default_factory=dict)
    pieces: tuple[dict[str, Any], ...] = ()

    def face_mask(self, names: tuple[str, ...] | None = None) -> np.ndarray:
        """(F,) True for faces in the named regions (default: `judged`)."""
        ids = [REGION_NAMES.index(n) for n in (names or self.judged)]
        return np.isin(self.face_labels, ids)

    def vertex_mask(self, faces: np.ndarray, names: tuple[str, ...] | None = None) -> np.ndarray:
        """(N,) True for vertices of a face in the named regions (default: `judged`)."""
        m = np.zeros(int(faces.max()) + 1, bool)
        m[faces[self.face_mask(names)].ravel()] = True
        return m

    def areas_m2(self, vertices: np.ndarray, faces: np.ndarray) -> dict[str, float]:
        """Area of each region [m²]."""
        a = face_areas(vertices, faces)
        return {n: float(a[self.face_labels == i].sum()) for i, n in enumerate(REGION_NAMES)}


def face_areas(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(F,) triangle areas [m²]."""
    return 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)


def _components(f: np.ndarray, mask: np.ndarray, n_vertices: int) -> list[np.ndarray]:
    """Edge-connected components of the faces in `mask` (arrays of face indices)."""
    idx = np.flatnonzero(mask)
    if len(idx) == 0:
        return []
    sub = trimesh.Trimesh(np.zeros((n_vertices, 3)), f[idx], process=False)
    groups = trimesh.graph.connected_components(sub.face_adjacency, nodes=np.arange(len(idx)),
                                                min_len=1)
    return [idx[np.sort(g)] for g in groups]


def _open_edge_length(v: np.ndarray, f: np.ndarray) -> float:
    e = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    u, c = np.unique(e, axis=0, return_counts=True)
    b = u[c == 1]
    return float(np.linalg.norm(v[b[:, 0]] - v[b[:, 1]], axis=1).sum())


def local_direction(v: np.ndarray, f: np.ndarray, d: np.ndarray,
                    voxel_m: float = LOCAL_VOXEL_M, closed: bool = False) -> np.ndarray:
    """(F, 3) unit painted direction at each face: the area-weighted mean of the face normals
    within the 3×3×3 voxels around it, each normal first turned to agree with the global `d`
    (so a hem's two layers add up instead of cancelling). closed: the faces are a closed
    solid's, wound outward; its outer skin alone sets the direction, each face weighted by
    n·d (the inner skin faces away, and the rim between the skins, edge-on to d, would tilt the
    direction by tens of degrees along a thin solid's edges)."""
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # length 2·area
    if closed:
        c = n @ d / np.maximum(np.linalg.norm(n, axis=1), 1e-300)
        n = n * np.clip(c, 0.0, None)[:, None]
    else:
        n = n * np.where(n @ d < 0, -1.0, 1.0)[:, None]
    c = v[f].mean(1)
    key3 = np.floor((c - c.min(0)) / voxel_m).astype(np.int64) + 1
    dims = key3.max(0) + 2
    key = (key3[:, 0] * dims[1] + key3[:, 1]) * dims[2] + key3[:, 2]
    uk, inv = np.unique(key, return_inverse=True)
    acc = np.zeros((len(uk), 3))
    np.add.at(acc, inv, n)
    out = np.zeros((len(f), 3))
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                nk = key + (dx * dims[1] + dy) * dims[2] + dz
                j = np.clip(np.searchsorted(uk, nk), 0, len(uk) - 1)
                hit = uk[j] == nk
                out[hit] += acc[j[hit]]
    norm = np.linalg.norm(out, axis=1, keepdims=True)
    return np.where(norm > 0, out / np.maximum(norm, 1e-300), d)


def classify_faces(v: np.ndarray, f: np.ndarray, face_piece: np.ndarray, d: np.ndarray,
                   hem_width_m: float = HEM_WIDTH_M, closed: bool = False) -> np.ndarray:
    """(F,) region label of each face of a mesh whose faces are wound toward the painted side.

    v (N, 3) [m], f (F, 3), face_piece (F,) piece index, d (3,) unit painted direction.
    """
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    area2 = np.linalg.norm(n, axis=1)
    cos_local = np.einsum("ij,ij->i", n, local_direction(v, f, d, closed=closed)) \
        / np.maximum(area2, 1e-300)
    front = cos_local > 0.0
    labels = np.full(len(f), SKIN, np.int8)
    for comp in _components(f, ~front, len(v)):
        a = 0.5 * float(area2[comp].sum())
        width = 2.0 * a / max(_open_edge_length(v, f[comp]), 1e-12)
        labels[comp] = HEM if width < hem_width_m else BACK
    steep = front & (cos_local < np.cos(EDGE_TURN_RAD))
    if steep.any():
        rim = np.zeros(len(v), bool)
        rim[f[~front].ravel()] = True
        e = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        u, c = np.unique(e, axis=0, return_counts=True)
        rim[u[c == 1].ravel()] = True
        for comp in _components(f, steep, len(v)):
            if rim[f[comp].ravel()].any():
                labels[comp] = EDGE
    _absorb_islands(f, labels, 0.5 * area2, len(v))
    labels[_hidden_pieces(v, f, face_piece, d, area2)] = INNER
    return labels


def _hidden_pieces(v: np.ndarray, f: np.ndarray, face_piece: np.ndarray, d: np.ndarray,
                   area2: np.ndarray) -> np.ndarray:
    """(F,) True on the faces of every piece, other than the one of largest area, that is mostly
    hidden behind another piece seen from the painter (rays from its faces toward +d)."""
    hidden_faces = np.zeros(len(f), bool)
    pieces = np.unique(face_piece)
    if len(pieces) < 2:
        return hidden_faces
    mesh = trimesh.Trimesh(v, f, process=False)
    centres = mesh.triangles_center
    diag = float(np.linalg.norm(np.ptp(v, axis=0)))
    main = pieces[int(np.argmax([area2[face_piece == p].sum() for p in pieces]))]
    for p in pieces:
        if p == main:
            continue
        cand = np.flatnonzero(face_piece == p)
        pick = cand[np.linspace(0, len(cand) - 1, min(_RAY_SAMPLES, len(cand))).astype(int)]
        origins = centres[pick] + 1e-6 * diag * d
        tri, ray_i = mesh.ray.intersects_id(origins, np.tile(d, (len(pick), 1)),
                                            multiple_hits=False)[:2]
        hidden = np.zeros(len(pick), bool)
        hidden[ray_i[face_piece[tri] != p]] = True
        if hidden.mean() > 0.5:
            hidden_faces[face_piece == p] = True
    return hidden_faces


def _absorb_islands(f: np.ndarray, labels: np.ndarray, area: np.ndarray, n_vertices: int) -> None:
    """Relabel (in place) patches of one label below `ISLAND_M2` with the most common label of
    the faces sharing a vertex with them (patches with no other-label neighbour stay)."""
    vf_face = np.repeat(np.arange(len(f)), 3)
    vf_vert = f.ravel()
    for lab in np.unique(labels):
        for comp in _components(f, labels == lab, n_vertices):
            if area[comp].sum() >= ISLAND_M2:
                continue
            verts = np.zeros(n_vertices, bool)
            verts[f[comp].ravel()] = True
            near = np.unique(vf_face[verts[vf_vert]])
            other = labels[near][labels[near] != lab]
            if len(other):
                labels[comp] = np.bincount(other).argmax()


def find_openings(v: np.ndarray, f: np.ndarray, front: np.ndarray, fill_holes_m: float
                  ) -> tuple[Opening, ...]:
    """Openings of one piece (v, f) whose front faces (skin and turned edges) are `front`.

    An opening is a boundary loop of the front, other than its outline (the loop spanning the
    largest area), that is a real hole of the part: the loop is on the piece's free boundary, or
    the turned-away faces it encloses reach a free boundary (a window's hem flange). Loops round
    a lip curled under the skin are not openings; nor are loops with an equivalent diameter
    (perimeter/π) below `fill_holes_m` (small holes, filled). Largest first.
    """
    e = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    u, c = np.unique(e, axis=0, return_counts=True)
    free = np.zeros(len(v), bool)
    free[u[c == 1].ravel()] = True
    # Back/turned-away patches that reach a free boundary mark their vertices as "leads out".
    leads_out = free.copy()
    for comp in _components(f, ~front, len(v)):
        verts = np.unique(f[comp].ravel())
        if free[verts].any():
            leads_out[verts] = True
    used, inv = np.unique(f[front], return_inverse=True)
    sub_f = inv.reshape(-1, 3)
    out: list[Opening] = []
    for comp in _components(sub_f, np.ones(len(sub_f), bool), len(used)):
        loops = boundary_loops(v[used], sub_f[comp])
        if len(loops) < 2:
            continue
        sizes = [loop_size(v[used], lp) for lp in loops]
        outline = int(np.argmax([s[1] for s in sizes]))
        for i, (lp, (per, area)) in enumerate(zip(loops, sizes, strict=True)):
            if i == outline or per / np.pi < fill_holes_m or not leads_out[used[lp]].any():
                continue
            ctr = v[used[lp]].mean(0)
            out.append(Opening(per, area, (float(ctr[0]), float(ctr[1]), float(ctr[2]))))
    return tuple(sorted(out, key=lambda o: -o.area_m2))
