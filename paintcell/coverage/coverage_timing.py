"""Timing of the passes of Algorithm 1 (paper §3): overspray extension beyond the surface, TCP
poses at standoff, the sub-offset band, the per-pass speed QP and the boustrophedon execution
order (lengths in m, speeds in m/s)."""

from __future__ import annotations

import numpy as np

from paintcell.core.errors import PlanError
from paintcell.coverage.coverage_planner import PassGeom, Planner
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.coverage.offset import walk
from paintcell.coverage.offset_polyline import arc_length, geodesic_curvature, tangents, unit
from paintcell.coverage.plan import PassPlan, times_from_speeds
from paintcell.coverage.smoothing import FOOTPRINT_FRACTION, limit_turn_rate, smooth_along
from paintcell.coverage.speed_qp import SubOffsetBand, optimize_pass_speed
from paintcell.surface.surface_data import Surface


def _band(pl: Planner, p: PassGeom, half_width_m: float) -> SubOffsetBand | None:
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


def time_pass(pl: Planner, p: PassGeom, w_local: float) -> None:
    """Add overspray and TCP poses to a pass and optimize its speed (paper §3) — called as
    Algorithm 1 generates the pass. The band spans ± band_half_width · w_local [m] (the width to
    the pass it was offset from; for the start curve, the bell's planar Fig. 5 width)."""
    if p.timing is not None:
        return
    st, app = pl.st, pl.app
    h = app.standoff_m
    # a pass whose end already runs off the part (an offset kept beyond the boundary) needs
    # only what is left of the overspray after that stretch
    off = (0.0, 0.0) if p.edge else _off_part_ends_m(p.foot, p.on_part)
    ext = [max(0.0, st.overspray_m - off[0]), max(0.0, st.overspray_m - off[1])]
    if not p.edge:
        # where the surface on both sides of the pass runs on past the end of its overspray (a
        # pass ending in a notch between two tongues), the overspray is counted from there
        ahead = _surface_ahead_m(pl.surface, p.foot, p.normals, 0.5 * w_local)
        ext = [a + st.overspray_m if a > e else e for e, a in zip(ext, ahead, strict=True)]
    foot, normals, on_part = _with_overspray(p.foot, p.normals, p.on_part,
                                             (ext[0] + p.extra_m[0], ext[1] + p.extra_m[1]),
                                             st.sample_spacing_m, h)
    # an edge pass runs on the virtual extension: its normals are the indexing curves' end
    # normals, the facets along the part's boundary, as ragged as the boundary is (a scan's rim),
    # and a standoff magnifies each tilt into a TCP zigzag the time law slows for. It paints only
    # overspray: its axis is low-passed at least at the spray's own scale.
    sigma = max(pl.smooth_scale, FOOTPRINT_FRACTION * app.footprint_radius_m) if p.edge \
        else pl.smooth_scale
    axes = limit_turn_rate(foot, smooth_along(foot, -normals, 0.5 * sigma),
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


def _surface_ahead_m(surface: Surface, foot: np.ndarray, normals: np.ndarray,
                     half_width_m: float) -> tuple[float, float]:
    """How far [m] the surface on both sides of a pass runs on past its head and its tail (a
    pass ending in a notch): along the end tangent, the farthest surface vertex ahead of the end
    within half_width_m of the straight continuation and facing the same side (normal within
    60° of the end's), on its left and on its right, the smaller of the two; 0 when either side
    has none ahead (an edge oblique to the passes: the neighbour pass there paints it)."""
    out = []
    span = min(2, len(foot) - 1)
    for f, n, t in ((foot[0], normals[0], unit(foot[0] - foot[span])),
                    (foot[-1], normals[-1], unit(foot[-1] - foot[-1 - span]))):
        d = surface.vertices - f
        s = d @ t
        lat = np.linalg.norm(d - s[:, None] * t, axis=1)
        side = d @ np.cross(n, t)
        m = (s > 0) & (lat <= half_width_m) & (surface.normals @ n > 0.5)
        left, right = m & (side > 0), m & (side < 0)
        out.append(float(min(s[left].max(), s[right].max())) if left.any() and right.any()
                   else 0.0)
    return out[0], out[1]


def _off_part_ends_m(foot: np.ndarray, on_part: np.ndarray) -> tuple[float, float]:
    """Arc length [m] of the off-part stretch at the head and at the tail of a pass (0, 0 for
    a pass whose ends lie on the part; the whole length for one with no sample on it)."""
    s = arc_length(foot)
    idx = np.flatnonzero(on_part)
    if len(idx) == 0:
        return float(s[-1]), float(s[-1])
    return float(s[idx[0]]), float(s[-1] - s[idx[-1]])


def time_passes(pl: Planner, passes: dict[int, PassGeom],
                st: PlannerSettings) -> list[PassPlan]:
    """Order the timed passes for execution (boustrophedon: every other pass reversed)."""
    out: list[PassPlan] = []
    for order, side in enumerate(sorted(passes)):
        p = passes[side]
        if p.timing is None:
            time_pass(pl, p, p.width_m if np.isfinite(p.width_m) else pl.nominal_width)
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
