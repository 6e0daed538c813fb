"""A booth run whose parts are planned and whose robots' programs are built on Dask
(`paintcell run --workers N / --scheduler ADDRESS`, `paintcell.booth.booth_tasks`).

The booth: two robots, each before one upright part, a library panel (made on the worker) and a
small plate read from a mesh file (read by the client and sent), the line at rest; ~20 s in this
process. Against the same booth run in this process, file by file (every plan, program, trace,
RAPID module and metric; only measured run times differ):
- a local cluster of two worker processes (the sweep's own cluster code), with the client's
  planner and program builder broken, so every plan and program came from a worker;
- a `dask scheduler` and two `dask worker` processes on 127.0.0.1 (`--scheduler`), one worker
  SIGKILLed while it plans a part: the scheduler reruns the task on the other;
- the last worker SIGKILLed too: the run fails in one line and writes no results folder.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from paintcell.app.pipeline import run_scenario
from paintcell.app.scenario_files import load_scenario
from paintcell.sweeps.dask_cluster import ClusterError, DaskTasks, dask_client
from tests.sweep_cases import plate_mesh
from tests.test_sweep_dask import cluster  # noqa: F401 - the loopback cluster fixture

pytestmark = pytest.mark.slow

BOOTH = """name = "two_parts"
fast_resolution_m = 0.025
[conveyor]
speed_m_s = 0.0

[[parts]]
part = "panel"
xyz_m = [1.4, 0.0, 1.0]
rpy_rad = [1.5707963267948966, 0.0, -1.5707963267948966]
robots = ["a"]

[[parts]]
xyz_m = [1.4, 3.0, 1.0]
rpy_rad = [1.5707963267948966, 0.0, -1.5707963267948966]
robots = ["b"]
[parts.part]
file = "plate.stl"

[[robots]]
name = "a"
model = "abb_paint"
home = [0.0, -0.6, 0.3, 0.0, 0.9, 0.0]
[robots.base]
xyz_m = [-0.65, 0.1, 0.5]
rpy_rad = [0.0, 0.0, -0.055]

[[robots]]
name = "b"
model = "abb_paint"
home = [0.0, -0.6, 0.3, 0.0, 0.9, 0.0]
[robots.base]
xyz_m = [-0.65, 3.1, 0.5]
rpy_rad = [0.0, 0.0, -0.055]
"""

#: what a run measures of itself (wall and CPU times), not what it computed.
RUN_TIMES = ("stage_times_s", "timing_s", "wall_time_s", "realtime_factor")


def _booth_file(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    plate_mesh(folder / "plate.stl")
    (folder / "two_parts.toml").write_text(BOOTH)
    return folder / "two_parts.toml"


@pytest.fixture(scope="module")
def local(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(booth file, results folder of its fast kinematic run in this process)."""
    folder = tmp_path_factory.mktemp("booth_dask")
    path = _booth_file(folder / "case")
    res = run_scenario(load_scenario(path), folder / "local", fast=True, mode="kinematic",
                       progress=False)
    assert res.passed and len(res.plans) == 2
    return path, folder / "local"


def _without_run_times(d: Any) -> Any:
    if isinstance(d, dict):
        return {k: _without_run_times(v) for k, v in d.items() if k not in RUN_TIMES}
    if isinstance(d, list):
        return [_without_run_times(v) for v in d]
    return d


def _assert_same_results(a: Path, b: Path) -> None:
    """Every data file of two booth results folders equal (arrays bit for bit, NaN where NaN;
    JSON and text byte for byte once the runs' own times are left out)."""
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    checked = 0
    for n in names:
        if n.endswith(".npz"):
            fa, fb = np.load(a / n), np.load(b / n)
            assert fa.files == fb.files, n
            for k in fa.files:
                x, y = fa[k], fb[k]
                if k == "_json":
                    x, y = (_without_run_times(json.loads(str(v))) for v in (x, y))
                    assert x == y, n
                else:
                    assert x.dtype == y.dtype and np.array_equal(
                        x, y, equal_nan=x.dtype.kind in "fc"), f"{n}: {k}"
        elif n.endswith(".json"):
            x, y = (_without_run_times(json.loads((f / n).read_text())) for f in (a, b))
            assert x == y, n
        elif n.endswith(".mod"):
            assert (a / n).read_text() == (b / n).read_text(), n
        else:
            continue
        checked += 1
    # plans, metrics, scenario, body, cell, film, per robot static/trajectory/trace, RAPID
    assert checked >= 2 + 2 + 4 + 2 * 4 + 1


def test_a_local_cluster_of_two_workers_gives_the_same_run(
        local: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path, ref = local
    booth = load_scenario(path)
    # The client may not plan a part nor build a program itself: the workers (spawned
    # processes, their own imports) must.
    from paintcell.booth import booth_job_programs
    from paintcell.coverage import algorithm

    def not_here(*args: Any, **kw: Any) -> Any:
        raise AssertionError("planned or built in the client")

    monkeypatch.setattr(algorithm, "plan_coverage", not_here)
    monkeypatch.setattr(booth_job_programs, "_clear_program", not_here)
    sent: list[str] = []

    class Counted(DaskTasks):
        def submit(self, fn: Any, *args: Any) -> Any:
            sent.append(fn.__name__)
            return super().submit(fn, *args)

    with dask_client(2, None) as client:
        assert len(client.scheduler_info()["workers"]) == 2
        res = run_scenario(booth, tmp_path / "dask", fast=True, mode="kinematic",
                           progress=False, tasks=Counted(client, "a local cluster"))
    assert res.passed
    assert sent.count("plan_part") == 2 and sent.count("remote_job_program") >= 2
    _assert_same_results(ref, tmp_path / "dask")
    # the client waited for the plans it could not make itself, within the two stages' wall
    t = res.timings_s
    assert 0.0 < t["workers_wait"] <= t["plan"] + t["trajectory"]
    metrics = json.loads((tmp_path / "dask" / "metrics.json").read_text())
    assert metrics["stage_times_s"]["workers_wait"] == t["workers_wait"]
    assert "workers_wait" not in json.loads((ref / "metrics.json").read_text())["stage_times_s"]


def test_robot_aware_replans_on_workers_are_the_ones_made_here() -> None:
    """The robot-aware round's re-plans (`speed_feedback.replan_capped`, sent by `map_tasks`)
    on two worker processes: each part's plan under its speed caps equals, bit for bit, the
    one made in this process, and every capped sample's planned speed is within its cap."""
    from paintcell.core.tasks import map_tasks
    from paintcell.coverage.algorithm import plan_coverage
    from paintcell.coverage.coverage_settings import PlannerSettings
    from paintcell.motion.speed_feedback import replan_capped
    from paintcell.paint.applicator import Applicator
    from paintcell.surface import parts

    app = Applicator.default()
    st = PlannerSettings(sample_spacing_m=0.04, overspray_m=0.1, n_knots=8, film_guard=False)
    args = []
    for skin in (parts.panel(0.04), parts.panel(0.05)):
        plan = plan_coverage(skin, app, st)
        caps = {}
        for k in (0, len(plan.passes) // 2):            # two passes capped at 70 % mid-pass
            v = plan.passes[k].speeds_m_s
            cap = np.full(len(v), st.v_max_m_s)
            cap[len(v) // 3: 2 * len(v) // 3] = 0.7 * v[len(v) // 3: 2 * len(v) // 3]
            caps[plan.passes[k].side] = cap             # caps go by the pass's side
        args.append((skin, app, st, caps))
    here = map_tasks(replan_capped, args)
    with dask_client(2, None) as client:
        there = map_tasks(replan_capped, args, DaskTasks(client, "a local cluster"))
    for a, b, (_, _, _, caps) in zip(here, there, args, strict=True):
        for pa, pb in zip(a.passes, b.passes, strict=True):
            assert np.array_equal(pa.speeds_m_s, pb.speeds_m_s)
            assert np.array_equal(pa.positions, pb.positions)
        for side, cap in caps.items():
            (v,) = [p.speeds_m_s for p in a.passes if p.side == side]
            assert (v <= cap * (1 + 1e-6)).all()


def test_a_booth_sends_its_robot_aware_replans_to_the_pool() -> None:
    """scenarios/booth.toml re-plans parts under robot-aware caps (its fender and roof; the
    booth here keeps those two and their robots): given a pool (here one that runs each call in
    this process when its value is asked for), the booth sends those re-plans to it, as it does
    the parts' plans and the robots' programs, and the plans and programs equal the run without
    a pool."""
    from dataclasses import replace

    from paintcell.booth.booth_data import load_toml_booth
    from paintcell.booth.booth_programs import booth_programs

    sent: list[str] = []

    class Here:
        def share(self, obj: Any) -> Any:
            return obj

        def submit(self, fn: Any, *args: Any) -> Any:
            sent.append(fn.__name__)

            class Later:
                def result(self) -> Any:
                    return fn(*args)

            return Later()

    full = load_toml_booth(Path(__file__).resolve().parent.parent / "scenarios" / "booth.toml")
    kept = [p for p in full.parts if p.part in ("fender", "roof")]
    booth = replace(full, parts=tuple(kept), robots=tuple(
        r for r in full.robots if any(r.name in (p.robots or ()) for p in kept)))
    assert len(booth.parts) == len(booth.robots) == 2
    pooled = booth_programs(booth, True, tasks=Here())
    plain = booth_programs(booth, True)
    replanned = [r.get("replanned", []) for r in pooled.record["speed_feedback"]["rounds"]]
    assert sum(map(len, replanned)) == sent.count("replan_capped") > 0
    assert {name for r in replanned for name in r} == {"fender", "roof"}
    assert sent.count("plan_part") == len(booth.parts) and "remote_job_program" in sent
    assert pooled.record["speed_feedback"] == plain.record["speed_feedback"]
    for a, b in zip(pooled.trajs, plain.trajs, strict=True):
        assert np.array_equal(a.q, b.q)


def _kill_when_planning(address: str, pids: dict[str, int], killed: list[int]) -> threading.Thread:
    """A thread that SIGKILLs the first worker the scheduler has running a part's plan (a task
    of seconds on a fresh worker: the kill comes within 0.1 s of its start)."""
    from distributed import Client

    def watch() -> None:
        with Client(address, timeout=30) as c:
            t_end = time.monotonic() + 300
            while time.monotonic() < t_end:
                busy = [w for w, keys in c.processing().items()
                        if any(str(k).startswith("plan_part") for k in keys)]
                if busy:
                    os.kill(pids[busy[0]], signal.SIGKILL)
                    killed.append(pids[busy[0]])
                    return
                time.sleep(0.1)

    th = threading.Thread(target=watch, daemon=True)
    th.start()
    return th


def test_a_killed_worker_is_replaced_and_a_lost_cluster_fails_in_one_line(
        local: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        cluster: tuple[str, list[Any]]) -> None:  # noqa: F811 - the fixture
    from distributed import Client

    from paintcell.sweeps import dask_cluster

    address, workers = cluster
    path, ref = local
    booth = load_scenario(path)
    with Client(address, timeout=30) as c:
        pids = c.run(os.getpid)
    assert sorted(pids.values()) == sorted(p.pid for p in workers)

    # 1. one worker SIGKILLed while it plans a part: its task reruns on the other
    killed: list[int] = []
    watcher = _kill_when_planning(address, pids, killed)
    with dask_client(0, address) as client:
        res = run_scenario(booth, tmp_path / "one_killed", fast=True, mode="kinematic",
                           progress=False, tasks=DaskTasks(client, address))
    watcher.join(timeout=5)
    assert killed, "no worker was seen planning a part"
    proc = next(p for p in workers if p.pid == killed[0])
    assert proc.wait(timeout=10) == -signal.SIGKILL
    assert res.passed
    _assert_same_results(ref, tmp_path / "one_killed")

    # 2. the last worker SIGKILLed as well: no worker left, the run fails in one line after
    # NO_WORKERS_S and leaves no results folder
    monkeypatch.setattr(dask_cluster, "NO_WORKERS_S", 3.0)
    monkeypatch.setattr(dask_cluster, "POLL_S", 0.5)
    left = {w: pid for w, pid in pids.items() if pid != killed[0]}
    killed.clear()
    watcher = _kill_when_planning(address, left, killed)
    out = tmp_path / "all_killed"
    with dask_client(0, address) as client, pytest.raises(ClusterError) as exc:
        run_scenario(booth, out, fast=True, mode="kinematic", progress=False,
                     tasks=DaskTasks(client, address))
    watcher.join(timeout=5)
    assert killed
    msg = str(exc.value)
    assert "\n" not in msg and "has had no worker for 3 s" in msg and address in msg
    assert "start workers" in msg
    assert not out.exists()


def test_run_options_refuse_what_they_cannot_do(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """--workers on a one-robot scenario and a --scheduler that is not one: one line each,
    before anything is planned or written."""
    from paintcell.cli.main import main

    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "out"
    assert main(["run", str(root / "scenarios" / "panel.toml"), "--workers", "2",
                 "--out", str(out)]) != 0
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--workers/--scheduler plan a booth's parts" in err
    assert main(["run", str(_booth_file(tmp_path / "case")), "--scheduler",
                 "tcp://127.0.0.1:1", "--out", str(out)]) != 0
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "cannot reach the Dask scheduler at tcp://127.0.0.1:1" in err
    assert not out.exists()
