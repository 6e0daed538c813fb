"""The MuJoCo models an execution runs on: the disturbed plant, its actuators, the controller's
perturbed copy, and discrete-time inverse dynamics for the feed-forward.

Torques [N·m], gains [N·m/rad] and [N·m·s/rad], joint positions [rad], lengths [m].
"""

from __future__ import annotations

import copy
import functools
import os
from concurrent.futures import ThreadPoolExecutor

import mujoco
import numpy as np

from paintcell.execution.cell import Cell
from paintcell.execution.cell_part import move_part_collision
from paintcell.execution.execute_compiled import MujocoC, inverse_dynamics_steps, mujoco_c
from paintcell.execution.execute_settings import Disturbances, ServoSettings

#: programs at least this long (samples) get their feed-forward on two threads.
SPLIT_MIN_SAMPLES = 2000


def disturbed_model(cell: Cell, dist: Disturbances | None) -> tuple[mujoco.MjModel, np.ndarray,
                                                                       np.ndarray]:
    """Model copy with the part moved and the TCP site offset; T_world_part actually used."""
    model = copy.copy(cell.model)
    T_actual = cell.T_world_part.copy()
    tcp_offset = np.zeros(3)
    if dist is not None:
        T_err, tcp_offset = dist.realize()
        T_actual = cell.T_world_part @ T_err
        q = np.zeros(4)
        mujoco.mju_mat2Quat(q, np.ascontiguousarray(T_actual[:3, :3]).ravel())
        model.body_pos[cell.part_body_id] = T_actual[:3, 3]
        model.body_quat[cell.part_body_id] = q
        if cell.part_collision_body_id != cell.part_body_id:  # the slabs sit on the world body
            move_part_collision(model, cell.part_collision_body_id,
                                T_actual @ np.linalg.inv(cell.T_world_part))
        R_body_site = np.zeros(9)
        mujoco.mju_quat2Mat(R_body_site, model.site_quat[cell.tcp_site_id])
        model.site_pos[cell.tcp_site_id] += R_body_site.reshape(3, 3) @ tcp_offset
    return model, T_actual, tcp_offset


def set_pd_actuators(model: mujoco.MjModel, cell: Cell, kp: np.ndarray, kd: np.ndarray) -> None:
    """Actuator force = ctrl − (Kp q + Kd q̇)/g², clamped to ±τ_max/g (g: gear)."""
    a = cell.actuator_ids
    g = model.actuator_gear[a, 0]
    model.actuator_gaintype[a] = mujoco.mjtGain.mjGAIN_FIXED
    model.actuator_gainprm[a, :] = 0.0
    model.actuator_gainprm[a, 0] = 1.0
    model.actuator_biastype[a] = mujoco.mjtBias.mjBIAS_AFFINE
    model.actuator_biasprm[a, :] = 0.0
    model.actuator_biasprm[a, 1] = -kp / g**2
    model.actuator_biasprm[a, 2] = -kd / g**2
    model.actuator_ctrllimited[a] = 0
    model.actuator_forcelimited[a] = 1
    model.actuator_forcerange[a, 0] = -cell.tau_max / np.abs(g)
    model.actuator_forcerange[a, 1] = cell.tau_max / np.abs(g)


def set_torque_actuators(model: mujoco.MjModel, cell: Cell) -> None:
    """Actuator force = ctrl (the whole servo law computed per step), clamped to ±τ_max/g."""
    set_pd_actuators(model, cell, np.zeros(cell.nq), np.zeros(cell.nq))


def joint_friction_nm(cell: Cell, servo: ServoSettings) -> np.ndarray:
    """(n,) joint Coulomb friction of the plant [N·m]."""
    return servo.coulomb_friction * np.asarray(cell.tau_max, float)


def controller_model(model: mujoco.MjModel, cell: Cell, servo: ServoSettings) -> mujoco.MjModel:
    """The controller's idea of the plant `model`: link masses and inertias scaled by seeded
    factors in [1 − model_error, 1 + model_error], the tool body by (1 − payload_error)."""
    m = copy.copy(model)
    tool = int(model.site_bodyid[cell.tcp_site_id])
    links = [int(b) for b in np.sort(cell.robot_body_ids) if model.body_mass[b] > 0 and b != tool]
    rng = np.random.default_rng(servo.seed)
    scale = 1.0 + servo.model_error * rng.uniform(-1.0, 1.0, size=len(links))
    for b, f in zip(links, scale, strict=True):
        m.body_mass[b] *= f
        m.body_inertia[b] *= f
    m.body_mass[tool] *= 1.0 - servo.payload_error
    m.body_inertia[tool] *= 1.0 - servo.payload_error
    return m


def inverse_dynamics(model: mujoco.MjModel, cell: Cell, q: np.ndarray, qd: np.ndarray,
                     qdd: np.ndarray) -> np.ndarray:
    """(K, n) joint torques [N·m] that make the model follow (q, q̇, q̈) (K, n) exactly.

    Discrete-time inverse dynamics (`mjENBL_INVDISCRETE`, so it matches the implicitfast step,
    actuator damping included) with contacts and joint limits off (the reference's own needs).
    """
    m = copy.copy(model)
    # No constraints, no collision detection, no sensors: only the arm's own dynamics.
    m.opt.disableflags |= (mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
                           | mujoco.mjtDisableBit.mjDSBL_CONTACT
                           | mujoco.mjtDisableBit.mjDSBL_SENSOR)
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_INVDISCRETE
    if m.ntendon == 0:
        # Nothing here reads a geom's pose (no collisions, no sensors, no tendon wrapping around
        # geoms): with no geoms listed per body, MuJoCo's kinematics skips the 89 part geoms' and
        # the links' pose updates every sample (1-1.5 µs of ~5); the torques are bit for bit the
        # same (tests/test_execute_compiled.py compares them with the full model's).
        m.body_geomnum[:] = 0
    c = mujoco_c()
    if c is not None:  # the same mj_inverse calls, looped in compiled code
        return _inverse_compiled(c, m, cell, q, qd, qdd)
    d = mujoco.MjData(m)
    qa, da = cell.qpos_adr, cell.dof_adr
    out = np.empty_like(q)
    inv = mujoco.mj_inverse
    qpos, qvel, qacc, qfrc = d.qpos, d.qvel, d.qacc, d.qfrc_inverse
    for k in range(len(q)):
        qpos[qa] = q[k]
        qvel[da] = qd[k]
        qacc[da] = qdd[k]
        inv(m, d)
        out[k] = qfrc[da]
    return out


def _inverse_compiled(c: MujocoC, m: mujoco.MjModel, cell: Cell, q: np.ndarray,
                      qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """`inverse_dynamics`'s samples in the compiled loop; a long program in two halves on two
    threads, each with its own MjData (the loop releases the GIL). With constraints and contacts
    off a sample's torque depends only on its own (q, q̇, q̈), so the halves give the very torques
    of one pass (tests/test_execute_compiled.py compares them bit for bit with a per-sample
    loop); the second core is otherwise idle while the servo waits for its feed-forward."""
    k = len(q)
    halves = [(0, k)] if k < SPLIT_MIN_SAMPLES or _cores() < 2 else [(0, k // 2), (k // 2, k)]

    def run(a: int, b: int) -> np.ndarray:
        return inverse_dynamics_steps(c, m, mujoco.MjData(m), cell.qpos_adr, cell.dof_adr,
                                      q[a:b], qd[a:b], qdd[a:b])

    if len(halves) == 1:
        return run(0, k)
    with ThreadPoolExecutor(max_workers=1) as pool:
        second = pool.submit(run, *halves[1])
        first = run(*halves[0])
        return np.concatenate([first, second.result()])


@functools.lru_cache(maxsize=1)
def _cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def joint_range(model: mujoco.MjModel, cell: Cell) -> tuple[np.ndarray, np.ndarray]:
    """(q_lower, q_upper) (n,) [rad] of the robot joints; nan where a joint is unlimited."""
    j = model.dof_jntid[cell.dof_adr]
    limited = model.jnt_limited[j].astype(bool)
    lo = np.where(limited, model.jnt_range[j, 0], np.nan)
    hi = np.where(limited, model.jnt_range[j, 1], np.nan)
    return lo, hi
