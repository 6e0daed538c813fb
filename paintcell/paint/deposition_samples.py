"""Inputs of the deposition model: the sampled gun trajectory (`GunSamples`: positions [m], unit
spray axes and travel directions, dwell [s]) and the checks every kernel applies to gun samples,
surface points [m] and unit normals, with the per-sample tool frame (x̂, ŷ, â) they are read in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from paintcell.core.errors import PaintcellError


class DepositionError(PaintcellError):
    """Gun samples, points or normals passed to the deposition model are invalid."""


@dataclass(frozen=True, eq=False)
class GunSamples:
    """A sampled gun trajectory.

    positions: (S, 3) spray points (TCP) [m], in the same frame as the surface points.
    spray_axes: (S, 3) unit spray directions (tool +z).
    travel_dirs: (S, 3) unit travel directions (tool +x), orthogonal to the spray axis.
    dwell_s: (S,) time attributed to each sample [s] (≥ 0).
    """

    positions: np.ndarray
    spray_axes: np.ndarray
    travel_dirs: np.ndarray
    dwell_s: np.ndarray

    def __post_init__(self) -> None:
        pos = as_vectors(self.positions, "positions")
        s = len(pos)
        axes = as_vectors(self.spray_axes, "spray_axes", s)
        trav = as_vectors(self.travel_dirs, "travel_dirs", s)
        dwell = np.asarray(self.dwell_s, float).reshape(-1)
        if len(dwell) != s:
            raise DepositionError(f"dwell_s has {len(dwell)} entries, expected {s} (one a sample)")
        if not np.all(np.isfinite(dwell)) or np.any(dwell < 0):
            raise DepositionError("dwell_s must be finite and >= 0 [s]")
        if s and np.any(np.abs(np.linalg.norm(axes, axis=1) - 1) > 1e-6):
            raise DepositionError("spray_axes must be unit vectors; normalize them")
        if s and np.any(np.abs(np.linalg.norm(trav, axis=1) - 1) > 1e-6):
            raise DepositionError("travel_dirs must be unit vectors; normalize them")
        if s and np.any(np.abs(np.sum(axes * trav, axis=1)) > 1e-6):
            raise DepositionError("travel_dirs must be orthogonal to spray_axes")
        for name, arr in (("positions", pos), ("spray_axes", axes), ("travel_dirs", trav),
                          ("dwell_s", dwell)):
            object.__setattr__(self, name, arr)

    def __len__(self) -> int:
        return len(self.positions)

    @property
    def total_time_s(self) -> float:
        """Σ dwell [s]."""
        return float(self.dwell_s.sum())

    @classmethod
    def straight_pass(cls, start_m: npt.ArrayLike, end_m: npt.ArrayLike, spray_axis: npt.ArrayLike,
                      speed_m_s: float, spacing_m: float = 0.005) -> GunSamples:
        """Constant-speed straight pass from `start_m` to `end_m` (3,) [m], spray axis (3,),
        sample spacing [m]; dwell by the trapezoid rule (half intervals at the ends)."""
        a = np.asarray(start_m, float)
        b = np.asarray(end_m, float)
        z = np.asarray(spray_axis, float)
        for name, v in (("start_m", a), ("end_m", b), ("spray_axis", z)):
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise DepositionError(f"straight_pass: {name} = {v.tolist()} must be a finite "
                                      "3-vector; give finite coordinates [m]")
        for name, x_ in (("speed_m_s", speed_m_s), ("spacing_m", spacing_m)):
            if not (isinstance(x_, int | float | np.floating) and math.isfinite(x_) and x_ > 0):
                raise DepositionError(f"straight_pass: {name} = {x_!r} must be a finite number "
                                      "> 0")
        length = float(np.linalg.norm(b - a))
        nz = float(np.linalg.norm(z))
        if length <= 0 or nz <= 0:
            raise DepositionError("straight_pass needs distinct end points and a nonzero spray "
                                  "axis; check start_m, end_m and spray_axis")
        z = z / nz
        x = (b - a) / length
        x = x - np.dot(x, z) * z
        nx = float(np.linalg.norm(x))
        if nx < 1e-9:
            raise DepositionError("straight_pass: the spray axis is parallel to the travel "
                                  "direction end_m - start_m; give a spray axis across the pass")
        x = x / nx
        n = max(2, int(math.ceil(length / spacing_m)) + 1)
        t = np.linspace(0.0, 1.0, n)
        pos = a + t[:, None] * (b - a)
        dt = length / (n - 1) / speed_m_s
        dwell = np.full(n, dt)
        dwell[[0, -1]] = dt / 2
        return cls(pos, np.tile(z, (n, 1)), np.tile(x, (n, 1)), dwell)


def as_vectors(x: npt.ArrayLike, name: str, rows: int | None = None) -> np.ndarray:
    """`x` as a finite contiguous (rows, 3) float array, or a DepositionError naming `name`."""
    arr = np.ascontiguousarray(x, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise DepositionError(f"{name} must have shape (n, 3), got {arr.shape}")
    if rows is not None and len(arr) != rows:
        raise DepositionError(f"{name} has {len(arr)} rows, expected {rows}")
    if not np.all(np.isfinite(arr)):
        raise DepositionError(f"{name} contains NaN or inf")
    return arr


#: |‖n‖ − 1| allowed for a surface normal: the rate scales with |n·ω|, so a non-unit normal
#: scales the film by ‖n‖; 1e-6 admits float32-stored unit normals (eps 6e-8) with margin.
UNIT_NORMAL_TOL = 1e-6


def as_normals(x: npt.ArrayLike, rows: int) -> np.ndarray:
    """`x` as (rows, 3) unit normals (within UNIT_NORMAL_TOL), or a DepositionError."""
    n = as_vectors(x, "normals", rows)
    bad = np.abs(np.linalg.norm(n, axis=1) - 1.0) > UNIT_NORMAL_TOL
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DepositionError(
            f"normals must be unit vectors (|n| - 1 within {UNIT_NORMAL_TOL:g}); {int(bad.sum())} "
            f"are not (first: row {i}, |n| = {np.linalg.norm(n[i]):.6g}); normalize them")
    return n


def tool_axes(spray_axes: np.ndarray, travel_dirs: np.ndarray) -> tuple[np.ndarray, ...]:
    """Unit (x̂, ŷ, â) per sample: x̂ re-orthogonalized against â, ŷ = â × x̂."""
    a = spray_axes / np.linalg.norm(spray_axes, axis=1, keepdims=True)
    x = travel_dirs - np.sum(travel_dirs * a, axis=1, keepdims=True) * a
    nx = np.linalg.norm(x, axis=1, keepdims=True)
    if np.any(nx < 1e-9):
        raise DepositionError("a travel direction is parallel to its spray axis; give x ⟂ z")
    x = x / nx
    return x, np.cross(a, x), a

