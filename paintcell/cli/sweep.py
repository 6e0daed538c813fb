"""`paintcell sweep SCENARIO` (its parser and command) and the sweep rows of `paintcell check`."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from paintcell.cli.common import SEED, number_option
from paintcell.validation.sweep_names import FACTORS, METHODS


def add_sweep_parser(add_parser: Any) -> None:
    """Register `sweep` with the CLI's `add_parser(name, **kw)`."""
    factors = "; ".join(f"{n} [{u}]: {m}" for n, (u, m) in FACTORS.items())
    s = add_parser(
        "sweep", help="robustness sweep: many runs under sampled tolerances",
        description="Run the scenario many times under sampled disturbances on Dask (a local "
        "cluster of processes, or --scheduler): the nominal run first, then every sample of a "
        "Latin-hypercube or Monte-Carlo design. Each sample's record streams into OUT/samples/ "
        "as it finishes; summary.json holds P5/P50/P95 of every figure, the yield with its 95 % "
        "Clopper-Pearson interval and the Spearman sensitivity of each factor; report.html "
        "plots them. Rerunning the same command in the same --out resumes: finished samples are "
        "not run again. Exits 1 when the scenario's sweep limits are not met.")
    s.add_argument("scenario", help="scenario file, e.g. scenarios/door.toml (its [sweep] table "
                   "gives default factors, samples and limits)")
    s.add_argument("--vary", action="append", default=[], metavar="NAME=DIST",
                   help="a factor and its distribution, repeatable, e.g. --vary "
                   "'part_offset_m=normal(0, 0.005)'. DIST: normal(mean, sd), uniform(low, "
                   "high), triangular(low, mode, high), truncnormal(mean, sd, low, high) or a "
                   f"number, in the factor's unit. Factors: {factors}")
    s.add_argument("--samples", default=None,
                   type=number_option("--samples", int, low=1, example="100"),
                   help="number of samples (default: the scenario's sweep samples, else 100)")
    s.add_argument("--method", choices=METHODS, default=None,
                   help="design: lhs (Latin hypercube) or mc (Monte Carlo); default lhs")
    s.add_argument("--seed", type=SEED, default=None,
                   help="sweep seed: the design and every sample's own seed derive from it "
                   "(default: the scenario's, else 0)")
    s.add_argument("--workers", default=None,
                   type=number_option("--workers", int, low=0, high=1024, example="2",
                                      note="0: run in this process"),
                   help="worker processes of the local Dask cluster (0: run in this process; "
                   "default: the scenario's sweep workers, else 2)")
    s.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="use an existing Dask cluster, e.g. tcp://10.0.0.5:8786 (then "
                   "--workers is ignored; the workers need paintcell installed)")
    s.add_argument("--out", type=Path, default=None,
                   help="results folder (default: results/<scenario name>-sweep)")
    s.add_argument("--fast", action="store_true",
                   help="the scenario's coarse resolution and fast planner (and its sweep "
                   "fast_samples, if given)")
    s.add_argument("--mode", choices=("servo", "kinematic"), default="servo",
                   help="execution of every sample: servo (PD + feed-forward) or kinematic")
    s.add_argument("--no-report", action="store_true", help="skip report.html and its plots")
    s.set_defaults(func=cmd_sweep)


def cmd_sweep(args: argparse.Namespace) -> int:
    """Run `paintcell sweep`; exit 0, or 1 when a sweep limit of the scenario is not met."""
    from paintcell.app.scenario_files import load_scenario
    from paintcell.sweeps.sweep import run_sweep
    from paintcell.validation.sweep_spec import SCENARIO_DEFAULTS, spec_from_scenario

    scn = load_scenario(args.scenario)
    spec = spec_from_scenario(scn.sweep, fast=args.fast, vary=args.vary, samples=args.samples,
                              method=args.method, seed=args.seed)
    out = args.out or Path("results") / f"{scn.name}-sweep"
    workers = args.workers if args.workers is not None else \
        scn.sweep.get("workers", SCENARIO_DEFAULTS["workers"])
    res = run_sweep(scn, spec, out, fast=args.fast, mode=args.mode, workers=workers,
                    scheduler=args.scheduler, report=not args.no_report)
    print(format_summary(res.summary))
    print(f"ran {res.ran} sample(s) in {res.wall_s:.1f} s; results: {out}"
          + ("" if args.no_report else f" (report: {out / 'report.html'})"))
    return 0 if res.summary["limits_passed"] else 1


def format_summary(s: dict[str, Any]) -> str:
    """Plain-text summary: yield, quantiles, top sensitivities, limit checks."""
    lo, hi = s["yield_ci_pct"]
    y = s["yield_pct"]
    lines = [f"yield {'-' if y is None else f'{y:.1f}'} % of {s['samples_done']} samples "
             f"(95 % CI {lo:.1f}-{hi:.1f} %), {s['errors']} not simulable"]
    lines.append(f"{'figure':<32} {'nominal':>9} {'P5':>9} {'P50':>9} {'P95':>9}")
    for k, v in s["figures"].items():
        lines.append(f"{k + ' [' + v['unit'] + ']':<32} "
                     + " ".join(f"{_f(v.get(q)):>9}" for q in ("nominal", "p5", "p50", "p95")))
    for f, row in s["sensitivity"].items():
        rho = row["executed_nsd_pct"]["rho"]
        lines.append(f"sensitivity of executed σ/μ to {f}: Spearman ρ = {_f(rho)}")
        if "max_part_executed_nsd_pct" in row:   # a booth: its threshold is the worst part's
            rho = row["max_part_executed_nsd_pct"]["rho"]
            lines.append(f"sensitivity of the worst part's executed σ/μ to {f}: Spearman ρ = "
                         f"{_f(rho)}")
    for c in s["limit_checks"]:
        lines.append(f"limit {c['name']}: {_f(c['value'])} {'≤' if c['kind'] == 'max' else '≥'} "
                     f"{_f(c['limit'])} {'PASS' if c['passed'] else 'FAIL'}")
    return "\n".join(lines)


def _f(v: Any) -> str:
    return "-" if v is None else f"{float(v):.4g}"


def sweep_checks(scn: Any, fast: bool, out: Path | None) -> list[dict[str, Any]]:
    """`paintcell check`: when the scenario's sweep has limits, run the sweep (its
    fast_samples under --fast; a local cluster of the sweep's `workers`, default 2, 0: in this
    process) and return its limit checks as check rows."""
    import tempfile

    from paintcell.sweeps.sweep import run_sweep
    from paintcell.validation.sweep_spec import SCENARIO_DEFAULTS, spec_from_scenario

    if not scn.sweep.get("limits"):
        return []
    spec = spec_from_scenario(scn.sweep, fast=fast)
    workers = scn.sweep.get("workers", SCENARIO_DEFAULTS["workers"])
    with tempfile.TemporaryDirectory() as tmp:
        folder = (out / f"{scn.name}-sweep") if out is not None else Path(tmp) / "sweep"
        res = run_sweep(scn, spec, folder, fast=fast, workers=workers, progress=False,
                        report=out is not None)
    return [{"name": f"sweep {c['name']}", "value": c["value"], "limit": c["limit"],
             "unit": "", "passed": c["passed"], "kind": c["kind"]}
            for c in res.summary["limit_checks"]]
