"""Algorithm 1 end to end: geometry of the passes re-measured, coverage of the part, round trips."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from paintcell.core.errors import PlanError
from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.coverage.index_width import nsd_vs_index_width, planar_index_width
from paintcell.coverage.plan import CoveragePlan
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate_reference, thickness
from paintcell.paint.metrics import boundary_band_mask, boundary_vertices, uniformity
from paintcell.surface import parts
from paintcell.surface.surface_data import Surface
from tests.helpers import FLAT_GEOMETRY_ATOL_M, KERNEL_CULL_RTOL, MESH_ARC_RTOL

RES = 0.025
FAST = PlannerSettings(optimize_speed=False, sample_spacing_m=0.025)
APP = Applicator.default()


def _feet(plan: CoveragePlan, i: int, on_part: bool = True) -> np.ndarray:
    p = plan.passes[i]
    keep = p.on_part if on_part else np.ones(len(p.on_part), bool)
    return (p.positions + APP.standoff_m * p.spray_axes)[keep]


@pytest.fixture(scope="module")
def panel_plan() -> CoveragePlan:
    return plan_coverage(parts.panel(RES), APP, FAST)


@pytest.fixture(scope="module")
def cylinder_plan() -> CoveragePlan:
    s = parts.cylinder_section(RES)
    return plan_coverage(s, APP, PlannerSettings(optimize_speed=False, sample_spacing_m=0.025,
                                                 orientation="zero-curvature"))


def test_settings_validate_and_round_trip() -> None:
    st = PlannerSettings(orientation=0.3, start_position=0.4, first_side="left")
    assert PlannerSettings.from_dict(st.to_dict()) == st
    for bad in ({"u_max": 0.0}, {"w_min_m": 0.5, "w_max_m": 0.2}, {"band_curves": 4},
                {"orientation": "diagonal"}, {"start_position": 2.0},
                {"v_nominal_m_s": 2.0}, {"n_future": 0}, {"first_side": "up"}):
        with pytest.raises(PlanError):
            PlannerSettings(**bad)
    with pytest.raises(PlanError, match="unknown"):
        PlannerSettings.from_dict({"speed": 1.0})


@pytest.mark.parametrize("field", ["start_position", "overspray_m", "width_change_weight",
                                   "band_half_width", "u_max", "n_knots"])
def test_settings_reject_bools_for_numbers(field: str) -> None:
    # bool is an int subclass: True would silently read as 1 (the far end, 1 m of overspray)
    with pytest.raises(PlanError, match=f"PlannerSettings.{field} = True"):
        PlannerSettings(**{field: True})
    with pytest.raises(PlanError, match="True or False"):
        PlannerSettings(optimize_speed=1)  # type: ignore[arg-type]


def test_plan_coverage_checks_its_inputs() -> None:
    s = parts.panel(0.1)
    with pytest.raises(PlanError, match="needs a paintcell.surface.analytic.Surface, "
                                         "got NoneType"):
        plan_coverage(None, APP)  # type: ignore[arg-type]
    with pytest.raises(PlanError,
                       match=r"needs an Applicator \(paintcell.paint.applicator\), "
                             "got dict"):
        plan_coverage(s, APP.to_dict())  # type: ignore[arg-type]
    with pytest.raises(PlanError, match="PlannerSettings or None, got dict"):
        plan_coverage(s, APP, FAST.to_dict())  # type: ignore[arg-type]


def test_plane_passes_straight_parallel_equally_spaced(panel_plan: CoveragePlan) -> None:
    want = planar_index_width(APP, FAST.w_min_m, FAST.w_max_m, FAST.w_res_m, FAST.u_max,
                              FAST.width_tolerance_m).width_m
    sides = [p.side for p in panel_plan.passes]
    assert sides == sorted(sides) and 0 in sides
    ys = []
    for i, p in enumerate(panel_plan.passes):
        foot = _feet(panel_plan, i, on_part=False)
        # straight, along x, on the plane, TCP at standoff along the normal
        assert np.ptp(foot[:, 1]) < FLAT_GEOMETRY_ATOL_M
        assert np.allclose(foot[:, 2], 0.0, atol=FLAT_GEOMETRY_ATOL_M)
        assert np.allclose(p.positions[:, 2], APP.standoff_m, atol=FLAT_GEOMETRY_ATOL_M)
        assert np.allclose(np.abs(p.travel_dirs[:, 0]), 1.0, atol=1e-12)
        ys.append(foot[0, 1])
        if p.side != 0:
            assert p.index_width_m == pytest.approx(want, abs=1e-12)
    gaps = np.abs(np.diff(ys))
    np.testing.assert_allclose(gaps, want, atol=FLAT_GEOMETRY_ATOL_M)
    # the passes cover the whole width: the outermost on-part passes lie within w of the edges
    # and the edge passes beyond them (sideways overspray)
    assert min(ys) < -0.4 + 1e-9 and max(ys) > 0.4 - 1e-9


def test_plane_overspray_and_alternating_direction(panel_plan: CoveragePlan) -> None:
    for i, p in enumerate(panel_plan.passes):
        x = p.positions[:, 0]
        assert x.max() == pytest.approx(0.5 + FAST.overspray_m, abs=1e-9)
        assert x.min() == pytest.approx(-0.5 - FAST.overspray_m, abs=1e-9)
        assert p.paint_on.all()
        foot_x = x[p.on_part]
        if len(foot_x):
            assert np.all(np.abs(foot_x) <= 0.5 + 1e-9)
        assert np.all(np.abs(x[~p.on_part]) > 0.5 - 1e-9) or not p.on_part.any()
        direction = np.sign(p.travel_dirs[:, 0].mean())
        assert direction == (1 if i % 2 == 0 else -1)
        # constant speed: times re-measured from the path length
        assert np.allclose(p.speeds_m_s, FAST.v_nominal_m_s)
        assert p.duration_s == pytest.approx(p.length_m / FAST.v_nominal_m_s)


def test_cylinder_generators_spaced_by_arc_length(cylinder_plan: CoveragePlan) -> None:
    ths = []
    for i, p in enumerate(cylinder_plan.passes):
        if not p.on_part.any():
            continue
        foot = _feet(cylinder_plan, i)
        # axis x, R = 1 m, centre of curvature below the part: the angle is constant on a
        # generator and the radius is R
        centre_z = foot[:, 2] - np.sqrt(1.0 - foot[:, 1] ** 2)
        assert np.ptp(centre_z) < 1e-6
        th = np.arctan2(foot[:, 1], foot[:, 2] - centre_z)
        assert np.ptp(th) < 1e-6
        assert np.allclose(np.abs(p.travel_dirs[:, 0]), 1.0, atol=1e-6)
        assert p.max_geodesic_curvature_1_m < 1e-6
        ths.append((p.side, float(th.mean()), p.index_width_m))
    ths.sort()
    for (s0, t0, _), (s1, t1, w1) in zip(ths, ths[1:], strict=False):
        w = w1 if s1 > 0 else dict((s, ww) for s, _, ww in ths)[s0]
        assert abs(t1 - t0) * 1.0 == pytest.approx(w, rel=MESH_ARC_RTOL)


def test_cylinder_around_passes_are_circles_spaced_straight() -> None:
    s = parts.cylinder_section(RES)
    plan = plan_coverage(s, APP, PlannerSettings(optimize_speed=False, sample_spacing_m=0.025,
                                                 orientation="max-curvature"))
    xs = []
    for i, p in enumerate(plan.passes):
        if p.on_part.any():
            foot = _feet(plan, i)
            assert np.ptp(foot[:, 0]) < 1e-9              # a circle x = const
            xs.append((p.side, foot[0, 0], p.index_width_m))
    xs.sort()
    gaps = np.abs(np.diff([x for _, x, _ in xs]))
    widths = [w if sd > 0 else None for sd, _, w in xs]
    assert np.all(gaps >= FAST.w_min_m - 1e-9) and np.all(gaps <= FAST.w_max_m + 1e-9)
    assert any(w is not None for w in widths)


@pytest.mark.parametrize("name", ["panel", "cylinder_section", "door"])
def test_union_of_passes_covers_whole_part(name: str) -> None:
    s = parts.get_part(name, RES)
    plan = plan_coverage(s, APP, FAST)
    film = thickness(APP, plan.gun_samples(), s.vertices, s.normals)
    target = float(np.dot(film, s.vertex_areas) / s.vertex_areas.sum())
    assert film.min() >= 0.5 * target, f"{name}: min {film.min() / target:.2f} of the mean"


def test_plane_mean_film_matches_flow_over_speed_times_width(panel_plan: CoveragePlan) -> None:
    # independent truth: parallel passes at spacing w and speed v build Q / (v w) in the interior
    s = parts.panel(RES)
    film = thickness(APP, panel_plan.gun_samples(), s.vertices, s.normals)
    w = panel_plan.passes[-2].index_width_m
    interior = (np.abs(s.vertices[:, 0]) < 0.2) & (np.abs(s.vertices[:, 1]) < 0.2)
    want = APP.emitted_flow_m3_s / (FAST.v_nominal_m_s * w)
    assert film[interior].mean() == pytest.approx(want, rel=0.02)


def test_save_load_round_trip(tmp_path, panel_plan: CoveragePlan) -> None:
    path = tmp_path / "plan.json"
    panel_plan.save(path)
    back = CoveragePlan.load(path)
    assert back.start_rule == panel_plan.start_rule
    assert back.settings == panel_plan.settings
    assert len(back.passes) == len(panel_plan.passes)
    for a, b in zip(panel_plan.passes, back.passes, strict=True):
        for name in ("positions", "spray_axes", "travel_dirs", "speeds_m_s", "times_s",
                     "on_part", "paint_on"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert a.side == b.side
        assert (a.index_width_m == b.index_width_m
                or (np.isnan(a.index_width_m) and np.isnan(b.index_width_m)))
    assert PlannerSettings.from_dict(back.settings) == FAST


#: Fig. 5 closed form against the planned film: the plan's film is sampled like
#: `nsd_vs_index_width` (one period, midpoints), so only the gun's 25 mm sampling along the pass
#: (trapezoid dwell) and the finite pass count separate them; measured 5e-5 relative.
FIG5_NSD_RTOL = 2e-3


def test_plane_interior_nsd_matches_fig5_closed_form(panel_plan: CoveragePlan) -> None:
    # independent truth: parallel straight passes at width w on a plane give the Fig. 5 σ/μ(w)
    # (paintcell.coverage.index_width, 1-D profile sums) in the interior, one period
    # between two passes
    w = panel_plan.passes[-2].index_width_m
    centre = int(np.flatnonzero([p.side == 0 for p in panel_plan.passes])[0])
    y0 = float(np.median(panel_plan.passes[centre].positions[:, 1]))
    n = 200
    ys = y0 + (np.arange(n) + 0.5) / n * w
    xs = np.linspace(-0.15, 0.15, 9)         # ≥ footprint radius (0.46 m) inside the pass ends
    #                                          (±0.65 m: the 1 m panel plus 0.15 m overspray)
    xx, yy = np.meshgrid(xs, ys)
    pts = np.c_[xx.ravel(), yy.ravel(), np.zeros(xx.size)]
    nrm = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    film = thickness(APP, panel_plan.gun_samples(), pts, nrm)
    got = film.std() / film.mean()
    want = float(nsd_vs_index_width(APP, [w])[0])
    assert got == pytest.approx(want, rel=FIG5_NSD_RTOL), (100 * got, 100 * want)


def test_saved_plan_is_byte_reproducible(tmp_path) -> None:
    s = parts.panel(0.05)
    st = PlannerSettings(sample_spacing_m=0.05, n_knots=6)
    for d in ("a", "b"):
        plan_coverage(s, APP, st).save(tmp_path / d / "plan.json")
    a, b = ((tmp_path / d / "plan.json").read_bytes() for d in ("a", "b"))
    assert a == b


def test_real_plan_times_follow_its_speeds() -> None:
    # what the film validation integrates (times_s) is what the robot executes (speeds_m_s, speed²
    # linear in arc length): Δt = 2 Δs / (v_i + v_i+1) on every segment of an optimized door plan
    s = parts.door(0.04)
    plan = plan_coverage(s, APP, PlannerSettings(sample_spacing_m=0.04, n_knots=8))
    assert any(np.ptp(p.speeds_m_s) > 0.05 for p in plan.passes)     # speeds really vary
    for p in plan.passes:
        ds = np.linalg.norm(np.diff(p.positions, axis=0), axis=1)
        dt = 2.0 * ds / (p.speeds_m_s[1:] + p.speeds_m_s[:-1])
        np.testing.assert_allclose(np.diff(p.times_s), dt, rtol=1e-12)
    p = plan.passes[0]
    with pytest.raises(PlanError, match="times_s and speeds_m_s disagree"):
        replace(p, times_s=p.times_s * 1.01)


def test_planning_is_deterministic() -> None:
    s = parts.door(0.04)
    st = PlannerSettings(optimize_speed=False, sample_spacing_m=0.04)
    a, b = plan_coverage(s, APP, st), plan_coverage(s, APP, st)
    assert len(a.passes) == len(b.passes)
    for pa, pb in zip(a.passes, b.passes, strict=True):
        np.testing.assert_array_equal(pa.positions, pb.positions)


def test_speed_optimized_plan_is_never_worse_than_constant_on_the_film() -> None:
    """Checked on the film itself (the plan's samples through the literal reference kernel), not
    on the speed module's band figures: whole part and interior (> 100 mm from the boundary)."""
    s = parts.panel(0.04)
    st = PlannerSettings(sample_spacing_m=0.04, overspray_m=0.1, n_knots=12)
    opt = plan_coverage(s, APP, st)
    const = plan_coverage(s, APP, replace(st, optimize_speed=False))
    for p in opt.passes:
        assert np.all(p.speeds_m_s >= st.v_min_m_s * (1 - 1e-6))
        assert np.all(p.speeds_m_s <= st.v_max_m_s * (1 + 1e-6))
        acc = np.diff(p.speeds_m_s**2) / (2 * np.linalg.norm(np.diff(p.positions, axis=0),
                                                               axis=1))
        assert np.all(np.abs(acc) <= st.a_max_m_s2 * (1 + 1e-6))
    inner = boundary_band_mask(s.vertices, s.vertices[boundary_vertices(s.faces)], 0.1)

    def film_nsd(plan: CoveragePlan) -> tuple[float, float]:
        g = plan.gun_samples()
        f = deposition_rate_reference(APP, g.positions, g.spray_axes, g.travel_dirs,
                                      s.vertices, s.normals).T @ g.dwell_s
        return (uniformity(f, s.vertex_areas).nsd_pct,
                uniformity(f, s.vertex_areas, mask=inner).nsd_pct)

    w_opt, i_opt = film_nsd(opt)
    w_const, i_const = film_nsd(const)
    assert w_opt <= w_const + 1e-9 and i_opt <= i_const + 1e-9
    # the short overspray leaves the panel ends thin at constant speed: the QP must help there
    assert w_opt < 0.8 * w_const
    assert opt.settings["report"]["film_guard"]["alpha"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("name", parts.PART_NAMES)
def test_algorithm1_terminates_on_every_part_and_covers_it(name: str) -> None:
    # 250 mm overspray: the fender's wheel-arch band wraps ~64° at each end of a pass, and 150 mm
    # along the end tangent leaves its lower corners at ~42 % of the mean at constant speed
    s = parts.get_part(name, RES)
    plan = plan_coverage(s, APP, replace(FAST, overspray_m=0.25))
    film = thickness(APP, plan.gun_samples(), s.vertices, s.normals)
    # an independent film evaluation: the deposition model written literally from DESIGN.md
    # (deposition_rate_reference) on every third vertex, summed with the plan's dwell times
    gun = plan.gun_samples()
    sub = np.arange(0, len(s.vertices), 3)
    ref = deposition_rate_reference(APP, gun.positions, gun.spray_axes, gun.travel_dirs,
                                    s.vertices[sub], s.normals[sub]).T @ gun.dwell_s
    np.testing.assert_allclose(film[sub], ref, rtol=KERNEL_CULL_RTOL, atol=KERNEL_CULL_RTOL
                               * float(ref.max()))
    u = uniformity(ref, s.vertex_areas[sub])
    # σ/μ bounds: the paper's planar 2.64 %; for the curved parts what this plan achieved
    # (constant speed, 250 mm overspray, every third vertex) + 1 point: cylinder 6.17, door 2.95,
    # fender 9.66, hood 1.70, roof 3.51 %; min film ≥ 65 % of the mean (achieved ≥ 71 %). The
    # curvature-robust default bell plans the door in 6 passes at 0.17-0.25 m: door 4.51 % here
    # (its speed-optimized check run: 4.41 %)
    bound = {"panel": 2.64, "cylinder_section": 7.2, "door": 5.5, "fender": 10.7, "hood": 2.7,
             "roof": 4.5}[name]
    assert u.nsd_pct <= bound, f"{name}: σ/μ {u.nsd_pct:.2f} % > {bound} %"
    assert ref.min() >= 0.65 * u.mean_m, f"{name}: min {ref.min() / u.mean_m:.2f} of the mean"
    sides = [p.side for p in plan.passes]
    assert sides == sorted(sides) and len(set(sides)) == len(sides)
    assert len(plan.passes) < FAST.max_passes
    for p in plan.passes:
        assert np.isfinite(p.max_geodesic_curvature_1_m) and p.max_geodesic_curvature_1_m >= 0
        if p.side != 0:
            assert FAST.w_min_m - 1e-9 <= p.index_width_m <= FAST.w_max_m + 1e-9
        # no kinks: the TCP path turns with the normal, at most |k|max per unit foot length
        d = np.diff(p.positions, axis=0)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        turn = np.arccos(np.clip(np.einsum("ij,ij->i", d[1:], d[:-1]), -1.0, 1.0))
        k_max = float(np.abs(s.principal_curvatures).max())
        assert turn.max() <= 1.5 * k_max * FAST.sample_spacing_m + 0.01, (p.side, turn.max())
    report = plan.settings["report"]
    assert len(report["passes"]) == len(plan.passes)
    assert "planning_time_s" not in report          # no wall-clock time in a saved plan


def test_fender_offsets_keep_constant_geodesic_index() -> None:
    # constant-index restriction (paper §4.3) on a doubly curved part: every interior sample of a
    # pass lies at the chosen width from the previous pass. The straight-line distance to the
    # previous pass is the chord of that geodesic arc: w (1 - κ² w² / 24) ≥ 0.97 w for κ ≤ 2 1/m.
    s = parts.fender(RES)
    plan = plan_coverage(s, APP, FAST)
    by_side = {p.side: i for i, p in enumerate(plan.passes)}
    checked = 0
    for side, i in by_side.items():
        p = plan.passes[i]
        prev = side - int(np.sign(side))
        if side == 0 or not p.on_part.any() or prev not in by_side:
            continue
        foot = _feet(plan, i)[3:-3]                       # away from the in-surface extensions
        other = _feet(plan, by_side[prev], on_part=False)
        seg_a, seg_b = other[:-1], other[1:]
        ab = seg_b - seg_a
        t = np.clip(np.einsum("pij,ij->pi", foot[:, None, :] - seg_a[None], ab)
                    / np.einsum("ij,ij->i", ab, ab), 0, 1)
        d = np.linalg.norm(foot[:, None, :] - (seg_a[None] + t[..., None] * ab[None]), axis=2)
        dist = d.min(axis=1)
        w = p.index_width_m
        assert np.all(dist <= w * (1 + MESH_ARC_RTOL)), (side, dist.max() / w)
        assert np.all(dist >= 0.97 * w), (side, dist.min() / w)
        checked += 1
    assert checked >= 2


def test_sphere_cap_offsets_are_small_circles_with_closed_form_geodesic_curvature() -> None:
    # a mesh (not a grid) with K > 0: the start curve through the cap's axis is a great circle;
    # the plane ⟂ its tangent through a sample holds the sphere's centre, so the indexing curve
    # is a great circle too and the offset at arc w is the small circle at angle w/R: its plane
    # lies R sin(w/R) from the centre and κ_g = tan(w/R)/R (closed forms)
    import trimesh

    from paintcell.surface.surface_data import Surface

    radius = 0.6
    ico = trimesh.creation.icosphere(subdivisions=5, radius=radius)     # edges ≈ 24 mm
    keep = ico.triangles_center[:, 2] > radius * np.cos(np.radians(60))
    cap = trimesh.Trimesh(ico.vertices, ico.faces[keep])
    cap.remove_unreferenced_vertices()
    s = Surface.from_mesh(cap, name="cap")
    # the width pinned to 0.15 m, where the faceted-cap tolerance below was measured (the chord
    # error of the section grows with the arc; the width choice is tested elsewhere)
    plan = plan_coverage(s, APP, replace(FAST, w_min_m=0.15, w_max_m=0.15))
    assert "gaussian-curvature divider" in plan.start_rule
    checked = 0
    for i, p in enumerate(plan.passes):
        if abs(p.side) != 1 or p.on_part.sum() < 5:
            continue
        foot = _feet(plan, i)
        centre = foot.mean(axis=0)
        normal = np.linalg.svd(foot - centre)[2][2]
        ang = p.index_width_m / radius
        assert abs(centre @ normal) == pytest.approx(radius * np.sin(ang), rel=MESH_ARC_RTOL)
        # max |κ_g| from second differences over 0.1 m of a faceted section: chord noise ~2 %
        assert p.max_geodesic_curvature_1_m == pytest.approx(np.tan(ang) / radius, rel=0.03)
        checked += 1
    assert checked == 2


def test_best_first_side_keeps_the_better_predicted_order() -> None:
    s = parts.door(0.04)
    base = PlannerSettings(optimize_speed=False, sample_spacing_m=0.04)
    plans = {side: plan_coverage(s, APP, replace(base, first_side=side))
             for side in ("right", "left", "best")}
    pred = {k: max(r["worst_marker_nsd_pct"] for r in p.settings["report"]["passes"]
                   if not r.get("edge") and r["side"] != 0) for k, p in plans.items()}
    assert pred["best"] == pytest.approx(min(pred["right"], pred["left"]))
    assert plans["best"].settings["report"]["predicted_worst_nsd_pct"] == pytest.approx(
        [pred["right"], pred["left"]])


def test_offset_past_a_focal_point_is_refused() -> None:
    # a start curve far off the hemisphere's axis is a small circle of high geodesic curvature;
    # its offsets toward the small circle's pole shrink and then pass through it (a cusp)
    import trimesh

    from paintcell.surface.surface_data import Surface

    ico = trimesh.creation.icosphere(subdivisions=4, radius=0.5)
    keep = ico.triangles_center[:, 2] > 0.02
    dome = trimesh.Trimesh(ico.vertices, ico.faces[keep])
    dome.remove_unreferenced_vertices()
    s = Surface.from_mesh(dome, name="dome")
    # the plain width rule (width_tolerance_m = 0): with the width rule's sensitivity window the
    # narrower widths on this dome walk a later level-set pass onto the pole (a degenerate pass)
    st = PlannerSettings(optimize_speed=False, start_position=0.2, sample_spacing_m=0.04,
                         geodesic_fallback=False, width_tolerance_m=0.0)
    with pytest.raises(PlanError, match="self-intersects"):
        plan_coverage(s, APP, st)
    # With the fallback (the default) the walked offset that reverses is replaced by a level set
    # of the heat-method geodesic distance (paintcell.coverage.geodesic), which cannot
    # self-intersect.
    plan = plan_coverage(s, APP, replace(st, geodesic_fallback=True))
    assert any(r.get("offset") == "heat-method level set"
               for r in plan.settings["report"]["passes"])


def _turn_limit_rad(curvature_1_m: float, spacing_m: float) -> float:
    """The no-kink criterion: the TCP path turns with the normal, at most |k|max per unit foot
    length (with the margin of `test_algorithm1_terminates_on_every_part_and_covers_it`)."""
    return 1.5 * curvature_1_m * spacing_m + 0.01


def _max_turn_rad(positions: np.ndarray) -> float:
    d = np.diff(positions, axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return float(np.arccos(np.clip(np.einsum("ij,ij->i", d[1:], d[:-1]), -1.0, 1.0)).max())


MESH_RES = 0.02
# film_guard off: the per-pass QP speeds are compared (the guard blends the whole plan at once)
MESH_ST = PlannerSettings(orientation="zero-curvature", film_guard=False)


@pytest.mark.parametrize("name", ["door", "fender"])
def test_part_from_a_mesh_file_plans_like_the_parametric_part(name: str, tmp_path) -> None:
    # The same part exported as a bare mesh (no (u, v), normals and sections from the triangles).
    # Before: the edge pass of the door kinked 42° at its end (the indexing curve through the
    # pass's last sample, on the boundary the pass ends at, left the mesh at once along that
    # boundary, and its straight extension was taken as the offset) and its speed ran to v_max;
    # the fender's passes turned 7° at their ends (one-sided boundary vertex normals).
    lib = parts.get_part(name, MESH_RES)
    path = tmp_path / f"{name}.stl"
    lib.mesh.export(path)
    mesh = Surface.from_mesh(path)
    want = plan_coverage(lib, APP, MESH_ST)
    plan = plan_coverage(mesh, APP, MESH_ST)
    assert sorted(p.side for p in plan.passes) == sorted(p.side for p in want.passes)
    assert sum(not p.on_part.any() for p in plan.passes) == 2         # both edge passes
    k_max = float(np.abs(lib.principal_curvatures).max())         # the part's true curvature
    limit = _turn_limit_rad(k_max, MESH_ST.sample_spacing_m)
    ref = {p.side: p for p in want.passes}
    for p in plan.passes:
        assert _max_turn_rad(p.positions) <= limit, (name, p.side, _max_turn_rad(p.positions))
        # the bell axis turns no faster than on the library part (+0.25°; < 2.5° where that
        # one does: the default bell's pass 2 of the fender turns 2.55° mid-pass on both)
        axes = np.einsum("ij,ij->i", p.spray_axes[1:], p.spray_axes[:-1])
        ref_axes = np.einsum("ij,ij->i", ref[p.side].spray_axes[1:],
                             ref[p.side].spray_axes[:-1])
        ref_turn = float(np.degrees(np.arccos(np.clip(ref_axes.min(), -1, 1))))
        assert np.degrees(np.arccos(np.clip(axes.min(), -1, 1))) < max(2.5, ref_turn + 0.25), \
            (name, p.side)
        # the edge passes reach as far as the library part's (no end sample dropped for good)
        length = arc_length_m(p.positions)
        assert length == pytest.approx(arc_length_m(ref[p.side].positions), abs=0.03)
        # speeds within the QP's bounds, and the pass ends at the speed the QP gives the
        # parametric part there (not run up to v_max by a kink)
        assert np.all(p.speeds_m_s >= MESH_ST.v_min_m_s * (1 - 1e-6))
        assert np.all(p.speeds_m_s <= MESH_ST.v_max_m_s * (1 + 1e-6))
        ends = sorted([p.speeds_m_s[0], p.speeds_m_s[-1]])
        ref_ends = sorted([ref[p.side].speeds_m_s[0], ref[p.side].speeds_m_s[-1]])
        if p.on_part.any():
            # (an edge pass's end speeds are weakly determined — its paint there lands off the
            # part — so for edge passes only the no-run-up check below applies)
            np.testing.assert_allclose(ends, ref_ends, atol=0.05, err_msg=f"{name} {p.side}")
        # (a pass whose width differs by the 10 mm search step has another band and QP: with
        # the default bell the mesh fender's pass 1, 0.28 vs 0.29 m, legitimately peaks at
        # 0.99 m/s mid-pass against 0.68; its ends are checked above)
        if p.index_width_m == ref[p.side].index_width_m or p.side == 0:
            assert p.speeds_m_s.max() <= ref[p.side].speeds_m_s.max() + 0.1, (name, p.side)


def arc_length_m(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def test_door_from_a_mesh_file_gives_a_robot_program(tmp_path) -> None:
    # the trajectory stage used to fail on the mesh door's kinked edge pass ("TOPP-RA failed on
    # a pass"); the placement of scenarios/door.toml
    from paintcell.app.scenario import facing_robot
    from paintcell.core.placement import Placement
    from paintcell.motion.trajectory import TrajectorySettings, build_program
    from paintcell.robots import load_robot

    path = tmp_path / "door.stl"
    parts.door(MESH_RES).mesh.export(path)
    plan = plan_coverage(Surface.from_mesh(path), APP, MESH_ST)
    T_world_part = Placement(xyz_m=(1.4, 0.0, 1.0), rpy_rad=facing_robot()).matrix
    T_world_base = Placement(xyz_m=(-0.623, -0.3, 0.5), rpy_rad=(0.0, 0.0, 0.1651)).matrix
    robot = load_robot("abb_paint", T_world_base=T_world_base)
    traj = build_program(robot, plan, T_world_part,
                         TrajectorySettings(q_home=(0.0, -0.6, 0.3, 0.0, 0.9, 0.0)))
    assert traj.meta["reachability"]["all_reachable"]
    assert traj.meta["cycle_time_s"] > sum(p.times_s[-1] for p in plan.passes)


def test_a_door_turned_end_for_end_plans_alike(tmp_path) -> None:
    """A generated door (door_solid, seed 3) as written and turned 180° about z: a rigid motion
    changes nothing of the part, so its plan must not change either — the same passes and the
    planned film as even (σ/μ over the skin within 0.3 pp). The two imports differ by a face at
    the window's corner, where one indexing curve of an outer pass lands behind its neighbours'
    offsets; that sample is left out (the pass's report says so) rather than the pass being
    re-made as a level set that bends round the window (σ/μ 10.7 % against 2.5 %)."""
    from paintcell.surface.part_families import make_family_part
    from paintcell.surface.part_import import import_part
    from paintcell.surface.part_spec import MeshPart

    mesh = make_family_part("door_solid", 3).mesh
    turned = mesh.copy()
    turned.apply_transform(np.diag([-1.0, -1.0, 1.0, 1.0]))
    nsd, n_passes, strays = [], [], []
    for k, m in enumerate((mesh, turned)):
        path = tmp_path / f"door_{k}.stl"
        m.export(path)
        surf, _ = import_part(MeshPart(file=str(path)), resolution_m=0.025)
        skin = surf.region_surface(("skin",))
        plan = plan_coverage(skin, APP, PlannerSettings(film_refine=False))
        film = thickness(APP, plan.gun_samples(), skin.vertices, skin.normals)
        nsd.append(uniformity(film, skin.vertex_areas).nsd_pct)
        n_passes.append(len(plan.passes))
        strays.append(sum(p.get("stray_samples_left_out", 0)
                          for p in plan.settings["report"]["passes"]))
    assert n_passes[0] == n_passes[1]
    assert abs(nsd[0] - nsd[1]) < 0.3, nsd
    assert max(strays) > 0      # the case this is about: a stray sample met, and left out
