"""Benchmark: a booth run on local Dask workers (`paintcell run --fast BOOTH --workers N`).

Runs `paintcell run --fast` (the command line, servo execution, no report) on
scenarios/booth.toml with 1 and then 2 local Dask worker processes (`--workers 1 2`; 0 adds the
in-process run), and prints for each: the wall time of the command, its stages as metrics.json
records them — planning (the parts' plans, finished plans, robot models and body probes),
programs (allocation, the robots' programs, robot-aware re-planning, staggering, tracking),
execution (the one MuJoCo booth) and validation — and the rest (interpreter start, the local
cluster's start, writing the results); then the ratio of the 1-worker time to the 2-worker time
of each, and whether every metric equals the first run's. Planning and programs are the stages
the workers share; execution and validation run in the client. Planning + programs is split
into the time the client waited on the workers' tasks (the parts planned, the robots' programs
built, the robot-aware re-plans: what more workers shorten) and the client's own work between
them (reading the parts, film refinement, seam blending, the body's joint fit, staggering:
serial, the same with any worker count), each with its ratio.

Then the same on a generated car body's paint line (`paintcell generate body --seed S`, then
`paintcell init BODY --line --takt T`, each command's wall time printed), when this paintcell
has those commands; when it has not, it says so and skips that part. With --hand, the seed-1
SUV's line laid out by hand (benchmarks/hand_line.toml: scenarios/booth.toml's layout extended
to the whole body, the same body, panels, plans and spec) runs after it, and the two booth
cycles are printed with their ratio. Other jobs may share the machine: the load average is
printed beside the figures.

    .venv/bin/python benchmarks/body_line.py [--workers 1 2] [--takt 100] [--seed 1] [--no-body]
                                             [--hand]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
BOOTH = ROOT / "scenarios" / "booth.toml"
#: the seed-1 SUV's line laid out by hand (scenarios/booth.toml's layout extended).
HAND = ROOT / "benchmarks" / "hand_line.toml"
#: metrics.json's stage_times_s keys, as the benchmark names them.
STAGES = {"plan": "planning", "trajectory": "programs", "execute": "execution",
          "validate": "validation"}
#: the stages the workers share (their 1→2 ratio is the speed-up of the pool).
PARALLEL = ("planning", "programs")


def _paintcell(*args: str, timeout_s: float = 3600.0) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run([sys.executable, "-m", "paintcell", *args], capture_output=True,
                          text=True, env=env, timeout=timeout_s)


def run_once(scenario: Path, workers: int, out: Path) -> dict[str, Any]:
    """`paintcell run --fast scenario --workers N`: wall time [s], stage times [s], metrics."""
    t0 = time.perf_counter()
    r = _paintcell("run", "--fast", str(scenario), "--workers", str(workers), "--out", str(out),
                   "--no-report")
    wall = time.perf_counter() - t0
    if not (out / "metrics.json").exists():
        raise SystemExit(f"paintcell run --workers {workers} failed (rc {r.returncode}): "
                         f"{(r.stderr or r.stdout).strip()[-400:]}")
    m = json.loads((out / "metrics.json").read_text())
    times = m.pop("stage_times_s")
    stages = {STAGES[k]: float(v) for k, v in times.items() if k in STAGES}
    stages["rest"] = wall - sum(stages.values())
    # of planning + programs: waiting on the workers' tasks, and the client's own work
    wait = float(times.get("workers_wait", 0.0))
    split = {"waiting on the workers": wait,
             "the client's own work": sum(stages[k] for k in PARALLEL) - wait}
    return {"wall": wall, "stages": stages, "split": split, "metrics": m,
            "passed": r.returncode == 0}


def bench(label: str, scenario: Path, workers: list[int], tmp: Path) -> dict[int, dict[str, Any]]:
    """Run the scenario with each worker count; print every figure and the 1→2 ratios; the
    runs by worker count."""
    print(f"\n== {label}: paintcell run --fast {scenario}")
    runs: dict[int, dict[str, Any]] = {}
    for n in workers:
        load = os.getloadavg()[0]
        res = runs[n] = run_once(scenario, n, tmp / f"{label}-{n}")
        who = "in this process" if n == 0 else f"{n} local Dask worker process(es)"
        print(f"workers {n} ({who}; load average {load:.1f} before, "
              f"{os.getloadavg()[0]:.1f} after):")
        print(f"  wall time of the command     {res['wall']:8.1f} s")
        for k, v in res["stages"].items():
            print(f"  {k + ' time':<28} {v:8.1f} s")
        for k, v in res["split"].items():
            print(f"    planning + programs: {k:<26} {v:8.1f} s")
        same = res["metrics"] == runs[workers[0]]["metrics"]
        print(f"  result {'PASS' if res['passed'] else 'FAIL'}; every metric equal to the "
              f"workers {workers[0]} run: {'yes' if same else 'NO'}")
    if 1 in runs and 2 in runs:
        a, b = runs[1], runs[2]
        print("ratio 1 worker → 2 workers (time with 1 ÷ time with 2; > 1: faster with 2):")
        for k in (*PARALLEL, "execution"):
            print(f"  {k:<28} {a['stages'][k] / b['stages'][k]:8.2f} ×")
        par = [sum(r["stages"][k] for k in PARALLEL) for r in (a, b)]
        print(f"  {'planning + programs':<28} {par[0] / par[1]:8.2f} ×")
        for k in a["split"]:
            ratio = f"{a['split'][k] / b['split'][k]:8.2f} ×" if b["split"][k] > 0 else "     n/a"
            print(f"    {k:<26} {ratio}")
        print(f"  {'wall time':<28} {a['wall'] / b['wall']:8.2f} ×")
    return runs


def beside_hand(auto: dict[str, Any], workers: int, tmp: Path) -> None:
    """The hand-laid line (`HAND`) run as the automatic one was; both cycles and their ratio."""
    print(f"\n== the line laid out by hand: paintcell run --fast {HAND} --workers {workers}")
    hand = run_once(HAND, workers, tmp / "hand")
    a, h = (float(r["metrics"]["executed_cycle_time_s"]) for r in (auto, hand))
    print(f"  result {'PASS' if hand['passed'] else 'FAIL'}; worst panel σ/μ "
          f"{hand['metrics']['max_part_executed_nsd_pct']:.2f} %, body "
          f"{hand['metrics']['executed_nsd_pct']:.2f} %, seams ÷ interiors "
          f"{hand['metrics']['seam_nsd_ratio']:.2f}")
    print(f"  booth cycle: automatic {a:.2f} s (result {'PASS' if auto['passed'] else 'FAIL'}), "
          f"by hand {h:.2f} s; automatic ÷ by hand {a / h:.3f} (> 1: the automatic line is "
          "slower)")


def body_line(tmp: Path, takt_s: float, seed: int) -> Path | None:
    """A generated body's paint line (booth file), or None with the reason printed when this
    paintcell cannot make one."""
    gen = _paintcell("generate", "--help")
    init = _paintcell("init", "--help")
    if "body" not in gen.stdout or "--line" not in init.stdout:
        print("\n== body line: skipped — this paintcell has no `paintcell generate body` and/or "
              "`paintcell init BODY --line --takt T`")
        return None
    body = tmp / "body.stl"
    line = tmp / "line.toml"
    print(f"\n== body line: paintcell generate body --seed {seed}, then init --line --takt "
          f"{takt_s:g}")
    for args in (("generate", "body", "--seed", str(seed), "--out", str(body)),
                 ("init", str(body), "--line", "--takt", f"{takt_s:g}", "--out", str(line))):
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        r = _paintcell(*args)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            print(f"body line: skipped — `paintcell {' '.join(args)}` failed "
                  f"(rc {r.returncode}): {(r.stderr or r.stdout).strip()[-300:]}")
            return None
        print(f"  wall time of `paintcell {args[0]}`{' ' * (12 - len(args[0]))} {wall:8.1f} s "
              f"(load average {load:.1f} before, {os.getloadavg()[0]:.1f} after)")
        if args[0] == "init":
            print("  " + r.stdout.strip().splitlines()[0])
    return line


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2],
                    help="local Dask worker counts to time, in order (0: in this process)")
    ap.add_argument("--takt", type=float, default=100.0,
                    help="the generated body line's takt [s] (a body every TAKT seconds; 100: "
                         "the seed-1 SUV's six-robot line has an ~83 s cycle, which a 75 s or "
                         "90 s takt does not leave room for)")
    ap.add_argument("--seed", type=int, default=1,
                    help="the generated body's seed (odd: an SUV; scenarios/body_line.toml's: 1)")
    ap.add_argument("--no-body", action="store_true", help="only scenarios/booth.toml")
    ap.add_argument("--hand", action="store_true",
                    help="also run benchmarks/hand_line.toml (the seed-1 SUV's line laid out by "
                         "hand) with the largest --workers, beside the generated line (seed 1, "
                         "takt 100: the body and panels it was laid out for)")
    args = ap.parse_args()
    print(f"{os.cpu_count()} CPU cores; load average {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory(prefix="paintcell-body-line-") as d:
        tmp = Path(d)
        bench("booth", BOOTH, args.workers, tmp)
        if not args.no_body and (line := body_line(tmp, args.takt, args.seed)) is not None:
            runs = bench("body line", line, args.workers, tmp)
            if args.hand:
                beside_hand(runs[max(args.workers)], max(args.workers), tmp)


if __name__ == "__main__":
    main()
