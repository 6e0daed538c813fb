"""Algorithm 1 on one pass family (`plan_family`): start curve, the sweeps of offsets to either
side at the chosen index widths until an offset leaves the surface, per-pass speeds, the film
guard, assembled into one `CoveragePlan` (lengths in m, speeds in m/s, σ/μ in %)."""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import Any

import numpy as np

from paintcell.core.errors import AxisTurnError, PlanError
from paintcell.coverage.back_fill import back_fill
from paintcell.coverage.coverage_planner import PassGeom, Planner, edge_spikes, mirrored_curve
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.coverage.coverage_timing import time_pass, time_passes
from paintcell.coverage.family_geometry import (
    FamilyGeometry,
    geometry_key,
    keep,
    kept,
)
from paintcell.coverage.film_refine import refine_plan
from paintcell.coverage.index_width import planar_index_width
from paintcell.coverage.notches import (
    NOTCH_DEPTH_FRACTION,
    closed_surface,
    find_notches,
    notch_samples,
)
from paintcell.coverage.offset import check_offset_order, stray_samples, walk
from paintcell.coverage.offset_polyline import arc_length
from paintcell.coverage.openings import (
    brush_off_openings,
    fill_samples,
    filled_surface,
    find_openings,
)
from paintcell.coverage.plan import CoveragePlan, PassPlan, times_from_speeds
from paintcell.coverage.smoothing import smoothed_surface, smoothing_scale_m
from paintcell.coverage.start_curve import select_start_curve
from paintcell.coverage.stitch import STITCH_GAP_FRACTION, stitched_surface
from paintcell.paint.applicator import Applicator
from paintcell.surface.surface_data import Surface

#: A surface whose principal curvatures stay below this everywhere is planar [1/m] (a 1 km
#: radius; the discrete curvature of a flat grid is ~1e-12).
PLANAR_CURVATURE_1_M = 1e-3


def _is_planar(surface: Any) -> bool:
    return bool(np.max(np.abs(surface.principal_curvatures)) < PLANAR_CURVATURE_1_M)



def plan_family(surface: Surface, applicator: Applicator, st: PlannerSettings,
                speed_caps_m_s: dict[int, np.ndarray] | None = None,
                tool_x: dict[int, np.ndarray] | None = None,
                axis_turn_fails_fast: bool = False) -> CoveragePlan:
    """Algorithm 1 on one pass family over the whole of `surface` (`st.patches` is not looked
    at): the body of `paintcell.coverage.algorithm.plan_coverage` after its input checks,
    with the same
    arguments and result (see there); `paintcell.coverage.patches` calls it on each
    patch. With `first_side = "best"` the two start orders are planned a pass at a time in turn
    (`_plan_orders`); axis_turn_fails_fast: an `AxisTurnError` in either order is raised at
    once (`plan_coverage` does when it has a larger "auto" smoothing scale left to try), else
    the order that meets it drops out and the other plans on."""
    caps = {int(side): np.asarray(cap, dtype=float).reshape(-1)
            for side, cap in (speed_caps_m_s or {}).items()}
    for side, cap in caps.items():
        if not np.all(np.isfinite(cap)) or np.any(cap <= 0):
            raise PlanError(f"speed caps of pass {side} must be finite speeds > 0 [m/s]")
    axes_x = {int(side): np.asarray(xs, dtype=float) for side, xs in (tool_x or {}).items()}
    for side, xs in axes_x.items():
        if xs.ndim != 2 or xs.shape[1] != 3 or not np.all(np.isfinite(xs)):
            raise PlanError(f"tool_x of pass {side} must be finite (M, 3) directions")
    real_surface = surface            # the film is judged on it; the passes on its smoothing
    # the pass geometry does not depend on caps or bell axes: a re-plan re-times the one kept
    # from the last plan without them (or raises the PlanError that plan raised)
    key = geometry_key(surface, applicator, st, axis_turn_fails_fast)
    geo = kept(key, applicator)
    if geo is None:
        try:
            geo = _geometry(surface, applicator, st, caps, axes_x, axis_turn_fails_fast)
        except PlanError as e:
            if not caps and not axes_x:
                keep(key, e)
            raise
        if not caps and not axes_x:
            keep(key, geo)
    pl, passes, openings = geo.pl, geo.passes, geo.openings
    pl.speed_caps, pl.tool_x = caps, axes_x
    plan_passes = time_passes(pl, passes, st)     # the passes not timed yet (a kept geometry)
    bad = [f"pass {p.side}: {p.info['feedback_mismatch']}" for p in passes.values()
           if "feedback_mismatch" in p.info]
    if bad:
        raise PlanError("speed caps / bell axes do not fit this plan (" + "; ".join(bad) + "); "
                        "they must come from a plan of the same part and settings")
    n_brush_off = 0
    if openings or geo.notches:
        fill = [np.concatenate(x) for x in zip(fill_samples(real_surface, openings),
                                               notch_samples(real_surface, geo.notches),
                                               strict=True)]
        plan_passes, n_brush_off = brush_off_openings(applicator, plan_passes,
                                                      (fill[0], fill[1], fill[2]),
                                                      st.max_opening_fraction)
    guard: dict[str, Any] = {}
    if st.optimize_speed and st.film_guard:
        plan_passes, guard = _film_guard(pl, real_surface, plan_passes)
    refine: dict[str, Any] = {}
    if st.optimize_speed and st.film_refine:
        plan_passes, refine = _refine(pl, real_surface, plan_passes)
    report = {
        "film_refine": refine,
        "film_guard": guard,
        "start_rule": geo.start_rule,
        "first_side": ("left" if geo.reversed_start else "right") + f" ({st.first_side})",
        "predicted_worst_nsd_pct": list(geo.candidates),
        "planar": geo.planar,
        "smoothing_scale_m": geo.smooth_scale_m,
        "smoothing_max_shift_m": geo.smoothing_max_shift_m,
        "openings": [{"perimeter_m": o.perimeter_m, "area_m2": o.area_m2} for o in openings],
        "notches": [{"mouth_m": o.mouth_m, "depth_m": o.depth_m, "area_m2": o.area_m2}
                    for o in geo.notches],
        "samples_brushed_off_over_openings": n_brush_off,
        "planar_width_m": geo.planar_width_m,
        "cross_profiles_computed": geo.profiles[0],
        "cross_profile_cache_hits": geo.profiles[1],
        "passes": [dict(side=p.side, **jsonable(passes[p.side].info)) for p in plan_passes],
    }
    settings_dict = st.to_dict()
    settings_dict["report"] = report
    return CoveragePlan(surface_name=surface.name, applicator=applicator,
                        passes=tuple(plan_passes), start_rule=geo.start_rule,
                        settings=settings_dict)


def _geometry(surface: Surface, applicator: Applicator, st: PlannerSettings,
              caps: dict[int, np.ndarray], axes_x: dict[int, np.ndarray],
              axis_turn_fails_fast: bool) -> FamilyGeometry:
    """Openings and notches, smoothing, start curve and the sweeps of each start order
    (`_plan_orders`, the passes timed under `caps` / `axes_x` as Algorithm 1 generates them);
    the order kept."""
    real_surface = surface
    if st.plan_across_openings:     # pieces a gap apart: one surface, the window between an opening
        surface = stitched_surface(surface, STITCH_GAP_FRACTION * applicator.footprint_radius_m)
    openings = find_openings(surface) if st.plan_across_openings else []
    surface = filled_surface(surface, openings)
    notches = find_notches(surface, NOTCH_DEPTH_FRACTION * applicator.footprint_radius_m) \
        if st.plan_across_openings else []
    surface = closed_surface(surface, notches)
    smooth_scale = smoothing_scale_m(surface, applicator.footprint_radius_m, st.smoothing_m)
    surface = smoothed_surface(surface, smooth_scale)
    pl = Planner(surface, applicator, st)
    pl.smooth_scale = smooth_scale
    pl.speed_caps, pl.tool_x = caps, axes_x
    sc = select_start_curve(surface, st.orientation, st.start_position, st.sample_spacing_m,
                            geom=pl.geom)
    planar = _is_planar(surface)
    planar_w = None
    if planar:
        planar_w = planar_index_width(applicator, st.w_min_m, st.w_max_m, st.w_res_m, st.u_max,
                                      st.width_tolerance_m)
    # Algorithm 1 does not say which side is offset first, and the semi-global width search
    # (known passes on one side, free future passes on the other) depends on it: "best" runs
    # both and keeps the one whose largest predicted optimization-profile σ/μ is smaller.
    orders = {"right": [False], "left": [True], "best": [False, True]}[st.first_side]
    if planar_w is not None:
        orders = orders[:1]               # a plane is symmetric: both orders give one plan
    candidates = _plan_orders(pl, surface.name, sc, orders, planar_w, axis_turn_fails_fast)
    _, reversed_start, passes = min(candidates, key=lambda c: c[0])
    return FamilyGeometry(
        pl=pl, passes=passes, reversed_start=reversed_start,
        candidates=[c[0] for c in candidates], start_rule=sc.rule, planar=planar,
        planar_width_m=None if planar_w is None else planar_w.width_m,
        smooth_scale_m=smooth_scale,
        smoothing_max_shift_m=float(np.max(np.linalg.norm(
            surface.vertices[:len(real_surface.vertices)] - real_surface.vertices, axis=1))),
        openings=openings, profiles=(len(pl.cache), pl.cache_hits), notches=notches)



def _plan_orders(pl: Planner, name: str, sc: Any, orders: list[bool], planar_w: Any,
                 axis_turn_fails_fast: bool) -> list[tuple[float, bool, dict[int, PassGeom]]]:
    """(predicted worst σ/μ [%], reversed start, passes) of each start order (`orders`: the start
    curve reversed or not) that plans, in the order given; raises the first order's PlanError
    when none does. The orders advance one pass at a time in turn (`_sweeps` steps): each
    order's passes are what it plans alone (the planner's caches hold values, not order), but
    an order that fails does so after as many passes as it took, not after the whole other
    order: crs_cowling_creases at the "auto" scale failed on the left-first order's pass 3
    only after the right-first order's 39 passes (~20 s), when `axis_turn_fails_fast` makes
    an `AxisTurnError` end both (`plan_coverage` then plans at the next scale)."""
    steps = {}
    for reverse in orders:
        pts, nrm = (sc.points[::-1], sc.normals[::-1]) if reverse else (sc.points, sc.normals)
        steps[reverse] = _sweeps(pl, name, pts, nrm, planar_w)
    done: dict[bool, dict[int, PassGeom]] = {}
    errors: dict[bool, PlanError] = {}
    while len(done) + len(errors) < len(orders):
        for reverse in orders:
            if reverse in done or reverse in errors:
                continue
            try:
                next(steps[reverse])
            except StopIteration as stop:
                done[reverse] = stop.value
            except AxisTurnError as e:
                if axis_turn_fails_fast:
                    raise
                errors[reverse] = e
            except PlanError as e:      # "best" keeps the order that works
                errors[reverse] = e
    if not done:
        raise errors[orders[0]]
    return [(_predicted_worst(done[r]), r, done[r]) for r in orders if r in done]


def _sweeps(pl: Planner, name: str, start_pts: np.ndarray, start_nrm: np.ndarray,
            planar_w: Any) -> Generator[None, None, dict[int, PassGeom]]:
    """Algorithm 1's two loops from the start curve: offsets to the right (s > 0 along the
    indexing curves, T × n), then to the left, until an offset lies completely outside. A
    generator that yields after each pass it adds and returns the passes {side: pass}."""
    st = pl.st
    start = PassGeom(start_pts, start_nrm, np.ones(len(start_pts), bool), 0, float("nan"))
    start.info = {"rule": "start curve"}
    time_pass(pl, start, pl.nominal_width)      # Algorithm 1: optimize the start curve's speed
    passes: dict[int, PassGeom] = {0: start}
    yield
    right_widths: list[float] = []
    for sign in (1, -1):
        cur = start
        widths_this_side: list[float] = []
        for k in range(1, st.max_passes + 1):
            curves = pl.curves_of(cur)
            sweep_curves = curves if sign > 0 else [mirrored_curve(c) for c in curves]
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
                try:
                    check_offset_order(cur.foot[ok], pts[ok],
                                       f"offset {sign * k:+d} of the {name} plan")
                except PlanError:
                    # a few curves astray: left out, from a pass walked in order (a level
                    # set's wiggles make strays that are folds)
                    level_set = cur.info.get("offset") == "heat-method level set"
                    stray = None if level_set else stray_samples(cur.foot, pts)
                    if stray is None:
                        raise
                    pts = np.where(stray[:, None], np.nan, pts)
                    ok &= ~stray
                    info = dict(info, stray_samples_left_out=int(stray.sum()))
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
                    ok = ok & ~edge_spikes(pl, pts)
                    pts = np.where(ok[:, None], pts, np.nan)
                if st.edge_passes and ok.sum() >= 2:
                    foot, normals, on_part = pl.build_pass(pts, nrm, np.zeros(len(pts), bool),
                                                           extend=False)
                    edge = PassGeom(foot, normals, np.zeros(len(foot), bool), side, w0,
                                     edge=True)
                    # samples at the ends of the current pass whose indexing curves left the
                    # surface along the boundary it ends at have no offset: the edge pass goes
                    # on straight there (as its overspray does), as far as the current pass did
                    # (its on-part stretch: an off-part end of it is already a sideways pass)
                    i_ok = np.flatnonzero(ok)
                    i_on = np.flatnonzero(cur.on_part)
                    s_cur = arc_length(cur.foot)
                    edge.extra_m = (max(0.0, float(s_cur[i_ok[0]] - s_cur[i_on[0]])),
                                    max(0.0, float(s_cur[i_on[-1]] - s_cur[i_ok[-1]])))
                    edge.info = dict(info, edge=True)
                    # its band lies on the part, between it and the previous pass
                    edge.source = (curves, sign * w0)
                    time_pass(pl, edge, w0)
                    passes[side] = edge
                    yield
                break
            foot, normals, on_part = pl.build_pass(pts, nrm, inside)
            new = PassGeom(foot, normals, on_part, side, w0)
            new.info = info
            if st.edge_passes and back_fill(pl, cur, new, sign, w0, pl.last_extension_m) \
                    and cur is start and sign < 0 and 1 in passes:
                # the start curve grew after the right sweep was offset from it: what it gained
                # on the part gets its neighbour on the right too (pass +1, or its edge pass)
                first = passes[1]
                back_fill(pl, first, start, -1, first.width_m, tuple(start.info["back_fill_m"]))
            time_pass(pl, new, w0)                 # Algorithm 1: optimize the new pass's speed
            passes[side] = new
            widths_this_side.append(w0)
            cur = new
            yield
        else:
            raise PlanError(f"Algorithm 1 did not leave the surface after {st.max_passes} passes; "
                            "raise w_min_m or max_passes")
        if sign > 0:
            right_widths = widths_this_side
    return passes


def _predicted_worst(passes: dict[int, PassGeom]) -> float:
    """Largest predicted optimization-profile σ/μ [%] over the passes on the part."""
    vals = [p.info.get("worst_marker_nsd_pct", p.info.get("nsd_pct", 0.0))
            for p in passes.values() if not p.edge and p.side != 0]
    return float(max(vals)) if vals else 0.0


def jsonable(d: dict[str, Any]) -> dict[str, Any]:
    """A copy of a flat dict of figures for JSON: numpy scalars as Python numbers, non-finite
    floats as None."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, float) and not math.isfinite(v):
            v = None
        out[k] = v
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


def _refine(pl: Planner, surface: Surface, passes: list[PassPlan]
            ) -> tuple[list[PassPlan], dict[str, Any]]:
    """`film_refine.refine_plan` on the plan, within the robot's speed caps."""
    caps = []
    for order, p in enumerate(passes):
        cap = pl.speed_caps.get(p.side)
        caps.append(None if cap is None else (cap[::-1] if order % 2 == 1 else cap))
    out, info = refine_plan(pl.app, surface, passes, pl.st, caps)
    return out, jsonable(info)


def _film_guard(pl: Planner, surface: Surface, passes: list[PassPlan]
                ) -> tuple[list[PassPlan], dict[str, Any]]:
    """Keep the speed-optimized passes only as far as the simulated film on the part is no worse
    than at constant speed, on the whole part and on its interior (σ/μ, area weighted)."""
    from paintcell.paint.deposition import thickness
    from paintcell.paint.metrics import boundary_band_mask, boundary_vertices, uniformity

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
    tried = {a: nsd(a) for a in (1.0, 0.75, 0.5, 0.25, 0.125)}
    tried[0.0] = const
    # the blend with the best whole-part film among those no worse than constant speed on the
    # interior and the whole part (α = 0, constant speed, always qualifies)
    ok = [a for a, (w, i) in tried.items() if w <= const[0] and i <= const[1]]
    alpha = min(ok, key=lambda a: (tried[a][0], -a))
    info = {"alpha": alpha, "constant_whole_pct": const[0], "constant_interior_pct": const[1],
            "tried": {str(a): list(v) for a, v in tried.items()}}
    return (passes if alpha == 1.0 else _blend(passes, alpha, base)), info
