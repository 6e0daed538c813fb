"""What an execution is asked to do: the servo's settings and the seeded disturbances.

`ServoSettings`: the joint PD + inverse-dynamics feed-forward servo with the imperfections of a
real one (latency, model and payload error, Coulomb friction); `Disturbances`: seeded errors
between the planned cell and the executed one (part placement, TCP, gains, standoff, trigger,
flow). `ExecutionError` is the error of the whole execution stage. SI units: m, s, rad, N·m.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import mujoco
import numpy as np

from paintcell.core.errors import PaintcellError
from paintcell.core.transforms import matrix_from_axis_angle
from paintcell.execution.cell import Cell


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
        for name in ("part_offset_m", "part_rotation_rad", "tcp_offset_m", "gain_scale"):
            v = getattr(self, name)
            if (isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating)
                    or not math.isfinite(v) or v < 0):
                raise ExecutionError(f"disturbance {name} = {v!r} must be a finite number >= 0 "
                                     "[m, rad, factor]")
            object.__setattr__(self, name, float(v))  # JSON-safe in to_dict()
        if self.gain_scale <= 0:
            raise ExecutionError(f"disturbance gain_scale = {self.gain_scale!r} must be > 0 "
                                 "(a factor on the servo gains)")
        for name in ("standoff_error_m", "trigger_delay_s", "flow_scale", "flow_drift"):
            v = getattr(self, name)
            if (isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating)
                    or not math.isfinite(v)):
                raise ExecutionError(f"disturbance {name} = {v!r} must be a finite number "
                                     "[m, s, factor]")
            object.__setattr__(self, name, float(v))
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
        k = int(round(self.trigger_delay_s / dt_s))
        on = np.asarray(paint_on, bool)
        if k == 0:
            return on.copy()
        out = np.zeros_like(on)
        if 0 < k < len(on):
            out[k:] = on[:-k]
        elif -len(on) < k < 0:
            out[:k] = on[-k:]
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe settings."""
        return asdict(self)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)
