"""The paint booth in MuJoCo: several robots, the part on a conveyor carrier, the floor.

`build_booth_cell(robots, surface, T_world_part, conveyor)` assembles one `mujoco.MjSpec`:
every robot's MJCF attached under a static `robots` body at its own base pose with its own
prefix (`r0/`, `r1/`, ...), the part — the deposition mesh and thin convex collision slabs, as in
`paintcell.execution.cell` — in a body `part` that slides along the conveyor line on a servoed
slide joint
`conveyor` (a prismatic carrier with the part + skid mass), and the booth floor. Contact sensors
see the `robots` subtree against the part, the floor and itself, so robot–robot contacts count
like self-collisions; `_contacts` in `paintcell.execution.execute` names them.

The result is a `paintcell.execution.cell.Cell` whose "robot" is the whole booth — all robots'
joints, then the
carrier — so `paintcell.execution.execute.execute` runs every robot and the conveyor at once
with its servo (PD +
feed-forward, latency, friction, torque limits) unchanged; the carrier is servoed like a joint,
so the part really lags or leads its nominal position (the conveyor's own tracking error).
`BoothCell` keeps what belongs to each robot: its columns in the joint vector, its TCP site and
its bodies.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

from paintcell.booth.conveyor import Conveyor
from paintcell.core.transforms import check_pose, quat_wxyz_from_matrix
from paintcell.execution.cell import Cell, index_cell, new_cell_spec
from paintcell.execution.cell_part import add_part_geoms
from paintcell.execution.cell_robots import (
    BOOTH_BODY,
    PART_BODY,
    CellError,
    RobotLike,
    add_contact_sensors,
    attach_robots,
    robot_prefix,
    stand_robots,
)
from paintcell.surface.surface_data import Surface

#: the static body that holds every robot (its subtree is "the robots" for the contact sensors).
ROBOTS_BODY = "robots"
CONVEYOR_JOINT = "conveyor"


@dataclass(frozen=True)
class _BoothRobot:
    """The combined "robot" `paintcell.execution.cell.index_cell` indexes: all robots' joints +
    the carrier."""

    name: str
    joint_names: tuple[str, ...]
    tau_max: np.ndarray
    q_home: np.ndarray
    tcp_site_name: str
    base_body_name: str
    T_world_base: np.ndarray
    mjcf_path: str = ""


@dataclass(frozen=True, eq=False)
class BoothCell:
    """A compiled booth and its per-robot indices.

    cell: the `Cell` that `paintcell.execution.execute.execute` runs (joints: every robot's,
    prefixed, then the
        carrier `conveyor` [m] when there is one).
    robots: the robots, in order. columns: per robot, its (n_i,) columns in the joint vector.
    tcp_site_ids: per robot, the MuJoCo id of its TCP site. body_ids: per robot, its bodies.
    carrier_column: column of the carrier in the joint vector (None without a conveyor).
    conveyor: the line (None: a static part). T_world_part: nominal part placement (4, 4).
    """

    cell: Cell
    robots: tuple[RobotLike, ...]
    columns: tuple[np.ndarray, ...]
    tcp_site_ids: tuple[int, ...]
    body_ids: tuple[np.ndarray, ...]
    carrier_column: int | None
    conveyor: Conveyor | None
    T_world_part: np.ndarray

    @property
    def n_robots(self) -> int:
        """Number of robots."""
        return len(self.robots)

    def robot_of_body(self, body_name: str) -> int:
        """Index of the robot a MuJoCo body belongs to (-1: none)."""
        for i in range(self.n_robots):
            if body_name.startswith(robot_prefix(i)):
                return i
        return -1


def build_booth_cell(robots: Sequence[RobotLike], surface: Surface, T_world_part: npt.ArrayLike,
                     conveyor: Conveyor | None = None, booth: bool = True,
                     collision_piece_m: float = 0.1,
                     shell_thickness_m: float = 0.002) -> BoothCell:
    """Assemble and compile the booth (module doc).

    robots: `paintcell.robots.Robot`s at their base poses (a rail robot's base is its rail frame).
    surface: the part in its part frame; T_world_part: (4, 4) its nominal placement (the carrier
        at 0). conveyor: the line (None: the part body is static, no carrier joint).
    Raises CellError for an empty robot list or bad poses.
    """
    if not robots:
        raise CellError("a booth needs at least one robot")
    if not isinstance(surface, Surface):
        raise CellError("surface must be a Surface (paintcell.surface.analytic) in its "
                        "part frame")
    T_wp = check_pose(T_world_part, "T_world_part", error=CellError)
    spec = new_cell_spec(f"paintcell_booth_{surface.name}")
    bases = np.array([check_pose(r.T_world_base, f"robot {i} T_world_base", error=CellError)
                      [:3, 3] for i, r in enumerate(robots)])
    spec.stat.center = 0.5 * (T_wp[:3, 3] + bases.mean(axis=0))
    spec.stat.extent = max(3.0, float(np.ptp(np.vstack([bases, T_wp[None, :3, 3]]), axis=0).max()))

    prefixes = [robot_prefix(i) for i in range(len(robots))]
    attach_robots(spec, spec.worldbody.add_body(name=ROBOTS_BODY), robots, prefixes)

    part = spec.worldbody.add_body(name=PART_BODY, pos=T_wp[:3, 3],
                                   quat=quat_wxyz_from_matrix(T_wp[:3, :3]))
    if conveyor is not None:
        # The carrier: the part body slides along the line (world direction, in the part frame).
        part.mass = conveyor.mass_kg
        part.inertia = [conveyor.mass_kg * 0.5] * 3   # a 1-2 m body: ~0.5 m radius of gyration
        part.explicitinertial = True
        part.add_joint(name=CONVEYOR_JOINT, type=mujoco.mjtJoint.mjJNT_SLIDE,
                       axis=T_wp[:3, :3].T @ conveyor.unit,
                       damping=[conveyor.damping_n_s_m, 0, 0])
        spec.add_actuator(name="conveyor_motor", target=CONVEYOR_JOINT,
                          trntype=mujoco.mjtTrn.mjTRN_JOINT,
                          ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE,
                          ctrlrange=[-conveyor.force_max_n, conveyor.force_max_n])
    add_part_geoms(spec, part, surface, collision_piece_m, shell_thickness_m)
    if booth:
        floor = spec.worldbody.add_body(name=BOOTH_BODY)
        floor.add_geom(name="booth_floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                       rgba=[0.5, 0.52, 0.55, 1])
    stand_robots(spec, robots, prefixes, booth)
    spec.worldbody.add_light(name="key", pos=[0, 0, 6], dir=[0, 0, -1],
                             type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                             diffuse=[0.6, 0.6, 0.6], castshadow=False)

    site0 = robot_prefix(0) + robots[0].tcp_site_name
    spec.add_sensor(name="tcp_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site0)
    spec.add_sensor(name="tcp_quat", type=mujoco.mjtSensor.mjSENS_FRAMEQUAT,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site0)
    names = [robot_prefix(i) + jn for i, r in enumerate(robots) for jn in r.joint_names]
    if conveyor is not None:
        names.append(CONVEYOR_JOINT)
    for jn in names:
        spec.add_sensor(name=f"tau_{jn}", type=mujoco.mjtSensor.mjSENS_JOINTACTFRC,
                        objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=jn)
    add_contact_sensors(spec, ROBOTS_BODY, booth)
    try:
        model = spec.compile()
    except ValueError as exc:
        raise CellError(f"the booth does not compile ({exc})") from exc

    tau = [np.asarray(r.tau_max, float) for r in robots]
    home = [np.asarray(r.q_home, float) for r in robots]
    if conveyor is not None:
        tau.append(np.array([conveyor.force_max_n]))
        home.append(np.zeros(1))
    combined = _BoothRobot(name="booth", joint_names=tuple(names),
                           tau_max=np.concatenate(tau), q_home=np.concatenate(home),
                           tcp_site_name=site0,
                           base_body_name=ROBOTS_BODY, T_world_base=np.eye(4))
    # Names in the booth are prefixed per robot already: index with an empty prefix.
    cell = index_cell(model, spec, combined, surface, T_wp, np.eye(4), (), booth, prefix="")
    columns, start = [], 0
    for r in robots:
        columns.append(np.arange(start, start + len(r.joint_names)))
        start += len(r.joint_names)
    sites = tuple(int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE,
                                        robot_prefix(i) + r.tcp_site_name))
                  for i, r in enumerate(robots))
    bodies = tuple(np.array([b for b in range(model.nbody)
                             if model.body(b).name.startswith(robot_prefix(i))])
                   for i in range(len(robots)))
    return BoothCell(cell=cell, robots=tuple(robots), columns=tuple(columns), tcp_site_ids=sites,
                     body_ids=bodies, carrier_column=start if conveyor is not None else None,
                     conveyor=conveyor, T_world_part=T_wp)
