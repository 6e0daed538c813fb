"""Car-part library: realistic approximations of body panels, in metres, each in its part frame.

Part frame: the area-weighted centroid at the origin and the area-weighted mean normal along +z
(the painted side faces +z). Every part is one component without holes, sampled on a regular
(u, v) grid at `resolution_m` (default 5 mm; planning and CI use 10–25 mm).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from paintcell.core.errors import SurfaceError
from paintcell.surface.analytic import bspline_patch, cylinder, extruded, greville_abscissae, plane
from paintcell.surface.surface_data import Surface

DEFAULT_RESOLUTION_M = 0.005


def to_part_frame(surface: Surface) -> Surface:
    """Move a surface so its area-weighted centroid is the origin and its mean normal is +z."""
    w = surface.vertex_areas / surface.vertex_areas.sum()
    centroid = w @ surface.vertices
    n = w @ surface.normals
    n /= np.linalg.norm(n)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(n, z)
    s, c = np.linalg.norm(axis), float(n @ z)
    if s < 1e-12:
        R = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    else:  # Rodrigues: the minimal rotation taking n to z
        k = axis / s
        Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        R = np.eye(3) + s * Kx + (1 - c) * Kx @ Kx
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ centroid
    return surface.transformed(T)


def panel(resolution_m: float = DEFAULT_RESOLUTION_M) -> Surface:
    """Flat sheet 1.0 m (x) × 0.8 m (y): the paper's planar test sheet class."""
    return to_part_frame(plane(1.0, 0.8, resolution_m, name="panel"))


def cylinder_section(resolution_m: float = DEFAULT_RESOLUTION_M) -> Surface:
    """Convex cylinder sector, radius 1.0 m (the paper's 100 cm cylinder), 1.2 m long (axis x),
    arc 1.2 rad = 1.2 m of arc length around y; outside painted. K = 0, H = 0.5 1/m."""
    return to_part_frame(cylinder(1.0, 1.2, 1.2, resolution_m, name="cylinder_section"))


def door_profile(n: int = 1601) -> np.ndarray:
    """(n, 2) vertical section (y, z) [m] of the SUV front door outer skin, bottom to top.

    0.80 m of arc length built from a smooth curvature law k(s) [1/m] (convex positive):
    a flat-ish lower panel (k ≈ 0.15, radius ~7 m), a belt-line shoulder/crease centred at
    s = 0.58 m peaking at k ≈ 2.6 (radius ≈ 0.38 m), and a gently convex upper band
    (k ≈ 0.4) toward the window line — after the Ford Excursion door of the paper (§4).
    """
    s = np.linspace(0.0, 0.8, n)
    k = 0.15 + 2.45 * np.exp(-0.5 * ((s - 0.58) / 0.045) ** 2) + 0.25 / (
        1 + np.exp(-(s - 0.66) / 0.02))
    # Tangent angle in the (y, z) plane: a convex bend (k > 0) turns the tangent clockwise
    # when the painted side is the profile's left (toward +z when it runs along +y).
    ds = np.diff(s)
    theta = -np.concatenate([[0.0], np.cumsum(0.5 * (k[1:] + k[:-1]) * ds)])
    t = np.stack([np.cos(theta), np.sin(theta)], 1)
    p = np.concatenate([[[0.0, 0.0]], np.cumsum(0.5 * (t[1:] + t[:-1]) * ds[:, None], 0)])
    return p


def door(resolution_m: float = DEFAULT_RESOLUTION_M) -> Surface:
    """SUV front door outer skin: 1.10 m long (extrusion along x) × 0.80 m profile arc.

    Singly curved (K = 0) with varying curvature across the profile (`door_profile`): flat-ish
    bottom (toward -y), shoulder crease of radius ≈ 0.38 m at the belt line (toward +y).
    Direction of zero curvature: x; of maximum curvature: along the profile (≈ y).
    """
    return to_part_frame(extruded(door_profile(), 1.10, resolution_m, name="door"))


def _height_field_net(size_x: float, size_y: float, n_x: int, n_y: int,
                      z: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
    """(n_x, n_y, 3) cubic control net over [-size/2, size/2]² with heights z(x, y) [m].

    x, y at Greville abscissae so the patch's planform is exactly the rectangle."""
    gx = (greville_abscissae(n_x) - 0.5) * size_x
    gy = (greville_abscissae(n_y) - 0.5) * size_y
    X, Y = np.meshgrid(gx, gy, indexing="ij")
    return np.stack([X, Y, z(X, Y)], -1)


def fender(resolution_m: float = DEFAULT_RESOLUTION_M) -> Surface:
    """Front fender, doubly curved B-spline: planform 1.0 m (x, along the car) × 0.7 m (y, up).

    Height z = -x²/(2 Rx(y)) - y²/(2 Ry) with Rx shrinking from ≈ 1.4 m at the top to ≈ 0.45 m
    over the wheel-arch (lower) band and Ry ≈ 0.6 m: K ≈ 1–4 1/m² low, ≈ 1 1/m² high.
    """
    def z(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        w = 1.0 / (1.0 + np.exp((y + 0.05) / 0.08))  # 1 on the wheel-arch band, 0 on top
        rx = 1.4 - 0.95 * w
        return -x ** 2 / (2 * rx) - y ** 2 / (2 * 0.6)

    net = _height_field_net(1.0, 0.7, 9, 8, z)
    return to_part_frame(bspline_patch(net, 3, resolution_m, name="fender"))


def hood(resolution_m: float = DEFAULT_RESOLUTION_M) -> Surface:
    """Hood, gently doubly curved B-spline: planform 1.5 m (x, along the car) × 1.2 m (y).

    Crowned: radii ≈ 6 m along the car and ≈ 3.5 m across (K ≈ 0.05 1/m²)."""
    net = _height_field_net(1.5, 1.2, 6, 6, lambda x, y: -x ** 2 / 12.0 - y ** 2 / 7.0)
    return to_part_frame(bspline_patch(net, 3, resolution_m, name="hood"))


def roof(resolution_m: float = DEFAULT_RESOLUTION_M) -> Surface:
    """Roof, gently curved B-spline: planform 1.6 m (x, along the car) × 1.3 m (y, across).

    Radii ≈ 8 m along the car; across it ≈ 3 m in the middle, curving down to ≈ 1 m toward
    the side rails (z = -x²/16 - y²/6 - 0.15 y⁴)."""
    net = _height_field_net(1.6, 1.3, 6, 7,
                            lambda x, y: -x ** 2 / 16.0 - y ** 2 / 6.0 - 0.15 * y ** 4)
    return to_part_frame(bspline_patch(net, 3, resolution_m, name="roof"))


_PARTS: dict[str, Callable[[float], Surface]] = {
    "panel": panel,
    "cylinder_section": cylinder_section,
    "door": door,
    "fender": fender,
    "hood": hood,
    "roof": roof,
}
PART_NAMES: tuple[str, ...] = tuple(_PARTS)


def get_part(name: str, resolution_m: float = DEFAULT_RESOLUTION_M) -> Surface:
    """The library part `name` (one of PART_NAMES) sampled at `resolution_m` [m]."""
    if name not in _PARTS:
        raise SurfaceError(f"unknown part {name!r}; choose one of {', '.join(PART_NAMES)}")
    return _PARTS[name](resolution_m)
