"""Films of a booth on the merged body surface, in the body frame (`paintcell.booth.booth_run`
uses them).

The body's film is the sum of the robots' films. Kinds: plan (each robot's passes at planned
timing), trajectory (its tracked reference TCP against the nominal body position), servo (the
executed TCP against the nominal body position) and executed (the executed TCP against where the
carrier really was): see `paintcell.booth.booth_run` for the loss split they give.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from paintcell.booth.booth import Booth, Job
from paintcell.booth.booth_cell import BoothCell
from paintcell.coverage.plan import CoveragePlan
from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.paint.deposition import thickness
from paintcell.paint.deposition_samples import GunSamples
from paintcell.paint.metrics import uniformity
from paintcell.surface.surface_data import Surface
from paintcell.validation.validate_samples import executed_gun_samples

#: a point is in an overlap band when at least two robots each lay this share of its film.
OVERLAP_SHARE = 0.10


def merge_surfaces(parts: list[Surface], T_body_part: list[np.ndarray], name: str) -> Surface:
    """One surface in the body frame from parts (each moved by its (4, 4) placement)."""
    moved = [s.transformed(T) for s, T in zip(parts, T_body_part, strict=True)]
    offs = np.cumsum([0] + [len(s.vertices) for s in moved[:-1]])
    cat = {f: np.concatenate([getattr(s, f) for s in moved])
           for f in ("vertices", "normals", "vertex_areas", "gaussian_curvature",
                     "mean_curvature", "principal_curvatures", "principal_directions")}
    faces = np.concatenate([s.faces + o for s, o in zip(moved, offs, strict=True)])
    return Surface(name=name, vertices=cat["vertices"], faces=faces, normals=cat["normals"],
                   vertex_areas=cat["vertex_areas"], gaussian_curvature=cat["gaussian_curvature"],
                   mean_curvature=cat["mean_curvature"],
                   principal_curvatures=cat["principal_curvatures"],
                   principal_directions=cat["principal_directions"])


def judged_body_mask(parts: list[Surface]) -> np.ndarray:
    """(N,) bool over `merge_surfaces(parts, …)`'s vertices: a mesh part's judged regions
    (`Surface.judged_vertex_mask`, its skin), every vertex of a part without regions."""
    masks = [s.judged_vertex_mask() for s in parts]
    return np.concatenate([np.ones(len(s.vertices), bool) if m is None else np.asarray(m, bool)
                           for s, m in zip(parts, masks, strict=True)])


def plan_gun_in_body(plan: CoveragePlan, T_body_part: np.ndarray) -> GunSamples:
    """A plan's paint-on gun samples moved from its part frame into the body frame."""
    g = plan.gun_samples()
    R, t = T_body_part[:3, :3], T_body_part[:3, 3]
    return GunSamples(positions=g.positions @ R.T + t, spray_axes=g.spray_axes @ R.T,
                      travel_dirs=g.travel_dirs @ R.T, dwell_s=g.dwell_s)


def booth_disturbances(table: dict[str, Any]) -> Any:
    """A booth's `disturbances` table as the `Disturbances` its one execution runs under (None:
    an empty table, the nominal cell)."""
    from paintcell.core.settings import settings_from
    from paintcell.execution.execute import Disturbances

    return settings_from(Disturbances, table, "disturbances") if table else None


def disturbed_robot(trace: ExecutedTrace, pos: np.ndarray, rot: np.ndarray,
                    traj: JointTrajectory, cell: Any
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, float]]:
    """One robot's share of the booth trace's disturbances (`trace.meta`, as `execute` realized
    them): its TCP positions (K, 3) [m] moved by the TCP offset in its tool frame `rot`
    (K, 3, 3), its program's (`traj`) paint trigger (K,) and commanded flow (K,) [-] shifted by
    the trigger delay, and the flow factors its film takes (`ExecutedTrace.gun_samples`); the
    nominal ones without a disturbance."""
    d = trace.meta.get("disturbances")
    if d is None:
        return pos, traj.paint_on, traj.flow, {}
    from paintcell.execution.execute import Disturbances

    off = np.asarray(trace.meta.get("tcp_offset_tool_m", (0.0, 0.0, 0.0)), float)
    dist, dt = Disturbances(**d), cell.model.opt.timestep
    return (pos + rot @ off, dist.paint_on(traj.paint_on, dt), dist.flow(traj.flow, dt),
            {k: float(trace.meta[k]) for k in ("flow_scale", "flow_drift") if k in trace.meta})


def gun_in_body(t_s: np.ndarray, pos: np.ndarray, rot: np.ndarray, paint_on: np.ndarray,
                T_world_body0: np.ndarray, carrier_m: np.ndarray, unit: np.ndarray,
                flow: dict[str, float] | None = None,
                brush: np.ndarray | None = None) -> GunSamples:
    """Binned paint-on gun samples of a TCP trace (K,) in the body frame, the body at
    T_world_body0 shifted by carrier_m (K,) [m] along unit (3,); flow: a flow disturbance's
    `flow_scale` / `flow_drift` (`ExecutedTrace.gun_samples`); brush: (K,) the commanded flow
    ÷ the part's [-] (None: 1)."""
    R, t0 = T_world_body0[:3, :3], T_world_body0[:3, 3]
    p_body = (pos - t0 - carrier_m[:, None] * unit) @ R
    rot_body = np.einsum("ji,kjl->kil", R, rot)
    body_trace = ExecutedTrace(t_s=t_s, q=np.zeros((len(t_s), 1)), qd=np.zeros((len(t_s), 1)),
                               tau=np.zeros((len(t_s), 1)), tcp_pos_world=p_body,
                               tcp_rot_world=rot_body, paint_on=paint_on,
                               pass_index=np.zeros(len(t_s), int), mode="kinematic",
                               meta=dict(flow or {}), flow=brush)
    return executed_gun_samples(body_trace, np.eye(4))


def robot_films(booth: Booth, bcell: BoothCell, body: Surface, plans: list[CoveragePlan],
                jobs: dict[int, tuple[Job, ...]], T_bp: list[np.ndarray],
                trajs: list[JointTrajectory], traces: list[ExecutedTrace] | None,
                trace: ExecutedTrace | None, t_ref: float,
                reuse: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Per robot and kind (plan, trajectory, servo, executed): film (R, N) [m]. The servo and
    executed films follow each robot's trace (`traces`: its executed TCP, trigger and paint
    flow); the executed one against the body where it really was (the carrier's position and
    the placement the trace's disturbances put it at, `T_world_part_actual`). traces and trace
    None: the plan and trajectory films only (what no execution changes); reuse: those two,
    already measured (a sweep's samples)."""
    pts, nrm = body.vertices, body.normals
    t = trajs[0].t_s if trace is None else trace.t_s
    unit = booth.conveyor.unit
    nominal = booth.conveyor.position_m(t, t_ref)
    T0 = bcell.T_world_part
    shape = (bcell.n_robots, len(pts))
    out = dict(zip(("plan", "trajectory"), reuse or (np.zeros(shape), np.zeros(shape)),
                   strict=True))
    # (kind, from the executed trace, body placement, carrier position [m])
    runs: list[tuple[str, bool, np.ndarray, np.ndarray]] = \
        [("trajectory", False, T0, nominal)] if reuse is None else []
    if traces is not None and trace is not None:
        actual = trace.q[:, bcell.carrier_column] if bcell.carrier_column is not None \
            else nominal
        T_actual = np.asarray(trace.meta.get("T_world_part_actual", T0), float)
        runs += [("servo", True, T0, nominal), ("executed", True, T_actual, actual)]
        out.update(servo=np.zeros(shape), executed=np.zeros(shape))
    for i, tr in enumerate(trajs):
        if reuse is None:
            out["plan"][i] = planned_film(plans, jobs[i], T_bp, pts, nrm)
        ex = None if traces is None else traces[i]
        flow: dict[str, float] = {} if ex is None else {
            k: float(ex.meta[k]) for k in ("flow_scale", "flow_drift") if k in ex.meta}
        for key, executed, T, x in runs:
            src: Any = ex if executed else tr
            for app, on in job_paint(plans, jobs[i], tr, src.paint_on):
                g = gun_in_body(t, src.tcp_pos_world, src.tcp_rot_world, on, T, x, unit,
                                flow if executed else None, src.flow)
                out[key][i] += thickness(app, g, pts, nrm)
    return out


def planned_film(plans: list[CoveragePlan], jobs: tuple[Job, ...], T_bp: list[np.ndarray],
                 pts: np.ndarray, nrm: np.ndarray) -> np.ndarray:
    """(N,) film [m] of one robot's jobs at planned timing, each at its part's flow
    (`paintcell.booth.booth_build`), at body points pts (N, 3) with normals nrm (N, 3)."""
    film = np.zeros(len(pts))
    for job in jobs:
        sub = dataclasses.replace(plans[job.part],
                                  passes=plans[job.part].passes[job.first:job.end])
        film += thickness(plans[job.part].applicator, plan_gun_in_body(sub, T_bp[job.part]),
                          pts, nrm)
    return film


def job_paint(plans: list[CoveragePlan], jobs: tuple[Job, ...], traj: JointTrajectory,
              paint_on: np.ndarray | None = None) -> list[tuple[Any, np.ndarray]]:
    """Per job of one robot: its part's applicator (its flow) and the (K,) brush-on samples of
    `traj` (booth clock; `paint_on`: the trigger it really followed, default its own) that
    belong to the job (`paintcell.booth.booth_chain.job_windows`)."""
    from paintcell.booth.booth_chain import job_windows

    on = traj.paint_on if paint_on is None else paint_on
    return [(plans[j.part].applicator, on & w)
            for j, w in zip(jobs, job_windows(traj, len(jobs)), strict=True)]


def body_uniformity(film_m: np.ndarray, areas: np.ndarray, mask: np.ndarray | None = None,
                    target_m: float | None = None) -> float:
    """σ/μ [%] of a film (N,) [m] over the body (or `mask`)."""
    return float(uniformity(film_m, areas, mask=mask, target_m=target_m).nsd_pct)


def overlap_mask(films_m: np.ndarray) -> np.ndarray:
    """(N,) points where at least two robots (rows of films_m (R, N)) each lay ≥ OVERLAP_SHARE
    of the film."""
    total = films_m.sum(axis=0)
    share = films_m / np.where(total > 0, total, 1.0)
    return (share >= OVERLAP_SHARE).sum(axis=0) >= 2
