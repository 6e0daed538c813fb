"""`film.glb` (paintcell.output.gltf_film), written with pygltflib, read back by trimesh's glTF
loader: the part's vertices, bounds and colours, the film attribute, the node placements; the
LINE_STRIP passes (which trimesh's loader skips) read straight from the GLB container by the
format's own layout (glTF 2.0 §4.4: 12-byte header, JSON chunk, BIN chunk)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from paintcell.output.gltf_film import FilmGlbError, FilmScene, write_film_glb
from paintcell.output.report_film import FilmData
from tests.helpers import (
    GLB_COLOUR_ATOL,
    GLB_POSITION_ATOL_M,
    GLB_THICKNESS_ATOL_UM,
    R_GLTF_WORLD,
    line_strips,
    linear_from_srgb,
    spec_colours_linear,
)


def _rz(a: float, p: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    T[:3, 3] = p
    return T


@pytest.fixture()
def grid_scene() -> FilmScene:
    """A 0.4 × 0.3 m grid in z = 0, film rising along x from far below to far above a 20 µm
    window (±10 %), two passes, two robots."""
    x, y = np.meshgrid(np.linspace(0, 0.4, 9), np.linspace(0, 0.3, 7))
    v = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    i = np.arange(9 * 7).reshape(7, 9)[:-1, :-1].ravel()
    faces = np.vstack([np.column_stack([i, i + 1, i + 10]), np.column_stack([i, i + 10, i + 9])])
    t_m = 1e-6 * np.interp(v[:, 0], [0, 0.4], [10.0, 30.0])
    n = len(v)
    film = FilmData(t_m, t_m, np.full(n, 0.01), np.ones(n, bool), 20e-6, 0.1)
    passes = [np.column_stack([np.linspace(0, 0.4, 5), np.full(5, y0), np.full(5, 0.2)])
              for y0 in (0.05, 0.25)]
    return FilmScene(v, faces, np.tile([0.0, 0.0, 1.0], (n, 1)), film, passes,
                     _rz(0.3, (1.0, 0.5, 0.8)), {"left": _rz(1.0, (0, 1.5, 0)),
                                                 "right": _rz(-1.0, (0, -1.5, 0))})


def test_grid_film_file_reads_back_in_trimesh(grid_scene, tmp_path):
    path = write_film_glb(tmp_path / "film.glb", grid_scene)
    scene = trimesh.load(path, force="scene")
    mesh = scene.geometry["film"]
    v = grid_scene.vertices_m
    assert len(mesh.vertices) == len(v)
    np.testing.assert_allclose(mesh.vertices, v, atol=GLB_POSITION_ATOL_M)
    np.testing.assert_allclose(mesh.bounds, [v.min(0), v.max(0)], atol=GLB_POSITION_ATOL_M)
    np.testing.assert_array_equal(mesh.faces, grid_scene.faces)
    t_um = 1e6 * grid_scene.film.executed_m
    np.testing.assert_allclose(mesh.vertex_attributes["_THICKNESS_UM"].reshape(-1), t_um,
                               atol=GLB_THICKNESS_ATOL_UM)

    rgb = np.asarray(mesh.visual.vertex_attributes["color"], float)[:, :3]
    np.testing.assert_allclose(rgb, spec_colours_linear(grid_scene.film.executed_m, 20e-6, 0.1),
                               atol=GLB_COLOUR_ATOL)
    # the scale's ends are its defining colours: 10 µm and 30 µm lie at or past the range ends
    # (16 and 24 µm), so they take the darkest blue and the darkest red
    ends = linear_from_srgb(np.array([[0x08, 0x30, 0x6B], [0x67, 0x00, 0x0D]]) / 255.0)
    np.testing.assert_allclose(rgb[np.argmin(t_um)], ends[0], atol=GLB_COLOUR_ATOL)
    np.testing.assert_allclose(rgb[np.argmax(t_um)], ends[1], atol=GLB_COLOUR_ATOL)
    # below the window blue leads, inside green, above red
    lead = np.argmax(rgb, axis=1)
    assert (lead[t_um < 18.0] == 2).all() and (lead[t_um > 22.0] == 0).all()
    assert (lead[(t_um >= 18.0) & (t_um <= 22.0)] == 1).all()

    # placements: the part and each robot base, under the z-up → y-up turn
    T_part, geom = scene.graph["part"]
    assert geom == "film"
    np.testing.assert_allclose(T_part, R_GLTF_WORLD @ grid_scene.T_world_part, atol=1e-12)
    for name, T in grid_scene.bases.items():
        T_base, geom = scene.graph[f"robot base {name}"]
        np.testing.assert_allclose(T_base, R_GLTF_WORLD @ T, atol=1e-12)
        assert geom is not None and scene.geometry[geom].bounds[1, 2] > 0.1  # a visible marker

    strips = line_strips(path)
    assert len(strips) == len(grid_scene.passes_m)
    for got, want in zip(strips, grid_scene.passes_m, strict=True):
        np.testing.assert_allclose(got, want, atol=GLB_POSITION_ATOL_M)
    assert scene.metadata["spec_window_um"] == pytest.approx([18.0, 22.0])
    assert scene.metadata["unit"] == "m"


def test_film_scene_refuses_arrays_that_do_not_agree(grid_scene):
    g = grid_scene
    with pytest.raises(FilmGlbError, match="one row per vertex"):
        FilmScene(g.vertices_m[:-1], g.faces[:-10], g.normals[:-1], g.film, g.passes_m,
                  g.T_world_part, g.bases)
    with pytest.raises(FilmGlbError, match="faces"):
        FilmScene(g.vertices_m, g.faces + 1000, g.normals, g.film, g.passes_m, g.T_world_part,
                  g.bases)
    with pytest.raises(FilmGlbError, match="pass"):
        FilmScene(g.vertices_m, g.faces, g.normals, g.film, [np.zeros((4, 2))], g.T_world_part,
                  g.bases)
