"""Settings of Algorithm 1 (`PlannerSettings`): index-width search range, speed bounds, sample
spacings, pass-order and guard options — all SI (m, s, rad), validated on construction."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from paintcell.core.errors import PlanError
from paintcell.coverage.index_width import search_range
from paintcell.coverage.smoothing import check_smoothing_setting
from paintcell.coverage.speed_qp import SpeedSettings


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
        "centred" (each curve's deviation from its current mean); see
        `paintcell.coverage.speed_qp`.
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
    film_guard_band_m: the interior the film guard and film refine judge apart is the part
        farther than this from its boundary [m].
    film_refine: after the film guard, re-time all passes together by a bounded least-squares fit
        of the simulated film on the real part to its mean (slowness knots along each pass,
        speeds within [v_min, v_max] and the robot's caps), kept only where it lowers σ/μ on the
        whole part and its interior (`paintcell.coverage.film_refine`): it makes up
        the paint an opening's brush-off leaves off its rim, and stripes between passes.
    first_side: "right" (offset to the right of the start curve first, Algorithm 1 as written),
        "left" (the start curve reversed), or "best" (run both, keep the plan with the smaller
        largest predicted optimization-profile σ/μ; the semi-global search depends on the order).
    max_passes: refuse to plan more passes than this (a guard against a runaway offset loop).
    smoothing_m: pass geometry, tool axis and standoff come from the surface smoothed at this
        scale [m] ("auto": a quarter of the footprint radius, applied only where the surface has
        finer features, and 2× / 4× that where the bell axis cannot follow the surface within
        max_axis_turn_rad_m; None: the raw surface); the film stays on the real mesh
        (`paintcell.coverage.smoothing`).
    geodesic_fallback: where an offset walked along indexing curves self-intersects, take the
        level set of the heat-method geodesic distance from the pass instead
        (`paintcell.coverage.geodesic`; False: refuse the plan as before). An offset of a pass
        walked in order that runs in order once at most
        `paintcell.coverage.offset.MAX_STRAY_SAMPLES` samples (and `MAX_STRAY_FRACTION` of
        them) are left out (curves turned astray at an opening's corner) is kept without them,
        either way.
    plan_across_openings: plan on the surface with its openings (boundary loops other than the
        outer one) closed, so passes carry on straight across holes
        (`paintcell.coverage.openings`), and the deep bays of its outline (a wheel arch)
        closed too (`paintcell.coverage.notches`), brushing off over both.
    patches: split the part into normal-cone patches, plan each, blend the seams and order them
        (`paintcell.coverage.patches.plan_patches`; ordered from the part frame's origin).
    max_opening_fraction: brush off every sample that would send more than this share of the
        paint it emits into an opening [-]. 0.8 keeps the bell on until its centre is well past
        the rim, so the rim gets the film of both sides' footprints (at 0.5 the rim gets about
        half, a thin ring round every window, sunroof or arch).
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
    film_refine: bool = True
    first_side: str = "best"
    max_passes: int = 200
    smoothing_m: float | str | None = "auto"
    geodesic_fallback: bool = True
    plan_across_openings: bool = True
    patches: bool = False
    max_opening_fraction: float = 0.8
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
                     "plan_across_openings", "patches", "film_guard", "film_refine"):
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

