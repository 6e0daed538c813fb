"""Surfaces: analytic curvature against closed forms, discrete curvature against smooth truth,
mesh repair and refusal, rigid transforms."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from paintcell.core.errors import SurfaceError
from paintcell.coverage.offset_sections import SurfaceGeometry
from paintcell.surface.analytic import (
    bspline_patch,
    cylinder,
    extruded,
    greville_abscissae,
    grid_faces,
    plane,
)
from paintcell.surface.curvature import (
    boundary_vertex_mask,
    discrete_curvature,
    mixed_voronoi_areas,
    vertex_normals,
)
from paintcell.surface.surface_data import Surface
from tests.helpers import (
    ANALYTIC_CURVATURE_ATOL,
    DISCRETE_CURVATURE_RTOL,
    MESH_AREA_RTOL,
    ROUND_TRIP_ATOL_M,
    assert_unit,
)


def _sphere_cap_grid(radius: float, half: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Regular (x, y) grid lifted onto the upper sphere of `radius`, CCW from outside."""
    x = np.linspace(-half, half, n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    V = np.stack([X, Y, np.sqrt(radius ** 2 - X ** 2 - Y ** 2)], -1).reshape(-1, 3)
    return V, grid_faces(n, n)


# --- analytic constructors ---------------------------------------------------------------------
def test_plane_is_flat_and_sized() -> None:
    s = plane(0.6, 0.4, resolution_m=0.02)
    assert s.grid_shape == (31, 21)
    assert np.allclose(s.gaussian_curvature, 0) and np.allclose(s.mean_curvature, 0)
    assert np.allclose(s.normals, [0, 0, 1])
    assert s.area == pytest.approx(0.24, rel=1e-12)
    assert np.allclose(s.vertices.min(0), [-0.3, -0.2, 0]) and np.allclose(s.vertices.max(0),
                                                                          [0.3, 0.2, 0])
    # Row-major u order: vertex i*nv + j has uv = (u_i, v_j), and uv is arc length [m].
    nu, nv = s.grid_shape
    uv = s.uv.reshape(nu, nv, 2)
    assert np.allclose(uv[:, 0, 1], 0) and np.allclose(uv[0, :, 0], 0)
    assert np.allclose(s.vertices[:, :2] + [0.3, 0.2], s.uv)


def test_faces_wind_toward_normals() -> None:
    for s in (plane(0.3, 0.2, 0.05), cylinder(0.5, 0.3, 1.0, 0.05),
              extruded(np.stack([np.linspace(1, 0, 20), np.zeros(20)], 1), 0.3, 0.05)):
        tri = s.vertices[s.faces]
        fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        assert np.all((fn * s.normals[s.faces].mean(1)).sum(1) > 0), s.name
        assert_unit(s.normals)


def test_cylinder_closed_form_curvature() -> None:
    R = 0.8
    s = cylinder(R, 0.5, 1.5, resolution_m=0.02)
    tol = ANALYTIC_CURVATURE_ATOL
    assert np.allclose(s.gaussian_curvature, 0, atol=tol)
    assert np.allclose(s.mean_curvature, 1 / (2 * R), atol=tol)
    assert np.allclose(s.principal_curvatures, [1 / R, 0], atol=tol)
    # k1 direction runs around the arc (orthogonal to the x axis), k2 along the axis.
    assert np.allclose(np.abs(s.principal_directions[:, 1, 0]), 1, atol=1e-9)
    assert np.allclose(s.principal_directions[:, 0, 0], 0, atol=1e-9)
    # Outward normal: (p - axis) / R.
    axis_pt = np.stack([s.vertices[:, 0], np.zeros(len(s.vertices)), -R * np.ones(len(
        s.vertices))], 1)
    assert np.allclose(s.normals, (s.vertices - axis_pt) / R, atol=1e-12)
    # Arc-length uv: the grid spacing in v is R dθ.
    assert s.uv[:, 1].max() == pytest.approx(R * 1.5)
    assert s.area == pytest.approx(0.5 * R * 1.5, rel=MESH_AREA_RTOL)


def test_cylinder_discrete_estimator_matches_closed_form() -> None:
    R = 1.0
    s = cylinder(R, 0.6, 1.0, resolution_m=0.02)
    d = discrete_curvature(s.vertices, s.faces)
    inner = ~d.boundary
    assert inner.sum() > 100
    assert np.allclose(d.gaussian[inner], 0, atol=1e-6)
    assert np.allclose(d.mean[inner], 1 / (2 * R), rtol=DISCRETE_CURVATURE_RTOL)
    assert np.allclose(d.principal[inner], [1 / R, 0], atol=DISCRETE_CURVATURE_RTOL / R)
    # Boundary values are filled from the interior and keep the same truth.
    assert np.allclose(d.mean, 1 / (2 * R), rtol=DISCRETE_CURVATURE_RTOL)
    # Principal direction k1 matches the analytic one up to sign.
    cos = np.abs((d.directions[inner, 0] * s.principal_directions[inner, 0]).sum(1))
    assert cos.min() > 0.99
    assert np.allclose(d.normals[inner], s.normals[inner], atol=1e-3)
    # Boundary normals are extrapolated from the interior (the one-sided face average is tilted
    # by about half a cell, h / (2R)).
    assert np.allclose(d.normals, s.normals, atol=0.1 * 0.02 / R)


def test_extruded_circle_matches_cylinder() -> None:
    """A circular profile extruded must reproduce the analytic cylinder's curvature."""
    R, arc = 0.5, 1.2
    th = np.linspace(-arc / 2, arc / 2, 400)
    prof = np.stack([R * np.sin(th), R * np.cos(th) - R], 1)
    s = extruded(prof, 0.4, resolution_m=0.01)
    nu, nv = s.grid_shape
    inner = s.principal_curvatures.reshape(nu, nv, 2)[:, 5:-5]  # natural-spline ends excluded
    assert np.allclose(inner[..., 0], 1 / R, rtol=1e-3)
    assert np.allclose(inner[..., 1], 0, atol=1e-9)
    assert np.allclose(s.gaussian_curvature, 0, atol=ANALYTIC_CURVATURE_ATOL)
    assert s.uv[:, 1].max() == pytest.approx(R * arc, rel=1e-6)
    assert s.normals[:, 2].min() > np.cos(arc / 2) - 1e-3
    # Reversed profile: same painted side (+z), same curvature.
    s2 = extruded(prof[::-1], 0.4, resolution_m=0.01)
    assert s2.normals[:, 2].min() > 0.8
    assert np.allclose(np.sort(s2.mean_curvature), np.sort(s.mean_curvature), atol=1e-6)


def _quadratic_bspline(a: float, b: float, c: float, size: float, n: int = 6) -> np.ndarray:
    """Control net of a cubic B-spline that equals z = a x² + b xy + c y² exactly.

    x, y at Greville abscissae reproduce the linear map; the heights are the least-squares
    coefficients of the quadratic, which lies in the spline space (residual at round-off)."""
    from scipy.interpolate import BSpline

    g = (greville_abscissae(n) - 0.5) * size
    t = np.concatenate([np.zeros(3), np.linspace(0, 1, n - 2), np.ones(3)])
    par = np.linspace(0, 1, 50)
    B = BSpline(t, np.eye(n), 3)(par)                         # (50, n)
    xs = (par - 0.5) * size
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    Z = a * X ** 2 + b * X * Y + c * Y ** 2
    Binv = np.linalg.pinv(B)
    ctrl_z = Binv @ Z @ Binv.T
    GX, GY = np.meshgrid(g, g, indexing="ij")
    return np.stack([GX, GY, ctrl_z], -1)


def test_bspline_curvature_matches_closed_form_height_field() -> None:
    a, b, c, size = -0.6, 0.3, -0.25, 1.0
    s = bspline_patch(_quadratic_bspline(a, b, c, size), degree=3, resolution_m=0.02)
    x, y = s.vertices[:, 0], s.vertices[:, 1]
    assert np.allclose(s.vertices[:, 2], a * x ** 2 + b * x * y + c * y ** 2, atol=1e-10)
    fx, fy, fxx, fxy, fyy = 2 * a * x + b * y, b * x + 2 * c * y, 2 * a, b, 2 * c
    w = 1 + fx ** 2 + fy ** 2
    K = (fxx * fyy - fxy ** 2) / w ** 2
    # Upward normal: a cap (f'' < 0) bends away from it, so H > 0 with the project's sign.
    H = -((1 + fy ** 2) * fxx - 2 * fx * fy * fxy + (1 + fx ** 2) * fyy) / (2 * w ** 1.5)
    n = np.stack([-fx, -fy, np.ones_like(fx)], 1) / np.sqrt(w)[:, None]
    assert np.allclose(s.gaussian_curvature, K, atol=1e-8)
    assert np.allclose(s.mean_curvature, H, atol=1e-8)
    assert np.allclose(s.normals, n, atol=1e-9)
    k1, k2 = s.principal_curvatures.T
    assert np.all(k1 >= k2) and np.allclose(k1 * k2, K, atol=1e-8)
    # dn = k d: check the shape operator along each principal direction by finite differences
    # of the closed-form normal field.
    h = 1e-6
    for col in (0, 1):
        d = s.principal_directions[:, col]
        xp, yp = x + h * d[:, 0], y + h * d[:, 1]
        fxp, fyp = 2 * a * xp + b * yp, b * xp + 2 * c * yp
        npl = np.stack([-fxp, -fyp, np.ones_like(fxp)], 1)
        npl /= np.linalg.norm(npl, axis=1, keepdims=True)
        dn_dr = (npl - n) / h
        # Step in the plane projects to the surface: dr = d_xy + dz; divide by the true |dr|.
        dr = np.stack([h * d[:, 0], h * d[:, 1], fx * h * d[:, 0] + fy * h * d[:, 1]], 1) / h
        k = (dn_dr * dr).sum(1) / (dr * dr).sum(1)
        assert np.allclose(k, s.principal_curvatures[:, col], atol=1e-4)
    assert np.all(np.abs((s.principal_directions[:, 0] * s.principal_directions[:, 1]).sum(1))
                  < 1e-9)


def test_bspline_arc_length_uv_and_flip() -> None:
    net = _quadratic_bspline(0.0, 0.0, 0.0, 0.5, n=5)
    s = bspline_patch(net, resolution_m=0.01)
    assert s.grid_shape == (51, 51)
    assert np.allclose(s.uv, s.vertices[:, :2] + 0.25, atol=1e-6)
    flipped = bspline_patch(net[::-1], resolution_m=0.01)   # reversed u: r_u x r_v points -z
    assert np.allclose(flipped.normals, [0, 0, 1])
    tri = flipped.vertices[flipped.faces]
    assert np.all(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2] > 0)


@pytest.mark.parametrize("bad", [
    lambda: plane(1.0, 1.0, resolution_m=0.0),
    lambda: plane(-1.0, 1.0),
    lambda: cylinder(1.0, 1.0, 7.0),
    lambda: extruded(np.zeros((3, 2)), 1.0),
    lambda: bspline_patch(np.zeros((3, 3, 3))),
    lambda: bspline_patch(np.zeros((5, 5, 3)), degree=3),     # collapsed net: singular
])
def test_constructors_refuse_bad_input(bad) -> None:
    with pytest.raises(SurfaceError):
        bad()


# --- discrete curvature on meshes --------------------------------------------------------------
def test_sphere_cap_discrete_gaussian_curvature() -> None:
    R = 1.0
    V, F = _sphere_cap_grid(R, 0.5, 61)
    s = Surface.from_mesh(trimesh.Trimesh(V, F, process=False))
    inner = ~boundary_vertex_mask(s.faces, len(s.vertices))
    assert np.allclose(s.gaussian_curvature[inner], 1 / R ** 2, rtol=DISCRETE_CURVATURE_RTOL)
    assert np.allclose(s.mean_curvature, 1 / R, rtol=DISCRETE_CURVATURE_RTOL)
    assert np.allclose(s.principal_curvatures, 1 / R, rtol=DISCRETE_CURVATURE_RTOL)
    # Outward (painted) normals of a sphere are p / R, on the boundary too (extrapolated there;
    # the one-sided face average is off by ~h / R = 0.017).
    assert np.allclose(s.normals, s.vertices / R, atol=1e-3)
    assert_unit(s.normals)


def test_boundary_normals_of_a_mesh_are_extrapolated_from_the_interior() -> None:
    # A cylinder exported as a bare mesh: the face-averaged normal of a boundary vertex is
    # one-sided, off by ~κh/2 across the arc; Surface.from_mesh extrapolates it from the interior.
    R = 1.0
    cyl = cylinder(R, 1.2, 1.2, resolution_m=0.05)       # the cylinder_section part, unplaced
    mesh = Surface.from_mesh(cyl.mesh)
    order = np.lexsort(np.round(mesh.vertices, 9).T)
    ref = np.lexsort(np.round(cyl.vertices, 9).T)
    exact = cyl.normals[ref]

    def err_deg(n: np.ndarray) -> np.ndarray:
        return np.degrees(np.arccos(np.clip(np.sum(n[order] * exact, axis=1), -1.0, 1.0)))

    boundary = boundary_vertex_mask(mesh.faces, len(mesh.vertices))
    face_average = vertex_normals(mesh.vertices, mesh.faces)
    before, after = err_deg(face_average), err_deg(mesh.normals)
    assert before.max() > 0.5                              # the one-sided bias, κh/2 ≈ 1.4°
    assert after.max() < 0.25 * before.max()
    np.testing.assert_array_equal(mesh.normals[~boundary], face_average[~boundary])
    assert_unit(mesh.normals)
    # principal directions stay an orthonormal tangent frame of the corrected normals
    d = mesh.principal_directions
    assert np.abs(np.einsum("nkj,nj->nk", d, mesh.normals)).max() < 1e-12
    assert np.abs(np.einsum("nj,nj->n", d[:, 0], d[:, 1])).max() < 1e-12
    assert np.abs(np.linalg.norm(d, axis=2) - 1).max() < 1e-12
    # analytic normals (a parametric part) are untouched, by the planner's geometry too
    axis_pt = np.stack([cyl.vertices[:, 0], np.zeros(len(cyl.vertices)),
                        np.full(len(cyl.vertices), -R)], 1)
    np.testing.assert_allclose(cyl.normals, (cyl.vertices - axis_pt) / R, atol=1e-12)
    np.testing.assert_array_equal(SurfaceGeometry.from_surface(cyl).normals, cyl.normals)


def test_icosphere_cap_curvature_and_areas() -> None:
    """Irregular (valence 5 and 6) triangulation; areas sum to the cap's closed form."""
    R, z0 = 2.0, 1.0
    ico = trimesh.creation.icosphere(subdivisions=4, radius=R)
    cap = ico.submesh([np.flatnonzero(ico.triangles_center[:, 2] > z0)], append=True)
    s = Surface.from_mesh(cap)
    inner = ~boundary_vertex_mask(s.faces, len(s.vertices))
    assert np.allclose(s.gaussian_curvature[inner], 1 / R ** 2, rtol=DISCRETE_CURVATURE_RTOL)
    assert np.allclose(s.mean_curvature[inner], 1 / R, rtol=DISCRETE_CURVATURE_RTOL)
    assert s.vertex_areas.sum() == pytest.approx(s.mesh.area, rel=1e-12)
    assert mixed_voronoi_areas(s.vertices, s.faces).sum() == pytest.approx(s.mesh.area,
                                                                          rel=1e-12)


def test_closed_sphere_areas_and_outward_normals() -> None:
    R = 0.7
    sph = trimesh.creation.uv_sphere(radius=R, count=[64, 64])
    sph.faces = sph.faces[:, ::-1]         # inward winding: from_mesh must turn it outward
    s = Surface.from_mesh(sph)
    assert s.area == pytest.approx(4 * np.pi * R ** 2, rel=5e-3)   # 64-gon chordal deficit
    assert np.all((s.normals * s.vertices).sum(1) > 0)
    assert np.median(np.abs(s.gaussian_curvature * R ** 2 - 1)) < DISCRETE_CURVATURE_RTOL


def test_from_mesh_open_mesh_keeps_majority_side_and_flip() -> None:
    V, F = _sphere_cap_grid(1.0, 0.3, 15)
    F = F.copy()
    F[::7] = F[::7, ::-1]                  # a minority of faces wound the wrong way
    s = Surface.from_mesh(trimesh.Trimesh(V, F, process=False))
    assert np.all(s.normals[:, 2] > 0.9)
    assert np.all(s.mean_curvature > 0)    # cap seen from outside bends away from n
    f = Surface.from_mesh(trimesh.Trimesh(V, F, process=False), flip=True)
    assert np.all(f.normals[:, 2] < -0.9)
    assert np.allclose(f.mean_curvature, -s.mean_curvature, atol=1e-9)


def test_from_mesh_file_round_trip(tmp_path) -> None:
    s = cylinder(1.0, 0.4, 0.8, 0.02)
    for ext in ("stl", "obj", "ply"):
        path = tmp_path / f"part.{ext}"
        s.mesh.export(path)
        m = Surface.from_mesh(path)
        assert m.name == "part" and len(m.vertices) == len(s.vertices)
        assert m.area == pytest.approx(s.area, rel=1e-6)   # STL stores float32
        assert np.allclose(np.sort(m.mean_curvature), np.sort(s.mean_curvature), atol=1e-4)


def test_from_mesh_repairs_duplicates_and_collapsed_faces() -> None:
    V, F = _sphere_cap_grid(1.0, 0.3, 11)
    # Unshared vertices (STL style), one duplicated face, one collapsed face.
    soup_v = V[F].reshape(-1, 3)
    soup_f = np.arange(len(soup_v)).reshape(-1, 3)
    soup_f = np.concatenate([soup_f, soup_f[:1], [[0, 0, 1]]])
    s = Surface.from_mesh(trimesh.Trimesh(soup_v, soup_f, process=False))
    assert len(s.vertices) == len(V) and len(s.faces) == len(F)


def _expect_error(mesh_or_path, match: str, **kw) -> str:
    with pytest.raises(SurfaceError, match=match) as info:
        Surface.from_mesh(mesh_or_path, **kw)
    msg = str(info.value)
    assert "\n" not in msg and ";" in msg          # one line: the problem; the fix
    return msg


def test_from_mesh_refusals(tmp_path) -> None:
    V, F = _sphere_cap_grid(1.0, 0.3, 6)
    _expect_error(trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int)), "empty")
    Vn = V.copy()
    Vn[3] = np.nan
    _expect_error(trimesh.Trimesh(Vn, F, process=False), "NaN")
    # A sliver: three distinct collinear vertices.
    Vs = np.concatenate([V, [[2.0, 0, 0], [2.1, 0, 0], [2.2, 0, 0]]])
    Fs = np.concatenate([F, [[len(V), len(V) + 1, len(V) + 2]]])
    _expect_error(trimesh.Trimesh(Vs, Fs, process=False), "zero-area")
    # Non-manifold: a fin sharing an existing edge with two faces.
    a, b = F[0, 0], F[0, 2]                    # the cell diagonal: already used by two faces
    Vf = np.concatenate([V, [[0.0, 0.0, 2.0]]])
    Ff = np.concatenate([F, [[a, b, len(V)]]])
    _expect_error(trimesh.Trimesh(Vf, Ff, process=False), "non-manifold")
    _expect_error(tmp_path / "missing.stl", "does not exist")
    garbage = tmp_path / "junk.stl"
    garbage.write_text("not a mesh at all")
    msg = _expect_error(garbage, "could not read .*junk.stl as a triangle mesh")
    assert "STL, OBJ or PLY" in msg and "empty" not in msg


def test_from_mesh_components() -> None:
    V1, F1 = _sphere_cap_grid(1.0, 0.3, 8)    # 98 faces
    V2, F2 = _sphere_cap_grid(1.0, 0.1, 4)    # 18 faces
    V2 = V2 + [1.0, 0, 0]
    mesh = trimesh.Trimesh(np.concatenate([V1, V2]), np.concatenate([F1, F2 + len(V1)]),
                           process=False)
    msg = _expect_error(mesh, "2 connected components")
    assert "98, 18" in msg
    big = Surface.from_mesh(mesh, component=0)
    small = Surface.from_mesh(mesh, component=1)
    assert len(big.faces) == 98 and len(small.faces) == 18
    assert np.allclose(small.vertices.mean(0)[0], 1.0, atol=1e-9)
    _expect_error(mesh, "out of range", component=2)


# --- transforms ---------------------------------------------------------------------------------
def _random_rigid(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = q, rng.normal(size=3)
    return T


def test_transformed_round_trip_and_invariants() -> None:
    s = bspline_patch(_quadratic_bspline(-0.5, 0.2, -0.3, 0.6), resolution_m=0.03)
    T = _random_rigid(0)
    t = s.transformed(T)
    assert t is not s and np.allclose(t.vertices, s.vertices @ T[:3, :3].T + T[:3, 3])
    back = t.transformed(np.linalg.inv(T))
    assert np.allclose(back.vertices, s.vertices, atol=ROUND_TRIP_ATOL_M)
    assert np.allclose(back.normals, s.normals, atol=1e-12)
    assert np.allclose(back.principal_directions, s.principal_directions, atol=1e-12)
    assert np.array_equal(t.gaussian_curvature, s.gaussian_curvature)
    assert t.area == pytest.approx(s.area, rel=1e-12)
    # The moved normals are still the discrete normals of the moved mesh.
    d = discrete_curvature(t.vertices, t.faces)
    assert np.allclose(d.normals, t.normals, atol=2e-2)
    assert np.allclose(d.mean[~d.boundary], t.mean_curvature[~d.boundary], atol=2e-2)
    with pytest.raises(SurfaceError, match="rigid"):
        s.transformed(np.diag([2.0, 1, 1, 1]))


def test_mesh_property_is_cached_and_consistent() -> None:
    s = plane(0.2, 0.1, 0.05)
    assert s.mesh is s.mesh
    assert np.array_equal(s.mesh.faces, s.faces)
    assert s.mesh.area == pytest.approx(s.area, rel=1e-12)


def test_save_load_round_trip(tmp_path) -> None:
    for s in (plane(0.2, 0.1, 0.05), Surface.from_mesh(trimesh.creation.icosphere(2))):
        s.save(tmp_path / "s.npz")
        t = Surface.load(tmp_path / "s.npz")
        assert t.name == s.name and t.grid_shape == s.grid_shape
        for key in ("vertices", "faces", "normals", "principal_directions", "mean_curvature"):
            assert np.array_equal(getattr(t, key), getattr(s, key))
        assert (t.uv is None) == (s.uv is None)
    with pytest.raises(SurfaceError, match="not a paintcell surface"):
        np.savez(tmp_path / "x.npz", a=np.zeros(3))
        Surface.load(tmp_path / "x.npz")
