"""Start curve (paper §2.3) and the in-surface curve geometry it is built from
(paintcell.coverage.offset)."""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.core.errors import PlanError
from paintcell.coverage.offset import (
    IndexingCurve,
    check_offset_order,
    curve_through,
    indexing_curves,
    stray_samples,
    walk,
)
from paintcell.coverage.offset_polyline import arc_length, geodesic_curvature, resample
from paintcell.coverage.offset_sections import SurfaceGeometry, plane_sections
from paintcell.coverage.start_curve import (
    altitude_sweep,
    average_normal,
    divider_offset,
    select_start_curve,
)
from paintcell.surface import parts
from paintcell.surface.analytic import plane
from tests.helpers import FLAT_GEOMETRY_ATOL_M, MESH_ARC_RTOL

RES = 0.025


def _rotated_plane(angle: float):
    s = plane(1.2, 0.5, RES)
    c, si = np.cos(angle), np.sin(angle)
    T = np.eye(4)
    T[:2, :2] = [[c, -si], [si, c]]
    return s.transformed(T)


def _line_deviation(points: np.ndarray) -> float:
    d = points[-1] - points[0]
    d /= np.linalg.norm(d)
    rel = points - points[0]
    return float(np.max(np.linalg.norm(rel - np.outer(rel @ d, d), axis=1)))


def test_plane_start_curve_is_straight_along_long_side_at_median() -> None:
    s = parts.panel(RES)                               # 1.0 m (x) × 0.8 m (y)
    sc = select_start_curve(s, spacing_m=0.02)
    assert _line_deviation(sc.points) < FLAT_GEOMETRY_ATOL_M
    assert abs(sc.pass_dir[0]) == pytest.approx(1.0, abs=1e-12)
    assert sc.altitude_m == pytest.approx(0.8, abs=1e-9)
    assert "area median" in sc.rule
    # area median of a centred rectangle: the mid line, spanning the full 1 m length
    assert sc.plane_offset_m == pytest.approx(0.0, abs=1e-9)
    assert arc_length(sc.points)[-1] == pytest.approx(1.0, abs=1e-9)
    assert np.all(np.diff(sc.points @ sc.pass_dir) > 0)


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 117.0])
def test_minimal_altitude_finds_rotation_of_a_rectangle(angle_deg: float) -> None:
    s = _rotated_plane(np.deg2rad(angle_deg))
    sc = select_start_curve(s)
    long_axis = np.array([np.cos(np.deg2rad(angle_deg)), np.sin(np.deg2rad(angle_deg)), 0.0])
    assert abs(sc.pass_dir @ long_axis) > np.cos(np.deg2rad(1.0))
    assert sc.altitude_m == pytest.approx(0.5, rel=1e-3)


def test_altitude_sweep_closed_form_for_rectangle() -> None:
    s = parts.panel(RES)
    ang, alt = altitude_sweep(s.vertices, average_normal(s))
    # extent of a 1.0 × 0.8 rectangle across direction θ: |1.0 sin θ| + |0.8 cos θ|
    np.testing.assert_allclose(alt, np.abs(np.sin(ang)) * 1.0 + np.abs(np.cos(ang)) * 0.8,
                               atol=1e-9)


def test_cylinder_principal_orientations() -> None:
    s = parts.cylinder_section(RES)                    # axis x, R = 1 m
    along = select_start_curve(s, "zero-curvature")
    around = select_start_curve(s, "max-curvature")
    assert abs(along.pass_dir[0]) > np.cos(np.deg2rad(1.0))
    assert abs(around.pass_dir[1]) > np.cos(np.deg2rad(1.0))
    # the generator is straight; the circle around has length R·arc = 1.2 m
    assert _line_deviation(along.points) < 1e-9
    assert arc_length(around.points)[-1] == pytest.approx(1.2, rel=MESH_ARC_RTOL)


def test_gaussian_curvature_divider_splits_total_curvature() -> None:
    s = parts.fender(RES)
    sc = select_start_curve(s)
    assert "gaussian-curvature divider" in sc.rule
    proj = s.vertices @ sc.plane_normal
    kda = s.gaussian_curvature * s.vertex_areas
    lo, hi = kda[proj < sc.plane_offset_m].sum(), kda[proj >= sc.plane_offset_m].sum()
    # re-measured: the halves differ by at most the K·A of one grid row next to the plane
    near = np.abs(proj - sc.plane_offset_m) < 1.5 * RES
    assert abs(lo - hi) <= 2 * np.abs(kda[near]).sum()
    assert sc.total_k_rad == pytest.approx(kda.sum())


def test_divider_offset_closed_form() -> None:
    proj = np.array([0.0, 1.0, 2.0, 3.0])
    assert divider_offset(proj, np.array([1.0, 1.0, 1.0, 1.0])) == pytest.approx(1.0)
    assert divider_offset(proj, np.array([0.0, 0.0, 2.0, 2.0])) == pytest.approx(2.0)


def test_user_overrides() -> None:
    s = parts.panel(RES)
    sc = select_start_curve(s, orientation=np.pi / 2, position=0.25)
    assert abs(sc.pass_dir[1]) == pytest.approx(1.0, abs=1e-12)
    proj = s.vertices @ sc.plane_normal
    assert sc.plane_offset_m == pytest.approx(proj.min() + 0.25 * (proj.max() - proj.min()))
    assert "user" in sc.rule
    with pytest.raises(PlanError):
        select_start_curve(s, orientation="diagonal")
    with pytest.raises(PlanError):
        select_start_curve(s, position=1.5)
    with pytest.raises(PlanError):
        select_start_curve(s, orientation="zero-curvature")   # a plane has no principal axis


def test_plane_section_of_cylinder_is_an_arc() -> None:
    s = parts.cylinder_section(RES)
    geom = SurfaceGeometry.from_surface(s)
    secs = plane_sections(geom, [0.1, 0.0, 0.0], [1.0, 0.0, 0.0])
    assert len(secs) == 1 and not secs[0].closed
    p = secs[0].points
    assert np.allclose(p[:, 0], 0.1, atol=FLAT_GEOMETRY_ATOL_M)
    assert arc_length(p)[-1] == pytest.approx(1.2, rel=MESH_ARC_RTOL)
    assert plane_sections(geom, [5.0, 0.0, 0.0], [1.0, 0.0, 0.0]) == []


def test_indexing_curve_walk_is_geodesic_on_cylinder() -> None:
    s = parts.cylinder_section(RES)
    geom = SurfaceGeometry.from_surface(s)
    top = int(np.argmax(s.vertices[:, 2]))
    p, n = s.vertices[top], s.normals[top]
    (c,) = indexing_curves(geom, p[None], np.array([[1.0, 0.0, 0.0]]), n[None])
    assert c is not None
    for w in (0.1, 0.3, -0.25):
        q, qn, inside = c.sample(np.array([w]))
        assert inside[0]
        # arc length w on R = 1 m ⇒ chord 2 sin(w/2), and the right side of +x on +z is -y
        assert np.linalg.norm(q[0] - p) == pytest.approx(2 * np.sin(abs(w) / 2),
                                                         rel=MESH_ARC_RTOL)
        assert np.sign(q[0, 1] - p[1]) == -np.sign(w)
    # beyond the boundary the curve continues straight along its end tangent
    q, _, inside = c.sample(np.array([c.s_max + 0.1]))
    assert not inside[0]
    end, _, _ = c.sample(np.array([c.s_max]))
    assert np.linalg.norm(q[0] - end[0]) == pytest.approx(0.1, rel=1e-9)


def test_walk_handles_missing_curves() -> None:
    s = np.linspace(-1, 1, 11)
    c = IndexingCurve(np.stack([s, 0 * s, 0 * s], 1), np.tile([0, 0, 1.0], (11, 1)), s)
    pts, _, inside = walk([c, None], 0.5)
    assert inside.tolist() == [True, False]
    assert np.isnan(pts[1]).all()
    np.testing.assert_allclose(pts[0], [0.5, 0, 0])


def test_walk_gives_no_offset_beyond_an_end_that_leaves_along_the_boundary() -> None:
    # a pass ending on the boundary x = 0.5 of a 1.0 × 0.8 sheet, its tangent tilted 0.2° off
    # +x (the round-off of a mesh): the indexing plane through its end point nearly contains
    # that boundary. To one side the section leaves at once along it, to the other it hugs the
    # boundary row and leaves across the side boundary y = +0.4 at the corner.
    geom = SurfaceGeometry.from_surface(plane(1.0, 0.8, 0.05))
    tilt = np.deg2rad(0.2)
    t = np.array([np.cos(tilt), np.sin(tilt), 0.0])
    right = np.cross(t, [0.0, 0.0, 1.0])                          # ≈ -y
    c = curve_through(geom, [0.5, 0.1, 0.0], t, right)
    assert c is not None
    assert c.s_max < 1e-6 and c.s_min == pytest.approx(-0.3, abs=1e-3)
    assert c.extends == (True, False)
    pts, _, inside = walk([c], 0.2)                               # beyond the end left along
    assert np.isnan(pts).all() and not inside[0]
    pts, _, inside = walk([c], -0.45)                             # beyond the side boundary
    np.testing.assert_allclose(pts[0, 1], 0.55, atol=1e-3)
    assert not inside[0]
    assert c.reversed().extends == (False, True)
    # an indexing curve across the sheet leaves across both side boundaries
    c = curve_through(geom, [0.1, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0])
    assert c is not None and c.extends == (True, True)


def test_geodesic_curvature_of_planar_circle() -> None:
    r = 0.4
    th = np.linspace(0, np.pi, 400)
    pts = np.stack([r * np.cos(th), r * np.sin(th), 0 * th], 1)   # counter-clockwise seen from +z
    nrm = np.tile([0.0, 0.0, 1.0], (len(th), 1))
    kg = geodesic_curvature(pts, nrm, smoothing_m=0.02)
    # second differences at step h on a circle: O((h/r)²) = 2.5e-3 plus chord interpolation
    np.testing.assert_allclose(kg, 1 / r, rtol=1e-2)                # bends to the left: +1/r
    assert np.allclose(geodesic_curvature(pts[::-1], nrm), -1 / r, rtol=1e-2)
    line = np.stack([th, 0 * th, 0 * th], 1)
    assert np.max(np.abs(geodesic_curvature(line, nrm))) < 1e-9


def test_resample_keeps_ends_and_spacing() -> None:
    pts = np.array([[0.0, 0, 0], [0.3, 0, 0], [0.3, 0.5, 0]])
    nrm = np.tile([0, 0, 1.0], (3, 1))
    q, qn, f = resample(pts, nrm, 0.1, np.array([True, False, True]))
    np.testing.assert_allclose(q[[0, -1]], pts[[0, -1]])
    np.testing.assert_allclose(np.linalg.norm(np.diff(q, axis=0), axis=1).max(), 0.1, atol=1e-3)
    assert f[0] and f[-1]


def test_reversing_offset_is_refused() -> None:
    src = np.stack([np.linspace(0, 1, 11), np.zeros(11), np.zeros(11)], 1)
    off = src + [0.0, -0.2, 0.0]
    check_offset_order(src, off, "ok")                 # parallel: accepted
    bad = off.copy()
    bad[5:7, 0] = bad[5:7, 0][::-1] + [0.15, -0.15]     # a swallowtail
    with pytest.raises(PlanError, match="self-intersects"):
        check_offset_order(src, bad, "offset +1")


def test_a_stray_sample_is_left_out_and_a_cusp_is_not() -> None:
    """An offset (41 samples) whose one sample landed two steps back (an indexing curve turned
    at an opening's corner) reverses twice; left out, the rest runs in order, and only that
    sample is named. Two strays, a NaN sample skipped, likewise. Not mended: a swallowtail over
    nine samples (a cusp), and one stray on an offset of 12 samples (over 5 % of it)."""
    src = np.stack([np.linspace(0, 2, 41), np.zeros(41), np.zeros(41)], 1)
    off = src + [0.0, -0.2, 0.0]
    assert not stray_samples(src, off).any()
    one = off.copy()
    one[8, 0] -= 0.1                                   # two steps back
    with pytest.raises(PlanError, match="self-intersects"):
        check_offset_order(src, one, "offset +1")
    np.testing.assert_array_equal(np.flatnonzero(stray_samples(src, one)), [8])
    two = one.copy()
    two[25, 0] -= 0.12
    two[3] = np.nan                                    # a curve that left the surface
    got = stray_samples(src, two)
    assert got is not None
    np.testing.assert_array_equal(np.flatnonzero(got), [8, 25])
    keep = np.all(np.isfinite(two), axis=1) & ~got
    check_offset_order(src[keep], two[keep], "mended")
    cusp = off.copy()
    cusp[6:15, 0] = cusp[6:15, 0][::-1]                 # nine samples run backward
    assert stray_samples(src, cusp) is None
    assert stray_samples(src[:12], one[:12]) is None    # 1 of 12: a fold forming, not a stray


def test_sphere_cap_start_curve_is_a_great_circle_through_the_axis() -> None:
    """Analytic sphere cap (R = 0.6 m, 60° half-angle): ∫K dA = 2π(1 − cos 60°) = π; by
    symmetry the Gaussian-curvature divider is the plane through the cap's axis, so the start
    curve is a great circle: its points lie on the sphere (to the facet sag e²/8R of the 24 mm
    icosphere edges, 1.2e-4 m) in a plane through the centre."""
    import trimesh

    from paintcell.surface.surface_data import Surface

    radius = 0.6
    ico = trimesh.creation.icosphere(subdivisions=5, radius=radius)
    keep = ico.triangles_center[:, 2] > radius * np.cos(np.radians(60))
    cap = trimesh.Trimesh(ico.vertices, ico.faces[keep])
    cap.remove_unreferenced_vertices()
    sc = select_start_curve(Surface.from_mesh(cap, name="cap"))
    assert "gaussian-curvature divider" in sc.rule
    assert sc.total_k_rad == pytest.approx(np.pi, rel=1e-3)         # code: 5e-4
    assert abs(sc.plane_offset_m) < 1e-9                               # plane through the centre
    assert abs(sc.plane_normal[2]) < 1e-9                              # ... and the axis
    sag = 0.024**2 / (8 * radius)
    np.testing.assert_allclose(np.linalg.norm(sc.points, axis=1), radius, atol=1.5 * sag)
    np.testing.assert_allclose(sc.points @ sc.plane_normal, sc.plane_offset_m, atol=1e-12)


def _components_brute(geom: SurfaceGeometry, cross: np.ndarray) -> list[set[int]]:
    """Connected components of the crossings (two crossed edges of one face are linked), by a
    plain breadth-first search over the faces, written here from the definition."""
    at = {int(e): k for k, e in enumerate(cross)}
    nbrs: dict[int, set[int]] = {k: set() for k in range(len(cross))}
    for fe in geom.face_edges:
        hit = [at[int(e)] for e in fe if int(e) in at]
        if len(hit) == 2:
            nbrs[hit[0]].add(hit[1])
            nbrs[hit[1]].add(hit[0])
    comps, seen = [], set()
    for k in range(len(cross)):
        if k in seen:
            continue
        comp, todo = {k}, [k]
        while todo:
            for j in nbrs[todo.pop()] - comp:
                comp.add(j)
                todo.append(j)
        seen |= comp
        comps.append(comp)
    return comps


def test_section_components_are_ordered_chains_of_the_whole_component() -> None:
    """Plane sections of a doubly curved part with a hole-free, bumpy skin: each component the
    ordering returns (all of them, or the one holding a wanted crossing, as an indexing curve
    asks) is exactly a connected component found by brute force, every consecutive pair of its
    crossings shares a face, and an open chain starts at one of its ends."""
    from paintcell.coverage.offset_sections import order_components, section_crossings

    geom = SurfaceGeometry.from_surface(parts.get_part("hood", 0.05))
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(6):
        o = geom.vertices[rng.integers(len(geom.vertices))]
        nrm = rng.normal(size=3)
        d = (geom.vertices - o) @ (nrm / np.linalg.norm(nrm))
        cross, _, _ = section_crossings(geom, d)
        truth = _components_brute(geom, cross)
        faces_of = [set(geom.edge_faces[e]) - {-1} for e in cross]
        wanted = np.array([int(rng.integers(len(cross)))])
        for want in (None, wanted):
            got = order_components(geom, d, cross, want)
            expect = truth if want is None else [c for c in truth if int(wanted[0]) in c]
            assert sorted(map(sorted, (set(o.tolist()) for o, _ in got))) == \
                sorted(map(sorted, expect))
            for order, closed in got:
                assert len(set(order.tolist())) == len(order)
                assert all(faces_of[a] & faces_of[b]
                           for a, b in zip(order[:-1], order[1:], strict=True))
                if not closed and len(order) > 1:
                    first = order[0]
                    links = sum(bool(faces_of[first] & faces_of[j]) for j in order if j != first)
                    assert links == 1
                checked += 1
    assert checked >= 12
