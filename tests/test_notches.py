"""Deep bays of a part's outline closed for the plan (paintcell.coverage.notches).

Independent truths: on a flat U-shaped plate (a 0.8 × 0.6 m sheet with a 0.4 m wide, 0.3 m deep
rectangular bay cut from its top edge) the bay found has the cut's mouth, depth and area (closed
forms of the rectangle); a rectangle, and a plate whose edge has a shallow 40 mm bay, have none;
a bay whose sides are meshed in steps a quarter of the boundary's spacing is found with the same
mouth, depth and area; on a plate whose top edge curves in along a circular arc, 0.18 m deep
over 1.4 m (deeper than the depth asked, shallower than a quarter of its mouth), there is none,
and a half-disc bay of 0.3 m radius cut from the same edge is found with its radius as depth,
its diameter as mouth and the half-disc's area; and the plan of the U, planned across the closed
bay and judged by the deposition model on the real mesh, paints both legs with the film of the
plate below the bay.
"""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.coverage.notches import closed_surface, find_notches, notch_samples
from paintcell.coverage.openings import boundary_loops
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import thickness
from paintcell.surface.analytic import grid_faces
from paintcell.surface.surface_data import Surface, surface_from_triangles

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


def _delaunay_plate(in_bay, rim: np.ndarray, w: float, h: float) -> Surface:
    """A w × h plate in z = 0 (normals +z), a 20 mm grid plus the `rim` points (K, 2),
    Delaunay-triangulated, without the triangles whose centroid `in_bay` (xy (T, 2) -> bool)."""
    from scipy.spatial import Delaunay

    x = np.linspace(-w / 2, w / 2, int(round(w / STEP)) + 1)
    y = np.linspace(-h / 2, h / 2, int(round(h / STEP)) + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    g = np.column_stack([X.ravel(), Y.ravel()])
    g = g[~in_bay(g) | (g[:, 1] >= h / 2 - 1e-9)]
    xy = np.unique(np.vstack([g, rim]).round(9), axis=0)
    tri = Delaunay(xy).simplices
    F = tri[~in_bay(xy[tri].mean(axis=1))]
    used = np.unique(F)
    remap = np.full(len(xy), -1)
    remap[used] = np.arange(len(used))
    V = np.column_stack([xy[used], np.zeros(len(used))])
    a = xy[tri[:, 1]] - xy[tri[:, 0]]
    b = xy[tri[:, 2]] - xy[tri[:, 0]]
    assert np.all(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] > 0)          # wound toward +z
    return surface_from_triangles("plate", V, remap[F])


def test_a_bay_with_finely_meshed_sides_is_found_whole() -> None:
    """The bay's sides meshed at 5 mm, the rest at 20 mm: no step down a side runs along the
    mouth, however short."""
    side = np.arange(0.0, 0.3 + 1e-9, 0.005)
    rim = np.vstack([np.column_stack([np.full(len(side), sx), side]) for sx in (-0.2, 0.2)])
    s = _delaunay_plate(lambda p: (np.abs(p[:, 0]) < 0.2 - 1e-9) & (p[:, 1] > 1e-9), rim,
                        0.8, 0.6)
    (n,) = find_notches(s, 0.115)
    assert n.mouth_m == pytest.approx(0.4, abs=1e-9)
    assert n.depth_m == pytest.approx(0.3, abs=1e-9)
    assert n.area_m2 == pytest.approx(0.4 * 0.3, rel=1e-9)


def _arc_bay(radius: float, centre_y: float, w: float = 1.6, h: float = 0.8) -> Surface:
    """The plate with the disc of `radius` about (0, centre_y) cut from its top edge, the cut's
    rim sampled every 10 mm."""
    a = np.linspace(0.0, 2 * np.pi, int(2 * np.pi * radius / 0.01), endpoint=False)
    rim = np.column_stack([radius * np.cos(a), centre_y + radius * np.sin(a)])
    rim = rim[rim[:, 1] <= h / 2 + 1e-9]

    def in_bay(p: np.ndarray) -> np.ndarray:
        return np.hypot(p[:, 0], p[:, 1] - centre_y) < radius - 1e-9

    return _delaunay_plate(in_bay, rim, w, h)


def test_an_edge_that_curves_in_is_no_notch_and_a_half_disc_is() -> None:
    sag, half = 0.18, 0.7                           # 0.18 m deep over a 1.4 m chord
    r = (half ** 2 + sag ** 2) / (2 * sag)
    assert find_notches(_arc_bay(r, 0.4 - sag + r), 0.115) == []
    s = _arc_bay(0.3, 0.4)
    (n,) = find_notches(s, 0.115)
    assert n.depth_m == pytest.approx(0.3, abs=0.002)
    assert n.mouth_m == pytest.approx(0.6, abs=0.01)
    assert n.area_m2 == pytest.approx(np.pi * 0.3 ** 2 / 2, rel=0.01)


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
