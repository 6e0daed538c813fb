"""The `Surface` type: a triangle mesh in the part frame [m] with per-vertex unit normals, areas
[m²] and curvature (K [1/m²]; H, k1, k2 [1/m]; principal directions), its frame changes, region
subsets and exact `.npz` round trip, and its construction from triangles with discrete normal and
curvature estimates (`surface_from_triangles`, `paintcell.surface.curvature`).

Curvature sign (docs/interfaces.md): with the unit normal n pointing to the painted side, a
principal curvature k is positive when the surface bends away from n — dn = k dr along a principal
direction, so a sphere with outward normal has k1 = k2 = H = +1/R.
"""

from __future__ import annotations

import functools
import json
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import numpy.typing as npt
import trimesh

from paintcell.core.atomic_io import atomic_write_npz
from paintcell.core.errors import SurfaceError
from paintcell.core.transforms import check_pose
from paintcell.surface.regions import PartRegions
from paintcell.surface.surface_mesh_input import load_clean_mesh

_FORMAT = "paintcell.Surface/1"
_ARRAY_FIELDS = ("vertices", "faces", "normals", "vertex_areas", "gaussian_curvature",
                 "mean_curvature", "principal_curvatures", "principal_directions")


@dataclass(frozen=True, eq=False)
class Surface:
    """A painted surface: triangle mesh + per-vertex normals and curvature, in the part frame.

    name: part name.
    vertices: (N, 3) positions in the part frame [m].
    faces: (F, 3) int64 triangles, counter-clockwise seen from the painted side.
    normals: (N, 3) unit normals pointing to the painted side (toward the gun).
    vertex_areas: (N,) barycentric area (a third of each incident face) [m²]; sums to the area.
    gaussian_curvature: (N,) K [1/m²].
    mean_curvature: (N,) H [1/m], positive when the surface bends away from the normal.
    principal_curvatures: (N, 2) k1 >= k2 [1/m].
    principal_directions: (N, 2, 3) unit tangent directions of k1 and k2.
    uv: (N, 2) patch parameters in metres of arc length along the mid iso-curves, or None.
    grid_shape: (nu, nv) when vertex i*nv + j is grid node (u_i, v_j), else None.
    regions: per-face labels of a real part (skin, hem, inner, back), its openings and the
        regions the film is judged on (`paintcell.surface.regions.PartRegions`), or None
        (all skin).
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    vertex_areas: np.ndarray
    gaussian_curvature: np.ndarray
    mean_curvature: np.ndarray
    principal_curvatures: np.ndarray
    principal_directions: np.ndarray
    uv: np.ndarray | None = None
    grid_shape: tuple[int, int] | None = None
    regions: PartRegions | None = None

    def __post_init__(self) -> None:
        n = len(self.vertices)
        shapes = {
            "vertices": (n, 3), "normals": (n, 3), "vertex_areas": (n,),
            "gaussian_curvature": (n,), "mean_curvature": (n,),
            "principal_curvatures": (n, 2), "principal_directions": (n, 2, 3),
        }
        if n < 3:
            raise SurfaceError(f"surface {self.name!r} has {n} vertices; a surface needs >= 3")
        for key, shape in shapes.items():
            arr = getattr(self, key)
            if not isinstance(arr, np.ndarray) or arr.shape != shape:
                got = getattr(arr, "shape", type(arr).__name__)
                raise SurfaceError(f"surface field {key} has shape {got}, expected {shape}")
            if not np.all(np.isfinite(arr)):
                raise SurfaceError(f"surface field {key} contains NaN or inf; rebuild the surface")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3 or len(self.faces) == 0:
            raise SurfaceError(f"faces have shape {self.faces.shape}, expected (F>0, 3)")
        if self.faces.min() < 0 or self.faces.max() >= n:
            raise SurfaceError("faces index vertices out of range; rebuild the surface")
        if self.uv is not None and self.uv.shape != (n, 2):
            raise SurfaceError(f"uv has shape {self.uv.shape}, expected ({n}, 2) or None")
        if self.grid_shape is not None and self.grid_shape[0] * self.grid_shape[1] != n:
            raise SurfaceError(f"grid_shape {self.grid_shape} does not match {n} vertices")
        if self.regions is not None and self.regions.face_labels.shape != (len(self.faces),):
            raise SurfaceError(f"regions label {self.regions.face_labels.shape} faces, the "
                               f"surface has {len(self.faces)}; rebuild the regions")

    @functools.cached_property
    def mesh(self) -> trimesh.Trimesh:
        """The triangle mesh (trimesh, built once, not processed: vertex order is kept)."""
        return trimesh.Trimesh(self.vertices, self.faces, process=False)

    @property
    def area(self) -> float:
        """Total surface area [m²]."""
        return float(self.vertex_areas.sum())

    def transformed(self, T_new_part: npt.ArrayLike) -> Surface:
        """A new Surface in another frame: `T_new_part` (4, 4) rigid, maps part to new coordinates.

        Positions, normals and principal directions are moved; curvature, uv and areas are rigid
        invariants and are kept.
        """
        T = check_pose(T_new_part, "surface transform", tol=1e-9, error=SurfaceError)
        R, t = T[:3, :3], T[:3, 3]
        regions = self.regions
        if regions is not None:
            regions = replace(regions, painted_direction=R @ regions.painted_direction)
        return replace(
            self,
            vertices=self.vertices @ R.T + t,
            normals=self.normals @ R.T,
            principal_directions=self.principal_directions @ R.T,
            regions=regions,
        )

    def judged_vertex_mask(self) -> np.ndarray | None:
        """(N,) True on vertices of the regions the film is judged on, or None (every vertex)."""
        if self.regions is None:
            return None
        return self.regions.vertex_mask(self.faces)

    def region_surface(self, names: tuple[str, ...] = ("skin",)) -> Surface:
        """The faces of the named regions as a Surface of their own (same name; curvature
        re-estimated on the submesh), e.g. the skin the planner covers. Without regions: self."""
        if self.regions is None:
            return self
        keep = self.regions.face_mask(names)
        if keep.all():
            return self
        if not keep.any():
            raise SurfaceError(f"surface {self.name!r} has no {'/'.join(names)} faces")
        used, inv = np.unique(self.faces[keep], return_inverse=True)
        sub = surface_from_triangles(self.name, self.vertices[used],
                                     inv.reshape(-1, 3).astype(np.int64))
        regs = replace(self.regions, face_labels=self.regions.face_labels[keep],
                       face_piece=self.regions.face_piece[keep])
        return replace(sub, regions=regs)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the surface to an `.npz` file atomically (exact round trip with `load`)."""
        arrays = {k: getattr(self, k) for k in _ARRAY_FIELDS}
        arrays["format"] = np.array(_FORMAT)
        arrays["name"] = np.array(self.name)
        if self.uv is not None:
            arrays["uv"] = self.uv
        if self.grid_shape is not None:
            arrays["grid_shape"] = np.array(self.grid_shape, dtype=np.int64)
        if self.regions is not None:
            arrays["region_labels"] = self.regions.face_labels
            arrays["region_piece"] = self.regions.face_piece
            arrays["region_direction"] = self.regions.painted_direction
            arrays["region_judged"] = np.array(self.regions.judged)
            arrays["region_pieces"] = np.array(json.dumps(list(self.regions.pieces)))
        atomic_write_npz(path, arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Surface:
        """Read a surface written by `save`."""
        path = Path(path)
        if not path.is_file():
            raise SurfaceError(f"surface file {path} does not exist; check the path")
        with np.load(path) as z:
            if "format" not in z or str(z["format"]) != _FORMAT:
                raise SurfaceError(f"{path} is not a paintcell surface file; write it with "
                                   "Surface.save")
            kw = {k: np.array(z[k]) for k in _ARRAY_FIELDS}
            uv = np.array(z["uv"]) if "uv" in z else None
            grid = tuple(int(x) for x in z["grid_shape"]) if "grid_shape" in z else None
            name = str(z["name"])
            regions = None
            if "region_labels" in z:  # openings are not stored: `paintcell inspect` finds them
                regions = PartRegions(face_labels=np.array(z["region_labels"]),
                                      face_piece=np.array(z["region_piece"]),
                                      painted_direction=np.array(z["region_direction"]),
                                      judged=tuple(str(x) for x in z["region_judged"]),
                                      pieces=tuple(json.loads(str(z["region_pieces"])))
                                      if "region_pieces" in z else ())
        return cls(name=name, uv=uv, grid_shape=grid, regions=regions, **kw)  # type: ignore[arg-type]

    @classmethod
    def from_mesh(cls, path_or_mesh: str | os.PathLike[str] | trimesh.Trimesh,
                  component: int | None = None, flip: bool = False,
                  name: str | None = None) -> Surface:
        """Read a triangle mesh (STL/OBJ/PLY path or a trimesh.Trimesh) into a Surface.

        Repairs duplicate vertices, duplicate faces, collapsed faces (repeated vertex) and
        inconsistent winding. Refuses (SurfaceError) an empty mesh, NaN/inf vertices, zero-area
        faces with three distinct vertices (slivers), non-manifold edges, and more than one
        connected component unless `component` picks one (0 = largest by face count).
        Normals face the painted side: outward for a closed mesh, for an open mesh the side the
        (area-weighted) majority of the input faces already faced; `flip` reverses it.
        Normals and curvature are estimated discretely
        (`paintcell.surface.curvature.discrete_curvature`):
        vertex normals are area-weighted face averages, except on the boundary, where that
        average is one-sided (it lags by about κ·h/2) and the normal is extrapolated from the
        interior with the shape operator instead.
        """
        vertices, faces, default_name = load_clean_mesh(path_or_mesh, component=component,
                                                        flip=flip)
        return surface_from_triangles(name or default_name, vertices, faces)


def vertex_areas_barycentric(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N,) a third of the area of every incident face [m²] (vertices (N,3) [m], faces (F,3))."""
    a = 0.5 * np.linalg.norm(np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]],
                                      vertices[faces[:, 2]] - vertices[faces[:, 0]]), axis=1)
    return np.bincount(faces.ravel(), weights=np.repeat(a / 3.0, 3), minlength=len(vertices))


def surface_from_triangles(name: str, vertices: np.ndarray, faces: np.ndarray) -> Surface:
    """Surface from a clean, consistently wound mesh, with discrete normal and curvature
    estimates (`paintcell.surface.curvature.discrete_curvature`)."""
    from paintcell.surface.curvature import discrete_curvature

    vertices = np.ascontiguousarray(vertices, dtype=float)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    c = discrete_curvature(vertices, faces)
    return Surface(
        name=name, vertices=vertices, faces=faces, normals=c.normals,
        vertex_areas=vertex_areas_barycentric(vertices, faces),
        gaussian_curvature=c.gaussian, mean_curvature=c.mean,
        principal_curvatures=c.principal, principal_directions=c.directions,
    )
