"""The `paintcell` command line: run, check, plan, validate, export, report.

Exit codes: 0 success; 1 a scenario fell short of a threshold (`check`, `run`); 2 a usage or input
error (unknown scenario, missing file, malformed mesh, unreachable plan, bad option). Errors print
one line; `--debug` shows the traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import traceback
from dataclasses import replace
from pathlib import Path
from typing import Any

from planning.errors import PaintcellError

EXIT_OK, EXIT_FAIL, EXIT_USAGE = 0, 1, 2


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"paintcell: error: {message} (see `paintcell --help`)\n")
        raise SystemExit(EXIT_USAGE)


class _Help(argparse.ArgumentDefaultsHelpFormatter):
    """Shows a default only where it tells something (not None, False or an empty list)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default in (None, False, [], argparse.SUPPRESS) or action.required:
            return action.help
        return super()._get_help_string(action)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand (its --help is the reference)."""
    fmt = _Help
    # --debug works before or after the subcommand (SUPPRESS keeps the main parser's value).
    common = _Parser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show the full traceback on errors instead of one line")
    p = _Parser(prog="paintcell", formatter_class=fmt, description=(
        "Plan uniform spray-paint coverage for a car-body part, execute it on a simulated paint "
        "robot in MuJoCo and measure the film-thickness uniformity lost from plan to execution."))
    p.add_argument("--debug", action="store_true",
                   help="show the full traceback on errors instead of one line")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    def add_parser(name: str, **kw: Any) -> argparse.ArgumentParser:
        return sub.add_parser(name, parents=[common], **kw)

    r = add_parser("run", formatter_class=fmt, help="run one scenario end to end",
                       description="Plan → IK → trajectory → MuJoCo execution → validation → "
                       "report for one scenario script; writes plan.json/.npz, "
                       "trajectory.npz/.csv, trace.npz, metrics.json and report.html into --out "
                       "(atomically). Exits 1 when a threshold is not met.")
    r.add_argument("scenario", help="scenario script, e.g. scenarios/door.py")
    r.add_argument("--out", type=Path, default=None,
                   help="results folder (default: results/<scenario name>)")
    r.add_argument("--fast", action="store_true",
                   help="the scenario's coarse mesh resolution (fast_resolution_m, 25 mm unless "
                   "the scenario says otherwise) and fast planner overrides (CI budget)")
    r.add_argument("--mode", choices=("servo", "kinematic"), default="servo",
                   help="servo: PD + inverse-dynamics control at 1 kHz; kinematic: ideal replay")
    r.add_argument("--no-report", action="store_true",
                   help="skip renders, plots and report.html (data files only)")
    r.add_argument("--disturb", action="append", default=[], metavar="KEY=VALUE",
                   help="robustness study: a sim.execute.Disturbances setting on top of the "
                   "scenario's, repeatable: part_offset_m [m], part_rotation_rad [rad], "
                   "tcp_offset_m [m], gain_scale [-], seed [int]; e.g. --disturb "
                   "part_offset_m=0.005 --disturb seed=3")

    c = add_parser("check", formatter_class=fmt,
                       help="run every scenario and hold it to its thresholds (CI)",
                       description="Run every scenario found in PATHs, print one row per scenario "
                       "with each threshold and its measured value; exit 1 if any falls short, 2 "
                       "on usage or input errors.")
    c.add_argument("paths", nargs="*", default=["scenarios"],
                   help="scenario scripts or folders of them")
    c.add_argument("--junit", type=Path, default=None, help="also write JUnit XML to this file")
    c.add_argument("--fast", action="store_true",
                   help="each scenario's coarse mesh resolution (fast_resolution_m, 25 mm unless "
                   "the scenario says otherwise) and fast planner overrides (CI budget)")
    c.add_argument("--out", type=Path, default=None,
                   help="also write each scenario's results under this folder (no report)")

    pl = add_parser("plan", formatter_class=fmt, help="plan only: write plan.json/.npz",
                        description="Run the coverage planner of a scenario and write "
                        "plan.json (+ plan.npz) and scenario.json into --out.")
    pl.add_argument("scenario", help="scenario script, e.g. scenarios/door.py")
    pl.add_argument("--out", type=Path, default=None,
                    help="output folder (default: results/<scenario name>)")
    pl.add_argument("--fast", action="store_true",
                    help="the scenario's coarse mesh resolution (fast_resolution_m) and fast "
                    "planner overrides")

    v = add_parser("validate", formatter_class=fmt,
                       help="recompute metrics.json from a results folder",
                       description="Recompute the plan-vs-executed validation from plan.json, "
                       "trajectory.npz and trace.npz in DIR (written by `paintcell run`) and "
                       "rewrite metrics.json. Exits 1 when a threshold is not met.")
    v.add_argument("dir", type=Path, help="results folder written by `paintcell run`")

    e = add_parser("export", formatter_class=fmt, help="export the robot program",
                       description="Export the validated program of a results folder.")
    e.add_argument("dir", type=Path, help="results folder written by `paintcell run`")
    e.add_argument("--rapid", action="store_true", required=True,
                   help="write an ABB RAPID module (.mod)")
    e.add_argument("--style", choices=("trigg", "paintl"), default="trigg",
                   help="brush events as TriggL + TriggIO on a digital output (trigg), or as "
                   "PaintL + SetBrush (paintl, ABB paint option)")
    e.add_argument("--out", type=Path, default=None,
                   help="module file (default: DIR/<scenario>.mod)")
    e.add_argument("--spacing", type=float, default=0.05,
                   help="maximum distance between exported targets along a pass [m]")

    rep = add_parser("report", formatter_class=fmt, help="rebuild report.html of a folder",
                         description="Rebuild report.html from the files of a results folder.")
    rep.add_argument("dir", type=Path, help="results folder written by `paintcell run`")
    return p


def main(argv: list[str] | None = None) -> int:
    """Console entry point; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(_dispatch(args))
    except KeyboardInterrupt:
        sys.stderr.write("paintcell: interrupted\n")
        return EXIT_USAGE
    except (PaintcellError, FileNotFoundError, ValueError, OSError) as exc:
        if args.debug:
            traceback.print_exc()
        sys.stderr.write(f"paintcell: error: {_one_line(exc)}\n")
        return EXIT_USAGE
    except Exception as exc:  # a bug, not bad input: still one line unless --debug
        if args.debug:
            traceback.print_exc()
        sys.stderr.write(f"paintcell: internal error: {type(exc).__name__}: {_one_line(exc)} "
                         "(rerun with --debug for the traceback)\n")
        return EXIT_USAGE


def _one_line(exc: BaseException) -> str:
    msg = str(exc).strip().splitlines()
    return msg[0] if msg else type(exc).__name__


def _dispatch(args: argparse.Namespace) -> int:
    return {"run": _cmd_run, "check": _cmd_check, "plan": _cmd_plan, "validate": _cmd_validate,
            "export": _cmd_export, "report": _cmd_report}[args.command](args)


def _default_out(name: str) -> Path:
    return Path("results") / name


def _cmd_run(args: argparse.Namespace) -> int:
    from sim.pipeline import run_scenario
    from sim.scenario import load_scenario

    scn = load_scenario(args.scenario)
    if args.disturb:
        scn = replace(scn, disturbances={**scn.disturbances, **_key_values(args.disturb)})
    out = args.out or _default_out(scn.name)
    res = run_scenario(scn, out, fast=args.fast, mode=args.mode, report=not args.no_report)
    print(format_table([_row(scn.name, res.report)]))
    print(f"results: {out}" + ("" if args.no_report else f" (report: {out / 'report.html'})"))
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


def _cmd_check(args: argparse.Namespace) -> int:
    from sim.pipeline import run_scenario
    from sim.scenario import find_scenarios, load_scenario

    scripts = find_scenarios(args.paths)
    rows: list[dict[str, Any]] = []
    cases: list[tuple[str, float, list[dict[str, Any]], str | None]] = []
    for script in scripts:
        t0 = time.perf_counter()
        name = script.stem
        try:
            scn = load_scenario(script)
            name = scn.name
            out = None if args.out is None else args.out / scn.name
            res = run_scenario(scn, out, fast=args.fast, report=False)
        except PaintcellError as exc:
            # A scenario that cannot be loaded, planned or reached is a failed check, not a
            # crash: the other scenarios still run and the JUnit file is still written.
            rows.append({"name": name, "error": _one_line(exc), "passed": False, "checks": []})
            cases.append((name, time.perf_counter() - t0, [], _one_line(exc)))
            continue
        row = _row(scn.name, res.report)
        rows.append(row)
        cases.append((scn.name, time.perf_counter() - t0, row["checks"], None))
    print(format_table(rows))
    if args.junit is not None:
        write_junit(args.junit, cases)
    failed = [r["name"] for r in rows if not r["passed"]]
    print(f"{len(rows) - len(failed)} passed, {len(failed)} failed")
    return EXIT_FAIL if failed else EXIT_OK


def _cmd_plan(args: argparse.Namespace) -> int:
    from planning.atomic_io import atomic_write_text
    from sim.pipeline import load_surface, make_plan, scenario_json
    from sim.scenario import load_scenario

    scn = load_scenario(args.scenario)
    out = args.out or _default_out(scn.name)
    surface = load_surface(scn, args.fast)
    plan = make_plan(scn, surface, args.fast)
    plan.save(out / "plan.json")
    atomic_write_text(out / "scenario.json", scenario_json(scn, args.fast, "none"))
    print(f"{scn.name}: {len(plan.passes)} passes, paint time {plan.paint_time_s:.1f} s, "
          f"start curve: {plan.start_rule}")
    print(f"plan: {out / 'plan.json'}")
    return EXIT_OK


def _load_run_dir(d: Path) -> dict[str, Any]:
    """Plan, trajectory, trace and scenario of a results folder; one clear error per bad file."""
    from planning.plan import CoveragePlan
    from sim.joint_trajectory import JointTrajectory
    from sim.scenario import load_scenario
    from sim.trace import ExecutedTrace

    if not d.is_dir():
        raise PaintcellError(f"results folder {d} does not exist; run `paintcell run` first")

    def read(name: str, loader: Any) -> Any:
        path = d / name
        if not path.exists():
            raise PaintcellError(f"{path} is missing; {d} was not written by `paintcell run` "
                                 "(re-run it)")
        try:
            return loader(path)
        except PaintcellError:
            raise
        except Exception as exc:
            raise PaintcellError(f"cannot read {path} ({type(exc).__name__}: {_one_line(exc)}); "
                                 "re-run `paintcell run`") from exc

    meta = read("scenario.json", lambda p: json.loads(p.read_text()))
    if not isinstance(meta, dict) or "source" not in meta:
        raise PaintcellError(f"{d / 'scenario.json'} names no scenario source; re-run "
                             "`paintcell run`")
    files = {
        "scenario": load_scenario(meta["source"]),
        "run": meta.get("run", {"fast": False, "mode": "servo"}),
        "plan": read("plan.json", CoveragePlan.load),
        "trajectory": read("trajectory.npz", JointTrajectory.load_npz),
        "trace": read("trace.npz", ExecutedTrace.load_npz),
    }
    # The three files must come from one run: the trajectory and trace carry the plan's digest.
    digest = files["plan"].content_digest()
    for name in ("trajectory", "trace"):
        tagged = files[name].meta.get("plan_digest")
        if tagged is not None and tagged != digest:
            raise PaintcellError(f"{d / (name + '.npz')} was made from another plan than "
                                 f"{d / 'plan.json'}; re-run `paintcell run` on {d}")
    return files


def _cmd_validate(args: argparse.Namespace) -> int:
    from planning.atomic_io import atomic_write_text
    from sim.pipeline import RunResult, json_default, load_surface, metrics_dict
    from sim.validate import validate

    f = _load_run_dir(args.dir)
    scn, plan, traj, trace = f["scenario"], f["plan"], f["trajectory"], f["trace"]
    fast, mode = bool(f["run"]["fast"]), str(f["run"]["mode"])
    surface = load_surface(scn, fast)
    rep = validate(plan, surface, traj, trace, scn.part_placement.matrix, scn.thresholds,
                   reachability=traj.meta.get("reachability"))
    old = args.dir / "metrics.json"
    stage_times = json.loads(old.read_text()).get("stage_times_s", {}) if old.exists() else {}
    res = RunResult(scn, args.dir, surface, plan, traj, trace, rep, timings_s=stage_times,
                    fast=fast, mode=mode)
    atomic_write_text(args.dir / "metrics.json",
                      json.dumps(metrics_dict(res), indent=2, default=json_default))
    print(format_table([_row(scn.name, rep)]))
    return EXIT_OK if rep.passed else EXIT_FAIL


def _cmd_export(args: argparse.Namespace) -> int:
    from planning.atomic_io import atomic_write_text
    from sim.export_rapid import rapid_module

    f = _load_run_dir(args.dir)
    scn = f["scenario"]
    from sim.pipeline import load_robot_for

    robot = load_robot_for(scn)
    text = rapid_module(f["trajectory"], robot, module_name=scn.name, style=args.style,
                        max_spacing_m=args.spacing)
    out = args.out or args.dir / f"{scn.name}.mod"
    atomic_write_text(out, text)
    print(f"RAPID module: {out}")
    return EXIT_OK


def _cmd_report(args: argparse.Namespace) -> int:
    if not (args.dir / "metrics.json").exists():
        raise PaintcellError(f"{args.dir / 'metrics.json'} is missing; run `paintcell run` first")
    from sim.report import write_report

    path = write_report(args.dir)
    print(f"report: {path}")
    return EXIT_OK


# --- tables and JUnit ---------------------------------------------------------------------------

def _row(name: str, report: Any) -> dict[str, Any]:
    d = report.to_dict()
    checks = [dict(c) for c in d.get("checks", [])]
    return {"name": name, "passed": bool(report.passed), "checks": checks,
            "planned_nsd_pct": d.get("planned_nsd_pct"),
            "executed_nsd_pct": d.get("executed_nsd_pct"), "loss_pp": d.get("loss_pp"),
            "loss_time_law_pp": d.get("loss_time_law_pp"),
            "loss_servo_pp": d.get("loss_servo_pp"),
            "reachability_pct": d.get("reachability_pct"),
            "cycle_time_s": d.get("executed_cycle_time_s")}


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        # Counts (collisions) and whole percentages print without decimals.
        return f"{v:.0f}" if v.is_integer() and abs(v) < 1e9 else f"{v:.2f}"
    return str(v)


def _pp(v: Any) -> str:
    """A loss in percentage points: three decimals (servo losses are thousandths of a point)."""
    return "-" if v is None else f"{float(v):.3f}"


def format_table(rows: list[dict[str, Any]]) -> str:
    """A plain-text table: one row per scenario, each threshold as `value ≤ limit`."""
    lines = []
    head = (f"{'scenario':<10} {'planned σ/μ %':>13} {'executed σ/μ %':>14} {'loss pp':>8} "
            f"{'(time law':>9} {'+ servo)':>8} {'reach %':>8} {'cycle s':>8}  result  checks")
    lines.append(head)
    lines.append("-" * len(head))
    for r in rows:
        if r.get("error"):
            lines.append(f"{r['name']:<10} {'':>13} {'':>14} {'':>8} {'':>9} {'':>8} {'':>8} "
                         f"{'':>8}  ERROR   {r['error']}")
            continue
        checks = "; ".join(
            f"{c['name']} {_fmt(c['value'])} {'≤' if c.get('kind', 'max') == 'max' else '≥'} "
            f"{_fmt(c['limit'])}{'' if c['passed'] else ' ✗'}" for c in r["checks"])
        lines.append(
            f"{r['name']:<10} {_fmt(r['planned_nsd_pct']):>13} {_fmt(r['executed_nsd_pct']):>14} "
            f"{_pp(r['loss_pp']):>8} {_pp(r.get('loss_time_law_pp')):>9} "
            f"{_pp(r.get('loss_servo_pp')):>8} {_fmt(r['reachability_pct']):>8} "
            f"{_fmt(r['cycle_time_s']):>8}  {'PASS' if r['passed'] else 'FAIL':<6}  {checks}")
    return "\n".join(lines)


def write_junit(path: Path, cases: list[tuple[str, float, list[dict[str, Any]], str | None]]) \
        -> None:
    """JUnit XML with one test case per scenario; failures list the failing thresholds."""
    import xml.etree.ElementTree as ET

    from planning.atomic_io import atomic_write_text

    n_fail = sum(1 for _, _, checks, err in cases
                 if err is None and not all(c["passed"] for c in checks))
    n_err = sum(1 for c in cases if c[3] is not None)
    suite = ET.Element("testsuite", name="paintcell-check", tests=str(len(cases)),
                       failures=str(n_fail), errors=str(n_err),
                       time=f"{sum(c[1] for c in cases):.3f}")
    for name, dt, checks, err in cases:
        case = ET.SubElement(suite, "testcase", classname="paintcell.scenarios", name=name,
                             time=f"{dt:.3f}")
        if err is not None:
            ET.SubElement(case, "error", message=err).text = err
            continue
        bad = [c for c in checks if not c["passed"]]
        if bad:
            msg = "; ".join(f"{c['name']}={_fmt(c['value'])} (limit {_fmt(c['limit'])})"
                            for c in bad)
            ET.SubElement(case, "failure", message=msg).text = msg
        ET.SubElement(case, "system-out").text = "\n".join(
            f"{c['name']}: {_fmt(c['value'])} (limit {_fmt(c['limit'])} {c.get('unit', '')})"
            for c in checks)
    atomic_write_text(path, ET.tostring(suite, encoding="unicode", xml_declaration=True))


if __name__ == "__main__":
    raise SystemExit(main())
