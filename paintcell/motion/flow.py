"""The bell flow a program commands along its passes: a brush table that follows the time law.

The film a sample lays is the flow times the time the bell spends there (every rate of the ESRB
model is linear in the flow, `paintcell.paint.applicator`). Where the joint limits keep the TCP
slower than the plan, the film is thicker than planned by the inverse of the speed ratio. A paint
robot's process controller sets the flow per stretch of path (brush events along the pass, each
selecting a level of the brush table); so the program lowers the flow where the time law is slow
by the ratio of the plan's time to the program's over that stretch, and the film keeps the plan's
build there.

- Levels: multiples of `FLOW_STEP` from `flow_min` (the lowest flow the bell atomizes well at, a
  fraction of the part's flow: `TrajectorySettings.flow_min`) up to 1. Below `flow_min` the
  film is thicker than planned by what is left (and the speed caps of
  `paintcell.motion.speed_caps` bring the plan under what the robot reaches).
- Stretches: `FLOW_STRETCH_M` of arc length along each pass; each gets the plan's time over the
  program's time on its brush-on samples (the mean of v_program / v_plan, each sample's ratio
  taken at most 1: the flow never rises above the part's), rounded to the nearest level. A
  level holds over its whole stretch, so the brush events (RAPID `SetBrush`) are at least that
  far apart.

The speed the film sees is the program's speed ÷ the flow: what honest reachability compares
with the plan, pose by pose (`paintcell.validation.honest_reach`), and what the speed caps
(`paintcell.motion.speed_caps`) bring the plan under (`cap_speed`). The robot-aware re-plans
trust the flow first: the first caps a plan gets hold it to the film's speed everywhere, so a
stretch the lowest flow nearly covers asks little more of the robot. From the next round on,
where the flow still sits at its lowest level the caps take the TCP's own speed (the plan is
brought under what the robot reached, as at constant flow): capped at the film's speed there
round after round, a plan went on asking up to 1 / `flow_min` × what the robot reached, and the
steeper braking into the slow spot made the arm slower still (the rounds did not settle).
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: Resolution of the brush table's flow levels [-] (a fraction of the part's flow).
FLOW_STEP = 0.02
#: Arc length along a pass over which one flow level holds [m].
FLOW_STRETCH_M = 0.02


def brush_flow(s_m: np.ndarray, v_program_m_s: np.ndarray, v_plan_m_s: np.ndarray,
               paint_on: np.ndarray, pass_index: np.ndarray, flow_min: float,
               stretch_m: float = FLOW_STRETCH_M, step: float = FLOW_STEP) -> np.ndarray:
    """(K,) the flow a program commands ÷ its part's flow [-], at uniformly timed samples.

    s_m: (K,) arc length along the current pass [m] (nan off the passes); v_program_m_s /
    v_plan_m_s: (K,) the program's and the plan's TCP speed [m/s]; paint_on: (K,) brush on;
    pass_index: (K,) pass of each sample (-1 between passes); flow_min: lowest level (0, 1].
    1 wherever the brush is off, the plan is met, or `flow_min` is 1.
    """
    k = len(s_m)
    flow = np.ones(k)
    on = (np.asarray(paint_on, bool) & (np.asarray(pass_index) >= 0) & np.isfinite(s_m)
          & (np.asarray(v_plan_m_s) > 0))
    if flow_min >= 1.0 or not on.any():
        return flow
    idx = np.flatnonzero(on)
    ratio = np.minimum(np.asarray(v_program_m_s, float)[idx] / np.asarray(v_plan_m_s)[idx], 1.0)
    # one key per (pass, stretch); the passes are contiguous runs of samples
    stretch = np.floor(np.asarray(s_m)[idx] / stretch_m).astype(np.int64)
    pidx = np.asarray(pass_index)[idx].astype(np.int64)
    stretch -= stretch.min()
    _, key = np.unique(pidx * (int(stretch.max()) + 1) + stretch, return_inverse=True)
    mean = np.bincount(key, ratio) / np.bincount(key)
    level = np.clip(np.round(mean / step) * step, lowest_level(flow_min, step), 1.0)
    flow[idx] = level[key]
    return flow


def lowest_level(flow_min: float, step: float = FLOW_STEP) -> float:
    """The lowest flow level of the brush table [-]: `flow_min` rounded up to the step."""
    return float(min(np.ceil(flow_min / step - 1e-9) * step, 1.0))


def cap_speed(v_m_s: np.ndarray, traj: Any, idx: np.ndarray, trust_floor: bool = False
              ) -> np.ndarray:
    """The speed [m/s] the caps hold a program's samples `idx` to (module doc): the TCP speed
    `v_m_s` ÷ the flow the program commands there (`JointTrajectory.flow`); unless
    `trust_floor`, `v_m_s` itself where the flow sits at its lowest level (`flow_min` of the
    program's settings, `JointTrajectory.meta`)."""
    v = np.asarray(v_m_s, float)
    flow = np.asarray(getattr(traj, "flow", np.ones(len(traj.t_s))), float)[idx]
    f_min = float(getattr(traj, "meta", {}).get("settings", {}).get("flow_min", 1.0))
    floor = lowest_level(f_min)
    at_floor = (not trust_floor) & (floor < 1.0) & (flow <= floor + 1e-9)
    return np.where(at_floor, v, v / flow)
