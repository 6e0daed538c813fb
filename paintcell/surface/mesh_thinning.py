"""A mesh file far finer than the run needs, thinned on its way in; its memory budgeted first.

A scan or a CAD export at 0.1 mm can hold millions of faces for a part the run remeshes at
10 mm. Repairing and splitting such a triangle soup costs minutes and gigabytes for detail the
remesh throws away (a 2-million-face binary STL, `benchmarks/huge_mesh.py`: `paintcell inspect`
155 s and 4.8 GiB peak, `init` 556 s and 4.9 GiB; thinned first, 23 s and 1.06 GiB, 46 s and
1.14 GiB). So before the repair:

- the file's faces are budgeted (`paintcell.core.budget`) against the memory the
  process may use, and so is the surface at the run's resolution;
- a mesh with more than `DECIMATE_RATIO` times the faces of a mesh at a quarter of the run's
  resolution (an isotropic mesh at edge h has ~`FACES_PER_H2` · area / h² faces), or more than
  `MAX_INPUT_FACES` when no resolution is asked, is thinned by vertex clustering
  (Rossignac & Borrel 1993): the vertices of each cubic cell of side `cell_m` (a quarter of the
  resolution) become their mean, faces that collapse are dropped, and duplicates removed. It is
  linear in the faces and keeps the surface within a cell of where it was (the outline within
  half a cell); what it changes is finer than the remesh that follows keeps anyway. The report
  says it did so.
"""

from __future__ import annotations

import math

import numpy as np

from paintcell.core.memory import BudgetError

__all__ = ["CELL_FRACTION", "DECIMATE_RATIO", "FACES_PER_H2", "MAX_INPUT_FACES",
           "cluster_vertices", "thin_cell", "thin_for_resolution"]

#: Faces of an isotropic remesh at edge length h per area h² (equilateral triangles: 4/√3).
FACES_PER_H2 = 4 / math.sqrt(3)
#: The clustering cell as a fraction of the run's resolution: a part's outline moves inward by
#: up to half a cell (measured on a 1.0 × 0.8 m panel at 25 mm: area −1.4 % at ½, see the
#: tests), so a quarter keeps it within an eighth of the resolution.
CELL_FRACTION = 0.25
#: A mesh is thinned when it holds more than this many times the faces of a mesh at the cell.
DECIMATE_RATIO = 4
#: Most faces a mesh keeps on its way in when no resolution is asked (`inspect --resolution 0`).
MAX_INPUT_FACES = 400_000
def thin_cell(n_faces: int, area_m2: float, resolution_m: float | None) -> float | None:
    """The clustering cell [m] for a mesh of `n_faces` and `area_m2` at `resolution_m` (None:
    no remesh): a quarter of the resolution, used only when the mesh holds more than
    `DECIMATE_RATIO` times the faces a mesh at that edge length has; else None."""
    if resolution_m is not None:
        cell = CELL_FRACTION * resolution_m
        grid_faces = FACES_PER_H2 * area_m2 / cell**2
        return cell if n_faces > DECIMATE_RATIO * max(grid_faces, 1.0) else None
    if n_faces <= MAX_INPUT_FACES or area_m2 <= 0:
        return None
    return math.sqrt(FACES_PER_H2 * area_m2 / (MAX_INPUT_FACES / DECIMATE_RATIO))


def _grid_keys(p: np.ndarray, cell_m: float) -> np.ndarray:
    """(N,) one int64 key per cubic cell of side cell_m [m] holding each point (N, 3)."""
    idx = np.floor((p - p.min(axis=0)) / cell_m).astype(np.int64)
    dims = idx.max(axis=0) + 1
    if float(dims[0]) * float(dims[1]) * float(dims[2]) >= 2.0**62:
        raise BudgetError(f"a {cell_m:g} m clustering cell over a {np.ptp(p, axis=0).max():.3g} "
                          "m part has too many cells; check the part's units")
    return (idx[:, 0] * dims[1] + idx[:, 1]) * dims[2] + idx[:, 2]


def _boundary_vertices(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(V,) True for the vertices on an edge that only one face uses (the outline and the
    holes), the corners that coincide within `MERGE_TOL_M` taken as one vertex."""
    from paintcell.surface.mesh_repair import MERGE_TOL_M

    _, same = np.unique(_grid_keys(v, MERGE_TOL_M), return_inverse=True)
    same = same.reshape(-1)
    g = same[f]
    e = np.sort(np.concatenate([g[:, [0, 1]], g[:, [1, 2]], g[:, [2, 0]]]), axis=1)
    ek = e[:, 0] * (int(same.max()) + 1) + e[:, 1]
    _, inv, cnt = np.unique(ek, return_inverse=True, return_counts=True)
    on = np.zeros(int(same.max()) + 1, bool)
    on[e[cnt[inv.reshape(-1)] == 1].reshape(-1)] = True
    return on[same]


def cluster_vertices(v: np.ndarray, f: np.ndarray, cell_m: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Vertex clustering: the vertices (V, 3) of each cubic cell of side cell_m [m] become their
    mean — the outline's vertices (`_boundary_vertices`) a cluster of their own, so the outline
    stays where it was instead of being pulled toward the inside; faces (F, 3) with two corners
    in one cluster are dropped and repeated faces (the same three clusters, either orientation)
    kept once, in their first order."""
    key = _grid_keys(v, cell_m) * 2 + _boundary_vertices(v, f)
    _, inv = np.unique(key, return_inverse=True)
    inv = inv.reshape(-1)
    cnt = np.bincount(inv)
    nv = np.stack([np.bincount(inv, weights=v[:, k]) for k in range(3)], axis=1) / cnt[:, None]
    nf = inv[f]
    keep = (nf[:, 0] != nf[:, 1]) & (nf[:, 1] != nf[:, 2]) & (nf[:, 0] != nf[:, 2])
    nf = nf[keep]
    _, first = np.unique(np.sort(nf, axis=1), axis=0, return_index=True)
    nf = nf[np.sort(first)]
    used, remap = np.unique(nf, return_inverse=True)
    return nv[used], remap.reshape(-1, 3).astype(np.int64)


def thin_for_resolution(v: np.ndarray, f: np.ndarray, resolution_m: float | None
                        ) -> tuple[np.ndarray, np.ndarray, float | None]:
    """(vertices, faces, cell [m] or None): the mesh [m] thinned by `cluster_vertices` when it is
    far finer than `resolution_m` needs (module doc), else as it was."""
    a = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    cell = thin_cell(len(f), 0.5 * float(a.sum()), resolution_m)
    if cell is None:
        return v, f, None
    tv, tf = cluster_vertices(v, f, cell)
    if len(tf) < 2:      # a part smaller than a cell: keep it as it was
        return v, f, None
    return tv, tf, cell
