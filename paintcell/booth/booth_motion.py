"""Each booth robot's execution figures as a one-robot run measures its robot's
(`paintcell.validation.validate_motion`), `paintcell.booth.booth_results` reports them.

Per robot, its executed trace (cut from the booth's one trace) against its tracked program on
the booth clock: the TCP tracking error on paint samples and over the whole program [mm], the
spray axis's largest tilt from the reference on paint samples [deg], the speed-following error
of the TCP's speed over the moving body against the planned speed [%], the largest joint range
use (|q − mid| ÷ half-range, its rail included) and its contact samples with their deepest
penetration [mm]. The booth's figures are the worst robot's; its contact samples are the booth
trace's (a robot–robot contact once).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.validation.validate_motion import tracking_errors, utilization

__all__ = ["booth_motion"]

_WORST = ("tracking_error_max_mm", "tracking_error_max_all_mm", "spray_axis_error_max_deg",
          "speed_error_max_pct", "max_joint_range_utilization", "max_contact_depth_mm")


def booth_motion(names: list[str], trajs: list[JointTrajectory], traces: list[ExecutedTrace],
                 trace: ExecutedTrace, columns: tuple[np.ndarray, ...], body_shift_m: np.ndarray
                 ) -> tuple[dict[str, dict[str, float]], dict[str, Any]]:
    """(per robot figures, booth figures) (module doc). trajs / traces: each robot's tracked
    program and executed trace on the booth clock; trace: the booth's one trace (its joint
    limits in `meta`); columns: each robot's columns in the booth's joint vector;
    body_shift_m: (K, 3) the body's nominal displacement on the line at each time stamp [m],
    taken off both TCPs so the speeds are the TCP's over the body, as the plan times them (the
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
    booth: dict[str, Any] = {}
    for k in _WORST:
        v = np.array([r[k] for r in robots.values()], float)
        booth[k] = float(np.nanmax(v)) if np.isfinite(v).any() else float("nan")
    booth["n_contact_samples"] = len(trace.contacts)     # a robot–robot contact counts once
    return robots, booth
