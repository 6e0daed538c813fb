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

The module holds the settings (`ServoSettings`, `Disturbances`), the models the program runs on
(disturbed plant, controller copy, inverse dynamics), the rollout and the naming of contacts;
the compiled per-step loops are `paintcell.execution.execute_compiled`.
"""

from __future__ import annotations

import copy
import functools
import math
import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from typing import Any, Literal

import mujoco
import numpy as np
from mujoco import rollout

from paintcell.core.errors import PaintcellError
from paintcell.core.transforms import matrix_from_axis_angle, matrix_from_quat_wxyz
from paintcell.execution.cell import Cell
from paintcell.execution.cell_part import move_part_collision
from paintcell.execution.execute_compiled import (
    MujocoC,
    inverse_dynamics_steps,
    kinematic_steps,
    mujoco_c,
    servo_steps,
)
from paintcell.execution.trace import Contact, ExecutedTrace
from paintcell.motion.joint_trajectory import JointTrajectory

__all__ = [
    "CHUNK_STEPS", "FRICTION_SMOOTH_RAD_S", "SETTLE_MAX_S", "SETTLE_TOL_M", "Disturbances",
    "ExecutionError", "ServoSettings", "execute", "inverse_dynamics",
]


class ExecutionError(PaintcellError):
    """A trajectory cannot be executed on the cell, or the simulation went unstable."""


@dataclass(frozen=True)
class ServoSettings:
    """Joint PD + inverse-dynamics feed-forward servo, with the imperfections of a real one.

    bandwidth_hz: position-loop natural frequency f; per joint Kp = J ω², Kd = 2 ζ J ω with
        ω = 2π f and J the joint's diagonal inertia (armature included) at the home pose. 15 Hz is
        typical of an industrial position loop (velocity loops run at 50–100 Hz).
    damping_ratio: ζ of that loop (1 = critically damped).
    kp, kd: explicit per-joint gains [N·m/rad], [N·m·s/rad]; override the bandwidth rule.
    gain_scale: multiplies Kp and Kd (0.1 = a 10× softer servo).
    feedforward: add the inverse-dynamics torque of the reference (False: PD only).
    friction_compensation: share of the viscous joint friction (the MJCF's joint damping) that
        the feed-forward model compensates. Gear friction is identified to within 20–30 % in
        practice, so 0.8 by default: the remainder is what the PD loop has to reject.
    latency_steps: control periods (1 ms each) between sampling the joint encoders and the torque
        reaching the motors; the PD acts on the measured state this old, compared with the
        reference of the same instant (the controller delays its reference to match, as industrial
        controllers do, so latency costs phase margin and disturbance rejection, not a time
        shift). Default 2: one 1 ms drive-bus cycle (EtherCAT / SERCOS III run industrial drives
        at 1 kHz or faster) plus one cycle of controller computation — 1–2 ms is the usual
        encoder-to-torque latency of an industrial robot controller (estimate). 0: ideal (the
        state sampled at the start of the step). Latency eats phase margin: the 15 Hz, ζ = 1
        loop crosses over at ≈ 194 rad/s with 76° margin; 2 ms (+ half a step of hold) leave
        ≈ 48°, 4 ms ≈ 26° and the arm rings (tests/test_execute.py measures it).
    model_error: each robot link's mass and inertia in the controller's model is off by a
        seeded factor uniform in [1 − e, 1 + e]; the feed-forward is the inverse dynamics of that
        model while the plant is the robot MJCF. Default 0.05: CAD link masses leave out cables,
        grease and casting tolerances, and identified rigid-body parameters of industrial arms
        typically agree with the real arm to a few percent (estimate).
    payload_error: the controller's tool (the body carrying the TCP: the bell) is this fraction
        lighter than the real one, mass and inertia. Default 0.10: the load data of a bell come
        from its datasheet, while paint in the cup and the hose dress pack add ≈ 0.5–1 kg to a
        7 kg turbine bell (estimate).
    coulomb_friction: joint Coulomb friction in the plant (MuJoCo `frictionloss`) as a fraction
        of each joint's torque limit. Default 0.02: identified Coulomb friction of industrial
        gearboxes (RV / harmonic drives) is 1–5 % of the rated output torque (estimate from
        published friction identifications of industrial arms; the robot MJCF has none).
    coulomb_compensation: share of that Coulomb friction the feed-forward compensates (a smoothed
        sign of the reference velocity). Default 0.7: gear friction drifts ±30 % with temperature
        and load, so a model identified once compensates it only partly (estimate).
    seed: seeds the model-error draw; the same seed gives the same controller model.
    gain_inertia: the J of the bandwidth rule: "diagonal" (M_jj, the joint's inertia with the
        other joints held) or "effective" (1 / (M⁻¹)_jj, the inertia it moves with the other
        joints free, as a fast disturbance finds them). Measured on scenarios/roof_rail (IRB 5500
        on a rail, fast plan, 15 Hz, 2 ms latency): with "diagonal" J3's loop rings at ≈ 95 Hz in
        the turn-arounds — demanded torque 1.47× its limit, error 0.64 mrad peak — because J3's
        effective inertia is 0.74× its diagonal one (coupled to J2 and the rail), so its
        derivative loop crosses over ~1/0.74 higher than designed, where the latency leaves no
        phase; no latency, or half the Kd, removes it. With "effective": 0.44×, 0.13 mrad,
        0.043 mrad rms (10 Hz "diagonal": 0.43×, 0.21 mrad, 0.070 mrad rms).
    """

    bandwidth_hz: float = 15.0
    damping_ratio: float = 1.0
    kp: tuple[float, ...] | None = None
    kd: tuple[float, ...] | None = None
    gain_scale: float = 1.0
    feedforward: bool = True
    friction_compensation: float = 0.8
    latency_steps: int = 2
    model_error: float = 0.05
    payload_error: float = 0.10
    coulomb_friction: float = 0.02
    coulomb_compensation: float = 0.7
    seed: int = 0
    gain_inertia: str = "diagonal"

    def __post_init__(self) -> None:
        if self.gain_inertia not in ("diagonal", "effective"):
            raise ExecutionError(f"servo gain_inertia = {self.gain_inertia!r}: use 'diagonal' "
                                 "or 'effective'")
        for name in ("friction_compensation", "coulomb_compensation"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ExecutionError(f"servo {name} must be in [0, 1] (a fraction)")
        for name in ("model_error", "payload_error", "coulomb_friction"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ExecutionError(f"servo {name} must be in [0, 1) (a fraction)")
        if not (self.bandwidth_hz > 0 and self.damping_ratio >= 0 and self.gain_scale > 0):
            raise ExecutionError("servo bandwidth_hz and gain_scale must be > 0, damping_ratio "
                                 ">= 0; fix ServoSettings")
        lat = self.latency_steps
        if isinstance(lat, bool) or not isinstance(lat, int | np.integer) or not 0 <= lat <= 100:
            raise ExecutionError("servo latency_steps must be an int in [0, 100] (control "
                                 "periods)")
        object.__setattr__(self, "latency_steps", int(lat))  # JSON-safe in to_dict()

    @classmethod
    def ideal(cls, **kw: Any) -> ServoSettings:
        """The servo without imperfections: no latency, exact model, no Coulomb friction."""
        base: dict[str, Any] = dict(latency_steps=0, model_error=0.0, payload_error=0.0,
                                    coulomb_friction=0.0, friction_compensation=1.0)
        return cls(**{**base, **kw})

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
            Mr = M[np.ix_(cell.dof_adr, cell.dof_adr)]
            J = np.diag(Mr) if self.gain_inertia == "diagonal" \
                else 1.0 / np.diag(np.linalg.inv(Mr))
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
    standoff_error_m: actual − planned spray distance [m], signed (positive: the bell sprays from
        farther away): the real spray point sits this far behind the modelled one along the
        tool's spray axis (a TCP calibration error along z, or a bell mounted off its nominal).
    trigger_delay_s: the paint trigger switches this much later than programmed [s], signed
        (negative: early); applied in whole control periods (1 ms).
    flow_scale: actual ÷ nominal paint flow [-] (> 0): the film rate scales with it.
    flow_drift: relative change of the paint flow over the program [-], signed: the flow is
        flow_scale · (1 + flow_drift · (t − t0) / T) at time t of a program of length T.
    seed: random generator seed (directions); the same seed gives the same disturbance.
    """

    part_offset_m: float = 0.0
    part_rotation_rad: float = 0.0
    tcp_offset_m: float = 0.0
    gain_scale: float = 1.0
    standoff_error_m: float = 0.0
    trigger_delay_s: float = 0.0
    flow_scale: float = 1.0
    flow_drift: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name, signed in (("part_offset_m", False), ("part_rotation_rad", False),
                             ("tcp_offset_m", False), ("gain_scale", False),
                             ("standoff_error_m", True), ("trigger_delay_s", True),
                             ("flow_scale", True), ("flow_drift", True)):
            v = getattr(self, name)
            if (isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating)
                    or not math.isfinite(v) or (not signed and v < 0)):
                raise ExecutionError(f"disturbance {name} = {v!r} must be a finite number "
                                     + ("[m, s, factor]" if signed else ">= 0 [m, rad, factor]"))
            object.__setattr__(self, name, float(v))  # JSON-safe in to_dict()
        if self.gain_scale <= 0:
            raise ExecutionError(f"disturbance gain_scale = {self.gain_scale!r} must be > 0 "
                                 "(a factor on the servo gains)")
        if self.flow_scale <= 0:
            raise ExecutionError(f"disturbance flow_scale = {self.flow_scale!r} must be > 0 "
                                 "(actual ÷ nominal flow)")
        if abs(self.flow_drift) >= 1:
            raise ExecutionError(f"disturbance flow_drift = {self.flow_drift!r} must be in "
                                 "(-1, 1) (a relative change of the flow over the program)")
        seed = self.seed
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
            raise ExecutionError(f"disturbance seed = {seed!r} must be an int")
        object.__setattr__(self, "seed", int(seed))

    def realize(self) -> tuple[np.ndarray, np.ndarray]:
        """(T_nominal_actual (4, 4) part placement error, tcp_offset_tool (3,) [m])."""
        rng = np.random.default_rng(self.seed)
        d1, d2, d3 = (_unit(rng.normal(size=3)) for _ in range(3))
        T = np.eye(4)
        T[:3, :3] = matrix_from_axis_angle(d2, self.part_rotation_rad)
        T[:3, 3] = self.part_offset_m * d1
        # a longer standoff puts the real spray point behind the modelled one (tool −z)
        return T, self.tcp_offset_m * d3 - np.array([0.0, 0.0, self.standoff_error_m])

    def paint_on(self, paint_on: np.ndarray, dt_s: float) -> np.ndarray:
        """The brush signal (K,) the bell really followed: `paint_on` shifted by the trigger
        delay (whole steps of dt_s [s]), off where the shift leaves no programmed value."""
        return self._delayed(np.asarray(paint_on, bool), dt_s, False)

    def flow(self, flow: np.ndarray, dt_s: float) -> np.ndarray:
        """The flow (K,) ÷ the part's flow [-] the bell really followed: the program's
        (`JointTrajectory.flow`) shifted by the trigger delay like the brush, 1 where the shift
        leaves no programmed value."""
        return self._delayed(np.asarray(flow, float), dt_s, 1.0)

    def _delayed(self, signal: np.ndarray, dt_s: float, fill: Any) -> np.ndarray:
        k = int(round(self.trigger_delay_s / dt_s))
        if k == 0:
            return signal.copy()
        out = np.full_like(signal, fill)
        if 0 < k < len(signal):
            out[k:] = signal[:-k]
        elif -len(signal) < k < 0:
            out[:k] = signal[-k:]
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe settings."""
        return asdict(self)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


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
        tau_demand=np.ascontiguousarray(tau_demand),
        flow=(np.asarray(traj.flow, float).copy() if disturbances is None
              else disturbances.flow(traj.flow, cell.model.opt.timestep)))
