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


def _corner(turn_deg: float, legs: int = 12) -> np.ndarray:
    """A polyline at 20 mm along x that turns by `turn_deg` at its middle sample."""
    a = np.radians(turn_deg)
    back = -np.arange(legs, 0, -1)[:, None] * STEP_M * np.array([1.0, 0.0, 0.0])
    ahead = np.arange(legs + 1)[:, None] * STEP_M * np.array([np.cos(a), np.sin(a), 0.0])
    return np.vstack([back, ahead])


def _rotation(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rodrigues' rotation matrix about the unit `axis` (3,)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle_rad) * k + (1 - np.cos(angle_rad)) * (k @ k)


@pytest.mark.parametrize("turn_deg", [30.0, 60.0, 80.0, 90.0, 120.0, 170.0])
def test_flags_do_not_depend_on_how_the_curve_lies(turn_deg: float) -> None:
    """The same corner, and the same arc with a spike, turned to several orientations against
    the world axes (in its plane and out of it) get the same flags; a corner's apex is flagged
    exactly when its apex lies farther than the tolerance from the median of its window, which
    for straight legs is ⌈h/2⌉ spacings back along each leg: 3 · 20 mm · sin(turn / 2) > 40 mm,
    a turn above 2·asin(2/3) = 83.6°; a turn-back (170°) takes the samples next to its apex
    along."""
    rng = np.random.default_rng(3)
    spiky = _arc()
    spiky[25] += np.array([0.0, 0.0, 0.12])
    axes = [np.array([0.0, 0.0, 1.0])] + [v / np.linalg.norm(v) for v in rng.normal(size=(4, 3))]
    for curve in (_corner(turn_deg), spiky):
        ref = spikes(curve, 6, 2 * STEP_M)
        for axis in axes:
            for ang in (np.pi / 4, np.pi / 6, 1.0, np.pi / 2):
                turned = curve @ _rotation(axis, ang).T + np.array([0.3, -1.2, 0.7])
                np.testing.assert_array_equal(spikes(turned, 6, 2 * STEP_M), ref)
    flagged = np.flatnonzero(spikes(_corner(turn_deg), 6, 2 * STEP_M))
    if turn_deg < 150.0:
        want = [12] if 3 * np.sin(np.radians(turn_deg) / 2) > 2 else []
        np.testing.assert_array_equal(flagged, want)
    else:           # a turn-back: its neighbours jump off too, but not past half the window
        assert 12 in flagged and np.abs(flagged - 12).max() <= 3


def _turns_deg(p: np.ndarray) -> np.ndarray:
    d = np.diff(p, axis=0)
    n = np.linalg.norm(d, axis=1)
    d = d[n > 1e-9] / n[n > 1e-9, None]
    return np.degrees(np.arccos(np.clip(np.sum(d[1:] * d[:-1], axis=1), -1.0, 1.0)))


@pytest.mark.slow
def test_edge_passes_of_a_framed_closed_door_do_not_turn_back(tmp_path) -> None:
    from paintcell.coverage.algorithm import plan_coverage
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
