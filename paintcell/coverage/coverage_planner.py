"""Algorithm 1's state for one surface (`Planner`) and a pass before timing (`PassGeom`): mesh
connectivity, pass extension within the surface, indexing curves, geodesic fallback offsets and the
index-width choice of paper §4 (lengths in m)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from paintcell.core.errors import PlanError
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.coverage.index_width import (
    WidthSearch,
    choose_constant_width,
    cross_profiles,
    planar_index_width,
    search_range,
    search_widths,
)
from paintcell.coverage.offset import IndexingCurve, curve_through, indexing_curves
from paintcell.coverage.offset_polyline import arc_length, resample, spikes, tangents, unit
from paintcell.coverage.offset_sections import SurfaceGeometry
from paintcell.paint.applicator import Applicator

#: An edge pass's samples are checked against the median of their neighbours within this
#: fraction of the spray footprint radius (a 0.46 m footprint: ±115 mm, ±5 samples at 20 mm) …
SPIKE_WINDOW_FRACTION = 0.25
#: … and dropped farther than this many sample spacings from it (40 mm at 20 mm): the pass
#: is then drawn straight across where they were.
SPIKE_TOL_SPACINGS = 2.0


@dataclass(eq=False)
class PassGeom:
    """A pass in the surface before timing: foot points (on-part core with in-surface
    extensions), normals, on_part flags, side index, width from its predecessor."""

    foot: np.ndarray
    normals: np.ndarray
    on_part: np.ndarray
    side: int
    width_m: float
    edge: bool = False
    curves: list[IndexingCurve | None] | None = None
    info: dict[str, Any] = field(default_factory=dict)
    source: tuple[list[IndexingCurve | None], float] | None = None
    #: straight continuation beyond (head, tail) before the overspray [m]: the stretch of the
    #: source pass whose offsets are undefined (curves that left along the boundary)
    extra_m: tuple[float, float] = (0.0, 0.0)
    #: TCP samples with overspray and their speeds, set when the pass is timed (Algorithm 1:
    #: right after the pass is generated)
    timing: dict[str, Any] | None = None


def mirrored_curve(c: IndexingCurve | None) -> IndexingCurve | None:
    """The indexing curve traversed the other way (None stays None)."""
    return None if c is None else c.reversed()


def _length_to(piece: np.ndarray, start: np.ndarray) -> float:
    """Arc length [m] of the polyline from `start` (3,) through the points of `piece` (K, 3)."""
    return float(arc_length(np.vstack([start[None], piece]))[-1]) if len(piece) else 0.0


def edge_spikes(pl: Planner, points: np.ndarray) -> np.ndarray:
    """(S,) bool: the samples of an edge pass (S, 3) [m] (NaN: none) that jump off its line and
    back (`paintcell.coverage.offset_polyline.spikes` at the footprint's scale). An edge pass
    lies wholly on the virtual extension past the part's edge: each sample is its own indexing
    curve continued straight from where that curve left the part, and where the edge turns a
    corner (a frame member meeting its panel) one curve can leave through the member's side and
    go on in another direction — a sample 0.1–0.2 m off the line and back, a 170° turn of the
    pass that piles film where it dips onto the part."""
    st = pl.st
    h = int(np.ceil(SPIKE_WINDOW_FRACTION * pl.app.footprint_radius_m / st.sample_spacing_m))
    return spikes(points, h, SPIKE_TOL_SPACINGS * st.sample_spacing_m)


def outside_span(foot: np.ndarray, inside: np.ndarray, max_gap_m: float) -> tuple[int, int]:
    """Index range [lo, hi] of an offset (S, 3) kept as a pass: its first..last inside sample,
    widened over the finite points just beyond them (outside the part, on the virtual extension)
    as long as consecutive finite points lie within `max_gap_m` [m] of each other (an offset
    with undefined points between is cut there). (0, -1) when nothing is inside."""
    ok = np.all(np.isfinite(foot), axis=1)
    idx = np.flatnonzero(inside & ok)
    if len(idx) == 0:
        return 0, -1
    fin = np.flatnonzero(ok)
    gap = np.linalg.norm(np.diff(foot[fin], axis=0), axis=1) > max_gap_m
    run = np.concatenate([[0], np.cumsum(gap)])           # run label of each finite point
    i_first, i_last = np.searchsorted(fin, idx[0]), np.searchsorted(fin, idx[-1])
    lo = int(fin[np.flatnonzero(run == run[i_first])[0]])
    hi = int(fin[np.flatnonzero(run == run[i_last])[-1]])
    return lo, hi


class Planner:
    """Algorithm 1 state for one surface (mesh connectivity, cross-profile cache)."""

    def __init__(self, surface: Any, app: Applicator, settings: PlannerSettings) -> None:
        self.surface = surface
        self.app = app
        self.st = settings
        self.geom = SurfaceGeometry.from_surface(surface)
        self.widths = search_range(settings.w_min_m, settings.w_max_m, settings.w_res_m)
        k = max(1, settings.future_grid_n)
        self.future = np.unique(self.widths[np.rint(np.linspace(0, len(self.widths) - 1, k))
                                            .astype(int)])
        r = app.footprint_radius_m
        step = settings.w_res_m
        reach = settings.w_max_m + r + step
        self.g0 = int(np.ceil(reach / step))
        self.gun_s = (np.arange(2 * self.g0 + 1) - self.g0) * step
        self.point_s = np.arange(-settings.w_max_m, settings.w_max_m + 1e-9,
                                 settings.profile_spacing_m)
        self.cache: dict[bytes, np.ndarray] = {}
        self.cache_hits = 0
        self.diag = float(np.linalg.norm(np.ptp(surface.vertices, axis=0)))
        self.speed_settings = settings.speed_settings()
        self.speed_caps: dict[int, np.ndarray] = {}
        self.tool_x: dict[int, np.ndarray] = {}
        self._nominal_width: float | None = None
        # geodesic.HeatGeodesics, built when first needed
        self.heat: Any = None
        self.smooth_scale = 0.0        # smoothing scale of the planning surface [m]

    @property
    def nominal_width(self) -> float:
        """The bell's planar Fig. 5 width in SR [m]: the band scale of the start curve, whose
        neighbours do not exist yet when Algorithm 1 optimizes its speed."""
        if self._nominal_width is None:
            st = self.st
            self._nominal_width = planar_index_width(self.app, st.w_min_m, st.w_max_m, st.w_res_m,
                                                     st.u_max, st.width_tolerance_m).width_m
        return self._nominal_width

    def geodesic_offset(self, p: PassGeom, distance_m: float
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Heat-method offset of pass `p` at signed `distance_m` [m]: points, normals, inside
        (all True: a level set lies on the surface)."""
        from paintcell.coverage.geodesic import HeatGeodesics

        if self.heat is None:
            self.heat = HeatGeodesics(self.geom)
        pts, nrm = self.heat.offset(p.foot, p.normals, distance_m)
        return pts, nrm, np.ones(len(pts), bool)

    # --- geometry ---------------------------------------------------------------------------
    def extend_in_surface(self, foot: np.ndarray, normals: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
        """Continue a pass at its last point along the normal section containing its tangent
        until the surface boundary; returns the added points (K, 3) and normals (excluding the
        end point)."""
        sp = self.st.sample_spacing_m
        s = arc_length(foot)
        back = np.interp(s[-1] - min(2 * sp, s[-1]), s, np.arange(len(s)))
        j = int(np.floor(back))
        t = unit(foot[-1] - foot[j])
        n = normals[-1]
        t = unit(t - (t @ n) * n)
        c = curve_through(self.geom, foot[-1], np.cross(t, n), t)
        if c is None or c.s_max <= 0.5 * sp:
            return np.zeros((0, 3)), np.zeros((0, 3))
        keep = (c.s > 1e-6) & (c.s <= self.diag)
        pts, nrm = c.points[keep], c.normals[keep]
        # a pass ending on the boundary has no surface ahead: a section that runs back along the
        # pass (most of it within a sample spacing of it) is no continuation — the TCP would
        # reverse on the spot and retrace the pass
        body = foot[s <= s[-1] - 2 * sp]
        if len(pts) and len(body) and np.median(cKDTree(body).query(pts)[0]) < sp:
            return np.zeros((0, 3)), np.zeros((0, 3))
        return pts, nrm

    def build_pass(self, foot: np.ndarray, normals: np.ndarray, inside: np.ndarray,
                   extend: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Trim to the first..last inside sample, extend both ends within the surface, resample
        at the sample spacing. Returns foot (M, 3), normals (M, 3), on_part (M,).

        Where the offset leaves the part beyond its first (last) inside sample but still has
        points there (the part's boundary runs obliquely between this pass and the one it was
        offset from), those outside points are kept as the pass's head (tail): the strip
        between the boundary and the previous pass gets its second pass over the virtual
        extension, as an edge pass gives it where a whole offset leaves. Such an end is not
        extended within the surface. `self.last_extension_m` records the (head, tail) arc
        length [m] added by the extension within the surface."""
        self.last_extension_m = (0.0, 0.0)
        if extend:
            lo, hi = outside_span(foot, inside, 3.0 * self.st.sample_spacing_m)
        ok = np.all(np.isfinite(foot), axis=1)
        idx = np.flatnonzero(inside & ok)
        if extend and len(idx):
            keep = ok.copy()
            keep[:lo] = False
            keep[hi + 1:] = False
            out_head, out_tail = lo < idx[0], hi > idx[-1]
            foot, normals, inside = foot[keep], normals[keep], inside[keep]
        else:
            foot, normals, inside = foot[ok], normals[ok], inside[ok]
            out_head = out_tail = False
        if extend and len(foot) >= 2:
            tail_p, tail_n = (np.zeros((0, 3)), np.zeros((0, 3))) if out_tail else \
                self.extend_in_surface(foot, normals)
            head_p, head_n = (np.zeros((0, 3)), np.zeros((0, 3))) if out_head else \
                self.extend_in_surface(foot[::-1], normals[::-1])
            self.last_extension_m = (_length_to(head_p, foot[0]), _length_to(tail_p, foot[-1]))
            foot = np.concatenate([head_p[::-1], foot, tail_p])
            normals = np.concatenate([head_n[::-1], normals, tail_n])
            inside = np.concatenate([np.ones(len(head_p), bool), inside,
                                     np.ones(len(tail_p), bool)])
        if len(foot) < 2 or arc_length(foot)[-1] < self.st.sample_spacing_m:
            raise PlanError("an offset pass degenerated to a point; reduce w_max_m or check the "
                            "surface for narrow tips")
        return resample(foot, normals, self.st.sample_spacing_m, inside)

    def curves_of(self, p: PassGeom) -> list[IndexingCurve | None]:
        if p.curves is None:
            t = tangents(p.foot)
            curves = indexing_curves(self.geom, p.foot, t, p.normals)
            p.curves = [c if ok else None for c, ok in zip(curves, p.on_part, strict=True)]
        return p.curves

    # --- index width --------------------------------------------------------------------------
    def markers(self, p: PassGeom, valid: np.ndarray) -> np.ndarray:
        """Indices of marker samples: equal steps of turning/marker_turn + length/spacing."""
        idx = np.flatnonzero(valid)
        if len(idx) < 3:
            return idx[len(idx) // 2:len(idx) // 2 + 1]
        foot = p.foot[idx]
        s = arc_length(foot)
        t = tangents(foot)
        turn = np.concatenate([[0.0], np.cumsum(np.arccos(np.clip(
            np.einsum("ij,ij->i", t[1:], t[:-1]), -1.0, 1.0)))])
        c = turn / self.st.marker_turn_rad + s / self.st.marker_spacing_m
        n = int(np.clip(np.ceil(c[-1]), 1, self.st.max_markers))
        targets = (np.arange(n) + 0.5) / n * c[-1]
        return np.unique(idx[np.clip(np.searchsorted(c, targets), 0, len(idx) - 1)])

    def profile(self, curve: IndexingCurve, travel: np.ndarray) -> np.ndarray:
        """Cross-profile table of a marker, cached by the curve's shape in its local frame."""
        pts, nrm, _ = curve.sample(self.gun_s)
        o, _, _ = curve.sample(np.array([0.0]))
        n0 = nrm[self.g0]
        t = unit(travel - (travel @ n0) * n0)
        frame = np.stack([t, np.cross(n0, t), n0])
        key = np.concatenate([np.rint((pts - o[0]) @ frame.T / 1e-4),
                              np.rint(nrm @ frame.T / 1e-4)]).astype(np.int64).tobytes()
        film = self.cache.get(key)
        if film is None:
            film = cross_profiles(self.app, curve, t, self.gun_s, self.point_s)
            self.cache[key] = film
        else:
            self.cache_hits += 1
        return film

    def choose_width(self, p: PassGeom, curves: list[IndexingCurve | None],
                     known_s: list[float], w_prev: float | None) -> tuple[float, dict[str, Any]]:
        valid = np.array([c is not None for c in curves])
        if not valid.any():
            raise PlanError("no indexing curve could be built on the current pass; the surface "
                            "may be too coarse for the sample spacing (refine the mesh)")
        marks = self.markers(p, valid)
        t_all = tangents(p.foot)
        searches: list[WidthSearch] = []
        for i in marks:                            # a few markers per pass
            c = curves[int(i)]
            if c is None:                          # markers are chosen among valid curves
                continue
            film = self.profile(c, t_all[int(i)])
            searches.append(search_widths(film, self.st.w_res_m, self.g0, self.point_s,
                                          known_s, self.widths, self.future, self.st.n_future,
                                          w_prev))
        w0, feasible, worst = choose_constant_width(searches, self.st.u_max, w_prev,
                                                    self.st.width_change_weight,
                                                    self.st.width_tolerance_m)
        return w0, {"rule": "constant-index over markers", "markers": int(len(marks)),
                    "feasible": feasible, "worst_marker_nsd_pct": 100.0 * worst}

