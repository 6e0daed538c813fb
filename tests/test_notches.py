"""Deep bays of a part's outline closed for the plan (paintcell.coverage.notches).

Independent truths: on a flat U-shaped plate (a 0.8 × 0.6 m sheet with a 0.4 m wide, 0.3 m
deep rectangular bay cut from its top edge) the bay found has the cut's mouth, depth and area
(closed forms of the rectangle); a rectangle, and a plate whose edge has a shallow 40 mm bay,
have none; and the plan of the U, planned across the closed bay and judged by the deposition
model on the real mesh, paints both legs with the film of the plate below the bay.
"""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.coverage.coverage import PlannerSettings, plan_coverage
from paintcell.coverage.notches import closed_surface, find_notches, notch_samples
from paintcell.coverage.openings import boundary_loops
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import thickness
from paintcell.surface.surface import Surface, grid_faces, surface_from_triangles

STEP = 0.02


def cut_plate(bay_w: float, bay_d: float, w: float = 0.8, h: float = 0.6) -> Surface:
    """A w × h plate in z = 0 (normals +z, y up) with a bay_w wide, bay_d deep rectangle cut
    from the middle of its top edge (bay_d = 0: no cut)."""
    x = np.linspace(-w / 2, w / 2, int(round(w / STEP)) + 1)
    y = np.linspace(-h / 2, h / 2, int(round(h / STEP)) + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    F = grid_faces(len(x), len(y))
    c = V[F].mean(axis=1)
    cut = (np.abs(c[:, 0]) < bay_w / 2) & (c[:, 1] > h / 2 - bay_d)
    F = F[~cut]
    used = np.unique(F)
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    V, F = V[used], remap[F]
    s = surface_from_triangles("cut", V, F)
    return s if s.normals[:, 2].mean() > 0 else surface_from_triangles("cut", V, F[:, ::-1])


def test_the_bay_of_a_u_plate_is_found_with_its_mouth_depth_and_area() -> None:
    s = cut_plate(0.4, 0.3)
    (n,) = find_notches(s, 0.115)
    assert n.mouth_m == pytest.approx(0.4, abs=1e-9)
    assert n.depth_m == pytest.approx(0.3, abs=1e-9)
    assert n.area_m2 == pytest.approx(0.4 * 0.3, rel=1e-9)
    # closed: one boundary loop, the plate's outline, and the fill's samples cover the bay
    closed = closed_surface(s, [n])
    assert len(boundary_loops(closed.faces, len(closed.vertices))) == 1
    assert closed.area == pytest.approx(0.8 * 0.6, rel=1e-9)
    pts, nrm, w = notch_samples(s, [n])
    assert w.sum() == pytest.approx(0.12, rel=1e-9)
    assert np.all(nrm[:, 2] > 0.999)                   # on the painted side, as the plate's
    assert np.all((np.abs(pts[:, 0]) <= 0.2 + 1e-9) & (pts[:, 1] >= 0.0 - 1e-9))


def test_a_rectangle_and_a_shallow_bay_have_no_notch() -> None:
    assert find_notches(cut_plate(0.4, 0.0), 0.115) == []
    assert find_notches(cut_plate(0.4, 0.04), 0.115) == []


def _leg_films(across: bool) -> tuple[float, float, float]:
    """Mean planned film [m] on the left leg, the right leg and the part below the bay."""
    s = cut_plate(0.4, 0.3)
    st = PlannerSettings(orientation=0.0, first_side="right", optimize_speed=False,
                         plan_across_openings=across)
    plan = plan_coverage(s, Applicator.default(), st)
    film = thickness(plan.applicator, plan.gun_samples(), s.vertices, s.normals)
    V, a = s.vertices, s.vertex_areas
    legs = V[:, 1] > 0.05
    left, right, base = legs & (V[:, 0] < -0.25), legs & (V[:, 0] > 0.25), V[:, 1] < -0.05

    def mean(m: np.ndarray) -> float:
        return float(np.dot(a[m], film[m]) / a[m].sum())

    return mean(left), mean(right), mean(base)


def test_both_legs_of_the_u_get_the_film_of_its_base() -> None:
    left, right, base = _leg_films(True)
    for leg in (left, right):
        assert 0.8 * base < leg < 1.25 * base, (left, right, base)
