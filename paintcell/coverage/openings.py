"""Openings: plan straight across them, brush off where the spray would go mostly through.

A real part has holes: windows, handle holes, round service holes. Offsets walked along plane
sections break at a hole's rim and passes loop around it. A painter flies straight across a
hole and switches the gun off only where most of the spray would go through it. So:

- `find_openings`: the mesh's boundary loops other than the outer one (the longest) of each
  connected piece, each with its perimeter and area (its fan from the centroid);
- `filled_surface`: the surface with every opening closed by a fan of triangles — the planner
  plans on it (passes carry on straight across), the film is still judged on the real mesh;
- `opening_fraction`: for gun samples, the share of the paint each emits that lands in an
  opening (the deposition model evaluated on points spread over the fill triangles, against the
  applicator's emitted flow);
- `brush_off_openings`: brush off every sample whose share exceeds `max_fraction` (the
  planner's `max_opening_fraction`, 0.8 by default: the rim keeps both sides' film).

Openings here are found from the mesh alone; the part import's region detection (when present)
is the source of truth for which loops are openings and which are the outer boundary.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, depth_first_order

from paintcell.coverage.plan import PassPlan
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate
from paintcell.surface.surface_data import Surface, surface_from_triangles

#: barycentric lattice levels per fill triangle for the opening fraction (k(k+1)/2 points each).
_LATTICE = 8


@dataclass(frozen=True, eq=False)
class Opening:
    """A hole in the surface: loop (L,) vertex indices in boundary order; perimeter_m [m];
    area_m2 [m²] of its fan from the centroid; centroid (3,) [m]."""

    loop: np.ndarray
    perimeter_m: float
    area_m2: float
    centroid: np.ndarray


def boundary_loops(faces: np.ndarray, n_vertices: int) -> list[np.ndarray]:
    """Ordered vertex loops of the mesh boundary (each directed as the faces' edges run): every
    consecutive pair, last to first included, is a boundary edge of the mesh.

    A boundary edge's successor is the boundary edge leaving its end vertex in the same fan of
    faces (found by turning about that vertex across interior edges), not any boundary edge that
    leaves it: where a boundary touches itself at a vertex (a pinch, which a fine remesh of a
    scanned rim leaves now and then), a walk by vertices alone has two ways on, and the loop it
    gave jumped across the hole (crs_cowling_3_holes at 10 mm: two 0.23 m chords, the fill fan
    folded over itself and a pass offset across it left the surface by 55 mm). A pinch vertex
    belongs to each loop that passes through it."""
    F = np.asarray(faces, np.int64)
    if len(F) == 0:
        return []
    n = int(n_vertices)
    # half-edge h = 3·face + k runs F[f, k] → F[f, k+1]
    tail = F.ravel()
    head = F[:, [1, 2, 0]].ravel()
    key = tail * n + head
    order = np.argsort(key, kind="stable")
    skey = key[order]

    def twin(h: np.ndarray) -> np.ndarray:
        """The half-edge running the other way along h's edge, −1 for none."""
        k = head[h] * n + tail[h]
        i = np.minimum(np.searchsorted(skey, k), len(skey) - 1)
        return np.where(skey[i] == k, order[i], -1)

    bnd = np.flatnonzero(twin(np.arange(len(key))) < 0)
    if len(bnd) == 0:
        return []

    def next_in_face(h: np.ndarray) -> np.ndarray:
        return 3 * (h // 3) + (h % 3 + 1) % 3

    # from each boundary edge a → b, turn about b through its fan: the edge leaving b in the
    # same face, and while that edge has a twin, the edge leaving b in the twin's face
    cur = next_in_face(bnd)
    nxt = np.full(len(bnd), -1)
    todo = np.arange(len(bnd))
    for _ in range(int(np.bincount(F.ravel()).max()) + 1):    # ≤ the valence of b steps
        tw = twin(cur[todo])
        done = tw < 0
        nxt[todo[done]] = cur[todo[done]]
        todo, cur_t = todo[~done], next_in_face(tw[~done])
        if len(todo) == 0:
            break
        cur[todo] = cur_t
    pos = np.full(len(key), -1)
    pos[bnd] = np.arange(len(bnd))
    succ = np.where(nxt >= 0, pos[np.maximum(nxt, 0)], -1)    # index among the boundary edges
    lost = np.flatnonzero(succ < 0)
    if len(lost):
        # a fan that never reaches a boundary edge (faces wound against their neighbours, which
        # a scan's repair can leave): any boundary edge leaving the vertex, if there is one
        by_tail = np.argsort(tail[bnd], kind="stable")
        bt = tail[bnd][by_tail]
        i = np.minimum(np.searchsorted(bt, head[bnd[lost]]), len(bt) - 1)
        succ[lost] = np.where(bt[i] == head[bnd[lost]], by_tail[i], -1)
    has = succ >= 0
    g = sp.coo_matrix((np.ones(int(has.sum())), (np.flatnonzero(has), succ[has])),
                      shape=(len(bnd), len(bnd))).tocsr()
    _, labels = connected_components(g, directed=True, connection="weak")
    # walk each loop from an edge nothing leads to, if any (an open chain), else from any
    heads_of_chains = np.flatnonzero(np.bincount(succ[has], minlength=len(bnd)) == 0)
    first = np.unique(labels, return_index=True)[1]
    chain_start = np.full(labels.max() + 1, -1)
    chain_start[labels[heads_of_chains[::-1]]] = heads_of_chains[::-1]
    first = np.where(chain_start >= 0, chain_start, first)
    loops = []
    for start in first:                   # one entry per boundary loop
        # each boundary edge has exactly one successor: the walk is the loop in order
        chain = depth_first_order(g, int(start), directed=True, return_predecessors=False)
        loops.extend(_simple_loops(tail[bnd[np.asarray(chain)]]))
    return loops


def _simple_loops(loop: np.ndarray) -> list[np.ndarray]:
    """A boundary loop that passes a vertex twice (two holes touching at a pinch: one boundary
    curve, a figure eight) cut there into loops that pass each vertex once: each is filled by a
    fan of its own (one fan over the eight folds over the surface between its lobes)."""
    out, todo = [], [loop]
    while todo:                          # one round per pinch; pinches are rare
        lp = todo.pop()
        u, cnt = np.unique(lp, return_counts=True)
        if len(lp) == 0 or cnt.max() < 2:
            out.append(lp)
            continue
        i, j = np.flatnonzero(lp == u[np.argmax(cnt > 1)])[:2]
        todo += [lp[i:j], np.concatenate([lp[j:], lp[:i]])]
    return out


def find_openings(surface: Surface) -> list[Opening]:
    """Every boundary loop but the longest of its piece (`file_pieces`: the piece's outer
    boundary) as an `Opening`: a piece apart from the others has an outline, not a hole."""
    loops = boundary_loops(surface.faces, len(surface.vertices))
    if len(loops) < 2:
        return []
    V = surface.vertices

    def perimeter(lp: np.ndarray) -> float:
        return float(np.linalg.norm(V[np.roll(lp, -1)] - V[lp], axis=1).sum())

    per = np.array([perimeter(lp) for lp in loops])
    piece = file_pieces(surface)[[int(lp[0]) for lp in loops]]
    outer = {int(np.flatnonzero(piece == c)[np.argmax(per[piece == c])]) for c in set(piece)}
    out = []
    for k, lp in enumerate(loops):
        if k in outer:
            continue
        c = V[lp].mean(axis=0)
        area = 0.5 * float(np.linalg.norm(np.cross(V[lp] - c, V[np.roll(lp, -1)] - c),
                                          axis=1).sum())
        # a loop of one or two vertices (a slit, or a pinch a scan's repair left) encloses no
        # area: it is not an opening, and its fan would add a vertex without any face area
        if len(np.unique(lp)) < 3 or area <= 0.0:
            continue
        out.append(Opening(lp, per[k], area, c))
    return out


def file_pieces(surface: Surface) -> np.ndarray:
    """(N,) the piece of the part file each vertex belongs to (the import's `face_piece`), or,
    for a surface without regions, its connected piece. A region's patch cut off from the rest
    of the same file piece (a strip of skin beyond an edge region) is not a piece of its own."""
    regs = surface.regions
    F = np.asarray(surface.faces, np.int64)
    if regs is None or len(regs.face_piece) != len(F):
        return vertex_pieces(F, len(surface.vertices))
    out = np.full(len(surface.vertices), -1, np.int64)
    for k in range(3):
        out[F[:, k]] = regs.face_piece
    return out


def vertex_pieces(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """(N,) connected piece of each vertex (faces sharing a vertex are one piece)."""
    F = np.asarray(faces, np.int64)
    a = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    b = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    g = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(n_vertices, n_vertices))
    return connected_components(g, directed=False)[1]


def fill_triangles(surface: Surface, openings: list[Opening]) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (N + K, 3) (the surface's, then one centroid per opening) and the fan faces
    (F', 3) closing the openings, wound consistently with the surface."""
    V = surface.vertices
    cent = np.array([o.centroid for o in openings]).reshape(-1, 3)
    faces = []
    for k, o in enumerate(openings):      # a few openings per part
        a, b = o.loop, np.roll(o.loop, -1)
        faces.append(np.column_stack([b, a, np.full(len(a), len(V) + k)]))
    F = np.concatenate(faces) if faces else np.zeros((0, 3), np.int64)
    return np.vstack([V, cent]), F.astype(np.int64)


def filled_surface(surface: Surface, openings: list[Opening]) -> Surface:
    """The surface with its openings closed by fans (same name; the first N vertices are the
    surface's own)."""
    if not openings:
        return surface
    V, F_fill = fill_triangles(surface, openings)
    return surface_from_triangles(surface.name, V, np.vstack([surface.faces, F_fill]))


def fill_samples(surface: Surface, openings: list[Opening]
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (P, 3), unit normals (P, 3) and area weights (P,) [m²] spread over the openings'
    fill triangles (a barycentric lattice per triangle; the weights sum to the fill area)."""
    return lattice_samples(*fill_triangles(surface, openings))


def lattice_samples(vertices: np.ndarray, faces: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (P, 3), unit normals (P, 3) and area weights (P,) [m²] of a barycentric lattice
    over each triangle `faces` (F, 3) of `vertices` (the weights sum to the triangles' area; the
    normals are the faces' own, on the side their winding gives)."""
    V, F = vertices, faces
    if len(F) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    k = _LATTICE
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    m = (i + j) < k
    bary = np.column_stack([(i[m] + 1 / 3) / k, (j[m] + 1 / 3) / k])
    bary = np.column_stack([bary, 1.0 - bary.sum(axis=1)])
    bary = bary[bary[:, 2] > 0]
    tri = V[F]                                           # (F, 3, 3)
    pts = np.einsum("bk,fkd->fbd", bary, tri).reshape(-1, 3)
    cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cr, axis=1)
    n = cr / np.maximum(2 * area, 1e-30)[:, None]
    # the fill faces are wound like the surface: their normal is on the painted side
    nrm = np.repeat(n, len(bary), axis=0)
    w = np.repeat(area / len(bary), len(bary))
    return pts, nrm, w


def opening_fraction(app: Applicator, positions: np.ndarray, spray_axes: np.ndarray,
                     travel_dirs: np.ndarray, fill: tuple[np.ndarray, np.ndarray, np.ndarray]
                     ) -> np.ndarray:
    """(S,) share of the paint each gun sample emits that lands in the openings [-]: the film
    volume rate on the fill points (deposition model) over the applicator's emitted flow."""
    pts, nrm, w = fill
    if len(pts) == 0 or len(positions) == 0:
        return np.zeros(len(positions))
    rate = deposition_rate(app, positions, spray_axes, travel_dirs, pts, nrm)   # (S, P) [m/s]
    return (rate @ w) / app.emitted_flow_m3_s


def brush_off_openings(app: Applicator, passes: list[PassPlan],
                       fill: tuple[np.ndarray, np.ndarray, np.ndarray],
                       max_fraction: float = 0.5) -> tuple[list[PassPlan], int]:
    """Passes with the brush off at every sample whose `opening_fraction` exceeds
    `max_fraction`; returns them and the number of samples switched off."""
    out, n_off = [], 0
    for p in passes:
        f = opening_fraction(app, p.positions, p.spray_axes, p.travel_dirs, fill)
        off = p.paint_on & (f > max_fraction)
        n_off += int(off.sum())
        out.append(dataclasses.replace(p, paint_on=p.paint_on & ~off) if off.any() else p)
    return out, n_off
