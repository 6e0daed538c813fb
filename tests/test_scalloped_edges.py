"""Real-part coverage: a pass ending in a notch of a scalloped edge, and a smooth arch
cut by the patch segmentation.

Independent truth: the plate's geometry (where its tongues end), the film of the produced passes
re-measured on the mesh with the deposition model, and the closed form of a cylinder (every normal
perpendicular to its axis: extrusion residual 0).
"""

from __future__ import annotations

import numpy as np

from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.coverage.patches import extrusion_residual, face_normals_areas, segment
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import thickness
from paintcell.surface.analytic import grid_faces
from paintcell.surface.surface_data import Surface, surface_from_triangles

#: the plate's tongues: one every PERIOD_M along x, tips at TIP_M, notches down to NOTCH_M [m]
PERIOD_M, TIP_M, NOTCH_M = 0.25, 0.9, 0.6


def _facing_up(name: str, v: np.ndarray, f: np.ndarray) -> Surface:
    s = surface_from_triangles(name, v, f)
    return s if s.normals[:, 2].mean() > 0 else surface_from_triangles(name, v, f[:, ::-1])


def tongue_plate(res_m: float = 0.02) -> Surface:
    """A 1.0 m wide flat plate whose top edge is scalloped into tongues (tips at x = 0, 0.25, …,
    1.0 m reaching y = 0.9 m, notches between them down to y = 0.6 m)."""
    x = np.linspace(0.0, 1.0, int(round(1.0 / res_m)) + 1)
    y = np.linspace(0.0, TIP_M, int(round(TIP_M / res_m)) + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    v = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    f = grid_faces(len(x), len(y))
    c = v[f].mean(axis=1)
    top = NOTCH_M + (TIP_M - NOTCH_M) * np.cos(np.pi * c[:, 0] / PERIOD_M) ** 2
    f = f[c[:, 1] < top]
    used, inv = np.unique(f, return_inverse=True)
    return _facing_up("tongues", v[used], inv.reshape(-1, 3))


def test_a_pass_ending_in_a_notch_paints_past_the_tongues_beside_it() -> None:
    s = tongue_plate()
    app = Applicator.default()
    st = PlannerSettings(orientation=np.pi / 2)            # passes along y, into the tongues
    plan = plan_coverage(s, app, st)
    # every pass over the plate (not the sideways edge passes beyond x = 0 and 1) paints on
    # past the tongue tips by the overspray: the ones between two tongues stopped short
    inner = 0
    for p in plan.passes:
        foot = p.positions + app.standoff_m * p.spray_axes
        if not 0.0 < foot[:, 0].mean() < 1.0:
            continue
        inner += 1
        assert foot[p.paint_on, 1].max() >= TIP_M + st.overspray_m - 0.03, foot[:, 1].max()
    assert inner >= 3
    film = thickness(app, plan.gun_samples(), s.vertices, s.normals)
    a, v = s.vertex_areas, s.vertices
    mean = np.average(film, weights=a)
    for x_tip in (0.25, 0.5, 0.75):                         # the inner tongues' tips
        tip = (np.abs(v[:, 0] - x_tip) < 0.03) & (v[:, 1] > TIP_M - 0.1)
        assert film[tip].min() > 0.85 * mean, (x_tip, film[tip].min() / mean)
    nsd = 100 * np.sqrt(np.average((film - mean) ** 2, weights=a)) / mean
    assert nsd < 4.0, nsd                                  # 8.9 % with the passes stopping short


def arch(res_m: float = 0.03, radius_m: float = 1.0, span_rad: float = np.radians(140.0),
         length_m: float = 1.0) -> Surface:
    """A cylinder's arch (axis x), its normals turning ±span/2 about the axis."""
    th = np.linspace(-span_rad / 2, span_rad / 2, int(round(span_rad * radius_m / res_m)) + 1)
    x = np.linspace(0.0, length_m, int(round(length_m / res_m)) + 1)
    X, T = np.meshgrid(x, th, indexing="ij")
    v = np.column_stack([X.ravel(), radius_m * np.sin(T).ravel(), radius_m * np.cos(T).ravel()])
    return _facing_up("arch", v, grid_faces(len(x), len(th)))


def test_a_smooth_arch_is_one_patch_a_fold_stays_a_seam() -> None:
    s = arch()
    nf, af = face_normals_areas(s)
    assert extrusion_residual(nf, af) < 1e-3               # a cylinder: extruded
    # the normal cone (30°) alone cuts its 140° into strips along the axis; merged, one patch
    assert len(np.unique(segment(s, max_residual=-1.0))) >= 3
    assert len(np.unique(segment(s))) == 1
    # the same arch folded: two halves meeting at a 60° crease stay two patches
    v = s.vertices.copy()
    left = v[:, 1] < 0
    c, sn = np.cos(np.radians(60.0)), np.sin(np.radians(60.0))
    y, z = v[left, 1], v[left, 2] - 1.0
    v[left, 1], v[left, 2] = c * y - sn * z, sn * y + c * z + 1.0
    folded = _facing_up("folded", v, s.faces)
    lab = segment(folded)
    side = left[s.faces].all(axis=1)                       # faces of the folded half
    across = left[s.faces].any(axis=1) & ~side             # the faces touching the crease
    assert not set(np.unique(lab[side])) & set(np.unique(lab[~side & ~across]))
