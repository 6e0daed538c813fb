"""Algorithm 1 of the paper: start curve, offsets within the surface at optimized index widths,
per-pass speed optimization, assembled into a `CoveragePlan`.

    select the start curve (§2.3); optimize its speed (§3)
    repeat: offset the latest pass to its right at the index width of §4; optimize its speed
    until the offset lies completely outside the surface
    the same to the left of the start curve

Index widths: planar surfaces use the Fig. 5 rule (`planar_index_width`, one width for all
passes). Curved surfaces (extruded or not) use markers along the current pass spaced by its total
curvature; at each marker the surface is approximated by the extrusion of the marker's indexing
curve and the brute-force search over n future passes (eq. 3) gives the best σ/μ per candidate
width; the paper's constant-index restriction keeps the widths feasible at every marker, and the
cost penalizes small widths and |w0 − w−1|. The new pass is the offset of every sample of the
current pass by w0 along its indexing curve (geodesic), continued within the surface to the
boundary and beyond it by `overspray_m` along the tangent. After the last pass that touches the
surface, the first offset that lies completely outside is kept as a sideways overspray pass
(`edge_passes`), painted over the virtual extension of the surface. Where the current pass's end
samples have no offset there (their indexing curves left the surface along the boundary the pass
ends at, `planning.offset.walk`), the edge pass continues straight along its own path as far as
the current pass reaches, then by the overspray.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from planning.applicator import Applicator
from planning.errors import PlanError
from planning.index_width import (
    WidthSearch,
    choose_constant_width,
    cross_profiles,
    planar_index_width,
    search_range,
    search_widths,
)
from planning.offset import (
    IndexingCurve,
    SurfaceGeometry,
    arc_length,
    check_offset_order,
    curve_through,
    geodesic_curvature,
    indexing_curves,
    resample,
    tangents,
    unit,
    walk,
)
from planning.openings import brush_off_openings, fill_samples, filled_surface, find_openings
from planning.plan import CoveragePlan, PassPlan, times_from_speeds
from planning.smoothing import (
    check_smoothing_setting,
    limit_turn_rate,
    smooth_along,
    smoothed_surface,
    smoothing_scale_m,
)
from planning.speed_qp import SpeedSettings, SubOffsetBand, optimize_pass_speed
from planning.start_curve import select_start_curve
from planning.surface import Surface

#: A surface whose principal curvatures stay below this everywhere is planar [1/m] (a 1 km
#: radius; the discrete curvature of a flat grid is ~1e-12).
PLANAR_CURVATURE_1_M = 1e-3


@dataclass(frozen=True)
class PlannerSettings:
    """Settings of Algorithm 1 (all SI).

    u_max: largest acceptable σ/μ on an optimization profile (fraction; the paper uses 0.04).
    overspray_m: each pass continues this far beyond the surface boundary along its tangent [m].
    v_nominal_m_s: constant start speed of every pass; it sets the film thickness [m/s].
    v_min_m_s / v_max_m_s: TCP speed bounds of the speed QP [m/s].
    a_max_m_s2: TCP acceleration bound of the QP's linearized constraint [m/s²].
    n_knots: optimized speed knots per pass (slowness interpolated linearly between them).
    w_min_m / w_max_m / w_res_m: index-width search range SR and its resolution [m].
    width_tolerance_m: a width is feasible only if σ/μ ≤ u_max also holds for widths this much
        narrower and wider [m] (paper §4.1: w_max chosen by the σ/μ sensitivity; 0: plain rule).
    n_future: future passes considered in the extruded / curved search (the paper's n = 4).
    future_grid_n: widths tried for each future pass after the candidate (evenly spread over
        SR, ends included): the brute force costs future_grid_n^(n_future − 1) per candidate.
    width_change_weight: weight of |w0 − w−1| / w_max against w_max / w0 in the width cost.
    orientation: "auto" (minimal altitude), "zero-curvature", "max-curvature", or the angle of
        the pass direction about the average normal from the part x axis [rad].
    start_position: None (curvature divider / area median) or fraction in [0, 1] of the altitude.
    optimize_speed: run the speed QP on every pass (False: constant v_nominal).
    speed_objective: "paper" (eq. 2 with K_j fixed from the constant-speed profile) or
        "centred" (each curve's deviation from its current mean); see `planning.speed_qp`.
    sample_spacing_m: spacing of the TCP samples along passes and of the offset computation [m].
    band_curves: J sub-offset curves of the speed band (odd; curve 0 is the pass itself).
    band_half_width: the band spans ± this fraction of the local index width.
    marker_turn_rad / marker_spacing_m: a marker every this much turning of the pass tangent
        plus every this much arc length (paper §4.3: markers spaced by total curvature).
    max_markers: at most this many markers per pass.
    profile_spacing_m: spacing of the optimization-profile points on indexing curves [m].
    edge_passes: keep the first offset that lies completely outside as a sideways overspray pass.
    film_guard: after the per-pass speed QPs, simulate the film of the whole plan on the part and
        keep the optimized speeds only where they are no worse than constant speed on the film
        itself, whole part and interior (farther than film_guard_band_m [m] from the boundary):
        speeds v_nom + α (v_QP − v_nom), α ∈ {1, ¾, ½, ¼, 0}: the best whole-part film among
        the blends no worse than constant speed on both.
    first_side: "right" (offset to the right of the start curve first, Algorithm 1 as written),
        "left" (the start curve reversed), or "best" (run both, keep the plan with the smaller
        largest predicted optimization-profile σ/μ; the semi-global search depends on the order).
    max_passes: refuse to plan more passes than this (a guard against a runaway offset loop).
    smoothing_m: pass geometry, tool axis and standoff come from the surface smoothed at this
        scale [m] ("auto": a quarter of the footprint radius, applied only where the surface has
        finer features; None: the raw surface); the film stays on the real mesh
        (`planning.smoothing`).
    geodesic_fallback: where an offset walked along indexing curves self-intersects, take the
        level set of the heat-method geodesic distance from the pass instead
        (`planning.geodesic`; False: refuse the plan as before).
    plan_across_openings: plan on the surface with its openings (boundary loops other than the
        outer one) closed, so passes carry on straight across holes (`planning.openings`).
    patches: split the part into normal-cone patches, plan each, blend the seams and order them
        (`planning.patches.plan_patches`; ordered from the part frame's origin).
    max_opening_fraction: brush off every sample that would send more than this share of the
        paint it emits into an opening [-].
    max_axis_turn_rad_m: bound on how fast the bell axis, and its spin (the travel direction),
        may turn along a pass, per metre of TCP travel [rad/m] (4 rad/m ≈ 230 °/m: above every
        smooth library part, below a crease).
    """

    u_max: float = 0.04
    overspray_m: float = 0.15
    v_nominal_m_s: float = 0.5
    v_min_m_s: float = 0.2
    v_max_m_s: float = 1.0
    a_max_m_s2: float = 5.0
    n_knots: int = 12
    w_min_m: float = 0.10
    w_max_m: float = 0.45
    w_res_m: float = 0.01
    width_tolerance_m: float = 0.025
    n_future: int = 4
    future_grid_n: int = 6
    width_change_weight: float = 1.0
    orientation: float | str = "auto"
    start_position: float | None = None
    optimize_speed: bool = True
    speed_objective: str = "paper"
    sample_spacing_m: float = 0.02
    band_curves: int = 5
    band_half_width: float = 1.0
    marker_turn_rad: float = 0.25
    marker_spacing_m: float = 0.4
    max_markers: int = 7
    profile_spacing_m: float = 0.01
    edge_passes: bool = True
    film_guard: bool = True
    film_guard_band_m: float = 0.1
    first_side: str = "best"
    max_passes: int = 200
    smoothing_m: float | str | None = "auto"
    geodesic_fallback: bool = True
    plan_across_openings: bool = True
    patches: bool = False
    max_opening_fraction: float = 0.5
    max_axis_turn_rad_m: float = 4.0

    def __post_init__(self) -> None:
        positive = ("u_max", "v_nominal_m_s", "v_min_m_s", "v_max_m_s", "a_max_m_s2", "w_min_m",
                    "w_max_m", "w_res_m", "sample_spacing_m", "marker_turn_rad",
                    "marker_spacing_m", "profile_spacing_m")
        for name in positive:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                    or v <= 0:
                raise PlanError(f"PlannerSettings.{name} = {v!r} must be a finite number > 0")
        for name in ("overspray_m", "width_change_weight", "band_half_width",
                     "width_tolerance_m", "film_guard_band_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                    or v < 0:
                raise PlanError(f"PlannerSettings.{name} = {v!r} must be a finite number >= 0")
        for name, lo in (("n_knots", 2), ("n_future", 1), ("future_grid_n", 1),
                         ("band_curves", 1), ("max_markers", 1), ("max_passes", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise PlanError(f"PlannerSettings.{name} = {v!r} must be an int >= {lo}")
        check_smoothing_setting(self.smoothing_m)
        if isinstance(self.max_axis_turn_rad_m, bool) or not (self.max_axis_turn_rad_m > 0):
            raise PlanError(f"PlannerSettings.max_axis_turn_rad_m = {self.max_axis_turn_rad_m!r}"
                            " must be > 0 [rad/m] (inf: no bound)")
        if self.band_curves % 2 == 0:
            raise PlanError(f"PlannerSettings.band_curves = {self.band_curves} must be odd "
                            "(the pass itself plus pairs on both sides)")
        if not self.v_min_m_s <= self.v_nominal_m_s <= self.v_max_m_s:
            raise PlanError("PlannerSettings: need v_min_m_s <= v_nominal_m_s <= v_max_m_s")
        if self.w_min_m > self.w_max_m:
            raise PlanError("PlannerSettings: w_min_m > w_max_m; give w_min <= w_max")
        search_range(self.w_min_m, self.w_max_m, self.w_res_m)
        o = self.orientation
        if isinstance(o, str):
            if o not in ("auto", "zero-curvature", "max-curvature"):
                raise PlanError(f"PlannerSettings.orientation = {o!r}: use 'auto', "
                                "'zero-curvature', 'max-curvature' or an angle [rad]")
        elif isinstance(o, bool) or not isinstance(o, int | float) or not math.isfinite(o):
            raise PlanError(f"PlannerSettings.orientation = {o!r} must be a string or an angle")
        if not 0 < self.max_opening_fraction <= 1:
            raise PlanError(f"PlannerSettings.max_opening_fraction = "
                            f"{self.max_opening_fraction!r} must be in (0, 1]")
        for name in ("optimize_speed", "edge_passes", "geodesic_fallback",
                     "plan_across_openings", "patches", "film_guard"):
            if not isinstance(getattr(self, name), bool):
                raise PlanError(f"PlannerSettings.{name} = {getattr(self, name)!r} must be "
                                "True or False")
        if self.first_side not in ("right", "left", "best"):
            raise PlanError(f"PlannerSettings.first_side = {self.first_side!r}: use 'right', "
                            "'left' or 'best'")
        if self.speed_objective not in ("paper", "centred"):
            raise PlanError(f"PlannerSettings.speed_objective = {self.speed_objective!r}: use "
                            "'paper' or 'centred'")
        p = self.start_position
        if p is not None and (isinstance(p, bool) or not isinstance(p, int | float)
                              or not 0.0 <= p <= 1.0):
            raise PlanError(f"PlannerSettings.start_position = {p!r} must be None or in [0, 1]")

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of every field."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PlannerSettings:
        """Inverse of `to_dict` (also reads `CoveragePlan.settings`, whose planner `report`
        entry is skipped); unknown keys raise PlanError."""
        names = {f.name for f in fields(cls)}
        d = {k: v for k, v in d.items() if k != "report"}
        extra = set(d) - names
        if extra:
            raise PlanError(f"unknown planner settings {sorted(extra)}; valid: {sorted(names)}")
        return cls(**d)

    def speed_settings(self) -> SpeedSettings:
        """The speed-QP settings these planner settings imply."""
        return SpeedSettings(v_nominal_m_s=self.v_nominal_m_s, v_min_m_s=self.v_min_m_s,
                             v_max_m_s=self.v_max_m_s, a_max_m_s2=self.a_max_m_s2,
                             n_knots=self.n_knots, objective=self.speed_objective)


@dataclass(eq=False)
class _PassGeom:
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


def _mirror(c: IndexingCurve | None) -> IndexingCurve | None:
    return None if c is None else c.reversed()


class _Planner:
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
        self.heat: Any = None          # planning.geodesic.HeatGeodesics, built when first needed
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

    def geodesic_offset(self, p: _PassGeom, distance_m: float
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Heat-method offset of pass `p` at signed `distance_m` [m]: points, normals, inside
        (all True: a level set lies on the surface)."""
        from planning.geodesic import HeatGeodesics

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
        at the sample spacing. Returns foot (M, 3), normals (M, 3), on_part (M,)."""
        ok = np.all(np.isfinite(foot), axis=1)
        foot, normals, inside = foot[ok], normals[ok], inside[ok]
        idx = np.flatnonzero(inside)
        if extend and len(idx):
            foot = foot[idx[0]:idx[-1] + 1]
            normals = normals[idx[0]:idx[-1] + 1]
            inside = inside[idx[0]:idx[-1] + 1]
        if extend and len(foot) >= 2:
            tail_p, tail_n = self.extend_in_surface(foot, normals)
            head_p, head_n = self.extend_in_surface(foot[::-1], normals[::-1])
            foot = np.concatenate([head_p[::-1], foot, tail_p])
            normals = np.concatenate([head_n[::-1], normals, tail_n])
            inside = np.concatenate([np.ones(len(head_p), bool), inside,
                                     np.ones(len(tail_p), bool)])
        if len(foot) < 2 or arc_length(foot)[-1] < self.st.sample_spacing_m:
            raise PlanError("an offset pass degenerated to a point; reduce w_max_m or check the "
                            "surface for narrow tips")
        return resample(foot, normals, self.st.sample_spacing_m, inside)

    def curves_of(self, p: _PassGeom) -> list[IndexingCurve | None]:
        if p.curves is None:
            t = tangents(p.foot)
            curves = indexing_curves(self.geom, p.foot, t, p.normals)
            p.curves = [c if ok else None for c, ok in zip(curves, p.on_part, strict=True)]
        return p.curves

    # --- index width --------------------------------------------------------------------------
    def markers(self, p: _PassGeom, valid: np.ndarray) -> np.ndarray:
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

    def choose_width(self, p: _PassGeom, curves: list[IndexingCurve | None],
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


def _is_planar(surface: Any) -> bool:
    return bool(np.max(np.abs(surface.principal_curvatures)) < PLANAR_CURVATURE_1_M)


def plan_coverage(surface: Surface, applicator: Applicator,
                  settings: PlannerSettings | None = None,
                  speed_caps_m_s: dict[int, np.ndarray] | None = None,
                  tool_x: dict[int, np.ndarray] | None = None) -> CoveragePlan:
    """Plan uniform coverage of `surface` with `applicator` (paper Algorithm 1).

    surface: a `planning.surface.Surface` in its part frame; applicator: the deposition model;
    settings: `PlannerSettings` (defaults when None);
    speed_caps_m_s: optional per-pass speed upper bounds {side: (M,) [m/s]}, one per TCP sample of
        that pass in its generation direction (`plan.passes[i]` reversed when i is odd): the speed
        QP re-plans under them (robot-aware speeds, `sim.speed_feedback`). A re-plan with the same
        part and settings reproduces the same passes, so caps taken from a plan fit its re-plan;
    tool_x: optional per-pass bell x axes {side: (M, 3)} in the part frame, same sample order as
        the caps: the orientation the robot will hold about the spray axis (a robot that frees
        the bell's spin); the deposition model (QP, film) then uses it as the travel axis.
    Returns a `CoveragePlan` in the part frame: passes in execution order (side −k … +k,
    alternating direction), TCP at standoff along the normal, speeds and times, on_part /
    paint_on flags, index widths, the start-curve rule and the settings (with a `report` entry:
    per-pass width choice, markers, speed-QP status). The plan holds no wall-clock timing, so
    the same input gives a byte-identical saved plan (the pipeline records stage times).
    Raises PlanError when an offset self-intersects or the loop does not terminate.
    """
    if not isinstance(surface, Surface):
        raise PlanError(f"plan_coverage needs a planning.surface.Surface, got "
                        f"{type(surface).__name__}; build one with Surface.from_mesh or "
                        "planning.parts.get_part")
    if not isinstance(applicator, Applicator):
        raise PlanError(f"plan_coverage needs a planning.applicator.Applicator, got "
                        f"{type(applicator).__name__}; use Applicator.default() or from_toml")
    if settings is not None and not isinstance(settings, PlannerSettings):
        raise PlanError(f"plan_coverage settings must be PlannerSettings or None, got "
                        f"{type(settings).__name__}; use PlannerSettings.from_dict for a dict")
    st = PlannerSettings() if settings is None else settings
    if st.patches:
        from dataclasses import replace

        from planning.patches import plan_patches

        return plan_patches(surface, applicator, replace(st, patches=False))
    real_surface = surface            # the film is judged on it; the passes on its smoothing
    openings = find_openings(surface) if st.plan_across_openings else []
    surface = filled_surface(surface, openings)
    smooth_scale = smoothing_scale_m(surface, applicator.footprint_radius_m, st.smoothing_m)
    surface = smoothed_surface(surface, smooth_scale)
    pl = _Planner(surface, applicator, st)
    pl.smooth_scale = smooth_scale
    for side, cap in (speed_caps_m_s or {}).items():
        cap = np.asarray(cap, dtype=float).reshape(-1)
        if not np.all(np.isfinite(cap)) or np.any(cap <= 0):
            raise PlanError(f"speed caps of pass {side} must be finite speeds > 0 [m/s]")
        pl.speed_caps[int(side)] = cap
    for side, xs in (tool_x or {}).items():
        xs = np.asarray(xs, dtype=float)
        if xs.ndim != 2 or xs.shape[1] != 3 or not np.all(np.isfinite(xs)):
            raise PlanError(f"tool_x of pass {side} must be finite (M, 3) directions")
        pl.tool_x[int(side)] = xs
    sc = select_start_curve(surface, st.orientation, st.start_position, st.sample_spacing_m,
                            geom=pl.geom)
    planar = _is_planar(surface)
    planar_w = None
    if planar:
        pw = planar_index_width(applicator, st.w_min_m, st.w_max_m, st.w_res_m, st.u_max,
                                st.width_tolerance_m)
        planar_w = pw
    # Algorithm 1 does not say which side is offset first, and the semi-global width search
    # (known passes on one side, free future passes on the other) depends on it: "best" runs
    # both and keeps the one whose largest predicted optimization-profile σ/μ is smaller.
    orders = {"right": [False], "left": [True], "best": [False, True]}[st.first_side]
    if planar_w is not None:
        orders = orders[:1]               # a plane is symmetric: both orders give one plan
    candidates = []
    errors: list[PlanError] = []
    for reverse in orders:
        pts, nrm = (sc.points[::-1], sc.normals[::-1]) if reverse else (sc.points, sc.normals)
        try:
            passes = _sweeps(pl, surface.name, pts, nrm, planar_w)
        except PlanError as e:          # "best" keeps the order that works
            errors.append(e)
            continue
        candidates.append((_predicted_worst(passes), reverse, passes))
    if not candidates:
        raise errors[0]
    _, reversed_start, passes = min(candidates, key=lambda c: c[0])
    bad = [f"pass {p.side}: {p.info['feedback_mismatch']}" for p in passes.values()
           if "feedback_mismatch" in p.info]
    if bad:
        raise PlanError("speed caps / bell axes do not fit this plan (" + "; ".join(bad) + "); "
                        "they must come from a plan of the same part and settings")
    plan_passes = _time_passes(pl, passes, st)
    n_brush_off = 0
    if openings:
        plan_passes, n_brush_off = brush_off_openings(
            applicator, plan_passes, fill_samples(real_surface, openings),
            st.max_opening_fraction)
    guard: dict[str, Any] = {}
    if st.optimize_speed and st.film_guard:
        plan_passes, guard = _film_guard(pl, real_surface, plan_passes)
    report = {
        "film_guard": guard,
        "start_rule": sc.rule,
        "first_side": ("left" if reversed_start else "right") + f" ({st.first_side})",
        "predicted_worst_nsd_pct": [c[0] for c in candidates],
        "planar": planar,
        "smoothing_scale_m": smooth_scale,
        "smoothing_max_shift_m": float(np.max(np.linalg.norm(
            surface.vertices[:len(real_surface.vertices)] - real_surface.vertices, axis=1))),
        "openings": [{"perimeter_m": o.perimeter_m, "area_m2": o.area_m2} for o in openings],
        "samples_brushed_off_over_openings": n_brush_off,
        "planar_width_m": None if planar_w is None else planar_w.width_m,
        "cross_profiles_computed": len(pl.cache),
        "cross_profile_cache_hits": pl.cache_hits,
        "passes": [dict(side=p.side, **_jsonable(passes[p.side].info)) for p in plan_passes],
    }
    settings_dict = st.to_dict()
    settings_dict["report"] = report
    return CoveragePlan(surface_name=surface.name, applicator=applicator,
                        passes=tuple(plan_passes), start_rule=sc.rule, settings=settings_dict)


def _sweeps(pl: _Planner, name: str, start_pts: np.ndarray, start_nrm: np.ndarray,
            planar_w: Any) -> dict[int, _PassGeom]:
    """Algorithm 1's two loops from the start curve: offsets to the right (s > 0 along the
    indexing curves, T × n), then to the left, until an offset lies completely outside."""
    st = pl.st
    start = _PassGeom(start_pts, start_nrm, np.ones(len(start_pts), bool), 0, float("nan"))
    start.info = {"rule": "start curve"}
    _time_pass(pl, start, pl.nominal_width)      # Algorithm 1: optimize the start curve's speed
    passes: dict[int, _PassGeom] = {0: start}
    right_widths: list[float] = []
    for sign in (1, -1):
        cur = start
        widths_this_side: list[float] = []
        for k in range(1, st.max_passes + 1):
            curves = pl.curves_of(cur)
            sweep_curves = curves if sign > 0 else [_mirror(c) for c in curves]
            # known passes besides C0, as positions ≤ 0 in the sweep frame: back along this
            # side to the start curve, then (left sweep) across it to the right-side passes
            back = widths_this_side[::-1] + (right_widths if sign < 0 else [])
            known = list(-np.cumsum(back))
            w_prev: float | None = back[0] if back else None
            if planar_w is not None:
                w0 = planar_w.width_m
                info = {"rule": "planar (Fig. 5)", "feasible": planar_w.feasible,
                        "nsd_pct": float(100 * np.interp(w0, planar_w.widths_m, planar_w.nsd))}
            else:
                w0, info = pl.choose_width(cur, sweep_curves, known, w_prev)
            pts, nrm, inside = walk(sweep_curves, w0)
            ok = np.all(np.isfinite(pts), axis=1)
            try:
                check_offset_order(cur.foot[ok], pts[ok],
                                   f"offset {sign * k:+d} of the {name} plan")
            except PlanError:
                if not st.geodesic_fallback:
                    raise
                g_pts, g_nrm, g_in = pl.geodesic_offset(cur, sign * w0)
                info = dict(info, offset="heat-method level set")
                if len(g_pts) >= 2:
                    pts, nrm, inside = g_pts, g_nrm, g_in
                    ok = np.ones(len(pts), bool)
                else:                       # nothing left on the surface: the edge pass below
                    inside = np.zeros(len(pts), bool)
            side = sign * k
            if inside.sum() < 2:            # nothing (or a single point) left on the surface
                if st.edge_passes and ok.sum() >= 2:
                    foot, normals, on_part = pl.build_pass(pts, nrm, np.zeros(len(pts), bool),
                                                           extend=False)
                    edge = _PassGeom(foot, normals, np.zeros(len(foot), bool), side, w0,
                                     edge=True)
                    # samples at the ends of the current pass whose indexing curves left the
                    # surface along the boundary it ends at have no offset: the edge pass goes
                    # on straight there (as its overspray does), as far as the current pass did
                    i_ok = np.flatnonzero(ok)
                    s_cur = arc_length(cur.foot)
                    edge.extra_m = (float(s_cur[i_ok[0]]), float(s_cur[-1] - s_cur[i_ok[-1]]))
                    edge.info = dict(info, edge=True)
                    # its band lies on the part, between it and the previous pass
                    edge.source = (curves, sign * w0)
                    _time_pass(pl, edge, w0)
                    passes[side] = edge
                break
            foot, normals, on_part = pl.build_pass(pts, nrm, inside)
            new = _PassGeom(foot, normals, on_part, side, w0)
            new.info = info
            _time_pass(pl, new, w0)                 # Algorithm 1: optimize the new pass's speed
            passes[side] = new
            widths_this_side.append(w0)
            cur = new
        else:
            raise PlanError(f"Algorithm 1 did not leave the surface after {st.max_passes} passes; "
                            "raise w_min_m or max_passes")
        if sign > 0:
            right_widths = widths_this_side
    return passes


def _predicted_worst(passes: dict[int, _PassGeom]) -> float:
    """Largest predicted optimization-profile σ/μ [%] over the passes on the part."""
    vals = [p.info.get("worst_marker_nsd_pct", p.info.get("nsd_pct", 0.0))
            for p in passes.values() if not p.edge and p.side != 0]
    return float(max(vals)) if vals else 0.0


def _jsonable(d: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, float) and not math.isfinite(v):
            v = None
        out[k] = v
    return out


def _band(pl: _Planner, p: _PassGeom, half_width_m: float) -> SubOffsetBand | None:
    """Sub-offset curves of a pass: curve 0 its foot points (on-part ones; all of them for an
    edge pass, which lies on the virtual extension), then ± offsets walked along indexing curves
    (the pass's own, or for an edge pass the previous pass's, shifted by the width); only points
    inside the surface, gaps split off."""
    j = pl.st.band_curves
    offs = np.linspace(-half_width_m, half_width_m, j)
    offs = offs[np.abs(offs) > 1e-12]
    if p.source is None:
        curves, base = pl.curves_of(p), 0.0
        foot0, nrm0, keep0 = p.foot, p.normals, p.on_part.copy()
    else:
        curves, base = p.source
        foot0, nrm0 = p.foot, p.normals
        keep0 = np.ones(len(p.foot), bool)
    pts_l, nrm_l, len_l = [], [], []
    for k, d in enumerate(np.concatenate([[0.0], offs])):      # J ≤ ~7 curves
        if k == 0:
            pts, nrm, inside = foot0, nrm0, keep0
        else:
            pts, nrm, inside = walk(curves, base + d)
        keep = inside & np.all(np.isfinite(pts), axis=1)
        pts, nrm = pts[keep], nrm[keep]
        if len(pts) < 2:
            if k == 0:
                return None
            continue
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        good = (seg > 1e-9) & (seg < 3.0 * pl.st.sample_spacing_m)
        if good.sum() < 1:
            if k == 0:
                return None
            continue
        mid = 0.5 * (pts[1:] + pts[:-1])[good]
        mn = unit(nrm[1:] + nrm[:-1])[good]
        pts_l.append(mid)
        nrm_l.append(mn)
        len_l.append(seg[good])
    if len(pts_l) < 2:          # nothing of the band on the part: no objective to optimize
        return None
    return SubOffsetBand(tuple(pts_l), tuple(nrm_l), tuple(len_l))


def _time_pass(pl: _Planner, p: _PassGeom, w_local: float) -> None:
    """Add overspray and TCP poses to a pass and optimize its speed (paper §3) — called as
    Algorithm 1 generates the pass. The band spans ± band_half_width · w_local [m] (the width to
    the pass it was offset from; for the start curve, the bell's planar Fig. 5 width)."""
    if p.timing is not None:
        return
    st, app = pl.st, pl.app
    h = app.standoff_m
    foot, normals, on_part = _with_overspray(p.foot, p.normals, p.on_part,
                                             (st.overspray_m + p.extra_m[0],
                                              st.overspray_m + p.extra_m[1]),
                                             st.sample_spacing_m, h)
    axes = limit_turn_rate(foot, smooth_along(foot, -normals, 0.5 * pl.smooth_scale),
                           st.max_axis_turn_rad_m, h)
    pos = foot - h * axes
    seg = np.diff(pos, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    if np.any(seg_len <= 0):
        raise PlanError(f"pass {p.side} has repeated TCP samples; refine the mesh")
    travel = tangents(pos)
    travel = unit(travel - np.sum(travel * axes, axis=1, keepdims=True) * axes)
    # the bell's spin follows the travel direction: bound its turning rate too (a noisy pass end
    # or a scanned rim whips joint 6 otherwise)
    travel = limit_turn_rate(pos, travel, st.max_axis_turn_rad_m)
    tx = pl.tool_x.get(p.side)
    if tx is not None and len(tx) != len(pos):
        p.info["feedback_mismatch"] = f"tool_x: {len(tx)} samples, the pass {len(pos)}"
        tx = None
    if tx is not None:
        travel = tx
    travel = unit(travel - np.sum(travel * axes, axis=1, keepdims=True) * axes)
    speeds = np.full(len(pos), st.v_nominal_m_s)
    nsd_c = nsd_o = float("nan")
    # caps and bell axes of a re-plan belong to the passes of the order the plan chose; in the
    # other order of first_side="best" a side can be another pass: skipped there, an error only
    # if the chosen order does not fit (checked in plan_coverage)
    cap = pl.speed_caps.get(p.side)
    if cap is not None and len(cap) != len(pos):
        p.info["feedback_mismatch"] = f"speed caps: {len(cap)} samples, the pass {len(pos)}"
        cap = None
    if st.optimize_speed:
        band = _band(pl, p, st.band_half_width * w_local)
        p.info["speed_status"] = "constant: no band on the part"
        if band is not None:
            mid = 0.5 * (pos[1:] + pos[:-1])
            ax = unit(0.5 * (axes[1:] + axes[:-1]))
            tr = seg if tx is None else 0.5 * (travel[1:] + travel[:-1])
            tr = unit(tr - np.sum(tr * ax, axis=1, keepdims=True) * ax)
            res = optimize_pass_speed(app, mid, ax, tr, seg_len, band, pl.speed_settings, cap)
            speeds = np.asarray(res.sample_speeds_m_s, float)
            nsd_c, nsd_o = float(res.nsd_constant_pct), float(res.nsd_optimized_pct)
            p.info["speed_status"] = res.status
    else:
        p.info["speed_status"] = "constant: optimize_speed off"
        if cap is not None:
            speeds = np.minimum(speeds, cap)
    p.timing = dict(pos=pos, axes=axes, travel=travel, on_part=on_part, speeds=speeds,
                    nsd_c=nsd_c, nsd_o=nsd_o)


def _time_passes(pl: _Planner, passes: dict[int, _PassGeom],
                 st: PlannerSettings) -> list[PassPlan]:
    """Order the timed passes for execution (boustrophedon: every other pass reversed)."""
    out: list[PassPlan] = []
    for order, side in enumerate(sorted(passes)):
        p = passes[side]
        if p.timing is None:
            _time_pass(pl, p, p.width_m if np.isfinite(p.width_m) else pl.nominal_width)
        tm = p.timing
        assert tm is not None
        pos, axes, travel = tm["pos"], tm["axes"], tm["travel"]
        on_part, speeds = tm["on_part"], tm["speeds"]
        kg = geodesic_curvature(p.foot, p.normals)
        kg_max = float(np.max(np.abs(kg[p.on_part]))) if p.on_part.any() else 0.0
        p.info["max_geodesic_curvature_1_m"] = kg_max
        if order % 2 == 1:
            pos, axes, travel = pos[::-1], axes[::-1], -travel[::-1]
            on_part, speeds = on_part[::-1], speeds[::-1]
        # One timing for film and robot: the speed QP optimizes the sample speeds under the
        # robot's constant-acceleration law, so these times are the QP's segment times exactly.
        times = times_from_speeds(pos, speeds)
        out.append(PassPlan(
            positions=np.ascontiguousarray(pos), spray_axes=np.ascontiguousarray(axes),
            travel_dirs=np.ascontiguousarray(travel), speeds_m_s=np.ascontiguousarray(speeds),
            times_s=times, on_part=np.ascontiguousarray(on_part),
            paint_on=np.ones(len(pos), bool), side=side, index_width_m=p.width_m,
            max_geodesic_curvature_1_m=kg_max, nsd_constant_pct=tm["nsd_c"],
            nsd_optimized_pct=tm["nsd_o"]))
    return out


def _blend(passes: list[PassPlan], alpha: float, base: list[np.ndarray]) -> list[PassPlan]:
    """Passes with sample speeds base + α (v − base) (times rebuilt by the robot's rule)."""
    out = []
    for p, b in zip(passes, base, strict=True):
        v = b + alpha * (p.speeds_m_s - b)
        out.append(PassPlan(positions=p.positions, spray_axes=p.spray_axes,
                            travel_dirs=p.travel_dirs, speeds_m_s=v,
                            times_s=times_from_speeds(p.positions, v), on_part=p.on_part,
                            paint_on=p.paint_on, side=p.side, index_width_m=p.index_width_m,
                            max_geodesic_curvature_1_m=p.max_geodesic_curvature_1_m,
                            nsd_constant_pct=p.nsd_constant_pct,
                            nsd_optimized_pct=p.nsd_optimized_pct))
    return out


def _film_guard(pl: _Planner, surface: Surface, passes: list[PassPlan]
                ) -> tuple[list[PassPlan], dict[str, Any]]:
    """Keep the speed-optimized passes only as far as the simulated film on the part is no worse
    than at constant speed, on the whole part and on its interior (σ/μ, area weighted)."""
    from planning.deposition import thickness
    from planning.metrics import boundary_band_mask, boundary_vertices, uniformity

    st = pl.st
    mask = boundary_band_mask(surface.vertices,
                              surface.vertices[boundary_vertices(surface.faces)],
                              st.film_guard_band_m)
    has_interior = bool(mask.any())
    base = []
    for order, p in enumerate(passes):
        cap = pl.speed_caps.get(p.side)
        b = np.full(len(p.speeds_m_s), st.v_nominal_m_s)
        if cap is not None:
            b = np.minimum(b, cap[::-1] if order % 2 == 1 else cap)
        base.append(b)

    def nsd(alpha: float) -> tuple[float, float]:
        cand = _blend(passes, alpha, base)
        plan = CoveragePlan(surface_name=surface.name, applicator=pl.app, passes=tuple(cand),
                            start_rule="", settings={})
        film = thickness(pl.app, plan.gun_samples(), surface.vertices, surface.normals)
        whole = uniformity(film, surface.vertex_areas).nsd_pct
        inner = uniformity(film, surface.vertex_areas, mask=mask).nsd_pct if has_interior \
            else whole
        return whole, inner

    const = nsd(0.0)
    tried = {a: nsd(a) for a in (1.0, 0.75, 0.5, 0.25)}
    tried[0.0] = const
    # the blend with the best whole-part film among those no worse than constant speed on the
    # interior and the whole part (α = 0, constant speed, always qualifies)
    ok = [a for a, (w, i) in tried.items() if w <= const[0] and i <= const[1]]
    alpha = min(ok, key=lambda a: (tried[a][0], -a))
    info = {"alpha": alpha, "constant_whole_pct": const[0], "constant_interior_pct": const[1],
            "tried": {str(a): list(v) for a, v in tried.items()}}
    return (passes if alpha == 1.0 else _blend(passes, alpha, base)), info


def _with_overspray(foot: np.ndarray, normals: np.ndarray, on_part: np.ndarray,
                    overspray_m: float | tuple[float, float], spacing_m: float,
                    standoff_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Extend a pass by `overspray_m` at both ends (or (head, tail) [m]), off the surface: the TCP
    continues straight along the end tangent of its own path (no kink where the normal stops
    turning) and keeps standoff along the end normal, so the foot point is TCP − h · n_end."""
    if isinstance(overspray_m, tuple):
        head_m, tail_m = overspray_m
    else:
        head_m = tail_m = overspray_m
    tcp = foot + standoff_m * normals
    s = arc_length(tcp)
    span = min(2 * spacing_m, s[-1])

    def steps(length_m: float) -> np.ndarray:
        if length_m <= 0:
            return np.zeros(0)
        n_ext = int(np.ceil(length_m / spacing_m - 1e-9))
        return np.arange(1, n_ext + 1) * (length_m / n_ext)

    def end_tangent(f: np.ndarray, ss: np.ndarray) -> np.ndarray:
        back = np.array([np.interp(ss[-1] - span, ss, f[:, k]) for k in range(3)])
        return unit(f[-1] - back)

    d0, d1 = steps(head_m), steps(tail_m)
    t1 = end_tangent(tcp, s)
    t0 = end_tangent(tcp[::-1], s[-1] - s[::-1])
    head = tcp[0] + d0[::-1, None] * t0 - standoff_m * normals[0]
    tail = tcp[-1] + d1[:, None] * t1 - standoff_m * normals[-1]
    return (np.concatenate([head, foot, tail]),
            np.concatenate([np.tile(normals[0], (len(d0), 1)), normals,
                            np.tile(normals[-1], (len(d1), 1))]),
            np.concatenate([np.zeros(len(d0), bool), on_part, np.zeros(len(d1), bool)]))
