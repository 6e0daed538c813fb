"""One sample of a sweep, as a Dask worker runs it, for any cell: one robot or a booth of N.

The client plans once and sends a `SweepPayload` to every worker once: the scenario and what no
disturbance changes — a one-robot cell's surface, plan and 1 kHz program (`one_robot_payload`),
or a booth's programs (`booth_payload`: plans, allocation, staggered and conveyor-tracked
programs, without the robot models) — with the planned and trajectory films. A worker builds
its `WorkerContext` from it on the first sample (the robot models and the compiled MuJoCo cell)
and keeps it, with the inverse-dynamics feed-forward of a one-robot cell, for every later sample
of the same payload. A sample is then: execute under its disturbances (`disturbances_for`: the
scenario's own with the sampled factors set, on every robot of the cell), evaluate against the
reused films.

A booth's line really runs at v + δv (`conveyor_speed_error_m_s`), while the robots' programs
track the nominal speed v (`paintcell.booth.conveyor.track_program`: time-based tracking, as a
controller without a conveyor encoder does): the carrier in the MuJoCo booth is commanded along
v + δv (`carrier_program`), so the body drifts from where the programs expect it by
δv · (t − t_ref), the collisions see it, and the executed film counts it as conveyor loss. The
other factors act as on one robot: `part_offset_m` moves the whole body on its skid, the TCP,
trigger, flow and gain errors act on every robot (`paintcell.booth.booth_film.disturbed_robot`).
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from paintcell.core.errors import PaintcellError, one_line
from paintcell.validation.sweep_names import (
    BOOTH_METRICS,
    BOOTH_ONLY_FACTORS,
    MAGNITUDE_FACTORS,
    SAMPLE_METRICS,
)
from paintcell.validation.sweep_spec import SweepError

T = TypeVar("T")


@dataclass(frozen=True, eq=False)
class SweepPayload:
    """What every sample shares (built once by the client; pickled to each worker once).

    digest: identity of the sweep (spec + scenario); mode: "servo" or "kinematic";
    films: (planned, trajectory) films [m] on `surface.vertices`: (N,) for one robot, (R, N) per
    robot of a booth. A one-robot cell: plan, trajectory; a booth: programs
    (`paintcell.booth.booth_programs.BoothPrograms` without robot models), surface its body.
    """

    digest: str
    scenario: Any
    fast: bool
    mode: str
    surface: Any
    plan: Any
    trajectory: Any
    films: tuple[np.ndarray, np.ndarray]
    names: tuple[str, ...]
    programs: Any = None

    @property
    def metric_names(self) -> tuple[str, ...]:
        """The figures a sample records: `SAMPLE_METRICS`, a booth's `BOOTH_METRICS` too."""
        return (*SAMPLE_METRICS, *(BOOTH_METRICS if self.programs is not None else ()))


@dataclass
class WorkerContext:
    """Per-worker state kept across samples: robot (None in a booth), compiled cell (a booth's
    `BoothCell`), servo settings, feed-forward cache."""

    payload: SweepPayload
    robot: Any
    cell: Any
    servo: Any
    cache: dict[Any, np.ndarray] = field(default_factory=dict)
    build_s: float = 0.0


_CONTEXTS: dict[str, Any] = {}


def cached_context(digest: str, build: Callable[[], T]) -> T:
    """The worker's context for the sweep `digest`: built by `build()` on first use, then reused.

    One sweep at a time per worker: a new digest drops the older sweep's context (its compiled
    MuJoCo cell).
    """
    ctx = _CONTEXTS.get(digest)
    if ctx is None:
        ctx = build()
        _CONTEXTS.clear()
        _CONTEXTS[digest] = ctx
    return ctx  # type: ignore[no-any-return]


def one_robot_payload(scn: Any, names: tuple[str, ...], digest: str, fast: bool,
                      mode: str) -> SweepPayload:
    """Plan a one-robot scenario once: surface, plan, program and its two films."""
    from paintcell.app.pipeline import load_robot_for, load_surface, make_plan, make_trajectory
    from paintcell.validation.validate import program_films

    surface = load_surface(scn, fast)
    plan = make_plan(scn, surface, fast)
    traj = make_trajectory(scn, load_robot_for(scn), plan)
    films = program_films(plan, surface, traj, scn.part_placement.matrix)
    return SweepPayload(digest, scn, fast, mode, surface, plan, traj, films, names)


def booth_payload(booth: Any, names: tuple[str, ...], digest: str, fast: bool,
                  mode: str) -> SweepPayload:
    """Build a booth's programs once and their planned and trajectory films (R, N)
    (`paintcell.booth.booth_film.robot_films` before any execution)."""
    from paintcell.booth.booth_cell import build_booth_cell
    from paintcell.booth.booth_film import robot_films
    from paintcell.booth.booth_programs import booth_programs

    progs = booth_programs(booth, fast)
    assert progs.robots is not None               # loaded here (None once sent to a worker)
    bcell = build_booth_cell(progs.robots, progs.body, booth.body_placement.matrix,
                             booth.conveyor)
    films = robot_films(booth, bcell, progs.body, progs.plans, progs.jobs, progs.T_body_parts,
                        progs.trajs, None, None, progs.t_ref_s)
    return SweepPayload(digest, booth, fast, mode, progs.body, None, None,
                        (films["plan"], films["trajectory"]), names,
                        dataclasses.replace(progs, robots=None))


def context(payload: SweepPayload) -> WorkerContext:
    """The worker's context for this payload (built on first use, then reused)."""

    def build() -> WorkerContext:
        from paintcell.core.settings import settings_from
        from paintcell.execution.execute import ServoSettings

        t0 = time.perf_counter()
        scn = payload.scenario
        servo = settings_from(ServoSettings, scn.servo, "servo")
        cell: Any
        if payload.programs is not None:
            from paintcell.booth.booth_cell import build_booth_cell
            from paintcell.booth.booth_programs import load_robots

            robot = None
            cell = build_booth_cell(load_robots(scn), payload.surface,
                                    scn.body_placement.matrix, scn.conveyor)
        else:
            from paintcell.app.pipeline import load_robot_for
            from paintcell.execution.cell import build_cell

            robot = load_robot_for(scn)
            cell = build_cell(robot, payload.surface, scn.part_placement.matrix)
        ctx = WorkerContext(payload, robot, cell, servo)
        ctx.build_s = time.perf_counter() - t0
        return ctx

    return cached_context(payload.digest, build)


def disturbances_for(payload: SweepPayload, values: np.ndarray | None, seed: int) -> Any:
    """`Disturbances` of one sample: the scenario's own, with the sampled factors set (a length
    or angle in a random direction as its size; a line speed error is the carrier's, not a
    `Disturbances` field) and the sample's seed (values None: the nominal run, the scenario as
    declared)."""
    from paintcell.core.settings import settings_from
    from paintcell.execution.execute import Disturbances

    kw = dict(payload.scenario.disturbances)
    if values is None:
        return settings_from(Disturbances, kw, "disturbances") if kw else None
    kw.update({n: abs(float(v)) if n in MAGNITUDE_FACTORS else float(v)
               for n, v in zip(payload.names, values, strict=True) if n not in BOOTH_ONLY_FACTORS})
    kw["seed"] = int(seed)
    return settings_from(Disturbances, kw, "disturbances")


def run_sample(payload: SweepPayload, index: int, values: np.ndarray | None,
               seed: int) -> dict[str, Any]:
    """Execute and evaluate one sample; a JSON-safe record (index −1: the nominal run).

    A sample whose disturbance cannot be simulated (an invalid value, an unstable servo, no
    paint left) is recorded as failed with its one-line error, not dropped.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    ctx = context(payload)
    t_ctx = time.perf_counter() - t0
    factors = ({} if values is None else
               {n: float(v) for n, v in zip(payload.names, values, strict=True)})
    rec: dict[str, Any] = {"index": int(index), "seed": int(seed), "factors": factors}
    try:
        dist = disturbances_for(payload, values, seed)
        t1 = time.perf_counter()
        run = _booth_sample if payload.programs is not None else _one_robot_sample
        m, rep, t2 = run(ctx, dist, factors)
        t3 = time.perf_counter()
    except PaintcellError as exc:
        rec.update({"passed": False, "error": one_line(exc),
                    "metrics": {k: None for k in payload.metric_names},
                    "failed_checks": ["error"]})
        rec["timing_s"] = {"context": t_ctx, "total": time.perf_counter() - t0}
        rec["worker"] = f"{os.uname().nodename}:{os.getpid()}"
        return rec
    rec["metrics"] = {k: finite_or_none(m[k]) if k in m else None for k in payload.metric_names}
    rec["passed"] = bool(rep.passed)
    rec["failed_checks"] = [c.name for c in rep.checks if not c.passed]
    # cpu: this process's CPU time for the sample (a worker runs one sample at a time)
    rec["timing_s"] = {"context": t_ctx, "execute": t2 - t1, "validate": t3 - t2,
                       "total": time.perf_counter() - t0, "cpu": time.process_time() - c0,
                       "context_build": ctx.build_s}
    rec["worker"] = f"{os.uname().nodename}:{os.getpid()}"
    return rec


def _one_robot_sample(ctx: WorkerContext, dist: Any, factors: dict[str, float]
                      ) -> tuple[dict[str, Any], Any, float]:
    """A one-robot cell's sample: its metrics, its `ValidationReport`, when execution ended."""
    from paintcell.execution.execute import execute
    from paintcell.validation.validate import validate

    p, scn = ctx.payload, ctx.payload.scenario
    trace = execute(ctx.cell, p.trajectory, mode=p.mode,  # type: ignore[arg-type]
                    servo=ctx.servo, disturbances=dist, cache=ctx.cache)
    t2 = time.perf_counter()
    rep = validate(p.plan, p.surface, p.trajectory, trace, scn.part_placement.matrix,
                   scn.thresholds, reachability=p.trajectory.meta.get("reachability"),
                   films=p.films, spec=scn.spec)
    return rep.metrics, rep, t2


def _booth_sample(ctx: WorkerContext, dist: Any, factors: dict[str, float]
                  ) -> tuple[dict[str, Any], Any, float]:
    """A booth's sample (module doc): its metrics (a one-robot sample's figures and the booth's),
    its `ValidationReport`, when execution ended."""
    from paintcell.booth.booth_film import judged_body_mask, robot_films
    from paintcell.booth.booth_results import booth_metrics
    from paintcell.booth.booth_run import robot_tcp, robot_traces
    from paintcell.execution.execute import execute
    from paintcell.validation.validate_motion import collision_events

    p, booth, bcell = ctx.payload, ctx.payload.scenario, ctx.cell
    progs = p.programs
    speed = booth.conveyor.speed_m_s + factors.get("conveyor_speed_error_m_s", 0.0)
    trace = execute(bcell.cell, carrier_program(bcell, progs, speed),
                    mode=p.mode,  # type: ignore[arg-type]
                    servo=ctx.servo, disturbances=dist)
    t2 = time.perf_counter()
    pos, rot = robot_tcp(bcell, trace.q)
    traces = robot_traces(bcell, trace, progs.trajs, pos, rot)
    films = robot_films(booth, bcell, progs.body, progs.plans, progs.jobs, progs.T_body_parts,
                        progs.trajs, traces, trace, progs.t_ref_s, reuse=p.films)
    judged = judged_body_mask(progs.surfaces)
    rep = booth_metrics(booth, bcell, progs.body, films, progs.static, progs.trajs, traces,
                        trace, collision_events(trace), progs.record, progs.jobs,
                        [len(s.vertices) for s in progs.surfaces], progs.plans, judged)
    m = dict(rep.metrics)
    # the thinnest judged film (a mesh part's skin), as a one-robot sample's
    m["executed_min_um"] = 1e6 * float(films["executed"].sum(axis=0)[judged].min())
    m["tracking_error_max_mm"] = 1e3 * max(
        float(np.linalg.norm(ex.tcp_pos_world - tr.tcp_pos_world, axis=1).max())
        for ex, tr in zip(traces, progs.trajs, strict=True))
    # the line speed MuJoCo's carrier really ran at: least-squares slope of its position [m/s]
    m["carrier_speed_m_s"] = float(np.polyfit(trace.t_s, trace.q[:, bcell.carrier_column], 1)[0])
    return m, rep, t2


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


def finite_or_none(v: Any) -> float | None:
    """A figure as a float for a sample record, None when it is NaN or infinite."""
    v = float(v)
    return v if np.isfinite(v) else None


#: keys of a sample record that describe how it ran, not what it found (excluded when two
#: sweeps are compared sample for sample).
RUN_KEYS = ("timing_s", "worker")
