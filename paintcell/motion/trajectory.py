"""One continuous paint program: TOPP-RA paint passes joined by ruckig moves.

`build_program(robot, plan, T_world_part, settings)`:

1. IK of every pass (`paintcell.robots.ik`, unless `ik_results` are given), joint path q(s) over the
   planned TCP arc length s as a C² cubic spline, refined with extra knots until the FK of the
   spline stays within `path_tolerance_m` of the planned TCP polyline.
2. TOPP-RA on each pass (`paintcell.motion.time_law`): joint velocity and acceleration limits
(with margins),
   TCP speed ≤ planned speed, TCP acceleration ≤ `tcp_a_max_m_s2`. Passes start and end at the
   planned speed (the TCP is already moving when the brush opens), lowered only where the limits
   forbid it.
3. ruckig moves (`paintcell.motion.moves`), jerk-limited and time-optimal, that join the full
joint state
   (q, q̇, q̈) of their neighbours: approach home → first pass, a turn-around between passes, and
   retract last pass → home. Approach and retract go through a via pose backed off from the pass
   end along the spray axis (−z of the tool) by a clearance, passed moving where that is faster
   and brings the TCP no closer to the part than a stop there (`moving_vias`), else at rest.
   A turn-around is the fastest of three kinds whose TCP stays within `turnaround_max_dip_m`
   (50 mm) of the deeper pass end's standoff, measured along the spray axis on the sampled
   move: a direct joint-space move; a move through the midpoint of the two ends backed off by
   up to `turnaround_clearance_m` (150 mm), passed without stopping (several back-offs and via
   speeds tried, the fastest within the limit kept); or a stop at a backed-off via pose behind
   each end with the reconfiguration between them (1/2, 1/4 of the clearance where the joint
   limits forbid). If none qualifies, the one with the least dip is used and a warning is
   recorded. Each decision is in `meta["turnarounds"]`, the worst dip in
   `meta["turnaround_max_dip_m"]` (door, check --fast: direct moves would dip 75-147 mm; the
   midpoint vias keep it ≤ 50 mm at 1.0 s per turn-around, 5.0 s of the 27 s cycle; with only
   the 150 mm via at the direct move's speed it was 5.9 s). A joint-space reconfiguration
   between IK branches can sweep the arm across the part; `paintcell.execution.execute` checks
   collisions.
4. Sampling at the control rate on one global clock; each segment is evaluated analytically, so
   position, velocity and acceleration are continuous at every junction.

IK: unreachable poses get a best-effort joint path from `paintcell.robots.ik`; such passes are timed
as they are, named in `meta["warnings"]`, and the combined reachability summary is stored in
`meta["reachability"]` for `paintcell.validation.validate`. When no pose is reachable, or a
later stage fails
while some poses are unreachable (a move leaving the joint limits, an unreachable via pose), a
`paintcell.robots.errors.UnreachableError` carries the IK verdict and the fix (move the part or the
base).

Speed following: where the planned speed can be followed it is (TOPP-RA is time-optimal and the
planned speed is its velocity bound); where a limit binds, the runs of samples slower than
planned by more than `slowdown_threshold` are reported in `JointTrajectory.slowdowns` with the
limits that were active there.

`build_program` and its stages are here; the settings and the robot interface are in
`paintcell.motion.trajectory_settings`, IK and the joint splines in
`paintcell.motion.trajectory_paths`, back-offs and
turn-arounds in `paintcell.motion.trajectory_turnaround`, sampling and the speed report in
`paintcell.motion.trajectory_sampling`.
"""

from __future__ import annotations

import importlib.metadata
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.coverage.plan import CoveragePlan
from paintcell.motion.joint_trajectory import (
    APPROACH,
    PAINT,
    RETRACT,
    TURNAROUND,
    JointTrajectory,
    TrajectoryError,
)
from paintcell.motion.moves import JointMove, plan_move
from paintcell.motion.time_law import JointPath, PassTimeLaw, parameterize_pass
from paintcell.motion.trajectory_paths import ik_paths, refined_path
from paintcell.motion.trajectory_sampling import Segment, sample_program
from paintcell.motion.trajectory_settings import RobotLike, TrajectorySettings
from paintcell.motion.trajectory_turnaround import (
    backed_off_via,
    through_via,
    turnaround,
    turnaround_dip,
)
from paintcell.robots.errors import UnreachableError

__all__ = ["RobotLike", "TrajectorySettings", "build_program"]

# The fix named by an `UnreachableError`.
_MOVE_PART = "move the part or the robot base (see paintcell.robots.placement.find_base_pose)"

# TCP deviation [m] of a pass's joint path from the plan above which `meta["warnings"]` names
# the pass (the path is still timed: the loss is measured downstream by
# `paintcell.validation.validate`, with the
# reachability report in `meta["reachability"]`).
_IK_WARN_ERROR_M = 1e-3


def build_program(robot: RobotLike, plan: CoveragePlan, T_world_part: npt.ArrayLike,
                  settings: TrajectorySettings | None = None,
                  ik_results: Sequence[Any] | None = None) -> JointTrajectory:
    """The whole paint program of `plan` on `robot`, sampled at the control rate.

    robot: a `paintcell.robots.Robot` (or anything with its kinematic interface, see `RobotLike`).
    plan: coverage plan in the part frame.
    T_world_part: (4, 4) pose of the part in the world.
    settings: time-law settings (None: defaults).
    ik_results: per pass, the IK joint path (M_i, n) [rad] or an object with `.q` (an
        `IKPathResult`); None runs `paintcell.robots.ik` here.
    Returns a `JointTrajectory` whose `meta` holds stage timings [s], the limits used, and the
    measured path deviation and turn-around dip.
    """
    settings = settings or TrajectorySettings()
    T_wp = np.asarray(T_world_part, float)
    if T_wp.shape != (4, 4) or not np.all(np.isfinite(T_wp)):
        raise TrajectoryError("T_world_part must be a finite (4, 4) pose")
    n = int(robot.nq)
    q_home = np.asarray(robot.q_home if settings.q_home is None else settings.q_home, float)
    if q_home.shape != (n,):
        raise TrajectoryError(f"q_home must have {n} joint values [rad], got {q_home.shape}")
    timing = {"ik": 0.0, "path": 0.0, "toppra": 0.0, "ruckig": 0.0, "sampling": 0.0}

    # --- 1. IK (then joint paths in `_build`) ----------------------------------------------
    # Nothing reachable, or a failure while poses are unreachable, is an `UnreachableError` that
    # carries the IK verdict; a partly unreachable plan that can be timed is (with warnings).
    T_world_tcp = [T_wp @ plan.tcp_frames(i) for i in range(len(plan.passes))]
    t0 = time.perf_counter()
    q_paths, reachability = ik_paths(robot, T_world_tcp, q_home, settings, ik_results)
    timing["ik"] = time.perf_counter() - t0
    if reachability is not None and reachability["n_reachable"] == 0:
        raise UnreachableError(f"{reachability['verdict']}; {_MOVE_PART}")
    try:
        return _build(robot, plan, settings, T_world_tcp, q_paths, reachability, q_home, timing)
    except TrajectoryError as exc:
        if reachability is None or reachability["all_reachable"]:
            raise
        # A move or time law that fails on a partly unreachable plan fails because of it: say so
        # (the joint-limit message of a move alone would hide the IK report).
        cause = str(exc).split(";")[0]
        raise UnreachableError(f"{reachability['verdict']}; the program cannot be built "
                               f"({cause}); {_MOVE_PART}") from exc


def _build(robot: RobotLike, plan: CoveragePlan, settings: TrajectorySettings,
           T_world_tcp: list[np.ndarray], q_paths: list[np.ndarray],
           reachability: dict[str, Any] | None, q_home: np.ndarray,
           timing: dict[str, float]) -> JointTrajectory:
    """Stages 1 (joint paths) to 4 of `build_program`, after IK."""
    n = int(robot.nq)
    v_max = np.asarray(robot.v_max, float)
    a_max = np.asarray(robot.a_max, float)
    v_lim = settings.velocity_margin * v_max
    a_lim = settings.acceleration_margin * a_max
    j_lim = a_lim / settings.jerk_ramp_s

    def fk_pos(Q: np.ndarray) -> np.ndarray:
        return robot.fk_many(Q)[:, :3, 3]

    t0 = time.perf_counter()
    paths: list[JointPath] = []
    deviations: list[float] = []
    knot_lists: list[np.ndarray] = []
    warnings: list[str] = []
    for Tw, qk in zip(T_world_tcp, q_paths, strict=True):
        p_plan = Tw[:, :3, 3]
        s_plan = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p_plan, axis=0),
                                                                 axis=1))])
        path, dev = refined_path(robot, fk_pos, s_plan, p_plan, qk, settings.path_tolerance_m)
        if dev > _IK_WARN_ERROR_M:
            warnings.append(f"pass {len(paths)}: joint path {1e3 * dev:.1f} mm off the planned "
                            "TCP path (unreachable poses; see meta['reachability'])")
        paths.append(path)
        deviations.append(dev)
        knot_lists.append(s_plan)
    timing["path"] = time.perf_counter() - t0

    # --- 2. TOPP-RA on every pass ---------------------------------------------------------
    t0 = time.perf_counter()
    laws: list[PassTimeLaw] = []
    dt = 1.0 / settings.control_rate_hz
    for p, path, s_plan in zip(plan.passes, paths, knot_lists, strict=True):
        v_knots = np.interp(path.s_knots, s_plan, p.speeds_m_s**2) ** 0.5
        sd_b = None if settings.join_at_speed else 0.0
        laws.append(parameterize_pass(path, fk_pos, v_knots, v_lim, a_lim,
                                      settings.tcp_a_max_m_s2,
                                      grid_spacing_m=settings.grid_spacing_m,
                                      sd_start_m_s=sd_b, sd_end_m_s=sd_b, check_dt_s=dt))
    timing["toppra"] = time.perf_counter() - t0

    # --- 3. ruckig moves --------------------------------------------------------------------
    t0 = time.perf_counter()
    zero = np.zeros(n)

    def move(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> JointMove:
        return plan_move(a[0], a[1], a[2], b[0], b[1], b[2], v_lim, a_lim, j_lim,
                         robot.q_lower, robot.q_upper)

    def ends(law: PassTimeLaw) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        _, _, q, qd, qdd = law.joint_state(np.array([0.0, law.duration_s]))
        return (q[0], qd[0], qdd[0]), (q[1], qd[1], qdd[1])

    segments: list[Segment] = []

    def add_moves(kind: int, states: list[tuple[np.ndarray, ...]]) -> None:
        for x, y in zip(states[:-1], states[1:], strict=True):
            m = move(x, y)
            segments.append(Segment(kind, m.duration_s, move=m))

    def at_rest(q: np.ndarray) -> tuple[np.ndarray, ...]:
        return (q, zero, zero)

    def vias(q: np.ndarray, clearance_m: float) -> list[tuple[np.ndarray, ...]]:
        """The backed-off via of q (none at 0 clearance) and, with `fold_moves`, before it (seen
        from home) the same via with the shoulder and elbow at home's values."""
        out = [] if clearance_m == 0 else [at_rest(backed_off_via(robot, q, clearance_m))]
        wi = getattr(robot, "wrist_joint_index", None)
        if settings.fold_moves and wi is not None and wi >= 3:
            f = np.array(out[0][0] if out else q, float)
            f[wi - 3:wi - 1] = q_home[wi - 3:wi - 1]
            out.insert(0, at_rest(f))
        return out

    home = (q_home, zero, zero)
    first_start, _ = ends(laws[0])
    via_records: dict[str, Any] = {}

    def approach_or_retract(kind: int, a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...],
                            q_pass: np.ndarray, clearance_m: float, T_pass: np.ndarray) -> None:
        """home → via(s) → pass start, or pass end → via(s) → home; a single via (no fold) is
        passed moving where `through_via` finds that faster and no closer to the part."""
        vs = vias(q_pass, clearance_m)
        if kind == RETRACT:
            vs = vs[::-1]
        if settings.moving_vias and len(vs) == 1:
            moves, record = through_via(robot, move, a, vs[0][0], b, T_pass, settings, dt)
            segments.extend(Segment(kind, m.duration_s, move=m) for m in moves)
            via_records["approach" if kind == APPROACH else "retract"] = record
        else:
            add_moves(kind, [a, *vs, b])

    approach_or_retract(APPROACH, home, first_start, first_start[0],
                        settings.approach_clearance_m, T_world_tcp[0][0])
    turnarounds: list[dict[str, Any]] = []
    for i, law in enumerate(laws):
        segments.append(Segment(PAINT, law.duration_s, pass_index=i, law=law))
        _, end = ends(law)
        if i + 1 < len(laws):
            nxt, _ = ends(laws[i + 1])
            moves, record = turnaround(robot, move, end, nxt, T_world_tcp[i][-1],
                                        T_world_tcp[i + 1][0], settings, dt)
            segments.extend(Segment(TURNAROUND, m.duration_s, move=m) for m in moves)
            turnarounds.append({"after_pass": i, **record})
            if record["dip_m"] > settings.turnaround_max_dip_m:
                warnings.append(f"turn-around after pass {i} ({record['mode']}): the TCP comes "
                                f"{1e3 * record['dip_m']:.0f} mm closer to the part than the "
                                "pass ends (IK changes branch between passes?); check collisions")
        else:
            approach_or_retract(RETRACT, end, home, end[0], settings.retract_clearance_m,
                                T_world_tcp[i][-1])
    timing["ruckig"] = time.perf_counter() - t0

    # --- 4. sampling on one clock -----------------------------------------------------------
    t0 = time.perf_counter()
    traj = sample_program(robot, plan, segments, dt, knot_lists, settings, v_lim, a_lim)
    timing["sampling"] = time.perf_counter() - t0

    dip = turnaround_dip(traj, T_world_tcp)
    meta = dict(traj.meta)
    meta.update({
        "settings": settings.to_dict(),
        "timing_s": timing,
        "limits": {"v_max_rad_s": v_max.tolist(), "a_max_rad_s2": a_max.tolist(),
                   "v_used_rad_s": v_lim.tolist(), "a_used_rad_s2": a_lim.tolist(),
                   "j_used_rad_s3": j_lim.tolist(), "tcp_a_max_m_s2": settings.tcp_a_max_m_s2},
        "reachability": reachability,
        "warnings": warnings,
        "max_path_deviation_m": float(max(deviations)),
        "turnaround_max_dip_m": dip,
        "turnarounds": turnarounds,
        "approach_retract": via_records,
        "cycle_time_s": traj.duration_s,
        "paint_time_s": traj.paint_time_s,
        "planned_paint_time_s": plan.paint_time_s,
        "versions": {"toppra": importlib.metadata.version("toppra"),
                     "ruckig": importlib.metadata.version("ruckig")},
    })
    summary = tuple({**s, "max_path_deviation_m": float(d)}
                    for s, d in zip(traj.pass_summary, deviations, strict=True))
    return JointTrajectory(**{name: getattr(traj, name) for name in JointTrajectory._ARRAYS},
                           robot_name=traj.robot_name, joint_names=traj.joint_names,
                           slowdowns=traj.slowdowns, pass_summary=summary, meta=meta)
