"""Repair and isotropic remeshing of a part mesh with MeshLab's filters (pymeshlab).

Why pymeshlab: one maintained library holds every step a paint shop's files need — merging
duplicates, dropping null faces (slivers flatter than 10 µm are merged away or dropped),
splitting non-manifold edges and vertices, coherent orientation, selective hole closing, and an
isotropic explicit remesher that keeps feature edges (creases) and reprojects on the input.
Measured against gpytoolbox's `remesh_botsch` in `benchmarks/import.py`.

Coordinates here are metres (the caller scales the file first).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from paintcell.core.errors import SurfaceError

__all__ = ["RepairReport", "boundary_loops", "fill_small_holes", "loop_size", "remesh", "repair",
           "sliver_mask"]

#: Vertices closer than this are one vertex [m] (10 µm: far below any paint feature or sheet
#: thickness, far above the float round-off of an exporter that wrote each face separately).
MERGE_TOL_M = 1e-5
#: A face is a sliver when its smallest altitude is below this [m]: a needle or cap flatter than
#: the merge tolerance. (Long thin faces of a fillet or hem bend, 0.5 mm high, are real surface.)
SLIVER_HEIGHT_M = MERGE_TOL_M


@dataclass(frozen=True)
class RepairReport:
    """What `repair` changed (counts)."""

    faces_in: int
    merged_vertices: int
    duplicate_faces: int
    degenerate_faces: int
    slivers: int
    nonmanifold_edges: int
    faces_out: int
    holes_filled: int = 0
    thinned_from: int = 0
    """Faces of the file before it was thinned (`paintcell.surface.mesh_thinning`; 0: not)."""
    thin_cell_m: float = 0.0
    """Vertex-clustering cell of the thinning [m] (0: not thinned)."""

    def summary(self) -> str:
        """One line for `paintcell inspect`."""
        thin = (f"{self.thinned_from} faces thinned to {self.faces_in} (vertex clustering at "
                f"{self.thin_cell_m * 1e3:.3g} mm, far finer than the resolution); "
                if self.thinned_from else "")
        return (f"{thin}{self.faces_in} faces in, {self.faces_out} out: {self.merged_vertices} "
                f"duplicate vertices merged, {self.duplicate_faces} duplicate faces, "
                f"{self.degenerate_faces} degenerate faces and {self.slivers} slivers removed, "
                f"{self.nonmanifold_edges} non-manifold edges split, {self.holes_filled} small "
                "holes filled")


def sliver_mask(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(F,) True for faces with three distinct vertices and an altitude below
    `SLIVER_HEIGHT_M` (2·area / longest edge)."""
    distinct = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    e = np.stack([np.linalg.norm(v[f[:, i]] - v[f[:, (i + 1) % 3]], axis=1) for i in range(3)])
    area2 = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    return distinct & (area2 < SLIVER_HEIGHT_M * e.max(0))


def _ms(v: np.ndarray, f: np.ndarray, fq: np.ndarray | None = None):  # type: ignore[no-untyped-def]
    import pymeshlab

    ms = pymeshlab.MeshSet()
    kw = {} if fq is None else {"f_scalar_array": np.asarray(fq, float)}
    ms.add_mesh(pymeshlab.Mesh(np.asarray(v, float), np.asarray(f, np.int32), **kw))
    return ms


def _out(ms) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    m = ms.current_mesh()
    return np.asarray(m.vertex_matrix(), float), np.asarray(m.face_matrix(), np.int64)


def _count_nonmanifold_edges(f: np.ndarray) -> int:
    e = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, c = np.unique(e, axis=0, return_counts=True)
    return int(np.sum(c > 2))


def repair(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray, RepairReport]:
    """Clean a triangle soup [m]: merge duplicate vertices, remove duplicate and null faces,
    collapse or drop slivers (flatter than `SLIVER_HEIGHT_M`), split non-manifold edges and
    vertices, orient faces coherently (per connected piece). Returns vertices, faces (int64)
    and what changed."""
    import pymeshlab

    f_in = len(f)
    slivers = int(sliver_mask(v, f).sum())
    ms = _ms(v, f)
    ms.meshing_remove_unreferenced_vertices()
    n0 = ms.current_mesh().vertex_number()
    ms.meshing_merge_close_vertices(threshold=pymeshlab.PureValue(MERGE_TOL_M))
    merged = n0 - ms.current_mesh().vertex_number()
    k0 = ms.current_mesh().face_number()
    ms.meshing_remove_duplicate_faces()
    dup = k0 - ms.current_mesh().face_number()
    k1 = ms.current_mesh().face_number()
    ms.meshing_remove_null_faces()
    degenerate = max(0, k1 - ms.current_mesh().face_number() - slivers)
    nm = _count_nonmanifold_edges(_out(ms)[1])
    ms.meshing_repair_non_manifold_edges(method="Split Vertices")
    ms.meshing_repair_non_manifold_vertices()
    ms.meshing_remove_unreferenced_vertices()
    ms.meshing_re_orient_faces_coherently()
    v2, f2 = _out(ms)
    if len(f2) < 2:
        raise SurfaceError(f"after repair the mesh has {len(f2)} usable triangle(s) of {f_in}; "
                           "export the whole part surface again")
    # Slivers the merge did not collapse carry < 10 µm × edge of area: drop them.
    left = sliver_mask(v2, f2)
    if left.any():
        # Dropping a face can pinch two boundary loops into one vertex (a hole touching the
        # outline or another hole): split such vertices again, else the loops are traced as one
        # and a real opening is lost (crs_cowling_3_holes: a 236 mm hole vanished).
        ms = _ms(v2, f2[~left])
        ms.meshing_repair_non_manifold_vertices()
        ms.meshing_remove_unreferenced_vertices()
        v2, f2 = _out(ms)
    return v2, f2, RepairReport(faces_in=f_in, merged_vertices=merged, duplicate_faces=dup,
                                degenerate_faces=degenerate, slivers=slivers,
                                nonmanifold_edges=nm, faces_out=len(f2))


def boundary_loops(v: np.ndarray, f: np.ndarray) -> list[np.ndarray]:
    """Closed boundary loops of a mesh as vertex-index arrays (first vertex not repeated)."""
    mesh = trimesh.Trimesh(v, f, process=False)
    if len(trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)) == 0:
        return []
    from trimesh.path.exchange.misc import faces_to_path

    loops = []
    for ent in faces_to_path(mesh)["entities"]:
        pts = np.asarray(ent.points, np.int64)
        if len(pts) > 3 and pts[0] == pts[-1]:
            loops.append(pts[:-1])
    return loops


def loop_size(v: np.ndarray, loop: np.ndarray) -> tuple[float, float]:
    """(perimeter [m], spanned area [m²]) of a boundary loop: the area is the norm of the
    loop's vector area ½Σ pᵢ × pᵢ₊₁ (exact for a planar loop)."""
    p = v[loop]
    q = np.roll(p, -1, axis=0)
    per = float(np.linalg.norm(q - p, axis=1).sum())
    area = 0.5 * float(np.linalg.norm(np.cross(p - p.mean(0), q - p.mean(0)).sum(0)))
    return per, area


def fill_small_holes(v: np.ndarray, f: np.ndarray, max_diameter_m: float
                     ) -> tuple[np.ndarray, np.ndarray, int]:
    """Close the boundary loops whose equivalent diameter (perimeter/π) is below
    `max_diameter_m` (scan holes); larger loops (outline, openings) stay. Returns v, f, count."""
    if max_diameter_m <= 0:
        return v, f, 0
    loops = boundary_loops(v, f)
    if not loops:
        return v, f, 0
    # Never close a piece's outline (the loop spanning the largest area of its piece).
    mesh = trimesh.Trimesh(v, f, process=False)
    comp = np.full(len(v), -1)
    for k, g in enumerate(trimesh.graph.connected_components(mesh.face_adjacency,
                                                             nodes=np.arange(len(f)), min_len=1)):
        comp[f[np.asarray(g)].ravel()] = k
    sizes = [loop_size(v, lp) for lp in loops]
    outline: dict[int, int] = {}
    for i, lp in enumerate(loops):
        c = int(comp[lp[0]])
        if c not in outline or sizes[i][1] > sizes[outline[c]][1]:
            outline[c] = i
    keep_open = set(outline.values())
    small = [lp for i, lp in enumerate(loops)
             if i not in keep_open and sizes[i][0] / np.pi < max_diameter_m]
    if not small:
        return v, f, 0
    mark = np.zeros(len(v), bool)
    mark[np.concatenate(small)] = True
    fq = (mark[f].sum(1) >= 2).astype(float)  # faces with a boundary edge on a small loop
    ms = _ms(v, f, fq)
    ms.compute_selection_by_condition_per_face(condselect="fq > 0.5")
    ms.meshing_close_holes(maxholesize=max(len(lp) for lp in small) + 1, selected=True,
                           newfaceselected=False, selfintersection=False)
    v2, f2 = _out(ms)
    filled = len(loops) - len(boundary_loops(v2, f2))
    return v2, f2, filled


def remesh(v: np.ndarray, f: np.ndarray, target_m: float, feature_deg: float = 30.0,
           iterations: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Isotropic remesh to edges of about `target_m` [m], keeping feature edges sharper than
    `feature_deg` [deg] and reprojecting onto the input (surface deviation ≤ target/20)."""
    import pymeshlab

    if not np.isfinite(target_m) or target_m <= 0:
        raise SurfaceError(f"remesh target {target_m} m must be a positive length")
    ms = _ms(v, f)
    # A dense scan first goes down to ~4× the target's face count by quadric edge collapse
    # (boundary, normals and topology kept): the remesher's passes then work on a small mesh.
    area = float(np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                                axis=1).sum() / 2)
    target_faces = int(4 * area / (0.433 * target_m**2))
    if len(f) > 2 * target_faces:
        ms.meshing_decimation_quadric_edge_collapse(
            targetfacenum=max(target_faces, 100), preserveboundary=True, boundaryweight=2.0,
            preservenormal=True, preservetopology=True, qualitythr=0.5, planarquadric=True)
    ms.meshing_isotropic_explicit_remeshing(
        iterations=iterations, targetlen=pymeshlab.PureValue(target_m), featuredeg=feature_deg,
        checksurfdist=True, maxsurfdist=pymeshlab.PureValue(target_m / 20.0))
    ms.meshing_remove_unreferenced_vertices()
    return _out(ms)
