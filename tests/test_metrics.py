"""Uniformity metrics against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from paintcell.paint.metrics import (
    MetricsError,
    boundary_band_mask,
    boundary_vertices,
    transfer_efficiency,
    uniformity,
)


def test_equal_areas_by_hand() -> None:
    m = uniformity([1.0, 2.0, 3.0, 4.0], [1.0, 1.0, 1.0, 1.0])
    assert m.mean_m == pytest.approx(2.5)
    assert m.nsd_pct == pytest.approx(100 * math.sqrt(1.25) / 2.5)   # population σ
    assert (m.min_m, m.max_m, m.area_m2) == (1.0, 4.0, 4.0)
    assert m.within_tolerance_fraction == 0.0                         # none within ±0.25
    assert m.target_m == 2.5


def test_area_weights_mask_and_target() -> None:
    t = np.array([10.0, 20.0, 30.0, 1000.0])
    a = np.array([3.0, 1.0, 0.0, 2.0])
    m = uniformity(t, a, mask=np.array([True, True, True, False]), target_m=12.0, tolerance=0.2)
    # weighted over the first three: mean = (30 + 20 + 0) / 4 = 12.5
    assert m.mean_m == pytest.approx(12.5)
    var = (3 * 2.5**2 + 1 * 7.5**2 + 0) / 4
    assert m.nsd_pct == pytest.approx(100 * math.sqrt(var) / 12.5)
    assert (m.min_m, m.max_m) == (10.0, 30.0)   # min/max over the region's vertices
    # inside 12 ± 2.4: t = 10 (area 3) yes, 20 no, 30 (area 0) no → 3/4 of the area
    assert m.within_tolerance_fraction == pytest.approx(0.75)
    assert m.area_m2 == 4.0
    assert set(m.to_dict()) >= {"mean_m", "nsd_pct", "within_tolerance_fraction"}


def test_uniform_film_is_perfect() -> None:
    m = uniformity(np.full(10, 2e-5), np.linspace(1, 2, 10))
    assert m.nsd_pct == pytest.approx(0.0, abs=1e-12)
    assert m.within_tolerance_fraction == 1.0


def test_transfer_efficiency_by_hand() -> None:
    assert transfer_efficiency([2e-5, 4e-5], [0.5, 0.25], 4e-5) == pytest.approx(0.5)


def test_boundary_helpers_on_a_grid() -> None:
    n = 5                                            # 5 × 5 vertices, 1 m spacing
    ij = np.array([(i, j) for i in range(n) for j in range(n)], float)
    pts = np.c_[ij, np.zeros(len(ij))]
    faces = []
    for i in range(n - 1):
        for j in range(n - 1):
            v = i * n + j
            faces += [[v, v + n, v + 1], [v + 1, v + n, v + n + 1]]
    b = boundary_vertices(np.array(faces))
    assert len(b) == 16                             # 4·5 − 4 ring vertices
    inner = boundary_band_mask(pts, pts[b], band_m=1.5)
    # interior points ≥ 2 m from every edge vertex: only the centre (2, 2)
    assert np.flatnonzero(inner).tolist() == [12]
    assert boundary_band_mask(pts, pts[b], band_m=0.5).sum() == 9


@pytest.mark.parametrize("call", [
    lambda: uniformity([1.0, 2.0], [1.0]),
    lambda: uniformity([1.0, np.nan], [1.0, 1.0]),
    lambda: uniformity([1.0, 2.0], [1.0, -1.0]),
    lambda: uniformity([1.0, 2.0], [1.0, 1.0], mask=np.array([False, False])),
    lambda: uniformity([1.0, 2.0], [1.0, 1.0], mask=np.array([1, 0])),
    lambda: uniformity([1.0, 2.0], [1.0, 1.0], tolerance=-0.1),
    lambda: transfer_efficiency([1.0], [1.0], 0.0),
    lambda: boundary_band_mask(np.zeros((2, 3)), np.zeros((1, 3)), -1.0),
])
def test_bad_input_raises(call) -> None:
    with pytest.raises(MetricsError):
        call()


def test_unpainted_region_raises() -> None:
    # a zero film has no σ/μ and must not count as 100 % within tolerance
    with pytest.raises(MetricsError, match="mean film thickness is zero.*;"):
        uniformity(np.zeros(4), np.ones(4))
    with pytest.raises(MetricsError, match="nothing was painted"):
        uniformity([0.0, 1.0], [1.0, 1.0], mask=np.array([True, False]))
