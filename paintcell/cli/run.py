"""The `paintcell run` and `paintcell plan` sub-commands: a scenario in, a results folder out."""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

from paintcell.cli.check import format_table, row
from paintcell.cli.common import (
    EXIT_FAIL,
    EXIT_OK,
    FAST_HELP,
    SCENARIO_HELP,
    default_out,
    key_values,
    number_option,
)
from paintcell.core.errors import PaintcellError

# --- run ----------------------------------------------------------------------------------------

def add_run(add_parser: Any) -> None:
    r = add_parser("run", help="run one scenario end to end", description=(
        "Plan → IK → trajectory → MuJoCo execution → validation → report for one scenario; "
        "writes plan.json/.npz, trajectory.npz/.csv, trace.npz, metrics.json, scenario.json "
        "(the scenario as data) and report.html into --out, atomically. Exits 1 when a "
        "threshold is not met."))
    r.add_argument("scenario", help=SCENARIO_HELP)
    r.add_argument("--out", type=Path, default=None,
                   help="results folder (default: results/<scenario name>); replaced only if "
                   "missing, empty or an earlier paintcell results folder")
    r.add_argument("--fast", action="store_true", help=FAST_HELP)
    r.add_argument("--mode", choices=("servo", "kinematic"), default="servo",
                   help="servo: PD + inverse-dynamics control at 1 kHz; kinematic: ideal replay")
    r.add_argument("--no-report", action="store_true",
                   help="skip renders, plots and report.html (data files only)")
    r.add_argument("--video", action="store_true",
                   help="also render the execution video execution.gif (tens of seconds) and embed "
                   "it in report.html (a few MB; without it the report stays under 2 MB)")
    r.add_argument("--disturb", action="append", default=[], metavar="KEY=VALUE",
                   help="robustness study: a Disturbances setting (paintcell.execution) on top "
                   "of the scenario's (a booth: on every robot and the body), repeatable: "
                   "part_offset_m [m], part_rotation_rad [rad], "
                   "tcp_offset_m [m], gain_scale [-], standoff_error_m [m], trigger_delay_s [s], "
                   "flow_scale [-], flow_drift [-], seed [int]; e.g. --disturb "
                   "part_offset_m=0.005 --disturb seed=3")
    r.add_argument("--workers", default=0,
                   type=number_option("--workers", int, low=0, high=1024, example="2",
                                      note="0: run in this process"),
                   help="a booth: worker processes of a local Dask cluster that plan its parts, "
                   "build its robots' programs and re-plan its parts robot-aware at the same "
                   "time (a count of processes, one thread each; 0, the default: everything in "
                   "this process). The plans, programs and metrics are the same with any number "
                   "of workers (to rounding, ~1e-13, where a part's planner refines its film "
                   "itself)")
    r.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="a booth: plan its parts and build its programs on an existing Dask "
                   "cluster, e.g. tcp://10.0.0.5:8786 (then --workers is ignored; the workers "
                   "need paintcell installed and read no file: the parts' surfaces and the "
                   "bell are sent to them)")
    # Internal, for `paintcell check`: write the table row as JSON to an open file descriptor;
    # results under a folder; the check's pid (its child stops when the check dies).
    r.add_argument("--row-fd", default=None, help=argparse.SUPPRESS,
                   type=number_option("--row-fd", int, low=0, example="3"))
    r.add_argument("--out-under", type=Path, default=None, help=argparse.SUPPRESS)
    r.add_argument("--parent-pid", default=None, help=argparse.SUPPRESS,
                   type=number_option("--parent-pid", int, low=1, example="1234"))
    r.set_defaults(func=_cmd_run)


def _cmd_run(args: argparse.Namespace) -> int:
    if args.parent_pid is None:
        return _run(args)
    from paintcell.cli.process_group import scenario_worker

    with scenario_worker(args.parent_pid):
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    from paintcell.app.scenario_files import load_scenario

    scn = load_scenario(args.scenario)   # before the pipeline's imports: a bad file is told at once
    from paintcell.app.pipeline import run_scenario

    if args.disturb:       # a one-robot cell or a booth: every robot runs under it
        scn = replace(scn, disturbances={**scn.disturbances, **key_values(args.disturb)})
        from paintcell.validation.settings_tables import check_settings_table

        check_settings_table("disturbances", scn.disturbances, "--disturb")
    # `paintcell check` runs each scenario as `run --row-fd N` in its own process and
    # writes results only when it was given --out.
    worker = args.row_fd is not None
    out = args.out or (args.out_under / scn.name if args.out_under is not None
                       else None if worker else default_out(scn.name))
    kw = {"fast": args.fast, "mode": args.mode, "report": not (args.no_report or worker),
          "progress": not worker, "video": args.video}
    if args.workers or args.scheduler is not None:
        res = _run_on_dask(scn, out, args.workers, args.scheduler, kw)
    else:
        res = run_scenario(scn, out, **kw)
    r = row(scn.name, res.report)
    if worker:
        from paintcell.cli.sweep import (
            sweep_checks,  # the limits of the scenario's sweep, if any
        )
        r["checks"] += sweep_checks(scn, args.fast, args.out_under)
        r["passed"] = bool(r["passed"]) and all(c["passed"] for c in r["checks"])
        with open(args.row_fd, "w", encoding="utf-8", closefd=False) as f:
            f.write(json.dumps(r))
        return EXIT_OK if r["passed"] else EXIT_FAIL
    print(format_table([r]))
    if out is not None:
        html = (out / "report.html").exists()
        print(f"results: {out}" + (f" (report: {out / 'report.html'})" if html else ""))
    return EXIT_OK if res.passed else EXIT_FAIL


def _run_on_dask(scn: Any, out: Path | None, workers: int, scheduler: str | None,
                 kw: dict[str, Any]) -> Any:
    """A booth run whose parts and programs are made on Dask (`paintcell.sweeps.dask_cluster`:
    a local cluster of `workers` processes, or the cluster at `scheduler`)."""
    from paintcell.app.pipeline import run_scenario
    from paintcell.booth.booth import Booth
    from paintcell.sweeps.dask_cluster import DaskTasks, dask_client

    if not isinstance(scn, Booth):
        raise PaintcellError("--workers/--scheduler plan a booth's parts and build its robots' "
                             "programs in parallel; a one-robot scenario runs in this process: "
                             "drop them")
    where = scheduler if scheduler is not None else \
        f"(a local cluster of {max(1, workers)} worker processes)"
    with dask_client(workers, scheduler) as client:
        return run_scenario(scn, out, tasks=DaskTasks(client, where), **kw)


# --- plan ---------------------------------------------------------------------------------------

def add_plan(add_parser: Any) -> None:
    pl = add_parser("plan", help="plan only: write plan.json/.npz", description=(
        "Run the coverage planner of a scenario and write plan.json (+ plan.npz) and "
        "scenario.json into a fresh results folder --out (replacing an earlier one "
        "atomically; a failed plan leaves it as it was). A booth: each part's plan as its "
        "robots get it, plan_<part index>.json."))
    pl.add_argument("scenario", help=SCENARIO_HELP)
    pl.add_argument("--out", type=Path, default=None,
                    help="output folder (default: results/<scenario name>); replaced only if "
                    "missing, empty or an earlier paintcell results folder")
    pl.add_argument("--fast", action="store_true", help=FAST_HELP)
    pl.set_defaults(func=_cmd_plan)


def _cmd_plan(args: argparse.Namespace) -> int:
    from paintcell.app.pipeline import cell_plans, scenario_json
    from paintcell.app.scenario_files import load_scenario
    from paintcell.core.atomic_io import atomic_write_text
    from paintcell.core.results_dir import new_results

    scn = load_scenario(args.scenario)
    out = args.out or default_out(scn.name)
    with new_results(out, "plan") as tmp:
        assert tmp is not None
        plans = cell_plans(scn, args.fast)
        for stem, plan in plans.items():
            plan.save(tmp / f"{stem}.json")
        atomic_write_text(tmp / "scenario.json", scenario_json(scn, args.fast, "none"))
    for stem, plan in plans.items():
        label = scn.name if stem == "plan" else f"{scn.name}: {stem}"
        print(f"{label}: {len(plan.passes)} passes, paint time "
              f"{plan.paint_time_s:.1f} s, start curve: {plan.start_rule}")
        print(f"plan: {out / (stem + '.json')}")
    return EXIT_OK
