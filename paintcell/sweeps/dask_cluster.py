"""The Dask cluster paintcell's parallel work runs on (`paintcell sweep`, `paintcell run
--workers/--scheduler` of a booth): a `distributed.LocalCluster` of worker processes on this
machine, or an existing cluster at a scheduler address (`dask_client`), and the booth's task
pool on it (`DaskTasks`, a `paintcell.booth.booth_tasks.TaskPool`).

A worker that dies in the middle of a task: the scheduler runs the task again on another worker
(a local cluster's nanny also starts a fresh worker). A task that kills `allowed-failures`
workers (Dask's setting, 3), inputs the scheduler lost with their last worker, or a cluster
left without workers for `NO_WORKERS_S`: `DaskTasks` raises a one-line `ClusterError`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from contextlib import closing, contextmanager
from typing import Any, Generic, TypeVar

from paintcell.core.errors import PaintcellError, one_line

T = TypeVar("T")

#: how long a task waits for a cluster without a single worker before the run fails [s].
NO_WORKERS_S = 60.0
#: how often a waiting task checks that the cluster still has workers [s].
POLL_S = 2.0


class ClusterError(PaintcellError):
    """The Dask cluster cannot be reached or lost the work sent to it."""


def start_local_cluster(workers: int) -> Any:
    """A `distributed.LocalCluster` of `workers` processes (at least 1), one thread each."""
    import dask
    from distributed import LocalCluster

    # one thread a worker process: MuJoCo and the film kernel are single-threaded inside a task,
    # the processes share the cores
    old = os.environ.get("NUMBA_NUM_THREADS")
    os.environ["NUMBA_NUM_THREADS"] = "1"   # inherited by the worker processes only
    try:
        # spawned, never forked: the client ran the OpenMP film kernel (a sweep payload's films)
        # and GNU OpenMP kills a forked child that uses it (dask's default is spawn; a user's
        # dask config may say fork)
        with dask.config.set({"distributed.worker.multiprocessing-method": "spawn"}):
            return LocalCluster(n_workers=max(1, workers), threads_per_worker=1,
                                processes=True, dashboard_address=None, silence_logs=40)
    finally:
        if old is None:
            os.environ.pop("NUMBA_NUM_THREADS", None)
        else:
            os.environ["NUMBA_NUM_THREADS"] = old


def connect(scheduler: str) -> Any:
    """A `distributed.Client` of the cluster at `scheduler`, or a one-line ClusterError."""
    from distributed import Client

    from paintcell.sweeps.scheduler_probe import SchedulerProbeError, probe_scheduler

    try:
        probe_scheduler(scheduler)   # a web server or garbage: refused in seconds, not by Dask
    except SchedulerProbeError as exc:
        raise ClusterError(str(exc)) from None
    try:
        return Client(scheduler, timeout=15)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ClusterError(f"cannot reach the Dask scheduler at {scheduler} ({one_line(exc)}); "
                           "start one (dask scheduler) or drop --scheduler") from None


@contextmanager
def dask_client(workers: int, scheduler: str | None) -> Iterator[Any]:
    """A `distributed.Client`: of the cluster at `scheduler` (a Dask scheduler address, e.g.
    tcp://10.0.0.5:8786), else of a local cluster of `workers` processes started here; closed
    (and the local cluster stopped) at the end."""
    if scheduler is not None:
        with closing(connect(scheduler)) as client:
            yield client
        return
    from distributed import Client

    with closing(start_local_cluster(workers)) as cluster, closing(Client(cluster)) as client:
        yield client


class DaskTasks:
    """A booth's task pool (`paintcell.booth.booth_tasks.TaskPool`) on a Dask client: objects
    scattered to every worker, functions submitted as tasks (each its own, never cached by the
    scheduler), their results waited for as the module doc says. waited_s: the time the client
    has spent waiting for results [s] (a run's `stage_times_s["workers_wait"]`)."""

    def __init__(self, client: Any, where: str) -> None:
        self.client = client
        self.where = where      # the cluster, as a message names it
        self.waited_s = 0.0

    def share(self, obj: Any) -> Any:
        """obj on every worker (a handle a task takes in its place)."""
        [fut] = self.client.scatter([obj], broadcast=True, hash=False)
        return fut

    def submit(self, fn: Callable[..., T], *args: Any) -> _DaskFuture[T]:
        """fn(*args) as a task on the cluster."""
        return _DaskFuture(self, self.client.submit(fn, *args, pure=False))


class _DaskFuture(Generic[T]):
    def __init__(self, pool: DaskTasks, fut: Any) -> None:
        self.pool, self.fut = pool, fut

    def result(self) -> T:
        """The task's value or its own error; a lost task or cluster: a one-line ClusterError."""
        t0 = time.perf_counter()
        try:
            return self._result()
        finally:
            self.pool.waited_s += time.perf_counter() - t0

    def _result(self) -> T:
        from concurrent.futures import CancelledError

        from distributed import KilledWorker

        where = self.pool.where
        alone_since: float | None = None
        while True:
            try:
                return self.fut.result(timeout=POLL_S)  # type: ignore[no-any-return]
            except KilledWorker as exc:
                raise ClusterError(f"a task died with every Dask worker that ran it on {where} "
                                   f"({str(exc).splitlines()[0][:120]}; out of memory? see the "
                                   "workers' logs); nothing was written: rerun, or run in this "
                                   "process with --workers 0") from None
            except CancelledError:
                raise ClusterError(f"the Dask scheduler of {where} lost a task's inputs (the "
                                   "workers holding them died); nothing was written: rerun"
                                   ) from None
            except TimeoutError:
                if self.pool.client.scheduler_info().get("workers"):
                    alone_since = None
                    continue
                now = time.monotonic()
                alone_since = now if alone_since is None else alone_since
                if now - alone_since > NO_WORKERS_S:
                    raise ClusterError(f"the Dask cluster {where} has had no worker for "
                                       f"{NO_WORKERS_S:g} s; nothing was written: start workers "
                                       "(dask worker ADDRESS) and rerun") from None
