"""Deposition kernel against independent truth: flat-plane reduction, inverse-square and cosine
laws, paint conservation, the closed-form line integral of a straight pass, back-facing and
behind-the-gun points, dense vs fast kernel, thread determinism, occlusion and memory."""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest
import trimesh
from scipy import integrate

from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate, deposition_rate_reference, thickness
from paintcell.paint.deposition_samples import DepositionError, GunSamples

from .helpers import DEPOSITION_EXACT_RTOL, DEPOSITION_INTEGRAL_RTOL, KERNEL_CULL_RTOL


def _rot(axis: np.ndarray, ang: float) -> np.ndarray:
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(ang) * k + (1 - math.cos(ang)) * k @ k


def _grid(half_m: float, step_m: float) -> tuple[np.ndarray, float]:
    g = np.arange(-half_m, half_m + step_m / 2, step_m)
    x, y = np.meshgrid(g, g, indexing="ij")
    return np.c_[x.ravel(), y.ravel(), np.zeros(x.size)], step_m * step_m


@pytest.fixture(scope="module")
def app() -> Applicator:
    return Applicator.default()


def test_flat_plane_reduces_to_flux(app: Applicator) -> None:
    # gun h above an arbitrarily oriented plane facing it; the rate is f at the tool-frame coords
    rng = np.random.default_rng(1)
    rot = _rot(rng.normal(size=3), 0.7)
    g = np.array([0.3, -0.2, 1.0])
    a, x_hat = rot[:, 2], rot[:, 0]
    y_hat = np.cross(a, x_hat)
    uv = rng.uniform(-0.4, 0.4, size=(500, 2))
    pts = g + app.standoff_m * a + uv[:, :1] * x_hat + uv[:, 1:] * y_hat
    for fn in (deposition_rate, deposition_rate_reference):
        rate = fn(app, g[None], a[None], x_hat[None], pts, np.tile(-a, (500, 1)))[0]
        np.testing.assert_allclose(rate, app.flux(uv[:, 0], uv[:, 1]),
                                   rtol=DEPOSITION_EXACT_RTOL)
    gun = GunSamples(g[None], a[None], x_hat[None], np.array([1.0]))
    t = thickness(app, gun, pts, np.tile(-a, (500, 1)))
    np.testing.assert_allclose(t, app.flux(uv[:, 0], uv[:, 1]), rtol=DEPOSITION_EXACT_RTOL)


def test_inverse_square_and_cosine_laws(app: Applicator) -> None:
    # on the axis: a plane at 2h gets f(0)/4; a plane tilted by β at h gets f(0)·cos β
    f0 = float(app.flux(0.0, 0.0))
    g, a, x = np.zeros((1, 3)), np.array([[0.0, 0, 1]]), np.array([[1.0, 0, 0]])
    far = deposition_rate(app, g, a, x, [[0, 0, 2 * app.standoff_m]], [[0, 0, -1.0]])
    assert far[0, 0] == pytest.approx(f0 / 4, rel=DEPOSITION_EXACT_RTOL)
    for beta in (0.2, 0.6, 1.2):
        n = -_rot(np.array([0.3, 1.0, 0]), beta)[:, 2]
        tilt = deposition_rate(app, g, a, x, [[0, 0, app.standoff_m]], [n])
        assert tilt[0, 0] == pytest.approx(f0 * math.cos(beta), rel=DEPOSITION_EXACT_RTOL)


def test_back_facing_and_behind_gun_get_nothing(app: Applicator) -> None:
    g = np.array([[0.0, 0, 0.25]])
    a, x = np.array([[0.0, 0, -1]]), np.array([[1.0, 0, 0]])
    pts = np.array([[0.0, 0, 0], [0.05, 0.02, 0], [0, 0, 0.5], [0.01, 0, 0.3]])
    nrm = np.array([[0.0, 0, -1], [0.3, 0, -1], [0, 0, -1], [0, 0, 1.0]])  # away / behind
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    assert np.all(deposition_rate(app, g, a, x, pts, nrm) == 0)
    assert np.all(deposition_rate_reference(app, g, a, x, pts, nrm) == 0)
    gun = GunSamples(g, a, x, np.array([1.0]))
    assert np.all(thickness(app, gun, pts, nrm) == 0)
    assert thickness(app, gun, pts[:2], -nrm[:2]).min() > 0


def test_tilted_plane_conserves_paint(app: Applicator) -> None:
    # all paint through the cone lands on a large plane, whatever its tilt (solid-angle argument)
    pts0, cell = _grid(1.6, 0.006)
    for beta in (0.0, 0.35):
        rot = _rot(np.array([1.0, 0.4, 0]), beta)
        pts = pts0 @ rot.T
        nrm = np.tile(rot[:, 2], (len(pts), 1))
        gun = GunSamples(np.array([[0.0, 0, app.standoff_m]]), np.array([[0.0, 0, -1]]),
                         np.array([[1.0, 0, 0]]), np.array([2.0]))
        t = thickness(app, gun, pts, nrm)
        on_part = float(t.sum() * cell)
        assert on_part == pytest.approx(app.emitted_flow_m3_s * 2.0, rel=DEPOSITION_INTEGRAL_RTOL)


def test_raster_conserves_paint(app: Applicator) -> None:
    pts, cell = _grid(1.3, 0.005)
    nrm = np.tile([0.0, 0, 1], (len(pts), 1))
    parts = [GunSamples.straight_pass([-0.5, y, 0.25], [0.5, y, 0.25], [0, 0, -1], 0.6, 0.004)
             for y in (-0.3, 0.05, 0.4)]
    gun = GunSamples(*(np.concatenate([getattr(p, f) for p in parts])
                       for f in ("positions", "spray_axes", "travel_dirs", "dwell_s")))
    assert gun.total_time_s == pytest.approx(3 * 1.0 / 0.6, rel=1e-12)
    t = thickness(app, gun, pts, nrm)
    assert float(t.sum() * cell) == pytest.approx(app.emitted_flow_m3_s * gun.total_time_s,
                                                  rel=DEPOSITION_INTEGRAL_RTOL)


def _line_integral(app: Applicator, y: float) -> float:
    """∫ f(x, y) dx by adaptive quadrature (independent of paintcell.paint.calibration)."""
    gauss = app.a0_m_s * app.sigma_x_m * math.sqrt(2 * math.pi) * math.exp(
        -y * y / (2 * app.sigma_y_m**2))
    rings = sum(integrate.quad(lambda x, a=a, m=m, s=s: a * math.exp(
        -(math.hypot(x, y) - m) ** 2 / (2 * s * s)), -1.5, 1.5, epsabs=0, epsrel=1e-10,
        limit=200)[0]
        for a, m, s in zip(app.ring_amplitudes_m_s, app.ring_radii_m, app.ring_sigmas_m,
                           strict=True))
    return gauss + rings


def test_straight_pass_matches_line_integral(app: Applicator) -> None:
    speed = 0.5
    gun = GunSamples.straight_pass([-0.9, 0, 0.25], [0.9, 0, 0.25], [0, 0, -1], speed, 0.002)
    ys = np.linspace(-0.3, 0.3, 61)
    pts = np.c_[np.zeros_like(ys), ys, np.zeros_like(ys)]
    t = thickness(app, gun, pts, np.tile([0.0, 0, 1], (len(ys), 1)))
    ref = np.array([_line_integral(app, y) for y in ys]) / speed
    np.testing.assert_allclose(t, ref, rtol=DEPOSITION_INTEGRAL_RTOL,
                               atol=1e-3 * DEPOSITION_INTEGRAL_RTOL * ref.max())


def _curved_problem(seed: int) -> tuple[GunSamples, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    g = np.linspace(-0.6, 0.6, 61)
    x, y = np.meshgrid(g, g, indexing="ij")
    z = 0.3 * x**2 - 0.2 * y**2 + 0.05 * np.sin(5 * x)
    pts = np.c_[x.ravel(), y.ravel(), z.ravel()]
    dzdx = 0.6 * x + 0.25 * np.cos(5 * x)
    nrm = np.c_[-dzdx.ravel(), 0.4 * y.ravel(), np.ones(x.size)]
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm[rng.random(len(nrm)) < 0.1] *= -1                       # some back-facing points
    s = 37
    pos = np.c_[rng.uniform(-0.5, 0.5, s), rng.uniform(-0.5, 0.5, s), rng.uniform(0.15, 0.4, s)]
    pos[:3, 2] = -0.3                                           # a few guns under the surface
    axes = np.c_[rng.normal(0, 0.3, s), rng.normal(0, 0.3, s), -np.ones(s)]
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    trav = np.cross(axes, rng.normal(size=(s, 3)))
    trav /= np.linalg.norm(trav, axis=1, keepdims=True)
    return GunSamples(pos, axes, trav, rng.uniform(0.001, 0.01, s)), pts, nrm


def test_dense_rate_equals_literal_formula(app: Applicator) -> None:
    gun, pts, nrm = _curved_problem(2)
    args = (app, gun.positions, gun.spray_axes, gun.travel_dirs, pts, nrm)
    fast, ref = deposition_rate(*args), deposition_rate_reference(*args)
    assert fast.shape == (len(gun), len(pts)) and ref.max() > 0
    # same values up to round-off (both clamp exponents at -700: tails below 1e-290 differ)
    np.testing.assert_allclose(fast, ref, rtol=1e-9, atol=1e-12 * ref.max())


def test_fast_kernel_equals_dense(app: Applicator) -> None:
    gun, pts, nrm = _curved_problem(3)
    dense = gun.dwell_s @ deposition_rate_reference(app, gun.positions, gun.spray_axes,
                                                    gun.travel_dirs, pts, nrm)
    fast = thickness(app, gun, pts, nrm)
    assert fast.dtype == np.float64 and fast.shape == (len(pts),)
    assert dense.max() > 0 and np.all(fast >= 0)
    np.testing.assert_allclose(fast, dense, rtol=0, atol=KERNEL_CULL_RTOL * dense.max())
    # where the fast kernel evaluates a point at all, it is the same arithmetic up to round-off
    both = (fast > 0) & (dense > 1e-3 * dense.max())
    np.testing.assert_allclose(fast[both], dense[both], rtol=1e-6)


def test_threads_do_not_change_the_result(app: Applicator) -> None:
    gun, pts, nrm = _curved_problem(4)
    one = thickness(app, gun, pts, nrm, threads=1)
    two = thickness(app, gun, pts, nrm, threads=2)
    assert np.array_equal(one, two)
    assert np.array_equal(one, thickness(app, gun, pts, nrm, threads=1))


def test_point_order_does_not_matter(app: Applicator) -> None:
    gun, pts, nrm = _curved_problem(5)
    perm = np.random.default_rng(0).permutation(len(pts))
    t = thickness(app, gun, pts, nrm)
    tp = thickness(app, gun, pts[perm], nrm[perm])
    np.testing.assert_allclose(tp, t[perm], rtol=1e-12, atol=1e-12 * t.max())


def test_occlusion_blocks_points_behind_a_sheet(app: Applicator) -> None:
    # a lower sheet at z = 0; an upper sheet at z = 0.1 covers x < 0; gun passes at z = 0.35
    lower, _ = _grid(0.3, 0.02)
    nrm = np.tile([0.0, 0, 1], (len(lower), 1))
    upper = trimesh.creation.box(extents=[0.8, 1.0, 0.002])
    upper.apply_translation([-0.4, 0.0, 0.1])
    gun = GunSamples.straight_pass([-0.3, 0, 0.35], [0.3, 0, 0.35], [0, 0, -1], 0.5, 0.01)
    # the occlusion path is the numpy kernel: compare it with the same kernel unoccluded (the
    # compiled one agrees only to round-off, which `hidden <= free` would trip on)
    free = thickness(app, gun, lower, nrm, backend="numpy")
    hidden = thickness(app, gun, lower, nrm, occluder=upper)
    # a ray from (px, ·, 0) to a gun at (gx, ·, 0.35), |gx| ≤ 0.3, crosses z = 0.1 at
    # px + (gx − px)·0.1/0.35: every ray is blocked for px < −0.12 and none for px > 0.12,
    # whichever sample of a chunk the kernel tests visibility from
    under = lower[:, 0] < -0.15
    clear = lower[:, 0] > 0.15
    assert np.all(free > 0)
    assert np.all(hidden[under] == 0)
    assert np.all(hidden[~under & ~clear] <= free[~under & ~clear])
    assert np.any(clear)
    np.testing.assert_allclose(hidden[clear], free[clear], rtol=0,
                               atol=KERNEL_CULL_RTOL * free.max())


def test_memory_is_bounded(app: Applicator) -> None:
    pts, _ = _grid(1.0, 0.004)                                  # ~250k points
    nrm = np.tile([0.0, 0, 1], (len(pts), 1))
    gun = GunSamples.straight_pass([-0.1, 0, 0.25], [0.1, 0, 0.25], [0, 0, -1], 0.5, 0.02)
    tracemalloc.start()
    thickness(app, gun, pts, nrm, threads=1)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    # O(N) bookkeeping (~25 floats a point) plus O(MAX_PAIRS_PER_CALL) temporaries
    assert peak < 8 * 25 * len(pts) + 64e6, f"peak {peak / 1e6:.0f} MB"


def test_bad_gun_samples_raise() -> None:
    z, x = np.array([[0.0, 0, -1]]), np.array([[1.0, 0, 0]])
    with pytest.raises(DepositionError, match="shape"):
        GunSamples(np.zeros((1, 2)), z, x, np.ones(1))
    with pytest.raises(DepositionError, match="unit"):
        GunSamples(np.zeros((1, 3)), 2 * z, x, np.ones(1))
    with pytest.raises(DepositionError, match="orthogonal"):
        GunSamples(np.zeros((1, 3)), z, np.array([[0.0, 0.6, -0.8]]), np.ones(1))
    with pytest.raises(DepositionError, match="dwell"):
        GunSamples(np.zeros((1, 3)), z, x, -np.ones(1))
    with pytest.raises(DepositionError, match="NaN"):
        GunSamples(np.full((1, 3), np.nan), z, x, np.ones(1))
    gun = GunSamples(np.zeros((1, 3)), z, x, np.ones(1))
    with pytest.raises(DepositionError, match="rows"):
        thickness(Applicator.default(), gun, np.zeros((3, 3)), np.zeros((2, 3)))


def test_self_occlusion_of_a_convex_side_is_none(app: Applicator) -> None:
    # a Surface as its own occluder: points on its painted side are never hidden by themselves
    from paintcell.surface.analytic import plane
    surf = plane(0.6, 0.6, resolution_m=0.03)
    gun = GunSamples.straight_pass([-0.2, 0, 0.25], [0.2, 0, 0.25], [0, 0, -1], 0.5, 0.02)
    free = thickness(app, gun, surf.vertices, surf.normals)
    hidden = thickness(app, gun, surf.vertices, surf.normals, occluder=surf)
    np.testing.assert_allclose(hidden, free, rtol=0, atol=KERNEL_CULL_RTOL * free.max())


@pytest.mark.parametrize("scale", [3.0, 0.0, 1.0 + 1e-4])
def test_non_unit_normals_raise(app: Applicator, scale: float) -> None:
    # the rate scales with |n·ω|: ×3 normals would triple the film, zero normals paint nothing
    gun, pts, nrm = _curved_problem(5)
    bad = nrm.copy()
    bad[3] *= scale
    args = (app, gun.positions, gun.spray_axes, gun.travel_dirs, pts, bad)
    for call in (lambda: thickness(app, gun, pts, bad), lambda: deposition_rate(*args),
                 lambda: deposition_rate_reference(*args)):
        with pytest.raises(DepositionError, match="normals must be unit vectors.*normalize them"):
            call()


def test_straight_pass_bad_input_messages() -> None:
    z = [0.0, 0.0, -1.0]
    with pytest.raises(DepositionError, match="end_m .* must be a finite 3-vector"):
        GunSamples.straight_pass([0.0, 0, 0.25], [np.nan, 0, 0.25], z, 0.5)
    with pytest.raises(DepositionError, match="speed_m_s .* finite number > 0"):
        GunSamples.straight_pass([0.0, 0, 0.25], [0.1, 0, 0.25], z, math.inf)
    with pytest.raises(DepositionError, match="spray axis is parallel to the travel direction"):
        GunSamples.straight_pass([0.0, 0, 0.25], [0.0, 0, 0.0], z, 0.5)
