"""Benchmark: the booth's conveyor-speed sweep on the local Dask cluster.

Runs `scenarios/booth.toml` (4 rail robots, fender + door + roof + hood, line at 0.05 m/s) under its
[sweep.factors] (the line speed error; the robots track the nominal speed), servo execution, at
the fast resolution, with `--workers` processes, and prints: wall time, planning time (the
client builds the booth's programs once), the steady rate (samples per second between the first
and the last finished sample), the per-sample breakdown on a worker (execute, films + metrics,
wall and CPU), and the sweep's figures (yield, worst part's σ/μ and conveyor loss P5/P50/P95).
Other jobs may share the machine: the load average is printed beside the figures.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/sweep_booth.py [--samples 8] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from paintcell.app.scenario_files import load_scenario
from paintcell.sweeps.sweep import run_sweep
from paintcell.validation.sweep_spec import spec_from_scenario

BOOTH = Path(__file__).resolve().parent.parent / "scenarios" / "booth.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=8, help="samples of the sweep")
    ap.add_argument("--workers", type=int, default=2, help="local Dask worker processes")
    args = ap.parse_args()
    scn = load_scenario(BOOTH)
    spec = spec_from_scenario(scn.sweep, fast=True, samples=args.samples)
    print(f"booth sweep: {', '.join(f'{k} ~ {v}' for k, v in spec.factors.items())}; "
          f"{args.samples} samples, LHS, servo, resolution {scn.fast_resolution_m * 1e3:.0f} mm, "
          f"{args.workers} workers")
    print(f"load average before (1 min, shared machine): {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} cores")
    stamps: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = run_sweep(scn, spec, Path(tmp) / "out", fast=True, workers=args.workers,
                        progress=False, report=False,
                        on_sample=lambda r: stamps.append(time.perf_counter()))
        wall = time.perf_counter() - t0
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0]) if len(stamps) > 2 else float("nan")
    tm = [r["timing_s"] for r in res.samples if "execute" in r["timing_s"]]
    print(f"{args.samples} samples: {wall:.1f} s wall (planning {res.prepare_s:.1f} s, first "
          f"sample after {stamps[0] - t0:.1f} s), steady rate {rate:.3f} samples/s")
    print(f"per sample (mean, on a worker): execute {np.mean([t['execute'] for t in tm]):.2f} s, "
          f"films + metrics {np.mean([t['validate'] for t in tm]):.2f} s, total "
          f"{np.mean([t['total'] for t in tm]):.2f} s wall, {np.mean([t['cpu'] for t in tm]):.2f}"
          " s CPU")
    figs = res.summary["figures"]
    print(f"yield {res.summary['yield_pct']:.0f} % (95 % CI "
          f"{res.summary['yield_ci_pct'][0]:.0f}-{res.summary['yield_ci_pct'][1]:.0f} %)")
    for key in ("max_part_executed_nsd_pct", "loss_conveyor_pp", "carrier_speed_m_s"):
        f = figs[key]
        print(f"{key} [{f['unit']}]: nominal {f['nominal']:.4g}, P5 {f['p5']:.4g}, "
              f"P50 {f['p50']:.4g}, P95 {f['p95']:.4g}")
    print(f"load average after (1 min): {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
