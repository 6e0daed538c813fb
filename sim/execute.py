"""Run a `JointTrajectory` on the MuJoCo cell: a realistic servo, or an ideal kinematic replay.

Servo mode (1 kHz, one control update per physics step):

    τ = clip( τ_ff(q_ref, q̇_ref, q̈_ref) + Kp (q_ref − q) + Kd (q̇_ref − q̇),  ±τ_max )

τ_ff is MuJoCo's inverse dynamics (`mj_inverse`, discrete-time, constraints off) of the reference
state on the same model, so armature, joint damping and gravity are exactly the robot MJCF's.
Because τ_ff, q_ref and q̇_ref are known before the run, the PD law is written into each joint's
actuator as an affine force (gain 1, bias −Kp·q − Kd·q̇, force range ±τ_max) and the whole program
is rolled out inside MuJoCo (`mujoco.rollout`) — the feedback is still evaluated by MuJoCo at every
step from the current state; implicitfast integrates the Kd term implicitly, like a velocity loop
running faster than the position loop. TCP pose, joint torques and robot-vs-part/booth contacts
come from sensors at every step; steps where a contact sensor fires are re-evaluated to name the
bodies and the depth.

Kinematic mode sets q, q̇ to the reference each step (the control case); torques are τ_ff.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any, Literal

import mujoco
import numpy as np
from mujoco import rollout

from planning.errors import PaintcellError
from sim.cell import Cell
from sim.joint_trajectory import JointTrajectory
from sim.trace import Contact, ExecutedTrace

#: steps per rollout call; the progress callback is called after each (≈ 0.1 s wall).
CHUNK_STEPS = 10_000
#: the arm has settled when its TCP stays within this distance of the final reference [m].
SETTLE_TOL_M = 1e-4
#: hold the final reference at most this long after the program to measure settling [s].
SETTLE_MAX_S = 0.5
#: MuJoCo warnings that mean the simulation is not trustworthy (instability, bad input).
_FATAL_WARNINGS = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC", "mjWARN_BADCTRL")


class ExecutionError(PaintcellError):
    """A trajectory cannot be executed on the cell, or the simulation went unstable."""


@dataclass(frozen=True)
class ServoSettings:
    """Joint PD + inverse-dynamics feed-forward servo.

    bandwidth_hz: position-loop natural frequency f; per joint Kp = J ω², Kd = 2 ζ J ω with
        ω = 2π f and J the joint's diagonal inertia (armature included) at the home pose. 15 Hz is
        typical of an industrial position loop (velocity loops run at 50–100 Hz).
    damping_ratio: ζ of that loop (1 = critically damped).
    kp, kd: explicit per-joint gains [N·m/rad], [N·m·s/rad]; override the bandwidth rule.
    gain_scale: multiplies Kp and Kd (0.1 = a 10× softer servo).
    feedforward: add the inverse-dynamics torque of the reference (False: PD only).
    friction_compensation: share of the viscous joint friction (the MJCF's joint damping) that
        the feed-forward model compensates; rigid-body dynamics and armature are compensated
        exactly. Gear friction is identified to within 20–30 % in practice, so 0.8 by default:
        the remainder is what the PD loop has to reject, and where a softer servo loses accuracy.
    """

    bandwidth_hz: float = 15.0
    damping_ratio: float = 1.0
    kp: tuple[float, ...] | None = None
    kd: tuple[float, ...] | None = None
    gain_scale: float = 1.0
    feedforward: bool = True
    friction_compensation: float = 0.8

    def __post_init__(self) -> None:
        if not 0.0 <= self.friction_compensation <= 1.0:
            raise ExecutionError("servo friction_compensation must be in [0, 1] (a fraction)")
        if not (self.bandwidth_hz > 0 and self.damping_ratio >= 0 and self.gain_scale > 0):
            raise ExecutionError("servo bandwidth_hz and gain_scale must be > 0, damping_ratio "
                                 ">= 0; fix ServoSettings")

    def gains(self, cell: Cell) -> tuple[np.ndarray, np.ndarray]:
        """(Kp (n,) [N·m/rad], Kd (n,) [N·m·s/rad]) for the cell's robot, `gain_scale` applied."""
        n = cell.nq
        if (self.kp is None) != (self.kd is None):
            raise ExecutionError("give both servo kp and kd, or neither (bandwidth rule)")
        if self.kp is not None and self.kd is not None:
            kp, kd = np.asarray(self.kp, float), np.asarray(self.kd, float)
            if kp.shape != (n,) or kd.shape != (n,) or np.any(kp < 0) or np.any(kd < 0):
                raise ExecutionError(f"servo kp/kd need {n} non-negative values each")
        else:
            d = mujoco.MjData(cell.model)
            d.qpos[cell.qpos_adr] = cell.q_home
            mujoco.mj_forward(cell.model, d)
            M = np.zeros((cell.model.nv, cell.model.nv))
            mujoco.mj_fullM(cell.model, d, M)
            J = M[cell.dof_adr, cell.dof_adr]
            w = 2 * np.pi * self.bandwidth_hz
            kp, kd = J * w * w, 2 * self.damping_ratio * J * w
        return kp * self.gain_scale, kd * self.gain_scale

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe settings."""
        return asdict(self)


@dataclass(frozen=True)
class Disturbances:
    """Seeded errors between the planned cell and the executed one.

    part_offset_m: part placement error, a translation of this length in a random direction [m].
    part_rotation_rad: part placement error, a rotation of this angle about a random axis through
        the part-frame origin [rad].
    tcp_offset_m: TCP calibration error, the real spray point is this far from the modelled one in
        a random tool-frame direction [m].
    gain_scale: multiplies the servo gains (controller tuning error), on top of the servo's own.
    seed: random generator seed (directions); the same seed gives the same disturbance.
    """

    part_offset_m: float = 0.0
    part_rotation_rad: float = 0.0
    tcp_offset_m: float = 0.0
    gain_scale: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        if min(self.part_offset_m, self.part_rotation_rad, self.tcp_offset_m) < 0:
            raise ExecutionError("disturbance magnitudes must be >= 0 [m, rad]")
        if self.gain_scale <= 0:
            raise ExecutionError("disturbance gain_scale must be > 0")

    def realize(self) -> tuple[np.ndarray, np.ndarray]:
        """(T_nominal_actual (4, 4) part placement error, tcp_offset_tool (3,) [m])."""
        rng = np.random.default_rng(self.seed)
        d1, d2, d3 = (_unit(rng.normal(size=3)) for _ in range(3))
        T = np.eye(4)
        T[:3, :3] = _axis_angle(d2, self.part_rotation_rad)
        T[:3, 3] = self.part_offset_m * d1
        return T, self.tcp_offset_m * d3

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe settings."""
        return asdict(self)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def _quat_to_mat(q: np.ndarray) -> np.ndarray:
    """(K, 4) unit quaternions (w, x, y, z) → (K, 3, 3) rotation matrices."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    R = np.empty((len(q), 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - w * z)
    R[:, 0, 2] = 2 * (x * z + w * y)
    R[:, 1, 0] = 2 * (x * y + w * z)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - w * x)
    R[:, 2, 0] = 2 * (x * z - w * y)
    R[:, 2, 1] = 2 * (y * z + w * x)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


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


def _disturbed_model(cell: Cell, dist: Disturbances | None) -> tuple[mujoco.MjModel, np.ndarray,
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
        R_body_site = np.zeros(9)
        mujoco.mju_quat2Mat(R_body_site, model.site_quat[cell.tcp_site_id])
        model.site_pos[cell.tcp_site_id] += R_body_site.reshape(3, 3) @ tcp_offset
    return model, T_actual, tcp_offset


def _set_pd_actuators(model: mujoco.MjModel, cell: Cell, kp: np.ndarray, kd: np.ndarray) -> None:
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


def execute(cell: Cell, traj: JointTrajectory, mode: Literal["servo", "kinematic"] = "servo",
            servo: ServoSettings | None = None, disturbances: Disturbances | None = None,
            progress: Callable[[float], None] | None = None) -> ExecutedTrace:
    """Execute `traj` on `cell` and record what happened at every 1 ms step.

    mode: "servo" (PD + inverse-dynamics feed-forward, torque limits; see module doc) or
        "kinematic" (the reference itself, the control case).
    servo: gains (default `ServoSettings()`); disturbances: seeded placement/TCP/gain errors.
    progress: called with the completed fraction in [0, 1] after each chunk.
    Returns an `ExecutedTrace` (world frame) whose `meta` holds the settings, the realized
    disturbances (`T_world_part_actual`, `tcp_offset_tool_m`), wall time and MuJoCo warnings.
    Raises ExecutionError for mismatched inputs or an unstable simulation.
    """
    if mode not in ("servo", "kinematic"):
        raise ExecutionError(f"mode must be 'servo' or 'kinematic', got {mode!r}")
    _check_inputs(cell, traj)
    servo = servo or ServoSettings()
    t0 = time.perf_counter()
    model, T_actual, tcp_offset = _disturbed_model(cell, disturbances)
    kp, kd = servo.gains(cell)
    if disturbances is not None:
        kp, kd = kp * disturbances.gain_scale, kd * disturbances.gain_scale
    _set_pd_actuators(model, cell, kp, kd)
    q_ref, qd_ref = np.asarray(traj.q, float), np.asarray(traj.qd, float)
    tau_id = inverse_dynamics(model, cell, q_ref, qd_ref, np.asarray(traj.qdd, float))
    # The controller's model: rigid body + armature exact, viscous friction partly (see settings).
    damping = model.dof_damping[cell.dof_adr]
    tau_ff = (tau_id - (1.0 - servo.friction_compensation) * damping * qd_ref
              if servo.feedforward else np.zeros_like(q_ref))
    if mode == "servo":
        q, qd, sens, warnings, settle_s = _run_servo(model, cell, q_ref, qd_ref, tau_ff, kp, kd,
                                                     progress)
        tau = sens[:, cell.sensor_actuator_force]
    else:
        q, qd, sens, warnings = _run_kinematic(model, cell, q_ref, qd_ref, progress)
        tau = tau_id  # the torque the motors would need to follow the reference exactly
        settle_s = 0.0
    contacts = _contacts(model, cell, q, sens, traj.t_s)
    wall = time.perf_counter() - t0
    fatal = {k: v for k, v in warnings.items() if k in _FATAL_WARNINGS}
    if fatal or not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
        raise ExecutionError(f"MuJoCo went unstable ({fatal or 'NaN state'}); lower the servo "
                             "gains or check the trajectory's accelerations")
    sd = sens[:, cell.sensor_tcp_quat]
    meta = {
        "servo": servo.to_dict(), "kp": kp.tolist(), "kd": kd.tolist(),
        "disturbances": None if disturbances is None else disturbances.to_dict(),
        "T_world_part_planned": cell.T_world_part.tolist(),
        "T_world_part_actual": T_actual.tolist(),
        "tcp_offset_tool_m": tcp_offset.tolist(),
        "mujoco_warnings": warnings, "wall_time_s": wall,
        "settle_time_s": settle_s, "settle_tol_m": SETTLE_TOL_M,
        "settled": bool(settle_s < SETTLE_MAX_S),
        "realtime_factor": float((traj.t_s[-1] - traj.t_s[0] + cell.model.opt.timestep) / wall),
        "robot_name": cell.robot_name, "joint_names": list(cell.joint_names),
        "tau_max": cell.tau_max.tolist(),
        "q_lower": _joint_range(model, cell)[0].tolist(),
        "q_upper": _joint_range(model, cell)[1].tolist(),
    }
    return ExecutedTrace(
        t_s=np.asarray(traj.t_s, float).copy(), q=q, qd=qd, tau=np.ascontiguousarray(tau),
        tcp_pos_world=np.ascontiguousarray(sens[:, cell.sensor_tcp_pos]),
        tcp_rot_world=_quat_to_mat(sd / np.linalg.norm(sd, axis=1, keepdims=True)),
        paint_on=np.asarray(traj.paint_on, bool).copy(),
        pass_index=np.asarray(traj.pass_index).copy(), mode=mode, contacts=contacts, meta=meta)


def _joint_range(model: mujoco.MjModel, cell: Cell) -> tuple[np.ndarray, np.ndarray]:
    """(q_lower, q_upper) (n,) [rad] of the robot joints; nan where a joint is unlimited."""
    j = model.dof_jntid[cell.dof_adr]
    limited = model.jnt_limited[j].astype(bool)
    lo = np.where(limited, model.jnt_range[j, 0], np.nan)
    hi = np.where(limited, model.jnt_range[j, 1], np.nan)
    return lo, hi


def _warnings(d: mujoco.MjData) -> dict[str, int]:
    names = [w for w in mujoco.mjtWarning.__members__ if w != "mjNWARNING"]
    return {w: int(d.warning[int(mujoco.mjtWarning.__members__[w])].number) for w in names
            if d.warning[int(mujoco.mjtWarning.__members__[w])].number > 0}


def _run_servo(model: mujoco.MjModel, cell: Cell, q_ref: np.ndarray, qd_ref: np.ndarray,
               tau_ff: np.ndarray, kp: np.ndarray, kd: np.ndarray,
               progress: Callable[[float], None] | None,
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int], float]:
    """Roll the program out; (q, q̇, sensordata per step, warnings, settling time [s])."""
    K, _ = q_ref.shape
    state_end = np.empty(0)
    g = model.actuator_gear[cell.actuator_ids, 0]
    # ctrl so that force = ctrl + bias = (τ_ff + Kp q_ref + Kd q̇_ref − Kp q − Kd q̇) / g.
    ctrl = np.zeros((K, model.nu))
    ctrl[:, cell.actuator_ids] = (tau_ff + kp * q_ref + kd * qd_ref) / g
    d = mujoco.MjData(model)
    d.qpos[cell.qpos_adr] = q_ref[0]
    d.qvel[cell.dof_adr] = qd_ref[0]
    mujoco.mj_forward(model, d)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    nstate = mujoco.mj_stateSize(model, spec)
    state0 = np.empty(nstate)
    mujoco.mj_getState(model, d, state0, spec)
    states = np.empty((K, nstate))
    sens = np.empty((K, model.nsensordata))
    states[0] = state0
    warm = d.qacc_warmstart.copy()
    for a in range(0, K, CHUNK_STEPS):
        b = min(a + CHUNK_STEPS, K)
        st, sd = rollout.rollout(model, d, states[a], ctrl[None, a:b], initial_warmstart=warm)
        # Sensors of step k are evaluated before it integrates: they belong to the state at t_k.
        sens[a:b] = sd[0]
        if b < K:
            states[a + 1:b + 1] = st[0]
        else:
            states[a + 1:b] = st[0, :-1]
            state_end = st[0, -1].copy()
        warm = d.qacc_warmstart.copy()
        if progress is not None:
            progress(b / K)
    q = states[:, 1:1 + model.nq][:, cell.qpos_adr]
    qd = states[:, 1 + model.nq:1 + model.nq + model.nv][:, cell.dof_adr]
    warnings = _warnings(d)
    settle = _settle_time(model, cell, state_end, ctrl[-1], q_ref[-1])
    return np.ascontiguousarray(q), np.ascontiguousarray(qd), sens, warnings, settle


def _settle_time(model: mujoco.MjModel, cell: Cell, state_end: np.ndarray, ctrl_end: np.ndarray,
                 q_end: np.ndarray) -> float:
    """Time after the program until the TCP stays within SETTLE_TOL_M of where the final
    reference puts it [s] (the last control held; SETTLE_MAX_S when it never settles)."""
    n = int(round(SETTLE_MAX_S / model.opt.timestep))
    d = mujoco.MjData(model)
    d.qpos[cell.qpos_adr] = q_end
    mujoco.mj_kinematics(model, d)
    p_tcp_end = d.site_xpos[cell.tcp_site_id].copy()
    _, sd = rollout.rollout(model, d, state_end, np.tile(ctrl_end, (1, n, 1)))
    err = np.linalg.norm(sd[0][:, cell.sensor_tcp_pos] - p_tcp_end, axis=1)
    outside = np.flatnonzero(err > SETTLE_TOL_M)
    if len(outside) == 0:
        return 0.0
    if outside[-1] == n - 1:
        return SETTLE_MAX_S
    return float((outside[-1] + 1) * model.opt.timestep)


def _run_kinematic(model: mujoco.MjModel, cell: Cell, q_ref: np.ndarray, qd_ref: np.ndarray,
                   progress: Callable[[float], None] | None,
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
    K, _ = q_ref.shape
    d = mujoco.MjData(model)
    sens = np.empty((K, model.nsensordata))
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


def _contacts(model: mujoco.MjModel, cell: Cell, q: np.ndarray, sens: np.ndarray,
              t_s: np.ndarray) -> tuple[Contact, ...]:
    """Name the bodies of every robot-vs-part/booth contact the sensors saw (deepest per pair)."""
    found = sens[:, cell.sensor_contact_part.start] > 0
    if cell.sensor_contact_booth.stop > cell.sensor_contact_booth.start:
        found |= sens[:, cell.sensor_contact_booth.start] > 0
    steps = np.flatnonzero(found)
    if len(steps) == 0:
        return ()
    d = mujoco.MjData(model)
    robot = np.zeros(model.nbody, bool)
    robot[cell.robot_body_ids] = True
    partners = np.array([cell.part_body_id, cell.booth_body_id])
    out: list[Contact] = []
    for k in steps:
        d.qpos[cell.qpos_adr] = q[k]
        mujoco.mj_fwdPosition(model, d)
        nc = d.ncon
        if nc == 0:
            continue
        bodies = model.geom_bodyid[d.contact.geom[:nc]]
        depth = -d.contact.dist[:nc]
        swap = robot[bodies[:, 1]] & ~robot[bodies[:, 0]]
        bodies[swap] = bodies[swap][:, ::-1]
        keep = robot[bodies[:, 0]] & np.isin(bodies[:, 1], partners)
        deepest: dict[tuple[int, int], float] = {}
        for (b1, b2), dep in zip(bodies[keep].tolist(), depth[keep].tolist(), strict=True):
            deepest[(b1, b2)] = max(deepest.get((b1, b2), 0.0), dep)
        for (b1, b2), depth in deepest.items():
            out.append(Contact(time_s=float(t_s[k]), body1=model.body(b1).name,
                               body2=model.body(b2).name, depth_m=depth))
    return tuple(out)
