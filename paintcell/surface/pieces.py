"""Which connected pieces of a part file are one part: `[part] pieces = "auto"`.

A part often comes in pieces: a door's lower panel and its window frame's members a few
centimetres apart, a panel with clips, fasteners and sealer beads modelled on it. Starting from
the largest piece, a piece joins the part when it
- is not a stray bit: its area is at least `STRAY_AREA_FRACTION` of the largest piece's;
- faces the painted side: at least half its area has normals within 60° of the painted
  direction d (either winding: a file's pieces need not be wound alike);
- lies close: its surface comes within `gap_m` of the part's (touching: 0);
- is not hidden behind the part seen from the painter (an inner panel: rays from its faces
  toward +d mostly hit the part).
Joining repeats until no piece joins (a frame's members join through each other). Every piece
not joined is named with why (`PieceChoice.reasons`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from paintcell.surface.part_spec import PIECES_GAP_M

__all__ = ["FACING_COS", "STRAY_AREA_FRACTION", "PieceChoice", "choose_pieces"]

#: A piece of less than this share of the largest piece's area is a stray bit (a clip, a
#: fastener, a sealer bead) and is not painted [-].
STRAY_AREA_FRACTION = 0.01
#: A face faces the painted side when |n · d| is at least this (60°) [-].
FACING_COS = 0.5
#: Faces sampled per piece for the hidden-piece ray test [-].
_RAY_SAMPLES = 256


@dataclass(frozen=True)
class PieceChoice:
    """selected: indices into the pieces (the largest first, then in the order they joined);
    gaps_m: the gap [m] through which each joined piece joined (0 for the largest);
    reasons: why each piece that was not joined was left out."""

    selected: tuple[int, ...]
    gaps_m: dict[int, float]
    reasons: dict[int, str]


def _areas_normals(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    a2 = np.linalg.norm(n, axis=1)
    return 0.5 * a2, n / np.maximum(a2, 1e-300)[:, None]


def _mesh(v: np.ndarray, f: np.ndarray) -> trimesh.Trimesh:
    """The faces `f` of `v` as a mesh of their own vertices."""
    used, inv = np.unique(f, return_inverse=True)
    return trimesh.Trimesh(v[used], inv.reshape(-1, 3), process=False)


def _gap(v: np.ndarray, f: np.ndarray, mesh_a: trimesh.Trimesh, tree_a: cKDTree,
         edge_a: float, piece: np.ndarray, gap_m: float) -> float:
    """Smallest distance [m] between the surface `mesh_a` and the faces `piece` (both ways,
    vertex to surface), or inf when it exceeds `gap_m` plus the tessellation's reach."""
    mesh_b = _mesh(v, f[piece])
    vb = mesh_b.vertices
    best = np.inf
    near = tree_a.query(vb, k=1, distance_upper_bound=gap_m + edge_a)[0]
    pick = vb[np.isfinite(near)]
    if len(pick):
        best = float(trimesh.proximity.closest_point(mesh_a, pick)[1].min())
    edge_b = float(mesh_b.edges_unique_length.max()) if len(mesh_b.edges_unique) else 0.0
    near_b = cKDTree(vb).query(mesh_a.vertices, k=1, distance_upper_bound=gap_m + edge_b)[0]
    pick = mesh_a.vertices[np.isfinite(near_b)]
    if len(pick):
        best = min(best, float(trimesh.proximity.closest_point(mesh_b, pick)[1].min()))
    return best


def _hidden(v: np.ndarray, f: np.ndarray, mesh_a: trimesh.Trimesh, piece: np.ndarray,
            d: np.ndarray) -> bool:
    """True when most rays from the faces of `piece` toward +d hit `mesh_a` (the part)."""
    pick = piece[np.linspace(0, len(piece) - 1, min(_RAY_SAMPLES, len(piece))).astype(int)]
    c = v[f[pick]].mean(1)
    diag = float(np.linalg.norm(np.ptp(v, axis=0)))
    hit = mesh_a.ray.intersects_any(c + 1e-6 * diag * d, np.tile(d, (len(pick), 1)))
    return bool(np.mean(hit) > 0.5)


def choose_pieces(v: np.ndarray, f: np.ndarray, groups: list[np.ndarray], d: np.ndarray,
                  gap_m: float = PIECES_GAP_M,
                  stray_fraction: float = STRAY_AREA_FRACTION) -> PieceChoice:
    """The pieces painted as one part (module doc).

    v (N, 3) [m], f (F, 3); groups: face indices of each piece, the largest first
    (`paintcell.surface.part_import.split_pieces`); d (3,) unit painted direction of the
    largest piece; gap_m: largest gap [m]; stray_fraction: smallest area share of the largest
    piece [-].
    """
    area, normal = _areas_normals(v, f)
    a = np.array([float(area[g].sum()) for g in groups])
    reasons: dict[int, str] = {}
    todo: list[int] = []
    for i, g in enumerate(groups[1:], start=1):
        facing = float(area[g][np.abs(normal[g] @ d) >= FACING_COS].sum()) / max(a[i], 1e-300)
        if a[i] < stray_fraction * a[0]:
            reasons[i] = (f"stray bit: {a[i]:.4f} m², under {100 * stray_fraction:g} % of the "
                          "largest piece")
        elif facing < 0.5:
            reasons[i] = (f"faces another side ({100 * facing:.0f} % of it within 60° of the "
                          "painted direction)")
        else:
            todo.append(i)
    selected, gaps = [0], {0: 0.0}
    far: dict[int, float] = {}
    changed = True
    while changed and todo:
        changed = False
        faces_a = np.concatenate([groups[i] for i in selected])
        mesh_a = _mesh(v, f[faces_a])
        tree_a = cKDTree(mesh_a.vertices)
        edge_a = float(mesh_a.edges_unique_length.max())
        for i in list(todo):
            gap = _gap(v, f, mesh_a, tree_a, edge_a, groups[i], gap_m)
            far[i] = min(far.get(i, np.inf), gap)
            if gap > gap_m:
                continue
            todo.remove(i)
            if _hidden(v, f, mesh_a, groups[i], d):
                reasons[i] = "hidden behind the part seen from the painter (an inner panel)"
                continue
            selected.append(i)
            gaps[i] = gap
            changed = True
    for i in todo:
        g_far = far.get(i, float(np.inf))
        reasons[i] = (f"{1e3 * g_far:.0f} mm from the part" if np.isfinite(g_far) else
                      f"more than {1e3 * gap_m:.0f} mm from the part") + \
            f" (pieces_gap_m = {gap_m:g})"
    return PieceChoice(tuple(selected), gaps, dict(sorted(reasons.items())))
