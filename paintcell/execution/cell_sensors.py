"""Contact sensors of a MuJoCo cell's robot subtree: against the part, the booth floor and itself
(self-collision), and the names of those partner bodies. `paintcell.execution.cell` and
`paintcell.booth.booth_cell` add them.
"""

from __future__ import annotations

import mujoco

#: MuJoCo names of the part body and the booth-floor body (the contact sensors' partners).
PART_BODY = "part"
BOOTH_BODY = "booth"
#: contact sensor data: found (1) + dist (8) (MuJoCo mjtConDataField bits), reduce = mindist.
_CONTACT_DATA_FOUND_DIST = 1 | 8
_CONTACT_REDUCE_MINDIST = 1
#: name of the robot-vs-robot (self-collision) contact sensor.
SELF_CONTACT_SENSOR = "contact_self"


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
