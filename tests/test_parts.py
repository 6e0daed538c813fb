"""Car-part library: every part builds at planning resolution with its documented size, in its
part frame, with consistent normals and curvature re-measured on the mesh."""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.core.errors import SurfaceError
from paintcell.surface.curvature import discrete_curvature
from paintcell.surface.parts import PART_NAMES, door_profile, get_part
from tests.helpers import assert_unit

# name: (extent along x [m], extent along y [m] (planform or profile chord), area [m²]) as the
# docstrings give them; areas are closed forms for panel/cylinder/door, others are bounded below.
DOCUMENTED = {
    "panel": (1.0, 0.8, 0.8),
    "cylinder_section": (1.2, 2 * np.sin(0.6), 1.2 * 1.2),
    "door": (1.1, None, 1.1 * 0.8),
    "fender": (1.0, 0.7, None),
    "hood": (1.5, 1.2, None),
    "roof": (1.6, 1.3, None),
}


@pytest.fixture(scope="module", params=PART_NAMES)
def part(request):
    return get_part(request.param, resolution_m=0.01)


def test_part_frame_size_and_normals(part) -> None:
    ext_x, ext_y, area = DOCUMENTED[part.name]
    ext = part.vertices.max(0) - part.vertices.min(0)
    assert ext[0] == pytest.approx(ext_x, rel=0.02)
    if ext_y is not None:   # curved parts are levelled (mean normal to +z): a few % wider
        assert ext[1] == pytest.approx(ext_y, rel=0.04)
    if area is not None:
        assert part.area == pytest.approx(area, rel=1e-3)
    else:
        assert part.area >= ext_x * ext_y
    w = part.vertex_areas / part.area
    assert np.allclose(w @ part.vertices, 0, atol=1e-9)          # centred
    mean_n = w @ part.normals
    assert np.allclose(mean_n / np.linalg.norm(mean_n), [0, 0, 1], atol=1e-9)
    assert_unit(part.normals)
    assert part.normals[:, 2].min() > 0.5                         # painted side is +z
    assert part.grid_shape is not None and part.uv is not None
    assert part.mesh.is_winding_consistent and len(part.mesh.split(only_watertight=False)) == 1


def test_part_curvature_matches_discrete_estimate(part) -> None:
    d = discrete_curvature(part.vertices, part.faces)
    inner = ~d.boundary
    # 1 cm grid on radii >= 0.3 m: the O(h²) discrete error is far below 0.05 1/m.
    assert np.allclose(d.mean[inner], part.mean_curvature[inner], atol=0.05)
    assert np.allclose(d.gaussian[inner], part.gaussian_curvature[inner], atol=0.05)
    assert np.allclose(d.normals, part.normals, atol=0.02)
    k1, k2 = part.principal_curvatures.T
    assert np.all(k1 >= k2)


def test_part_curvature_character() -> None:
    assert np.allclose(get_part("panel", 0.02).gaussian_curvature, 0)
    cyl = get_part("cylinder_section", 0.02)
    assert np.allclose(cyl.mean_curvature, 0.5) and np.allclose(cyl.gaussian_curvature, 0)
    d = get_part("door", 0.01)
    k1 = d.principal_curvatures[:, 0]
    assert np.allclose(d.gaussian_curvature, 0, atol=1e-9)
    assert 1 / k1.max() == pytest.approx(0.38, abs=0.04)           # shoulder crease radius
    assert np.percentile(k1, 25) < 0.3                              # flat-ish lower panel
    f = get_part("fender", 0.01)
    assert 1.0 <= f.gaussian_curvature.max() <= 4.0
    for name in ("hood", "roof"):
        p = get_part(name, 0.02)
        assert np.all(p.principal_curvatures[:, 0] < 1.2)           # radii >= ~0.8 m
        assert np.all(p.mean_curvature > 0)                         # convex crown


def test_door_profile_is_unit_speed_with_documented_arc() -> None:
    p = door_profile()
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert seg.sum() == pytest.approx(0.8, rel=1e-4)


def test_coarse_resolutions_and_unknown_name() -> None:
    for name in PART_NAMES:
        s = get_part(name, resolution_m=0.025)
        assert len(s.vertices) < 6000
        fine = get_part(name, resolution_m=0.0125)
        assert fine.area == pytest.approx(s.area, rel=2e-3)
    with pytest.raises(SurfaceError, match="choose one of"):
        get_part("bumper")


def test_door_default_resolution_size() -> None:
    d = get_part("door")
    assert 30000 < len(d.vertices) < 40000
