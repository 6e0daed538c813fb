"""Reading a triangle mesh for `Surface.from_mesh`: STL/OBJ/PLY (or a trimesh.Trimesh) checked,
repaired where it can be (duplicate vertices and faces, collapsed faces, winding), refused with
the fix where it cannot (NaN, slivers, non-manifold edges, several components), and wound toward
the painted side. Coordinates are kept as given [m].
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import trimesh

from paintcell.core.errors import SurfaceError

# A face is a sliver (degenerate, not repairable by dropping it) below this area relative to the
# squared bounding-box diagonal: 1e-12 is far below any real CAD tessellation (a 1 m part would
# need a 1 µm² triangle) yet well above float64 round-off of a true zero-area face (~1e-16).
_SLIVER_REL_AREA = 1e-12


def load_clean_mesh(path_or_mesh: str | os.PathLike[str] | trimesh.Trimesh,
                    component: int | None = None, flip: bool = False
                    ) -> tuple[np.ndarray, np.ndarray, str]:
    """Read, check and repair a triangle mesh; see `Surface.from_mesh` for what is refused.

    Returns vertices (N, 3) [m], faces (F, 3) int64 consistently wound toward the painted side,
    and a default name (the file stem, or "mesh").
    """
    src: object
    if isinstance(path_or_mesh, trimesh.Trimesh):
        src, name = path_or_mesh, "mesh"
    else:
        path = Path(path_or_mesh)
        if not path.is_file():
            raise SurfaceError(f"mesh file {path} does not exist; check the path")
        try:
            src = trimesh.load(path, force="mesh", process=False)
        except Exception as exc:  # trimesh raises many types for unreadable files
            raise SurfaceError(f"cannot read mesh {path} ({type(exc).__name__}: {exc}); "
                               "export it as STL, OBJ or PLY") from exc
        name = path.stem
        if not isinstance(src, trimesh.Trimesh) or len(src.faces) == 0 \
                or len(src.vertices) == 0:
            # trimesh returns an empty mesh (no exception) for many unparseable files
            raise SurfaceError(f"could not read {path} as a triangle mesh (no triangles found); "
                               "export the part surface as an STL, OBJ or PLY triangle mesh")
    if not isinstance(src, trimesh.Trimesh) or len(src.faces) == 0 or len(src.vertices) == 0:
        raise SurfaceError("mesh is empty (no triangles); export the part surface as triangles")
    v = np.asarray(src.vertices, dtype=float)
    f = np.asarray(src.faces, dtype=np.int64)
    bad = ~np.all(np.isfinite(v), axis=1)
    if bad.any():
        raise SurfaceError(f"mesh has {int(bad.sum())} vertices with NaN or inf coordinates; "
                           "fix or re-export the mesh")
    if f.min() < 0 or f.max() >= len(v):
        raise SurfaceError("mesh faces index missing vertices; re-export the mesh")

    m = trimesh.Trimesh(v, f, process=False)
    m.merge_vertices()
    f = np.asarray(m.faces, dtype=np.int64)
    v = np.asarray(m.vertices, dtype=float)
    # Collapsed faces (a repeated vertex after merging) carry no area: drop them.
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    if len(f) == 0:
        raise SurfaceError("every face of the mesh is degenerate; export the part surface again")
    # Duplicate faces (same three vertices, either winding): keep the first.
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    f = f[np.sort(first)]
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                                axis=1)
    diag2 = float(np.sum((v.max(0) - v.min(0)) ** 2))
    sliver = area <= _SLIVER_REL_AREA * diag2
    if sliver.any():
        raise SurfaceError(f"mesh has {int(sliver.sum())} zero-area faces with three distinct "
                           f"vertices (first: face {int(np.flatnonzero(sliver)[0])}); collapse "
                           "the slivers or remesh in your CAD/mesh tool")
    edges = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, edge_count = np.unique(edges, axis=0, return_counts=True)
    if np.any(edge_count > 2):
        raise SurfaceError(f"mesh has {int(np.sum(edge_count > 2))} non-manifold edges (shared "
                           "by more than 2 faces); split or delete them (e.g. MeshLab: select "
                           "non-manifold edges)")

    m = trimesh.Trimesh(v, f, process=False)
    groups = trimesh.graph.connected_components(m.face_adjacency, nodes=np.arange(len(f)),
                                                min_len=1)
    groups = sorted(groups, key=lambda g: (-len(g), int(np.min(g))))
    sizes = ", ".join(str(len(g)) for g in groups)
    if component is None and len(groups) > 1:
        raise SurfaceError(f"mesh has {len(groups)} connected components (faces: {sizes}); "
                           "in a scenario choose them with [part] pieces = \"largest\", \"all\" "
                           "or [k, ...]; in Python pass component=k (0 = largest)")
    k = 0 if component is None else int(component)
    if not 0 <= k < len(groups):
        raise SurfaceError(f"component={component} is out of range; the mesh has "
                           f"{len(groups)} components (faces: {sizes})")
    f = f[np.sort(np.asarray(groups[k]))]
    used, f = np.unique(f, return_inverse=True)
    f = f.reshape(-1, 3).astype(np.int64)
    v = v[used]

    cross_in = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    m = trimesh.Trimesh(v, f, process=False)
    trimesh.repair.fix_winding(m)
    if not m.is_winding_consistent:
        raise SurfaceError("mesh cannot be wound consistently (non-orientable, Moebius-like); "
                           "cut it into orientable pieces")
    f = np.asarray(m.faces, dtype=np.int64)
    if m.is_watertight:
        out = float(m.volume) >= 0.0       # closed: paint the outside
    else:                                   # open: the side most input area already faced
        cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        agree = np.sign((cross * cross_in).sum(1))
        out = float(agree @ np.linalg.norm(cross_in, axis=1)) >= 0.0
    if out == flip:
        f = f[:, ::-1]
    return v, np.ascontiguousarray(f), name

