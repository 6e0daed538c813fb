"""Conveyor tracking: the part moves along a line at a set speed; programs follow it.

Plans and programs are built in the part frame at the part's nominal placement `T_world_part`
(the static cell). On a conveyor the part is at

    T_world_part(t) = Trans(d(t)) · T_world_part,   d(t) = v · (t − t_ref) · u

(u: unit line direction, v: line speed [m/s], t_ref: when the part passes its nominal placement —
by default the middle of the program, so the robots reach ± half the travel around it).
`track_program` turns a static program into one that follows the part: every sample's TCP target
becomes Trans(d(t)) · T_world_tcp(t), so the TCP's motion relative to the part — and hence the
film in the part frame — is the static program's.

- A robot on a rail takes the component of d(t) along its rail on the rail axis (exact, no IK).
- The rest (all of d for a fixed base) is solved by IK on the moving target: the closed-form
  ortho-parallel solution of every sample's shifted flange pose, on the branch (and 2π shifts)
  closest to the static program's joint values there (`paintcell.robots.opw`), else damped least
  squares warm-started from them.
- Velocities and accelerations: the static program's plus the finite-difference derivatives of
  the correction (the rail's is analytic: + v·(u·a), + 0). At v = 0 the program is unchanged,
  bit for bit.
The time law is the static program's; the joint limits are re-measured on the tracked program
and reported in `meta["conveyor"]` (the conveyor adds its speed to every TCP velocity).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.core.errors import PaintcellError
from paintcell.motion.joint_trajectory import JointTrajectory

#: largest joint step between two 1 ms samples of a tracked program [rad] (10 rad/s: above any
#: joint's speed limit; a larger step is a branch change, not motion).
MAX_STEP_RAD = 0.01
#: residual of the line motion across a rail below which the rail is taken as parallel [m].
RAIL_PARALLEL_TOL_M = 1e-12


class ConveyorError(PaintcellError):
    """A conveyor is mis-specified or a program cannot follow it."""


@dataclass(frozen=True)
class Conveyor:
    """The line that carries the part (SI units).

    speed_m_s: line speed [m/s] (≥ 0; car-body paint lines run 2–6 m/min = 0.03–0.1 m/s).
    direction: (3,) direction of travel in the world (normalized here).
    mass_kg: mass on the carrier (body + skid) [kg] — the carrier is a servoed slide in MuJoCo.
        600 kg: a body-in-white of ~300–400 kg on a steel skid (estimate).
    force_max_n: carrier drive force limit [N] (estimate: ample for constant speed).
    damping_n_s_m: viscous friction of the carrier [N·s/m] (estimate: roller-bed friction).
    """

    speed_m_s: float = 0.0
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    mass_kg: float = 600.0
    force_max_n: float = 20000.0
    damping_n_s_m: float = 500.0

    def __post_init__(self) -> None:
        u = np.asarray(self.direction, float)
        if u.shape != (3,) or not np.all(np.isfinite(u)) or np.linalg.norm(u) < 1e-9:
            raise ConveyorError(f"conveyor direction {self.direction!r} must be three finite "
                                "numbers, not all zero, e.g. [1, 0, 0]")
        for name in ("speed_m_s", "mass_kg", "force_max_n", "damping_n_s_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v) \
                    or v < 0 or (name in ("mass_kg", "force_max_n") and v == 0):
                raise ConveyorError(f"conveyor {name} = {v!r} must be a finite number ≥ 0 "
                                    "(> 0 for mass and force)")

    @property
    def unit(self) -> np.ndarray:
        """(3,) unit direction of travel."""
        u = np.asarray(self.direction, float)
        return u / np.linalg.norm(u)

    def position_m(self, t_s: npt.ArrayLike, t_ref_s: float) -> np.ndarray:
        """(K,) carrier position along the line [m] at times t_s (K,) [s]; 0 at t_ref_s."""
        return self.speed_m_s * (np.asarray(t_s, float) - t_ref_s)

    def displacement(self, t_s: npt.ArrayLike, t_ref_s: float) -> np.ndarray:
        """(K, 3) displacement d(t) of the part from its nominal placement [m]."""
        return self.position_m(t_s, t_ref_s)[:, None] * self.unit

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe settings."""
        return asdict(self)


def track_program(robot: Any, traj: JointTrajectory, conveyor: Conveyor,
                  t_ref_s: float | None = None) -> JointTrajectory:
    """The static program `traj` of `robot` made to follow the conveyor (module doc).

    robot: the `paintcell.robots.Robot` the program was built for (a rail robot: `robot.rail` set).
    t_ref_s: when the part passes its nominal placement [s] (None: the program's middle).
    Returns a new `JointTrajectory` (world-frame TCP recomputed by FK) with `meta["conveyor"]`:
    the settings, t_ref_s, the largest FK deviation from the moving target [m], and the joint
    position / velocity / acceleration utilization re-measured on the tracked program.
    Raises ConveyorError when a sample has no IK solution inside the joint limits, the arm would
    jump (a singularity crossed on the moving target) or a joint (the rail) leaves its range.
    """
    t = np.asarray(traj.t_s, float)
    t_ref = float(0.5 * (t[0] + t[-1]) if t_ref_s is None else t_ref_s)
    d = conveyor.displacement(t, t_ref)
    q, qd, qdd = (np.array(traj.q, float), np.array(traj.qd, float), np.array(traj.qdd, float))
    rail = getattr(robot, "rail", None)
    off = 1 if rail is not None else 0
    if rail is not None:
        axis = robot.T_world_base[:3, 1]          # the carriage slides along the rail frame's y
        r = d @ axis
        q[:, 0] += r
        qd[:, 0] += conveyor.speed_m_s * float(conveyor.unit @ axis)
        d = d - r[:, None] * axis
        # A rail along the line leaves only the round-off of its axis (cos 90° = 6e-17).
        d[np.abs(d) < RAIL_PARALLEL_TOL_M] = 0.0
    if np.any(d != 0.0):
        q_arm = _ik_moving(robot, traj, q, d, off)
        corr = q_arm - q[:, off:]
        dt = float(t[1] - t[0])
        step = np.abs(np.diff(q_arm, axis=0)).max(axis=1)
        if len(step) and step.max() > MAX_STEP_RAD:
            k = int(np.argmax(step))
            raise ConveyorError(f"following the conveyor makes the arm jump {step[k]:.2f} rad at "
                                f"t = {t[k]:.2f} s (a wrist singularity or branch change on the "
                                "moving target); lower the line speed, put the robot on a rail "
                                "along the line, or move it")
        dcorr = np.gradient(corr, dt, axis=0)
        qd[:, off:] += dcorr
        qdd[:, off:] += np.gradient(dcorr, dt, axis=0)
        q[:, off:] = q_arm
    lo, hi = np.asarray(robot.q_lower), np.asarray(robot.q_upper)
    # Only what the tracking adds counts: the static program's own excursion past a limit (the
    # joint spline between IK knots may graze one) is the time law's, reported elsewhere.
    q0 = np.asarray(traj.q, float)
    tol_lo = 1e-9 + np.maximum(lo - q0.min(axis=0), 0.0)
    tol_hi = 1e-9 + np.maximum(q0.max(axis=0) - hi, 0.0)
    out = np.flatnonzero(np.any((q < lo - tol_lo) | (q > hi + tol_hi), axis=0))
    if len(out):
        j = int(out[0])
        raise ConveyorError(f"following the conveyor drives {robot.joint_names[j]} to "
                            f"[{q[:, j].min():.3f}, {q[:, j].max():.3f}], outside its limits "
                            f"[{lo[j]:.3f}, {hi[j]:.3f}]; lower the line speed, lengthen the "
                            "rail or move the robot")
    T_fk = robot.fk_many(q)
    target = np.asarray(traj.tcp_pos_world, float) + conveyor.displacement(t, t_ref)
    meta = dict(traj.meta)
    meta["conveyor"] = {
        **conveyor.to_dict(), "t_ref_s": t_ref,
        "max_target_error_m": float(np.linalg.norm(T_fk[:, :3, 3] - target, axis=1).max()),
        "travel_m": float(np.ptp(conveyor.position_m(t, t_ref))),
        "max_velocity_utilization": float((np.abs(qd) / robot.v_max).max()),
        "max_acceleration_utilization": float((np.abs(qdd) / robot.a_max).max()),
    }
    arrays = {name: getattr(traj, name) for name in JointTrajectory._ARRAYS}
    arrays.update(q=q, qd=qd, qdd=qdd, tcp_pos_world=T_fk[:, :3, 3],
                  tcp_rot_world=T_fk[:, :3, :3])
    return JointTrajectory(**arrays, robot_name=traj.robot_name, joint_names=traj.joint_names,
                           slowdowns=traj.slowdowns, pass_summary=traj.pass_summary, meta=meta)


def _ik_moving(robot: Any, traj: JointTrajectory, q: np.ndarray, d: np.ndarray,
               off: int) -> np.ndarray:
    """(K, 6) arm joints that put the TCP at T_world_tcp(t) + d(t) (d: (K, 3) [m]), closest to the
    arm part of q (K, off + 6); closed form when the arm has one."""
    from paintcell.robots.opw import fit_to_limits, inverse

    q_ref = q[:, off:]
    # Targets: the static TCP pose (the rail already shifted) moved by d.
    T_tcp = robot.fk_many(q)
    T_tcp[:, :3, 3] += d
    if off:
        from paintcell.robots.rail import placed_rail

        rail = placed_rail(robot)
        arm = rail.arm
        # The arm's base sits at (0, s, 0) in the rail frame, unrotated: per-sample base poses.
        T_rail = rail.T_world_rail
        T_bt = np.empty_like(T_tcp)
        T_bt[:] = np.eye(4)
        T_bt[:, :3, :3] = T_rail[:3, :3].T @ T_tcp[:, :3, :3]
        T_bt[:, :3, 3] = (T_tcp[:, :3, 3] - T_rail[:3, 3]) @ T_rail[:3, :3]
        T_bt[:, 1, 3] -= q[:, 0]
        T_bf = T_bt @ np.linalg.inv(arm.T_flange_tcp)
    else:
        arm = robot
        T_bf = arm.flange_poses(T_tcp) if arm.opw is not None else T_tcp
    lo, hi = arm.q_lower, arm.q_upper
    if arm.opw is not None:
        Q, valid = inverse(arm.opw, T_bf)                              # (K, 8, 6)
        Qf, within = fit_to_limits(Q, lo, hi, q_ref[:, None, :])
        dist = np.where(valid & within, np.abs(Qf - q_ref[:, None]).max(axis=2), np.inf)
        b = np.argmin(dist, axis=1)
        if not np.all(np.isfinite(dist[np.arange(len(b)), b])):
            k = int(np.argmin(np.isfinite(dist[np.arange(len(b)), b])))
            why = "outside the joint limits" if valid[k].any() else "out of reach"
            raise ConveyorError(f"the conveyor carries the target {why} at t = "
                                f"{traj.t_s[k]:.2f} s (the static program there is "
                                f"{np.round(q_ref[k], 3).tolist()} rad); lower the line speed "
                                "or move the robot")
        return Qf[np.arange(len(b)), b]
    from paintcell.robots.ik import dls

    out = np.empty_like(q_ref)
    prev = q_ref[0]
    for k in range(len(q_ref)):
        prev, ok = dls(robot, T_tcp[k], prev)
        if not ok:
            raise ConveyorError(f"no IK for the moving target at t = {traj.t_s[k]:.2f} s; lower "
                                "the line speed or move the robot")
        out[k] = prev
    return out
