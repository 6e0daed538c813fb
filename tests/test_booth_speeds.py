"""Robot-aware speeds in a cell of N robots (paintcell.motion.speed_feedback.robot_aware_parts,
measured by paintcell.motion.speed_caps.part_speeds for any number of robots): a robot's
slowdown, measured on its chained program, lands as caps on the very samples it ran slow — found
again by where they are in space — through a part run backwards and a robot with two jobs."""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.booth.booth import Job
from paintcell.booth.booth_build import reversed_plan
from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.motion.speed_caps import (
    caps_from_speeds,
    part_speeds,
    planner_order,
    stored_caps,
)
from paintcell.paint.applicator import Applicator
from paintcell.surface import parts
from tests.helpers import stand_in_program

APP = Applicator.default()
ST = PlannerSettings(sample_spacing_m=0.04, overspray_m=0.1, n_knots=8, film_guard=False)


def _arc(p) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                           axis=1))])


def test_a_slowdown_in_a_reversed_part_is_capped_where_it_happened() -> None:
    plan0 = plan_coverage(parts.panel(0.04), APP, ST)       # the planner's own plan
    n = len(plan0.passes)
    assert n >= 4
    fin = reversed_plan(plan0)                               # the part runs backwards
    # robot 0 runs passes 0-1 of the finished plan; robot 1 chains two jobs: passes 2-2 and
    # 3..n, its second job slowed to 70 % over 0.3-0.5 m of its first pass (finished pass 3)
    jobs = {0: (Job(0, 0, 2),), 1: (Job(0, 2, 3), Job(0, 3, n))}
    prog0 = stand_in_program(fin.passes[0:2], {})
    prog1 = stand_in_program(fin.passes[2:n], {1: (0.3, 0.5, 0.7)})
    prog1.meta["job_first_pass_index"] = [0, 1]
    v_act = part_speeds([fin], jobs, [prog0, prog1])
    asked = [p.speeds_m_s for p in fin.passes]
    caps, n_new, worst = caps_from_speeds(plan0, planner_order(v_act[0], True),
                                          planner_order(asked, True))
    assert n_new > 0 and 25.0 <= worst <= 31.0
    # one pass capped: the planner's pass that finished pass 3 is (n - 1 - 3)
    p0 = plan0.passes[n - 4]
    assert set(caps) == {p0.side}
    gen = caps[p0.side]
    stored0 = gen[::-1] if (n - 4) % 2 == 1 else gen        # planner's execution order
    capped_xyz = p0.positions[np.isfinite(stored0)]
    # independent truth: where finished pass 3 ran slow, by position in space
    p3 = fin.passes[3]
    s3 = _arc(p3)
    nearest = np.argmin(np.linalg.norm(capped_xyz[:, None] - p3.positions[None], axis=2), axis=1)
    assert np.all((s3[nearest] > 0.3 - 0.05) & (s3[nearest] < 0.5 + 0.05))
    core = (s3 > 0.34) & (s3 < 0.46)
    back = stored_caps(plan0, caps, reverse=True)
    assert all(c is None for j, c in enumerate(back) if j != 3)
    assert np.all(np.isfinite(back[3][core]))
    assert np.all(back[3][core] < 0.75 * p3.speeds_m_s[core])
    assert np.all(np.isinf(back[3][(s3 < 0.2) | (s3 > 0.6)]))
    # nothing slowed: nothing capped
    free = [stand_in_program(fin.passes[0:2], {}), stand_in_program(fin.passes[2:n], {})]
    free[1].meta["job_first_pass_index"] = [0, 1]
    v_free = part_speeds([fin], jobs, free)
    caps, n_new, _ = caps_from_speeds(plan0, planner_order(v_free[0], True),
                                      planner_order(asked, True))
    assert caps == {} and n_new == 0


def _caps_at(plan, ratio_of_pass: dict[int, float]) -> dict[int, np.ndarray]:
    """Caps {side: generation direction} at ratio × the asked speed on whole passes."""
    caps = {}
    for i, r in ratio_of_pass.items():
        p = plan.passes[i]
        c = r * np.asarray(p.speeds_m_s, float)
        caps[p.side] = c[::-1] if i % 2 == 1 else c
    return caps


def test_part_pace_is_the_slowdown_the_flow_cannot_make_up() -> None:
    """`part_pace` by hand: r = cap ÷ asked per sample (the caps of the first round are the
    speeds the film sees, the flow's floor already counted); k = the 5 % quantile of r, clipped
    to [0.5, 1], 1 above 0.9."""
    from paintcell.motion.speed_feedback import PACE_MIN, part_pace

    plan = plan_coverage(parts.panel(0.04), APP, ST)
    n_samples = sum(len(p.speeds_m_s) for p in plan.passes)
    # every sample reached at 80 % of the asked speed: k = 0.8
    every = _caps_at(plan, {i: 0.8 for i in range(len(plan.passes))})
    assert part_pace(plan, every) == pytest.approx(0.8, rel=1e-12)
    # one pass of several at 20 %: more than 5 % of the samples, k = 0.2 → the floor
    one = _caps_at(plan, {1: 0.2})
    assert len(plan.passes[1].speeds_m_s) > 0.05 * n_samples
    assert part_pace(plan, one) == PACE_MIN
    # a slowdown the pace would hardly shorten (r ≥ 0.9): the planned speeds
    assert part_pace(plan, _caps_at(plan, {1: 0.92})) == 1.0
    # a few samples, under 5 % of the part, deeply slowed: not worth a slower part
    p = plan.passes[0]
    few = np.full(len(p.speeds_m_s), np.inf)
    few[:2] = 0.1 * p.speeds_m_s[:2]
    assert 2 < 0.05 * n_samples
    assert part_pace(plan, {p.side: few}) == 1.0
    # no caps at all
    assert part_pace(plan, {}) == 1.0


def test_a_paced_plan_is_the_same_film_slower() -> None:
    """`paced`: the same passes (positions) at k × the speeds, so k × the paint per metre: the
    film on the part is 1 / k thicker everywhere and its σ/μ the same (the speed QP's problem
    scales with its bounds); measured on the panel's own vertices by the deposition model."""
    from paintcell.motion.speed_feedback import paced
    from paintcell.paint.deposition import thickness

    surf = parts.panel(0.04)
    k = 0.6
    a, b = plan_coverage(surf, APP, ST), plan_coverage(surf, APP, paced(ST, k))
    assert len(a.passes) == len(b.passes)
    for pa, pb in zip(a.passes, b.passes, strict=True):
        np.testing.assert_allclose(pb.positions, pa.positions, atol=1e-9)
        np.testing.assert_allclose(pb.speeds_m_s, k * pa.speeds_m_s, rtol=2e-3)
    fa = thickness(APP, a.gun_samples(), surf.vertices, surf.normals)
    fb = thickness(APP, b.gun_samples(), surf.vertices, surf.normals)
    np.testing.assert_allclose(fb, fa / k, rtol=5e-3, atol=1e-3 * fa.max())
    # planned with the bell's flow turned down by the pace: the unpaced plan's film
    c = plan_coverage(surf, APP.scaled(k), paced(ST, k))
    fc = thickness(c.applicator, c.gun_samples(), surf.vertices, surf.normals)
    np.testing.assert_allclose(fc, fa, rtol=5e-3, atol=1e-3 * fa.max())
    assert paced(ST, 1.0) is ST


def test_a_scaled_bell_is_the_same_pattern_at_another_flow() -> None:
    """`Applicator.scaled`: f × factor at every point of the plane, and the closed-form emitted
    flow (∫∫ f dx dy) × factor; the footprint unchanged."""
    k = 0.58
    b = APP.scaled(k)
    x, y = np.meshgrid(np.linspace(-0.4, 0.4, 41), np.linspace(-0.4, 0.4, 41))
    np.testing.assert_allclose(b.flux(x, y), k * APP.flux(x, y), rtol=1e-12, atol=0.0)
    assert b.emitted_flow_m3_s == pytest.approx(k * APP.emitted_flow_m3_s, rel=1e-12)
    assert b.footprint_radius_m == pytest.approx(APP.footprint_radius_m, rel=1e-9)


def test_a_paced_part_is_refined_within_its_own_bounds() -> None:
    """`planned_speeds`: the part table's bounds scaled by the pace the plan records (its nominal
    speed over the table's), the table's own where the plan was planned at it."""
    import dataclasses

    from paintcell.booth.booth_plans import planned_speeds
    from paintcell.motion.speed_feedback import paced

    plan = plan_coverage(parts.panel(0.04), APP, paced(ST, 0.6))
    got = planned_speeds(ST, plan)
    assert (got.v_nominal_m_s, got.v_min_m_s, got.v_max_m_s) == pytest.approx(
        (0.6 * ST.v_nominal_m_s, 0.6 * ST.v_min_m_s, 0.6 * ST.v_max_m_s), rel=1e-12)
    own = plan_coverage(parts.panel(0.04), APP, ST)
    assert planned_speeds(ST, own) is ST
    # a part table with a lower v_max than its plan's (the plan made elsewhere): the table's
    table = dataclasses.replace(ST, v_max_m_s=0.55)
    assert planned_speeds(table, own) is table
