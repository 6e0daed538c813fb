"""The `paintcell` command line: run, check, plan, validate, export, report.

Each subcommand is registered by one `_add_<name>(sub)` function (its options, its help and the
function that runs it); `build_parser` calls them in order, so a new subcommand is one more
function and one more line there. Exit codes are in `EXIT_HELP`. Errors print one line;
`--debug` shows the traceback.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import traceback
from dataclasses import replace
from pathlib import Path
from typing import Any

from planning.errors import PaintcellError
from sim import interrupts
from sim.cli_check import add_check, format_table, row, write_junit
from sim.part_commands import register as add_part_commands

__all__ = ["EXIT_FAIL", "EXIT_INTERRUPTED", "EXIT_OK", "EXIT_USAGE", "build_parser", "main",
           "format_table", "write_junit"]

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130

EXIT_HELP = """\
exit codes:
  0    success (run/check/validate: every threshold met)
  1    a threshold was not met (run, check, validate), or a check scenario errored
  2    usage or input error (bad option, scenario, mesh, results folder; a busy folder)
  130  interrupted (Ctrl-C or SIGTERM); nothing half-written is left behind

results folders: a folder is paintcell's only if it holds the .paintcell-results marker;
run/plan replace only such a folder (or a missing or empty one), atomically, one writer at a
time; validate/export/report read the scenario snapshot in scenario.json, never a script."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"paintcell: error: {message} (see `paintcell --help`)\n")
        raise SystemExit(EXIT_USAGE)


class _Help(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Shows a default only where it tells something (not None, False or an empty list)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default in (None, False, [], argparse.SUPPRESS) or action.required:
            return action.help
        return super()._get_help_string(action)


FAST_HELP = ("the scenario's coarse mesh resolution (fast_resolution_m, 25 mm unless the "
             "scenario says otherwise) and fast planner overrides (CI budget)")
SCENARIO_HELP = "scenario file: TOML (e.g. scenarios/door.toml) or a Python script"
DIR_HELP = "results folder written by `paintcell run`"


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand (its --help is the reference)."""
    # --debug works before or after the subcommand (SUPPRESS keeps the main parser's value).
    common = _Parser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show the full traceback on errors instead of one line")
    p = _Parser(prog="paintcell", formatter_class=_Help, epilog=EXIT_HELP, description=(
        "Plan uniform spray-paint coverage for a car-body part, execute it on a simulated paint "
        "robot in MuJoCo and measure the film-thickness uniformity lost from plan to execution."))
    p.add_argument("--debug", action="store_true",
                   help="show the full traceback on errors instead of one line")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    def add_parser(name: str, **kw: Any) -> argparse.ArgumentParser:
        return sub.add_parser(name, parents=[common], formatter_class=_Help, epilog=EXIT_HELP,
                              **kw)

    from sim.sweep_cli import add_sweep_parser

    for register in (_add_run, add_check, _add_plan, _add_validate, _add_export, _add_report,
                     add_part_commands,  # inspect, init, generate (issue 11)
                     add_sweep_parser):
        register(add_parser)
    return p


def main(argv: list[str] | None = None) -> int:
    """Console entry point; returns the exit code."""
    interrupts.reset()
    previous = {s: signal.signal(s, interrupts.on_signal)
                for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        code = _main(argv)
        # A signal that a library swallowed (see sim.interrupts) still ends the command as one.
        return EXIT_INTERRUPTED if interrupts.pending() is not None else code
    except KeyboardInterrupt as exc:  # a signal while the parser was built, before the command
        sys.stderr.write(f"paintcell: interrupted ({exc or 'SIGINT'}); nothing half-written was "
                         "left\n")
        return EXIT_INTERRUPTED
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except KeyboardInterrupt as exc:
        what = str(exc) or "SIGINT"
        sys.stderr.write(f"paintcell: interrupted ({what}); nothing half-written was left\n")
        return EXIT_INTERRUPTED
    except (PaintcellError, FileNotFoundError, ValueError, OSError) as exc:
        if args.debug:
            traceback.print_exc()
        sys.stderr.write(f"paintcell: error: {one_line(exc)}\n")
        return EXIT_USAGE
    except MemoryError:
        if args.debug:
            traceback.print_exc()
        sys.stderr.write("paintcell: error: out of memory; use a coarser resolution_m or "
                         "smaller sample settings in the scenario\n")
        return EXIT_USAGE
    except Exception as exc:  # a bug, not bad input: still one line unless --debug
        if args.debug:
            traceback.print_exc()
        sys.stderr.write(f"paintcell: internal error: {type(exc).__name__}: {one_line(exc)} "
                         "(rerun with --debug for the traceback)\n")
        return EXIT_USAGE


def one_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type name when empty)."""
    msg = str(exc).strip().splitlines()
    return msg[0] if msg else type(exc).__name__


def _default_out(name: str) -> Path:
    return Path("results") / name


# --- run ----------------------------------------------------------------------------------------

def _add_run(add_parser: Any) -> None:
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
                   help="robustness study: a sim.execute.Disturbances setting on top of the "
                   "scenario's, repeatable: part_offset_m [m], part_rotation_rad [rad], "
                   "tcp_offset_m [m], gain_scale [-], standoff_error_m [m], trigger_delay_s [s], "
                   "flow_scale [-], flow_drift [-], seed [int]; e.g. --disturb "
                   "part_offset_m=0.005 --disturb seed=3")
    # Internal, for `paintcell check`: write the table row as JSON; results under a folder.
    r.add_argument("--row-json", type=Path, default=None, help=argparse.SUPPRESS)
    r.add_argument("--out-under", type=Path, default=None, help=argparse.SUPPRESS)
    r.set_defaults(func=_cmd_run)


def _cmd_run(args: argparse.Namespace) -> int:
    from sim.booth import Booth
    from sim.booth_run import run_booth
    from sim.pipeline import run_scenario
    from sim.scenario_files import load_scenario

    scn = load_scenario(args.scenario)
    if args.disturb and not hasattr(scn, "disturbances"):
        raise PaintcellError("--disturb applies to single-robot scenarios, not to a booth")
    if args.disturb:
        scn = replace(scn, disturbances={**scn.disturbances, **_key_values(args.disturb)})
        from sim.scenario_data import check_settings

        check_settings(scn, "--disturb")
    # `paintcell check` runs each scenario as `run --row-json FILE` in its own process and
    # writes results only when it was given --out.
    worker = args.row_json is not None
    out = args.out or (args.out_under / scn.name if args.out_under is not None
                       else None if worker else _default_out(scn.name))
    if isinstance(scn, Booth):   # several robots on a conveyor
        res: Any = run_booth(scn, out, fast=args.fast, mode=args.mode)
    else:
        res = run_scenario(scn, out, fast=args.fast, mode=args.mode,
                           report=not (args.no_report or worker), progress=not worker,
                           video=args.video)
    r = row(scn.name, res.report)
    if worker:
        from planning.atomic_io import atomic_write_text
        from sim.sweep_cli import sweep_checks  # the limits of the scenario's sweep, if any

        r["checks"] += sweep_checks(scn, args.fast, args.out_under)
        r["passed"] = bool(r["passed"]) and all(c["passed"] for c in r["checks"])
        atomic_write_text(args.row_json, json.dumps(r))
        return EXIT_OK if r["passed"] else EXIT_FAIL
    print(format_table([r]))
    if out is not None:
        html = (out / "report.html").exists()   # a booth writes no HTML report (yet)
        print(f"results: {out}" + (f" (report: {out / 'report.html'})" if html else ""))
    return EXIT_OK if res.passed else EXIT_FAIL


def _key_values(items: list[str]) -> dict[str, Any]:
    """Parse KEY=VALUE options; values are ints, floats or strings."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise PaintcellError(f"option value {item!r} is not KEY=VALUE (e.g. "
                                 "part_offset_m=0.005)")
        value: Any = raw
        for conv in (int, float):
            try:
                value = conv(raw)
                break
            except ValueError:
                continue
        out[key.strip()] = value
    return out


# --- plan ---------------------------------------------------------------------------------------

def _add_plan(add_parser: Any) -> None:
    pl = add_parser("plan", help="plan only: write plan.json/.npz", description=(
        "Run the coverage planner of a scenario and write plan.json (+ plan.npz) and "
        "scenario.json into a fresh results folder --out (replacing an earlier one "
        "atomically; a failed plan leaves it as it was)."))
    pl.add_argument("scenario", help=SCENARIO_HELP)
    pl.add_argument("--out", type=Path, default=None,
                    help="output folder (default: results/<scenario name>); replaced only if "
                    "missing, empty or an earlier paintcell results folder")
    pl.add_argument("--fast", action="store_true", help=FAST_HELP)
    pl.set_defaults(func=_cmd_plan)


def _cmd_plan(args: argparse.Namespace) -> int:
    from planning.atomic_io import atomic_write_text
    from sim.pipeline import load_surface, make_plan, scenario_json
    from sim.results_dir import new_results
    from sim.scenario_files import load_scenario

    scn = load_scenario(args.scenario)
    out = args.out or _default_out(scn.name)
    with new_results(out, "plan") as tmp:
        assert tmp is not None
        surface = load_surface(scn, args.fast)
        plan = make_plan(scn, surface, args.fast)
        plan.save(tmp / "plan.json")
        atomic_write_text(tmp / "scenario.json", scenario_json(scn, args.fast, "none"))
    print(f"{scn.name}: {len(plan.passes)} passes, paint time {plan.paint_time_s:.1f} s, "
          f"start curve: {plan.start_rule}")
    print(f"plan: {out / 'plan.json'}")
    return EXIT_OK


# --- validate, export, report: read a results folder, write into it in place --------------------

def _add_validate(add_parser: Any) -> None:
    v = add_parser("validate", help="recompute metrics.json from a results folder", description=(
        "Recompute the plan-vs-executed validation from plan.json, trajectory.npz and trace.npz "
        "in DIR with the scenario snapshot of scenario.json (never the scenario file) and "
        "rewrite metrics.json. Exits 1 when a threshold is not met."))
    v.add_argument("dir", type=Path, help=DIR_HELP)
    v.set_defaults(func=_cmd_validate)


def _cmd_validate(args: argparse.Namespace) -> int:
    from planning.atomic_io import atomic_write_text
    from sim.pipeline import RunResult, json_default, load_surface, metrics_dict
    from sim.report_film import FILM_NAME, save_film
    from sim.results_dir import lock_results, note_files, require_results
    from sim.run_files import load_run_dir, read_json
    from sim.validate import validate

    require_results(args.dir)
    with lock_results(args.dir, "validate"):
        f = load_run_dir(args.dir)
        scn, plan, traj, trace = f["scenario"], f["plan"], f["trajectory"], f["trace"]
        fast, mode = bool(f["run"]["fast"]), str(f["run"]["mode"])
        surface = load_surface(scn, fast)
        rep = validate(plan, surface, traj, trace, scn.part_placement.matrix, scn.thresholds,
                       reachability=traj.meta.get("reachability"))
        old = args.dir / "metrics.json"
        stage_times: dict[str, Any] = {}
        if old.exists():
            try:
                stage_times = dict(read_json(old).get("stage_times_s") or {})
            except (PaintcellError, TypeError, ValueError) as exc:
                # metrics.json is what validate rewrites: a corrupt one is replaced, not fatal.
                sys.stderr.write(f"paintcell: warning: {one_line(exc)} (replacing it)\n")
        res = RunResult(scn, args.dir, surface, plan, traj, trace, rep, timings_s=stage_times,
                        fast=fast, mode=mode)
        atomic_write_text(old, json.dumps(metrics_dict(res), indent=2, default=json_default))
        save_film(args.dir / FILM_NAME, surface, rep)
        note_files(args.dir, ["metrics.json", FILM_NAME])
    print(format_table([row(scn.name, rep)]))
    return EXIT_OK if rep.passed else EXIT_FAIL


def _add_export(add_parser: Any) -> None:
    e = add_parser("export", help="export the robot program", description=(
        "Export the validated program of a results folder, from its files and scenario "
        "snapshot. A run that did not pass validation is refused unless --allow-failed, which "
        "writes a module whose header says it FAILED and why."))
    e.add_argument("dir", type=Path, help=DIR_HELP)
    e.add_argument("--rapid", action="store_true", required=True,
                   help="write an ABB RAPID module (.mod)")
    e.add_argument("--style", choices=("trigg", "paintl"), default="trigg",
                   help="brush events as TriggL + TriggIO on a digital output (trigg), or as "
                   "PaintL + SetBrush (paintl, ABB paint option)")
    e.add_argument("--out", type=Path, default=None,
                   help="module file (default: DIR/<scenario>.mod); an existing file is replaced "
                   "only if paintcell wrote it")
    e.add_argument("--spacing", type=float, default=0.05,
                   help="maximum distance between exported targets along a pass [m]")
    e.add_argument("--allow-failed", action="store_true",
                   help="export a run that failed validation anyway, marked FAILED in the header")
    e.set_defaults(func=_cmd_export)


def _cmd_export(args: argparse.Namespace) -> int:
    from planning.atomic_io import atomic_write_text
    from sim.export_rapid import rapid_module, validation_header
    from sim.pipeline import load_robot_for
    from sim.results_dir import lock_results, note_files, require_results
    from sim.run_files import load_run_dir, read_json

    require_results(args.dir)
    with lock_results(args.dir, "export"):
        metrics = read_json(args.dir / "metrics.json")
        f = load_run_dir(args.dir)
        header = validation_header(metrics, f["plan"].content_digest())
        if not header[0].startswith("VALIDATED"):
            if not args.allow_failed:
                raise PaintcellError(f"{args.dir} did not pass validation ({header[1][8:-1]}); "
                                     "no program exported — fix the scenario and re-run, or "
                                     "pass --allow-failed for a module marked FAILED")
            sys.stderr.write(f"paintcell: warning: exporting a FAILED run ({header[1]})\n")
        scn = f["scenario"]
        text = rapid_module(f["trajectory"], load_robot_for(scn), module_name=scn.name,
                            style=args.style, max_spacing_m=args.spacing, validation=header)
        out = args.out or args.dir / f"{scn.name}.mod"
        inside = out.resolve().parent == args.dir.resolve()
        if out.exists() and not inside and "Generated by paintcell" not in \
                out.read_text(errors="replace")[:400]:
            raise PaintcellError(f"--out {out} exists and was not written by paintcell; choose "
                                 "another file")
        atomic_write_text(out, text)
        if inside:
            note_files(args.dir, [out.name])
    print(f"RAPID module: {out}")
    return EXIT_OK


def _add_report(add_parser: Any) -> None:
    rep = add_parser("report", help="rebuild report.html of a folder",
                     description="Rebuild report.html from the files of a results folder: verdict, "
                     "film map, histogram vs the spec window, per-pass table; then the detail.")
    rep.add_argument("dir", type=Path, help=DIR_HELP)
    rep.add_argument("--video", action="store_true",
                     help="embed the folder's execution video execution.gif (made by "
                     "`paintcell run --video`; adds a few MB)")
    rep.set_defaults(func=_cmd_report)


def _cmd_report(args: argparse.Namespace) -> int:
    from sim.report import write_report
    from sim.results_dir import lock_results, note_files, require_results
    from sim.run_files import check_folder_files

    if not (args.dir / "metrics.json").exists():
        raise PaintcellError(f"{args.dir / 'metrics.json'} is missing; run `paintcell run` first")
    require_results(args.dir)
    with lock_results(args.dir, "report"):
        check_folder_files(args.dir)
        try:
            path = write_report(args.dir, video=args.video)
        except (PaintcellError, OSError):
            raise
        except Exception as exc:  # a file whose content is valid JSON but not what it should be
            raise PaintcellError(f"cannot build the report of {args.dir} ({type(exc).__name__}: "
                                 f"{one_line(exc)}); a file in it was edited or corrupted — "
                                 "re-run `paintcell run`") from exc
        note_files(args.dir, [path.name])
    print(f"report: {path}")
    return EXIT_OK


if __name__ == "__main__":
    raise SystemExit(main())


def run_script(scenario: Any, argv: list[str] | None = None) -> int:
    """Entry point of a scenario script: `paintcell run <the script>` with the script's command-line
    arguments (or `argv`). A script ends with `raise SystemExit(run_script(SCENARIO))`."""
    src = scenario.source or sys.argv[0]
    return main(["run", src, *(sys.argv[1:] if argv is None else argv)])
