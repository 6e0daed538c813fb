"""Run a `JointTrajectory` on the MuJoCo cell: a realistic servo, or an ideal kinematic replay.

Servo mode (1 kHz digital servo, one control update per physics step, d = latency_steps):

    τ_k = clip( τ_ff,k + Kp (q_ref,k−d − q_k−d) + Kd (q̇_ref,k−d − q̇_k−d),  ±τ_max )

held over step k. The PD acts on the state measured d control periods earlier (drive-bus and
computation latency), compared with the reference of that same instant. τ_ff is MuJoCo's inverse
dynamics (`mj_inverse`, discrete-time, constraints off) of the reference on the *controller's*
model — a copy of the plant whose link masses/inertias are off by a seeded `model_error` and
whose tool is `payload_error` too light — plus the compensated shares of the viscous
(`friction_compensation`) and Coulomb (`coulomb_compensation`) joint friction. The plant is the
robot MJCF with joint Coulomb friction added (`frictionloss`, `coulomb_friction` × τ_max).
`ServoSettings.ideal()` switches every imperfection off.

The torque of step k needs states up to t_{k−d} only. The program is stepped with `mj_step` in a
compiled loop that computes each step's torque from the state measured d steps before
(`paintcell.execution.execute_compiled`); without it, in exact `mujoco.rollout` chunks of
d + 1 steps, each chunk's controls from the states the previous chunks produced. TCP pose,
joint torques and robot-vs-part/booth and robot-vs-robot (self-collision) contacts come from
sensors at every step; steps where a contact sensor fires are re-evaluated to name the bodies and
the depth. After the program the last reference is held for SETTLE_MAX_S in the same loop to
measure settling; contacts during that hold are recorded too (times past the program's end).

The trace keeps both the applied joint torque (`tau`, after the ±τ_max clamp, so never above the
limit) and the torque the servo law demanded before the clamp (`tau_demand`): |τ_demand| / τ_max
is the torque utilization (above 1 where the actuator saturated).

Kinematic mode sets q, q̇ to the reference each step (the control case); torques (applied and
demanded) are the exact inverse dynamics of the plant.

The settings (`paintcell.execution.execute_settings`), the models the program runs on
(`paintcell.execution.execute_models`),
the rollout itself (`paintcell.execution.execute_rollout`, its compiled loops in
`paintcell.execution.execute_compiled`) and the naming of contacts
(`paintcell.execution.execute_contacts`)
are modules of their own; every public name is importable from here.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, Literal

import numpy as np

from paintcell.core.transforms import matrix_from_quat_wxyz
from paintcell.execution.cell import Cell
from paintcell.execution.execute_contacts import named_contacts
from paintcell.execution.execute_models import (
    controller_model,
    disturbed_model,
    inverse_dynamics,
    joint_friction_nm,
    joint_range,
    set_pd_actuators,
    set_torque_actuators,
)
from paintcell.execution.execute_rollout import (
    CHUNK_STEPS,
    SETTLE_MAX_S,
    SETTLE_TOL_M,
    run_kinematic,
    run_servo,
)
from paintcell.execution.execute_settings import Disturbances, ExecutionError, ServoSettings
from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.joint_trajectory import JointTrajectory

__all__ = [
    "CHUNK_STEPS", "FRICTION_SMOOTH_RAD_S", "SETTLE_MAX_S", "SETTLE_TOL_M", "Disturbances",
    "ExecutionError", "ServoSettings", "execute", "inverse_dynamics",
]

#: velocity scale of the smoothed sign in the Coulomb-friction feed-forward [rad/s]: below it the
#: compensation fades out, as controllers do to avoid chattering at velocity reversals (estimate).
FRICTION_SMOOTH_RAD_S = 0.01
#: MuJoCo warnings that mean the simulation is not trustworthy (instability, bad input).
_FATAL_WARNINGS = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC", "mjWARN_BADCTRL")


def _check_inputs(cell: Cell, traj: JointTrajectory) -> None:
    if tuple(traj.joint_names) != tuple(cell.joint_names):
        raise ExecutionError(f"trajectory joints {traj.joint_names} differ from the cell's "
                             f"{cell.joint_names}; build the trajectory for this robot")
    if len(traj.t_s) < 2:
        raise ExecutionError("trajectory has fewer than 2 samples; nothing to execute")
    dt = np.diff(traj.t_s)
    h = cell.model.opt.timestep
    if not np.allclose(dt, h, rtol=1e-6, atol=1e-9):
        raise ExecutionError(f"trajectory step is {dt.mean():.6g} s but the cell runs at {h} s; "
                             "resample the trajectory at the control rate (1 kHz)")
    for name in ("q", "qd", "qdd"):
        if not np.all(np.isfinite(getattr(traj, name))):
            raise ExecutionError(f"trajectory {name} contains NaN or inf; rebuild it")


def execute(cell: Cell, traj: JointTrajectory, mode: Literal["servo", "kinematic"] = "servo",
            servo: ServoSettings | None = None, disturbances: Disturbances | None = None,
            progress: Callable[[float], None] | None = None,
            cache: dict[Any, np.ndarray] | None = None) -> ExecutedTrace:
    """Execute `traj` on `cell` and record what happened at every 1 ms step.

    mode: "servo" (PD + inverse-dynamics feed-forward, torque limits; see module doc) or
        "kinematic" (the reference itself, the control case).
    servo: gains (default `ServoSettings()`); disturbances: seeded placement/TCP/gain errors.
    progress: called with the completed fraction in [0, 1] after each chunk.
    cache: a dict the caller keeps across calls with the same cell and trajectory (a sweep): the
        inverse-dynamics feed-forward, which no disturbance changes (they move the part and the
        TCP site, not the arm's links), is computed once per servo setting and kept there.
    Returns an `ExecutedTrace` (world frame) whose `meta` holds the settings, the realized
    disturbances (`T_world_part_actual`, `tcp_offset_tool_m`), wall time and MuJoCo warnings.
    Raises ExecutionError for mismatched inputs or an unstable simulation.
    """
    if mode not in ("servo", "kinematic"):
        raise ExecutionError(f"mode must be 'servo' or 'kinematic', got {mode!r}")
    _check_inputs(cell, traj)
    servo = servo or ServoSettings()
    t0 = time.perf_counter()
    model, T_actual, tcp_offset = disturbed_model(cell, disturbances)
    kp, kd = servo.gains(cell)
    if disturbances is not None:
        kp, kd = kp * disturbances.gain_scale, kd * disturbances.gain_scale
    q_ref, qd_ref = np.asarray(traj.q, float), np.asarray(traj.qd, float)
    qdd_ref = np.asarray(traj.qdd, float)
    if mode == "servo":
        # The plant: the robot MJCF plus joint Coulomb friction; the controller's feed-forward
        # model: a perturbed copy of it (model_error, payload_error), friction partly known.
        fc = joint_friction_nm(cell, servo)
        model.dof_frictionloss[cell.dof_adr] = fc
        set_torque_actuators(model, cell)
        key = ("servo-id", repr(servo))
        tau_id = None if cache is None else cache.get(key)
        if tau_id is None or tau_id.shape != q_ref.shape:
            tau_id = inverse_dynamics(controller_model(model, cell, servo), cell, q_ref, qd_ref,
                                      qdd_ref)
            if cache is not None:
                cache[key] = tau_id
        damping = model.dof_damping[cell.dof_adr]
        tau_ff = (tau_id - (1.0 - servo.friction_compensation) * damping * qd_ref
                  + servo.coulomb_compensation * fc * np.tanh(qd_ref / FRICTION_SMOOTH_RAD_S)
                  if servo.feedforward else np.zeros_like(q_ref))
        q_all, qd_all, sens_all, tau_demand, warnings, settle_s = run_servo(
            model, cell, q_ref, qd_ref, tau_ff, kp, kd, int(servo.latency_steps), progress)
        K = len(q_ref)
        q, qd, sens = q_all[:K], qd_all[:K], sens_all[:K]
        tau = sens[:, cell.sensor_actuator_force]
        # Contacts of the program and of the settling hold after it (times past the end).
        t_all = traj.t_s[0] + np.arange(len(q_all)) * cell.model.opt.timestep
        contacts = named_contacts(model, cell, q_all, sens_all, t_all)
    else:
        set_pd_actuators(model, cell, kp, kd)
        tau_id = inverse_dynamics(model, cell, q_ref, qd_ref, qdd_ref)
        q, qd, sens, warnings = run_kinematic(model, cell, q_ref, qd_ref, progress)
        tau = tau_id  # the torque the motors would need to follow the reference exactly
        tau_demand = tau_id
        settle_s = 0.0
        contacts = named_contacts(model, cell, q, sens, traj.t_s)
    wall = time.perf_counter() - t0
    fatal = {k: v for k, v in warnings.items() if k in _FATAL_WARNINGS}
    if fatal or not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))
                     and np.all(np.isfinite(tau_demand))):
        raise ExecutionError(f"MuJoCo went unstable ({fatal or 'NaN state'}); lower the servo "
                             "gains or check the trajectory's accelerations")
    sd = sens[:, cell.sensor_tcp_quat]
    meta = {
        "servo": servo.to_dict(), "kp": kp.tolist(), "kd": kd.tolist(),
        "disturbances": None if disturbances is None else disturbances.to_dict(),
        "T_world_part_planned": cell.T_world_part.tolist(),
        "T_world_part_actual": T_actual.tolist(),
        "flow_scale": 1.0 if disturbances is None else disturbances.flow_scale,
        "flow_drift": 0.0 if disturbances is None else disturbances.flow_drift,
        "tcp_offset_tool_m": tcp_offset.tolist(),
        "mujoco_warnings": warnings, "wall_time_s": wall,
        "settle_time_s": settle_s, "settle_tol_m": SETTLE_TOL_M,
        "settled": bool(settle_s < SETTLE_MAX_S),
        "realtime_factor": float((traj.t_s[-1] - traj.t_s[0] + cell.model.opt.timestep) / wall),
        "robot_name": cell.robot_name, "joint_names": list(cell.joint_names),
        "tau_max": cell.tau_max.tolist(),
        "q_lower": joint_range(model, cell)[0].tolist(),
        "q_upper": joint_range(model, cell)[1].tolist(),
    }
    return ExecutedTrace(
        t_s=np.asarray(traj.t_s, float).copy(), q=q, qd=qd, tau=np.ascontiguousarray(tau),
        tcp_pos_world=np.ascontiguousarray(sens[:, cell.sensor_tcp_pos]),
        tcp_rot_world=matrix_from_quat_wxyz(sd / np.linalg.norm(sd, axis=1, keepdims=True)),
        paint_on=(np.asarray(traj.paint_on, bool).copy() if disturbances is None
                  else disturbances.paint_on(traj.paint_on, cell.model.opt.timestep)),
        pass_index=np.asarray(traj.pass_index).copy(), mode=mode, contacts=contacts, meta=meta,
        tau_demand=np.ascontiguousarray(tau_demand))
