"""Rolling a program out in MuJoCo: the digital servo (each step's torque from the state measured
latency steps before), the settling hold after it, and the kinematic replay; states and sensors at
every 1 ms step. The steps run in the compiled loops of `paintcell.execution.execute_compiled`
(MuJoCo's `mj_step`, no Python per step); without them the servo runs as exact `mujoco.rollout`
chunks of latency + 1 steps and the replay as a Python loop (same results).

Times [s], joint positions [rad], torques [N·m], TCP distances [m].
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np
from mujoco import rollout

from paintcell.execution.cell import Cell
from paintcell.execution.execute_compiled import (
    MujocoC,
    kinematic_steps,
    mujoco_c,
    servo_steps,
)

#: steps per rollout call; the progress callback is called after each (≈ 0.1 s wall).
CHUNK_STEPS = 10_000
#: the arm has settled when its TCP stays within this distance of the final reference [m].
SETTLE_TOL_M = 1e-4
#: hold the final reference at most this long after the program to measure settling [s].
SETTLE_MAX_S = 0.5


def _warnings(d: mujoco.MjData) -> dict[str, int]:
    names = [w for w in mujoco.mjtWarning.__members__ if w != "mjNWARNING"]
    return {w: int(d.warning[int(mujoco.mjtWarning.__members__[w])].number) for w in names
            if d.warning[int(mujoco.mjtWarning.__members__[w])].number > 0}


def run_servo(model: mujoco.MjModel, cell: Cell, q_ref: np.ndarray, qd_ref: np.ndarray,
              tau_ff: np.ndarray, kp: np.ndarray, kd: np.ndarray, latency: int,
              progress: Callable[[float], None] | None,
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, int], float]:
    """Roll the program out, then hold its last reference for SETTLE_MAX_S; (q, q̇, sensordata
    per step of the program and the hold (K + H rows), joint torque demanded before the clamp
    per program step (K, n) [N·m], warnings, settling time [s]). `model` has torque actuators
    (`_set_torque_actuators`).

    A digital servo: the torque held over step k is computed from the state sampled at t_{k−d}
    (d = latency). So the controls of d + 1 consecutive steps depend only on states already
    known, and rollouts of d + 1 steps are exact: each chunk's controls come from states the
    previous chunks produced (before t0 the arm rests at q_ref[0]).
    """
    K, n = q_ref.shape
    H = int(round(SETTLE_MAX_S / model.opt.timestep))
    g = model.actuator_gear[cell.actuator_ids, 0]
    # The program, then the final reference held (last feed-forward, zero velocity).
    q_r = np.vstack([q_ref, np.tile(q_ref[-1], (H, 1))])
    qd_r = np.vstack([qd_ref, np.zeros((H, n))])
    ff = np.vstack([tau_ff, np.tile(tau_ff[-1], (H, 1))])
    N = K + H
    d = mujoco.MjData(model)
    d.qpos[cell.qpos_adr] = q_ref[0]
    d.qvel[cell.dof_adr] = qd_ref[0]
    mujoco.mj_forward(model, d)
    lag = max(latency, 0)
    act = cell.actuator_ids
    # Reference of the same instant as the (delayed) measurement; feed-forward on time.
    q_del = np.vstack([np.tile(q_r[0], (lag, 1)), q_r[:N - lag]])
    qd_del = np.vstack([np.tile(qd_r[0], (lag, 1)), qd_r[:N - lag]])
    base = np.zeros((N, model.nu))
    base[:, act] = (ff + kp * q_del + kd * qd_del) / g
    sens = np.empty((N, model.nsensordata))
    ctrl = np.zeros((N, model.nu))
    c = mujoco_c()
    if c is not None:
        q, qd = _servo_compiled(c, model, d, cell, base, kp / g, kd / g, lag, N, K, sens, ctrl,
                                progress)
    else:
        q, qd = _servo_rollout(model, d, cell, base, kp / g, kd / g, lag, N, K, sens, ctrl,
                               progress)
    # The servo law's torque before the actuator clamp (ctrl is in actuator units: × gear).
    tau_demand = ctrl[:K, act] * g
    warnings = _warnings(d)
    settle = _settle_time(model, cell, sens[K:], q_ref[-1])
    return (np.ascontiguousarray(q), np.ascontiguousarray(qd), sens, tau_demand, warnings,
            settle)


def _servo_compiled(c: MujocoC, model: mujoco.MjModel, d: mujoco.MjData, cell: Cell,
                    base: np.ndarray, kp_g: np.ndarray, kd_g: np.ndarray, lag: int, N: int,
                    K: int, sens: np.ndarray, ctrl: np.ndarray,
                    progress: Callable[[float], None] | None) -> tuple[np.ndarray, np.ndarray]:
    """The servo's N steps in the compiled loop (`execute_compiled.servo_steps`), CHUNK_STEPS
    a call; (q, q̇) (N, n) at t_0 … t_{N−1}; `sens`, `ctrl` filled."""
    n = len(cell.qpos_adr)
    q_meas, qd_meas = np.empty((N + 1, n)), np.empty((N + 1, n))
    q_meas[0], qd_meas[0] = d.qpos[cell.qpos_adr], d.qvel[cell.dof_adr]
    for a in range(0, N, CHUNK_STEPS):
        b = min(a + CHUNK_STEPS, N)
        servo_steps(c, model, d, cell.qpos_adr, cell.dof_adr, cell.actuator_ids, base, kp_g,
                    kd_g, lag, a, b, q_meas, qd_meas, sens, ctrl)
        if progress is not None and b < K:
            progress(b / K)
    if progress is not None:
        progress(1.0)
    return q_meas[:N], qd_meas[:N]


def _servo_rollout(model: mujoco.MjModel, d: mujoco.MjData, cell: Cell, base: np.ndarray,
                   kp_g: np.ndarray, kd_g: np.ndarray, lag: int, N: int, K: int,
                   sens: np.ndarray, ctrl: np.ndarray,
                   progress: Callable[[float], None] | None) -> tuple[np.ndarray, np.ndarray]:
    """The same N steps through `mujoco.rollout` in exact chunks of lag + 1 steps (each chunk's
    controls from states the previous chunks produced): the path without the compiled loop."""
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    nstate = mujoco.mj_stateSize(model, spec)
    # S[lag + k] is the state at t_k; the first lag rows stand for the rest before t0.
    S = np.empty((lag + N + 1, nstate))
    mujoco.mj_getState(model, d, S[0], spec)
    S[:lag + 1] = S[0]
    act = cell.actuator_ids
    # ctrl[k] = base[k] − S[k] @ W: the measured state of t_{k−lag} times the gains, one product.
    W = np.zeros((nstate, model.nu))
    W[1 + cell.qpos_adr, act] = kp_g
    W[1 + model.nq + cell.dof_adr, act] = kd_g
    step = lag + 1
    # Measured joint state columns of the full-physics state (time, qpos, qvel, ...).
    iq = 1 + cell.qpos_adr
    iv = 1 + model.nq + cell.dof_adr
    fb = np.empty((step, model.nu))
    runner = rollout.Rollout(nthread=0)
    models, datas = [model], [d]
    warm = d.qacc_warmstart.reshape(1, -1)
    next_report, reported = CHUNK_STEPS, 0.0
    try:
        for a in range(0, N, step):
            b = min(a + step, N)
            np.matmul(S[a:b], W, out=fb[:b - a])
            np.subtract(base[a:b], fb[:b - a], out=ctrl[a:b])
            # With nthread=0 the rollout steps `d` itself, so d.qacc_warmstart carries over.
            runner.rollout(models, datas, S[None, lag + a], ctrl[None, a:b], skip_checks=True,
                           nstep=b - a, initial_warmstart=warm,
                           state=S[None, lag + a + 1:lag + b + 1], sensordata=sens[None, a:b],
                           chunk_size=1)
            if progress is not None and b >= next_report and b < K:
                reported = b / K
                progress(reported)
                next_report += CHUNK_STEPS
    finally:
        runner.close()
    if progress is not None and reported < 1.0:
        progress(1.0)
    # Sensors of step k are evaluated before it integrates: they belong to the state at t_k.
    return S[lag:lag + N, iq], S[lag:lag + N, iv]


def _settle_time(model: mujoco.MjModel, cell: Cell, sens_hold: np.ndarray,
                 q_end: np.ndarray) -> float:
    """Time after the program until the TCP stays within SETTLE_TOL_M of where the final
    reference puts it [s] (SETTLE_MAX_S when it never settles). sens_hold: (H, nsensordata)."""
    d = mujoco.MjData(model)
    d.qpos[cell.qpos_adr] = q_end
    mujoco.mj_kinematics(model, d)
    p_tcp_end = d.site_xpos[cell.tcp_site_id].copy()
    err = np.linalg.norm(sens_hold[:, cell.sensor_tcp_pos] - p_tcp_end, axis=1)
    outside = np.flatnonzero(err > SETTLE_TOL_M)
    if len(outside) == 0:
        return 0.0
    if outside[-1] == len(err) - 1:
        return SETTLE_MAX_S
    return float((outside[-1] + 1) * model.opt.timestep)


def run_kinematic(model: mujoco.MjModel, cell: Cell, q_ref: np.ndarray, qd_ref: np.ndarray,
                  progress: Callable[[float], None] | None,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
    """Play the reference (K, n) joint positions and velocities straight into the model (no
    dynamics): (q, qd, sensor data, per-step counters) as `run_servo` returns them."""
    K, _ = q_ref.shape
    d = mujoco.MjData(model)
    sens = np.empty((K, model.nsensordata))
    c = mujoco_c()
    if c is not None:
        q, qd = np.ascontiguousarray(q_ref, float), np.ascontiguousarray(qd_ref, float)
        for a in range(0, K, CHUNK_STEPS):
            b = min(a + CHUNK_STEPS, K)
            kinematic_steps(c, model, d, cell.qpos_adr, cell.dof_adr, q, qd, a, b, sens)
            if progress is not None and b < K:
                progress(b / K)
    else:
        qa, da = cell.qpos_adr, cell.dof_adr
        qpos, qvel, sdata = d.qpos, d.qvel, d.sensordata
        fwd_pos, sens_pos = mujoco.mj_fwdPosition, mujoco.mj_sensorPos
        for k in range(K):
            qpos[qa] = q_ref[k]
            qvel[da] = qd_ref[k]
            fwd_pos(model, d)
            sens_pos(model, d)
            sens[k] = sdata
            if progress is not None and (k + 1) % CHUNK_STEPS == 0:
                progress((k + 1) / K)
    if progress is not None:
        progress(1.0)
    return q_ref.copy(), qd_ref.copy(), sens, _warnings(d)
