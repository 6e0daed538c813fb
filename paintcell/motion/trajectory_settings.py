"""What `paintcell.motion.trajectory.build_program` takes besides the plan: its settings
(`TrajectorySettings`:
control rate [Hz], limits and margins, clearances [m], tolerances, all SI) and the kinematic
interface it needs of a robot (`RobotLike`: joint limits [rad], [rad/s], [rad/s²], FK, Jacobian).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from paintcell.motion.joint_trajectory import TrajectoryError


class RobotLike(Protocol):
    """What `build_program` needs of a robot (`paintcell.robots.Robot` satisfies it)."""

    name: str
    joint_names: tuple[str, ...]
    q_lower: np.ndarray
    q_upper: np.ndarray
    v_max: np.ndarray
    a_max: np.ndarray
    q_home: np.ndarray

    @property
    def nq(self) -> int:
        """Number of joints."""
        ...

    def fk(self, q: npt.ArrayLike) -> np.ndarray:
        """(4, 4) world pose of the TCP at joint position q (nq,) [rad; m for a rail]."""
        ...

    def fk_many(self, Q: npt.ArrayLike) -> np.ndarray:
        """(N, 4, 4) world poses of the TCP at joint positions Q (N, nq)."""
        ...

    def jacobian(self, q: npt.ArrayLike) -> np.ndarray:
        """(6, nq) TCP Jacobian [v; ω] at q in world-aligned axes at the TCP (m/rad, rad/rad)."""
        ...


@dataclass(frozen=True)
class TrajectorySettings:
    """Settings of the time law and the moves between passes (SI units)."""

    control_rate_hz: float = 1000.0
    """Sample rate of the program [Hz] (the controller's servo rate)."""
    tcp_a_max_m_s2: float = 24.0
    """TCP acceleration limit on paint passes [m/s²]; ABB quotes up to 24 m/s² for its paint
    robots (IRB 5500 FlexPainter datasheet)."""
    velocity_margin: float = 0.95
    """Fraction of each joint's v_max the program may use (headroom for the servo)."""
    acceleration_margin: float = 0.90
    """Fraction of each joint's a_max the program may use; the sampled output is re-measured and
    proved to stay within it."""
    jerk_ramp_s: float = 0.08
    """Joint jerk limit as a ramp time: j_max = margin·a_max / jerk_ramp_s [rad/s³]. No public
    figure exists; 80 ms from zero to full acceleration is typical of industrial arm motion
    profiles (≈ 11·a_max: 68-338 rad/s³ for the ABB-style arm at the 0.9 margin)."""
    q_home: tuple[float, ...] | None = None
    """Home joint position [rad] where the program starts and ends (None: the robot's)."""
    approach_clearance_m: float = 0.10
    """Back-off of the via pose before the first pass, along −z of the tool [m] (0: none)."""
    retract_clearance_m: float = 0.10
    """Back-off of the via pose after the last pass, along −z of the tool [m] (0: none)."""
    moving_vias: bool = True
    """Approach and retract pass their backed-off via without stopping where that is faster and
    brings the TCP no closer to the part (along the pass end's spray axis) than stopping there
    does (`paintcell.motion.trajectory_turnaround._through_via`; False: stop at the via, as
    before; with `fold_moves` the vias are always stops)."""
    fold_moves: bool = False
    """Approach and retract also pass through a folded via: the backed-off via with the shoulder
    and elbow (J2, J3) at home's values, so the arm pulls back toward its base before it turns
    its wrist and base (used by the booth next to other parts,
    `paintcell.booth.booth_clearance`)."""
    turnaround_max_dip_m: float = 0.05
    """Largest approach of the TCP toward the part during a turn-around, beyond the deeper of the
    two pass ends, along the spray axis [m] (20 % of the default bell's 250 mm standoff); picks
    the turn-around kind (module docstring). inf: always direct; 0: back off as far as possible."""
    turnaround_clearance_m: float = 0.15
    """Back-off of turn-around via poses along −z of the tool [m]."""
    grid_spacing_m: float = 0.01
    """Largest TOPP-RA grid interval along the pass [m] (every plan sample is a grid point)."""
    path_tolerance_m: float = 0.5e-3
    """Largest FK deviation of the joint spline from the planned TCP path [m]."""
    slowdown_threshold: float = 0.005
    """Relative speed deficit below planned that counts as a slowdown (0.005 = 0.5 %)."""
    join_at_speed: bool = True
    """Passes start and end at the planned TCP speed (False: at rest)."""
    ik_free_spin: bool = False
    """Let IK rotate the tool about its spray axis (bell atomizers are symmetric)."""

    def __post_init__(self) -> None:
        checks = [
            (self.control_rate_hz > 0, "control_rate_hz must be positive [Hz]"),
            (self.tcp_a_max_m_s2 > 0, "tcp_a_max_m_s2 must be positive [m/s²]"),
            (0 < self.velocity_margin <= 1, "velocity_margin must be in (0, 1]"),
            (0 < self.acceleration_margin <= 1, "acceleration_margin must be in (0, 1]"),
            (self.jerk_ramp_s > 0, "jerk_ramp_s must be positive [s]"),
            (self.approach_clearance_m >= 0, "approach_clearance_m must be ≥ 0 [m]"),
            (self.retract_clearance_m >= 0, "retract_clearance_m must be ≥ 0 [m]"),
            (self.turnaround_clearance_m > 0, "turnaround_clearance_m must be > 0 [m]"),
            (self.turnaround_max_dip_m >= 0, "turnaround_max_dip_m must be ≥ 0 [m] (inf: "
             "always direct)"),
            (self.grid_spacing_m > 0, "grid_spacing_m must be positive [m]"),
            (self.path_tolerance_m > 0, "path_tolerance_m must be positive [m]"),
            (0 < self.slowdown_threshold < 1, "slowdown_threshold must be in (0, 1)"),
        ]
        for ok, msg in checks:
            if not ok:
                raise TrajectoryError(f"invalid TrajectorySettings: {msg}")
        if self.q_home is not None:
            object.__setattr__(self, "q_home", tuple(float(x) for x in self.q_home))

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (round-trips through `from_dict`)."""
        d = asdict(self)
        d["q_home"] = None if self.q_home is None else list(self.q_home)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrajectorySettings:
        """Settings from `to_dict` output; unknown keys raise `TrajectoryError`."""
        names = {f.name for f in fields(cls)}
        bad = sorted(set(d) - names)
        if bad:
            raise TrajectoryError(f"unknown TrajectorySettings keys {bad}; valid: {sorted(names)}")
        return cls(**d)
