"""`Placement`: where a rigid thing sits in the cell (a part, a robot base, a car body), as a
position [m] and roll-pitch-yaw [rad], and `pose` that turns the pair into a (4, 4) transform."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paintcell.core.errors import ScenarioError

__all__ = ["Placement", "pose", "triple"]


def triple(x: object, ndigits: int | None = None) -> tuple[float, float, float]:
    """Three numbers (a position [m], angles [rad] or a direction) as a tuple of floats,
    rounded to `ndigits` decimals when given; anything but three numbers is a ValueError."""
    a = np.asarray(x, float).reshape(-1)
    if len(a) != 3:
        raise ValueError(f"three numbers expected, got {len(a)}")
    x0, x1, x2 = (float(v) if ndigits is None else round(float(v), ndigits) for v in a)
    return (x0, x1, x2)


def pose(xyz_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
         rpy_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """(4, 4) transform from a position [m] and roll-pitch-yaw (fixed XYZ axes) [rad]."""
    r, p, y = rpy_rad
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    T = np.eye(4)
    T[:3, :3] = np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])
    T[:3, 3] = xyz_m
    return T


@dataclass(frozen=True)
class Placement:
    """A rigid placement in the cell: position [m] and roll-pitch-yaw [rad] (fixed XYZ axes)."""

    xyz_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("xyz_m", "rpy_rad"):
            raw = getattr(self, name)
            ok = isinstance(raw, list | tuple | np.ndarray) and len(raw) == 3 and all(
                isinstance(x, int | float | np.integer | np.floating)
                and not isinstance(x, bool | np.bool_) for x in raw)
            if not ok or not np.all(np.isfinite(np.asarray(raw, float))):
                raise ScenarioError(f"{name} = {list(raw) if ok else raw!r} must be three finite "
                                    f"numbers (no quotes), e.g. {name} = [0.0, 0.0, 0.0]")

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) homogeneous transform."""
        return pose(self.xyz_m, self.rpy_rad)
