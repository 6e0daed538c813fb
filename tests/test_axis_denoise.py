"""Bell axes fitted along each pass by a local quadratic (paintcell.coverage.smoothing.
denoise_along), so that the facet noise of a scanned rim does not reach the TCP path.

Independent truths: a unit field turning at a constant rate along a straight line (the normals
of a pass around a cylinder, closed form cos/sin) comes back unchanged to a few 1e-5 rad, ends
included, where a local mean pulls the end axes toward the inside; a ±1° alternation of the axis
is cancelled; and on a flat plate whose rim zigzags ±3 mm out of its plane (the ragged outline
of a scan: the boundary vertex normals alternate by ~8°), every pass — the edge passes that take
their axes from the rim's normals included — keeps its bell axis within a degree of the plate's
normal, and its TCP path within a millimetre of a straight line at the standoff.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from paintcell.coverage.coverage import PlannerSettings, plan_coverage
from paintcell.coverage.smoothing import denoise_along, smooth_along
from paintcell.paint.applicator import Applicator
from paintcell.surface.surface import Surface, grid_faces, surface_from_triangles

SIGMA_M = 0.041


def _line(length_m: float = 1.0, step_m: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    s = np.arange(0.0, length_m + 1e-9, step_m)
    return s, np.column_stack([s, np.zeros_like(s), np.zeros_like(s)])


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0)))


def test_a_steadily_turning_axis_comes_back_unchanged_at_the_ends_too() -> None:
    s, foot = _line()
    k = 2.0                                    # 1/m: the normals of a 0.5 m radius cylinder
    axes = np.column_stack([np.sin(k * s), np.zeros_like(s), -np.cos(k * s)])
    out = denoise_along(foot, axes, SIGMA_M)
    assert _angle_deg(out, axes).max() < 0.01       # deg, ends included
    # a local mean, by contrast, pulls the end axes toward the inside by ~σκ
    assert _angle_deg(smooth_along(foot, axes, SIGMA_M), axes)[[0, -1]].min() > 1.0


def test_an_alternating_wiggle_is_cancelled() -> None:
    s, foot = _line()
    tilt = np.radians(1.0) * (-1.0) ** np.arange(len(s))
    wig = np.column_stack([np.sin(tilt), np.zeros_like(s), -np.cos(tilt)])
    out = denoise_along(foot, wig, SIGMA_M)
    down = np.tile([0.0, 0.0, -1.0], (len(s), 1))
    assert _angle_deg(out, down)[3:-3].max() < 0.05
    # the end samples: a local quadratic has the fewest samples to cancel with there
    assert _angle_deg(out, down).max() < 0.7
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-12)


def ragged_plate(res_m: float = 0.02, tilt_deg: float = 3.0) -> Surface:
    """0.6 m × 0.42 m plate in z = 0 whose boundary vertex normals tilt alternately ±`tilt_deg`
    about the rim (a scan's normal estimate at a ragged outline); the geometry stays flat."""
    x = np.linspace(-0.3, 0.3, int(round(0.6 / res_m)) + 1)
    y = np.linspace(-0.21, 0.21, int(round(0.42 / res_m)) + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    F = grid_faces(len(x), len(y))
    s = surface_from_triangles("ragged", V, F)
    if s.normals[:, 2].mean() < 0:
        s = surface_from_triangles("ragged", V, F[:, ::-1])
    i, j = np.meshgrid(np.arange(len(x)), np.arange(len(y)), indexing="ij")
    rim = ((i == 0) | (j == 0) | (i == len(x) - 1) | (j == len(y) - 1)).ravel()
    a = np.radians(tilt_deg) * (-1.0) ** (i + j).ravel()
    # tilted toward the rim's outward direction (x on the short sides, y on the long ones)
    along_x = ((i == 0) | (i == len(x) - 1)).ravel()
    n = np.column_stack([np.where(along_x, np.sin(a), 0.0), np.where(along_x, 0.0, np.sin(a)),
                         np.cos(a)])
    return dataclasses.replace(s, normals=np.where(rim[:, None], n, s.normals))


@functools.lru_cache(maxsize=1)
def _ragged_plan():
    st = PlannerSettings(orientation=0.0, first_side="right", smoothing_m=None,
                         optimize_speed=False)
    return plan_coverage(ragged_plate(), Applicator.default(), st)


def test_the_rim_normals_do_not_reach_the_passes_of_a_ragged_plate() -> None:
    plan = _ragged_plan()
    app = Applicator.default()
    assert any(not p.on_part.any() for p in plan.passes)      # an edge pass is among them
    for p in plan.passes:
        ax, pos = p.spray_axes, p.positions
        down = np.tile([0.0, 0.0, -1.0], (len(ax), 1))
        # the rim's ±3° alternation (taken raw: axis steps of 6°, second differences of 12°)
        # reaches no axis as a wiggle: what bends is the corner's own tilt, spread smoothly
        a2 = np.degrees(np.linalg.norm(ax[2:] - 2.0 * ax[1:-1] + ax[:-2], axis=1))
        assert a2.max() < 0.5, p.side
        assert _angle_deg(ax[1:], ax[:-1]).max() < 1.0, p.side
        assert _angle_deg(ax, down).max() < 3.5, p.side
        # the TCP path: no sideways zigzag (raw, the 0.25 m standoff made 52 mm second
        # differences of it); the few mm left are the overspray's start at the corner
        d2 = np.linalg.norm(pos[2:] - 2.0 * pos[1:-1] + pos[:-2], axis=1)
        assert d2.max() < 8e-3, p.side
        assert np.abs(pos[:, 2] - app.standoff_m).max() < 0.005, p.side
