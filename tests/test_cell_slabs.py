"""The part's collision slabs on MuJoCo's world body (`build_cell(part_slabs_on_world=True)`, the
default: a third less collision time) give the contacts the slabs on the part body gave, on the
real two-pass program of tests/test_execute.py with the part pushed 0.3 m into the bell's path:
the same robot bodies, steps and depths, the same servo states; and a displaced part
(`Disturbances`: offset and rotation) moves its slabs and their bounding-volume tree with it.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from paintcell.execution.cell import build_cell
from paintcell.execution.execute import Disturbances, execute
from paintcell.execution.trace import ExecutedTrace
from tests.test_execute import make_case

PUSH_M = 0.3  # the part through the bell's path: contacts all along the first pass


def _same_contacts(new: ExecutedTrace, old: ExecutedTrace) -> None:
    assert len(new.contacts) > 100
    assert [(c.body1, c.body2, round(c.time_s, 6)) for c in new.contacts] == \
        [(c.body1, c.body2, round(c.time_s, 6)) for c in old.contacts]
    for a, b in zip(new.contacts, old.contacts, strict=True):
        assert a.depth_m == pytest.approx(b.depth_m, abs=1e-12)


def test_slabs_on_the_world_give_the_part_body_contacts() -> None:
    case = make_case(PUSH_M)
    new_cell = build_cell(case.robot, case.surface, case.T_world_part)
    old_cell = build_cell(case.robot, case.surface, case.T_world_part, part_slabs_on_world=False)
    m = new_cell.model
    assert new_cell.part_collision_body_id == 0 and old_cell.part_collision_body_id == \
        old_cell.part_body_id
    assert m.body_geomnum[new_cell.part_body_id] == 1  # only the visual mesh left on the part
    # Kinematic replay: the same contacts, bit for bit (the narrow phase sees the same geoms).
    new, old = (execute(c, case.traj, mode="kinematic") for c in (new_cell, old_cell))
    _same_contacts(new, old)
    assert {c.body2 for c in new.contacts} == {"part"}
    # Servo: the contacts push the arm back the same way (the contact order in MuJoCo's list
    # follows the geom ids, which differ: 1e-9 rad).
    new, old = (execute(c, case.traj) for c in (new_cell, old_cell))
    _same_contacts(new, old)
    assert np.abs(new.q - old.q).max() <= 1e-9
    assert np.all(np.abs(new.tau - old.tau) <= 1e-9 * new_cell.tau_max)


def test_a_displaced_part_takes_its_slabs_along() -> None:
    case = make_case(PUSH_M)
    new_cell = build_cell(case.robot, case.surface, case.T_world_part)
    old_cell = build_cell(case.robot, case.surface, case.T_world_part, part_slabs_on_world=False)
    dist = Disturbances(part_offset_m=0.08, part_rotation_rad=0.15, seed=4)
    new, old = (execute(c, case.traj, mode="kinematic", disturbances=dist)
                for c in (new_cell, old_cell))
    _same_contacts(new, old)
    nominal = execute(new_cell, case.traj, mode="kinematic")
    # ... and those are not the nominal part's contacts (the displacement moved them).
    depth = {(c.body1, round(c.time_s, 6)): c.depth_m for c in nominal.contacts}
    moved = [abs(c.depth_m - depth.get((c.body1, round(c.time_s, 6)), 0.0)) for c in new.contacts]
    assert max(moved) > 0.01
    # The world body's tree still bounds every moved slab (MuJoCo's midphase reaches them all).
    from paintcell.execution.execute import disturbed_model

    model, _, _ = disturbed_model(new_cell, dist)
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    root = model.bvh_aabb[model.body_bvhadr[0]]
    for g in range(model.body_geomnum[0]):
        corners = d.geom_xpos[g] + (np.array(np.meshgrid(*[[-1, 1]] * 3)).reshape(3, -1).T
                                    * model.geom_aabb[g, 3:] + model.geom_aabb[g, :3]) \
            @ d.geom_xmat[g].reshape(3, 3).T
        assert np.all(np.abs(corners - root[:3]) <= root[3:] + 1e-12)
