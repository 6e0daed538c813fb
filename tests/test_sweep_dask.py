"""Sweeps on a real Dask cluster: a `dask scheduler` and two `dask worker` processes started on
127.0.0.1 by the test (subprocesses, killed at the end).

- a sweep through the cluster gives the same records, sample for sample, as the same sweep run
  in this process (and so whatever the number of workers);
- SIGKILL to one worker in the middle of a sweep loses no sample (the scheduler reruns its work
  on the other), and the records still equal the local ones.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from paintcell.sim.app.scenario_files import load_scenario
from paintcell.sim.sweeps.sweep import run_sweep
from paintcell.sim.sweeps.sweep_spec import spec_from_scenario
from paintcell.sim.sweeps.sweep_worker import RUN_KEYS
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


@pytest.fixture()
def cluster(tmp_path: Path) -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """(scheduler address, [worker processes]) of a fresh loopback cluster."""
    from distributed import Client

    sched_file = tmp_path / "scheduler.json"
    procs: list[subprocess.Popen[bytes]] = []
    log = open(tmp_path / "cluster.log", "wb")  # noqa: SIM115 - closed below
    try:
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
             "--port", "0", "--no-dashboard", "--scheduler-file", str(sched_file)],
            env=_env(), stdout=log, stderr=log))
        _wait_for(sched_file.exists, 60, "the dask scheduler")
        address = json.loads(sched_file.read_text())["address"]
        for _ in range(2):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", address, "--host",
                 "127.0.0.1", "--nthreads", "1", "--no-nanny", "--no-dashboard"],
                env=_env(), stdout=log, stderr=log, cwd=tmp_path))
        with Client(address, timeout=30) as c:
            c.wait_for_workers(2, timeout=90)
        yield address, procs[1:]
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        log.close()


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
