"""Plan versus executed: how much coat uniformity the robot lost, and why.

Three thickness maps go through the same deposition model (`planning.deposition.thickness`) on
the same surface (part frame):

- plan: the plan's ideal TCP samples at planned timing (`plan.gun_samples()`);
- trajectory: the `JointTrajectory`'s own paint-on TCP samples (ideal kinematics, at the time law's
  timing: TOPP-RA slowdowns, the free bell spin IK chose, turn-around timing), where the part was
  planned to be;
- executed: the executed TCP trace (`trace.gun_samples(T_part_world)`, where the part really was
  when a placement disturbance moved it).

The trajectory and executed maps use the same 1 ms samples merged into the same bins, so a
kinematic replay gives the same film to round-off. The loss (executed − planned σ/μ, percentage
points) splits into its two causes: `loss_time_law_pp` = trajectory − plan (what the time law and
IK did to the plan) and `loss_servo_pp` = executed − trajectory (what execution did: servo
tracking, and any disturbance of the part or TCP); `loss_pp` is their sum, exactly. Beside it:
thickness differences, coverage inside the ±tolerance window, TCP tracking and speed-following
errors on paint segments, cycle time, joint and torque utilization (torque from what the servo
demanded before the actuator clamp, so it exceeds 1 when a joint saturates), reachability and
collisions — each checked against caller thresholds.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from planning.atomic_io import atomic_write_text
from planning.deposition import GunSamples, thickness
from planning.errors import PaintcellError
from planning.metrics import transfer_efficiency, uniformity
from planning.plan import CoveragePlan
from planning.surface import Surface
from planning.transforms import inverse_pose
from sim.honest_reach import honest_reachability
from sim.joint_trajectory import JointTrajectory
from sim.region_film import region_film
from sim.trace import ExecutedTrace

#: contacts of the same body pair closer than this in time belong to one collision event [s].
_EVENT_GAP_S = 0.0105


class ValidationError(PaintcellError):
    """Plan, trajectory and trace cannot be compared (mismatched lengths, frames, parts)."""


@dataclass(frozen=True)
class Thresholds:
    """Pass/fail limits of a validation (inf or None disables a check).

    reachability_pct: minimum share of plan poses the robot reaches [%].
    max_collisions: maximum number of collision events: robot–part, robot–booth and robot–robot
        (self-collision, e.g. the wrist driven into the robot's base).
    max_executed_nsd_pct: maximum executed film σ/μ over the part [%].
    max_loss_pp: maximum loss of uniformity, executed − planned σ/μ [percentage points].
    max_abs_loss_pp: maximum |executed − planned σ/μ| [percentage points]: a large negative loss
        (executed more uniform than planned) is a departure from the plan too. None: unchecked.
    max_cycle_time_s: maximum executed cycle time [s].
    max_tracking_error_mm: maximum TCP position error on paint segments [mm].
    max_speed_error_pct: maximum RMS TCP speed-following error on paint segments [%].
    max_torque_utilization: maximum |τ_demand|/τ_max of any joint, τ_demand the torque the
        controller demanded before the actuator clamp (> 1: the joint saturated) [-].
    max_joint_range_utilization: maximum |q − mid|/half-range of any joint (1 = at a limit) [-].
    tolerance: half-width of the thickness window around the planned mean [fraction].
    """

    reachability_pct: float | None = 100.0
    max_collisions: int | None = 0
    max_executed_nsd_pct: float | None = 20.0
    max_loss_pp: float | None = 1.0
    max_abs_loss_pp: float | None = None
    max_cycle_time_s: float | None = 120.0
    max_tracking_error_mm: float | None = None
    max_speed_error_pct: float | None = None
    max_torque_utilization: float | None = 1.0
    max_joint_range_utilization: float | None = 1.0
    tolerance: float = 0.10

    def __post_init__(self) -> None:
        if not (0 < self.tolerance < 1):
            raise ValidationError(f"tolerance = {self.tolerance} must be a fraction in (0, 1)")


@dataclass(frozen=True)
class Check:
    """One threshold check: value vs limit; kind "max" (value ≤ limit) or "min" (value ≥ limit)."""

    name: str
    value: float
    limit: float
    unit: str
    passed: bool
    kind: str = "max"
    detail: str = ""


@dataclass(frozen=True, eq=False)
class ValidationReport:
    """Plan-vs-executed metrics (scalars in `metrics`, report units in the key names).

    metrics: JSON-safe scalars (σ/μ in %, thickness in µm, errors in mm / %, times in s).
    checks: one `Check` per enabled threshold; passed: all checks passed.
    reachability: summary dict from the robots' reachability report (or None).
    collisions: collision events (bodies, start/end time [s], max depth [m], samples).
    joint_range_utilization / torque_utilization: per joint, max fraction [-] (torque: demanded
        before the actuator clamp, so > 1 where the joint saturated).
    torque_saturation_pct: per joint, share of program steps whose demanded torque exceeded
        τ_max [%].
    planned_thickness_m / executed_thickness_m / trajectory_thickness_m: (N,) film per surface
        vertex [m] (plots only).
    """

    metrics: dict[str, Any]
    checks: tuple[Check, ...]
    reachability: dict[str, Any] | None
    collisions: tuple[dict[str, Any], ...]
    joint_range_utilization: tuple[float, ...]
    torque_utilization: tuple[float, ...]
    planned_thickness_m: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    executed_thickness_m: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    trajectory_thickness_m: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    torque_saturation_pct: tuple[float, ...] = ()

    @property
    def passed(self) -> bool:
        """True when every enabled check passed."""
        return all(c.passed for c in self.checks)

    @property
    def loss_pp(self) -> float:
        """Executed − planned σ/μ [percentage points]."""
        return float(self.metrics["loss_pp"])

    def __getattr__(self, name: str) -> Any:
        # Scalar metrics read as attributes too (report.executed_nsd_pct).
        metrics = self.__dict__.get("metrics", {})
        if name in metrics:
            return metrics[name]
        raise AttributeError(name)

    def to_dict(self) -> dict[str, Any]:
        """JSON-serializable report (no thickness arrays; nan/inf → None)."""
        d: dict[str, Any] = {k: _json_num(v) for k, v in self.metrics.items()}
        d["passed"] = self.passed
        d["checks"] = [{k: _json_num(v) for k, v in asdict(c).items()} for c in self.checks]
        d["reachability"] = self.reachability
        d["collisions"] = list(self.collisions)
        d["joint_range_utilization"] = [_json_num(x) for x in self.joint_range_utilization]
        d["torque_utilization"] = [_json_num(x) for x in self.torque_utilization]
        d["torque_saturation_pct"] = [_json_num(x) for x in self.torque_saturation_pct]
        return d

    def save_json(self, path: str | Path) -> None:
        """Write `to_dict()` as JSON atomically."""
        atomic_write_text(path, json.dumps(self.to_dict(), indent=2, allow_nan=False))


def _json_num(v: Any) -> Any:
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    return v


def collision_events(trace: ExecutedTrace, gap_s: float = _EVENT_GAP_S) -> list[dict[str, Any]]:
    """Group per-step contacts into events: same body pair, consecutive in time (≤ gap_s [s]).

    Self-collisions (both bodies robot links, the distal one as body1) are events like any other.
    """
    events: list[dict[str, Any]] = []
    open_by_pair: dict[tuple[str, str], dict[str, Any]] = {}
    for c in sorted(trace.contacts, key=lambda c: c.time_s):
        key = (c.body1, c.body2)
        ev = open_by_pair.get(key)
        if ev is not None and c.time_s - ev["t_end_s"] <= gap_s:
            ev["t_end_s"] = c.time_s
            ev["max_depth_m"] = max(ev["max_depth_m"], c.depth_m)
            ev["samples"] += 1
        else:
            ev = {"body1": c.body1, "body2": c.body2, "t_start_s": c.time_s, "t_end_s": c.time_s,
                  "max_depth_m": c.depth_m, "samples": 1}
            events.append(ev)
            open_by_pair[key] = ev
    return events


def tracking_errors(traj: JointTrajectory, trace: ExecutedTrace) -> dict[str, float]:
    """TCP tracking and speed-following errors (executed trace vs the trajectory's FK reference).

    Returns max / RMS position error [mm] on paint samples and over the whole program, the max
    orientation error of the spray axis [deg] on paint samples, and the speed-following error of
    the executed TCP speed against the trajectory's planned speed on paint samples (RMS and max,
    [%] of the planned speed).
    """
    if len(trace.t_s) != len(traj.t_s):
        raise ValidationError(f"trace has {len(trace.t_s)} samples, trajectory {len(traj.t_s)}; "
                              "validate the trace that was executed from this trajectory")
    err = np.linalg.norm(trace.tcp_pos_world - traj.tcp_pos_world, axis=1)
    paint = np.asarray(traj.paint_on, bool)
    z_exec, z_ref = trace.tcp_rot_world[:, :, 2], traj.tcp_rot_world[:, :, 2]
    cosang = np.clip(np.sum(z_exec * z_ref, axis=1), -1.0, 1.0)
    ang = np.degrees(np.arccos(cosang))
    v_exec = np.linalg.norm(np.gradient(trace.tcp_pos_world, trace.t_s, axis=0), axis=1)
    v_plan = np.asarray(traj.v_tcp_planned, float)
    use = paint & (v_plan > 1e-6)
    rel = (v_exec[use] - v_plan[use]) / v_plan[use] if np.any(use) else np.zeros(1)
    p = err[paint] if np.any(paint) else np.zeros(1)
    return {
        "tracking_error_max_mm": 1e3 * float(p.max()),
        "tracking_error_rms_mm": 1e3 * float(np.sqrt(np.mean(p**2))),
        "tracking_error_max_all_mm": 1e3 * float(err.max()),
        "tracking_error_rms_all_mm": 1e3 * float(np.sqrt(np.mean(err**2))),
        "spray_axis_error_max_deg": float(ang[paint].max()) if np.any(paint) else 0.0,
        "speed_error_rms_pct": 100.0 * float(np.sqrt(np.mean(rel**2))),
        "speed_error_max_pct": 100.0 * float(np.abs(rel).max()),
        "speed_error_mean_pct": 100.0 * float(rel.mean()),
    }


def _utilization(trace: ExecutedTrace) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per joint: max |q − mid| / half-range, max |τ_demand| / τ_max and the share of steps with
    |τ_demand| > τ_max [%] (limits from `trace.meta`; traces without `tau_demand` fall back to
    the applied torque, which the clamp keeps ≤ τ_max)."""
    n = trace.q.shape[1]
    lo = np.asarray([np.nan if x is None else x for x in trace.meta.get("q_lower", [None] * n)],
                    float)
    hi = np.asarray([np.nan if x is None else x for x in trace.meta.get("q_upper", [None] * n)],
                    float)
    tau_max = np.asarray(trace.meta.get("tau_max", [np.nan] * n), float)
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    tau = np.abs(trace.tau if trace.tau_demand is None else trace.tau_demand)
    with np.errstate(invalid="ignore", divide="ignore"):
        q_use = np.max(np.abs(trace.q - mid) / half, axis=0)
        tau_use = np.max(tau, axis=0) / tau_max
        saturated = 100.0 * np.mean(tau > tau_max, axis=0)
    return q_use, tau_use, np.where(np.isfinite(tau_max), saturated, np.nan)


def _reachability_summary(reach: dict[str, Any] | None) -> tuple[dict[str, Any] | None, float]:
    if reach is None:
        return None, float("nan")
    summary = {k: v for k, v in reach.items() if k != "poses"}
    if "reachability_pct" in reach:
        pct = float(reach["reachability_pct"])
    elif reach.get("n_poses"):
        pct = 100.0 * float(reach["n_reachable"]) / float(reach["n_poses"])
    else:
        pct = float("nan")
    summary["reachability_pct"] = pct
    return summary, pct


def executed_gun_samples(trace: ExecutedTrace, T_part_world: np.ndarray,
                         sample_s: float | None = 0.005) -> GunSamples:
    """Paint-on trace samples in the part frame, merged into bins of `sample_s` [s].

    Each contiguous brush-on run is cut into bins of ⌈sample_s/dt⌉ steps; a bin sits at its
    dwell-weighted mean position with its middle step's axes and the bin's summed dwell (the
    midpoint rule). At ≤ 1 m/s a 5 ms bin spans
    ≤ 5 mm of travel against a footprint σ of ~50 mm; on the door program the film differs from
    the every-step sum by < 1e-5 relative (σ/μ by 2e-5 pp) at a fifth of the cost.
    None: every step.
    """
    return _binned(trace.gun_samples(T_part_world), trace.t_s, trace.paint_on, sample_s)


def trajectory_gun_samples(traj: JointTrajectory, T_part_world: np.ndarray,
                           sample_s: float | None = 0.005) -> GunSamples:
    """The trajectory's own paint-on TCP samples (ideal kinematics at the time law's timing) in
    the part frame, sampled and binned exactly as `executed_gun_samples` does a trace."""
    ideal = ExecutedTrace(
        t_s=traj.t_s, q=traj.q, qd=traj.qd, tau=np.zeros_like(traj.q),
        tcp_pos_world=traj.tcp_pos_world, tcp_rot_world=traj.tcp_rot_world,
        paint_on=traj.paint_on, pass_index=traj.pass_index, mode="kinematic")
    return executed_gun_samples(ideal, T_part_world, sample_s)


def _binned(full: GunSamples, t_s: np.ndarray, paint_on: np.ndarray,
            sample_s: float | None) -> GunSamples:
    """`full` (one sample per paint-on step of `t_s`) merged into bins of `sample_s` [s]."""
    if sample_s is None or len(t_s) < 2:
        return full
    dt = float(t_s[1] - t_s[0])
    m = max(1, int(math.ceil(sample_s / dt - 1e-9)))
    if m == 1:
        return full
    idx = np.flatnonzero(np.asarray(paint_on, bool))
    run_id = np.concatenate([[0], np.cumsum(np.diff(idx) > 1)])
    pos_in_run = np.arange(len(idx)) - np.searchsorted(run_id, run_id)
    bin_key = run_id * (len(idx) + 1) + pos_in_run // m
    starts = np.flatnonzero(np.concatenate([[True], bin_key[1:] != bin_key[:-1]]))
    ends = np.append(starts[1:], len(idx))
    mid = (starts + ends - 1) // 2
    dwell = np.add.reduceat(full.dwell_s, starts)
    # Time-centroid of the bin (exact midpoint also for even and partial bins at run ends).
    pos = np.add.reduceat(full.positions * full.dwell_s[:, None], starts) / dwell[:, None]
    return GunSamples(positions=pos, spray_axes=full.spray_axes[mid],
                      travel_dirs=full.travel_dirs[mid], dwell_s=dwell)


def validate(plan: CoveragePlan, surface: Surface, traj: JointTrajectory, trace: ExecutedTrace,
             T_world_part: npt.ArrayLike, thresholds: Thresholds | None = None,
             reachability: dict[str, Any] | None = None,
             exec_sample_s: float | None = 0.005,
             films: tuple[np.ndarray, np.ndarray] | None = None) -> ValidationReport:
    """Compare the executed program with the plan.

    plan: the coverage plan (part frame); surface: the part it covers (part frame, the same mesh
    the cell shows); traj: the joint trajectory that was executed; trace: what MuJoCo did;
    T_world_part: (4, 4) planned placement of the part [m] (the trace's `meta` says where the part
    really was when a placement disturbance moved it); thresholds: pass/fail limits;
    reachability: `ReachabilityReport.to_dict()` of the IK stage (per-pose arrays dropped).
    exec_sample_s: bin of the executed trace and of the trajectory for the deposition sum [s]
    (see `executed_gun_samples`; None: every 1 ms step).
    films: (planned, trajectory) films (N,) [m] of this plan, surface, trajectory and placement
    computed earlier (a sweep computes them once): taken instead of recomputed (neither depends
    on how the program was executed).
    """
    thresholds = thresholds or Thresholds()
    T_world_part = np.asarray(T_world_part, float)
    if T_world_part.shape != (4, 4):
        raise ValidationError(f"T_world_part has shape {T_world_part.shape}; pass a 4x4 pose")
    T_actual = np.asarray(trace.meta.get("T_world_part_actual", T_world_part), float)
    planned_T = trace.meta.get("T_world_part_planned")
    if planned_T is not None and not np.allclose(planned_T, T_world_part, atol=1e-9):
        raise ValidationError("the trace was executed with a different part placement than "
                              "T_world_part; validate with the scenario's placement")
    if plan.surface_name and surface.name and plan.surface_name != surface.name:
        raise ValidationError(f"plan covers {plan.surface_name!r} but the surface is "
                              f"{surface.name!r}; load the plan's part")

    app = plan.applicator
    pts, nrm, areas = surface.vertices, surface.normals, surface.vertex_areas
    gun_plan = plan.gun_samples()
    if not np.any(trace.paint_on):
        raise ValidationError("the trace has no paint-on samples; the trajectory never painted")
    if not np.any(traj.paint_on):
        raise ValidationError("the trajectory has no paint-on samples; rebuild it from the plan")
    gun_exec = executed_gun_samples(trace, inverse_pose(T_actual), exec_sample_s)
    t_exec = thickness(app, gun_exec, pts, nrm)
    if films is not None:
        t_plan, t_traj = (np.asarray(f, float) for f in films)
        if t_plan.shape != (len(pts),) or t_traj.shape != (len(pts),):
            raise ValidationError(f"films must be two ({len(pts)},) arrays, one value a surface "
                                  "vertex; pass the films of this plan and surface")
    else:
        t_plan = thickness(app, gun_plan, pts, nrm)
        # The program as built: its own TCP samples where the part was planned to be.
        t_traj = thickness(app, trajectory_gun_samples(traj, inverse_pose(T_world_part),
                                                       exec_sample_s), pts, nrm)
    judged = surface.judged_vertex_mask()  # a real part: its skin by default; else every vertex
    u_plan = uniformity(t_plan, areas, mask=judged, tolerance=thresholds.tolerance)
    u_exec = uniformity(t_exec, areas, mask=judged, target_m=u_plan.mean_m,
                        tolerance=thresholds.tolerance)
    u_traj = uniformity(t_traj, areas, mask=judged, target_m=u_plan.mean_m,
                        tolerance=thresholds.tolerance)
    loss_time_law = u_traj.nsd_pct - u_plan.nsd_pct
    loss_servo = u_exec.nsd_pct - u_traj.nsd_pct
    diff = t_exec - t_plan
    rms_diff = float(np.sqrt(np.dot(areas, diff**2) / areas.sum()))

    trk = tracking_errors(traj, trace)
    q_use, tau_use, tau_sat = _utilization(trace)
    reach_summary, _ = _reachability_summary(reachability)
    # Jumps, wrist flips, contacts and slowdowns count against reachability (sim.honest_reach).
    honest = honest_reachability(plan, traj, trace, reachability)
    reach_pct = float("nan") if honest is None else float(honest["reachability_pct"])
    if reach_summary is not None and honest is not None:
        reach_summary["ik_reachability_pct"] = reach_summary["reachability_pct"]
        reach_summary["reachability_pct"] = reach_pct
        reach_summary["honest"] = honest
        reach_summary["verdict"] = f"{reach_summary.get('verdict', '')}; {honest['verdict']}"
    events = collision_events(trace)
    dt = float(trace.t_s[1] - trace.t_s[0]) if len(trace.t_s) > 1 else 0.0

    metrics: dict[str, Any] = {
        "planned_nsd_pct": u_plan.nsd_pct,
        "trajectory_nsd_pct": u_traj.nsd_pct,
        "executed_nsd_pct": u_exec.nsd_pct,
        # executed − planned, split into its two causes; the sum is the headline, exactly.
        "loss_pp": loss_time_law + loss_servo,
        "loss_time_law_pp": loss_time_law,
        "loss_servo_pp": loss_servo,
        "abs_loss_pp": abs(loss_time_law + loss_servo),
        "planned_mean_um": 1e6 * u_plan.mean_m,
        "executed_mean_um": 1e6 * u_exec.mean_m,
        "trajectory_mean_um": 1e6 * u_traj.mean_m,
        "planned_min_um": 1e6 * u_plan.min_m, "planned_max_um": 1e6 * u_plan.max_m,
        "executed_min_um": 1e6 * u_exec.min_m, "executed_max_um": 1e6 * u_exec.max_m,
        "max_thickness_diff_um": 1e6 * float(np.abs(diff).max()),
        "rms_thickness_diff_um": 1e6 * rms_diff,
        "tolerance_fraction": thresholds.tolerance,
        "planned_within_tolerance_pct": 100.0 * u_plan.within_tolerance_fraction,
        "executed_within_tolerance_pct": 100.0 * u_exec.within_tolerance_fraction,
        "trajectory_within_tolerance_pct": 100.0 * u_traj.within_tolerance_fraction,
        **trk,
        "planned_cycle_time_s": traj.duration_s,
        # The program's own time plus the time the arm needs to settle on its last pose.
        "executed_cycle_time_s": float(trace.t_s[-1] - trace.t_s[0])
        + float(trace.meta.get("settle_time_s", 0.0)),
        "settle_time_s": float(trace.meta.get("settle_time_s", 0.0)),
        "planned_paint_time_s": plan.paint_time_s,
        "executed_paint_time_s": dt * float(np.count_nonzero(trace.paint_on)),
        # Paint on the part ÷ paint the bell emitted while the brush was on (film volumes).
        "planned_transfer_efficiency_pct": 100.0 * transfer_efficiency(
            t_plan, areas, app.emitted_flow_m3_s * float(gun_plan.dwell_s.sum())),
        "executed_transfer_efficiency_pct": 100.0 * transfer_efficiency(
            t_exec, areas, app.emitted_flow_m3_s * float(gun_exec.dwell_s.sum())),
        "max_joint_range_utilization": float(np.nanmax(q_use)) if len(q_use) else float("nan"),
        "max_torque_utilization": float(np.nanmax(tau_use)) if len(tau_use) else float("nan"),
        "max_torque_saturation_pct": (float(np.nanmax(tau_sat)) if len(tau_sat)
                                      else float("nan")),
        "torque_source": "applied" if trace.tau_demand is None else "demanded",
        "reachability_pct": reach_pct,
        "ik_reachability_pct": float("nan") if honest is None else honest["ik_reachability_pct"],
        **({} if honest is None else {f"reach_{k}": honest[k] for k in (
            "n_lost", "n_unreachable", "n_joint_jumps", "n_config_flips", "n_contact_poses",
            "n_slowed_poses")}),
        "reachability_verdict": "" if honest is None else honest["verdict"],
        "n_collisions": len(events),
        "n_contact_samples": len(trace.contacts),
        "max_contact_depth_mm": 1e3 * max((c.depth_m for c in trace.contacts), default=0.0),
        "execution_mode": trace.mode,
        "n_mujoco_warnings": int(sum(trace.meta.get("mujoco_warnings", {}).values())),
        "part_placement_error_mm": 1e3 * float(np.linalg.norm(T_actual[:3, 3]
                                                              - T_world_part[:3, 3])),
    }
    # hems, flanges, turned edges: their film reported apart (not judged)
    metrics.update(region_film(surface, t_plan, t_exec, u_exec.mean_m))
    checks = _checks(metrics, thresholds)
    return ValidationReport(
        metrics=metrics, checks=tuple(checks), reachability=reach_summary,
        collisions=tuple(events),
        joint_range_utilization=tuple(float(x) for x in q_use),
        torque_utilization=tuple(float(x) for x in tau_use),
        planned_thickness_m=t_plan, executed_thickness_m=t_exec, trajectory_thickness_m=t_traj,
        torque_saturation_pct=tuple(float(x) for x in tau_sat))


def _checks(m: dict[str, Any], th: Thresholds) -> list[Check]:
    spec = [  # (name, metric key, limit, unit, kind)
        ("reachability", "reachability_pct", th.reachability_pct, "%", "min"),
        ("collisions", "n_collisions", th.max_collisions, "events", "max"),
        ("executed σ/μ", "executed_nsd_pct", th.max_executed_nsd_pct, "%", "max"),
        ("uniformity loss", "loss_pp", th.max_loss_pp, "pp", "max"),
        ("|uniformity loss|", "abs_loss_pp", th.max_abs_loss_pp, "pp", "max"),
        ("cycle time", "executed_cycle_time_s", th.max_cycle_time_s, "s", "max"),
        ("TCP tracking error", "tracking_error_max_mm", th.max_tracking_error_mm, "mm", "max"),
        ("speed-following error", "speed_error_rms_pct", th.max_speed_error_pct, "%", "max"),
        ("torque utilization", "max_torque_utilization", th.max_torque_utilization, "-", "max"),
        ("joint range utilization", "max_joint_range_utilization",
         th.max_joint_range_utilization, "-", "max"),
    ]
    out = []
    for name, key, limit, unit, kind in spec:
        if limit is None or not math.isfinite(float(limit)):
            continue
        value = float(m[key])
        if not math.isfinite(value):
            if key == "reachability_pct":  # no reachability report given: nothing to check
                continue
            passed = False
        else:
            passed = value <= limit if kind == "max" else value >= limit
        detail = ""
        if key == "reachability_pct" and not passed:
            detail = str(m.get("reachability_verdict", ""))
        out.append(Check(name=name, value=value, limit=float(limit), unit=unit,
                         passed=bool(passed), kind=kind, detail=detail))
    return out
