"""A booth's independent work as tasks on a pool of worker processes (`paintcell run
--workers/--scheduler`): each part's plan (`paintcell.booth.booth_plans.plan_part`), for every
allocation `paintcell.booth.booth_programs` builds, each robot's program for each of its jobs
(IK, moves, time law and body clearance: `paintcell.booth.booth_job_programs.job_program`),
and each robot-aware round's re-plans (`paintcell.motion.speed_feedback.replan_capped`).

A pool (`TaskPool`) sends an object to its workers once (`share`, a handle a task takes in its
place) and runs a function there (`submit`, a future whose `result()` is the function's value
or raises its error); `paintcell.sweeps.dask_cluster.DaskTasks` is one on Dask. The client
takes the results in the order the in-process run makes them and caches them the same way, so
the plans, programs and every figure of the run are the ones the in-process run gives.

A worker reads no file the client has not sent: a library part's surface is made on the worker
(a deterministic function of its name and resolution), a mesh or CAD part's surface is read by
the client and sent, the bell is sent as loaded; the robots are catalog models, loaded on the
worker from the booth (as a booth sweep's worker loads them), and each robot's probe of the
whole body (`paintcell.booth.booth_clearance.BodyProbe`) is built there from the body sent once.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable
from typing import Any, Protocol, TypeVar

from paintcell.booth.booth import Booth, Job
from paintcell.core.errors import PaintcellError
from paintcell.coverage.plan import CoveragePlan
from paintcell.motion.joint_trajectory import JointTrajectory

T = TypeVar("T")
T_co = TypeVar("T_co", covariant=True)


class TaskFuture(Protocol[T_co]):
    """A task's outcome: `result()` waits for it and returns its value or raises its error."""

    def result(self) -> T_co: ...


class TaskPool(Protocol):
    """Workers that run functions of this package (module doc)."""

    def share(self, obj: Any) -> Any:
        """Send obj to every worker once; a handle a task takes in its place."""

    def submit(self, fn: Callable[..., T], *args: Any) -> TaskFuture[T]:
        """Run fn(*args) on a worker (a handle from `share` arrives as its object)."""


class JobPrograms:
    """The robots' programs for their jobs, built on a pool for one set of plans and robots
    (`booth_programs._choose`): `submit(jobs)` sends every job of an allocation not yet sent;
    `take(r, job)` is robot r's program for the job, or the `PaintcellError` that refused it
    (as `booth_job_programs.job_program` gives them).

    body: the whole body (body frame), sent once per run (`share`); part_counts: the parts'
    vertex counts in its stacking order; shrink_m: the rails' shrink of `load_robots` [m];
    probes: whether the programs keep `Booth.body_clearance_m` from the body."""

    def __init__(self, tasks: TaskPool, run_key: str, booth: Booth, body: Any,
                 part_counts: tuple[int, ...], plans: list[CoveragePlan], shrink_m: float,
                 probes: bool) -> None:
        self.tasks, self.booth, self.plans = tasks, booth, plans
        self._args = (run_key, booth, body, part_counts, shrink_m, probes)
        self._futures: dict[tuple[int, Job], TaskFuture[JointTrajectory | PaintcellError]] = {}

    def submit(self, jobs: dict[int, tuple[Job, ...]]) -> None:
        """Send the allocation's jobs not sent yet, robot by robot."""
        import dataclasses

        from paintcell.booth.booth_job_programs import remote_job_program

        T_wb = self.booth.body_placement.matrix
        for r, js in sorted(jobs.items()):
            for job in js:
                if (r, job) in self._futures:
                    continue
                pl = self.plans[job.part]
                plan = dataclasses.replace(pl, passes=pl.passes[job.first:job.end])
                T = T_wb @ self.booth.parts[job.part].placement.matrix
                self._futures[(r, job)] = self.tasks.submit(remote_job_program, *self._args,
                                                            r, plan, T)

    def take(self, r: int, job: Job) -> JointTrajectory | PaintcellError:
        """Robot r's program for the job (sent by `submit`), or the error that refused it."""
        return self._futures[(r, job)].result()


def new_run_key() -> str:
    """A key of one run's worker state (its robots and probes), unique across runs."""
    return uuid.uuid4().hex
