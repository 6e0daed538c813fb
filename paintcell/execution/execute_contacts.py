"""Naming the contacts of an executed program: which robot body touched the part, the booth or
another robot body, when [s] and how deep [m].
"""

from __future__ import annotations

import mujoco
import numpy as np

from paintcell.execution.cell import Cell
from paintcell.execution.trace import Contact


def named_contacts(model: mujoco.MjModel, cell: Cell, q: np.ndarray, sens: np.ndarray,
                   t_s: np.ndarray) -> tuple[Contact, ...]:
    """Name the bodies of every robot-vs-part/booth and robot-vs-robot contact the sensors saw
    (deepest per body pair and step).

    Robot-vs-part/booth: body1 is the robot body, body2 the part or booth. Self-collision: both
    are robot bodies, body1 the one farther out along the chain (bodies are numbered depth-first,
    so a descendant has the larger id), e.g. ("robot/link5", "robot/base_link").
    """
    found = sens[:, cell.sensor_contact_part.start] > 0
    for sl in (cell.sensor_contact_booth, cell.sensor_contact_self):
        if sl.stop > sl.start:
            found |= sens[:, sl.start] > 0
    steps = np.flatnonzero(found)
    if len(steps) == 0:
        return ()
    d = mujoco.MjData(model)
    robot = np.zeros(model.nbody, bool)
    robot[cell.robot_body_ids] = True
    partners = np.array([cell.part_collision_body_id, cell.booth_body_id])
    out: list[Contact] = []
    for k in steps:
        d.qpos[cell.qpos_adr] = q[k]
        mujoco.mj_fwdPosition(model, d)
        nc = d.ncon
        if nc == 0:
            continue
        bodies = model.geom_bodyid[d.contact.geom[:nc]]
        depth = -d.contact.dist[:nc]
        both = robot[bodies[:, 0]] & robot[bodies[:, 1]]
        # Robot body first; between two robot bodies, the distal one (larger id) first.
        swap = np.where(both, bodies[:, 0] < bodies[:, 1],
                        robot[bodies[:, 1]] & ~robot[bodies[:, 0]])
        bodies[swap] = bodies[swap][:, ::-1]
        keep = both | (robot[bodies[:, 0]] & np.isin(bodies[:, 1], partners))
        deepest: dict[tuple[int, int], float] = {}
        for (b1, b2), dep in zip(bodies[keep].tolist(), depth[keep].tolist(), strict=True):
            deepest[(b1, b2)] = max(deepest.get((b1, b2), 0.0), dep)
        for (b1, b2), depth in deepest.items():
            name2 = cell.part_body_name if b2 == cell.part_collision_body_id else \
                model.body(b2).name  # the slabs may sit on the world body: they are the part
            out.append(Contact(time_s=float(t_s[k]), body1=model.body(b1).name,
                               body2=name2, depth_m=depth))
    return tuple(out)
