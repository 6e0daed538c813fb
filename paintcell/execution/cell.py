"""The MuJoCo paint cell: the robot at its base pose, the part at its placement, the booth.

Assembled programmatically with `mujoco.MjSpec`: the robot's own MJCF (`robot.mjcf_path`, the one
source of truth Pinocchio also loads) is attached under a frame at `T_world_base`; the part is a
static body whose visual mesh is exactly `surface.vertices/faces` (the geometry the deposition
model evaluates), with collision geometry made of thin convex slabs (the open shell extruded by
`shell_thickness_m` and cut into pieces of about `collision_piece_m`, because MuJoCo collides
meshes through their convex hulls and the hull of a curved shell would be a solid lens).
The booth is a floor plane (its own static body, so contacts name it). Sensors on the TCP site,
the actuator forces and robot-vs-part / robot-vs-booth / robot-vs-robot (self-collision) contact
detectors let `paintcell.execution.execute` roll the whole program out inside MuJoCo.

Self-collision: every robot collision geom collides with every other (`COLLISION_BIT` in both
contype and conaffinity), except what MuJoCo filters (parent–child bodies, bodies welded together)
and the excluded pairs — the robot MJCF's own `<contact><exclude>` neighbours, whose collision
capsules overlap by construction at a joint, and the foot against its moving children
(`paintcell.execution.cell_robots`, which attaches the robots of a booth's cell too).
The `contact_self` sensor (robot subtree against the same subtree) sees exactly those contacts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from paintcell.core.transforms import check_pose, quat_wxyz_from_matrix
from paintcell.execution.cell_part import add_part_geoms
from paintcell.execution.cell_robots import (
    BOOTH_BODY,
    PART_BODY,
    SELF_CONTACT_SENSOR,
    CellError,
    RobotLike,
    add_contact_sensors,
    attach_robots,
    stand_robots,
)
from paintcell.surface.surface_data import Surface

__all__ = ["ROBOT_PREFIX", "TIMESTEP_S", "CameraSpec", "Cell", "build_cell", "index_cell",
           "new_cell_spec"]

#: physics and control rate: 1 kHz (DESIGN.md, execution).
TIMESTEP_S = 1e-3
#: prefix of every name that comes from the robot's MJCF inside the cell.
ROBOT_PREFIX = "robot/"


@dataclass(frozen=True)
class CameraSpec:
    """A fixed camera for `build_cell(cameras=...)`: position and look-at point in the world [m],
    vertical field of view [deg]. (The report's views are
    `paintcell.output.render.part_cameras`.)"""

    name: str
    pos_world: tuple[float, float, float]
    target_world: tuple[float, float, float]
    fovy_deg: float = 45.0


@dataclass(frozen=True, eq=False)
class Cell:
    """A compiled paint cell and the indices `paintcell.execution.execute` and
    `paintcell.output.render` need.

    model: the compiled `mujoco.MjModel` (1 kHz, implicitfast).
    spec: the `mujoco.MjSpec` it was compiled from (copy it before adding to it, e.g. a film).
    robot_name, joint_names: the robot and its joint order (as in `Robot.joint_names`).
    qpos_adr, dof_adr, actuator_ids: (n,) int arrays, in joint order.
    tau_max: (n,) actuator torque limits [N·m] (the robot's `tau_max`).
    tcp_site_id, tcp_site_name: the TCP site (spray point; z = spray axis, x = travel).
    robot_body_ids: (B,) ids of every robot body; part_body_id, booth_body_id; names likewise.
    part_collision_body_id: the body holding the part's collision slabs: the part body, or the
        world body (0) when the part stands still (`build_cell(part_slabs_on_world=True)`).
    part_visual_geom_id: the mesh geom that shows the painted surface (vertex order of `surface`).
    sensor slices: tcp_pos / tcp_quat / actuator forces / contact (found, dist) per partner:
        part, booth (empty slice without a booth) and the robot itself (self-collision).
    T_world_part, T_world_base: (4, 4) placements [m].
    camera_names: the fixed cameras given to `build_cell` (none by default; the views of the
        part are `paintcell.output.render.part_cameras`, free cameras that work on any scene).
    """

    model: mujoco.MjModel
    spec: mujoco.MjSpec
    robot_name: str
    joint_names: tuple[str, ...]
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    actuator_ids: np.ndarray
    tau_max: np.ndarray
    tcp_site_id: int
    tcp_site_name: str
    robot_body_ids: np.ndarray
    robot_body_names: tuple[str, ...]
    part_body_id: int
    part_body_name: str
    part_collision_body_id: int
    booth_body_id: int
    booth_body_name: str
    part_visual_geom_id: int
    T_world_part: np.ndarray
    T_world_base: np.ndarray
    camera_names: tuple[str, ...]
    sensor_tcp_pos: slice
    sensor_tcp_quat: slice
    sensor_actuator_force: slice
    sensor_contact_part: slice
    sensor_contact_booth: slice
    sensor_contact_self: slice
    q_home: np.ndarray
    surface_name: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def nq(self) -> int:
        """Number of robot joints."""
        return len(self.joint_names)

    def body_name(self, body_id: int) -> str:
        """MuJoCo name of a body id."""
        return mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_BODY, int(body_id)) or ""


def new_cell_spec(model_name: str) -> mujoco.MjSpec:
    """An empty MuJoCo spec with the cells' common settings: angles in radians, the 1 ms step
    (TIMESTEP_S), the implicit-fast integrator and a 1280 × 960 offscreen buffer."""
    spec = mujoco.MjSpec()
    spec.modelname = model_name
    spec.compiler.degree = False
    spec.option.timestep = TIMESTEP_S
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 960
    return spec


def _camera_quat(pos: np.ndarray, target: np.ndarray) -> np.ndarray:
    """MuJoCo camera looks along its -z with +y up: build that frame from a look-at."""
    z = pos - target
    nz = np.linalg.norm(z)
    if nz < 1e-9:
        raise CellError("camera position equals its target; move the camera")
    z = z / nz
    up = np.array([0.0, 0.0, 1.0])
    if abs(z @ up) > 0.999:  # looking straight down: use +y of the world as "up" on screen
        up = np.array([0.0, 1.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return quat_wxyz_from_matrix(np.column_stack([x, y, z]))


def build_cell(robot: RobotLike, surface: Surface, T_world_part: npt.ArrayLike, booth: bool = True,
               cameras: Sequence[CameraSpec] = (),
               collision_piece_m: float = 0.1, shell_thickness_m: float = 0.002,
               part_slabs_on_world: bool = True) -> Cell:
    """Assemble and compile the paint cell.

    robot: a `paintcell.robots.Robot` (`RobotLike`: name, mjcf_path, T_world_base, tcp_site_name,
        base_body_name, joint_names, tau_max [N·m], q_home [rad]).
    surface: the part in its part frame (vertices [m], faces, normals).
    T_world_part: (4, 4) placement of the part in the world.
    booth: add the booth floor (z = 0 plane) as body `booth`.
    cameras: fixed cameras compiled into the model (default none: renders frame the part with
        `paintcell.output.render.part_cameras`, free cameras that need nothing in the model).
    collision_piece_m, shell_thickness_m: size of the convex collision slabs and their thickness
        [m] (see `paintcell.execution.cell_part._collision_pieces`).
    part_slabs_on_world: carry the collision slabs on MuJoCo's world body (the part stands still:
        the same contacts for a third less collision time, `cell_part`); False keeps them on the
        part body (the former model, for comparisons).
    Raises CellError when the robot MJCF lacks a named joint, site or body, or the poses are bad.
    """
    if not isinstance(surface, Surface):
        raise CellError(f"surface must be a Surface (paintcell.surface.analytic; the part "
                        f"in its part "
                        f"frame), got {type(surface).__name__}; load one with "
                        "paintcell.surface.parts.get_part or Surface.from_mesh")
    T_world_part = check_pose(T_world_part, "T_world_part", error=CellError)
    T_world_base = check_pose(robot.T_world_base, "robot.T_world_base",
                              error=CellError)
    if collision_piece_m <= 0 or shell_thickness_m <= 0:
        raise CellError("collision_piece_m and shell_thickness_m must be > 0 [m]")

    spec = new_cell_spec(f"paintcell_{robot.name}_{surface.name}")
    spec.visual.headlight.ambient = [0.3, 0.3, 0.3]
    spec.visual.headlight.diffuse = [0.5, 0.5, 0.5]
    spec.stat.center = 0.5 * (T_world_part[:3, 3] + T_world_base[:3, 3])
    spec.stat.extent = max(2.0, float(np.linalg.norm(T_world_part[:3, 3] - T_world_base[:3, 3])))

    # --- robot ----------------------------------------------------------------------------
    attach_robots(spec, spec.worldbody, [robot], [ROBOT_PREFIX])

    # --- part: visual mesh (exact surface) + thin convex collision slabs ---------------------
    part = spec.worldbody.add_body(name=PART_BODY, pos=T_world_part[:3, 3],
                                   quat=quat_wxyz_from_matrix(T_world_part[:3, :3]))
    if part_slabs_on_world:
        add_part_geoms(spec, part, surface, collision_piece_m, shell_thickness_m,
                       collision_body=spec.worldbody, T_body_part=T_world_part)
    else:
        add_part_geoms(spec, part, surface, collision_piece_m, shell_thickness_m)

    # --- booth --------------------------------------------------------------------------------
    if booth:
        tex = spec.add_texture(name="booth_floor", type=mujoco.mjtTexture.mjTEXTURE_2D,
                               builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                               mark=mujoco.mjtMark.mjMARK_EDGE, rgb1=[0.55, 0.57, 0.6],
                               rgb2=[0.45, 0.47, 0.5], markrgb=[0.8, 0.8, 0.8],
                               width=300, height=300)
        mat = spec.add_material(name="booth_floor", texuniform=True, texrepeat=[4, 4],
                                reflectance=0.1)
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex.name
        floor = spec.worldbody.add_body(name=BOOTH_BODY)
        floor.add_geom(name="booth_floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                       material="booth_floor")
    stand_robots(spec, [robot], [ROBOT_PREFIX], booth)

    # --- lights, sky and (optional) cameras ------------------------------------------------------
    spec.add_texture(name="booth_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.85, 0.88, 0.92],
                     rgb2=[0.35, 0.4, 0.48], width=256, height=1536)
    spec.worldbody.add_light(name="key", pos=[0, 0, 5], dir=[0, 0, -1],
                             type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                             diffuse=[0.6, 0.6, 0.6], castshadow=False)
    cams = tuple(cameras)
    for cam in cams:
        pos = np.asarray(cam.pos_world, float)
        spec.worldbody.add_camera(name=cam.name, pos=pos,
                                  quat=_camera_quat(pos, np.asarray(cam.target_world, float)),
                                  fovy=cam.fovy_deg)

    # --- sensors: TCP pose, actuator forces, contacts -------------------------------------------
    site_name = ROBOT_PREFIX + robot.tcp_site_name
    base_name = ROBOT_PREFIX + robot.base_body_name
    spec.add_sensor(name="tcp_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site_name)
    spec.add_sensor(name="tcp_quat", type=mujoco.mjtSensor.mjSENS_FRAMEQUAT,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site_name)
    joint_names = tuple(robot.joint_names)
    for jn in joint_names:
        spec.add_sensor(name=f"tau_{jn}", type=mujoco.mjtSensor.mjSENS_JOINTACTFRC,
                        objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=ROBOT_PREFIX + jn)
    add_contact_sensors(spec, base_name, booth,
                        part_body="world" if part_slabs_on_world else PART_BODY)

    try:
        model = spec.compile()
    except ValueError as exc:
        raise CellError(f"the cell does not compile ({exc}); check the robot MJCF names "
                        f"(tcp site {robot.tcp_site_name!r}, base {robot.base_body_name!r})"
                        ) from exc
    return index_cell(model, spec, robot, surface, T_world_part, T_world_base, cams, booth)


def index_cell(model: mujoco.MjModel, spec: mujoco.MjSpec, robot: RobotLike, surface: Surface,
               T_world_part: np.ndarray, T_world_base: np.ndarray, cams: Sequence[CameraSpec],
               booth: bool, prefix: str = ROBOT_PREFIX) -> Cell:
    """The `Cell` of a compiled MuJoCo model: the ids of the robot's joints, actuators, TCP site,
    sensors and geoms (names under `prefix`), with the part, its pose and the cameras; a booth
    cell (`paintcell.booth.booth_cell`) indexes each robot with its own prefix."""
    def oid(kind: mujoco.mjtObj, name: str) -> int:
        i = mujoco.mj_name2id(model, kind, name)
        if i < 0:
            raise CellError(f"the cell has no {kind.name[6:].lower()} named {name!r}; check "
                            "the robot MJCF against Robot.joint_names / tcp_site_name")
        return int(i)

    joint_names = tuple(robot.joint_names)
    jids = [oid(mujoco.mjtObj.mjOBJ_JOINT, prefix + jn) for jn in joint_names]
    act_ids = []
    for j in jids:
        hits = np.flatnonzero((model.actuator_trntype == mujoco.mjtTrn.mjTRN_JOINT)
                              & (model.actuator_trnid[:, 0] == j))
        if len(hits) != 1:
            raise CellError(f"joint {model.joint(j).name!r} has {len(hits)} actuators; the robot "
                            "MJCF needs exactly one motor per joint")
        act_ids.append(int(hits[0]))
    base_id = oid(mujoco.mjtObj.mjOBJ_BODY, prefix + robot.base_body_name)
    # Robot bodies: the base and everything below it.
    robot_bodies = [b for b in range(model.nbody) if _is_descendant(model, b, base_id)]

    def sensor_slice(name: str) -> slice:
        s = oid(mujoco.mjtObj.mjOBJ_SENSOR, name)
        a = int(model.sensor_adr[s])
        return slice(a, a + int(model.sensor_dim[s]))

    n = len(jids)
    tau_first = sensor_slice(f"tau_{joint_names[0]}")
    tau_max = np.asarray(robot.tau_max, float)
    if tau_max.shape != (n,) or np.any(tau_max <= 0):
        raise CellError(f"robot.tau_max must hold {n} positive torque limits [N·m]")
    return Cell(
        model=model, spec=spec, robot_name=str(robot.name), joint_names=joint_names,
        qpos_adr=model.jnt_qposadr[jids].astype(np.int64).copy(),
        dof_adr=model.jnt_dofadr[jids].astype(np.int64).copy(),
        actuator_ids=np.asarray(act_ids, np.int64), tau_max=tau_max,
        tcp_site_id=oid(mujoco.mjtObj.mjOBJ_SITE, prefix + robot.tcp_site_name),
        tcp_site_name=prefix + robot.tcp_site_name,
        robot_body_ids=np.asarray(robot_bodies, np.int64),
        robot_body_names=tuple(model.body(b).name for b in robot_bodies),
        part_body_id=oid(mujoco.mjtObj.mjOBJ_BODY, PART_BODY), part_body_name=PART_BODY,
        part_collision_body_id=int(model.geom_bodyid[oid(mujoco.mjtObj.mjOBJ_GEOM,
                                                          "part_collision_0")]),
        booth_body_id=oid(mujoco.mjtObj.mjOBJ_BODY, BOOTH_BODY) if booth else -1,
        booth_body_name=BOOTH_BODY if booth else "",
        part_visual_geom_id=oid(mujoco.mjtObj.mjOBJ_GEOM, "part_visual"),
        T_world_part=T_world_part.copy(), T_world_base=T_world_base.copy(),
        camera_names=tuple(c.name for c in cams),
        sensor_tcp_pos=sensor_slice("tcp_pos"), sensor_tcp_quat=sensor_slice("tcp_quat"),
        sensor_actuator_force=slice(tau_first.start, tau_first.start + n),
        sensor_contact_part=sensor_slice(f"contact_{PART_BODY}"),
        sensor_contact_booth=sensor_slice(f"contact_{BOOTH_BODY}") if booth else slice(0, 0),
        sensor_contact_self=sensor_slice(SELF_CONTACT_SENSOR),
        q_home=np.asarray(robot.q_home, float).copy(),
        surface_name=surface.name,
    )


def _is_descendant(model: mujoco.MjModel, body: int, ancestor: int) -> bool:
    while body > 0:
        if body == ancestor:
            return True
        body = int(model.body_parentid[body])
    return ancestor == 0 and body == 0
