"""Offscreen MuJoCo renders of the paint cell: film thickness as a colour map, robot poses, videos.

The one-call entry points live here; their parts are modules of their own: the GL backend and
the errors (`paintcell.output.render_backend`), cameras (`paintcell.output.render_cameras`),
the film colour map (`paintcell.output.render_film`), the compiled scene and its renderer
(`paintcell.output.render_scene`), and image and
video files with the thickness legend (`paintcell.output.render_images`). Every name is
importable from here.

Units: positions [m], thickness [m] inside and [µm] in colour ranges and legends, angles [deg]
for MuJoCo's free camera (azimuth, elevation), image sizes in pixels (width, height).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.output.render_backend import (
    BACKENDS,
    RenderBackendError,
    RenderError,
    backend_name,
    probe_backend,
)
from paintcell.output.render_cameras import CameraView, camera_presets, look_from, part_cameras
from paintcell.output.render_film import (
    DEFAULT_CMAP,
    FILM_OFFSET_M,
    Film,
    add_film,
    colormap_rgb,
    film_from_surface,
)
from paintcell.output.render_images import add_colorbar, write_png, write_video
from paintcell.output.render_scene import SceneRenderer, booth_spec, robot_qpos_adr

__all__ = [
    "BACKENDS", "DEFAULT_CMAP", "FILM_OFFSET_M", "CameraView", "Film", "RenderBackendError",
    "RenderError", "SceneRenderer", "add_colorbar", "add_film", "backend_name", "booth_spec",
    "camera_presets", "colormap_rgb", "film_from_surface", "frame_indices", "look_from",
    "part_cameras", "probe_backend", "render_execution_video", "render_frames",
    "render_robot_at", "render_thickness", "robot_qpos_adr", "write_png", "write_video",
]


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
