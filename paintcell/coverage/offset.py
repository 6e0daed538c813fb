"""Curves within a surface: plane sections, indexing curves and geodesic offsets (paper §2.3, §4).

Every curve here is a planar section of the triangle mesh: the start curve (a section plane
orthogonal to the average normal's tangent plane), the *indexing curve* at a pass sample (the
section by the plane through the sample orthogonal to the pass tangent, which contains the surface
normal), and the in-surface continuation of a pass past its last offset point (the normal section
containing the pass tangent). Offsets are measured as arc length along indexing curves — geodesic
distance in the surface, not a straight shift: on a cylinder, passes around it are spaced by arc.

Crossing points lie on mesh edges; their normals are the linear interpolation of the vertex
normals (renormalized). Beyond the surface boundary an indexing curve is continued along its end
tangent with the end normal (the "virtual extension" that overspray and edge passes paint on).
That continuation is only an extension of the surface *beside* the pass where the curve leaves
through a boundary that crosses it. A curve that leaves through a boundary running along it (a
pass sample on, or next to, the boundary the pass itself ends at: the section plane nearly
contains that boundary, and whether the section hugs it or leaves at once is decided by
round-off) says nothing about the surface there; `walk` gives no offset beyond such an end.

Plane sections of the mesh are in `paintcell.coverage.offset_sections`, polyline arc
length, resampling and geodesic curvature in `paintcell.coverage.offset_polyline`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from paintcell.core.errors import PlanError
from paintcell.coverage.offset_polyline import (
    arc_length,
    unit,
)
from paintcell.coverage.offset_sections import (
    SurfaceGeometry,
    dedupe_points,
    order_components,
    section_crossings,
    signed_distances,
)

__all__ = [
    "IndexingCurve",
    "check_offset_order",
    "curve_through",
    "indexing_curves",
    "stray_samples",
    "walk",
]

#: An offset chord running backward by more than this fraction of its source step is a reversal
#: (a cusp: the offset self-intersects) [-].
_REVERSAL_FRACTION = 0.02
#: Most samples of an offset `stray_samples` may leave out before its reversal counts as a cusp,
#: and at most this share of its samples [-]: on a short offset (a narrow bell's pass over a
#: hood's tip, 8 samples) one stray is a fold forming, and the passes mended there crossed
#: their neighbours two offsets on.
MAX_STRAY_SAMPLES = 2
MAX_STRAY_FRACTION = 0.05
#: Length over which an end tangent is measured for the straight continuation past a boundary [m].
_END_TANGENT_M = 0.01
#: A curve leaves the surface *along* the boundary (not across it) when its end tangent is within
#: this angle of the boundary's direction there: 45°, the boundary is then closer to the indexing
#: direction than to the pass direction, so it is the boundary the pass ends at, not its side.
_ALONG_BOUNDARY_COS = float(np.cos(np.pi / 4))


@dataclass(frozen=True, eq=False)
class IndexingCurve:
    """A curve of the surface through a source point, parameterized by signed arc length.

    points: (K, 3) polyline on the surface [m]; normals: (K, 3) unit normals;
    s: (K,) arc length [m], increasing, 0 at the source point (its foot on the polyline);
    positive s lies on the requested side ("right" of the pass for an indexing curve).
    extends: (before the first point, after the last) whether the straight virtual extension
        beyond that end continues the surface beside the pass: False where the curve left the
        surface along the boundary (see the module docstring); `walk` gives no offset there.
    """

    points: np.ndarray
    normals: np.ndarray
    s: np.ndarray
    extends: tuple[bool, bool] = (True, True)

    @property
    def s_min(self) -> float:
        """Arc length of the first point (≤ 0) [m]: the boundary on the left side."""
        return float(self.s[0])

    @property
    def s_max(self) -> float:
        """Arc length of the last point (≥ 0) [m]: the boundary on the right side."""
        return float(self.s[-1])

    def sample(self, s_query: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points (Q, 3), normals (Q, 3) and `inside` (Q,) bool at arc lengths s_query (Q,) [m].

        Beyond either end the curve continues straight along its end tangent (measured over the
        last `_END_TANGENT_M`) with the end normal: the virtual extension of the surface.
        """
        q = np.atleast_1d(np.asarray(s_query, float))
        s, p, n = self.s, self.points, self.normals
        pts = np.stack([np.interp(q, s, p[:, k]) for k in range(3)], axis=1)
        nrm = unit(np.stack([np.interp(q, s, n[:, k]) for k in range(3)], axis=1))
        lo, hi = q < s[0], q > s[-1]
        if lo.any():
            t0 = unit(p[0] - self._at(s[0] + min(_END_TANGENT_M, s[-1] - s[0])))
            pts[lo] = p[0] + (s[0] - q[lo])[:, None] * t0
            nrm[lo] = n[0]
        if hi.any():
            t1 = unit(p[-1] - self._at(s[-1] - min(_END_TANGENT_M, s[-1] - s[0])))
            pts[hi] = p[-1] + (q[hi] - s[-1])[:, None] * t1
            nrm[hi] = n[-1]
        return pts, nrm, ~(lo | hi)

    def _at(self, s0: float) -> np.ndarray:
        return np.array([np.interp(s0, self.s, self.points[:, k]) for k in range(3)])

    def end_tangents(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit outward tangents (3,) at the first and the last point: the directions of the
        virtual extension beyond each end (measured over the last `_END_TANGENT_M`)."""
        span = min(_END_TANGENT_M, self.s_max - self.s_min)
        return (unit(self.points[0] - self._at(self.s_min + span)),
                unit(self.points[-1] - self._at(self.s_max - span)))

    def reversed(self) -> IndexingCurve:
        """The same curve with s negated (its left and right sides swapped)."""
        return IndexingCurve(self.points[::-1].copy(), self.normals[::-1].copy(), -self.s[::-1],
                             (self.extends[1], self.extends[0]))


def _leaves_across(geom: SurfaceGeometry, edge: int, tangent: np.ndarray) -> bool:
    """Whether a section ending on mesh edge `edge` with outward tangent (3,) leaves the surface
    across the boundary (True; also for an interior edge or no boundary data) rather than along
    it (within 45° of the boundary's direction there)."""
    if geom.boundary_dir is None or geom.edge_faces[edge, 1] >= 0:
        return True
    return bool(abs(float(geom.boundary_dir[edge] @ tangent)) < _ALONG_BOUNDARY_COS)


def _foot_on_polyline(points: np.ndarray, p: np.ndarray) -> tuple[float, float]:
    """(arc length of the closest point of the polyline to p [m], distance [m])."""
    a, b = points[:-1], points[1:]
    ab = b - a
    l2 = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.where(l2 > 0, l2, 1.0), 0.0, 1.0)
    foot = a + t[:, None] * ab
    dist = np.linalg.norm(foot - p, axis=1)
    i = int(np.argmin(dist))
    seg = np.sqrt(l2)
    s_cum = np.concatenate([[0.0], np.cumsum(seg)])
    return float(s_cum[i] + t[i] * seg[i]), float(dist[i])


def curve_through(geom: SurfaceGeometry, point: npt.ArrayLike, plane_normal: npt.ArrayLike,
                  forward: npt.ArrayLike, *, max_gap_m: float | None = None,
                  signed_d: np.ndarray | None = None) -> IndexingCurve | None:
    """The section component through `point`, as arc length from it, positive toward `forward`.

    point: (3,) a point on (or within `max_gap_m` of) the surface [m];
    plane_normal: (3,) the section plane's normal; forward: (3,) the direction of increasing s.
    max_gap_m: refuse (return None) when the section passes farther than this from the point
        (default: two mesh edge lengths). signed_d: precomputed signed vertex distances (N,).
    Closed sections are cut open opposite the point. Returns None when there is no section there.
    """
    p = np.asarray(point, float)
    nrm = unit(np.asarray(plane_normal, float))
    d = signed_distances(geom, p, nrm) if signed_d is None else signed_d
    cross, pts, nn = section_crossings(geom, d)
    if len(cross) < 2:
        # a plane through a boundary edge of the mesh touches it without crossing: nudge it
        # inward by a negligible distance so the boundary row itself becomes the section
        eps = 1e-9 * geom.edge_length_m
        if d.min() >= -eps:
            d = d - eps
        elif d.max() <= eps:
            d = d + eps
        cross, pts, nn = section_crossings(geom, d)
        if len(cross) < 2:
            return None
    near = int(np.argmin(np.linalg.norm(pts - p, axis=1)))
    (order, closed), = order_components(geom, d, cross, wanted=np.array([near]))
    cp, cn = dedupe_points(pts[order], nn[order])
    if len(cp) < 2:
        return None
    if closed:  # cut the loop at the point farthest from the source point
        far = int(np.argmax(np.linalg.norm(cp - p, axis=1)))
        cp, cn = np.roll(cp, -far, axis=0), np.roll(cn, -far, axis=0)
    s0, gap = _foot_on_polyline(cp, p)
    if gap > (2.0 * geom.edge_length_m if max_gap_m is None else max_gap_m):
        return None
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(cp, axis=0), axis=1))]) - s0
    curve = IndexingCurve(cp, cn, s)
    if not closed:      # how each end leaves the surface: across the boundary or along it
        t0, t1 = curve.end_tangents()
        curve = IndexingCurve(cp, cn, s, (_leaves_across(geom, int(cross[order[0]]), t0),
                                          _leaves_across(geom, int(cross[order[-1]]), t1)))
    # orientation: the local tangent at the source point must point along `forward`
    i = int(np.clip(np.searchsorted(s, 0.0), 1, len(s) - 1))
    if np.dot(cp[i] - cp[i - 1], np.asarray(forward, float)) < 0:
        curve = curve.reversed()
    return curve


def indexing_curves(geom: SurfaceGeometry, points: npt.ArrayLike, tangents: npt.ArrayLike,
                    normals: npt.ArrayLike) -> list[IndexingCurve | None]:
    """Indexing curve at each pass sample: the section by the plane through the sample orthogonal
    to the pass tangent (it contains the surface normal), s > 0 on the pass's right (T × n).

    points: (S, 3) foot points on the surface [m]; tangents: (S, 3) pass tangents;
    normals: (S, 3) surface normals. Returns S curves (None where no section passes the point).
    """
    p = np.asarray(points, float)
    n = unit(np.asarray(normals, float))
    t = np.asarray(tangents, float)
    t = unit(t - np.sum(t * n, axis=1, keepdims=True) * n)
    right = np.cross(t, n)
    d_all = geom.vertices @ t.T - np.sum(p * t, axis=1)      # (N, S) signed distances
    return [curve_through(geom, p[i], t[i], right[i], signed_d=d_all[:, i])
            for i in range(len(p))]


def walk(curves: list[IndexingCurve | None], distance_m: float | np.ndarray
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (S, 3), normals (S, 3) and inside (S,) reached at arc length `distance_m` along each
    curve (scalar or (S,) [m], signed: > 0 to the right). Missing curves, and distances beyond
    an end the curve left along the boundary (`IndexingCurve.extends`), give NaN points and
    inside = False."""
    m = len(curves)
    dist = np.broadcast_to(np.asarray(distance_m, float), (m,))
    pts = np.full((m, 3), np.nan)
    nrm = np.full((m, 3), np.nan)
    inside = np.zeros(m, bool)
    for i, c in enumerate(curves):
        if c is None:
            continue
        if (dist[i] < c.s_min and not c.extends[0]) or (dist[i] > c.s_max and not c.extends[1]):
            continue
        a, b, ok = c.sample(dist[i:i + 1])
        pts[i], nrm[i], inside[i] = a[0], b[0], ok[0]
    return pts, nrm, inside


def _progress(source_points: np.ndarray, offset_points: np.ndarray) -> np.ndarray:
    """(S − 1,) forward progress of each chord of the offset along its source step, as a
    fraction of the step [-] (1: in step; < 0: backward; NaN where either end is not finite)."""
    ds = np.diff(source_points, axis=0)
    do = np.diff(offset_points, axis=0)
    step = np.linalg.norm(ds, axis=1)
    with np.errstate(invalid="ignore"):
        return np.einsum("ij,ij->i", ds, do) / np.where(step > 0, step * step, 1.0)


def _reversals(source_points: np.ndarray, offset_points: np.ndarray) -> np.ndarray:
    """(S − 1,) bool: the chords of the offset that run backward along their source step by
    more than `_REVERSAL_FRACTION` of it (False where either end is not finite). A few 0.1 mm
    back is the noise of mesh sections near a focal point; a real cusp goes back by a good part
    of a step."""
    with np.errstate(invalid="ignore"):
        return _progress(source_points, offset_points) < -_REVERSAL_FRACTION


def stray_samples(source_points: np.ndarray, offset_points: np.ndarray,
                  max_stray: int = MAX_STRAY_SAMPLES) -> np.ndarray | None:
    """(S,) bool: at most `max_stray` samples (and `MAX_STRAY_FRACTION` of those with finite points)
    of an offset that, left out, leave it with no reversal (`check_offset_order` on the samples
    with finite points); None when no such set exists (a cusp: many samples run back). An indexing
    curve that turns at an opening's corner can land behind its neighbours' offsets while theirs
    run on in order (a door's window frame): left out, the neighbours bridge the gap, as they do a
    sample whose curve left the surface. Chosen greedily: each time the sample, of those at a
    reversed chord, whose removal leaves the fewest reversals, then the surest progress on the
    chord that makes least (the sample out of line rather than a neighbour that then coincides with
    it), then the first."""
    src = np.asarray(source_points, float)
    pts = np.asarray(offset_points, float)
    finite = np.all(np.isfinite(pts), axis=1)
    max_stray = min(max_stray, int(MAX_STRAY_FRACTION * finite.sum()))
    drop = np.zeros(len(pts), bool)
    while True:
        idx = np.flatnonzero(finite & ~drop)
        bad = np.flatnonzero(_reversals(src[idx], pts[idx]))
        if len(bad) == 0:
            return drop
        if drop.sum() == max_stray:
            return None
        best: tuple[int, float, int] | None = None
        for j in np.unique(np.concatenate([idx[bad], idx[bad + 1]])):
            rest = idx[idx != j]
            prog = _progress(src[rest], pts[rest])
            least = float(np.nanmin(prog)) if prog.size else 1.0
            key = (int(np.sum(prog < -_REVERSAL_FRACTION)), -least, int(j))
            if best is None or key < best:
                best = key
        assert best is not None
        drop[best[2]] = True


def check_offset_order(source_points: np.ndarray, offset_points: np.ndarray,
                       label: str) -> None:
    """Refuse an offset that reverses direction (a cusp/swallowtail: it self-intersects).

    source_points / offset_points: (S, 3) corresponding points of the current pass and its
    offset [m]. Raises PlanError naming where along the pass it happened.
    """
    bad = _reversals(np.asarray(source_points, float), np.asarray(offset_points, float))
    if np.any(bad):
        i = int(np.argmax(bad))
        s = float(arc_length(source_points)[i])
        raise PlanError(f"{label} self-intersects (the offset reverses direction {s:.3f} m along "
                        "the current pass; geodesic curvature too high): narrow the index range "
                        "(w_max_m) or choose another start-curve orientation")
