"""The coverage plan: ordered spray passes with dense TCP samples, in the part frame.

A `CoveragePlan` is what `planning` hands to the robot side. It is pure data: every array is in
the part frame and SI units, and `save`/`load` round-trip it exactly (JSON for scalars and
settings, a sibling `.npz` for the arrays).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from planning.applicator import Applicator
from planning.atomic_io import atomic_write_npz, atomic_write_text
from planning.deposition import GunSamples
from planning.errors import PlanError

_PASS_ARRAYS = ("positions", "spray_axes", "travel_dirs", "speeds_m_s", "times_s", "on_part",
                "paint_on")


@dataclass(frozen=True, eq=False)
class PassPlan:
    """One spray pass: dense TCP samples along a curve at standoff from the surface.

    positions: (M, 3) TCP positions in the part frame [m] (surface point + h · normal).
    spray_axes: (M, 3) unit spray directions (tool +z), pointing at the surface.
    travel_dirs: (M, 3) unit travel directions (tool +x), orthogonal to the spray axis.
    speeds_m_s: (M,) planned TCP speed at each sample [m/s], > 0.
    times_s: (M,) planned time of each sample from the start of the pass [s], increasing.
    on_part: (M,) True where the sample's foot point lies on the part (False on overspray).
    paint_on: (M,) True where the brush is on (the part plus the overspray extension).
    side: 0 for the start curve, +k for the k-th pass to its right, -k to its left.
    index_width_m: geodesic index width from the neighbouring pass toward the start curve [m]
        (nan for the start curve).
    max_geodesic_curvature_1_m: max |κ_g| of the pass in the surface [1/m] (self-intersection risk).
    nsd_constant_pct / nsd_optimized_pct: σ/μ on this pass's band at constant and optimized speed
        [%] (nan where the speed optimization was not run).
    """

    positions: np.ndarray
    spray_axes: np.ndarray
    travel_dirs: np.ndarray
    speeds_m_s: np.ndarray
    times_s: np.ndarray
    on_part: np.ndarray
    paint_on: np.ndarray
    side: int = 0
    index_width_m: float = float("nan")
    max_geodesic_curvature_1_m: float = 0.0
    nsd_constant_pct: float = float("nan")
    nsd_optimized_pct: float = float("nan")

    def __post_init__(self) -> None:
        m = len(self.positions)
        if m < 2:
            raise PlanError(f"a pass needs at least 2 samples, got {m}")
        for name in _PASS_ARRAYS:
            arr = getattr(self, name)
            if len(arr) != m:
                raise PlanError(f"pass array {name} has {len(arr)} rows, expected {m}")
            if arr.dtype != bool and not np.all(np.isfinite(arr)):
                raise PlanError(f"pass array {name} contains NaN or inf; re-plan the pass")
        if np.any(self.speeds_m_s <= 0):
            raise PlanError("pass speeds must be positive [m/s]; check v_min/v_max settings")
        if np.any(np.diff(self.times_s) <= 0):
            raise PlanError("pass times must strictly increase")

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample [s]."""
        return float(self.times_s[-1] - self.times_s[0])

    @property
    def length_m(self) -> float:
        """Polyline length of the TCP path [m]."""
        return float(np.linalg.norm(np.diff(self.positions, axis=0), axis=1).sum())

    def dwell_s(self) -> np.ndarray:
        """(M,) time attributed to each sample [s]: half of each adjacent interval (trapezoid)."""
        dt = np.diff(self.times_s)
        dwell = np.zeros(len(self.times_s))
        dwell[:-1] += 0.5 * dt
        dwell[1:] += 0.5 * dt
        return dwell


@dataclass(frozen=True, eq=False)
class CoveragePlan:
    """Ordered passes (alternating direction, execution order) over one part, in the part frame.

    surface_name: the part the plan covers.
    applicator: the deposition model the plan was optimized for.
    passes: passes in execution order.
    start_rule: how the start curve was placed ("gaussian-curvature divider" or "area median",
        plus the orientation rule), for the report.
    settings: the planner settings used, JSON-serializable.
    """

    surface_name: str
    applicator: Applicator
    passes: tuple[PassPlan, ...]
    start_rule: str = ""
    settings: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.passes:
            raise PlanError("a coverage plan needs at least one pass")

    @property
    def paint_time_s(self) -> float:
        """Sum of pass durations [s] (turn-arounds excluded)."""
        return float(sum(p.duration_s for p in self.passes))

    @property
    def index_widths_m(self) -> np.ndarray:
        """(P,) index width of each pass in execution order [m] (nan for the start curve)."""
        return np.array([p.index_width_m for p in self.passes])

    def gun_samples(self, paint_only: bool = True) -> GunSamples:
        """All samples of all passes at planned timing as `GunSamples` (part frame).

        paint_only: keep only samples where the brush is on (what deposits paint).
        """
        parts = []
        for p in self.passes:
            keep = p.paint_on if paint_only else np.ones(len(p.times_s), bool)
            parts.append((p.positions[keep], p.spray_axes[keep], p.travel_dirs[keep],
                          p.dwell_s()[keep]))
        return GunSamples(
            positions=np.concatenate([x[0] for x in parts]),
            spray_axes=np.concatenate([x[1] for x in parts]),
            travel_dirs=np.concatenate([x[2] for x in parts]),
            dwell_s=np.concatenate([x[3] for x in parts]),
        )

    def tcp_frames(self, pass_index: int) -> np.ndarray:
        """(M, 4, 4) TCP poses `T_part_tcp` of one pass: x = travel, z = spray axis."""
        p = self.passes[pass_index]
        return tcp_frames(p.positions, p.spray_axes, p.travel_dirs)

    # --- persistence -----------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str]) -> None:
        """Write `path` (JSON) and `path` with suffix `.npz` (arrays), each atomically."""
        path = Path(path)
        arrays: dict[str, np.ndarray] = {}
        meta_passes = []
        for i, p in enumerate(self.passes):
            for name in _PASS_ARRAYS:
                arrays[f"p{i}_{name}"] = getattr(p, name)
            meta_passes.append({
                "side": p.side,
                "index_width_m": _num(p.index_width_m),
                "max_geodesic_curvature_1_m": _num(p.max_geodesic_curvature_1_m),
                "nsd_constant_pct": _num(p.nsd_constant_pct),
                "nsd_optimized_pct": _num(p.nsd_optimized_pct),
                "n_samples": len(p.times_s),
                "duration_s": p.duration_s,
                "length_m": p.length_m,
            })
        meta = {
            "format": "paintcell.CoveragePlan/1",
            "frame": "part",
            "surface_name": self.surface_name,
            "applicator": self.applicator.to_dict(),
            "start_rule": self.start_rule,
            "settings": self.settings,
            "paint_time_s": self.paint_time_s,
            "arrays": path.with_suffix(".npz").name,
            "passes": meta_passes,
        }
        atomic_write_npz(path.with_suffix(".npz"), arrays)
        atomic_write_text(path, json.dumps(meta, indent=2, allow_nan=False))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> CoveragePlan:
        """Read a plan written by `save`."""
        path = Path(path)
        if not path.exists():
            raise PlanError(f"plan file {path} does not exist; run `paintcell plan` first")
        meta = json.loads(path.read_text())
        if meta.get("format") != "paintcell.CoveragePlan/1":
            raise PlanError(f"{path} is not a paintcell plan (format {meta.get('format')!r})")
        npz_path = path.parent / meta["arrays"]
        if not npz_path.exists():
            raise PlanError(f"plan arrays {npz_path} are missing; re-run `paintcell plan`")
        with np.load(npz_path) as z:
            passes = []
            for i, mp in enumerate(meta["passes"]):
                kw = {name: z[f"p{i}_{name}"] for name in _PASS_ARRAYS}
                passes.append(PassPlan(
                    **kw,
                    side=int(mp["side"]),
                    index_width_m=_unnum(mp["index_width_m"]),
                    max_geodesic_curvature_1_m=_unnum(mp["max_geodesic_curvature_1_m"]),
                    nsd_constant_pct=_unnum(mp["nsd_constant_pct"]),
                    nsd_optimized_pct=_unnum(mp["nsd_optimized_pct"]),
                ))
        return cls(
            surface_name=meta["surface_name"],
            applicator=Applicator.from_dict(meta["applicator"]),
            passes=tuple(passes),
            start_rule=meta["start_rule"],
            settings=meta["settings"],
        )


def tcp_frames(positions: npt.ArrayLike, spray_axes: npt.ArrayLike,
               travel_dirs: npt.ArrayLike) -> np.ndarray:
    """(M, 4, 4) homogeneous TCP frames from positions (M,3) [m], spray axes and travel dirs.

    The travel direction is re-orthogonalized against the spray axis; y = z × x.
    """
    p = np.asarray(positions, float)
    z = np.asarray(spray_axes, float)
    z = z / np.linalg.norm(z, axis=1, keepdims=True)
    x = np.asarray(travel_dirs, float)
    x = x - np.sum(x * z, axis=1, keepdims=True) * z
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    T = np.zeros((len(p), 4, 4))
    T[:, :3, 0], T[:, :3, 1], T[:, :3, 2], T[:, :3, 3] = x, y, z, p
    T[:, 3, 3] = 1.0
    return T


def _num(x: float) -> float | None:
    return None if not np.isfinite(x) else float(x)


def _unnum(x: float | None) -> float:
    return float("nan") if x is None else float(x)
