"""Coat uniformity numbers: area-weighted mean, σ/μ (the paper's measure), min, max, in-tolerance
fraction, transfer efficiency, and a boundary-band mask for evaluating away from the edges."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from paintcell.core.errors import PaintcellError


class MetricsError(PaintcellError):
    """Inputs to a uniformity metric are inconsistent or empty."""


@dataclass(frozen=True)
class UniformityMetrics:
    """Area-weighted statistics of a film over a region.

    mean_m: area-weighted mean thickness μ [m].
    nsd_pct: normalized standard deviation σ/μ (area-weighted, population) [%].
    min_m / max_m: extreme thickness in the region [m].
    within_tolerance_fraction: area fraction with |t − target| ≤ tolerance · target, in [0, 1].
    area_m2: area of the region [m²].
    target_m: the target used for the tolerance window [m] (the mean unless given).
    """

    mean_m: float
    nsd_pct: float
    min_m: float
    max_m: float
    within_tolerance_fraction: float
    area_m2: float
    target_m: float = float("nan")

    def to_dict(self) -> dict[str, float]:
        """Plain-float dict (JSON-safe for finite values)."""
        return {k: float(v) for k, v in asdict(self).items()}


def uniformity(thickness_m: npt.ArrayLike, areas_m2: npt.ArrayLike,
               mask: npt.ArrayLike | None = None, target_m: float | None = None,
               tolerance: float = 0.10) -> UniformityMetrics:
    """Uniformity of a film over the whole part or a masked region.

    thickness_m: (N,) film thickness per vertex [m]; areas_m2: (N,) vertex areas [m²];
    mask: optional (N,) bool, True for vertices in the evaluation region;
    target_m: target thickness [m] of the tolerance window (default: the area-weighted mean);
    tolerance: half-width of the window as a fraction of the target (0.10 = ±10 %).
    """
    t = np.asarray(thickness_m, float).reshape(-1)
    w = np.asarray(areas_m2, float).reshape(-1)
    if len(t) != len(w):
        raise MetricsError(f"thickness has {len(t)} entries but areas {len(w)}; give one a vertex")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(w))) or np.any(w < 0):
        raise MetricsError("thickness and areas must be finite and areas >= 0")
    if not tolerance >= 0:
        raise MetricsError(f"tolerance = {tolerance} must be >= 0 (a fraction of the target)")
    if mask is not None:
        m = np.asarray(mask).reshape(-1)
        if m.dtype != bool or len(m) != len(t):
            raise MetricsError(f"mask must be a bool array of length {len(t)}")
        t, w = t[m], w[m]
    area = float(w.sum())
    if len(t) == 0 or area <= 0:
        raise MetricsError("the evaluation region is empty (no vertex or zero area); widen it")
    mean = float(np.dot(w, t) / area)
    var = float(np.dot(w, (t - mean) ** 2) / area)
    if not mean > 0:
        # σ/μ is undefined and every vertex would sit "within tolerance" of a zero target
        raise MetricsError("mean film thickness is zero: nothing was painted in the evaluation "
                           "region; check the plan, the mask and the gun samples")
    nsd = 100.0 * np.sqrt(var) / mean
    target = mean if target_m is None else float(target_m)
    inside = np.abs(t - target) <= tolerance * abs(target)
    return UniformityMetrics(
        mean_m=mean, nsd_pct=float(nsd), min_m=float(t.min()), max_m=float(t.max()),
        within_tolerance_fraction=float(w[inside].sum() / area), area_m2=area, target_m=target)


def transfer_efficiency(thickness_m: npt.ArrayLike, areas_m2: npt.ArrayLike,
                        emitted_volume_m3: float) -> float:
    """Paint on the part ÷ paint emitted: Σ t·A / V_emitted (film volumes) [fraction].

    thickness_m: (N,) [m]; areas_m2: (N,) [m²]; emitted_volume_m3: film volume the bell emitted
    while painting (`Applicator.emitted_flow_m3_s` × paint-on time) [m³].
    """
    t = np.asarray(thickness_m, float).reshape(-1)
    w = np.asarray(areas_m2, float).reshape(-1)
    if len(t) != len(w):
        raise MetricsError(f"thickness has {len(t)} entries but areas {len(w)}")
    if not emitted_volume_m3 > 0:
        raise MetricsError(f"emitted_volume_m3 = {emitted_volume_m3} must be > 0")
    return float(np.dot(t, w) / emitted_volume_m3)


def boundary_band_mask(points: npt.ArrayLike, boundary_points: npt.ArrayLike,
                       band_m: float) -> np.ndarray:
    """(N,) bool: True for points farther than `band_m` [m] from every boundary point.

    points: (N, 3) [m]; boundary_points: (B, 3) samples of the part's boundary [m] (e.g. the
    vertices of the mesh's boundary edges, `boundary_vertices(faces)`); straight-line distance.
    """
    p = np.asarray(points, float).reshape(-1, 3)
    b = np.asarray(boundary_points, float).reshape(-1, 3)
    if band_m < 0:
        raise MetricsError(f"band_m = {band_m} must be >= 0 [m]")
    if len(b) == 0:
        return np.ones(len(p), bool)
    dist, _ = cKDTree(b).query(p, k=1)
    return np.asarray(dist > band_m)


def boundary_vertices(faces: npt.ArrayLike) -> np.ndarray:
    """Sorted indices of the vertices on boundary edges (edges used by exactly one triangle).

    faces: (F, 3) int triangle indices.
    """
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    return np.unique(uniq[counts == 1])
