"""The film of a run as a 3-D file: `film.glb` (glTF 2.0 binary) for Blender, any glTF viewer and
the report's 3-D view (`paintcell.output.film_view`).

One scene, in metres:

- node `cell`: paintcell's world frame (z up) turned into glTF's y-up convention (glTF 2.0
  §3.4: +Y up, metres) by −90° about x, so every viewer shows the cell upright. Under it:
- node `part` (a booth: `body`), matrix `T_world_part` (a booth: the body at conveyor position 0):
  mesh `film`, the judged surface in the part (body) frame: POSITION, NORMAL (painted side),
  COLOR_0 = the executed film through the report's spec colour scale
  (`paintcell.output.report_film.spec_rgb`: blue below the spec window, green inside, red above),
  stored as linear RGB (float) as glTF requires of vertex colours, and `_THICKNESS_UM`, the
  executed film per vertex [µm] (an application attribute: the report's hover reads it; Blender
  imports it as a colour-free attribute). Unlit (`KHR_materials_unlit`), double-sided, so the
  colours are the scale's under any light.
- node `passes` (child of `part`): mesh `passes`, one LINE_STRIP primitive per planned pass, the
  TCP positions [m] in the part (body) frame, in execution order.
- one node `robot base NAME` per robot, matrix `T_world_base`: mesh `base marker`, a cone 0.3 m
  high along the base's +z.

The scene's `extras` hold the spec window [µm], the colour range [µm], the frame names and the
unit, so a reader need not guess them. Written with pygltflib, which writes each primitive's mode
(LINE_STRIP) and accessor type exactly as given.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pygltflib as gl

from paintcell.core.atomic_io import atomic_path
from paintcell.core.errors import PaintcellError
from paintcell.output.report_film import FilmData, spec_range_um, spec_rgb

__all__ = ["FILM_GLB_NAME", "FilmGlbError", "FilmScene", "film_glb_bytes", "run_film_scene",
           "srgb_to_linear", "write_film_files", "write_film_glb"]

FILM_GLB_NAME = "film.glb"
#: glTF is y-up (§3.4); paintcell's world is z-up: −90° about x, as an (x, y, z, w) quaternion.
Q_GLTF_WORLD = (-np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5))
# Base marker: a cone this high [m] and this wide at its foot [m] — visible at cell scale (a
# robot stands ~1–2 m from the part) without hiding the part.
_MARKER_HEIGHT_M = 0.3
_MARKER_RADIUS_M = 0.12
# sRGB colours: passes near-black, base markers orange
_PASS_RGBA = (0.1, 0.1, 0.1, 1.0)
_MARKER_RGBA = (0.95, 0.5, 0.05, 1.0)


class FilmGlbError(PaintcellError):
    """The film scene cannot be written (shapes that do not agree, an empty part)."""


@dataclass(frozen=True, eq=False)
class FilmScene:
    """What `film.glb` shows.

    vertices_m: (N, 3) surface vertices in the part (body) frame [m]; faces: (F, 3) int;
    normals: (N, 3) unit painted-side normals; film: the executed film per vertex and its spec
    window (`FilmData`, N vertices); passes_m: one (M, 3) array of TCP positions [m] per pass, in
    the part frame; T_world_part: (4, 4) the part (body) placement in the world; bases: robot
    name → (4, 4) T_world_base; frame: what the part frame is ("part" or "body").
    """

    vertices_m: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    film: FilmData
    passes_m: Sequence[np.ndarray]
    T_world_part: np.ndarray
    bases: Mapping[str, np.ndarray]
    frame: str = "part"

    def __post_init__(self) -> None:
        n = len(self.vertices_m)
        if self.vertices_m.shape != (n, 3) or n < 3:
            raise FilmGlbError(f"the film mesh needs (N, 3) vertices, got {self.vertices_m.shape}")
        if self.normals.shape != (n, 3) or len(self.film.executed_m) != n:
            raise FilmGlbError(f"normals {self.normals.shape} and film "
                               f"({len(self.film.executed_m)},) must have one row per vertex "
                               f"({n})")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3 or len(self.faces) == 0 \
                or self.faces.min() < 0 or self.faces.max() >= n:
            raise FilmGlbError(f"faces must be a non-empty (F, 3) array indexing 0..{n - 1}")
        if any(np.asarray(p).ndim != 2 or np.asarray(p).shape[1] != 3 for p in self.passes_m):
            raise FilmGlbError("each pass must be an (M, 3) array of positions [m]")


def srgb_to_linear(rgb: npt.ArrayLike) -> np.ndarray:
    """sRGB colour components in [0, 1] → linear (IEC 61966-2-1, the transfer glTF's COLOR_0
    is defined against)."""
    c = np.asarray(rgb, float)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


class _Blob:
    """The one binary buffer of a GLB and the accessors into it."""

    def __init__(self, doc: gl.GLTF2) -> None:
        self.doc = doc
        self.data = bytearray()

    def add(self, a: np.ndarray, kind: str, target: int | None = None,
            bounds: bool = False) -> int:
        """Append array `a` (float32 or uint32) as a buffer view + accessor; return its index."""
        self.data.extend(b"\0" * (-len(self.data) % 4))  # 4-byte alignment (§3.6.2.4)
        raw = np.ascontiguousarray(a).tobytes()
        self.doc.bufferViews.append(gl.BufferView(buffer=0, byteOffset=len(self.data),
                                                  byteLength=len(raw), target=target))
        self.data.extend(raw)
        ctype = gl.FLOAT if a.dtype == np.float32 else gl.UNSIGNED_INT
        acc = gl.Accessor(bufferView=len(self.doc.bufferViews) - 1, componentType=ctype,
                          count=len(a), type=kind)
        if bounds:  # POSITION accessors must carry min/max (§3.7.2.1)
            acc.min = a.min(axis=0).astype(float).tolist()
            acc.max = a.max(axis=0).astype(float).tolist()
        self.doc.accessors.append(acc)
        return len(self.doc.accessors) - 1


def _material(doc: gl.GLTF2, name: str, rgba: Sequence[float]) -> int:
    """An unlit, double-sided material of sRGB colour `rgba` (stored linear, as glTF wants)."""
    linear = [*srgb_to_linear(rgba[:3]).tolist(), float(rgba[3])]
    doc.materials.append(gl.Material(
        name=name, doubleSided=True,
        pbrMetallicRoughness=gl.PbrMetallicRoughness(baseColorFactor=linear,
                                                     metallicFactor=0.0, roughnessFactor=1.0),
        extensions={"KHR_materials_unlit": {}}))
    return len(doc.materials) - 1


def _cone(height_m: float, radius_m: float, n: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n + 2, 3) [m], faces (2n, 3)) of a closed cone on z = 0 with apex on +z."""
    a = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    rim = np.column_stack([radius_m * np.cos(a), radius_m * np.sin(a), np.zeros(n)])
    v = np.vstack([rim, [0.0, 0.0, height_m], [0.0, 0.0, 0.0]])
    i = np.arange(n)
    j = (i + 1) % n
    side = np.column_stack([i, j, np.full(n, n)])
    foot = np.column_stack([j, i, np.full(n, n + 1)])
    return v, np.vstack([side, foot])


def _matrix(T: npt.ArrayLike) -> list[float]:
    """A 4×4 transform as glTF's column-major list."""
    return np.asarray(T, float).reshape(4, 4).T.reshape(-1).tolist()


def film_glb_bytes(scene: FilmScene) -> bytes:
    """The GLB bytes of `scene` (module doc)."""
    film = scene.film
    target_um = 1e6 * film.target_m
    colours = srgb_to_linear(spec_rgb(film.executed_m, target_um, film.tolerance))
    doc = gl.GLTF2(asset=gl.Asset(generator="paintcell", version="2.0"),
                   extensionsUsed=["KHR_materials_unlit"])
    blob = _Blob(doc)
    attrs = gl.Attributes(
        POSITION=blob.add(scene.vertices_m.astype(np.float32), gl.VEC3, gl.ARRAY_BUFFER, True),
        NORMAL=blob.add(scene.normals.astype(np.float32), gl.VEC3, gl.ARRAY_BUFFER),
        COLOR_0=blob.add(colours.astype(np.float32), gl.VEC3, gl.ARRAY_BUFFER),
        # application attributes start with "_" (glTF 2.0 §3.7.2.1)
        _THICKNESS_UM=blob.add((1e6 * film.executed_m).astype(np.float32), gl.SCALAR,
                               gl.ARRAY_BUFFER))
    faces = blob.add(scene.faces.astype(np.uint32).reshape(-1), gl.SCALAR,
                     gl.ELEMENT_ARRAY_BUFFER)
    film_mat = _material(doc, "film", (1.0, 1.0, 1.0, 1.0))
    doc.meshes.append(gl.Mesh(name="film", primitives=[gl.Primitive(
        attributes=attrs, indices=faces, material=film_mat, mode=gl.TRIANGLES)]))

    pass_mat = _material(doc, "passes", _PASS_RGBA)
    strips = [gl.Primitive(attributes=gl.Attributes(POSITION=blob.add(
        np.asarray(p, np.float32), gl.VEC3, gl.ARRAY_BUFFER, True)), material=pass_mat,
        mode=gl.LINE_STRIP) for p in scene.passes_m if len(p) >= 2]
    nodes = [gl.Node(name="cell", rotation=list(Q_GLTF_WORLD), children=[1]),
             gl.Node(name=scene.frame, matrix=_matrix(scene.T_world_part), mesh=0, children=[])]
    if strips:
        doc.meshes.append(gl.Mesh(name="passes", primitives=strips))
        nodes[1].children.append(len(nodes))
        nodes.append(gl.Node(name="passes", mesh=len(doc.meshes) - 1))

    if scene.bases:
        cv, cf = _cone(_MARKER_HEIGHT_M, _MARKER_RADIUS_M)
        doc.meshes.append(gl.Mesh(name="base marker", primitives=[gl.Primitive(
            attributes=gl.Attributes(POSITION=blob.add(cv.astype(np.float32), gl.VEC3,
                                                       gl.ARRAY_BUFFER, True)),
            indices=blob.add(cf.astype(np.uint32).reshape(-1), gl.SCALAR,
                             gl.ELEMENT_ARRAY_BUFFER),
            material=_material(doc, "robot base", _MARKER_RGBA), mode=gl.TRIANGLES)]))
        for name, T in scene.bases.items():
            nodes[0].children.append(len(nodes))
            nodes.append(gl.Node(name=f"robot base {name}", matrix=_matrix(T),
                                 mesh=len(doc.meshes) - 1, extras={"robot": name}))
    doc.nodes = nodes
    lo, hi = (1e6 * x for x in film.window_m)
    doc.scenes = [gl.Scene(name="film", nodes=[0], extras={
        "unit": "m", "frames": f"world z-up under node 'cell'; film and passes in the "
                               f"{scene.frame} frame",
        "film": "executed", "spec_window_um": [lo, hi],
        "colour_range_um": list(spec_range_um(target_um, film.tolerance)),
        "colour_scale": "blue below the spec window, green inside, red above",
        "passes": len(strips), "robots": list(scene.bases)})]
    doc.scene = 0
    doc.buffers = [gl.Buffer(byteLength=len(blob.data))]
    doc.set_binary_blob(bytes(blob.data))
    return b"".join(doc.save_to_bytes())


def run_film_scene(surface: Any, film: FilmData, plan: Any, T_world_part: npt.ArrayLike,
                   robot: str, T_world_base: npt.ArrayLike) -> FilmScene:
    """The `FilmScene` of a one-robot run: `surface` (part frame), its `film`, the `plan`'s
    passes (TCP positions), the part placement and robot `robot`'s base placement (4, 4)."""
    return FilmScene(np.asarray(surface.vertices, float), np.asarray(surface.faces, np.int64),
                     np.asarray(surface.normals, float), film,
                     [np.asarray(p.positions, float) for p in plan.passes],
                     np.asarray(T_world_part, float), {robot: np.asarray(T_world_base, float)})


def write_film_glb(path: str | os.PathLike[str], scene: FilmScene) -> Path:
    """Write `film.glb` of `scene` atomically; return its path."""
    data = film_glb_bytes(scene)
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return path


def write_film_files(out: str | os.PathLike[str], film: FilmData, scene: FilmScene
                     ) -> list[str]:
    """Write a run's film into results folder `out` — `film.npz` (the arrays and the spec window,
    `paintcell.output.report_film`) and `film.glb` (`scene` in 3-D) — for a cell of one robot
    or several; return the names written."""
    from paintcell.output.report_film import FILM_NAME, save_film_data

    save_film_data(Path(out) / FILM_NAME, film)
    write_film_glb(Path(out) / FILM_GLB_NAME, scene)
    return [FILM_NAME, FILM_GLB_NAME]
