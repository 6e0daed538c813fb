"""One sample of a booth sweep: the conveyor running off its nominal speed, the body off its
nominal place on the skid.

The robots' programs follow the conveyor at its nominal speed v
(`paintcell.booth.conveyor.track_program`:
time-based tracking, as a controller without a conveyor encoder does). The line really runs at
v + δv (`conveyor_speed_error_m_s`): the carrier in the MuJoCo booth
(`paintcell.booth.booth_cell`, a servoed
slide) is commanded along v + δv, so the body drifts from where the programs expect it by
δv · (t − t_ref) — behind or ahead of the bells — the collisions see it, and the executed film
(the executed TCP against where the carrier really was) counts it as conveyor loss.
`part_offset_m`: the body sits |x| off its nominal place on the skid, in the sample's seeded
random direction (the single-robot sweep's placement error): the MuJoCo part body is moved by it
(collisions), and the executed film takes the TCP against the moved body; `loss_conveyor_pp`
(executed − servo) is then the loss of the body being elsewhere than the programs expect, line
drift and placement together.

The client builds the booth's programs once (`paintcell.booth.booth_programs.booth_programs`)
and sends them
with the plan and trajectory films (which neither error changes) to every worker once. A
worker loads the robots and compiles the booth cell on its first sample and keeps them.
"""

from __future__ import annotations

import dataclasses
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from paintcell.core.errors import PaintcellError
from paintcell.sweeps.sweep_worker import cached_context, finite_or_none
from paintcell.validation.sweep_names import BOOTH_METRICS, SAMPLE_METRICS
from paintcell.validation.sweep_spec import SweepError, check_booth_factors

BOOTH_EXTRA = tuple(BOOTH_METRICS)


@dataclass(frozen=True, eq=False)
class BoothPayload:
    """What every sample of a booth sweep shares (pickled to each worker once).

    programs: `paintcell.booth.booth_programs.BoothPrograms` without robot models; films: plan
    and trajectory films (R, N) [m] on `programs.body.vertices`.
    """

    digest: str
    scenario: Any
    fast: bool
    mode: str
    programs: Any
    films: tuple[np.ndarray, np.ndarray]
    names: tuple[str, ...]


def prepare_booth_payload(booth: Any, names: tuple[str, ...], digest: str, fast: bool,
                          mode: str) -> BoothPayload:
    """Build the booth's programs and the two speed-independent films, once."""
    from paintcell.booth.booth_programs import booth_programs

    check_booth_factors(names)
    progs = booth_programs(booth, fast)
    return BoothPayload(digest, booth, fast, mode, dataclasses.replace(progs, robots=None),
                        reference_films(booth, progs), names)


def reference_films(booth: Any, progs: Any) -> tuple[np.ndarray, np.ndarray]:
    """Plan and trajectory films (R, N) [m] of the booth's programs on the body (the kinds of
    `paintcell.booth.booth_film.robot_films` that no execution changes)."""
    from paintcell.booth.booth_film import gun_in_body, job_paint, planned_film
    from paintcell.paint.deposition import thickness

    pts, nrm = progs.body.vertices, progs.body.normals
    t = progs.trajs[0].t_s
    nominal = booth.conveyor.position_m(t, progs.t_ref_s)
    T0 = booth.body_placement.matrix
    plan = np.zeros((len(progs.trajs), len(pts)))
    traj = np.zeros_like(plan)
    for i, tr in enumerate(progs.trajs):
        # each part at its own flow (paintcell.booth.booth_build)
        plan[i] = planned_film(progs.plans, progs.jobs[i], progs.T_body_parts, pts, nrm)
        for app, on in job_paint(progs.plans, progs.jobs[i], tr):
            g = gun_in_body(t, tr.tcp_pos_world, tr.tcp_rot_world, on, T0, nominal,
                            booth.conveyor.unit)
            traj[i] += thickness(app, g, pts, nrm)
    return plan, traj


@dataclass
class _BoothContext:
    payload: BoothPayload
    bcell: Any
    servo: Any
    build_s: float


def _context(payload: BoothPayload) -> _BoothContext:
    def build() -> _BoothContext:
        from paintcell.booth.booth_cell import build_booth_cell
        from paintcell.booth.booth_programs import load_robots
        from paintcell.core.settings import settings_from
        from paintcell.execution.execute import ServoSettings

        t0 = time.perf_counter()
        booth = payload.scenario
        bcell = build_booth_cell(load_robots(booth), payload.programs.body,
                                 booth.body_placement.matrix, booth.conveyor)
        return _BoothContext(payload, bcell,
                             settings_from(ServoSettings, booth.servo, "servo"),
                             time.perf_counter() - t0)

    return cached_context(payload.digest, build)


def carrier_program(bcell: Any, progs: Any, speed_m_s: float) -> Any:
    """The booth's combined program with the carrier commanded along `speed_m_s` [m/s] (the
    robots' columns unchanged: they still track the nominal speed)."""
    from paintcell.booth.booth_run import combined_program

    if not np.isfinite(speed_m_s) or speed_m_s < 0:
        raise SweepError(f"the line would run at {speed_m_s:.4g} m/s (nominal + speed error); "
                         "keep conveyor_speed_error_m_s above minus the line speed")
    prog = combined_program(bcell, progs.trajs, progs.t_ref_s)
    c = bcell.carrier_column
    if c is None:
        raise SweepError("the booth has no conveyor carrier; give it a [conveyor]")
    prog.q[:, c] = speed_m_s * (prog.t_s - progs.t_ref_s)
    prog.qd[:, c] = speed_m_s
    return prog


def placement(factors: dict[str, float], seed: int) -> Any:
    """The body's placement error on the skid as `Disturbances` (None without
    `part_offset_m`): a translation of |part_offset_m| [m] in the sample's seeded random
    direction of the part frame (`Disturbances.realize`, as the single-robot sweep). `execute`
    moves the part body of the booth cell by it (the carrier's joint and its line direction
    unchanged), so the collisions see the body where it really is."""
    from paintcell.execution.execute_settings import Disturbances

    if "part_offset_m" not in factors:
        return None
    return Disturbances(part_offset_m=abs(float(factors["part_offset_m"])), seed=int(seed))


def run_booth_sample(payload: BoothPayload, index: int, values: np.ndarray | None,
                     seed: int) -> dict[str, Any]:
    """Execute and evaluate one booth sample; a JSON-safe record like `run_sample`'s (index −1:
    the nominal run). Booth figures beyond `SAMPLE_METRICS` are under `metrics` too."""
    from paintcell.booth.booth_film import gun_in_body, judged_body_mask
    from paintcell.booth.booth_results import booth_metrics
    from paintcell.booth.booth_run import robot_tcp, robot_traces
    from paintcell.execution.execute import execute
    from paintcell.validation.validate import collision_events

    t0, c0 = time.perf_counter(), time.process_time()
    ctx = _context(payload)
    t_ctx = time.perf_counter() - t0
    booth, progs, bcell = payload.scenario, payload.programs, ctx.bcell
    factors = ({} if values is None else
               {n: float(v) for n, v in zip(payload.names, values, strict=True)})
    rec: dict[str, Any] = {"index": int(index), "seed": int(seed), "factors": factors}
    try:
        speed = booth.conveyor.speed_m_s + factors.get("conveyor_speed_error_m_s", 0.0)
        t1 = time.perf_counter()
        trace = execute(bcell.cell, carrier_program(bcell, progs, speed),
                        mode=payload.mode,  # type: ignore[arg-type]
                        servo=ctx.servo, disturbances=placement(factors, seed))
        t2 = time.perf_counter()
        pos, rot = robot_tcp(bcell, trace.q)
        traces = robot_traces(bcell, trace, progs.trajs, pos, rot)
        films = _films(booth, bcell, payload, trace, traces, gun_in_body)
        rep = booth_metrics(booth, bcell, progs.body, films, progs.static, progs.trajs, traces,
                            trace, collision_events(trace), progs.record, progs.jobs,
                            [len(s.vertices) for s in progs.surfaces], progs.plans,
                            judged_body_mask(progs.surfaces))
        t3 = time.perf_counter()
    except PaintcellError as exc:
        msg = str(exc).strip().splitlines()
        rec.update({"passed": False, "error": msg[0] if msg else type(exc).__name__,
                    "metrics": {k: None for k in (*SAMPLE_METRICS, *BOOTH_EXTRA)},
                    "failed_checks": ["error"]})
        rec["timing_s"] = {"context": t_ctx, "total": time.perf_counter() - t0}
        rec["worker"] = f"{os.uname().nodename}:{os.getpid()}"
        return rec
    m = dict(rep.metrics)
    total = films["executed"].sum(axis=0)
    # the thinnest judged film (a mesh part's skin), as a one-robot sample's
    m["executed_min_um"] = 1e6 * float(total[judged_body_mask(progs.surfaces)].min())
    m["tracking_error_max_mm"] = 1e3 * max(
        float(np.linalg.norm(ex.tcp_pos_world - tr.tcp_pos_world, axis=1).max())
        for ex, tr in zip(traces, progs.trajs, strict=True))
    # the line speed MuJoCo's carrier really ran at: least-squares slope of its position [m/s]
    m["carrier_speed_m_s"] = float(np.polyfit(trace.t_s, trace.q[:, bcell.carrier_column], 1)[0])
    rec["metrics"] = {k: finite_or_none(m[k]) if k in m else None
                      for k in (*SAMPLE_METRICS, *BOOTH_EXTRA)}
    rec["passed"] = bool(rep.passed)
    rec["failed_checks"] = [c.name for c in rep.checks if not c.passed]
    rec["timing_s"] = {"context": t_ctx, "execute": t2 - t1, "validate": t3 - t2,
                       "total": time.perf_counter() - t0, "cpu": time.process_time() - c0,
                       "context_build": ctx.build_s}
    rec["worker"] = f"{os.uname().nodename}:{os.getpid()}"
    return rec


def _films(booth: Any, bcell: Any, payload: BoothPayload, trace: Any, traces: list[Any],
           gun_in_body: Any) -> dict[str, np.ndarray]:
    """Per robot and kind: the payload's plan and trajectory films, and this sample's servo
    (executed TCP against the nominal body position) and executed (against the body's real
    position: the carrier's, and the placement on the skid) films (R, N) [m] —
    `paintcell.booth.booth_film.robot_films` without the two reused kinds."""
    from paintcell.booth.booth_film import job_paint
    from paintcell.paint.deposition import thickness

    progs = payload.programs
    pts, nrm = progs.body.vertices, progs.body.normals
    t, unit = trace.t_s, booth.conveyor.unit
    nominal = booth.conveyor.position_m(t, progs.t_ref_s)
    actual = trace.q[:, bcell.carrier_column]
    # where the body really sat on the skid (the placement error `execute` applied)
    T_actual = np.asarray(trace.meta.get("T_world_part_actual", bcell.T_world_part), float)
    out = {"plan": payload.films[0], "trajectory": payload.films[1],
           "servo": np.zeros_like(payload.films[0]), "executed": np.zeros_like(payload.films[0])}
    for i, (tr, ex) in enumerate(zip(progs.trajs, traces, strict=True)):
        for app, on in job_paint(progs.plans, progs.jobs[i], tr):   # each part's own flow
            for key, T, x in (("servo", bcell.T_world_part, nominal),
                              ("executed", T_actual, actual)):
                g = gun_in_body(t, ex.tcp_pos_world, ex.tcp_rot_world, on, T, x, unit)
                out[key][i] += thickness(app, g, pts, nrm)
    return out
