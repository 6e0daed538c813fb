"""Benchmark: a door robustness sweep on the local Dask cluster.

Runs the door scenario (`scenarios/door.toml`, servo execution) under seven tolerances, first with
1 worker and then with 2 (`--probe` samples each), and prints for each: wall time, the
steady-state rate (samples per second between the first and the last finished sample), and the
per-sample breakdown (execute, validate, the rest: queueing, transfer, writing). Then either runs
the `--samples` sweep with 2 workers (`--full`) or extrapolates its wall time from the 2-worker
rate (start-up + samples ÷ rate), and says which. Resolution: the scenario's fast resolution
(25 mm) unless `--full-resolution`. Other jobs may share the machine: the load average is
printed beside the figures.

    .venv/bin/python benchmarks/sweep.py [--probe 24] [--samples 1000] [--full]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.app.scenario_files import load_scenario
from paintcell.sweeps.sweep import run_sweep
from paintcell.validation.sweep_spec import SweepSpec

DOOR = Path(__file__).resolve().parent.parent / "scenarios" / "door.toml"
#: the door scenario's own sweep factors (scenarios/door.toml [sweep.factors]).
FACTORS = [f"{k}={v}" for k, v in load_scenario(DOOR).sweep["factors"].items()]


def one(scn: Any, n: int, workers: int, fast: bool, out: Path) -> dict[str, Any]:
    """Run an n-sample sweep; timings."""
    stamps: list[float] = []
    spec = SweepSpec.from_strings(FACTORS, n, "lhs", seed=1)
    t0 = time.perf_counter()
    res = run_sweep(scn, spec, out, fast=fast, workers=workers, progress=False, report=False,
                    on_sample=lambda r: stamps.append(time.perf_counter()))
    wall = time.perf_counter() - t0
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0]) if len(stamps) > 2 else float("nan")
    tm = [r["timing_s"] for r in res.samples]
    return {"wall": wall, "rate": rate, "startup": stamps[0] - t0 if stamps else float("nan"),
            "prepare": res.prepare_s, "execute": float(np.mean([t["execute"] for t in tm])),
            "validate": float(np.mean([t["validate"] for t in tm])),
            "total": float(np.mean([t["total"] for t in tm])),
            "cpu": float(np.mean([t["cpu"] for t in tm])),
            "yield": res.summary["yield_pct"],
            "p95_nsd": res.summary["figures"]["executed_nsd_pct"]["p95"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--probe", type=int, default=24, help="samples of the 1- and 2-worker runs")
    ap.add_argument("--samples", type=int, default=1000, help="samples of the big sweep")
    ap.add_argument("--full", action="store_true", help="run the big sweep (else extrapolate)")
    ap.add_argument("--full-resolution", action="store_true",
                    help="the scenario's full resolution instead of the fast one")
    args = ap.parse_args()
    fast = not args.full_resolution
    scn = load_scenario(DOOR)
    res_m = scn.fast_resolution_m if fast else scn.resolution_m
    print(f"door sweep: {len(FACTORS)} factors ({', '.join(f.split('=')[0] for f in FACTORS)}),"
          f" LHS, servo execution, resolution {res_m * 1e3:.0f} mm")
    print(f"load average before (1 min, shared machine): {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} cores")
    rates = {}
    with tempfile.TemporaryDirectory() as tmp:
        for w in (1, 2):
            r = one(scn, args.probe, w, fast, Path(tmp) / f"w{w}")
            rates[w] = r
            print(f"{w} worker(s), {args.probe} samples: {r['wall']:.1f} s wall "
                  f"(planning {r['prepare']:.1f} s, first sample after {r['startup']:.1f} s), "
                  f"steady rate {r['rate']:.2f} samples/s")
            print(f"  per sample (mean, on a worker): execute {r['execute']:.2f} s, validate "
                  f"{r['validate']:.3f} s, total {r['total']:.2f} s wall, {r['cpu']:.2f} s CPU;"
                  f" yield {r['yield']:.0f} %, P95 executed σ/μ {r['p95_nsd']:.3f} %")
        print(f"2 / 1 worker rate: {rates[2]['rate'] / rates[1]['rate']:.2f} x")
        if args.full:
            r = one(scn, args.samples, 2, fast, Path(tmp) / "full")
            print(f"{args.samples}-sample sweep, 2 workers: {r['wall']:.1f} s wall "
                  f"({r['wall'] / 60:.1f} min; target <= 10 min), measured")
        else:
            est = rates[2]["startup"] + args.samples / rates[2]["rate"]
            print(f"{args.samples}-sample sweep, 2 workers: {est:.0f} s ({est / 60:.1f} min; "
                  "target <= 10 min), EXTRAPOLATED from the 2-worker steady rate (not run)")
            cpu = rates[2]["startup"] + args.samples * rates[2]["cpu"] / 2
            print(f"{args.samples}-sample sweep on 2 unshared cores, estimated from the CPU time "
                  f"a sample takes (startup + samples x CPU / 2): {cpu:.0f} s "
                  f"({cpu / 60:.1f} min), an ESTIMATE")
    print(f"load average after (1 min): {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
