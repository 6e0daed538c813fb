"""Sweeps on a real Dask cluster: a `dask scheduler` and two `dask worker` processes started on
127.0.0.1 by the test (subprocesses, killed at the end).

- a sweep through the cluster gives the same records, sample for sample, as the same sweep run
  in this process (and so whatever the number of workers);
- SIGKILL to one worker in the middle of a sweep loses no sample (the scheduler reruns its work
  on the other), and the records still equal the local ones;
- SIGKILL to the only worker holding the sweep's inputs: the scheduler cancels the samples that
  needed them, and the sweep sends them again to a worker that joins later.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from paintcell.app.scenario_files import load_scenario
from paintcell.sweeps.sweep import run_sweep
from paintcell.sweeps.sweep_worker import RUN_KEYS
from paintcell.validation.sweep_spec import spec_from_scenario
from tests.sweep_cases import plate_scenario

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parent.parent
SWEEP = {"factors": {"tcp_offset_m": "normal(0, 0.003)", "gain_scale": "uniform(0.5, 1.5)",
                     "trigger_delay_s": "uniform(-0.02, 0.02)"}, "samples": 4, "seed": 7}


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["NUMBA_NUM_THREADS"] = "1"
    return env


def _wait_for(cond: Any, timeout_s: float, what: str) -> None:
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        if cond():
            return
        time.sleep(0.2)
    raise TimeoutError(f"timed out waiting for {what}")


def _start_worker(address: str, log: Any, cwd: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_worker", address, "--host", "127.0.0.1",
         "--nthreads", "1", "--no-nanny", "--no-dashboard"],
        env=_env(), stdout=log, stderr=log, cwd=cwd)


@contextmanager
def _loopback_cluster(tmp_path: Path, n_workers: int
                      ) -> Iterator[tuple[str, list[subprocess.Popen[bytes]], Any]]:
    """(scheduler address, [worker processes], log file) of a fresh loopback cluster; every
    process started here or appended to the list is stopped at the end."""
    from distributed import Client

    sched_file = tmp_path / "scheduler.json"
    procs: list[subprocess.Popen[bytes]] = []
    log = open(tmp_path / "cluster.log", "wb")  # noqa: SIM115 - closed below
    workers: list[subprocess.Popen[bytes]] = []
    try:
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
             "--port", "0", "--no-dashboard", "--scheduler-file", str(sched_file)],
            env=_env(), stdout=log, stderr=log))
        _wait_for(sched_file.exists, 60, "the dask scheduler")
        address = json.loads(sched_file.read_text())["address"]
        workers.extend(_start_worker(address, log, tmp_path) for _ in range(n_workers))
        with Client(address, timeout=30) as c:
            c.wait_for_workers(n_workers, timeout=90)
        yield address, workers, log
    finally:
        # SIGKILL the workers: on SIGTERM a dask worker retires gracefully, handing the data it
        # holds (a booth sweep's payload) to the others first — up to the 15 s timeout each
        # under load, for nothing at the end of a test
        for p in workers:
            if p.poll() is None:
                p.kill()
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs + workers:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        log.close()


@pytest.fixture()
def cluster(tmp_path: Path) -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """(scheduler address, [worker processes]) of a fresh loopback cluster of two workers."""
    with _loopback_cluster(tmp_path, 2) as (address, workers, _):
        yield address, workers


def _strip(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: v for k, v in r.items() if k not in RUN_KEYS} for r in records]


def _local(tmp_path: Path, scn: Any) -> list[dict[str, Any]]:
    spec = spec_from_scenario(scn.sweep)
    res = run_sweep(scn, spec, tmp_path / "local", fast=True, workers=0, progress=False,
                    report=False)
    return _strip(res.samples)


def test_cluster_sweep_equals_local_and_survives_a_killed_worker(
        tmp_path: Path, cluster: tuple[str, list[subprocess.Popen[bytes]]]) -> None:
    address, workers = cluster
    scn = load_scenario(plate_scenario(tmp_path / "case", SWEEP))
    spec = spec_from_scenario(scn.sweep)
    local = _local(tmp_path, scn)
    assert len(local) == spec.samples

    # 1. the same sweep through the cluster: equal sample for sample
    res = run_sweep(scn, spec, tmp_path / "remote", fast=True, scheduler=address,
                    progress=False, report=False)
    assert res.ran == spec.samples
    assert _strip(res.samples) == local
    pids = {p.pid: p for p in workers}
    assert {int(r["worker"].split(":")[1]) for r in res.samples} <= set(pids)

    # 2. again (another folder, same spec), SIGKILL to the worker that delivered the first
    # record (so a busy one) as soon as it arrives: no sample lost, records still equal, the
    # rest done by the other worker
    killed: list[int] = []

    def kill_busy_worker(rec: dict[str, Any]) -> None:
        if not killed:
            pid = int(rec["worker"].split(":")[1])
            assert pid in pids
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    res2 = run_sweep(scn, spec, tmp_path / "killed", fast=True, scheduler=address,
                     progress=False, report=False, on_sample=kill_busy_worker)
    assert killed and pids[killed[0]].wait(timeout=10) == -signal.SIGKILL
    assert sorted(r["index"] for r in res2.samples) == list(range(spec.samples))
    assert _strip(res2.samples) == local
    by = {int(r["worker"].split(":")[1]) for r in res2.samples}
    assert killed[0] in by and len(by) == 2
    files = sorted((tmp_path / "killed" / "samples").glob("*.json"))
    assert len(files) == spec.samples


def test_samples_whose_inputs_the_scheduler_lost_are_sent_again(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """The scheduler state of a worker dying with the only copy of the sweep's inputs: one
    worker holds the scattered payload; SIGKILL to it as the first record arrives, and a fresh
    worker joins only after that. The scheduler cannot recompute scattered data, so it forgets
    the payload and cancels every sample still waiting on it (`CancelledError` at the client).
    The sweep sends the payload again and reruns those samples on the new worker: none lost,
    each with its own factor value (kinematic mode: the TCP offset is the whole tracking error,
    an independent check). Without the resubmission the sweep dies on the first cancelled
    sample."""
    sweep = {"factors": {"tcp_offset_m": "normal(0, 0.003)"}, "samples": 2, "seed": 7}
    scn = load_scenario(plate_scenario(tmp_path / "case", sweep))
    spec = spec_from_scenario(scn.sweep)
    with _loopback_cluster(tmp_path, 1) as (address, workers, log):
        holder = workers[0]
        fresh: list[subprocess.Popen[bytes]] = []

        def kill_the_holder(rec: dict[str, Any]) -> None:
            if not fresh:
                assert int(rec["worker"].split(":")[1]) == holder.pid
                os.kill(holder.pid, signal.SIGKILL)
                assert holder.wait(timeout=10) == -signal.SIGKILL
                fresh.append(_start_worker(address, log, tmp_path))
                workers.append(fresh[0])   # stopped with the cluster

        with caplog.at_level(logging.WARNING, logger="paintcell.sweeps.sweep"):
            res = run_sweep(scn, spec, tmp_path / "lost", fast=True, mode="kinematic",
                            scheduler=address, progress=False, report=False,
                            on_sample=kill_the_holder)
    resent = [r.getMessage() for r in caplog.records if "sent again" in r.getMessage()]
    assert resent, "no sample was cancelled: the scheduler state was not forced"
    assert sorted(r["index"] for r in res.samples) == list(range(spec.samples))
    assert len(list((tmp_path / "lost" / "samples").glob("*.json"))) == spec.samples
    by_worker = {r["index"]: int(r["worker"].split(":")[1]) for r in res.samples}
    for msg in resent:
        i = int(msg.split()[1].rstrip(":"))
        assert by_worker[i] == fresh[0].pid
    design, seeds = spec.design(), spec.sample_seeds()
    for r in res.samples:
        i = r["index"]
        assert r["seed"] == int(seeds[i])
        offset = r["factors"]["tcp_offset_m"]
        assert offset == pytest.approx(float(design[i][0]), rel=1e-12)
        assert r["metrics"]["tracking_error_max_mm"] == pytest.approx(1e3 * abs(offset),
                                                                      abs=1e-6)
