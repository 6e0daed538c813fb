"""One sample of a sweep, as a Dask worker runs it, and what a worker keeps between samples.

The client plans once and sends a `SweepPayload` (scenario, surface, plan, 1 kHz program, and the
planned and trajectory films, none of which a disturbance changes) to every worker once. A worker
builds its `WorkerContext` from it on the first sample — the robot model and the compiled MuJoCo
cell — and keeps it, with the inverse-dynamics feed-forward, for every later sample of the same
payload. A sample is then: execute under its disturbances, validate against the reused films.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from paintcell.core.errors import PaintcellError
from paintcell.validation.sweep_names import SAMPLE_METRICS

T = TypeVar("T")


@dataclass(frozen=True, eq=False)
class SweepPayload:
    """What every sample shares (built once by the client; pickled to each worker once).

    digest: identity of the sweep (spec + scenario); mode: "servo" or "kinematic";
    films: (planned, trajectory) films (N,) [m] on `surface.vertices`.
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


@dataclass
class WorkerContext:
    """Per-worker state kept across samples: robot, compiled cell, feed-forward cache."""

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
    MuJoCo cell), whatever kind of sweep (single robot or booth) it was.
    """
    ctx = _CONTEXTS.get(digest)
    if ctx is None:
        ctx = build()
        _CONTEXTS.clear()
        _CONTEXTS[digest] = ctx
    return ctx  # type: ignore[no-any-return]


def context(payload: SweepPayload) -> WorkerContext:
    """The worker's context for this payload (built on first use, then reused)."""

    def build() -> WorkerContext:
        from paintcell.app.pipeline import load_robot_for, servo_settings
        from paintcell.execution.cell import build_cell

        t0 = time.perf_counter()
        scn = payload.scenario
        robot = load_robot_for(scn)
        cell = build_cell(robot, payload.surface, scn.part_placement.matrix)
        ctx = WorkerContext(payload, robot, cell, servo_settings(scn))
        ctx.build_s = time.perf_counter() - t0
        return ctx

    return cached_context(payload.digest, build)


def disturbances_for(payload: SweepPayload, values: np.ndarray | None, seed: int) -> Any:
    """`Disturbances` of one sample: the scenario's own, with the sampled factors set and the
    sample's seed (values None: the nominal run, the scenario as declared)."""
    from paintcell.core.settings import settings_from
    from paintcell.execution.execute_settings import Disturbances

    kw = dict(payload.scenario.disturbances)
    if values is None:
        return settings_from(Disturbances, kw, "disturbances") if kw else None
    kw.update({n: float(v) for n, v in zip(payload.names, values, strict=True)})
    kw["seed"] = int(seed)
    return settings_from(Disturbances, kw, "disturbances")


def run_sample(payload: SweepPayload, index: int, values: np.ndarray | None,
               seed: int) -> dict[str, Any]:
    """Execute and validate one sample; a JSON-safe record (index −1: the nominal run).

    A sample whose disturbance cannot be simulated (an invalid value, an unstable servo, no
    paint left) is recorded as failed with its one-line error, not dropped.
    """
    from paintcell.execution.execute import execute
    from paintcell.validation.validate import validate

    t0, c0 = time.perf_counter(), time.process_time()
    ctx = context(payload)
    t_ctx = time.perf_counter() - t0
    scn = payload.scenario
    rec: dict[str, Any] = {
        "index": int(index), "seed": int(seed),
        "factors": ({} if values is None else
                    {n: float(v) for n, v in zip(payload.names, values, strict=True)}),
    }
    try:
        dist = disturbances_for(payload, values, seed)
        t1 = time.perf_counter()
        trace = execute(ctx.cell, payload.trajectory, mode=payload.mode,  # type: ignore[arg-type]
                        servo=ctx.servo, disturbances=dist, cache=ctx.cache)
        t2 = time.perf_counter()
        rep = validate(payload.plan, payload.surface, payload.trajectory, trace,
                       scn.part_placement.matrix, scn.thresholds,
                       reachability=payload.trajectory.meta.get("reachability"),
                       films=payload.films, spec=scn.spec)
        t3 = time.perf_counter()
    except PaintcellError as exc:
        msg = str(exc).strip().splitlines()
        rec.update({"passed": False, "error": msg[0] if msg else type(exc).__name__,
                    "metrics": {k: None for k in SAMPLE_METRICS}, "failed_checks": ["error"]})
        rec["timing_s"] = {"context": t_ctx, "total": time.perf_counter() - t0}
        rec["worker"] = f"{os.uname().nodename}:{os.getpid()}"
        return rec
    m = rep.metrics
    rec["metrics"] = {k: finite_or_none(m[k]) for k in SAMPLE_METRICS}
    rec["passed"] = bool(rep.passed)
    rec["failed_checks"] = [c.name for c in rep.checks if not c.passed]
    # cpu: this process's CPU time for the sample (a worker runs one sample at a time)
    rec["timing_s"] = {"context": t_ctx, "execute": t2 - t1, "validate": t3 - t2,
                       "total": time.perf_counter() - t0, "cpu": time.process_time() - c0,
                       "context_build": ctx.build_s}
    rec["worker"] = f"{os.uname().nodename}:{os.getpid()}"
    return rec


def finite_or_none(v: Any) -> float | None:
    """A figure as a float for a sample record, None when it is NaN or infinite."""
    v = float(v)
    return v if np.isfinite(v) else None


#: keys of a sample record that describe how it ran, not what it found (excluded when two
#: sweeps are compared sample for sample).
RUN_KEYS = ("timing_s", "worker")
