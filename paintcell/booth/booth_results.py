"""Booth metrics, checks and results folder (`paintcell.booth.booth_run` produces the inputs).

Metrics (all in `ValidationReport.metrics`, units in the names):
- cycle: `executed_cycle_time_s` (the booth: the longest robot program, all tracked on one clock),
  `one_robot_cycle_s` (the robots' programs back to back: one robot doing everything, ignoring
  that it could not reach it all), `speedup`;
- per robot: busy share (its own program time ÷ the booth cycle), paint share (brush-on time ÷
  cycle), paint credit (its share of the film volume on the body) and coverage credit (the share
  of the body's area where it lays most of the film); its cycle split into painting / moving /
  waiting at home, paint sent and laid, transfer efficiency (`paintcell.booth.booth_usage`,
  also the booth's and each part's paint), TCP tracking and joint use (`robots_motion`);
- film: planned / trajectory / executed σ/μ over the whole body and in the overlap bands (points
  where two robots each lay ≥ 10 % of the film), the loss split into time law, servo and
  conveyor tracking; per part and the seams (`paintcell.booth.booth_part_film`);
- contacts: all collision events and the robot–robot ones; the smallest distance between two
  bells while both paint (reference programs).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.booth.booth import Booth, Job
from paintcell.booth.booth_cell import BoothCell
from paintcell.booth.booth_part_film import part_film_figures
from paintcell.booth.booth_spec import booth_spec_metrics
from paintcell.booth.booth_usage import booth_usage
from paintcell.core.atomic_io import atomic_write_text
from paintcell.core.json_values import json_default
from paintcell.coverage.plan import CoveragePlan
from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.output.gltf_film import FilmScene, write_film_files
from paintcell.output.report_film import FilmData
from paintcell.surface.surface_data import Surface
from paintcell.validation.paint_spec import spec_checks
from paintcell.validation.validate_motion import robots_motion
from paintcell.validation.validate_report import Check, ValidationReport

#: half-width of the body's spec window as a fraction of its planned mean film (±10 %, as a
#: one-robot run's default `tolerance_fraction`): `executed_within_tolerance_pct` and `film.glb`.
FILM_TOLERANCE = 0.10


def _nsd(film: np.ndarray, areas: np.ndarray, mask: np.ndarray | None = None) -> float:
    from paintcell.booth.booth_film import body_uniformity

    if mask is not None and not mask.any():
        return float("nan")
    return body_uniformity(film, areas, mask)


def _torque_use(trace: ExecutedTrace, tau_max: np.ndarray) -> float:
    """Largest demanded torque ÷ limit over a robot's joints (nan for a kinematic run)."""
    if trace.tau_demand is None:
        return float("nan")
    return float((np.abs(trace.tau_demand) / np.asarray(tau_max, float)).max())


def _within(film: np.ndarray, plan: np.ndarray, areas: np.ndarray) -> float:
    """% of the area within ±10 % of the planned film's area-weighted mean."""
    from paintcell.paint.metrics import uniformity

    target = float(plan @ areas / areas.sum())
    return 100.0 * uniformity(film, areas, target_m=target,
                              tolerance=FILM_TOLERANCE).within_tolerance_fraction


def _least(honest: list[dict[str, Any] | None], key: str) -> float:
    """The least robot's figure `key` [%]; nan when a robot has none (no IK report)."""
    if any(h is None for h in honest):
        return float("nan")
    return min(float(h[key]) for h in honest if h is not None)


def min_bell_distance(trajs: list[JointTrajectory]) -> float:
    """Smallest distance [m] between two robots' TCPs at a step where both paint (inf if never)."""
    best = np.inf
    for i in range(len(trajs)):
        for j in range(i + 1, len(trajs)):
            both = trajs[i].paint_on & trajs[j].paint_on
            if both.any():
                d = np.linalg.norm(trajs[i].tcp_pos_world[both] - trajs[j].tcp_pos_world[both],
                                   axis=1)
                best = min(best, float(d.min()))
    return best


def booth_metrics(booth: Booth, bcell: BoothCell, body: Surface, films: dict[str, np.ndarray],
                  trajs0: list[JointTrajectory], trajs: list[JointTrajectory],
                  traces: list[ExecutedTrace], trace: ExecutedTrace,
                  events: list[dict[str, Any]], record: dict[str, Any],
                  jobs: dict[int, tuple[Job, ...]], part_counts: list[int],
                  plans: list[CoveragePlan], judged: np.ndarray | None = None
                  ) -> ValidationReport:
    """The booth's `ValidationReport` (module doc). trajs0: each robot's own program (static, not
    delayed); trajs: the tracked programs on the booth clock. part_counts: the parts' vertex
    counts, in the order `paintcell.booth.booth_film.merge_surfaces` stacked them into
    `body`. plans: the parts' plans (the jobs' passes are slices of them). judged: (N,) bool,
    the body's vertices the film is judged on (a mesh part's skin, as a one-robot run judges it:
    `paintcell.booth.booth_film.judged_body_mask`); the others count with zero area in every
    film figure. None: every vertex. Each part is held to the booth's paint spec (`Booth.spec`):
    the worst part's σ/μ and share inside the window, measured over the faces whose corners are
    all judged (what a results folder's files give again: `revalidate_booth`)."""
    from paintcell.booth.booth_chain import robot_reachability
    from paintcell.booth.booth_film import overlap_mask

    areas = body.vertex_areas if judged is None else body.vertex_areas * judged
    tot = {k: v.sum(axis=0) for k, v in films.items()}
    band = overlap_mask(films["executed"])
    nsd = {k: _nsd(tot[k], areas) for k in tot}
    cycle = float(trace.t_s[-1] - trace.t_s[0]) + float(trace.meta.get("settle_time_s", 0.0))
    own = [float(tr.duration_s) for tr in trajs0]
    vol = films["executed"] @ areas
    lead = np.argmax(films["executed"], axis=0)
    robots: dict[str, Any] = {}
    honest = [robot_reachability(plans, jobs[i], trajs0[i], trajs[i], traces[i])
              for i in range(len(booth.robots))]
    for i, rspec in enumerate(booth.robots):
        js = jobs[i]
        robots[rspec.name] = {
            "model": rspec.model, "part": "+".join(booth.parts[j.part].part for j in js),
            "passes": [js[0].first, js[0].end] if len(js) == 1
            else [[j.first, j.end] for j in js],
            "busy_share_pct": 100.0 * own[i] / cycle,
            "paint_share_pct": 100.0 * float(trajs[i].paint_on.mean()),
            "paint_credit_pct": 100.0 * float(vol[i] / vol.sum()),
            "coverage_credit_pct": 100.0 * float(areas[lead == i].sum() / areas.sum()),
            "program_s": own[i],
            "start_delay_s": float(trajs[i].meta.get("start_delay_s", 0.0)),
            "conveyor": trajs[i].meta.get("conveyor"),
            "max_torque_utilization": _torque_use(traces[i], bcell.robots[i].tau_max),
            "honest_reachability": honest[i],
        }
    robot_robot = [e for e in events if bcell.robot_of_body(e["body1"]) >= 0
                   and bcell.robot_of_body(e["body2"]) >= 0
                   and bcell.robot_of_body(e["body1"]) != bcell.robot_of_body(e["body2"])]
    tau_use = (np.abs(trace.tau_demand) / bcell.cell.tau_max).max() \
        if trace.tau_demand is not None else float("nan")
    # Per part (the body's vertices are the parts' in order): the parts' films are planned each
    # on its own with its own mean, so the whole body's σ/μ also measures the mean mismatch.
    offs = np.cumsum([0, *part_counts])
    per_part = {f"{i}:{bp.part}": _nsd(tot["executed"][offs[i]:offs[i + 1]],
                                       areas[offs[i]:offs[i + 1]])
                for i, bp in enumerate(booth.parts)}
    m: dict[str, Any] = {
        "planned_nsd_pct": nsd["plan"], "trajectory_nsd_pct": nsd["trajectory"],
        "servo_nsd_pct": nsd["servo"], "executed_nsd_pct": nsd["executed"],
        "part_executed_nsd_pct": per_part,
        "max_part_executed_nsd_pct": max(per_part.values()),
        "part_executed_mean_um": {
            k: 1e6 * float(tot["executed"][offs[i]:offs[i + 1]] @ areas[offs[i]:offs[i + 1]]
                           / areas[offs[i]:offs[i + 1]].sum())
            for i, k in enumerate(per_part)},
        "loss_pp": nsd["executed"] - nsd["plan"],
        "loss_time_law_pp": nsd["trajectory"] - nsd["plan"],
        "loss_servo_pp": nsd["servo"] - nsd["trajectory"],
        "loss_conveyor_pp": nsd["executed"] - nsd["servo"],
        "abs_loss_pp": abs(nsd["executed"] - nsd["plan"]),
        "overlap_band_area_pct": 100.0 * float(areas[band].sum() / areas.sum()),
        "overlap_planned_nsd_pct": _nsd(tot["plan"], areas, band),
        "overlap_executed_nsd_pct": _nsd(tot["executed"], areas, band),
        "executed_mean_um": 1e6 * float(tot["executed"] @ areas / areas.sum()),
        # share of the judged area within ±10 % of the planned mean film (as a one-robot run)
        "executed_within_tolerance_pct": _within(tot["executed"], tot["plan"], areas),
        "planned_within_tolerance_pct": _within(tot["plan"], tot["plan"], areas),
        "executed_cycle_time_s": cycle, "one_robot_cycle_s": float(sum(own)),
        "speedup": float(sum(own)) / cycle,
        # the least robot's honest figure (`honest_reach`); IK alone beside it
        "reachability_pct": _least(honest, "reachability_pct"),
        "ik_reachability_pct": _least(honest, "ik_reachability_pct"),
        # the robots' lost poses by cause, summed (a one-robot run's keys)
        **{f"reach_{k}": (sum(int(h[k]) for h in honest if h) if all(honest) else None)
           for k in ("n_lost", "n_unreachable", "n_joint_jumps", "n_config_flips",
                     "n_contact_poses", "n_slowed_poses")},
        "reachability_verdict": "; ".join(f"{r.name}: {h['verdict']}" for r, h
                                          in zip(booth.robots, honest, strict=True) if h),
        "n_collisions": len(events), "n_robot_robot_collisions": len(robot_robot),
        "min_bell_distance_m": min_bell_distance(trajs),
        "max_torque_utilization": float(tau_use),
        "conveyor_speed_m_s": booth.conveyor.speed_m_s,
        "conveyor_travel_m": booth.conveyor.speed_m_s * float(trace.t_s[-1] - trace.t_s[0]),
        "carrier_tracking_error_max_mm": (
            1e3 * float(np.abs(trace.q[:, bcell.carrier_column]
                               - trajs_carrier(trace, booth, trajs)).max())
            if bcell.carrier_column is not None else 0.0),
        "execution_mode": trace.mode,
        "n_mujoco_warnings": int(sum(trace.meta.get("mujoco_warnings", {}).values())),
    }
    judged_faces = None if judged is None else np.asarray(judged, bool)[body.faces].all(axis=1)
    m.update(booth_spec_metrics(booth, body, tot, areas, judged_faces, offs))
    # each part's film and loss split, the seams; each robot's time, paint and motion
    m.update(part_film_figures(body, tot, areas, judged_faces, offs, list(per_part),
                               1e-6 * m["spec_target_um"], booth.spec))
    names = [r.name for r in booth.robots]
    for per_robot, whole in (booth_usage(names, list(per_part), plans, jobs, trajs, own, trace.t_s,
                                         cycle, films, body.vertex_areas, offs),
                             robots_motion(names, trajs, traces, trace, bcell.columns, np.outer(
                                 trajs_carrier(trace, booth, trajs), booth.conveyor.unit))):
        for name, figures in per_robot.items():
            robots[name].update(figures)
        m.update(whole)
    th = booth.thresholds
    spec = [("collisions", "n_collisions", th.max_collisions, "events", "max"),
            ("robot-robot collisions", "n_robot_robot_collisions", th.max_robot_collisions,
             "events", "max"),
            ("executed σ/μ (whole body)", "executed_nsd_pct", th.max_body_nsd_pct, "%", "max"),
            ("seams' σ/μ ÷ interiors'", "seam_nsd_ratio", th.max_seam_nsd_ratio, "-", "max"),
            ("|uniformity loss|", "abs_loss_pp", th.max_abs_loss_pp, "pp", "max"),
            ("cycle time", "executed_cycle_time_s", th.max_cycle_time_s, "s", "max"),
            ("bell distance", "min_bell_distance_m", th.min_bell_distance_m, "m", "min"),
            ("torque utilization", "max_torque_utilization", th.max_torque_utilization, "-",
             "max"),
            ("joint range utilization", "max_joint_range_utilization",
             th.max_joint_range_utilization, "-", "max"),
            ("reachability", "reachability_pct", th.reachability_pct, "%", "min")]
    checks = []
    for name, key, limit, unit, kind in spec:
        if limit is None:
            continue
        v = float(m[key])
        ok = (v <= limit) if kind == "max" else (v >= limit)
        # A bell distance of inf (never two bells painting at once) passes.
        checks.append(Check(name, v, float(limit), unit, bool(ok and not np.isnan(v)), kind))
    at = sum(c.name in ("collisions", "robot-robot collisions") for c in checks)
    checks[at:at] = spec_checks(m, booth.spec, th.max_executed_nsd_pct,
                                nsd_key="max_part_executed_nsd_pct",
                                inside_key="min_part_executed_inside_spec_pct",
                                what=" (worst part)")
    m["robots"] = robots
    m["allocation"] = record
    return ValidationReport(metrics=m, checks=tuple(checks), reachability=None,
                            collisions=tuple(events), joint_range_utilization=(),
                            torque_utilization=(), planned_thickness_m=tot["plan"],
                            executed_thickness_m=tot["executed"],
                            trajectory_thickness_m=tot["trajectory"])


def trajs_carrier(trace: ExecutedTrace, booth: Booth, trajs: list[JointTrajectory]
                  ) -> np.ndarray:
    """(K,) the carrier's commanded position [m] (the conveyor's nominal motion)."""
    t_ref = float(trajs[0].meta.get("conveyor", {}).get("t_ref_s", 0.0))
    return booth.conveyor.position_m(trace.t_s, t_ref)


def write_booth_results(result: Any, out: Path, robots: list[Any]) -> None:
    """A booth's results folder: metrics.json (booth metrics, per-robot credit, allocation, film
    build), scenario.json (the booth's snapshot and run settings), the parts' plans
    `plan_<part index>.json`, the body surface `body.npz` and `cell.npz` (the parts' vertex
    counts, the judged vertices, the jobs), per robot its static program `static_<robot>.npz`,
    its tracked program `trajectory_<robot>.npz` and its trace `trace_<robot>.npz`, the booth's
    one trace `trace.npz` (with the carrier), one RAPID module per robot, the body's film
    (`film.npz`, `film.glb`: `booth_film`), `booth.png` (`plot_robot_timeline`), `body_film.png`
    (`plot_body_film`) and `report.html` (`paintcell.output.report`, as every cell's).
    `read_booth_results` reads them back."""
    from paintcell.booth.booth_data import booth_snapshot
    from paintcell.booth.booth_film import overlap_mask
    from paintcell.core.atomic_io import atomic_write_npz
    from paintcell.output.export_rapid import cell_modules
    from paintcell.output.plots import plot_body_film, plot_robot_timeline
    from paintcell.output.report import write_report

    booth = result.scenario
    d = result.report.to_dict()
    d["scenario"] = {"name": booth.name, "source": booth.source}
    d["stage_times_s"] = result.timings_s
    atomic_write_text(out / "metrics.json", json_dump(d))
    atomic_write_text(out / "scenario.json",
                      json_dump(booth_snapshot(booth, {"fast": result.fast, "mode": result.mode})))
    for i, plan in enumerate(result.plans):
        plan.save(out / f"plan_{i}.json")
    result.surface.save(out / "body.npz")
    judged = np.ones(len(result.surface.vertices), bool) if result.judged is None \
        else np.asarray(result.judged, bool)
    atomic_write_npz(out / "cell.npz", {
        "part_vertex_counts": np.asarray(result.part_vertex_counts, np.int64), "judged": judged,
        "jobs": np.array([(r, j.part, j.first, j.end) for r, js in sorted(result.jobs.items())
                          for j in js], np.int64).reshape(-1, 4)})
    for spec, st, tr, ex in zip(booth.robots, result.static_trajectories, result.trajectories,
                                result.traces, strict=True):
        st.save_npz(out / f"static_{spec.name}.npz")
        tr.save_npz(out / f"trajectory_{spec.name}.npz")
        ex.save_npz(out / f"trace_{spec.name}.npz")
    if result.trace is not None:
        result.trace.save_npz(out / "trace.npz")
    m = result.report.metrics
    for name, text in cell_modules(booth, m, result.jobs, result.static_trajectories,
                                   robots).items():
        atomic_write_text(out / f"{name}.mod", text)
    plot_robot_timeline(out / "booth.png", [r.name for r in booth.robots], result.trajectories,
                        [len(s.t_s) for s in result.static_trajectories], m,
                        f"{booth.name}: conveyor {m['conveyor_speed_m_s']:.3f} m/s")
    ex = result.films_m["executed"]
    plot_body_film(out / "body_film.png", result.surface, result.part_vertex_counts, ex,
                   [r.name for r in booth.robots], band=overlap_mask(ex),
                   title=f"{booth.name}: executed film over the whole body "
                         f"(σ/μ {m['executed_nsd_pct']:.2f} %)")
    write_film_files(out, *booth_film(booth, result.surface, result.judged, result.films_m,
                                      result.plans))
    write_report(out)


def read_booth_results(out: Path, booth: Booth, read: Any) -> dict[str, Any]:
    """The data files `write_booth_results` wrote into `out`, for `booth` (from the folder's
    snapshot): plans, body, part_vertex_counts, judged, jobs, and per robot static,
    trajectories, traces, with the booth's trace. read(name, loader): reads one file, naming
    it in a one-line error when it is missing or unreadable."""
    cell = read("cell.npz", lambda p: dict(np.load(p)))
    jobs: dict[int, tuple[Job, ...]] = {}
    for r, part, first, end in np.asarray(cell["jobs"], int).reshape(-1, 4):
        jobs[int(r)] = (*jobs.get(int(r), ()), Job(int(part), int(first), int(end)))
    names = [r.name for r in booth.robots]
    return {
        "plans": [read(f"plan_{i}.json", CoveragePlan.load) for i in range(len(booth.parts))],
        "body": read("body.npz", Surface.load),
        "part_vertex_counts": [int(n) for n in cell["part_vertex_counts"]],
        "judged": np.asarray(cell["judged"], bool), "jobs": jobs,
        "static": [read(f"static_{n}.npz", JointTrajectory.load_npz) for n in names],
        "trajectories": [read(f"trajectory_{n}.npz", JointTrajectory.load_npz) for n in names],
        "traces": [read(f"trace_{n}.npz", ExecutedTrace.load_npz) for n in names],
        "trace": read("trace.npz", ExecutedTrace.load_npz),
    }


def revalidate_booth(booth: Booth, files: dict[str, Any], metrics: dict[str, Any]
                     ) -> tuple[ValidationReport, dict[str, np.ndarray]]:
    """The booth's `ValidationReport` recomputed from its results folder's files
    (`read_booth_results`), with the robots' films (kind → (R, N) [m]) on the body: every metric
    and check; `metrics` (the folder's metrics.json) gives the allocation, film build and seam
    records the run made before it executed."""
    from paintcell.booth.booth_cell import build_booth_cell
    from paintcell.booth.booth_film import robot_films
    from paintcell.booth.booth_programs import load_robots
    from paintcell.validation.validate_motion import collision_events

    body, plans, jobs = files["body"], files["plans"], files["jobs"]
    trajs, traces, trace = files["trajectories"], files["traces"], files["trace"]
    bcell = build_booth_cell(load_robots(booth), body, booth.body_placement.matrix,
                             booth.conveyor)
    t_ref = float(trajs[0].meta["conveyor"]["t_ref_s"])
    films = robot_films(booth, bcell, body, plans, jobs,
                        [bp.placement.matrix for bp in booth.parts], trajs, traces, trace, t_ref)
    report = booth_metrics(booth, bcell, body, films, files["static"], trajs, traces, trace,
                           collision_events(trace), metrics.get("allocation", {}), jobs,
                           files["part_vertex_counts"], plans, files["judged"])
    for key in ("film_build", "seams"):
        if key in metrics:
            report.metrics[key] = metrics[key]
    return report, films


def booth_film(booth: Booth, body: Surface, judged: np.ndarray | None,
               films_m: dict[str, np.ndarray], plans: list[CoveragePlan]
               ) -> tuple[FilmData, FilmScene]:
    """The body's film (the robots' films `films_m` summed; the window of the booth's paint
    spec, `Booth.spec`, as its checks hold every part to: around `film_target_um`, else the
    planned area-weighted mean of the judged area) and its 3-D scene: the body at conveyor
    position 0, every part's passes moved into the body frame, every robot's base."""
    n = len(body.vertices)
    judged = np.ones(n, bool) if judged is None else np.asarray(judged, bool)
    areas = np.asarray(body.vertex_areas, float)
    planned = films_m["plan"].sum(axis=0)
    w = areas * judged
    own = (1e-6 * booth.film_target_um if booth.film_target_um is not None
           else float(planned @ w / w.sum()))
    faces = np.asarray(body.faces, np.int64)
    # with the mesh and judged faces (corners all judged), film.npz's share of the judged area
    # inside the spec window is the one metrics.json gives
    film = FilmData(planned, films_m["executed"].sum(axis=0), areas, judged,
                    booth.spec.target_m(own), 0.01 * booth.spec.window_pct,
                    np.asarray(body.vertices, float), faces,
                    np.asarray(judged[faces].all(axis=1), bool))
    passes = []
    for bp, plan in zip(booth.parts, plans, strict=True):
        T = bp.placement.matrix
        passes += [np.asarray(p.positions, float) @ T[:3, :3].T + T[:3, 3] for p in plan.passes]
    scene = FilmScene(np.asarray(body.vertices, float), faces,
                      np.asarray(body.normals, float), film, passes,
                      booth.body_placement.matrix, {r.name: r.base.matrix for r in booth.robots},
                      frame="body")
    return film, scene


def json_dump(d: dict[str, Any]) -> str:
    """JSON of a metrics dict (numpy scalars made plain)."""
    return json.dumps(d, indent=2, default=json_default)
