"""The coverage plan: ordered spray passes with dense TCP samples, in the part frame.

A `CoveragePlan` is what `planning` hands to the robot side. It is pure data: every array is in
the part frame and SI units, and `save`/`load` round-trip it exactly (JSON for scalars and
settings, a sibling `.npz` for the arrays).
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.core.atomic_io import atomic_write_npz, atomic_write_text
from paintcell.core.errors import ApplicatorError, PlanError
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition_samples import GunSamples

_PASS_ARRAYS = ("positions", "spray_axes", "travel_dirs", "speeds_m_s", "times_s", "on_part",
                "paint_on")
_VECTOR_ARRAYS = ("positions", "spray_axes", "travel_dirs")
_BOOL_ARRAYS = ("on_part", "paint_on")

#: | |v| − 1 | allowed for spray axes and travel directions, and |x·z| between them: the
#: deposition model (`GunSamples`) holds them to the same 1e-6.
UNIT_TOL = 1e-6
#: Relative disagreement allowed between an interval of times_s and 2 Δs / (v_i + v_{i+1}): the
#: planner sets times from the speeds (round-off only, ~1e-15); plans resampled from a
#: jerk-limited time law agree to ~5e-5 (tests/test_execute.py); the inconsistency this guards
#: against was 3 % (QP segment times beside averaged sample speeds).
TIMING_RTOL = 1e-3
_FORMAT = "paintcell.CoveragePlan/1"


@dataclass(frozen=True, eq=False)
class PassPlan:
    """One spray pass: dense TCP samples along a curve at standoff from the surface.

    positions: (M, 3) TCP positions in the part frame [m] (surface point + h · normal).
    spray_axes: (M, 3) unit spray directions (tool +z), pointing at the surface.
    travel_dirs: (M, 3) unit travel directions (tool +x), orthogonal to the spray axis.
    speeds_m_s: (M,) planned TCP speed at each sample [m/s], > 0.
    times_s: (M,) planned time of each sample from the start of the pass [s], increasing.
        Timing is one definition for the film and for the robot: between samples the TCP moves
        at constant tangential acceleration (speed² linear in arc length, what
        `paintcell.motion.trajectory`
        follows), so each interval is the trapezoid rule in time on the TCP polyline,
        Δt_i = 2 Δs_i / (v_i + v_{i+1}) with Δs_i = |positions[i+1] − positions[i]|; checked to
        `TIMING_RTOL`.
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
        arrays = {}
        for name in _PASS_ARRAYS:
            arr = np.asarray(getattr(self, name))
            if name in _BOOL_ARRAYS:
                if arr.dtype != bool:
                    raise PlanError(f"pass array {name} must be bool, got dtype {arr.dtype}; "
                                    "give True/False flags")
            else:
                try:
                    arr = arr.astype(float, copy=False)
                except (TypeError, ValueError) as exc:
                    raise PlanError(f"pass array {name} is not numeric ({exc}); give floats"
                                    ) from exc
            arrays[name] = arr
        pos = arrays["positions"]
        if pos.ndim != 2 or pos.shape[1] != 3:
            raise PlanError(f"pass positions must have shape (M, 3), got {pos.shape}")
        m = len(pos)
        if m < 2:
            raise PlanError(f"a pass needs at least 2 samples, got {m}; plan a longer pass")
        for name, arr in arrays.items():
            want = (m, 3) if name in _VECTOR_ARRAYS else (m,)
            if arr.shape != want:
                raise PlanError(f"pass array {name} has shape {arr.shape}, expected {want} "
                                "(one row a sample)")
            if arr.dtype != bool and not np.all(np.isfinite(arr)):
                raise PlanError(f"pass array {name} contains NaN or inf; re-plan the pass")
        axes, trav = arrays["spray_axes"], arrays["travel_dirs"]
        for name, v in (("spray_axes", axes), ("travel_dirs", trav)):
            err = float(np.max(np.abs(np.linalg.norm(v, axis=1) - 1.0)))
            if err > UNIT_TOL:
                raise PlanError(f"pass {name} must be unit vectors (| |v| - 1 | = {err:.3g} > "
                                f"{UNIT_TOL:g}); normalize them")
        dots = float(np.max(np.abs(np.sum(axes * trav, axis=1))))
        if dots > UNIT_TOL:
            raise PlanError(f"pass travel_dirs must be orthogonal to spray_axes (|x·z| = "
                            f"{dots:.3g} > {UNIT_TOL:g}); project them onto the tool xy plane")
        speeds, times = arrays["speeds_m_s"], arrays["times_s"]
        if np.any(speeds <= 0):
            raise PlanError("pass speeds must be positive [m/s]; check v_min/v_max settings")
        dt = np.diff(times)
        if np.any(dt <= 0):
            raise PlanError("pass times must strictly increase; re-plan the pass")
        ds = np.linalg.norm(np.diff(pos, axis=0), axis=1)
        dt_speed = 2.0 * ds / (speeds[1:] + speeds[:-1])
        rel = float(np.max(np.abs(dt_speed - dt) / dt))
        if rel > TIMING_RTOL:
            raise PlanError(f"pass times_s and speeds_m_s disagree by {100 * rel:.3g} % on a "
                            f"segment (> {100 * TIMING_RTOL:g} %); set times_s from the speeds "
                            "by Δt = 2 Δs / (v_i + v_i+1) (`times_from_speeds`)")
        for name, arr in arrays.items():
            object.__setattr__(self, name, arr)

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample [s]."""
        return float(self.times_s[-1] - self.times_s[0])

    @property
    def length_m(self) -> float:
        """Polyline length of the TCP path [m]."""
        return float(np.linalg.norm(np.diff(self.positions, axis=0), axis=1).sum())

    @property
    def max_turn_deg(self) -> float:
        """Largest angle [°] between consecutive segments of the TCP path: the sharpest turn a
        robot must follow between two samples (0 for a straight pass)."""
        d = np.diff(self.positions, axis=0)
        n = np.linalg.norm(d, axis=1)
        d = d[n > 1e-12] / n[n > 1e-12, None]
        if len(d) < 2:
            return 0.0
        c = np.clip(np.einsum("ij,ij->i", d[1:], d[:-1]), -1.0, 1.0)
        return float(np.degrees(np.arccos(c)).max())

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

    def tcp_frames(self, pass_index: int, keep_roll: bool = True) -> np.ndarray:
        """(M, 4, 4) TCP poses `T_part_tcp` of one pass: z = spray axis, x = ± travel with the
        sign of `roll_signs` (the bell keeps its roll from one pass to the next); keep_roll=False:
        x = travel (what a free-spin IK starts each pass from,
        `paintcell.motion.trajectory.TrajectorySettings.ik_free_spin`)."""
        p = self.passes[pass_index]
        sign = self.roll_signs()[pass_index] if keep_roll else 1.0
        return tcp_frames(p.positions, p.spray_axes, sign * p.travel_dirs)

    def roll_signs(self) -> np.ndarray:
        """(P,) ±1 per pass: the TCP x axis is sign × travel. The spray pattern is even in x and
        y (`paintcell.paint.deposition`), so a bell turned half a turn about its axis lays the
        same film; what the sign spares is the wrist's half turn at every turn-around of a
        back-and-forth family (x = travel flips with the travel). The first pass keeps x =
        travel; each later pass takes the sign that points its first x the way the previous
        pass's last x points."""
        signs = np.ones(len(self.passes))
        for i in range(1, len(self.passes)):
            prev = signs[i - 1] * self.passes[i - 1].travel_dirs[-1]
            signs[i] = -1.0 if float(prev @ self.passes[i].travel_dirs[0]) < 0 else 1.0
        return signs

    # --- persistence -----------------------------------------------------------------------
    def _arrays(self) -> dict[str, np.ndarray]:
        return {f"p{i}_{name}": getattr(p, name)
                for i, p in enumerate(self.passes) for name in _PASS_ARRAYS}

    def content_digest(self) -> str:
        """Short sha256 of the plan's arrays (what `save` stores as `arrays_sha256`); trajectories
        and traces carry it so that files of different runs are never mixed up."""
        return arrays_digest(self._arrays())

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write `path` (JSON) and `path` with suffix `.npz` (arrays), each atomically."""
        path = Path(path)
        arrays = self._arrays()
        meta_passes = []
        for p in self.passes:
            meta_passes.append({
                "side": p.side,
                "index_width_m": _num(p.index_width_m),
                "max_geodesic_curvature_1_m": _num(p.max_geodesic_curvature_1_m),
                "nsd_constant_pct": _num(p.nsd_constant_pct),
                "nsd_optimized_pct": _num(p.nsd_optimized_pct),
                "n_samples": len(p.times_s),
                "duration_s": p.duration_s,
                "length_m": p.length_m,
                "max_turn_deg": p.max_turn_deg,
            })
        meta = {
            "format": _FORMAT,
            "frame": "part",
            "surface_name": self.surface_name,
            "applicator": self.applicator.to_dict(),
            "start_rule": self.start_rule,
            "settings": self.settings,
            "paint_time_s": self.paint_time_s,
            "arrays": path.with_suffix(".npz").name,
            "arrays_sha256": arrays_digest(arrays),
            "passes": meta_passes,
        }
        atomic_write_npz(path.with_suffix(".npz"), arrays)
        atomic_write_text(path, json.dumps(meta, indent=2, allow_nan=False))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> CoveragePlan:
        """Read a plan written by `save`; PlanError (naming the file) when the JSON is unreadable
        or the `.npz` beside it does not belong to it."""
        path = Path(path)
        if not path.exists():
            raise PlanError(f"plan file {path} does not exist; run `paintcell plan` first")
        rerun = "re-run `paintcell plan`"
        try:
            meta = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise PlanError(f"plan file {path} is not valid JSON (truncated or corrupt: {exc}); "
                            f"{rerun}") from exc
        if not isinstance(meta, dict) or meta.get("format") != _FORMAT:
            fmt = meta.get("format") if isinstance(meta, dict) else None
            raise PlanError(f"{path} is not a paintcell plan (format {fmt!r}); give a plan.json "
                            f"written by `paintcell plan` or {rerun}")
        try:
            npz_path = path.parent / meta["arrays"]
            if not npz_path.exists():
                raise PlanError(f"plan arrays {npz_path} are missing; {rerun}")
            with np.load(npz_path) as z:
                arrays = {k: z[k] for k in z.files}
            digest = meta.get("arrays_sha256")      # absent in plans saved before it existed
            if digest is not None and digest != arrays_digest(arrays):
                raise PlanError(f"plan arrays {npz_path} do not match {path} (content hash "
                                f"differs: a file of another plan run?); {rerun}")
            passes = []
            for i, mp in enumerate(meta["passes"]):
                kw = {name: arrays[f"p{i}_{name}"] for name in _PASS_ARRAYS}
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
        except PlanError as exc:
            if str(path) in str(exc):
                raise
            raise PlanError(f"plan {path}: {exc}") from exc
        except (KeyError, TypeError, ValueError, OSError, zipfile.BadZipFile,
                ApplicatorError) as exc:
            raise PlanError(f"plan {path} and its arrays do not match or are corrupt "
                            f"({type(exc).__name__}: {exc}); {rerun}") from exc


def times_from_speeds(positions: npt.ArrayLike, speeds_m_s: npt.ArrayLike) -> np.ndarray:
    """(M,) sample times [s] from 0 of a pass at constant tangential acceleration between samples.

    positions: (M, 3) TCP positions [m]; speeds_m_s: (M,) TCP speeds [m/s] > 0.
    Each interval is Δt_i = 2 Δs_i / (v_i + v_{i+1}) (the `PassPlan` timing definition).
    """
    p = np.asarray(positions, float)
    v = np.asarray(speeds_m_s, float)
    ds = np.linalg.norm(np.diff(p, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(2.0 * ds / (v[1:] + v[:-1]))])


def arrays_digest(arrays: dict[str, np.ndarray]) -> str:
    """Short sha256 (16 hex digits) of named arrays: names, dtypes, shapes and bytes.

    Hashes content, not the `.npz` file (zip entries carry a time stamp), so the JSON that
    stores it is byte-for-byte reproducible.
    """
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


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
