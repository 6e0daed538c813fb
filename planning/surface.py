"""Surfaces to paint: a triangle mesh in the part frame with normals and curvature per vertex.

Parametric constructors (`plane`, `cylinder`, `extruded`, `bspline_patch`) sample a regular
(u, v) grid and compute normals and curvature analytically from the first and second fundamental
forms. `Surface.from_mesh` reads STL/OBJ/PLY through trimesh, repairs what can be repaired, and
estimates normals and curvature discretely (`planning.curvature`, boundary normals extrapolated
from the interior).

Curvature sign (docs/interfaces.md): with the unit normal n pointing to the painted side, a
principal curvature k is positive when the surface bends away from n — dn = k dr along a principal
direction, so a sphere with outward normal has k1 = k2 = H = +1/R.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import numpy.typing as npt
import trimesh
from scipy.interpolate import BSpline, CubicSpline

from planning.atomic_io import atomic_write_npz
from planning.errors import SurfaceError
from planning.regions import PartRegions
from planning.transforms import check_pose

_FORMAT = "paintcell.Surface/1"
_ARRAY_FIELDS = ("vertices", "faces", "normals", "vertex_areas", "gaussian_curvature",
                 "mean_curvature", "principal_curvatures", "principal_directions")

# Parameter-space sampling used to measure arc length of a curve before resampling it [-].
_ARC_SAMPLES = 4001


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
        regions the film is judged on (`planning.regions.PartRegions`), or None (all skin).
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
                                      judged=tuple(str(x) for x in z["region_judged"]))
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
        Normals and curvature are estimated discretely (`planning.curvature.discrete_curvature`):
        vertex normals are area-weighted face averages, except on the boundary, where that
        average is one-sided (it lags by about κ·h/2) and the normal is extrapolated from the
        interior with the shape operator instead.
        """
        vertices, faces, default_name = load_clean_mesh(path_or_mesh, component=component,
                                                        flip=flip)
        return surface_from_triangles(name or default_name, vertices, faces)


# --- mesh input --------------------------------------------------------------------------------
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
                           "pass component=k (0 = largest) or keep one part in the file")
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


# --- shared construction helpers -------------------------------------------------------------
def vertex_areas_barycentric(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N,) a third of the area of every incident face [m²] (vertices (N,3) [m], faces (F,3))."""
    a = 0.5 * np.linalg.norm(np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]],
                                      vertices[faces[:, 2]] - vertices[faces[:, 0]]), axis=1)
    return np.bincount(faces.ravel(), weights=np.repeat(a / 3.0, 3), minlength=len(vertices))


def surface_from_triangles(name: str, vertices: np.ndarray, faces: np.ndarray) -> Surface:
    """Surface from a clean, consistently wound mesh, with discrete normal and curvature
    estimates (`planning.curvature.discrete_curvature`)."""
    from planning.curvature import discrete_curvature

    vertices = np.ascontiguousarray(vertices, dtype=float)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    c = discrete_curvature(vertices, faces)
    return Surface(
        name=name, vertices=vertices, faces=faces, normals=c.normals,
        vertex_areas=vertex_areas_barycentric(vertices, faces),
        gaussian_curvature=c.gaussian, mean_curvature=c.mean,
        principal_curvatures=c.principal, principal_directions=c.directions,
    )


def grid_faces(nu: int, nv: int) -> np.ndarray:
    """(2(nu-1)(nv-1), 3) triangles of a row-major grid, CCW seen from the side of r_u × r_v."""
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
    a = (i * nv + j).ravel()
    b, c, d = a + nv, a + nv + 1, a + 1
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int64)


def _n_samples(length_m: float, resolution_m: float) -> int:
    return max(2, int(np.ceil(length_m / resolution_m - 1e-9)) + 1)


def _check_resolution(resolution_m: float, *lengths: float) -> None:
    if not np.isfinite(resolution_m) or resolution_m <= 0:
        raise SurfaceError(f"resolution_m={resolution_m}; pass a positive grid spacing [m]")
    for length in lengths:
        if not np.isfinite(length) or length <= 0:
            raise SurfaceError(f"surface size {length} m is not positive; pass sizes > 0 [m]")
    if max(lengths) / resolution_m > 20000:
        raise SurfaceError(f"resolution_m={resolution_m} gives > 20000 samples a side; "
                           "use a coarser resolution")


def surface_from_grid(name: str, r: np.ndarray, r_u: np.ndarray, r_v: np.ndarray,
                      r_uu: np.ndarray, r_uv: np.ndarray, r_vv: np.ndarray,
                      uv: np.ndarray, flip: bool = False) -> Surface:
    """Surface from a sampled parametric patch and its derivatives (analytic curvature).

    r, r_u, r_v, r_uu, r_uv, r_vv: (nu, nv, 3) position [m] and partial derivatives.
    uv: (nu, nv, 2) parameters to store [m of arc length].
    flip: painted side is -(r_u × r_v) instead of +(r_u × r_v).
    """
    nu, nv = r.shape[:2]
    f = lambda a: a.reshape(nu * nv, 3)  # noqa: E731
    r, r_u, r_v, r_uu, r_uv, r_vv = map(f, (r, r_u, r_v, r_uu, r_uv, r_vv))
    cr = np.cross(r_u, r_v)
    norm = np.linalg.norm(cr, axis=1)
    if np.any(norm < 1e-12 * np.maximum(1.0, np.linalg.norm(r_u, axis=1) ** 2)):
        raise SurfaceError(f"patch {name!r} is singular (r_u x r_v = 0 somewhere); "
                           "move coincident control points apart")
    sign = -1.0 if flip else 1.0
    n = sign * cr / norm[:, None]
    E, F, G = (r_u * r_u).sum(1), (r_u * r_v).sum(1), (r_v * r_v).sum(1)
    # Second form with the project's sign (k > 0 bends away from n): II = -r_xy · n.
    L, M, N = -(r_uu * n).sum(1), -(r_uv * n).sum(1), -(r_vv * n).sum(1)
    det = E * G - F * F
    K = (L * N - M * M) / det
    H = (E * N - 2 * F * M + G * L) / (2 * det)
    disc = np.sqrt(np.maximum(H * H - K, 0.0))
    k1, k2 = H + disc, H - disc
    # Direction of k1 in (du, dv): a row of (II - k1 I) is orthogonal to it.
    d_a = np.stack([M - k1 * F, -(L - k1 * E)], 1)
    d_b = np.stack([N - k1 * G, -(M - k1 * F)], 1)
    use_b = (d_b * d_b).sum(1) > (d_a * d_a).sum(1)
    d = np.where(use_b[:, None], d_b, d_a)
    t1 = d[:, :1] * r_u + d[:, 1:] * r_v
    t1_norm = np.linalg.norm(t1, axis=1)
    umbilic = t1_norm <= 1e-9 * np.maximum(1.0, np.abs(k1)) * np.sqrt(E * G)
    t1 = np.where(umbilic[:, None], r_u, t1)
    t1 = t1 - (t1 * n).sum(1, keepdims=True) * n
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    faces = grid_faces(nu, nv)
    if flip:
        faces = faces[:, ::-1].copy()
    return Surface(
        name=name, vertices=np.ascontiguousarray(r), faces=faces, normals=n,
        vertex_areas=vertex_areas_barycentric(r, faces),
        gaussian_curvature=K, mean_curvature=H,
        principal_curvatures=np.stack([k1, k2], 1),
        principal_directions=np.stack([t1, t2], 1),
        uv=np.ascontiguousarray(uv.reshape(nu * nv, 2), dtype=float),
        grid_shape=(int(nu), int(nv)),
    )


# --- parametric constructors -----------------------------------------------------------------
def plane(width_m: float, length_m: float, resolution_m: float = 0.005,
          name: str = "plane") -> Surface:
    """Flat rectangle in z = 0 centred at the origin, painted side +z.

    width_m: extent along x [m] (u direction); length_m: extent along y [m] (v direction).
    resolution_m: grid spacing [m] (rounded so the edges are sampled exactly).
    uv = (x + width/2, y + length/2) [m].
    """
    _check_resolution(resolution_m, width_m, length_m)
    u = np.linspace(0.0, width_m, _n_samples(width_m, resolution_m))
    v = np.linspace(0.0, length_m, _n_samples(length_m, resolution_m))
    U, V = np.meshgrid(u, v, indexing="ij")
    r = np.stack([U - width_m / 2, V - length_m / 2, np.zeros_like(U)], -1)
    one, zero = np.ones_like(U), np.zeros_like(U)
    r_u = np.stack([one, zero, zero], -1)
    r_v = np.stack([zero, one, zero], -1)
    z3 = np.zeros_like(r)
    return surface_from_grid(name, r, r_u, r_v, z3, z3, z3, np.stack([U, V], -1))


def cylinder(radius_m: float, length_m: float, arc_rad: float, resolution_m: float = 0.005,
             name: str = "cylinder") -> Surface:
    """Convex cylinder sector, outside painted, axis along x at (y, z) = (0, -radius).

    The apex line (θ = 0) lies on the x axis at z = 0 with normal +z; θ ∈ [-arc/2, arc/2] turns
    toward ±y. radius_m [m], length_m along x [m], arc_rad opening angle [rad] (< 2π).
    uv = (x + length/2, radius·(θ + arc/2)) [m]. Analytic: K = 0, H = 1/(2R), k1 = 1/R around
    the arc, k2 = 0 along the axis.
    """
    _check_resolution(resolution_m, radius_m, length_m, radius_m * arc_rad)
    if arc_rad >= 2 * np.pi:
        raise SurfaceError(f"arc_rad={arc_rad} >= 2π would close the cylinder; pass < 2π")
    u = np.linspace(0.0, length_m, _n_samples(length_m, resolution_m))
    s = np.linspace(0.0, radius_m * arc_rad, _n_samples(radius_m * arc_rad, resolution_m))
    U, S = np.meshgrid(u, s, indexing="ij")
    th = S / radius_m - arc_rad / 2
    c, sn = np.cos(th), np.sin(th)
    zero, one = np.zeros_like(U), np.ones_like(U)
    r = np.stack([U - length_m / 2, radius_m * sn, radius_m * c - radius_m], -1)
    r_u = np.stack([one, zero, zero], -1)
    r_v = np.stack([zero, c, -sn], -1)
    r_vv = np.stack([zero, -sn, -c], -1) / radius_m
    z3 = np.zeros_like(r)
    return surface_from_grid(name, r, r_u, r_v, z3, z3, r_vv, np.stack([U, S], -1))


def extruded(profile_xy: npt.ArrayLike, length_m: float, resolution_m: float = 0.005,
             name: str = "extruded") -> Surface:
    """Sheet swept along x from a planar profile given in the part's (y, z) plane.

    profile_xy: (P, 2) profile points (y, z) [m], P >= 4, ordered along the profile; they are
        interpolated by a C² cubic spline (chord-length parameter) and resampled at equal arc
        length, so pass points dense enough to define the shape (~1 cm or finer).
    length_m: extrusion length along x [m], centred on x = 0.
    The painted side is the one whose normals point on average toward +z (the profile's left
    side when it runs toward +y). uv = (x + length/2, profile arc length) [m]; curvature is
    analytic from the spline: k1/k2 = profile curvature and 0, K = 0.
    """
    p = np.asarray(profile_xy, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 4 or not np.all(np.isfinite(p)):
        raise SurfaceError(f"profile has shape {p.shape}; pass (P >= 4, 2) finite (y, z) points")
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    if np.any(seg <= 1e-12):
        raise SurfaceError("profile has repeated consecutive points; remove duplicates")
    t = np.concatenate([[0.0], np.cumsum(seg)])
    spl = CubicSpline(t, p, bc_type="natural")
    # Arc length of the spline (trapezoid on a fine grid), then equal-arc-length parameters.
    tf = np.linspace(0.0, t[-1], max(_ARC_SAMPLES, 8 * len(p)))
    sf = np.concatenate([[0.0], np.cumsum(0.5 * (np.linalg.norm(spl(tf, 1), axis=1)[1:]
                                                 + np.linalg.norm(spl(tf, 1), axis=1)[:-1])
                                          * np.diff(tf))])
    arc = float(sf[-1])
    _check_resolution(resolution_m, length_m, arc)
    s = np.linspace(0.0, arc, _n_samples(arc, resolution_m))
    ts = np.interp(s, sf, tf)
    q, dq, ddq = spl(ts), spl(ts, 1), spl(ts, 2)
    u = np.linspace(0.0, length_m, _n_samples(length_m, resolution_m))
    nu, nv = len(u), len(s)
    x = np.broadcast_to((u - length_m / 2)[:, None], (nu, nv))
    zero = np.zeros((nu, nv))

    def lift(yz: np.ndarray, xval: np.ndarray | float) -> np.ndarray:
        return np.stack([np.broadcast_to(xval, (nu, nv)),
                         np.broadcast_to(yz[None, :, 0], (nu, nv)),
                         np.broadcast_to(yz[None, :, 1], (nu, nv))], -1)

    r = lift(q, x)
    r_u = np.stack([np.ones((nu, nv)), zero, zero], -1)
    r_v, r_vv = lift(dq, 0.0), lift(ddq, 0.0)
    z3 = np.zeros_like(r)
    # r_u × r_v = (0, -z', y'): flip when it points on average toward -z (weighted by |r_v|).
    flip = bool(np.sum(dq[:, 0] * np.gradient(s)) < 0)
    U, S = np.meshgrid(u, s, indexing="ij")
    return surface_from_grid(name, r, r_u, r_v, z3, z3, r_vv, np.stack([U, S], -1), flip=flip)


def _clamped_knots(n_ctrl: int, degree: int) -> np.ndarray:
    inner = np.linspace(0.0, 1.0, n_ctrl - degree + 1)
    return np.concatenate([np.zeros(degree), inner, np.ones(degree)])


def greville_abscissae(n_ctrl: int, degree: int = 3) -> np.ndarray:
    """(n_ctrl,) Greville parameters in [0, 1] of the clamped uniform knot vector of
    `bspline_patch`; control points placed at linear functions of them reproduce that function."""
    t = _clamped_knots(n_ctrl, degree)
    return np.array([t[i + 1:i + degree + 1].mean() for i in range(n_ctrl)])


def _basis(knots: np.ndarray, degree: int, n_ctrl: int, params: np.ndarray) -> list[np.ndarray]:
    """[B, B', B''] each (len(params), n_ctrl): basis functions and parameter derivatives."""
    spl = BSpline(knots, np.eye(n_ctrl), degree, extrapolate=False)
    out = [spl(params)]
    for k in (1, 2):
        out.append(spl.derivative(k)(params) if degree >= k else np.zeros_like(out[0]))
    return [np.nan_to_num(b) for b in out]


def _arc_length_params(knots: np.ndarray, degree: int, curve_ctrl: np.ndarray,
                       resolution_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Parameters in [0, 1] at equal arc length along the curve with control points (n, 3),
    and the arc lengths at them [m]."""
    tf = np.linspace(0.0, 1.0, _ARC_SAMPLES)
    _, d1, _ = _basis(knots, degree, len(curve_ctrl), tf)
    speed = np.linalg.norm(d1 @ curve_ctrl, axis=1)
    sf = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(tf))])
    if sf[-1] <= 0:
        raise SurfaceError("a B-spline iso-curve has zero length; spread the control points")
    s = np.linspace(0.0, sf[-1], _n_samples(float(sf[-1]), resolution_m))
    return np.interp(s, sf, tf), s


def bspline_patch(control_points: npt.ArrayLike, degree: int = 3, resolution_m: float = 0.005,
                  name: str = "bspline") -> Surface:
    """Tensor-product B-spline patch (clamped, uniform knots on [0, 1] in both directions).

    control_points: (nu, nv, 3) control net [m], nu, nv > degree; u runs along the first index.
    degree: polynomial degree in both directions (1..5).
    resolution_m: approximate grid spacing [m]: parameters are placed at equal arc length along
        the mid iso-curves, and uv stores those arc lengths [m].
    The painted side is r_u × r_v, flipped if it points on average toward -z.
    Normals, K, H, k1, k2 and principal directions are analytic (fundamental forms).
    """
    C = np.asarray(control_points, dtype=float)
    if C.ndim != 3 or C.shape[2] != 3 or not np.all(np.isfinite(C)):
        raise SurfaceError(f"control_points have shape {C.shape}; pass a finite (nu, nv, 3) net")
    if not 1 <= degree <= 5:
        raise SurfaceError(f"degree={degree}; pass a degree between 1 and 5")
    nu_c, nv_c = C.shape[:2]
    if nu_c <= degree or nv_c <= degree:
        raise SurfaceError(f"control net {nu_c}x{nv_c} is too small for degree {degree}; "
                           f"pass at least {degree + 1} points a side")
    if not np.isfinite(resolution_m) or resolution_m <= 0:
        raise SurfaceError(f"resolution_m={resolution_m}; pass a positive grid spacing [m]")
    tu, tv = _clamped_knots(nu_c, degree), _clamped_knots(nv_c, degree)
    # Mid iso-curves: v = 0.5 (varying u) and u = 0.5 (varying v), as control polygons.
    Bv_mid = _basis(tv, degree, nv_c, np.array([0.5]))[0][0]
    Bu_mid = _basis(tu, degree, nu_c, np.array([0.5]))[0][0]
    pu, su = _arc_length_params(tu, degree, np.einsum("ijk,j->ik", C, Bv_mid), resolution_m)
    pv, sv = _arc_length_params(tv, degree, np.einsum("ijk,i->jk", C, Bu_mid), resolution_m)
    _check_resolution(resolution_m, float(su[-1]), float(sv[-1]))
    Bu, Bu1, Bu2 = _basis(tu, degree, nu_c, pu)
    Bv, Bv1, Bv2 = _basis(tv, degree, nv_c, pv)
    ev = lambda A, B: np.einsum("ai,ijk,bj->abk", A, C, B, optimize=True)  # noqa: E731
    r, r_u, r_v = ev(Bu, Bv), ev(Bu1, Bv), ev(Bu, Bv1)
    r_uu, r_uv, r_vv = ev(Bu2, Bv), ev(Bu1, Bv1), ev(Bu, Bv2)
    flip = bool(np.cross(r_u, r_v)[..., 2].sum() < 0)
    U, V = np.meshgrid(su, sv, indexing="ij")
    return surface_from_grid(name, r, r_u, r_v, r_uu, r_uv, r_vv, np.stack([U, V], -1),
                             flip=flip)
