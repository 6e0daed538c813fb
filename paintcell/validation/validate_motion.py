"""How the executed motion went: TCP tracking and speed-following errors against the trajectory,
joint-range and torque utilization, and collision events grouped from per-step contacts; for one
robot, or per robot of a cell of N with the cell's worst (`robots_motion`).

Errors in mm, degrees and % of the planned speed; utilizations as fractions [-]; times [s].
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.validation.validate_report import ValidationError

#: contacts of the same body pair closer than this in time belong to one collision event [s].
_EVENT_GAP_S = 0.0105


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


def utilization(trace: ExecutedTrace) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


#: the cell's figure is its worst robot's (`robots_motion`).
_WORST = ("tracking_error_max_mm", "tracking_error_max_all_mm", "spray_axis_error_max_deg",
          "speed_error_max_pct", "max_joint_range_utilization", "max_contact_depth_mm")


def robots_motion(names: list[str], trajs: list[JointTrajectory], traces: list[ExecutedTrace],
                  trace: ExecutedTrace, columns: tuple[np.ndarray, ...], body_shift_m: np.ndarray
                  ) -> tuple[dict[str, dict[str, float]], dict[str, Any]]:
    """(per robot figures, the cell's figures) of a cell of N robots: each robot's executed trace
    (cut from the cell's one trace) against its program on the cell's clock, as `tracking_errors`
    measures one robot's, with its largest joint range use (`utilization`, its rail included),
    its contact samples and their deepest penetration [mm]; the cell's figures are the worst
    robot's, its contact samples the one trace's (a robot–robot contact once).

    trajs / traces: each robot's program and executed trace on the cell clock; trace: the cell's
    one trace (its joint limits in `meta`); columns: each robot's columns in its joint vector;
    body_shift_m: (K, 3) the part's nominal displacement on a conveyor at each time stamp [m],
    taken off both TCPs so the speeds are the TCP's over the part, as the plan times them (the
    position and axis errors do not change: both TCPs shift alike)."""
    q_use, _, _ = utilization(trace)
    shift = np.asarray(body_shift_m, float)
    robots: dict[str, dict[str, float]] = {}
    for name, tr, ex, cols in zip(names, trajs, traces, columns, strict=True):
        use = q_use[cols]
        robots[name] = {
            **tracking_errors(replace(tr, tcp_pos_world=tr.tcp_pos_world - shift),
                              replace(ex, tcp_pos_world=ex.tcp_pos_world - shift)),
            "max_joint_range_utilization": (float(np.nanmax(use)) if np.isfinite(use).any()
                                            else float("nan")),
            "n_contact_samples": len(ex.contacts),
            "max_contact_depth_mm": 1e3 * max((c.depth_m for c in ex.contacts), default=0.0),
        }
    cell: dict[str, Any] = {}
    for k in _WORST:
        v = np.array([r[k] for r in robots.values()], float)
        cell[k] = float(np.nanmax(v)) if np.isfinite(v).any() else float("nan")
    cell["n_contact_samples"] = len(trace.contacts)     # a robot–robot contact counts once
    return robots, cell
