"""The robots in a MuJoCo cell (`paintcell.execution.cell` for one robot,
`paintcell.booth.booth_cell` for several): each robot's MJCF attached at its base pose under its
name prefix (`attach_robots`), the contacts its foot makes by design excluded (`stand_robots`),
and the contact sensors of the robots' subtree against the part, the booth floor and itself
(`add_contact_sensors`, with the names of those partner bodies).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Protocol

import mujoco
import numpy as np

from paintcell.core.errors import PaintcellError
from paintcell.core.transforms import quat_wxyz_from_matrix


def robot_prefix(i: int) -> str:
    """Name prefix of robot i's MJCF in a cell of several robots (its bodies' names)."""
    return f"r{i}/"


class CellError(PaintcellError):
    """The MuJoCo cell cannot be assembled from the robot, part and placement given."""


class RobotLike(Protocol):
    """What the cell needs of a `paintcell.robots.Robot` (read-only)."""

    @property
    def name(self) -> str: ...
    @property
    def mjcf_path(self) -> str | os.PathLike[str]: ...
    @property
    def T_world_base(self) -> np.ndarray: ...
    @property
    def tcp_site_name(self) -> str: ...
    @property
    def base_body_name(self) -> str: ...
    @property
    def joint_names(self) -> tuple[str, ...]: ...
    @property
    def tau_max(self) -> np.ndarray: ...
    @property
    def q_home(self) -> np.ndarray: ...


#: MuJoCo names of the part body and the booth-floor body (the contact sensors' partners).
PART_BODY = "part"
BOOTH_BODY = "booth"
#: contact sensor data: found (1) + dist (8) (MuJoCo mjtConDataField bits), reduce = mindist.
_CONTACT_DATA_FOUND_DIST = 1 | 8
_CONTACT_REDUCE_MINDIST = 1
#: name of the robot-vs-robot (self-collision) contact sensor.
SELF_CONTACT_SENSOR = "contact_self"
#: contype/conaffinity bit shared by the robot's collision geoms, the part slabs and the floor
#: (MuJoCo's default 1): any two of them collide, the robot's links with each other included.
COLLISION_BIT = 1


def add_contact_sensors(spec: mujoco.MjSpec, subtree_body: str, booth: bool,
                        part_body: str = PART_BODY) -> None:
    """Contact sensors of the robot subtree rooted at `subtree_body` (MuJoCo body name): one per
    partner (the part — `part_body`, the body holding its collision slabs — and the booth floor
    when `booth`) and one for self-contact.

    Self-collision: the subtree against the same subtree matches the contacts whose two geoms
    both belong to it (MuJoCo 4.0 contact-sensor matching: each side's criterion must hold for one
    of the two geoms). Only contacts MuJoCo generated are seen, so the filtered (parent-child,
    welded) and excluded pairs never count. In a booth the subtree holds every robot, so
    robot-robot contacts are self-contacts.
    """
    for partner, body in [(PART_BODY, part_body)] + ([(BOOTH_BODY, BOOTH_BODY)] if booth else []):
        spec.add_sensor(name=f"contact_{partner}", type=mujoco.mjtSensor.mjSENS_CONTACT,
                        objtype=mujoco.mjtObj.mjOBJ_XBODY, objname=subtree_body,
                        reftype=mujoco.mjtObj.mjOBJ_BODY, refname=body,
                        intprm=[_CONTACT_DATA_FOUND_DIST, _CONTACT_REDUCE_MINDIST, 1])
    spec.add_sensor(name=SELF_CONTACT_SENSOR, type=mujoco.mjtSensor.mjSENS_CONTACT,
                    objtype=mujoco.mjtObj.mjOBJ_XBODY, objname=subtree_body,
                    reftype=mujoco.mjtObj.mjOBJ_XBODY, refname=subtree_body,
                    intprm=[_CONTACT_DATA_FOUND_DIST, _CONTACT_REDUCE_MINDIST, 1])


def attach_robots(spec: mujoco.MjSpec, parent: mujoco.MjsBody, robots: Sequence[RobotLike],
                  prefixes: Sequence[str]) -> None:
    """Attach each robot's MJCF (its keyframes dropped: the arm's alone do not fit the cell's
    state) to `parent` at its base pose, its names under its prefix. Before any other geom: the
    robots' collision geoms (a contype or conaffinity bit; visual geoms have neither) then get
    `COLLISION_BIT` in both, so they collide with each other, not only with the part and the
    floor (a robot MJCF may split the bits, contype 2 / conaffinity 1, to switch self-collision
    off)."""
    for robot, prefix in zip(robots, prefixes, strict=True):
        try:
            rs = mujoco.MjSpec.from_file(str(robot.mjcf_path))
        except Exception as exc:  # mujoco raises ValueError with its own message
            raise CellError(f"cannot read the robot MJCF {robot.mjcf_path}: {exc}") from exc
        for key in list(rs.keys):
            rs.delete(key)
        rs.nkey = 0
        T = np.asarray(robot.T_world_base, float)
        spec.attach(rs, prefix=prefix, frame=parent.add_frame(
            pos=T[:3, 3], quat=quat_wxyz_from_matrix(T[:3, :3])))
    for geom in spec.geoms:
        if geom.contype or geom.conaffinity:
            geom.contype |= COLLISION_BIT
            geom.conaffinity |= COLLISION_BIT


def stand_robots(spec: mujoco.MjSpec, robots: Sequence[RobotLike], prefixes: Sequence[str],
                 floor: bool) -> None:
    """Exclude the contacts each robot's foot makes by design. With the `floor` (body
    BOOTH_BODY): the foot standing on it, and on a rail the carriage and the arm's foot on it,
    which ride at the rail's height (no rotating joint between them and the rail's frame). And
    the foot against its moving children: MuJoCo filters parent-child contacts except for a
    parent welded to the world, and the rotating base stands in the foot plate by construction
    (the ABB link1 cylinder overlaps the foot box by 20 mm). Neighbours two joints apart whose
    collision geoms overlap by construction are excluded by the robot MJCF itself
    (`<contact><exclude>`, e.g. the ABB link1/link3, link3/link5, link4/flange); no other robot
    pair touches at the home pose (tests/test_cell.py checks this for every robot), so
    self-contacts are real collisions."""
    for i, (robot, prefix) in enumerate(zip(robots, prefixes, strict=True)):
        base = spec.body(prefix + robot.base_body_name)
        if base is None:
            raise CellError(f"robot {i} MJCF has no body {robot.base_body_name!r}; fix its "
                            "base_body_name")
        for body in [base, *riding_bodies(base)] if floor else []:
            spec.add_exclude(bodyname1=body.name, bodyname2=BOOTH_BODY)
        for child in base.bodies:
            spec.add_exclude(bodyname1=base.name, bodyname2=child.name)


def riding_bodies(body: mujoco.MjsBody) -> list[mujoco.MjsBody]:
    """The bodies below `body` that only slide with it (no hinge or ball joint on the way)."""
    out = []
    for child in body.bodies:
        if all(j.type == mujoco.mjtJoint.mjJNT_SLIDE for j in child.joints):
            out += [child, *riding_bodies(child)]
    return out
