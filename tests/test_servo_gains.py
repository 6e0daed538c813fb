"""The servo's bandwidth rule with the joints' effective inertia (ServoSettings.gain_inertia):
the J of each joint is what a unit torque on it accelerates with the other joints free, measured
by MuJoCo's forward dynamics — not by inverting the mass matrix as the code does."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from paintcell.execution.cell import build_cell
from paintcell.execution.execute import ExecutionError, ServoSettings
from paintcell.robots.rail import load_rail_robot
from paintcell.surface import parts


def test_effective_inertia_gains_are_what_a_unit_torque_accelerates():
    robot = load_rail_robot("irb5500")
    T = np.eye(4)
    T[:3, 3] = [2.5, 0.0, -3.0]
    cell = build_cell(robot, parts.get_part("panel", resolution_m=0.1), T)
    m = cell.model
    w = 2 * math.pi * 15.0
    kp, kd = ServoSettings(gain_inertia="effective").gains(cell)
    kp0, _ = ServoSettings().gains(cell)
    d = mujoco.MjData(m)
    m.opt.gravity[:] = 0.0
    for j, dof in enumerate(cell.dof_adr):
        d.qpos[:] = 0.0
        d.qpos[cell.qpos_adr] = cell.q_home
        d.qvel[:] = 0.0
        d.qfrc_applied[:] = 0.0
        d.qfrc_applied[dof] = 1.0                     # 1 N·m (1 N on the rail), the rest free
        mujoco.mj_forward(m, d)
        assert kp[j] == pytest.approx(w * w / d.qacc[dof], rel=1e-9)
        assert kd[j] == pytest.approx(2 * w / d.qacc[dof], rel=1e-9)
    # the other joints free lighten every coupled joint: J3 notably (the ringing of its loop)
    assert np.all(kp <= kp0 * (1 + 1e-12)) and kp[3] < 0.8 * kp0[3]
    with pytest.raises(ExecutionError, match="gain_inertia"):
        ServoSettings(gain_inertia="full")
