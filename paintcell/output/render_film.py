"""A film thickness map as a textured MuJoCo mesh: per-vertex colours from a colour-map strip.

The film is an extra mesh geom, the part's triangles in the world frame lifted `offset_m` along
the painted-side normals (no z-fighting with the part geom). Its texture is a colour-map strip
(256 texels) and each vertex's texture coordinate is its normalized thickness, so the GPU
interpolates thickness linearly across every triangle and looks the colour up — a true
per-vertex colour map on any mesh, with or without (u, v). Thickness range `[vmin_um, vmax_um]`
is fixed by the caller so planned and executed renders share one scale. MuJoCo culls back faces:
cameras must look at the painted side.

Units: positions [m], thickness [m] inside and [µm] in colour ranges.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from paintcell.output.render_backend import RenderError
from paintcell.output.render_cameras import pose_or_identity

# Colour-map strip [texels]: 224 levels (finer than the eye separates on a render) padded with
# 16 texels of each end colour, so that mipmaps (down to 1/16) and wrap-around filtering never
# blend the thin-coat and thick-coat ends on small or steep triangles.
_STRIP = 256
_PAD = 16
_LEVELS = _STRIP - 2 * _PAD
# Film lift above the part surface [m]: 0.5 mm clears depth-buffer precision at cell scale.
FILM_OFFSET_M = 5e-4
DEFAULT_CMAP = "viridis"


@dataclass(frozen=True, eq=False)
class Film:
    """A film thickness map on a triangle mesh, world frame, ready to draw.

    vertices_world: (N, 3) [m]; faces: (F, 3) int, counter-clockwise from the painted side;
    normals_world: (N, 3) unit painted-side normals; thickness_m: (N,) [m] (NaN drawn as vmin);
    vmin_um, vmax_um: colour range [µm] (values outside are clamped); cmap: matplotlib name.
    """

    vertices_world: np.ndarray
    faces: np.ndarray
    normals_world: np.ndarray
    thickness_m: np.ndarray
    vmin_um: float
    vmax_um: float
    cmap: str = DEFAULT_CMAP

    def __post_init__(self) -> None:
        n = len(self.vertices_world)
        if self.vertices_world.shape != (n, 3) or n < 4:
            raise RenderError(f"film needs (N, 3) vertices with N ≥ 4, got "
                              f"{self.vertices_world.shape}")
        if self.thickness_m.shape != (n,):
            raise RenderError(f"thickness has shape {self.thickness_m.shape}, expected ({n},): "
                              "one value [m] per surface vertex")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3 or len(self.faces) == 0:
            raise RenderError("film faces must be a non-empty (F, 3) integer array")
        if self.faces.min() < 0 or self.faces.max() >= n:
            raise RenderError(f"film faces index outside 0..{n - 1}")
        if not (np.isfinite(self.vmin_um) and np.isfinite(self.vmax_um)
                and self.vmax_um > self.vmin_um):
            raise RenderError(f"thickness colour range [{self.vmin_um}, {self.vmax_um}] µm is "
                              "empty: pass vmax_um > vmin_um")

    def texcoords(self) -> np.ndarray:
        """(N, 2) texture coordinates: u = normalized thickness at texel centres, v = 0.5."""
        t_um = np.nan_to_num(self.thickness_m * 1e6, nan=self.vmin_um)
        s = np.clip((t_um - self.vmin_um) / (self.vmax_um - self.vmin_um), 0.0, 1.0)
        # Texel centres inside the padded strip (see _PAD).
        u = (_PAD + 0.5 + s * (_LEVELS - 1)) / _STRIP
        return np.column_stack([u, np.full_like(u, 0.5)])


def film_from_surface(surface: Any, thickness_m: npt.ArrayLike, vmin_um: float, vmax_um: float,
                      T_world_part: npt.ArrayLike | None = None,
                      cmap: str = DEFAULT_CMAP) -> Film:
    """`Film` of a `Surface` (part frame) placed at `T_world_part` (4, 4).

    thickness_m: (N,) film thickness per surface vertex [m]; vmin_um/vmax_um: colour range [µm].
    """
    T = pose_or_identity(T_world_part)
    R = T[:3, :3]
    return Film(
        vertices_world=np.asarray(surface.vertices, float) @ R.T + T[:3, 3],
        faces=np.asarray(surface.faces, np.int64),
        normals_world=np.asarray(surface.normals, float) @ R.T,
        thickness_m=np.asarray(thickness_m, float).reshape(-1),
        vmin_um=float(vmin_um), vmax_um=float(vmax_um), cmap=cmap)


def colormap_rgb(cmap: str, n: int = _LEVELS) -> np.ndarray:
    """(n, 3) uint8 colours of a matplotlib colormap from its low to its high end."""
    from matplotlib import colormaps

    try:
        cm = colormaps[cmap]
    except KeyError as e:
        raise RenderError(f"unknown colormap {cmap!r}: use a matplotlib name like "
                          "'viridis' or 'turbo'") from e
    return np.round(cm(np.linspace(0.0, 1.0, n))[:, :3] * 255).astype(np.uint8)


def add_film(spec: mujoco.MjSpec, film: Film, name: str = "film",
             offset_m: float = FILM_OFFSET_M) -> None:
    """Add `film` to `spec` as a textured, non-colliding mesh geom in the world body."""
    tex = spec.add_texture(name=f"{name}_cmap", type=mujoco.mjtTexture.mjTEXTURE_2D,
                           width=_STRIP, height=1, nchannel=3)
    levels = colormap_rgb(film.cmap, _LEVELS)
    strip = np.concatenate([np.repeat(levels[:1], _PAD, 0), levels,
                            np.repeat(levels[-1:], _PAD, 0)])
    tex.data = np.ascontiguousarray(strip).tobytes()
    mat = spec.add_material(name=f"{name}_mat")
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"{name}_cmap"
    # Part emission keeps colours close to the legend under any light; the rest shades shape.
    mat.emission = 0.45
    mat.specular = 0.1
    mat.shininess = 0.1
    mesh = spec.add_mesh(name=f"{name}_mesh")
    verts = film.vertices_world + offset_m * film.normals_world
    faces = np.ascontiguousarray(film.faces, np.int32)
    mesh.uservert = verts.ravel().tolist()
    mesh.userface = faces.ravel().tolist()
    mesh.usertexcoord = film.texcoords().ravel().tolist()
    mesh.userfacetexcoord = faces.ravel().tolist()
    # Open surfaces have no volume: shell inertia; no collision so no convex hull is needed.
    mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"{name}_mesh",
                            material=f"{name}_mat", contype=0, conaffinity=0, group=0)
