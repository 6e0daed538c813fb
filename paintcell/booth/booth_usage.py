"""What a booth's robots spend over one booth cycle: time (painting, moving, waiting at home) and
paint (sent, laid on the body, transfer efficiency), `paintcell.booth.booth_results` reports it.

Time, per robot, over the booth cycle (the booth's trace from its first time stamp to its last,
plus the settle time): each trace sample stands for the time to the next one (the last one for
the rest of the cycle, the settle included), and counts as
- painting: inside the robot's program on one of its planned passes (the program's
  `pass_index` ≥ 0, brush on or off: a seam's switched-off samples are still pass time);
- moving: inside its program, between passes (approach, turn-arounds, job changes, retract);
- waiting at home: outside its program, its arm at home: before its start delay
  (`paintcell.booth.booth_stagger`) and after its program ended. A rail carriage may ride with
  the line meanwhile; the arm stands still.
The three shares add up to 100 % of the cycle; painting + moving is the robot's own program
time (the `busy_share_pct` beside them).

Paint, in film volume (the deposition model's unit, `Applicator.emitted_flow_m3_s`: the volume
of film the bell's spray would lay, not the wet paint with its solvent): sent = the bell's flow ×
the time its brush is on (× the flow its brush table commands there), per job at its part's
flow (`paintcell.booth.booth_build`); laid on
the body = ∫ film dA over the whole body mesh (judged or not); transfer efficiency = laid ÷
sent. Overspray that misses every part is the difference.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from paintcell.booth.booth import Job
from paintcell.booth.booth_film import job_paint
from paintcell.core.errors import PaintcellError
from paintcell.coverage.plan import CoveragePlan
from paintcell.motion.joint_trajectory import JointTrajectory

__all__ = ["L_PER_M3", "booth_usage", "paint_sent_m3", "time_shares"]

#: litres in a cubic metre.
L_PER_M3 = 1000.0


class UsageError(PaintcellError):
    """A booth's time stamps or program window cannot be measured (empty or out of order)."""


def time_shares(t_s: np.ndarray, in_pass: np.ndarray, start_s: float, program_s: float,
                cycle_s: float) -> dict[str, float]:
    """One robot's painting / moving / waiting shares of the booth cycle (module doc).

    t_s: (K,) the booth trace's time stamps [s], increasing; in_pass: (K,) bool, the robot's
    program on a planned pass at that sample; start_s: its program's start after t_s[0] [s];
    program_s: its program's duration [s]; cycle_s: the booth cycle [s] (≥ t_s[-1] − t_s[0]).
    Returns `painting_s`, `moving_s`, `waiting_s` and their `*_share_pct` (sum 100)."""
    t = np.asarray(t_s, float)
    on = np.asarray(in_pass, bool)
    if len(t) < 2 or on.shape != t.shape or np.any(np.diff(t) <= 0):
        raise UsageError("a robot's trace needs ≥ 2 increasing time stamps and one pass flag "
                         "each; re-run the booth")
    if cycle_s < t[-1] - t[0] - 1e-9:
        raise UsageError(f"booth cycle {cycle_s:.3f} s is shorter than its trace "
                         f"({t[-1] - t[0]:.3f} s); re-run the booth")
    span = np.diff(np.append(t, t[0] + max(cycle_s, t[-1] - t[0])))
    half = 0.5 * float(np.min(np.diff(t)))    # a sample on a window edge: on the later side
    rel = t - t[0]
    own = (rel >= start_s - half) & (rel < start_s + program_s - half)
    out = {"painting_s": float(span[own & on].sum()), "moving_s": float(span[own & ~on].sum()),
           "waiting_s": float(span[~own].sum())}
    total = float(span.sum())
    out.update({f"{k.removesuffix('_s')}_share_pct": 100.0 * v / total
                for k, v in list(out.items())})
    return out


def paint_sent_m3(apps_on: list[tuple[Any, np.ndarray]], t_s: np.ndarray,
                  flow: np.ndarray | None = None) -> float:
    """Film volume the bell sent [m³]: Σ over (applicator, brush-on mask (K,)) pairs of the
    applicator's flow [m³/s] × the brush-on time, each sample standing for its step (the
    midpoint rule the film's dwell uses, `ExecutedTrace.gun_samples`) times the flow the
    program commands there (`flow` (K,) [-], None: 1)."""
    dt = np.gradient(np.asarray(t_s, float))
    if flow is not None:
        dt = dt * np.asarray(flow, float)
    return float(sum(app.emitted_flow_m3_s * float(dt[np.asarray(on, bool)].sum())
                     for app, on in apps_on))


def _planned_sent_m3(plans: list[CoveragePlan], jobs: tuple[Job, ...]) -> float:
    """Film volume one robot's jobs send at planned timing [m³]: flow × the plan's dwell."""
    return float(sum(plans[j.part].applicator.emitted_flow_m3_s
                     * sum(float(p.dwell_s()[p.paint_on].sum())
                           for p in plans[j.part].passes[j.first:j.end])
                     for j in jobs))


def _pct(part: float, whole: float) -> float:
    """100 · part ÷ whole [%]; nan when nothing was sent."""
    return 100.0 * part / whole if whole > 0 else float("nan")


def booth_usage(names: list[str], part_keys: list[str], plans: list[CoveragePlan],
                jobs: dict[int, tuple[Job, ...]], trajs: list[JointTrajectory],
                program_s: list[float], t_s: np.ndarray, cycle_s: float,
                films: dict[str, np.ndarray], areas_m2: np.ndarray, offs: np.ndarray
                ) -> tuple[dict[str, dict[str, float]], dict[str, Any]]:
    """(per robot figures, booth figures) of time and paint (module doc).

    names: the robots; part_keys: the parts' "index:name"; trajs: the tracked programs on the
    booth clock (their `start_delay_s`, pass flags and brush); program_s: each robot's own
    program time [s]; t_s: the booth trace's time stamps [s]; films: kind → (R, N) film [m];
    areas_m2: (N,) every body vertex's area; offs: (P + 1,) the parts' first vertices, then N.
    Booth figures: `paint_used_l`, `planned_paint_used_l`, `film_on_body_l`, the executed and
    planned `*_transfer_efficiency_pct`, `bell_on_time_s` (summed over robots) and per part
    (`part_paint`) the paint its jobs sent and the film on it from every robot."""
    areas = np.asarray(areas_m2, float)
    robots: dict[str, dict[str, float]] = {}
    sent_part = np.zeros(len(part_keys))
    sent = np.zeros(len(names))
    planned_sent = np.zeros(len(names))
    bell_on = 0.0
    dt = np.gradient(np.asarray(t_s, float))
    for i, (name, tr) in enumerate(zip(names, trajs, strict=True)):
        r = time_shares(t_s, tr.pass_index >= 0, float(tr.meta.get("start_delay_s", 0.0)),
                        program_s[i], cycle_s)
        per_job = job_paint(plans, jobs[i], tr)
        for j, pair in zip(jobs[i], per_job, strict=True):
            sent_part[j.part] += paint_sent_m3([pair], t_s, tr.flow)
        sent[i] = paint_sent_m3(per_job, t_s, tr.flow)
        planned_sent[i] = _planned_sent_m3(plans, jobs[i])
        bell_on += float(dt[tr.paint_on].sum())
        laid = float(films["executed"][i] @ areas)
        robots[name] = {
            **{k: r[k] for k in ("painting_share_pct", "moving_share_pct", "waiting_share_pct",
                                 "painting_s", "moving_s", "waiting_s")},
            "paint_used_l": L_PER_M3 * sent[i], "film_on_body_l": L_PER_M3 * laid,
            "transfer_efficiency_pct": _pct(laid, float(sent[i]))}
    laid_all = float(films["executed"].sum(axis=0) @ areas)
    planned_laid = float(films["plan"].sum(axis=0) @ areas)
    body = films["executed"].sum(axis=0) * areas
    on_part = [float(body[offs[k]:offs[k + 1]].sum()) for k in range(len(part_keys))]
    booth = {
        "paint_used_l": L_PER_M3 * float(sent.sum()),
        "planned_paint_used_l": L_PER_M3 * float(planned_sent.sum()),
        "film_on_body_l": L_PER_M3 * laid_all,
        "executed_transfer_efficiency_pct": _pct(laid_all, float(sent.sum())),
        "planned_transfer_efficiency_pct": _pct(planned_laid, float(planned_sent.sum())),
        "bell_on_time_s": bell_on,
        "part_paint": {k: {"paint_used_l": L_PER_M3 * float(sent_part[p]),
                           "film_on_part_l": L_PER_M3 * on_part[p]}
                       for p, k in enumerate(part_keys)},
    }
    return robots, booth
