"""A robot-aware re-plan re-times the kept pass geometry (`paintcell.coverage.
family_geometry`) instead of planning the passes again: the same plan, array by array, as a
re-plan from scratch, without a single width search, and within its caps."""

from __future__ import annotations

import numpy as np
import pytest

import paintcell.coverage.coverage_planner as cp
from paintcell.coverage import family_geometry
from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.paint.applicator import Applicator
from paintcell.surface import parts

# a curved part (width searches on markers) and both start orders planned
ST = PlannerSettings(sample_spacing_m=0.04, overspray_m=0.1, n_knots=8, first_side="best")


@pytest.fixture
def searches(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """[the index-width searches run since], counted from an empty geometry cache."""
    count = [0]
    orig = cp.search_widths

    def counted(*a, **k):
        count[0] += 1
        return orig(*a, **k)

    monkeypatch.setattr(cp, "search_widths", counted)
    family_geometry.forget()
    return count


def _assert_same_plan(a: object, b: object) -> None:
    """Every array of the two plans equal (dtype and values), and their settings."""
    x, y = a._arrays(), b._arrays()
    assert x.keys() == y.keys()
    for k in x:
        assert x[k].dtype == y[k].dtype and np.array_equal(x[k], y[k]), k
    assert a.settings == b.settings


def test_a_capped_replan_retimes_the_kept_passes_and_equals_a_replan_from_scratch(
        searches: list[int]) -> None:
    s = parts.cylinder_section(0.05)
    plan = plan_coverage(s, Applicator.default(), ST)
    assert searches[0] > 0 and len(plan.passes) >= 3
    # caps at 80 % of the planned speed over the middle third of every other pass (generation
    # direction: execution order reversed on odd passes), bell x axes turned 30° off the travel
    caps, tool_x = {}, {}
    for i, p in enumerate(plan.passes):
        v = p.speeds_m_s[::-1] if i % 2 else p.speeds_m_s
        tr = -p.travel_dirs[::-1] if i % 2 else p.travel_dirs
        ax = p.spray_axes[::-1] if i % 2 else p.spray_axes
        if i % 2 == 0:
            c = np.full(len(v), ST.v_max_m_s)
            m = len(v) // 3
            c[m:2 * m] = 0.8 * v[m:2 * m]
            caps[p.side] = c
        tool_x[p.side] = np.cos(np.pi / 6) * tr + np.sin(np.pi / 6) * np.cross(ax, tr)
    searches[0] = 0
    kept = plan_coverage(s, Applicator.default(), ST, speed_caps_m_s=caps, tool_x=tool_x)
    assert searches[0] == 0                     # no index-width search: the geometry was kept
    family_geometry.forget()
    fresh = plan_coverage(s, Applicator.default(), ST, speed_caps_m_s=caps, tool_x=tool_x)
    assert searches[0] > 0                      # planned from scratch
    _assert_same_plan(kept, fresh)
    # the caps moved the speeds, not the passes; every capped sample is within its cap
    moved = 0.0
    for i, (p, q) in enumerate(zip(plan.passes, kept.passes, strict=True)):
        np.testing.assert_array_equal(q.positions, p.positions)
        moved = max(moved, float(np.max(np.abs(q.speeds_m_s - p.speeds_m_s))))
        if p.side in caps:
            cap = caps[p.side][::-1] if i % 2 else caps[p.side]
            assert np.all(q.speeds_m_s <= cap * (1 + 1e-6))
    assert moved > 0.01


def test_a_refined_plan_after_the_unrefined_one_plans_its_passes_once(
        searches: list[int]) -> None:
    """`paintcell init` plans a part without the film refinement, then with it: the second
    plan re-times the kept passes (no width search) and equals a refined plan from scratch."""
    import dataclasses

    s = parts.cylinder_section(0.05)
    plain = plan_coverage(s, Applicator.default(), dataclasses.replace(ST, film_refine=False))
    assert searches[0] > 0
    searches[0] = 0
    refined = plan_coverage(s, Applicator.default(), ST)
    assert searches[0] == 0
    family_geometry.forget()
    fresh = plan_coverage(s, Applicator.default(), ST)
    assert searches[0] > 0
    _assert_same_plan(refined, fresh)
    # the refinement re-timed the same poses
    assert refined.settings["report"]["film_refine"]["applied"]
    for p, q in zip(plain.passes, refined.passes, strict=True):
        np.testing.assert_array_equal(q.positions, p.positions)
    assert max(float(np.max(np.abs(q.speeds_m_s - p.speeds_m_s)))
               for p, q in zip(plain.passes, refined.passes, strict=True)) > 1e-3
