"""Free cameras for renders of a part: a view from a direction, and presets framing a part.

Units: positions and distances [m], MuJoCo free-camera angles (azimuth, elevation) [deg].
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from paintcell.output.render_backend import RenderError


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
    """`camera_presets` for a `paintcell.surface.surface.Surface` placed at `T_world_part`
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
