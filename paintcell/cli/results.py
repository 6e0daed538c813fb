"""The `paintcell validate`, `export` and `report` sub-commands: read a results folder, write
into it in place."""

from __future__ import annotations

import argparse
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


def _cmd_validate(args: argparse.Namespace) -> int:
    from paintcell.app.run_files import revalidate_run_dir
    from paintcell.core.results_dir import lock_results, note_files, require_results

    require_results(args.dir)
    with lock_results(args.dir, "validate"):
        name, rep, written = revalidate_run_dir(args.dir)
        note_files(args.dir, written)
    print(format_table([row(name, rep)]))
    return EXIT_OK if rep.passed else EXIT_FAIL


def add_export(add_parser: Any) -> None:
    e = add_parser("export", help="export the robot program", description=(
        "Export the validated program of a results folder, from its files and scenario "
        "snapshot (a booth: one module per robot, synchronised with WaitSyncTask). The verdict "
        "is re-derived first: the validation is recomputed from the folder's plans, programs "
        "and traces with the thresholds of scenario.json and compared with metrics.json. A run "
        "that does not pass, or whose metrics.json disagrees with its data, is refused unless "
        "--allow-failed, which writes a module whose header says it is NOT VALIDATED and why."))
    e.add_argument("dir", type=Path, help=DIR_HELP)
    e.add_argument("--rapid", action="store_true", required=True,
                   help="write an ABB RAPID module (.mod)")
    e.add_argument("--style", choices=("trigg", "paintl"), default="trigg",
                   help="brush events as TriggL + TriggIO on a digital output (trigg), or as "
                   "PaintL + SetBrush (paintl, ABB paint option)")
    add_out_force(e, "module file (default: DIR/<scenario>.mod, which is replaced: the "
                  "folder's own); a booth's modules, one per robot, go into this folder "
                  "(default: DIR) as <task>.mod", required=False)
    e.add_argument("--spacing", default=0.05,
                   type=number_option("--spacing", float, low=0.0, low_open=True, high=10.0,
                                      unit="m", example="0.05"),
                   help="maximum distance between exported targets along a pass [m]")
    e.add_argument("--allow-failed", action="store_true",
                   help="export a run that failed validation anyway, marked FAILED in the header")
    e.set_defaults(func=_cmd_export)


def _cmd_export(args: argparse.Namespace) -> int:
    from paintcell.app.run_files import (
        load_run_dir,
        plans_digest,
        program_modules,
        read_json,
        rederive,
    )
    from paintcell.core.atomic_io import atomic_write_text
    from paintcell.core.results_dir import (
        MARKER,
        lock_results,
        marker_files,
        note_files,
        require_results,
    )
    from paintcell.core.safe_paths import check_new_target, check_write_target
    from paintcell.output.export_rapid import task_names
    from paintcell.output.rapid_text import rapid_ident, recorded_mismatches, validation_header

    marker = require_results(args.dir)
    with lock_results(args.dir, "export"):
        metrics = read_json(args.dir / "metrics.json")
        f = load_run_dir(args.dir)
        names = [rapid_ident(f["scenario"].name)] if f["kind"] != "booth" else \
            task_names([r.name for r in f["scenario"].robots])
        # one module: --out names its file; several (a booth's robots): the folder they go in
        if len(names) == 1:
            outs = {names[0]: args.out or args.dir / f"{names[0]}.mod"}
        else:
            folder = args.out or args.dir
            if folder.suffix == ".mod" or (folder.exists() and not folder.is_dir()):
                raise PaintcellError(f"--out {folder}: this run has {len(names)} robot programs; "
                                     "give a folder for their modules")
            outs = {n: folder / f"{n}.mod" for n in names}
        for out in outs.values():
            inside = out.parent.resolve() == args.dir.resolve()
            if inside and (out.name == MARKER or (out.name in marker_files(marker)
                                                  and not out.name.endswith(".mod"))):
                raise PaintcellError(f"--out {out} is a file of the results folder {args.dir}; "
                                     "write the module to a .mod file")
            if inside and out.name in marker_files(marker):
                check_write_target(out, "--out")  # the folder's own module: replaced
            else:
                check_new_target(out, "--out", args.force)
        rep, _ = rederive(f, metrics)
        checks = list(rep.checks)
        mismatches = recorded_mismatches(metrics, checks, rep.passed)
        header = validation_header(checks, plans_digest(f), mismatches)
        if not header[0].startswith("VALIDATED"):
            if not args.allow_failed:
                raise PaintcellError(f"{args.dir} did not pass validation ({header[1][8:-1]}); "
                                     "no program exported — fix the scenario and re-run (or "
                                     "`paintcell validate` a stale metrics.json), or pass "
                                     "--allow-failed for a module marked NOT VALIDATED")
            why = (header[1].strip().splitlines() or ["?"])[0]
            sys.stderr.write(f"paintcell: warning: exporting a FAILED run ({why})\n")
        modules = program_modules(f, metrics, header, args.style, args.spacing)
        for out, text in zip(outs.values(), modules.values(), strict=True):
            out.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(out, text)
        inside_names = [o.name for o in outs.values()
                        if o.parent.resolve() == args.dir.resolve()]
        if inside_names:
            note_files(args.dir, inside_names)
    for out in outs.values():
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
