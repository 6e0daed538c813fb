"""Plan versus executed: how much coat uniformity the robot lost, and why.

Three thickness maps go through the same deposition model
(`paintcell.paint.deposition.thickness`) on
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
thickness differences, the share of the judged area inside the paint spec's window
(`paintcell.validation.paint_spec`: the spec's checks replace a bare σ/μ limit), the pieces
painted and not (`paintcell.validation.painted_side`), coverage inside the ±tolerance window, TCP
tracking and speed-following errors on paint segments, cycle time, joint and torque utilization
(torque from what the servo demanded before the actuator clamp, so it exceeds 1 when a joint
saturates), reachability and collisions — each checked against caller thresholds.

The result types and threshold checks (`paintcell.validation.validate_report`), the motion
metrics (`paintcell.validation.validate_motion`) and the binned TCP samples
(`paintcell.validation.validate_samples`) are modules of their
own, imported from where they are defined.
"""

from __future__ import annotations

import threading
from concurrent.futures import Future
from dataclasses import replace
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.core.transforms import inverse_pose
from paintcell.coverage.plan import CoveragePlan
from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.paint.deposition import thickness
from paintcell.paint.metrics import transfer_efficiency, uniformity
from paintcell.surface.surface_data import Surface
from paintcell.validation.honest_reach import honest_reachability
from paintcell.validation.paint_spec import PaintSpec, spec_checks, spec_metrics
from paintcell.validation.painted_side import painted_side_checks, painted_side_metrics
from paintcell.validation.region_film import region_film
from paintcell.validation.validate_motion import collision_events, tracking_errors, utilization
from paintcell.validation.validate_report import (
    Thresholds,
    ValidationError,
    ValidationReport,
    threshold_checks,
)
from paintcell.validation.validate_samples import executed_gun_samples, trajectory_gun_samples

__all__ = ["program_films", "start_program_films", "validate"]


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


def validate(plan: CoveragePlan, surface: Surface, traj: JointTrajectory, trace: ExecutedTrace,
             T_world_part: npt.ArrayLike, thresholds: Thresholds | None = None,
             reachability: dict[str, Any] | None = None,
             exec_sample_s: float | None = 0.005,
             films: tuple[np.ndarray, np.ndarray] | None = None,
             spec: PaintSpec | None = None) -> ValidationReport:
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
    spec: the paint spec the executed film is judged against (`paintcell.validation.paint_spec`;
    None: its defaults, centred on the planned mean film of the judged area).
    """
    thresholds = thresholds or Thresholds()
    spec = spec or PaintSpec()
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
        t_plan, t_traj = program_films(plan, surface, traj, T_world_part, exec_sample_s)
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
    q_use, tau_use, tau_sat = utilization(trace)
    reach_summary, _ = _reachability_summary(reachability)
    # Jumps, wrist flips, contacts and slowdowns count against reachability
    # (paintcell.validation.honest_reach).
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
        "max_joint_range_utilization": _max_or_nan(q_use),
        "max_torque_utilization": _max_or_nan(tau_use),
        "max_torque_saturation_pct": (_max_or_nan(tau_sat) if len(tau_sat)
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
    # the paint spec: the executed film against its window, area-weighted over the judged faces
    faces_judged = None if surface.regions is None else surface.regions.face_mask()
    target = spec.target_m(u_plan.mean_m)
    metrics.update(spec_metrics(t_plan, pts, surface.faces, faces_judged, target, spec,
                                "planned"))
    metrics.update(spec_metrics(t_exec, pts, surface.faces, faces_judged, target, spec))
    metrics.update({"spec_window_pct": spec.window_pct,
                    "spec_min_inside_pct": spec.min_inside_pct,
                    "spec_max_nsd_pct": spec.max_nsd_pct})
    metrics.update(painted_side_metrics(surface))
    # the spec's σ/μ check replaces the threshold's (which can only tighten it)
    checks = threshold_checks(metrics, replace(thresholds, max_executed_nsd_pct=None))
    at = sum(c.name in ("reachability", "collisions") for c in checks)
    checks[at:at] = spec_checks(metrics, spec, thresholds.max_executed_nsd_pct)
    checks += painted_side_checks(metrics)
    return ValidationReport(
        metrics=metrics, checks=tuple(checks), reachability=reach_summary,
        collisions=tuple(events),
        joint_range_utilization=tuple(float(x) for x in q_use),
        torque_utilization=tuple(float(x) for x in tau_use),
        planned_thickness_m=t_plan, executed_thickness_m=t_exec, trajectory_thickness_m=t_traj,
        torque_saturation_pct=tuple(float(x) for x in tau_sat))


def program_films(plan: CoveragePlan, surface: Surface, traj: JointTrajectory,
                  T_world_part: npt.ArrayLike, exec_sample_s: float | None = 0.005,
                  threads: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """(planned, trajectory) films (N,) [m] on `surface.vertices`: the plan's ideal TCP samples at
    planned timing, and the program as built (its own paint-on TCP samples, binned by
    `exec_sample_s` [s], where the part was planned to be, `T_world_part` (4, 4) [m]). Neither
    depends on how the program was executed: `validate(..., films=...)` takes them.
    threads: the film kernel's threads (the films do not depend on it)."""
    app, pts, nrm = plan.applicator, surface.vertices, surface.normals
    t_plan = thickness(app, plan.gun_samples(), pts, nrm, threads=threads)
    gun = trajectory_gun_samples(traj, inverse_pose(np.asarray(T_world_part, float)),
                                 exec_sample_s)
    return t_plan, thickness(app, gun, pts, nrm, threads=threads)


def start_program_films(plan: CoveragePlan, surface: Surface, traj: JointTrajectory,
                        T_world_part: npt.ArrayLike, exec_sample_s: float | None = 0.005
                        ) -> Future[tuple[np.ndarray, np.ndarray]]:
    """`program_films` on a background thread, one kernel thread: started before `execute`, the
    films are computed on the core MuJoCo leaves idle (its step loops release the GIL, so does
    the film kernel). Pass `.result()` to `validate(films=...)`: the same films as validate
    computes itself, bit for bit (the kernel's sum does not depend on its thread count).
    A daemon thread: an interrupted run exits without waiting for it."""
    fut: Future[tuple[np.ndarray, np.ndarray]] = Future()

    def work() -> None:
        if not fut.set_running_or_notify_cancel():
            return
        try:
            fut.set_result(program_films(plan, surface, traj, T_world_part, exec_sample_s,
                                         threads=1))
        except BaseException as exc:  # raised again by fut.result() in the caller's thread
            fut.set_exception(exc)

    threading.Thread(target=work, name="paintcell-films", daemon=True).start()
    return fut


def _max_or_nan(x: np.ndarray) -> float:
    """np.nanmax without its All-NaN warning: NaN when every entry is NaN (a kinematic run has
    no torques)."""
    x = np.asarray(x, float)
    known = x[~np.isnan(x)]
    return float(known.max()) if known.size else float("nan")
