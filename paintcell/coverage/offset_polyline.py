"""Polylines in 3-D: rows scaled to unit length, cumulative arc length [m], resampling at uniform
arc-length spacing, tangents, the geodesic curvature [1/m] of a curve lying in a surface, and the
samples that spike off a sampled curve.
"""

from __future__ import annotations

import warnings

import numpy as np
import numpy.typing as npt

from paintcell.core.errors import PlanError


def unit(v: np.ndarray) -> np.ndarray:
    """Rows of `v` (..., 3) scaled to unit length; zero rows stay zero."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def arc_length(points: npt.ArrayLike) -> np.ndarray:
    """(M,) cumulative polyline arc length from the first point [m]."""
    p = np.asarray(points, float)
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


def resample(points: npt.ArrayLike, normals: npt.ArrayLike, spacing_m: float,
             flags: npt.ArrayLike | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Resample a polyline at (nearly) uniform arc-length spacing, keeping both ends.

    points: (M, 3) [m]; normals: (M, 3) interpolated linearly and renormalized;
    flags: (M,) bool carried by nearest neighbour (default all True).
    Returns points (Q, 3), normals (Q, 3), flags (Q,).
    """
    p = np.asarray(points, float)
    n = np.asarray(normals, float)
    f = np.ones(len(p), bool) if flags is None else np.asarray(flags, bool)
    s = arc_length(p)
    if s[-1] <= 0:
        raise PlanError("cannot resample a curve of zero length; the pass degenerated to a point")
    q = np.linspace(0.0, s[-1], max(2, int(np.ceil(s[-1] / spacing_m - 1e-9)) + 1))
    pts = np.stack([np.interp(q, s, p[:, k]) for k in range(3)], axis=1)
    nrm = unit(np.stack([np.interp(q, s, n[:, k]) for k in range(3)], axis=1))
    idx = np.clip(np.searchsorted(s, q), 0, len(s) - 1)
    prev = np.clip(idx - 1, 0, len(s) - 1)
    nearest = np.where(np.abs(s[prev] - q) <= np.abs(s[idx] - q), prev, idx)
    return pts, nrm, f[nearest]


def tangents(points: npt.ArrayLike) -> np.ndarray:
    """(M, 3) unit tangents of a polyline by central differences (one-sided at the ends)."""
    p = np.asarray(points, float)
    t = np.gradient(p, axis=0)
    return unit(t)


def geodesic_curvature(points: npt.ArrayLike, normals: npt.ArrayLike,
                       smoothing_m: float = 0.1) -> np.ndarray:
    """(M,) signed geodesic curvature κ_g = (d²r/ds²) · (n × T) of a curve in the surface [1/m].

    points: (M, 3) curve on the surface [m]; normals: (M, 3) surface normals there.
    smoothing_m: second differences are taken at this arc-length step (a mesh section is faceted,
        so point-to-point differences are noisy); positive κ_g bends toward n × T (the left).
    """
    p = np.asarray(points, float)
    n = np.asarray(normals, float)
    s = arc_length(p)
    if len(p) < 3 or s[-1] <= 0:
        return np.zeros(len(p))
    m = max(3, int(np.ceil(s[-1] / smoothing_m)) + 1)
    q = np.linspace(0.0, s[-1], m)
    h = q[1] - q[0]
    r = np.stack([np.interp(q, s, p[:, k]) for k in range(3)], axis=1)
    nq = unit(np.stack([np.interp(q, s, n[:, k]) for k in range(3)], axis=1))
    t = unit(r[2:] - r[:-2])
    k_vec = (r[2:] - 2.0 * r[1:-1] + r[:-2]) / (h * h)
    kg = np.einsum("ij,ij->i", k_vec, np.cross(nq[1:-1], t))
    return np.interp(s, q[1:-1], kg)


def spikes(points: npt.ArrayLike, half_window: int, tol_m: float) -> np.ndarray:
    """(M,) bool: the points of a sampled curve (M, 3) [m] (NaN rows: no point) farther than
    `tol_m` [m] from where their neighbours put them: the coordinate-wise median of the finite
    points in a window symmetric about each point (`half_window` samples each way, fewer where
    the curve ends: an end sample is its own median and is never flagged; a missing sample
    drops its mirror image from the window too), taken in a frame of the curve's own there —
    along the window's chord (the sum of the differences of its mirrored pairs), toward the
    point across it, and normal to both — so that the flags do not depend on how the curve
    lies against the world axes. Each coordinate that runs monotonically over a symmetric
    window has its own value as the median, so a smooth curve sampled finely against the
    window is not flagged; a sample or a few that jump off the curve and back (a spike) are,
    and so is the apex of a corner sharper than about 2·asin(tol / (⌈h/2⌉ · spacing)) (84° at
    h = 6 and a tolerance of two spacings), which is then cut by at most a spacing. NaN rows are
    never flagged."""
    p = np.asarray(points, float)
    m, h = len(p), int(half_window)
    if m < 3 or h < 1:
        return np.zeros(m, bool)
    i = np.arange(m)
    off = np.arange(-h, h + 1)
    k = np.minimum(np.minimum(i, m - 1 - i), h)                  # symmetric half-width
    win = p[np.clip(i[:, None] + off[None, :], 0, m - 1)]         # (M, 2h + 1, 3)
    gone = (np.abs(off)[None, :] > k[:, None]) | np.isnan(win[:, :, 0])
    win[gone | gone[:, ::-1]] = np.nan                          # kept symmetric about the point
    with warnings.catch_warnings():                              # an all-NaN window: NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        chord = np.nansum(win[:, h + 1:] - win[:, :h][:, ::-1], axis=1)
        across = p - np.nanmean(win, axis=1)
        e1 = unit(np.nan_to_num(chord))
        flat = np.linalg.norm(e1, axis=1) < 0.5                  # no chord (a full turn-back)
        e1[flat] = unit(np.nan_to_num(across[flat]))
        e2 = unit(np.nan_to_num(across - np.sum(across * e1, axis=1)[:, None] * e1))
        lost = np.linalg.norm(e2, axis=1) < 0.5                  # the point lies on the chord
        axis = np.eye(3)[np.argmin(np.abs(e1), axis=1)]
        e2[lost] = unit(axis[lost] - np.sum(axis[lost] * e1[lost], axis=1)[:, None] * e1[lost])
        frame = np.stack([e1, e2, np.cross(e1, e2)], axis=1)      # (M, 3, 3): rows are axes
        rel = np.einsum("mkj,maj->mka", win - p[:, None, :], frame)
        dev = np.linalg.norm(np.nanmedian(rel, axis=1), axis=1)
    return np.isfinite(dev) & (dev > tol_m)
