"""sim.cell: the MuJoCo paint cell compiles, holds what execution needs, and runs warning-free."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from planning.surface import plane
from sim.cell import CameraSpec, CellError, build_cell
from tests.test_execute import make_case, make_cell


def test_cell_indexes_robot_part_booth_and_sensors() -> None:
    case = make_case()
    cell = make_cell()
    m = cell.model
    assert m.opt.timestep == pytest.approx(1e-3)
    assert cell.joint_names == tuple(case.robot.joint_names)
    assert len(cell.qpos_adr) == len(cell.actuator_ids) == case.robot.nq
    assert cell.part_body_name == "part" and cell.booth_body_name == "booth"
    assert {"front", "top", "passes"} <= set(cell.camera_names)
    assert m.nlight >= 1
    # The part's visual mesh is the surface itself, placed at T_world_part.
    gid = cell.part_visual_geom_id
    assert m.mesh_vertnum[m.geom_dataid[gid]] == len(case.surface.vertices)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    np.testing.assert_allclose(d.xpos[cell.part_body_id], case.T_world_part[:3, 3], atol=1e-12)
    np.testing.assert_allclose(d.xmat[cell.part_body_id].reshape(3, 3),
                               case.T_world_part[:3, :3], atol=1e-9)


def test_tcp_site_matches_robot_fk() -> None:
    case = make_case()
    cell = make_cell()
    d = mujoco.MjData(cell.model)
    q = case.robot.q_home + np.array([0.3, 0.2, -0.1, 0.5, 0.4, -0.7])
    d.qpos[cell.qpos_adr] = q
    mujoco.mj_forward(cell.model, d)
    T = case.robot.fk(q)
    np.testing.assert_allclose(d.site_xpos[cell.tcp_site_id], T[:3, 3], atol=1e-9)
    np.testing.assert_allclose(d.site_xmat[cell.tcp_site_id].reshape(3, 3), T[:3, :3], atol=1e-9)
    np.testing.assert_allclose(d.sensordata[cell.sensor_tcp_pos], T[:3, 3], atol=1e-9)


def test_cell_runs_without_warnings_under_random_torques() -> None:
    cell = make_cell()
    m = cell.model
    d = mujoco.MjData(m)
    d.qpos[cell.qpos_adr] = cell.q_home
    rng = np.random.default_rng(0)
    for _ in range(20):
        d.ctrl[cell.actuator_ids] = rng.uniform(-0.2, 0.2, cell.nq) * cell.tau_max
        for _ in range(50):
            mujoco.mj_step(m, d)
    assert all(d.warning[i].number == 0 for i in range(len(d.warning)))
    assert np.all(np.isfinite(d.qpos))


def test_robot_at_home_touches_nothing() -> None:
    cell = make_cell()
    d = mujoco.MjData(cell.model)
    d.qpos[cell.qpos_adr] = cell.q_home
    mujoco.mj_forward(cell.model, d)
    assert d.sensordata[cell.sensor_contact_part.start] == 0
    assert d.sensordata[cell.sensor_contact_booth.start] == 0


def test_part_collision_slabs_cover_the_shell() -> None:
    """A sphere dropped onto the middle of the (open, thin) part shell is stopped by it."""
    case = make_case()
    cell = make_cell()
    spec = cell.spec.copy()
    p = case.T_world_part[:3, 3] + 0.05 * case.T_world_part[:3, 2]
    ball = spec.worldbody.add_body(name="probe", pos=p)
    ball.add_freejoint()
    ball.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.02, 0, 0], mass=0.1)
    m = spec.compile()
    d = mujoco.MjData(m)
    m.opt.gravity = -9.81 * case.T_world_part[:3, 2]  # "down" into the painted side
    for _ in range(500):
        mujoco.mj_step(m, d)
    bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "probe")
    height = (d.xpos[bid] - case.T_world_part[:3, 3]) @ case.T_world_part[:3, 2]
    assert 0.0 < height < 0.03  # resting on the slab (radius 0.02 + half thickness), not through


def test_custom_cameras_and_bad_placement() -> None:
    case = make_case()
    cams = (CameraSpec("side", (0.0, -3.0, 1.5), (1.0, 0.0, 1.0), 50.0),)
    cell = build_cell(case.robot, plane(0.2, 0.2, 0.02), case.T_world_part, cameras=cams)
    assert cell.camera_names == ("side",)
    bad = case.T_world_part.copy()
    bad[:3, :3] *= 2.0
    with pytest.raises(CellError, match="rigid"):
        build_cell(case.robot, case.surface, bad)


def test_cell_compiles_without_attach_or_compiler_warnings() -> None:
    case = make_case()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cell = build_cell(case.robot, plane(0.3, 0.3, 0.02), case.T_world_part)
    assert cell.model.nkey == 0


@pytest.mark.parametrize("surface", [None, "door", np.zeros((3, 3))])
def test_surface_type_is_checked_at_entry(surface) -> None:
    from robots import load_robot

    with pytest.raises(CellError, match="surface must be a planning.surface.Surface"):
        build_cell(load_robot("abb_paint"), surface, np.eye(4))
