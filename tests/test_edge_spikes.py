"""Samples that jump off a pass's line and back (`paintcell.coverage.offset_polyline.spikes`), and
edge passes that no longer carry them (`paintcell.coverage.coverage_planner.edge_spikes`).

Independent truths: smooth curves in closed form (a circle arc of 0.3 m radius, a helix, a
straight line) sampled at 20 mm have no spike; a run of samples displaced by a known vector is
flagged exactly; and on a door generated as a closed thin solid, whose window frame meets the
panel in corners (the edge passes' virtual extension turned 170° there and piled 7× the film),
every pass's TCP path, re-measured from the plan's positions, turns by less than 45° between
consecutive samples, and the planned film stays inside the paint spec.
"""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.coverage.offset_polyline import spikes

STEP_M = 0.02


def _arc(radius_m: float = 0.3, n: int = 60) -> np.ndarray:
    a = np.arange(n) * STEP_M / radius_m
    return np.column_stack([radius_m * np.cos(a), radius_m * np.sin(a), np.zeros(n)])


def _helix(n: int = 80) -> np.ndarray:
    a = np.arange(n) * 0.05
    return np.column_stack([0.4 * np.cos(a), 0.4 * np.sin(a), 0.01 * np.arange(n)])


@pytest.mark.parametrize("curve", [_arc(), _arc(0.15), _helix(),
                                   np.column_stack([np.arange(50) * STEP_M, np.zeros((50, 2))])])
def test_smooth_curves_have_no_spike(curve: np.ndarray) -> None:
    assert not spikes(curve, 6, 2 * STEP_M).any()


@pytest.mark.parametrize("at,width", [(20, 1), (30, 3), (2, 1), (55, 2)])
def test_a_displaced_run_of_samples_is_flagged_exactly(at: int, width: int) -> None:
    c = _arc()
    c[at:at + width] += np.array([0.0, 0.0, 0.15])       # off the arc's plane by 0.15 m
    flagged = spikes(c, 6, 2 * STEP_M)
    want = np.zeros(len(c), bool)
    want[at:at + width] = True
    np.testing.assert_array_equal(flagged, want)


def test_an_end_sample_is_its_own_median() -> None:
    """The window shrinks symmetrically toward an end: the end sample has no neighbours to be
    judged by (an end-point extrapolation flagged the ends of curved edge passes)."""
    c = _arc()
    c[[0, -1]] += np.array([0.0, 0.0, 0.15])
    assert not spikes(c, 6, 2 * STEP_M).any()


def test_missing_samples_are_skipped_and_never_flagged() -> None:
    c = _arc()
    c[10:14] = np.nan
    c[40] += np.array([0.1, 0.1, 0.0])
    flagged = spikes(c, 6, 2 * STEP_M)
    assert flagged[40] and flagged.sum() == 1
    assert not flagged[10:14].any()


def _turns_deg(p: np.ndarray) -> np.ndarray:
    d = np.diff(p, axis=0)
    n = np.linalg.norm(d, axis=1)
    d = d[n > 1e-9] / n[n > 1e-9, None]
    return np.degrees(np.arccos(np.clip(np.sum(d[1:] * d[:-1], axis=1), -1.0, 1.0)))


@pytest.mark.slow
def test_edge_passes_of_a_framed_closed_door_do_not_turn_back(tmp_path) -> None:
    from paintcell.coverage.coverage import plan_coverage
    from paintcell.coverage.coverage_settings import PlannerSettings
    from paintcell.paint.applicator import Applicator
    from paintcell.paint.deposition import thickness
    from paintcell.paint.metrics import uniformity
    from paintcell.surface.part_families import make_family_part
    from paintcell.surface.part_spec import MeshPart
    from paintcell.surface.part_surface import part_surface

    f = tmp_path / "door.stl"
    make_family_part("door_solid", 0).mesh.export(f)
    skin = part_surface(MeshPart(file=str(f)), 0.025).region_surface(("skin",))
    app = Applicator.default()
    plan = plan_coverage(skin, app, PlannerSettings())
    edge = [q["side"] for q in plan.settings["report"]["passes"] if q.get("edge")]
    assert edge                                     # the case: passes wholly past an edge
    for p in plan.passes:
        assert _turns_deg(p.positions).max() < 45.0, (p.side, _turns_deg(p.positions).max())
    t = thickness(app, plan.gun_samples(), skin.vertices, skin.normals)
    assert uniformity(t, skin.vertex_areas).nsd_pct < 10.0
