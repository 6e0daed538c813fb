"""One continuous paint program: TOPP-RA paint passes joined by ruckig moves.

`build_program(robot, plan, T_world_part, settings)`:

1. IK of every pass (`paintcell.robots.ik`, unless `ik_results` are given), joint path q(s) over the
   planned TCP arc length s as a C² cubic spline, refined with extra knots until the FK of the
   spline stays within `path_tolerance_m` of the planned TCP polyline.
2. TOPP-RA on each pass (`paintcell.motion.time_law`): joint velocity and acceleration limits (with
   margins), TCP speed ≤ planned speed, TCP acceleration ≤ `tcp_a_max_m_s2`. Passes start and end
   at the planned speed (the TCP is already moving when the brush opens), lowered only where the
   limits forbid it.
3. ruckig moves (`paintcell.motion.moves`), jerk-limited and time-optimal, that join the full joint
   state (q, q̇, q̈) of their neighbours: approach home → first pass, a turn-around between passes,
   and retract last pass → home. Approach and retract go through a via pose backed off from the
   pass end along the spray axis (−z of the tool) by a clearance, passed moving where that is
   faster and brings the TCP no closer to the part than a stop there (`moving_vias`), else at rest.
   A turn-around is the fastest of three kinds whose TCP stays within `turnaround_max_dip_m` (50
   mm) of the deeper pass end's standoff, measured along the spray axis on the sampled move: a
   direct joint-space move; a move through the midpoint of the two ends backed off by up to
   `turnaround_clearance_m` (150 mm), passed without stopping (several back-offs and via speeds
   tried, the fastest within the limit kept); or a stop at a backed-off via pose behind each end
   with the reconfiguration between them (1/2, 1/4 of the clearance where the joint limits forbid).
   If none qualifies, the one with the least dip is used and a warning is recorded. Each decision
   is in `meta["turnarounds"]`, the worst dip in `meta["turnaround_max_dip_m"]` (door, check
   --fast: direct moves would dip 75-147 mm; the midpoint vias keep it ≤ 50 mm at 1.0 s per
   turn-around, 5.0 s of the 27 s cycle; with only the 150 mm via at the direct move's speed it was
   5.9 s). A joint-space reconfiguration between IK branches can sweep the arm across the part;
   `paintcell.execution.execute` checks collisions.
4. Sampling at the control rate on one global clock; each segment is evaluated analytically, so
   position, velocity and acceleration are continuous at every junction.

IK: unreachable poses get a best-effort joint path from `paintcell.robots.ik`; such passes are timed
as they are, named in `meta["warnings"]`, and the combined reachability summary is stored in
`meta["reachability"]` for `paintcell.validation.validate`. When no pose is reachable, or a
later stage fails while some poses are unreachable (a move leaving the joint limits, an
unreachable via pose), a `paintcell.robots.errors.UnreachableError` carries the IK verdict and
the fix (move the part or the base).

Speed following: where the planned speed can be followed it is (TOPP-RA is time-optimal and the
planned speed is its velocity bound); where a limit binds, the runs of samples slower than
planned by more than `slowdown_threshold` are reported in `JointTrajectory.slowdowns` with the
limits that were active there.

The module holds the settings (`TrajectorySettings`) and the robot interface it needs
(`RobotLike`), IK and the joint splines of the passes, back-offs and turn-arounds, the program's
sampling with its speed report, and `build_program` itself.
"""

from __future__ import annotations

import importlib.metadata
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields
from typing import Any, Protocol, cast

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from paintcell.coverage.offset_polyline import arc_length
from paintcell.coverage.plan import CoveragePlan
from paintcell.motion.flow import brush_flow
from paintcell.motion.joint_trajectory import (
    APPROACH,
    PAINT,
    RETRACT,
    TURNAROUND,
    JointTrajectory,
    TrajectoryError,
    true_runs,
)
from paintcell.motion.moves import JointMove, plan_move
from paintcell.motion.time_law import (
    JointPath,
    PassTimeLaw,
    parameterize_pass,
    tcp_path_derivatives,
)
from paintcell.robots.errors import UnreachableError
from paintcell.robots.rail import RAIL_JOINT

__all__ = ["RobotLike", "TrajectorySettings", "build_program"]


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

    def planned_home(self, q: npt.ArrayLike) -> np.ndarray:
        """q (nq,) with a joint on its limit moved just inside it, onto the planned range."""
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
    does (`through_via`; False: stop at the via, as
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
    """Let IK rotate the tool about its spray axis (bell atomizers are symmetric); each pass
    starts from x = travel (`paintcell.coverage.plan.CoveragePlan.tcp_frames`, keep_roll)."""
    keep_roll: bool = True
    """The bell keeps its roll about the spray axis from pass to pass (the wrist does not turn
    half a turn at each turn-around; `CoveragePlan.roll_signs`). False: x = the travel on every
    pass, the roll turning half a turn between back-and-forth passes (the same film; another
    arm pose on every other pass, which a cell whose arms come close may need)."""
    flow_min: float = 0.7
    """Lowest bell flow the program may command on a pass, a fraction of its part's flow [-]:
    where the time law is slower than the plan the flow drops with it (a brush table,
    `paintcell.motion.flow`) so the film keeps the plan's build. 1: constant flow. 0.7: a
    moderate turn-down, over which the bell's spray pattern (the deposition model, linear in
    the flow) changes little; a bell's whole flow range is wider, about 2:1 at a fixed speed and
    shaping air."""

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
            (0 < self.flow_min <= 1, "flow_min must be in (0, 1] (a fraction of the part's "
             "flow; 1: constant flow)"),
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


def ik_paths(robot: RobotLike, T_world_tcp: list[np.ndarray], q_home: np.ndarray,
             settings: TrajectorySettings, ik_results: Sequence[Any] | None
             ) -> tuple[list[np.ndarray], dict[str, Any] | None]:
    """Joint paths (M_i, n) of every pass, from `ik_results` or `paintcell.robots.ik`, and the
    combined
    reachability summary (`ReachabilityReport.to_dict()` without per-pose arrays; None when the
    results carry no report)."""
    n = int(robot.nq)
    if ik_results is None:
        from paintcell.robots.paths import (
            solve_paths,  # robots/ is the only IK; imported when needed
        )

        # Each pass is seeded with the end of the previous one, the first with home.
        ik_results = solve_paths(cast(Any, robot), list(T_world_tcp), q_seed=q_home,
                                 free_spin=settings.ik_free_spin)
    if len(ik_results) != len(T_world_tcp):
        raise TrajectoryError(f"ik_results has {len(ik_results)} passes, the plan has "
                              f"{len(T_world_tcp)}; solve IK for the same plan")
    q_paths = []
    for i, (r, Tw) in enumerate(zip(ik_results, T_world_tcp, strict=True)):
        q = np.asarray(getattr(r, "q", r), float)
        if q.shape != (len(Tw), n) or not np.all(np.isfinite(q)):
            raise TrajectoryError(f"IK result of pass {i} has shape {q.shape}, expected "
                                  f"({len(Tw)}, {n}) finite joint values")
        q_paths.append(q)
    reports = [getattr(r, "reachability", None) for r in ik_results]
    summary = None
    if reports and all(r is not None for r in reports):
        from paintcell.robots.reachability import ReachabilityReport

        summary = ReachabilityReport.concatenate(cast(list[Any], reports)).to_dict()
        # per-pose flags that paintcell.validation.honest_reach needs (validate drops them from
        # its report)
        poses = summary.pop("poses", {})
        summary["poses"] = {k: poses[k] for k in ("reachable", "joint_jump_rad") if k in poses}
    return q_paths, summary


# --- joint path refinement -----------------------------------------------------------------------
def refined_path(robot: RobotLike, fk_pos: Any, s_plan: np.ndarray, p_plan: np.ndarray,
                 q_knots: np.ndarray, tol_m: float, max_rounds: int = 4) -> tuple[JointPath,
                                                                                   float]:
    """Spline through the IK samples, with corrected midpoint knots where its FK strays.

    Returns the path and its largest deviation [m] from the planned polyline (checked at the
    knots and at 3 points inside every knot interval).
    """
    if np.any(np.diff(s_plan) <= 1e-9):
        raise TrajectoryError("a pass repeats a TCP position (zero-length step); remove "
                              "duplicate samples from the plan")
    s, q = s_plan.copy(), q_knots.copy()
    frac = np.array([0.25, 0.5, 0.75])
    # A rail's carriage stays where `paintcell.robots.rail` put it for the pass: the inserted
    # knots move the arm only (moving the carriage too left it drifting at the pass's ends, out
    # through its travel's end when it sat there).
    hold = np.array([n == RAIL_JOINT for n in robot.joint_names])
    for _ in range(max_rounds + 1):
        path = JointPath(s, q)
        s_chk = (s[:-1, None] + np.diff(s)[:, None] * frac).ravel()
        dev_in = np.linalg.norm(fk_pos(path(s_chk)) - _lerp_rows(s_plan, p_plan, s_chk), axis=1)
        dev_in = dev_in.reshape(-1, len(frac)).max(axis=1)
        dev_knots = np.linalg.norm(fk_pos(q) - _lerp_rows(s_plan, p_plan, s), axis=1)
        dev = float(max(dev_in.max(), dev_knots.max()))
        # Refine only between IK samples that are themselves on the path (unreachable samples
        # cannot be corrected by more knots).
        on_path = dev_knots <= 0.5 * tol_m
        bad = np.flatnonzero((dev_in > 0.5 * tol_m) & on_path[:-1] & on_path[1:])
        if dev <= tol_m or len(bad) == 0 or len(s) > 8 * len(s_plan):
            return path, dev
        s_new = 0.5 * (s[bad] + s[bad + 1])
        q_new = path(s_new)
        p_target = _lerp_rows(s_plan, p_plan, s_new)
        for k in range(len(s_new)):  # loop over a few inserted knots, not samples
            q_new[k] = move_tcp_to(robot, q_new[k], p_target[k], hold=hold)
        s = np.concatenate([s, s_new])
        q = np.concatenate([q, q_new])
        order = np.argsort(s)
        s, q = s[order], q[order]
    return path, dev


def _lerp_rows(x: np.ndarray, Y: np.ndarray, xq: np.ndarray) -> np.ndarray:
    """Row-wise linear interpolation of Y (M, d) at xq (K,)."""
    return np.column_stack([np.interp(xq, x, Y[:, k]) for k in range(Y.shape[1])])


def move_tcp_to(robot: RobotLike, q: np.ndarray, p_target: np.ndarray,
                R_target: np.ndarray | None = None, iters: int = 8,
                hold: np.ndarray | None = None) -> np.ndarray:
    """Damped Newton steps moving the TCP to p_target (3,) [m], holding R_target (default: the
    orientation at q). hold: (n,) bool, joints kept where they are. Returns the new q (n,)."""
    q = np.array(q, float)
    T = robot.fk(q)
    R_target = T[:3, :3] if R_target is None else R_target
    for _ in range(iters):
        err = np.concatenate([p_target - T[:3, 3], pin.log3(R_target @ T[:3, :3].T)])
        if np.linalg.norm(err) < 1e-10:
            break
        J = robot.jacobian(q)
        if hold is not None:
            J = np.where(hold[None, :], 0.0, J)
        # Projected onto the joint limits: the other joints take over the remaining error.
        q = np.clip(q + J.T @ np.linalg.solve(J @ J.T + 1e-8 * np.eye(6), err), robot.q_lower,
                    robot.q_upper)
        T = robot.fk(q)
    return q


@dataclass
class Segment:
    """One piece of the program in time order: a pass's time law or a joint move (`kind`: the
    `JointTrajectory` segment code) lasting `duration_s` [s]."""

    kind: int
    duration_s: float
    pass_index: int = -1
    move: JointMove | None = None
    law: PassTimeLaw | None = None


def sample_program(robot: RobotLike, plan: CoveragePlan, segments: list[Segment], dt: float,
                   knot_lists: list[np.ndarray], settings: TrajectorySettings, v_lim: np.ndarray,
                   a_lim: np.ndarray) -> JointTrajectory:
    """The whole program sampled every `dt` [s] from its segments: q, q̇, q̈, the TCP pose and
    speed, the paint trigger and the flow (`paintcell.motion.flow`), with each pass's limit
    utilization (`knot_lists`: the passes' IK knots; v_lim, a_lim (n,): the joint limits handed
    to TOPP-RA)."""
    n = int(robot.nq)
    starts = np.concatenate([[0.0], np.cumsum([sg.duration_s for sg in segments])])
    total = float(starts[-1])
    k = int(np.ceil(total / dt - 1e-9)) + 1
    t = np.arange(k) * dt
    seg_of = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(segments) - 1)
    q = np.empty((k, n))
    qd = np.empty((k, n))
    qdd = np.empty((k, n))
    v_plan = np.zeros(k)
    paint = np.zeros(k, bool)
    pass_index = np.full(k, -1, np.int64)
    segment = np.empty(k, np.int64)
    s_pass = np.full(k, np.nan)
    sd_pass = np.full(k, np.nan)
    v_law = np.zeros(k)
    for j, sg in enumerate(segments):
        idx = np.flatnonzero(seg_of == j)
        if len(idx) == 0:
            continue
        tl = t[idx] - starts[j]
        segment[idx] = sg.kind
        if sg.move is not None:
            q[idx], qd[idx], qdd[idx] = sg.move.sample(tl)
            continue
        law = sg.law
        assert law is not None
        s, sd, q[idx], qd[idx], qdd[idx] = law.joint_state(tl)
        p = plan.passes[sg.pass_index]
        s_knots = knot_lists[sg.pass_index]
        s_pass[idx], sd_pass[idx] = s, sd
        v_law[idx] = np.interp(s, law.s_grid, law.tcp_speed_scale_grid) * sd
        pass_index[idx] = sg.pass_index
        v_plan[idx] = np.interp(s, s_knots, p.speeds_m_s**2) ** 0.5
        # Brush on over the knot intervals whose both ends the plan marks as painted.
        i0 = np.clip(np.searchsorted(s_knots, s, side="right") - 1, 0, len(s_knots) - 1)
        i1 = np.minimum(i0 + 1, len(s_knots) - 1)
        paint[idx] = p.paint_on[i0] & (p.paint_on[i1] | (s <= s_knots[i0]))
    T = robot.fk_many(q)
    slowdowns, summary = _speed_report(plan, segments, starts, t, s_pass, sd_pass, v_plan,
                                       pass_index, robot, settings, v_lim, a_lim)
    return JointTrajectory(t_s=t, q=q, qd=qd, qdd=qdd, tcp_pos_world=T[:, :3, 3],
                           tcp_rot_world=T[:, :3, :3], v_tcp_planned=v_plan, paint_on=paint,
                           pass_index=pass_index, segment=segment, s_pass_m=s_pass,
                           robot_name=str(robot.name), joint_names=tuple(robot.joint_names),
                           slowdowns=tuple(slowdowns), pass_summary=tuple(summary),
                           flow=brush_flow(s_pass, v_law, v_plan, paint, pass_index,
                                           settings.flow_min))


def _speed_report(plan: CoveragePlan, segments: list[Segment], starts: np.ndarray,
                  t: np.ndarray, s_pass: np.ndarray, sd_pass: np.ndarray, v_plan: np.ndarray,
                  pass_index: np.ndarray, robot: RobotLike, settings: TrajectorySettings,
                  v_lim: np.ndarray, a_lim: np.ndarray) -> tuple[list[dict[str, Any]],
                                                                 list[dict[str, Any]]]:
    """Slowdown runs and per-pass speed-following summary."""
    slowdowns: list[dict[str, Any]] = []
    summary: list[dict[str, Any]] = []
    names = tuple(robot.joint_names)

    def fk_pos(Q: np.ndarray) -> np.ndarray:
        return robot.fk_many(Q)[:, :3, 3]

    for j, sg in enumerate(segments):
        if sg.law is None:
            continue
        law, i = sg.law, sg.pass_index
        idx = np.flatnonzero(pass_index == i)
        s, sd = s_pass[idx], sd_pass[idx]
        v_act = np.interp(s, law.s_grid, law.tcp_speed_scale_grid) * sd
        deficit = 1.0 - v_act / v_plan[idx]
        slow = deficit > settings.slowdown_threshold
        util = _utilization(law, fk_pos, names, v_lim, a_lim, settings.tcp_a_max_m_s2)
        runs = true_runs(slow)
        for r0, r1 in runs:
            s0, s1 = float(s[r0]), float(s[r1 - 1])
            g = (law.s_grid >= s0 - 1e-9) & (law.s_grid <= s1 + 1e-9)
            gi = np.flatnonzero(g)
            lo = max(int(gi[0]) - 1, 0) if len(gi) else int(np.searchsorted(law.s_grid, s0)) - 1
            hi = min(int(gi[-1]) + 2, len(law.s_grid)) if len(gi) else lo + 2
            peak = {name: float(u[max(lo, 0):hi].max()) for name, u in util.items()}
            active = sorted((nm for nm, u in peak.items() if u >= 0.99),
                            key=lambda nm: -peak[nm])
            if not active:
                active = [max(peak, key=lambda nm: peak[nm])]
            slowdowns.append({
                "pass": i, "s_start_m": s0, "s_end_m": s1,
                "t_start_s": float(t[idx[r0]]), "t_end_s": float(t[idx[r1 - 1]]),
                "duration_s": float(t[idx[r1 - 1]] - t[idx[r0]]),
                "max_speed_deficit_pct": float(100 * deficit[r0:r1].max()),
                "limiting": active,
            })
        free = ~slow
        err = np.abs(v_act[free] / v_plan[idx][free] - 1.0) if np.any(free) else np.zeros(1)
        summary.append({
            "pass": i,
            "t_start_s": float(starts[j]),
            "length_m": law.length_m,
            "planned_duration_s": plan.passes[i].duration_s,
            "duration_s": law.duration_s,
            "time_ratio": law.duration_s / max(plan.passes[i].duration_s, 1e-12),
            "slowed_fraction": float(np.mean(slow)) if len(slow) else 0.0,
            "max_speed_deficit_pct": float(100 * max(deficit.max(), 0.0)) if len(idx) else 0.0,
            "max_following_error_pct_unconstrained": float(100 * err.max()),
            "start_speed_clipped": law.sd_start_clipped,
            "end_speed_clipped": law.sd_end_clipped,
            "limit_shrink": law.limit_shrink,
            "n_slowdowns": len(runs),
        })
    return slowdowns, summary


def _utilization(law: PassTimeLaw, fk_pos: Any, names: tuple[str, ...], v_lim: np.ndarray,
                 a_lim: np.ndarray, a_tcp: float) -> dict[str, np.ndarray]:
    """Per grid point, the fraction of each limit (as handed to TOPP-RA) in use."""
    s, sd = law.s_grid, law.sd_grid
    q1, q2 = law.path(s, 1), law.path(s, 2)
    p1, p2 = tcp_path_derivatives(law.path, fk_pos, s)
    # Each grid point sees the s̈ of the intervals on both sides; take the larger use.
    u_l = np.concatenate([law.sdd[:1], law.sdd])
    u_r = np.concatenate([law.sdd, law.sdd[-1:]])
    x = sd**2
    sh = law.limit_shrink
    out: dict[str, np.ndarray] = {}
    for k, nm in enumerate(names):
        out[f"{nm} velocity"] = np.abs(q1[:, k]) * sd / (sh * v_lim[k])
        acc = np.maximum(np.abs(q1[:, k] * u_l + q2[:, k] * x), np.abs(q1[:, k] * u_r
                                                                        + q2[:, k] * x))
        out[f"{nm} acceleration"] = acc / (sh * a_lim[k])
    tcp = np.maximum(np.linalg.norm(p1 * u_l[:, None] + p2 * x[:, None], axis=1),
                     np.linalg.norm(p1 * u_r[:, None] + p2 * x[:, None], axis=1))
    # The TCP polygon is inscribed at cos(π/16) of the disc radius.
    out["TCP acceleration"] = tcp / (sh * a_tcp * np.cos(np.pi / 16))
    return out


def backed_off_via(robot: RobotLike, q: np.ndarray, clearance_m: float) -> np.ndarray:
    """Via joint position (n,) [rad]: the TCP of FK(q) moved by `clearance_m` [m] along −z of the
    tool (away from the part), same orientation."""
    T = robot.fk(q)
    target = T[:3, 3] - clearance_m * T[:3, 2]
    q_via = move_tcp_to(robot, q, target, T[:3, :3], iters=40)
    miss = float(np.linalg.norm(robot.fk(q_via)[:3, 3] - target))
    if miss > 1e-3 or np.any(q_via < robot.q_lower) or np.any(q_via > robot.q_upper):
        raise TrajectoryError("a backed-off via pose is not reachable within the joint limits; "
                              "lower the approach/retract/turnaround clearance")
    return q_via


def turnaround(robot: RobotLike, move: Any, end: tuple[np.ndarray, ...],
               nxt: tuple[np.ndarray, ...], T_end: np.ndarray, T_next: np.ndarray,
               settings: TrajectorySettings, dt: float) -> tuple[list[JointMove],
                                                                  dict[str, Any]]:
    """Moves from the state `end` of one pass to the state `nxt` of the next (see the module
    docstring), tried in order of speed until the TCP dip is within `turnaround_max_dip_m`:

    1. direct: one joint-space move;
    2. via: through the midpoint of the two ends backed off by `turnaround_clearance_m` (or ¾,
       ½, ¼ of it), passed without stopping at ½, 1, 1.5 or 2 times the mean joint velocity of
       the direct move (capped at 0.8 of the usable joint velocity): the fastest of these whose
       dip is within the limit;
    3. backed-off: stop at a via pose behind each end, reconfigure between them.
    If none is within the limit, the candidate with the smallest dip is used. Returns the moves
    and a record (mode, dip [m], duration [s], the direct move's dip and duration).
    """
    zero = np.zeros_like(end[0])
    c = settings.turnaround_clearance_m
    direct = move(end, nxt)
    direct_dip = _move_dip(robot, direct, T_end, T_next, dt)

    def via_moving() -> list[JointMove] | None:
        Ta, Tb = robot.fk(end[0]), robot.fk(nxt[0])
        z = Ta[:3, 2] + Tb[:3, 2]
        z = z / max(float(np.linalg.norm(z)), 1e-12)
        q_mid = 0.5 * (end[0] + nxt[0])
        v_cap = 0.8 * np.asarray(settings.velocity_margin * np.asarray(robot.v_max))
        fastest: tuple[float, float, list[JointMove]] | None = None  # within the dip limit
        shallowest: tuple[float, list[JointMove]] | None = None  # if none is
        for f in VIA_CLEARANCE_FRACTIONS:
            target = 0.5 * (Ta[:3, 3] + Tb[:3, 3]) - f * c * z
            q_via = move_tcp_to(robot, q_mid, target, robot.fk(q_mid)[:3, :3], iters=40)
            if np.linalg.norm(robot.fk(q_via)[:3, 3] - target) > 1e-3:
                continue
            for g in VIA_SPEED_FACTORS:
                qd_via = np.clip(g * (nxt[0] - end[0]) / direct.duration_s, -v_cap, v_cap)
                try:
                    moves = [move(end, (q_via, qd_via, zero)), move((q_via, qd_via, zero), nxt)]
                except TrajectoryError:
                    continue
                t = float(sum(m.duration_s for m in moves))
                if fastest is not None and t >= fastest[0]:
                    continue
                dip = max(_move_dip(robot, m, T_end, T_next, dt) for m in moves)
                if dip <= settings.turnaround_max_dip_m:
                    fastest = (t, dip, moves)
                elif shallowest is None or dip < shallowest[0]:
                    shallowest = (dip, moves)
        if fastest is not None:
            return fastest[2]
        return None if shallowest is None else shallowest[1]

    def backed_off() -> list[JointMove] | None:
        vias = _backed_off_pair(robot, end[0], nxt[0], c)
        if vias is None:
            return None
        states = [end, (vias[0], zero, zero), (vias[1], zero, zero), nxt]
        return [move(x, y) for x, y in zip(states[:-1], states[1:], strict=True)]

    best: tuple[float, str, list[JointMove]] = (direct_dip, "direct", [direct])
    if direct_dip > settings.turnaround_max_dip_m:
        for name, make in (("via", via_moving), ("backed-off", backed_off)):
            try:
                moves = make()
            except TrajectoryError:  # a via outside the joint limits: try the next candidate
                moves = None
            if moves is None:
                continue
            dip = max(_move_dip(robot, m, T_end, T_next, dt) for m in moves)
            if dip < best[0]:
                best = (dip, name, moves)
            if dip <= settings.turnaround_max_dip_m:
                break
    dip, name, moves = best
    return moves, {"mode": name, "dip_m": dip,
                   "duration_s": float(sum(m.duration_s for m in moves)),
                   "direct_dip_m": direct_dip, "direct_duration_s": direct.duration_s}


#: How much nearer the part [m] a moving approach/retract via may bring the TCP than stopping
#: there does: none, beyond the sampling's round-off (a via exists to keep the bell away).
VIA_DIP_TOLERANCE_M = 1e-6


def through_via(robot: RobotLike, move: Any, a: tuple[np.ndarray, ...], q_via: np.ndarray,
                b: tuple[np.ndarray, ...], T_pass: np.ndarray, settings: TrajectorySettings,
                dt: float) -> tuple[list[JointMove], dict[str, Any]]:
    """Approach or retract moves from state `a` through the backed-off via `q_via` (n,) [rad] to
    state `b`, one of them a pass end whose TCP pose is `T_pass` (4, 4).

    Candidates: stop at the via (at rest), or pass it moving, at the mean joint velocity of
    either leg of the resting version or of both together, full or half (capped at 0.8 of the
    usable joint velocity, as a turn-around's midpoint via). The fastest moving one is used when
    it beats the stop and its TCP comes no closer to the part, along the pass end's spray axis,
    than the resting one does (`VIA_DIP_TOLERANCE_M`: the via exists to back the bell off before
    it turns toward the part). Returns the moves and a record (mode, dip [m] of the chosen moves,
    duration [s], the resting candidate's duration and dip).
    """
    zero = np.zeros_like(q_via)
    rest = [move(a, (q_via, zero, zero)), move((q_via, zero, zero), b)]
    dip_rest = max(_move_dip(robot, m, T_pass, T_pass, dt) for m in rest)
    t_rest = float(sum(m.duration_s for m in rest))
    record = {"mode": "via at rest", "dip_m": dip_rest, "duration_s": t_rest,
              "at_rest_duration_s": t_rest, "at_rest_dip_m": dip_rest}
    v_cap = 0.8 * settings.velocity_margin * np.asarray(robot.v_max, float)
    # Via velocities tried: the mean joint velocity of each leg at rest and of the two together
    # (full and half): the fastest candidate within the dip bound wins.
    mean_v = [(q_via - a[0]) / rest[0].duration_s, (b[0] - q_via) / rest[1].duration_s,
              (b[0] - a[0]) / t_rest]
    best: tuple[float, list[JointMove], float] | None = None
    for qd in [f * v for v in mean_v for f in (2.0, 1.5, 1.0, 0.5)]:
        qd_via = np.clip(qd, -v_cap, v_cap)
        try:
            moving = [move(a, (q_via, qd_via, zero)), move((q_via, qd_via, zero), b)]
        except TrajectoryError:  # this one would leave the joint limits
            continue
        t_moving = float(sum(m.duration_s for m in moving))
        if t_moving >= (t_rest if best is None else best[0]):
            continue
        dip = max(_move_dip(robot, m, T_pass, T_pass, dt) for m in moving)
        if dip <= dip_rest + VIA_DIP_TOLERANCE_M:
            best = (t_moving, moving, dip)
    if best is not None:
        record.update(mode="moving via", dip_m=best[2], duration_s=best[0])
        return best[1], record
    return rest, record


#: Turn-around midpoint vias tried: back-offs as fractions of `turnaround_clearance_m`, and via
#: joint velocities as multiples of the direct move's mean joint velocity.
VIA_CLEARANCE_FRACTIONS = (1.0, 0.75, 0.5, 0.25)
VIA_SPEED_FACTORS = (0.5, 1.0, 1.5, 2.0)


def _backed_off_pair(robot: RobotLike, q_a: np.ndarray, q_b: np.ndarray, clearance_m: float
                     ) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Via poses backed off from both turn-around ends by `clearance_m`, or by 1/2, 1/4 of it
    when that leaves the joint limits: (q_via_a, q_via_b, clearance used [m]), or None."""
    for c in clearance_m * np.array([1.0, 0.5, 0.25]):
        try:
            return (backed_off_via(robot, q_a, float(c)), backed_off_via(robot, q_b, float(c)),
                    float(c))
        except TrajectoryError:
            continue
    return None


def _move_dip(robot: RobotLike, move: JointMove, T_end: np.ndarray, T_next: np.ndarray,
              dt: float) -> float:
    """How much closer to the part [m] the TCP comes during `move` than the deeper of its two
    end poses T_end, T_next (4, 4), along their mean spray axis (sampled every `dt` [s])."""
    q, _, _ = move.sample(np.arange(0.0, move.duration_s + dt, dt))
    p = robot.fk_many(q)[:, :3, 3]
    z = T_end[:3, 2] + T_next[:3, 2]
    z = z / max(float(np.linalg.norm(z)), 1e-12)
    deepest_end = max(0.0, float((T_next[:3, 3] - T_end[:3, 3]) @ z))
    return max(0.0, float(np.max((p - T_end[:3, 3]) @ z)) - deepest_end)


def turnaround_dip(traj: JointTrajectory, T_world_tcp: list[np.ndarray]) -> float:
    """Deepest excursion of the TCP toward the part during turn-arounds [m], beyond the deeper
    of the two pass ends it joins: displacement along the mean spray axis of the two ends
    (≤ 0: the turn-around stays behind both standoff points)."""
    dip = 0.0
    seg = traj.segment
    for i in range(len(T_world_tcp) - 1):
        after = np.flatnonzero(traj.pass_index == i)
        if len(after) == 0:
            continue
        k0 = after[-1] + 1
        rest = np.flatnonzero(seg[k0:] != TURNAROUND)
        k1 = k0 + (int(rest[0]) if len(rest) else len(seg) - k0)
        if k1 == k0:
            continue
        z = T_world_tcp[i][-1, :3, 2] + T_world_tcp[i + 1][0, :3, 2]
        z = z / max(float(np.linalg.norm(z)), 1e-12)
        p_end, p_next = T_world_tcp[i][-1, :3, 3], T_world_tcp[i + 1][0, :3, 3]
        deepest_end = max(0.0, float((p_next - p_end) @ z))
        dip = max(dip, float(np.max((traj.tcp_pos_world[k0:k1] - p_end) @ z)) - deepest_end)
    return dip


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
    q_home = robot.planned_home(q_home)     # a home on a limit starts just inside it
    timing = {"ik": 0.0, "path": 0.0, "toppra": 0.0, "ruckig": 0.0, "sampling": 0.0}

    # --- 1. IK (then joint paths in `_build`) ----------------------------------------------
    # Nothing reachable, or a failure while poses are unreachable, is an `UnreachableError` that
    # carries the IK verdict; a partly unreachable plan that can be timed is (with warnings).
    T_world_tcp = [T_wp @ plan.tcp_frames(i, keep_roll=settings.keep_roll
                                          and not settings.ik_free_spin)
                   for i in range(len(plan.passes))]
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
        s_plan = arc_length(p_plan)
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
