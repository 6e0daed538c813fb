"""The outer surfaces of a generated car body [mm], from which its panels are cut.

Body frame: x forward (the front at +x), y to the car's left, z up, origin on the floor under
the body's centre.

- The *wall* runs round the car: in plan view a rounded rectangle (half width `Wh`, front at
  `Xf`, rear at `Xr`, corner radius `Rc`), moved inward by `inset(z)` at height z: a tuck toward
  the sill below the belt line (radius `R_low`) and the tumblehome of the greenhouse above it
  (radius `R_top`). Its points are addressed by (s, ζ): s the arc length along the plan outline
  from the front centre (+ toward the left, round to the rear centre at `half_perimeter`; − the
  mirror on the right), ζ the arc length up the wall from the belt line. Along the straight sides
  and the straight rear the wall is a cylinder, so (s, ζ) develops it without stretch: a gap of
  g in (s, ζ) is a gap of g on the body.
- The *tops* (hood, roof, trunk lid) are heights z = h(x) + crown, the crown `h_c (1 − (y/Y)²)²`
  vanishing with zero slope at the wall's line Y(x), so a top meets the wall along a crease.

`crease_insets` gives how far a top and a wall panel stop short of their crease so their edges
are a chosen gap apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BodyShape", "crease_insets", "crown"]

#: Table step of the wall's height ↔ arc length map [mm].
_TABLE_STEP_MM = 0.5


@dataclass(frozen=True)
class BodyShape:
    """The wall of a body [mm] (module doc): plan outline `Xf`, `Xr`, `Wh`, `Rc`; belt line
    height `z_belt`; the wall's radii below (`R_low`) and above (`R_top`) the belt."""

    Xf: float
    Xr: float
    Wh: float
    Rc: float
    z_belt: float
    R_low: float
    R_top: float

    # -- the wall's cross-section ---------------------------------------------------------
    def inset(self, z: np.ndarray) -> np.ndarray:
        """How far the wall lies inside the plan outline at height z [mm]."""
        d = np.asarray(z, float) - self.z_belt
        return np.where(d < 0, d * d / (2 * self.R_low), d * d / (2 * self.R_top))

    def inset_slope(self, z: np.ndarray) -> np.ndarray:
        """d inset / dz at height z [-] (negative below the belt: the wall tucks in going down)."""
        d = np.asarray(z, float) - self.z_belt
        return np.where(d < 0, d / self.R_low, d / self.R_top)

    def zeta(self, z: np.ndarray) -> np.ndarray:
        """Arc length up the wall from the belt line to height z [mm] (closed form)."""
        d = np.asarray(z, float) - self.z_belt
        R = np.where(d < 0, self.R_low, self.R_top)
        u = d / R
        return R / 2 * (u * np.sqrt(1 + u * u) + np.arcsinh(u))

    def z_of(self, zeta: np.ndarray) -> np.ndarray:
        """Height [mm] at arc length ζ up the wall from the belt (inverse of `zeta`)."""
        z = np.arange(self.z_belt - 1500.0, self.z_belt + 1500.0, _TABLE_STEP_MM)
        return np.interp(zeta, self.zeta(z), z)

    # -- the plan outline ------------------------------------------------------------------
    @property
    def front_end_s(self) -> float:
        """s where the straight left side begins, at x = Xf − Rc [mm]."""
        return (self.Wh - self.Rc) + np.pi * self.Rc / 2

    @property
    def half_perimeter(self) -> float:
        """s of the rear centre [mm]."""
        return 2 * self.front_end_s + (self.Xf - self.Xr - 2 * self.Rc)

    def outline(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Plan-view points (…, 2) and outward unit normals (…, 2) at arc length s [mm]."""
        s = np.asarray(s, float)
        sg = np.where(s < 0, -1.0, 1.0)
        a = np.abs(s)
        rear = a > self.half_perimeter / 2
        a = np.where(rear, self.half_perimeter - a, a)     # the rear end mirrors the front
        straight = self.Wh - self.Rc
        phi = np.clip((a - straight) / self.Rc, 0.0, np.pi / 2)
        rest = np.maximum(a - self.front_end_s, 0.0)
        x = np.where(a <= straight, self.Rc, self.Rc * np.cos(phi)) - rest
        y = np.where(a <= straight, a, straight + self.Rc * np.sin(phi))
        x = x + (self.Xf - self.Rc)
        nx, ny = np.cos(phi), np.sin(phi)
        x = np.where(rear, self.Xf + self.Xr - x, x)
        nx = np.where(rear, -nx, nx)
        return np.stack([x, sg * y], -1), np.stack([nx, sg * ny], -1)

    def wall(self, s: np.ndarray, zeta: np.ndarray) -> np.ndarray:
        """Wall points (…, 3) [mm] at (s, ζ)."""
        z = self.z_of(zeta)
        p, n = self.outline(s)
        xy = p - self.inset(z)[..., None] * n
        return np.concatenate([xy, z[..., None]], -1)

    def side(self, x: np.ndarray, zeta: np.ndarray) -> np.ndarray:
        """Points (…, 3) [mm] of the left side's straight part at (x, ζ)."""
        z = self.z_of(zeta)
        return np.stack([np.asarray(x, float) + 0 * z, self.Wh - self.inset(z), z], -1)

    # -- the tops -------------------------------------------------------------------------
    def crease_y(self, h: np.ndarray) -> np.ndarray:
        """Half width [mm] of the wall's crease with a top whose edge is at height h."""
        return self.Wh - self.inset(h)


def crown(y: np.ndarray, Y: np.ndarray, h_c: float) -> np.ndarray:
    """A top's crown [mm]: h_c on the centre line, zero with zero slope at |y| = Y."""
    t = np.clip(1 - (np.asarray(y) / Y) ** 2, 0.0, None)
    return h_c * t * t


def crease_insets(gap_mm: float, wall_slope: np.ndarray, top_rise: np.ndarray | float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """How far a top and a wall panel stop short of their crease [mm] so their edges are
    `gap_mm` apart: (a, b), the top's edge `a` inside the crease (measured in plan), the wall
    panel's edge `b` down the wall (arc length).

    wall_slope: d inset / dz of the wall at the crease [-]; top_rise: the top's slope going
    inward from its edge [-]. The wall panel stops b = gap/√2 down; a solves
    |(a + b q c, b c + σ a)| = gap with c = 1/√(1 + q²).
    """
    q = np.asarray(wall_slope, float)
    sig = np.asarray(top_rise, float)
    b = np.full(np.broadcast(q, sig).shape, gap_mm / np.sqrt(2.0))
    c = 1 / np.sqrt(1 + q * q)
    k = b * c * (q + sig)
    a = (-k + np.sqrt(k * k - (1 + sig * sig) * (b * b - gap_mm ** 2))) / (1 + sig * sig)
    return a, b
