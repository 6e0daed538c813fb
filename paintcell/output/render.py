"""Offscreen MuJoCo renders of the paint cell: film thickness as a colour map, robot poses, videos.

The module holds the offscreen GL backend and the errors of rendering, free cameras, the film
colour map as a textured mesh, the compiled scene and its renderer, image and video files with
the thickness legend, and the one-call entry points.

Units: positions [m], thickness [m] inside and [µm] in colour ranges and legends, angles [deg]
for MuJoCo's free camera (azimuth, elevation), image sizes in pixels (width, height).
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import mujoco
import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw, ImageFont

from paintcell.core.atomic_io import atomic_path
from paintcell.core.errors import PaintcellError, one_line
from paintcell.execution.cell import Cell

__all__ = [
    "BACKENDS", "DEFAULT_CMAP", "FILM_OFFSET_M", "CameraView", "Film", "RenderBackendError",
    "RenderError", "SceneRenderer", "add_colorbar", "add_film", "backend_name", "booth_spec",
    "camera_presets", "colormap_rgb", "film_from_surface", "frame_indices", "look_from",
    "part_cameras", "probe_backend", "render_execution_video", "render_frames",
    "render_robot_at", "render_thickness", "robot_qpos_adr", "write_png", "write_video",
]


# Probe order when MUJOCO_GL is unset: EGL serves GPUs and Mesa's software rasterizer alike.
BACKENDS = ("egl", "osmesa")
_INSTALL_HINT = ("install libosmesa6 (apt-get install -y libosmesa6) or libegl1 "
                 "(apt-get install -y libegl1), or set MUJOCO_GL=egl|osmesa")

_backend: str | None = None


class RenderError(PaintcellError):
    """A render cannot be made (bad camera, bad sizes, bad thickness array, ...)."""


class RenderBackendError(RenderError):
    """No offscreen OpenGL backend works on this machine."""


_PROBE_CODE = (
    "import mujoco\n"
    "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><light pos=\"0 0 2\"/>"
    "<geom size=\"0.1\"/></worldbody></mujoco>')\n"
    "r = mujoco.Renderer(m, 8, 8)\n"
    "d = mujoco.MjData(m)\n"
    "mujoco.mj_forward(m, d)\n"
    "r.update_scene(d)\n"
    "r.render()\n"
    "r.close()\n"
)


def probe_backend(name: str, timeout_s: float = 120.0) -> str | None:
    """Try to render an 8×8 frame with `MUJOCO_GL=name` in a subprocess.

    Returns None when it works, else the last line of the error (one line).
    """
    env = dict(os.environ, MUJOCO_GL=name, PYOPENGL_PLATFORM=name)
    try:
        res = subprocess.run([sys.executable, "-c", _PROBE_CODE], env=env, capture_output=True,
                             text=True, timeout=timeout_s, check=False)
    except subprocess.TimeoutExpired:
        return f"probe timed out after {timeout_s:.0f} s"
    if res.returncode == 0:
        return None
    lines = [ln for ln in (res.stderr or res.stdout).strip().splitlines() if ln.strip()]
    return lines[-1].strip() if lines else f"exit status {res.returncode}"


def _install_backend(name: str) -> None:
    """Make `name` the GL backend of this process (and of its children)."""
    os.environ["MUJOCO_GL"] = name
    if name in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", name)
    from mujoco.rendering.classic import gl_context as glc

    if getattr(glc, "_MUJOCO_GL", None) == name:
        return  # mujoco was imported with this backend already
    try:
        if name == "egl":
            from mujoco.egl import GLContext
        elif name == "osmesa":
            from mujoco.osmesa import GLContext
        elif name in ("glfw", "glx"):
            from mujoco.glfw import GLContext
        else:
            raise RenderBackendError(f"unknown MUJOCO_GL={name!r}: use egl or osmesa")
    except (ImportError, OSError, RuntimeError) as e:
        raise RenderBackendError(f"MUJOCO_GL={name} cannot be loaded ({one_line(e, 200)}): "
                                 f"{_INSTALL_HINT}") from e
    glc.GLContext = GLContext  # type: ignore[attr-defined]


def backend_name() -> str:
    """Name of the offscreen GL backend in use ("egl", "osmesa", ...); chooses it on first call.

    Raises RenderBackendError (one line, naming the package to install) when none works.
    """
    global _backend
    if _backend is not None:
        return _backend
    explicit = os.environ.get("MUJOCO_GL", "").strip().lower()
    if explicit:
        _install_backend(explicit)
        _backend = explicit
        return explicit
    errors = []
    for name in BACKENDS:
        err = probe_backend(name)
        if err is None:
            _install_backend(name)
            _backend = name
            return name
        errors.append(f"{name}: {err}")
    raise RenderBackendError(f"no offscreen OpenGL backend ({'; '.join(errors)}): {_INSTALL_HINT}")


def make_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """A MuJoCo offscreen renderer of `width` × `height` pixels, or a RenderBackendError naming
    the GL backend and how to install one."""
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as e:  # any GL failure: the backend is unusable
        raise RenderBackendError(f"offscreen renderer with MUJOCO_GL={backend_name()} failed "
                                 f"({one_line(e, 200)}): {_INSTALL_HINT}") from e


@dataclass(frozen=True)
class CameraView:
    """A free camera: looks at `lookat` from `distance_m` along (azimuth, elevation).

    lookat: (3,) world point [m]; distance_m: [m]; azimuth_deg, elevation_deg: MuJoCo free-camera
    angles [deg] (view direction = (cos el cos az, cos el sin az, sin el); el < 0 looks down).
    """

    name: str
    lookat: tuple[float, float, float]
    distance_m: float
    azimuth_deg: float
    elevation_deg: float

    def to_mjv(self) -> mujoco.MjvCamera:
        """The equivalent `mujoco.MjvCamera` (type free)."""
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat
        cam.distance = self.distance_m
        cam.azimuth = self.azimuth_deg
        cam.elevation = self.elevation_deg
        return cam


def look_from(name: str, lookat: npt.ArrayLike, view_dir: npt.ArrayLike,
              distance_m: float) -> CameraView:
    """Camera at `lookat - distance_m · view_dir` looking along `view_dir` (3,) (any length)."""
    d = np.asarray(view_dir, float)
    n = np.linalg.norm(d)
    if not np.isfinite(n) or n < 1e-12:
        raise RenderError(f"camera {name!r}: view direction {d} is zero or not finite")
    d = d / n
    # Straight down/up is a gimbal pole for azimuth: stay 0.1° off it.
    el = float(np.degrees(np.arcsin(np.clip(d[2], -1.0, 1.0))))
    el = float(np.clip(el, -89.9, 89.9))
    az = float(np.degrees(np.arctan2(d[1], d[0]))) if np.hypot(d[0], d[1]) > 1e-9 else 90.0
    c = np.asarray(lookat, float)
    return CameraView(name, (float(c[0]), float(c[1]), float(c[2])), float(distance_m), az, el)


def camera_presets(vertices_world: npt.ArrayLike, normal_world: npt.ArrayLike,
                   pass_dir_world: npt.ArrayLike | None = None, fovy_deg: float = 45.0,
                   margin: float = 1.15) -> dict[str, CameraView]:
    """Camera presets framing a part: "front", "top", "along_passes" (and "oblique").

    vertices_world: (N, 3) part vertices [m]; normal_world: (3,) mean painted-side normal;
    pass_dir_world: (3,) travel direction of the passes (default: the bounding box's long axis);
    fovy_deg: vertical field of view [deg] (MuJoCo's default 45°); margin: framing slack (≥ 1).
    Distances make the bounding sphere fit the vertical field of view.
    """
    v = np.asarray(vertices_world, float)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0 or not np.all(np.isfinite(v)):
        raise RenderError("camera presets need finite (N, 3) vertices [m]")
    lo, hi = v.min(0), v.max(0)
    center = 0.5 * (lo + hi)
    radius = max(float(np.linalg.norm(v - center, axis=1).max()), 1e-3)
    dist = margin * radius / np.sin(np.radians(fovy_deg) / 2.0)
    n = np.asarray(normal_world, float)
    n = n / max(np.linalg.norm(n), 1e-12)
    if pass_dir_world is None:
        # Long axis of the vertex cloud, projected into the tangent plane of the mean normal.
        _, _, vt = np.linalg.svd(v - v.mean(0), full_matrices=False)
        t = vt[0]
    else:
        t = np.asarray(pass_dir_world, float)
    t = t - np.dot(t, n) * n
    if np.linalg.norm(t) < 1e-9:
        t = np.cross(n, [1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.cross(n, [0.0, 1.0, 0.0])
    t = t / np.linalg.norm(t)
    side = np.cross(n, t)
    # "along_passes": behind the start of a pass, 35° above the surface, looking along travel.
    tilt = np.radians(35.0)
    return {
        "front": look_from("front", center, -n, dist),
        "top": look_from("top", center, [0.0, 0.0, -1.0], dist),
        "along_passes": look_from("along_passes", center, np.cos(tilt) * t - np.sin(tilt) * n,
                                  dist),
        "oblique": look_from("oblique", center, -n + 0.6 * side - 0.3 * t, dist),
    }


def part_cameras(surface: Any, T_world_part: npt.ArrayLike | None = None,
                 travel_dir_part: npt.ArrayLike | None = None,
                 fovy_deg: float = 45.0) -> dict[str, CameraView]:
    """`camera_presets` for a `paintcell.surface.analytic.Surface` placed at `T_world_part`
    (4, 4).

    travel_dir_part: (3,) pass travel direction in the part frame (e.g. the mean of a plan
    pass's `travel_dirs`), or None for the part's long axis.
    """
    T = pose_or_identity(T_world_part)
    verts = np.asarray(surface.vertices, float) @ T[:3, :3].T + T[:3, 3]
    areas = getattr(surface, "vertex_areas", None)
    normals = np.asarray(surface.normals, float)
    w = np.ones(len(normals)) if areas is None else np.asarray(areas, float)
    n_world = T[:3, :3] @ (w[:, None] * normals).sum(0)
    t_world = None if travel_dir_part is None else T[:3, :3] @ np.asarray(travel_dir_part, float)
    return camera_presets(verts, n_world, t_world, fovy_deg=fovy_deg)


def pose_or_identity(T: npt.ArrayLike | None) -> np.ndarray:
    """A checked finite (4, 4) pose, the identity for None (RenderError otherwise)."""
    if T is None:
        return np.eye(4)
    T = np.asarray(T, float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise RenderError(f"a pose must be a finite (4, 4) matrix, got shape {T.shape}")
    return T


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


def _check_image(image: npt.ArrayLike) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] not in (3, 4) or img.size == 0:
        raise RenderError(f"image must be (H, W, 3|4), got shape {img.shape}")
    if img.dtype != np.uint8:
        raise RenderError(f"image must be uint8, got {img.dtype}")
    return img


def write_png(path: str | os.PathLike[str], image: npt.ArrayLike) -> Path:
    """Write an (H, W, 3|4) uint8 image as PNG atomically; returns the path."""
    img = _check_image(image)
    path = Path(path)
    with atomic_path(path) as tmp:
        Image.fromarray(img).save(tmp, format="PNG")
    return path


def write_video(path: str | os.PathLike[str], frames: Sequence[np.ndarray] | Iterable[np.ndarray],
                fps: float = 10.0) -> Path:
    """Write frames ((H, W, 3) uint8 each) at `fps` [1/s] as `.gif` (Pillow) or `.mp4`
    (needs imageio + imageio-ffmpeg); atomic; returns the path."""
    frames = [_check_image(f)[:, :, :3] for f in frames]
    if not frames:
        raise RenderError("a video needs at least one frame")
    if fps <= 0:
        raise RenderError(f"fps must be > 0, got {fps}")
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".gif":
        # One palette for the whole clip, from a montage of up to 8 frames: 10× faster than a
        # palette per frame, and no colour flicker between frames.
        sample = frames[::max(1, len(frames) // 8)][:8]
        pal = Image.fromarray(np.concatenate(sample, axis=0)).quantize(
            colors=255, method=Image.Quantize.MEDIANCUT)
        pil = [Image.fromarray(f).quantize(palette=pal, dither=Image.Dither.NONE)
               for f in frames]
        with atomic_path(path) as tmp:
            pil[0].save(tmp, format="GIF", save_all=True, append_images=pil[1:],
                        duration=max(int(round(1000.0 / fps)), 20), loop=0, optimize=False)
        return path
    if suffix == ".mp4":
        try:
            import imageio.v2 as imageio  # type: ignore[import-not-found]
        except ImportError as e:
            raise RenderError("MP4 needs imageio and imageio-ffmpeg (pip install imageio "
                              "imageio-ffmpeg); or write a .gif") from e
        with atomic_path(path) as tmp:
            imageio.mimsave(tmp, cast(Any, frames), fps=fps, macro_block_size=1)
        return path
    raise RenderError(f"unknown video format {path.suffix!r}: use .gif or .mp4")


def _font(size_px: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    """DejaVu Sans from matplotlib (has the µ glyph), else Pillow's default font."""
    from matplotlib import get_data_path

    ttf = Path(get_data_path()) / "fonts" / "ttf" / "DejaVuSans.ttf"
    try:
        return ImageFont.truetype(str(ttf), size_px)
    except OSError:
        return ImageFont.load_default(size_px)


def add_colorbar(image: npt.ArrayLike, vmin_um: float, vmax_um: float,
                 cmap: str = DEFAULT_CMAP) -> np.ndarray:
    """Return a copy of `image` (H, W, 3) with a film-thickness legend [µm] drawn over its right
    edge (same size as the input)."""
    img = _check_image(image)[:, :, :3]
    h, w = img.shape[:2]
    font = _font(max(h // 32, 8))
    bar_w, pad = max(w // 48, 5), max(w // 100, 2)
    labels = [f"{v:.3g}" for v in (vmin_um, 0.5 * (vmin_um + vmax_um), vmax_um)]
    text_w = int(max(font.getlength(t) for t in labels + ["[µm]"]))
    panel_w = min(bar_w + text_w + 4 * pad, w // 3)
    out = Image.fromarray(np.ascontiguousarray(img))
    draw = ImageDraw.Draw(out)
    x0 = w - panel_w
    draw.rectangle([x0, 0, w - 1, h - 1], fill=(255, 255, 255))
    top, bottom = int(0.12 * h), int(0.9 * h)
    colours = colormap_rgb(cmap, max(bottom - top, 2))[::-1]  # high values on top
    strip = np.repeat(colours[:, None, :], bar_w, axis=1)
    out.paste(Image.fromarray(np.ascontiguousarray(strip)), (x0 + pad, top))
    for frac, text in zip((0.0, 0.5, 1.0), labels, strict=True):
        y = int(bottom - frac * (bottom - top))
        draw.line([(x0 + pad + bar_w, y), (x0 + 2 * pad + bar_w, y)], fill=(0, 0, 0))
        draw.text((x0 + 2 * pad + bar_w, y), text, fill=(0, 0, 0), font=font, anchor="lm")
    draw.text((x0 + panel_w // 2, top // 2), "[µm]", fill=(0, 0, 0), font=font, anchor="mm")
    return np.asarray(out)


def booth_spec(extent_m: float = 3.0, floor_z_m: float = -1.0) -> mujoco.MjSpec:
    """A bare booth: grey floor at `floor_z_m` [m], key and fill lights, no robot.

    extent_m: half size of the floor and height of the key light [m].
    """
    spec = mujoco.MjSpec()
    spec.modelname = "booth"
    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.5, 0.5, 0.5]
    sky = spec.add_texture(name="booth_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                           builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.93, 0.94, 0.96],
                           rgb2=[0.72, 0.75, 0.8], width=64, height=64)
    del sky  # a skybox texture needs no material: MuJoCo draws it as the background
    spec.worldbody.add_geom(name="booth_floor", type=mujoco.mjtGeom.mjGEOM_PLANE,
                            size=[extent_m, extent_m, 0.05], pos=[0.0, 0.0, floor_z_m],
                            rgba=[0.55, 0.57, 0.6, 1.0], contype=0, conaffinity=0)
    spec.worldbody.add_light(name="key", pos=[0.5 * extent_m, -0.5 * extent_m, 1.5 * extent_m],
                             dir=[-0.3, 0.3, -1.0], diffuse=[0.6, 0.6, 0.6])
    return spec


def _spec_of(scene: Any) -> mujoco.MjSpec | None:
    """A private copy of the scene's MjSpec (Cell.spec, an MjSpec), or None."""
    if isinstance(scene, mujoco.MjSpec):
        return scene.copy()
    spec = getattr(scene, "spec", None)
    if isinstance(spec, mujoco.MjSpec):
        return spec.copy()
    return None


def _model_of(scene: Any) -> mujoco.MjModel | None:
    if isinstance(scene, mujoco.MjModel):
        return scene
    model = getattr(scene, "model", None)
    return model if isinstance(model, mujoco.MjModel) else None


def robot_qpos_adr(scene: Any, model: mujoco.MjModel) -> np.ndarray | None:
    """qpos addresses (n,) of the robot joints, in the robot's joint order, or None.

    A `paintcell.execution.cell.Cell` knows them (`Cell.qpos_adr`, indexed when the cell was
    compiled). Any other
    scene is a plain model: the robot's joints are looked up by name in `model` — the names from
    `scene.joint_names` or `scene.robot.joint_names`, each matched exactly or else as the unique
    joint whose name ends with it (a robot attached under a prefix, e.g. "robot/joint_1"). None
    when the scene names no joints or a name is missing or ambiguous: `SceneRenderer.set_q` then
    writes q into the model's first qpos entries.
    """
    if isinstance(scene, Cell):
        return np.asarray(scene.qpos_adr, int).copy()
    names = getattr(scene, "joint_names", None)
    if names is None:
        names = getattr(getattr(scene, "robot", None), "joint_names", None)
    if names is None:
        return None
    adr = []
    for n in names:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)
        if jid < 0:
            cands = [j for j in range(model.njnt) if (mujoco.mj_id2name(
                model, mujoco.mjtObj.mjOBJ_JOINT, j) or "").endswith(n)]
            if len(cands) != 1:
                return None
            jid = cands[0]
        adr.append(int(model.jnt_qposadr[jid]))
    return np.asarray(adr, int)


def _film_spec_like(model: mujoco.MjModel, data: mujoco.MjData, film: Film) -> mujoco.MjSpec:
    """A spec with only `film`, lights and copies of `model`'s cameras (world poses at `data`),
    so that a render of it lines up pixel for pixel with a render of `model`."""
    spec = mujoco.MjSpec()
    spec.modelname = "film_overlay"
    spec.visual.headlight.ambient = model.vis.headlight.ambient.copy()
    spec.visual.headlight.diffuse = model.vis.headlight.diffuse.copy()
    spec.worldbody.add_light(name="key", pos=[0, 0, 5], dir=[0, 0, -1],
                             type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                             diffuse=[0.6, 0.6, 0.6], castshadow=False)
    for i in range(model.ncam):
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, data.cam_xmat[i])
        spec.worldbody.add_camera(name=mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i)
                                  or f"camera{i}", pos=data.cam_xpos[i].copy(), quat=quat,
                                  fovy=float(model.cam_fovy[i]))
    add_film(spec, film)
    return spec


class SceneRenderer:
    """A compiled scene (a cell, an MjSpec, an MjModel, or a bare booth) with an offscreen
    renderer; optionally with a film-thickness mesh.

    scene: a `paintcell.execution.cell.Cell` (its spec; joint vectors go to `Cell.qpos_adr`), an
    `MjModel`, an
        `MjSpec` (the film is added to a copy), or None for `booth_spec()`.
    film: the thickness map to draw, or None. With a compiled model the film lives in a second
        model that shares the cameras and clip planes; the two renders are composited by depth
        (the film, lifted 0.5 mm off the part, wins over the part; the robot in front wins).
    size: (width, height) [px]; shadows: MuJoCo shadow pass (off: several × faster on software
        GL). cameras: extra named `CameraView`s usable by name in `render`.
    """

    def __init__(self, scene: Any = None, film: Film | None = None,
                 size: tuple[int, int] = (640, 480), shadows: bool = False,
                 cameras: Mapping[str, CameraView] | None = None) -> None:
        width, height = int(size[0]), int(size[1])
        if width < 8 or height < 8 or width > 8192 or height > 8192:
            raise RenderError(f"image size {size} px out of range: use 8..8192 per side")
        backend_name()
        self.size = (width, height)
        self.cameras: dict[str, CameraView] = dict(cameras or {})
        self._film_r: mujoco.Renderer | None = None
        self._film_cache: dict[Any, tuple[np.ndarray, np.ndarray]] = {}
        self._renderer: mujoco.Renderer | None = None
        spec = _spec_of(scene)
        if scene is None:
            # The cell's floor is z = 0; a part placed around the origin gets one below it.
            z0 = -1.0 if film is None else min(0.0, float(film.vertices_world[:, 2].min()) - 0.25)
            spec = booth_spec(floor_z_m=z0)
        if spec is not None:
            if film is not None:
                add_film(spec, film)
            model = _compile(spec)
        else:
            model = _model_of(scene)
            if model is None:
                raise RenderError(f"cannot render a {type(scene).__name__}: pass a Cell, an "
                                  "MjModel, an MjSpec or None")
        _fit_offscreen(model, width, height)
        self.model = model
        self.data = mujoco.MjData(model)
        mujoco.mj_forward(model, self.data)
        self.qpos_adr = robot_qpos_adr(scene, model) if scene is not None else None
        home = getattr(scene, "q_home", None)
        if home is not None and self.qpos_adr is not None and len(home) == len(self.qpos_adr):
            self.set_q(home)
        self._renderer = make_renderer(model, width, height)
        if spec is None and film is not None:
            fmodel = _compile(_film_spec_like(model, self.data, film))
            _fit_offscreen(fmodel, width, height)
            # Same free-camera field of view and clip planes: pixels and depths line up.
            fmodel.vis.global_.fovy = model.vis.global_.fovy
            fmodel.vis.map.znear = model.vis.map.znear
            fmodel.vis.map.zfar = model.vis.map.zfar
            fmodel.stat.extent = model.stat.extent
            fmodel.stat.center = model.stat.center
            self._film_model = fmodel
            self._film_data = mujoco.MjData(fmodel)
            mujoco.mj_forward(fmodel, self._film_data)
            self._film_r = make_renderer(fmodel, width, height)
        self.set_shadows(shadows)

    def set_shadows(self, on: bool) -> None:
        """Turn MuJoCo's shadow pass on or off (off by default: much faster)."""
        for r in (self._renderer, self._film_r):
            if r is not None:
                r.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = int(bool(on))

    def set_q(self, q: npt.ArrayLike) -> None:
        """Set the robot joint positions (n,) [rad] and run `mj_forward`."""
        q = np.asarray(q, float).reshape(-1)
        adr = self.qpos_adr if self.qpos_adr is not None else np.arange(len(q))
        if len(adr) != len(q) or (len(adr) and adr.max() >= self.model.nq):
            raise RenderError(f"joint vector has {len(q)} values but the scene's robot has "
                              f"{len(adr)} joints (model nq = {self.model.nq})")
        self.data.qpos[adr] = q
        mujoco.mj_forward(self.model, self.data)

    def _camera(self, camera: CameraView | str | None) -> mujoco.MjvCamera | str:
        if isinstance(camera, CameraView):
            return camera.to_mjv()
        if camera is None:
            cam = mujoco.MjvCamera()
            mujoco.mjv_defaultFreeCamera(self.model, cam)
            return cam
        if camera in self.cameras:
            return self.cameras[camera].to_mjv()
        if mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, camera) >= 0:
            return camera
        names = sorted(self.cameras) + [mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_CAMERA,
                                                          i) for i in range(self.model.ncam)]
        raise RenderError(f"unknown camera {camera!r}: use one of {names} or a CameraView")

    def render(self, camera: CameraView | str | None = None,
               q: npt.ArrayLike | None = None) -> np.ndarray:
        """(H, W, 3) uint8 RGB frame from `camera`, robot at `q` (n,) [rad] if given."""
        if self._renderer is None:
            raise RenderError("renderer is closed; make a new SceneRenderer")
        if q is not None:
            self.set_q(q)
        cam = self._camera(camera)
        self._renderer.update_scene(self.data, camera=cam)
        rgb = self._renderer.render().copy()
        if self._film_r is None:
            return rgb
        # The film model is static: its colour and depth depend on the camera only (cached).
        key = camera if isinstance(camera, CameraView | str | None) else id(camera)
        if key not in self._film_cache:
            self._film_r.update_scene(self._film_data, camera=cam)
            self._film_cache[key] = (self._film_r.render().copy(), _depth(self._film_r))
        film_rgb, film_depth = self._film_cache[key]
        depth = _depth(self._renderer)
        far = float(self._film_model.vis.map.zfar * self._film_model.stat.extent)
        # The film is lifted FILM_OFFSET_M off the part: it wins over the part's own surface;
        # anything nearer the camera than the film (the robot) wins over the film.
        show = (film_depth < 0.999 * far) & (film_depth < depth + 0.2 * FILM_OFFSET_M)
        rgb[show] = film_rgb[show]
        return rgb

    def close(self) -> None:
        """Free the GL contexts."""
        for r in (self._renderer, self._film_r):
            if r is not None:
                r.close()
        self._renderer = self._film_r = None

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _depth(r: mujoco.Renderer) -> np.ndarray:
    """(H, W) distance along the view axis [m] of the scene last updated in `r`."""
    r.enable_depth_rendering()
    try:
        return r.render()
    finally:
        r.disable_depth_rendering()


def _compile(spec: mujoco.MjSpec) -> mujoco.MjModel:
    try:
        return spec.compile()
    except ValueError as e:
        raise RenderError(f"scene does not compile for rendering: {one_line(e, 200)}") from e


def _fit_offscreen(model: mujoco.MjModel, width: int, height: int) -> None:
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)


def render_thickness(scene: Any, surface: Any, thickness_m: npt.ArrayLike, vmin_um: float,
                     vmax_um: float, camera: CameraView | str | None = "front",
                     size: tuple[int, int] = (640, 480), T_world_part: npt.ArrayLike | None = None,
                     q: npt.ArrayLike | None = None, cmap: str = DEFAULT_CMAP,
                     colorbar: bool = True, shadows: bool = False) -> np.ndarray:
    """(H, W, 3) uint8 render of the part coloured by film thickness.

    scene: a Cell / MjModel (film composited by depth), an MjSpec (film added to a copy) or
    None (bare booth); surface: `Surface` in the
    part frame; thickness_m: (N,) per vertex [m]; vmin_um/vmax_um: shared colour range [µm];
    camera: a CameraView, a preset name ("front", "top", "along_passes", "oblique" from
    `part_cameras`), a model camera name, or None (MuJoCo's default free camera);
    size: (width, height) [px]; T_world_part: (4, 4) (default: the cell's, else identity);
    q: robot joints [rad] or None; colorbar: draw the µm legend on the right edge.
    """
    if T_world_part is None:
        T_world_part = getattr(scene, "T_world_part", None)
    film = film_from_surface(surface, thickness_m, vmin_um, vmax_um, T_world_part, cmap)
    presets = part_cameras(surface, T_world_part)
    with SceneRenderer(scene, film, size, shadows, presets) as r:
        img = r.render(camera, q)
    if colorbar:
        img = add_colorbar(img, vmin_um, vmax_um, cmap)
    return img


def render_robot_at(scene: Any, q: npt.ArrayLike, camera: CameraView | str | None = None,
                    size: tuple[int, int] = (640, 480), film: Film | None = None,
                    shadows: bool = False) -> np.ndarray:
    """(H, W, 3) uint8 render of the cell with the robot at joint positions q (n,) [rad]."""
    with SceneRenderer(scene, film, size, shadows) as r:
        return r.render(camera, q)


def frame_indices(t_s: npt.ArrayLike, fps: float, speedup: float = 1.0,
                  max_frames: int | None = None) -> np.ndarray:
    """Indices of the samples shown at `fps` [1/s] when time runs `speedup` × faster.

    t_s: (K,) increasing sample times [s]; max_frames: cap (frames are spread evenly).
    """
    t = np.asarray(t_s, float)
    if t.ndim != 1 or len(t) == 0:
        raise RenderError("frame times must be a non-empty (K,) array [s]")
    if fps <= 0 or speedup <= 0:
        raise RenderError(f"fps ({fps}) and speedup ({speedup}) must be > 0")
    t_show = np.arange(t[0], t[-1] + 1e-12, speedup / fps)
    hi = np.clip(np.searchsorted(t, t_show), 1, max(len(t) - 1, 1))
    lo = hi - 1
    nearest = np.where(np.abs(t[np.minimum(hi, len(t) - 1)] - t_show) < np.abs(t[lo] - t_show),
                       hi, lo) if len(t) > 1 else np.zeros(len(t_show), int)
    idx = np.unique(nearest)
    if max_frames is not None and len(idx) > max_frames:
        idx = idx[np.round(np.linspace(0, len(idx) - 1, max_frames)).astype(int)]
    return idx


def render_frames(scene: Any, q: npt.ArrayLike, camera: CameraView | str | None = None,
                  size: tuple[int, int] = (320, 240), film: Film | None = None,
                  cameras: Mapping[str, CameraView] | None = None) -> list[np.ndarray]:
    """One (H, W, 3) uint8 frame per row of q (K, n) [rad], one compiled scene for all."""
    q = np.atleast_2d(np.asarray(q, float))
    with SceneRenderer(scene, film, size, False, cameras) as r:
        return [r.render(camera, qi) for qi in q]


def render_execution_video(path: str | os.PathLike[str], scene: Any, t_s: npt.ArrayLike,
                           q: npt.ArrayLike, camera: CameraView | str | None = None,
                           fps: float = 10.0, speedup: float = 1.0,
                           size: tuple[int, int] = (320, 240), film: Film | None = None,
                           cameras: Mapping[str, CameraView] | None = None,
                           max_frames: int = 300) -> Path:
    """Write a video (GIF, or MP4 with imageio-ffmpeg) of the robot following q (K, n) [rad]
    sampled at t_s (K,) [s], subsampled to `fps` [1/s] at `speedup`; returns the path."""
    q = np.asarray(q, float)
    idx = frame_indices(t_s, fps, speedup, max_frames)
    frames = render_frames(scene, q[idx], camera, size, film, cameras)
    return write_video(path, frames, fps)
