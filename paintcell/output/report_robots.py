"""The robots of a cell in `report.html`: a section a robot (its figures, reachability,
collisions, program), for one robot and for each of several alike; for several, what they share:
the cycle against one robot doing it all, each robot's time and paint, how the work was shared.

From the results folder's files: metrics.json (several robots: `robots`, each one's figures, and
`allocation`; one robot: the run's figures are its own), each robot's own program
(`static_<name>.npz`; one robot: `trajectory.npz`) and RAPID module.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from paintcell.output.export_rapid import task_names
from paintcell.output.report_names import ROBOT_FIGURES
from paintcell.output.report_sections import (
    collisions_html,
    headline_html,
    kv_table,
    slowdowns_html,
    values_table,
)

#: each robot's time and paint, side by side: metrics key → column.
_USE = {"painting_share_pct": "painting [% of cycle]", "moving_share_pct": "moving [% of cycle]",
        "waiting_share_pct": "waiting at home [% of cycle]", "paint_used_l": "paint sent [L]",
        "film_on_body_l": "film on the body [L]",
        "transfer_efficiency_pct": "transfer efficiency [%]",
        "tracking_error_max_mm": "TCP error on passes, max [mm]",
        "speed_error_rms_pct": "speed error over the body, RMS [%]",
        "max_joint_range_utilization": "joint range use, max [-]"}


@dataclass(frozen=True)
class RobotRun:
    """One robot of a results folder: its name (one robot: its model), its figures (one robot:
    the run's), its own program's file, the start of its bodies' names in a collision event."""

    name: str
    figures: dict[str, Any]
    program: Path
    prefix: str


def robot_runs(d: Path, metrics: dict[str, Any], scenario: dict[str, Any] | None
               ) -> list[RobotRun]:
    """The robots of results folder `d`, in the order the cell numbers them."""
    robots = metrics.get("robots")
    if isinstance(robots, dict) and robots:
        from paintcell.execution.cell_robots import robot_prefix

        return [RobotRun(str(n), f if isinstance(f, dict) else {}, d / f"static_{n}.npz",
                         robot_prefix(i)) for i, (n, f) in enumerate(robots.items())]
    return [RobotRun(str((scenario or {}).get("robot") or "robot"), metrics,
                     d / "trajectory.npz", "")]


def _span(passes: Sequence[Any]) -> str:
    """'pass 3' / 'passes 1–6' from [first, end) counted from 0 (a list of them: joined with
    '+'), numbered from 1 as the report's pass tables are."""
    if passes and isinstance(passes[0], list | tuple):
        return " + ".join(_span(list(x)) for x in passes)
    a, b = passes
    return f"pass {a + 1}" if b - a == 1 else f"passes {a + 1}–{b}"


def _jobs_text(jobs: dict[str, Any], names: list[str], parts: list[str],
               est: dict[str, float] | None = None) -> str:
    """'side_a: fender passes 1–6 (24.8 s); ...' from {robot (index or name): [part, first,
    end] or a list of them} and optionally each robot's estimated program time [s]."""
    out = []
    for r, v in jobs.items():
        rn = names[int(r)] if str(r).isdigit() else str(r)
        t = f" ({est[r]:.1f} s)" if est is not None and r in est else ""
        triples = v if isinstance(v[0], list | tuple) else [v]
        work = " then ".join(f"{parts[int(p)]} {_span([a, b])}" for p, a, b in triples)
        out.append(f"{rn}: {work}{t}")
    return "; ".join(out)


def robot_section(d: Path, run: RobotRun, metrics: dict[str, Any]) -> str:
    """One robot's section: what it paints, its figures, reachability, collisions, program."""
    f = run.figures
    ident = html.escape(run.name)
    what = ", ".join(html.escape(str(x)) for x in (
        f.get("model"), f.get("part") and f"{f['part']} {_span(f['passes'])}") if x)
    # a one-robot run's figures are the run's, shown under Key figures already
    figures = "" if f is metrics else headline_html(f, ROBOT_FIGURES)
    out = [f"<section id='robot-{ident}'><h2>Robot {ident}</h2>"
           + (f"<p>{what}.</p>" if what else "") + figures]
    reach = f.get("honest_reachability", metrics.get("reachability"))
    out.append("<h3>Reachability</h3>" + (
        f"<p>{html.escape(str(reach.get('verdict', '')))}</p><details><summary>reachability "
        "details (metrics.json)</summary>" + kv_table(reach) + "</details>"
        if isinstance(reach, dict) else "<p>no reachability summary in metrics.json</p>"))
    out.append("<h3>Collisions</h3>" + collisions_html(metrics, d, run.prefix))
    module = d / f"{task_names([run.name])[0]}.mod"
    out.append("<h3>Program and slowdowns</h3>" + slowdowns_html(run.program)
               + (f"<p>Its RAPID module: <code>{html.escape(module.name)}</code>.</p>"
                  if run.prefix and module.is_file() else ""))
    return "\n".join(out) + "</section>"


def cell_html(metrics: dict[str, Any], scenario: dict[str, Any] | None) -> str:
    """The first screen of a cell of several robots: its cycle against one robot doing every
    program, the whole body's σ/μ, and each robot's time and paint."""
    m, robots = metrics, metrics["robots"]
    parts = [str(p.get("part")) for p in (scenario or {}).get("parts", [])]
    return (f"<div id='cell'><p>{len(robots)} robots paint {html.escape(' + '.join(parts))} on a "
            f"conveyor at {m['conveyor_speed_m_s']:.3f} m/s "
            f"({60 * m['conveyor_speed_m_s']:.1f} m/min). Cycle <b id='cycle'>"
            f"{m['executed_cycle_time_s']:.2f} s</b> against {m['one_robot_cycle_s']:.2f} s for "
            f"one robot running every program back to back ({m['speedup']:.2f}×). Whole-body "
            f"executed σ/μ <b id='body-nsd'>{m['executed_nsd_pct']:.2f} %</b>.</p>"
            + values_table(["robot", *_USE.values()],
                           [[n, *map(r.get, _USE)] for n, r in robots.items()], "robot-use",
                           (2, 2, 2, 2, 4, 4, 2, 2, 2, 2)) + "</div>")


def sharing_html(metrics: dict[str, Any], scenario: dict[str, Any] | None) -> str:
    """A cell of several robots: how the work was shared (the allocation's candidates, the ones
    built, the one chosen) and the robot-aware speed rounds."""
    from paintcell.motion.moves import APPROACH_RETRACT_S, TURN_S

    names = ([str(r.get("name")) for r in (scenario or {}).get("robots", [])]
             or list(metrics["robots"]))
    parts = [str(p.get("part")) for p in (scenario or {}).get("parts", [])]
    a = metrics.get("allocation", {})
    alloc = [f"<h2>How the work was shared</h2><p>Rule: {html.escape(str(a.get('rule', '')))}.</p>"]
    if "candidates" in a:
        alloc.append(f"<p>{a['candidates']} assignments enumerated (each part whole or cut in "
                     f"two at a pass boundary, at most one job per robot); {a['feasible']} put "
                     "every pass within its robot's reach. They are ranked by their longest "
                     f"estimated program (paint time + {TURN_S} s per turn-around + "
                     f"{APPROACH_RETRACT_S} s approach and retract), then the next longest, and "
                     "so on:</p>")
        alloc.append(values_table(
            ["rank", "jobs (estimated program)", "longest estimate [s]"],
            [[k + 1, _jobs_text(c["jobs"], names, parts, c.get("estimated_s")),
              max(c["estimated_programs_s"])] for k, c in enumerate(a.get("best_ranked", []))]))
    if "tried" in a:
        alloc.append("<p>The estimate knows nothing of the start delays that keep the arms "
                     "apart, so the best ranked were built, staggered and timed; the shortest "
                     "real cycle (start delay + own program, the longest robot) was taken:</p>")
        alloc.append(values_table(
            ["rank", "jobs", "start delays [s]", "real cycle [s]"],
            [[t["rank"], _jobs_text(t["jobs"], names, parts),
              (", ".join(f"{d:.2f}" for d in t["start_delays_s"]) if "start_delays_s" in t
               else t.get("rejected", t.get("skipped", ""))), t.get("real_cycle_s")]
             for t in a["tried"]]))
    else:
        alloc += [f"<p>Rejected: {html.escape(_jobs_text(r['jobs'], names, parts))} — "
                  f"{html.escape(r['rejected'])}</p>" for r in a.get("rejected", [])]
    if "chosen" in a:
        alloc.append(f"<p id='chosen'>Chosen: {html.escape(_jobs_text(a['chosen'], names, parts))}"
                     f"; start delays {', '.join(f'{d:.2f}' for d in a.get('start_delays_s', []))}"
                     " s (each the shortest cycle that keeps every two arms apart).</p>")
    sf = a.get("speed_feedback", {})
    if sf.get("rounds"):
        alloc.append("<h2>Robot-aware speeds</h2>"
                 f"<p>{html.escape(str(sf.get('rule', '')))}. Round 0 is the plans as the "
                 "planner made them; each later round is planned again under the speeds the "
                 "robots reached:</p>" + values_table(
                     ["round", "newly capped samples", "largest speed deficit [%]",
                      "cycle [s]", "re-planned", "not taken"],
                     [[k, r["capped_samples"], r["max_deficit_pct"], r["cycle_s"],
                       ", ".join(r.get("replanned", [])), r.get("rejected", "")]
                      for k, r in enumerate(sf["rounds"])]))
    return "\n".join(alloc)
