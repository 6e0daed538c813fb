"""paintcell.execution.cell: the MuJoCo paint cell compiles, holds what execution needs, and
runs warning-free."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from paintcell.execution.cell import CameraSpec, Cell, build_cell
from paintcell.execution.cell_robots import CellError
from paintcell.surface.analytic import plane
from tests.test_execute import make_case, make_cell


def test_cell_indexes_robot_part_booth_and_sensors() -> None:
    case = make_case()
    cell = make_cell()
    m = cell.model
    assert m.opt.timestep == pytest.approx(1e-3)
    assert cell.joint_names == tuple(case.robot.joint_names)
    assert len(cell.qpos_adr) == len(cell.actuator_ids) == case.robot.nq
    assert cell.part_body_name == "part" and cell.booth_body_name == "booth"
    # No preset cameras in the model: renders frame the part with
    # paintcell.output.render.part_cameras.
    assert cell.camera_names == () and m.ncam == 0
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
    assert d.sensordata[cell.sensor_contact_self.start] == 0


def _one_robot_cell(robot: Any, case: Any) -> Cell:
    return build_cell(robot, case.surface, case.T_world_part)


def _booth_cell(robot: Any, case: Any) -> Cell:
    from paintcell.booth.booth_cell import build_booth_cell

    return build_booth_cell([robot], case.surface, case.T_world_part).cell


@pytest.mark.parametrize("builder", [_one_robot_cell, _booth_cell], ids=["cell", "booth"])
def test_a_rail_at_floor_level_stands_on_the_floor_without_contact(builder: Any) -> None:
    """A rail robot whose rail frame is on the floor (init's rail frames at height 0): the
    arm's foot rides the carriage at floor level by design, at every carriage position — no
    booth contact (it was one at every step of the run: 235 of 235 poses lost on
    bezier_part_scan), in the one-robot cell and in the booth's. The arm itself still meets the
    floor: its wrist bent down to it does."""
    from paintcell.robots import load_robot

    case = make_case()
    robot = load_robot("irb5500_rail")
    cell = builder(robot, case)
    d = mujoco.MjData(cell.model)
    for s_m in (-1.5, 0.0, 1.5):
        d.qpos[cell.qpos_adr] = np.r_[s_m, robot.q_home[1:]]
        mujoco.mj_forward(cell.model, d)
        assert d.sensordata[cell.sensor_contact_booth.start] == 0
    q = np.r_[0.0, robot.q_home[1:]]
    q[2] = 1.4                                   # shoulder forward and down: the arm on the floor
    d.qpos[cell.qpos_adr] = q
    mujoco.mj_forward(cell.model, d)
    assert d.sensordata[cell.sensor_contact_booth.start] > 0


def _robot_contacts(cell: Cell, q: np.ndarray) -> dict[tuple[str, str], float]:
    """{(body, body): min distance [m]} of the robot-vs-robot contacts MuJoCo finds at q."""
    m, d = cell.model, mujoco.MjData(cell.model)
    d.qpos[cell.qpos_adr] = q
    mujoco.mj_forward(m, d)
    robot = set(cell.robot_body_ids.tolist())
    out: dict[tuple[str, str], float] = {}
    for c in (d.contact[i] for i in range(d.ncon)):
        b = tuple(int(x) for x in m.geom_bodyid[c.geom])
        if b[0] in robot and b[1] in robot:
            key = tuple(sorted(m.body(x).name for x in b))
            out[key] = min(out.get(key, 0.0), float(c.dist))  # type: ignore[index]
    return out


@pytest.mark.parametrize("name", ["abb_paint", "ur10"])
def test_no_robot_links_overlap_by_construction(name: str) -> None:
    """Self-contacts are real collisions: at the home pose no two robot bodies touch (a pair whose
    collision geoms overlap by construction at a joint would touch at every pose), and no pair
    touches in every one of a set of random poses within the joint limits."""
    from paintcell.robots import load_robot

    case = make_case()
    cell = build_cell(load_robot(name), case.surface, case.T_world_part)
    assert _robot_contacts(cell, cell.q_home) == {}
    m = cell.model
    j = m.dof_jntid[cell.dof_adr]
    lo = np.where(m.jnt_limited[j], m.jnt_range[j, 0], -np.pi)
    hi = np.where(m.jnt_limited[j], m.jnt_range[j, 1], np.pi)
    rng = np.random.default_rng(0)
    seen = [set(_robot_contacts(cell, rng.uniform(lo, hi))) for _ in range(200)]
    assert set.intersection(*seen) == set()


def test_self_contact_sensor_sees_self_collisions_only() -> None:
    """The robot-vs-robot sensor fires when the bell is folded into the upper arm (J3 at its
    limit, J5 bent back), with that depth, and ignores what MuJoCo filters or the cell excludes:
    the foot plate and the rotating base overlap by construction at every pose."""
    cell = make_cell()
    m = cell.model
    d = mujoco.MjData(m)
    folded = np.array([0.0, -0.2, 1.3, 0.0, 2.0, 0.0])
    hits = _robot_contacts(cell, folded)
    assert set(hits) == {("robot/flange", "robot/link2")} and hits[("robot/flange",
                                                                     "robot/link2")] < -0.05
    d.qpos[cell.qpos_adr] = folded
    mujoco.mj_forward(m, d)
    assert d.sensordata[cell.sensor_contact_self.start] > 0
    assert d.sensordata[cell.sensor_contact_self.start + 1] == pytest.approx(
        hits[("robot/flange", "robot/link2")])
    assert d.sensordata[cell.sensor_contact_part.start] == 0
    # The excluded foot/base pair really overlaps at home; the sensor does not count it.
    d.qpos[cell.qpos_adr] = cell.q_home
    mujoco.mj_forward(m, d)
    body = m.geom_bodyid
    foot = [g for g in range(m.ngeom) if m.body(body[g]).name == "robot/base_link"
            and m.geom_contype[g]]
    link1 = [g for g in range(m.ngeom) if m.body(body[g]).name == "robot/link1"
             and m.geom_contype[g]]
    assert foot and link1
    assert mujoco.mj_geomDistance(m, d, foot[0], link1[0], 0.1, None) < 0
    assert d.sensordata[cell.sensor_contact_self.start] == 0


def test_robot_geoms_collide_with_each_other_whatever_their_bits(tmp_path: Path) -> None:
    """A robot MJCF that switches self-collision off with split bits (contype 2, conaffinity 1:
    the links still hit the part) gets its collision geoms colliding with each other again."""
    from paintcell.robots import load_robot

    robot = load_robot("abb_paint")
    xml = Path(robot.mjcf_path).read_text()
    old = '<geom type="capsule" group="3"'
    assert old in xml
    split = tmp_path / "abb_paint_split_bits.xml"
    split.write_text(xml.replace(old, '<geom type="capsule" group="3" contype="2" conaffinity="1"'))

    class SplitBits:
        def __getattr__(self, name: str) -> Any:
            return split if name == "mjcf_path" else getattr(robot, name)

    case = make_case()
    cell = build_cell(SplitBits(), case.surface, case.T_world_part)  # type: ignore[arg-type]
    m = cell.model
    coll = [g for g in range(m.ngeom) if m.geom_bodyid[g] in cell.robot_body_ids
            and (m.geom_contype[g] or m.geom_conaffinity[g])]
    assert len(coll) >= 7 and all(m.geom_contype[g] & m.geom_conaffinity[h]
                                  for g in coll for h in coll)
    assert ("robot/flange", "robot/link2") in _robot_contacts(
        cell, np.array([0.0, -0.2, 1.3, 0.0, 2.0, 0.0]))


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
    assert cell.camera_names == ("side",) and cell.model.ncam == 1
    # The fixed camera sits where asked and looks at its target (MuJoCo cameras look along -z).
    d = mujoco.MjData(cell.model)
    mujoco.mj_forward(cell.model, d)
    np.testing.assert_allclose(d.cam_xpos[0], [0.0, -3.0, 1.5], atol=1e-12)
    view = np.array([1.0, 3.0, -0.5]) / np.linalg.norm([1.0, 3.0, -0.5])
    np.testing.assert_allclose(-d.cam_xmat[0].reshape(3, 3)[:, 2], view, atol=1e-9)
    assert cell.model.cam_fovy[0] == pytest.approx(50.0)
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
    from paintcell.robots import load_robot

    with pytest.raises(CellError, match=r"surface must be a Surface \(paintcell.surface"):
        build_cell(load_robot("abb_paint"), surface, np.eye(4))
