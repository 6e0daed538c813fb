"""The `paintcell validate`, `export` and `report` sub-commands: read a results folder, write
into it in place."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from paintcell.cli.check import format_table, row
from paintcell.cli.common import (
    DIR_HELP,
    EXIT_FAIL,
    EXIT_OK,
    add_out_force,
    number_option,
    one_line,
)
from paintcell.core.errors import PaintcellError


def add_validate(add_parser: Any) -> None:
    v = add_parser("validate", help="recompute metrics.json from a results folder", description=(
        "Recompute the plan-vs-executed validation from plan.json, trajectory.npz and trace.npz "
        "in DIR with the scenario snapshot of scenario.json (never the scenario file) and "
        "rewrite metrics.json. Exits 1 when a threshold is not met."))
    v.add_argument("dir", type=Path, help=DIR_HELP)
    v.set_defaults(func=_cmd_validate)


def _revalidate(f: dict[str, Any]) -> tuple[Any, Any]:
    """(surface, `ValidationReport`) of a loaded results folder (`load_run_dir`), recomputed from
    its plan, trajectory and trace with the thresholds of its scenario.json."""
    from paintcell.app.pipeline import load_surface
    from paintcell.validation.validate import validate

    scn, plan, traj, trace = f["scenario"], f["plan"], f["trajectory"], f["trace"]
    surface = load_surface(scn, bool(f["run"]["fast"]))
    return surface, validate(plan, surface, traj, trace, scn.part_placement.matrix,
                             scn.thresholds, reachability=traj.meta.get("reachability"))


def _cmd_validate(args: argparse.Namespace) -> int:
    from paintcell.app.pipeline import RunResult, metrics_dict, write_film_files
    from paintcell.app.run_files import load_run_dir, read_json
    from paintcell.core.atomic_io import atomic_write_text
    from paintcell.core.json_values import json_default
    from paintcell.core.results_dir import lock_results, note_files, require_results

    require_results(args.dir)
    with lock_results(args.dir, "validate"):
        f = load_run_dir(args.dir)
        scn, plan, traj, trace = f["scenario"], f["plan"], f["trajectory"], f["trace"]
        fast, mode = bool(f["run"]["fast"]), str(f["run"]["mode"])
        surface, rep = _revalidate(f)
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
        note_files(args.dir, ["metrics.json",
                              *write_film_files(args.dir, scn, surface, plan, rep)])
    print(format_table([row(scn.name, rep)]))
    return EXIT_OK if rep.passed else EXIT_FAIL


def add_export(add_parser: Any) -> None:
    e = add_parser("export", help="export the robot program", description=(
        "Export the validated program of a results folder, from its files and scenario "
        "snapshot. The verdict is re-derived first: the validation is recomputed from plan.json, "
        "trajectory.npz and trace.npz with the thresholds of scenario.json and compared with "
        "metrics.json. A run that does not pass, or whose metrics.json disagrees with its data, "
        "is refused unless --allow-failed, which writes a module whose header says it is NOT "
        "VALIDATED and why."))
    e.add_argument("dir", type=Path, help=DIR_HELP)
    e.add_argument("--rapid", action="store_true", required=True,
                   help="write an ABB RAPID module (.mod)")
    e.add_argument("--style", choices=("trigg", "paintl"), default="trigg",
                   help="brush events as TriggL + TriggIO on a digital output (trigg), or as "
                   "PaintL + SetBrush (paintl, ABB paint option)")
    add_out_force(e, "module file (default: DIR/<scenario>.mod, which is replaced: the "
                  "folder's own)", required=False)
    e.add_argument("--spacing", default=0.05,
                   type=number_option("--spacing", float, low=0.0, low_open=True, high=10.0,
                                      unit="m", example="0.05"),
                   help="maximum distance between exported targets along a pass [m]")
    e.add_argument("--allow-failed", action="store_true",
                   help="export a run that failed validation anyway, marked FAILED in the header")
    e.set_defaults(func=_cmd_export)


def _cmd_export(args: argparse.Namespace) -> int:
    from paintcell.app.pipeline import load_robot_for
    from paintcell.app.run_files import load_run_dir, read_json
    from paintcell.core.atomic_io import atomic_write_text
    from paintcell.core.results_dir import (
        MARKER,
        lock_results,
        marker_files,
        note_files,
        require_results,
    )
    from paintcell.core.safe_paths import check_new_target, check_write_target
    from paintcell.output.export_rapid import (
        rapid_ident,
        rapid_module,
        recorded_mismatches,
        validation_header,
    )

    marker = require_results(args.dir)
    with lock_results(args.dir, "export"):
        metrics = read_json(args.dir / "metrics.json")
        f = load_run_dir(args.dir)
        scn = f["scenario"]
        out = args.out or args.dir / f"{rapid_ident(scn.name)}.mod"
        inside = out.parent.resolve() == args.dir.resolve()
        if inside and (out.name == MARKER or (out.name in marker_files(marker)
                                              and not out.name.endswith(".mod"))):
            raise PaintcellError(f"--out {out} is a file of the results folder {args.dir}; "
                                 "write the module to a .mod file")
        if inside and out.name in marker_files(marker):
            check_write_target(out, "--out")  # the folder's own module: replaced
        else:
            check_new_target(out, "--out", args.force)
        _, rep = _revalidate(f)
        checks = list(rep.checks)
        mismatches = recorded_mismatches(metrics, checks, rep.passed)
        header = validation_header(checks, f["plan"].content_digest(), mismatches)
        if not header[0].startswith("VALIDATED"):
            if not args.allow_failed:
                raise PaintcellError(f"{args.dir} did not pass validation ({header[1][8:-1]}); "
                                     "no program exported — fix the scenario and re-run (or "
                                     "`paintcell validate` a stale metrics.json), or pass "
                                     "--allow-failed for a module marked NOT VALIDATED")
            sys.stderr.write(f"paintcell: warning: exporting a FAILED run ({one_line(header[1])})"
                             "\n")
        text = rapid_module(f["trajectory"], load_robot_for(scn), module_name=scn.name,
                            style=args.style, max_spacing_m=args.spacing, validation=header)
        atomic_write_text(out, text)
        if inside:
            note_files(args.dir, [out.name])
    print(f"RAPID module: {out}")
    return EXIT_OK


def add_report(add_parser: Any) -> None:
    rep = add_parser("report", help="rebuild report.html of a folder",
                     description="Rebuild report.html from the files of a results folder: verdict, "
                     "film map, histogram vs the spec window, per-pass table; then the detail.")
    rep.add_argument("dir", type=Path, help=DIR_HELP)
    rep.add_argument("--video", action="store_true",
                     help="embed the folder's execution video execution.gif (made by "
                     "`paintcell run --video`; adds a few MB)")
    rep.set_defaults(func=_cmd_report)


def _cmd_report(args: argparse.Namespace) -> int:
    from paintcell.app.run_files import check_folder_files
    from paintcell.core.results_dir import lock_results, note_files, require_results
    from paintcell.output.report import write_report

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
