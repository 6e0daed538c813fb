"""paintcell.output.render: backend choice, film colour map, compositing over a compiled model,
writers."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
from PIL import Image

from paintcell.output import render
from paintcell.surface.analytic import plane
from tests.helpers import RENDER_MIN_PIXEL_STD, RENDER_RAMP_MIN_LEVEL_GAP

VMIN_UM, VMAX_UM = 10.0, 50.0
SIZE = (160, 120)


@pytest.fixture(scope="module")
def panel():
    """0.8 m × 0.5 m plane (x = width) and a thickness ramp 10 → 50 µm along x."""
    s = plane(0.8, 0.5, resolution_m=0.05)
    x = s.vertices[:, 0]
    ramp = (VMIN_UM + (VMAX_UM - VMIN_UM) * (x - x.min()) / np.ptp(x)) * 1e-6
    return s, ramp


def _level(rgb: np.ndarray, cmap: str = render.DEFAULT_CMAP) -> float:
    """Position in [0, 1] of the colour-map entry nearest to a pixel colour."""
    lut = render.colormap_rgb(cmap).astype(float)
    return float(np.argmin(np.linalg.norm(lut - rgb.astype(float), axis=1)) / (len(lut) - 1))


def _part_row_levels(img: np.ndarray) -> tuple[float, float]:
    """Colour-map levels at 30 % and 70 % of the image width on the middle row."""
    h, w = img.shape[:2]
    return _level(img[h // 2, int(0.3 * w)]), _level(img[h // 2, int(0.7 * w)])


def test_backend_is_chosen():
    assert render.backend_name() in ("egl", "osmesa", "glfw", "glx")


def test_no_backend_is_a_clear_error(monkeypatch):
    monkeypatch.setattr(render, "_backend", None)
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(render, "probe_backend",
                        lambda name, timeout_s=0: "cannot open display")
    with pytest.raises(render.RenderBackendError) as e:
        render.backend_name()
    msg = str(e.value)
    assert "libosmesa6" in msg and "\n" not in msg


def test_thickness_ramp_colours(panel, tmp_path):
    s, ramp = panel
    img = render.render_thickness(None, s, ramp, VMIN_UM, VMAX_UM, camera="front", size=SIZE,
                                  colorbar=False)
    assert img.shape == (SIZE[1], SIZE[0], 3) and img.dtype == np.uint8
    path = render.write_png(tmp_path / "ramp.png", img)
    assert path.stat().st_size > 0
    back = np.asarray(Image.open(path))
    assert back.shape == img.shape and np.array_equal(back, img)
    assert back.reshape(-1, 3).std(0).max() > RENDER_MIN_PIXEL_STD
    a, b = _part_row_levels(img)
    # thin and thick ends sit at opposite ends of the colour map (either screen orientation)
    assert abs(a - b) > RENDER_RAMP_MIN_LEVEL_GAP
    # reversing the ramp swaps the two colours: the colour really follows the thickness
    rev = (VMIN_UM + VMAX_UM) * 1e-6 - ramp
    a2, b2 = _part_row_levels(render.render_thickness(None, s, rev, VMIN_UM, VMAX_UM, "front",
                                                      SIZE, colorbar=False))
    assert np.sign(a - b) == -np.sign(a2 - b2)


def test_uniform_thin_and_thick_differ(panel):
    s, _ = panel
    thin = render.render_thickness(None, s, np.full(len(s.vertices), 12e-6), VMIN_UM, VMAX_UM,
                                   "front", SIZE, colorbar=False)
    thick = render.render_thickness(None, s, np.full(len(s.vertices), 48e-6), VMIN_UM, VMAX_UM,
                                    "front", SIZE, colorbar=False)
    c = (SIZE[1] // 2, SIZE[0] // 2)
    assert _level(thin[c]) < 0.25 and _level(thick[c]) > 0.75


def test_colorbar_keeps_size_and_draws_legend(panel):
    s, ramp = panel
    img = render.render_thickness(None, s, ramp, VMIN_UM, VMAX_UM, "oblique", SIZE)
    assert img.shape == (SIZE[1], SIZE[0], 3)
    right = img[:, -SIZE[0] // 8:]
    assert (right == 255).all(axis=2).mean() > 0.3  # white legend panel on the right edge


def _occluded_model() -> mujoco.MjModel:
    """A grey plate at z = 0 and a red box hovering over its +x half (a stand-in robot)."""
    xml = """<mujoco><worldbody><light pos="0 0 3" dir="0 0 -1"/>
      <geom name="plate" type="box" size="0.4 0.25 0.001" pos="0 0 -0.001" rgba="0.7 0.7 0.7 1"/>
      <body name="arm" pos="0.25 0 0.3"><joint name="slide" type="slide" axis="1 0 0"/>
        <geom type="box" size="0.15 0.15 0.15" rgba="1 0 0 1"/></body>
    </worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def test_film_composited_over_compiled_model(panel):
    s, _ = panel
    model = _occluded_model()
    film = render.film_from_surface(s, np.full(len(s.vertices), 48e-6), VMIN_UM, VMAX_UM)
    cam = render.look_from("down", [0, 0, 0], [0, 0, -1], 1.6)
    with render.SceneRenderer(model, film, SIZE) as r:
        img = r.render(cam, q=[0.0])
        moved = r.render(cam, q=[-0.4])  # box slides over the -x half
    h, w = SIZE[1], SIZE[0]
    # film (yellow end of viridis) where nothing is in front of it; the box wins where it is
    left, right = img[h // 2, int(0.3 * w)], img[h // 2, int(0.7 * w)]
    assert _level(left) > 0.75
    assert right[0] > 150 and right[1] < 80  # red box occludes the film
    assert not np.array_equal(img, moved)


def test_robot_pose_changes_render(panel):
    model = _occluded_model()
    a = render.render_robot_at(model, [0.0], None, SIZE)
    b = render.render_robot_at(model, [0.3], None, SIZE)
    assert a.reshape(-1, 3).std(0).max() > RENDER_MIN_PIXEL_STD
    assert np.abs(a.astype(int) - b.astype(int)).sum() > 0


def test_bad_inputs_raise(panel):
    s, ramp = panel
    with pytest.raises(render.RenderError, match="per surface vertex"):
        render.film_from_surface(s, ramp[:-1], VMIN_UM, VMAX_UM)
    with pytest.raises(render.RenderError, match="vmax_um > vmin_um"):
        render.film_from_surface(s, ramp, 30.0, 30.0)
    with pytest.raises(render.RenderError, match="unknown camera"):
        render.render_thickness(None, s, ramp, VMIN_UM, VMAX_UM, "nope", SIZE)
    with pytest.raises(render.RenderError, match="film needs|MjSpec|Cell"):
        render.SceneRenderer(object(), None, SIZE)
    with pytest.raises(render.RenderError, match="gif or .mp4"):
        render.write_video("x.avi", [np.zeros((8, 8, 3), np.uint8)], 10)


def test_camera_presets_frame_the_part(panel):
    s, _ = panel
    cams = render.part_cameras(s)
    assert {"front", "top", "along_passes", "oblique"} <= set(cams)
    front = cams["front"]
    assert front.elevation_deg < -89.0  # part normal +z: the front camera looks straight down
    center = np.asarray(front.lookat)
    r = np.linalg.norm(s.vertices - center, axis=1).max()
    assert front.distance_m * np.sin(np.radians(22.5)) >= r


def test_frame_indices_and_gif(tmp_path, panel):
    t = np.arange(0, 10.0, 0.001)
    idx = render.frame_indices(t, fps=10, speedup=2.0)
    assert np.all(np.diff(idx) > 0) and abs(len(idx) - 51) <= 1
    assert len(render.frame_indices(t, 10, 1.0, max_frames=20)) == 20
    model = _occluded_model()
    q = np.linspace(-0.3, 0.3, 40)[:, None]
    p = render.render_execution_video(tmp_path / "v.gif", model, np.linspace(0, 3.9, 40), q,
                                      None, fps=10, size=(64, 48))
    with Image.open(p) as im:
        assert im.n_frames == 40


def test_robot_qpos_adr_of_a_cell_is_the_cells():
    from tests.test_execute import make_case, make_cell

    cell = make_cell()
    np.testing.assert_array_equal(render.robot_qpos_adr(cell, cell.model), cell.qpos_adr)
    # The Cell's own addresses are used as they are, not looked up again by name.
    shuffled = dataclasses.replace(cell, qpos_adr=cell.qpos_adr[::-1].copy())
    np.testing.assert_array_equal(render.robot_qpos_adr(shuffled, cell.model),
                                  cell.qpos_adr[::-1])
    # Plain model + joint names (the robot's, attached under a prefix): the same joints by name.
    robot = make_case().robot
    np.testing.assert_array_equal(render.robot_qpos_adr(robot, cell.model), cell.qpos_adr)
    np.testing.assert_array_equal(
        render.robot_qpos_adr(SimpleNamespace(robot=robot), cell.model), cell.qpos_adr)


def test_robot_qpos_adr_of_a_plain_model_by_name():
    model = _occluded_model()
    assert render.robot_qpos_adr(model, model) is None  # nothing names the robot's joints
    assert list(render.robot_qpos_adr(SimpleNamespace(joint_names=("slide",)), model)) == [0]
    assert render.robot_qpos_adr(SimpleNamespace(joint_names=("nope",)), model) is None
