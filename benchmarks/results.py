"""Write docs/results.md (and docs/results.json) from runs: the figures of every shipped scenario
at `paintcell check --fast` and the paper's Tables 1 and 2, stamped with the commands and the date
they ran. The file is generated; edit this script, not the page.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/results.py --jobs 2          # everything
    PYTHONPATH=$PWD .venv/bin/python benchmarks/results.py scenarios/panel.toml --no-paper
    PYTHONPATH=$PWD .venv/bin/python benchmarks/results.py --keep DIR         # keep the runs
    PYTHONPATH=$PWD .venv/bin/python benchmarks/results.py --from DIR         # no new runs

Scenarios run through `paintcell check SCENARIOS --fast --out DIR` (each in its own process, as
CI runs them) and every figure is read back from the scenario's own `DIR/NAME/metrics.json`;
`--from DIR` reads an existing such folder instead. A scenario whose part comes from a mesh or
CAD file (its `scenario.json` names one) is a real part; the others are library parts. The paper
tables come from `benchmarks/paper_tables.py --json` (`--no-paper` leaves them out).

Columns: planned and executed σ/μ of the judged film [%] (a booth: over the whole body); loss =
executed − planned [pp], split into the time law's and the servo's share; judged area whose
executed film lies inside the paint spec's window (`[spec]`, ±20 % of the target by default)
[%]; executed cycle time [s]; honest
reachability [%] (`paintcell.validation.honest_reach`; a booth: its least robot's); poses reached
through a joint jump / a configuration flip; collision events; PASS when every threshold of the
scenario is met.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
MESH_SUFFIXES = (".ply", ".stl", ".obj", ".step", ".stp", ".iges", ".igs")

#: (header, metrics.json key, format) of the scenario tables.
COLUMNS = (("planned σ/μ %", "planned_nsd_pct", "{:.2f}"),
           ("executed σ/μ %", "executed_nsd_pct", "{:.2f}"),
           ("loss pp", "loss_pp", "{:+.3f}"),
           ("time law pp", "loss_time_law_pp", "{:+.3f}"),
           ("servo pp", "loss_servo_pp", "{:+.3f}"),
           ("in spec window %", "executed_inside_spec_pct", "{:.1f}"),
           ("cycle s", "executed_cycle_time_s", "{:.2f}"),
           ("honest reach %", "reachability_pct", "{:.2f}"),
           ("jumps", "reach_n_joint_jumps", "{:.0f}"),
           ("flips", "reach_n_config_flips", "{:.0f}"),
           ("collisions", "n_collisions", "{:.0f}"))

#: The booth table: several robots on one body.
BOOTH_COLUMNS = (("whole body σ/μ %", "executed_nsd_pct", "{:.2f}"),
                 ("worst part σ/μ %", "max_part_executed_nsd_pct", "{:.2f}"),
                 ("overlap bands σ/μ %", "overlap_executed_nsd_pct", "{:.2f}"),
                 ("conveyor pp", "loss_conveyor_pp", "{:+.3f}"),
                 ("booth cycle s", "executed_cycle_time_s", "{:.2f}"),
                 ("one robot s", "one_robot_cycle_s", "{:.2f}"),
                 ("closest bells m", "min_bell_distance_m", "{:.2f}"))

TABLE1 = (("paper constant %", "paper_constant_pct", "{:.2f}"),
          ("paper optimized %", "paper_optimized_pct", "{:.2f}"),
          ("whole constant %", "whole_constant_pct", "{:.2f}"),
          ("whole optimized %", "whole_optimized_pct", "{:.2f}"),
          ("interior constant %", "interior_constant_pct", "{:.2f}"),
          ("interior optimized %", "interior_optimized_pct", "{:.2f}"))
TABLE2 = (("paper %", "paper_pct", "{:.2f}"),
          ("whole constant %", "whole_constant_pct", "{:.2f}"),
          ("whole Algorithm 1 %", "whole_optimized_pct", "{:.2f}"),
          ("interior constant %", "interior_constant_pct", "{:.2f}"),
          ("interior Algorithm 1 %", "interior_optimized_pct", "{:.2f}"),
          ("passes", "passes", "{:.0f}"),
          ("min / mean", "min_over_mean", "{:.2f}"))

#: Keys kept in docs/results.json per scenario (the tables' and the verdict).
KEPT = tuple(dict.fromkeys([k for _, k, _ in COLUMNS + BOOTH_COLUMNS] + ["passed"]))


def run_check(scenarios: list[str], out: Path, jobs: int) -> list[str]:
    """`paintcell check SCENARIOS --fast --out OUT`; the command as run (for the stamp)."""
    cmd = [sys.executable, "-m", "paintcell", "check", *scenarios, "--fast", "--jobs", str(jobs),
           "--out", str(out)]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT),
                                                                     os.environ.get("PYTHONPATH")])))
    proc = subprocess.run(cmd, env=env, text=True, capture_output=True)   # paths as the user's
    print(proc.stdout, end="", flush=True)
    if proc.returncode not in (0, 1):   # 1: a scenario failed its thresholds (its row says so)
        last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        raise SystemExit(f"paintcell check exited {proc.returncode}: {last}")
    return ["paintcell", "check", *scenarios, "--fast", "--jobs", str(jobs), "--out", "DIR"]


def run_paper(resolution_m: float, out: Path) -> tuple[dict[str, Any], list[str]]:
    """`benchmarks/paper_tables.py --json`; its rows and the command as run."""
    rows_file = out / "paper_rows.json"
    args = ["--resolution", f"{resolution_m:g}", "--json", str(rows_file), "--fig5",
            str(out / "fig5.png")]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT),
                                                                     os.environ.get("PYTHONPATH")])))
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "paper_tables.py"), *args],
                          cwd=ROOT, env=env, text=True, capture_output=True)
    if proc.returncode != 0 or not rows_file.exists():
        last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        raise SystemExit(f"benchmarks/paper_tables.py exited {proc.returncode}: {last}")
    return (json.loads(rows_file.read_text()),
            ["python", "benchmarks/paper_tables.py", "--resolution", f"{resolution_m:g}"])


def read_runs(folder: Path) -> dict[str, dict[str, Any]]:
    """Per scenario name (sorted): its group ("library", "real" or "booth" + the part kind), the
    table keys of its metrics.json and its verdict."""
    runs = {}
    for mfile in sorted(folder.glob("*/metrics.json")):
        m = json.loads(mfile.read_text())
        snap = (mfile.parent / "scenario.json").read_text() \
            if (mfile.parent / "scenario.json").exists() else ""
        real = any(f'{s}"' in snap.lower() for s in MESH_SUFFIXES)
        booth = isinstance(m.get("robots"), dict)
        runs[mfile.parent.name] = {
            "part": "real" if real else "library", "booth": booth,
            "metrics": {k: m.get(k) for k in KEPT if k in m}}
    return runs


def _cell(value: Any, fmt: str) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "PASS" if value else "FAIL"
    return fmt.format(float(value))


def table(rows: list[tuple[str, dict[str, Any]]], cols: tuple, first: str,
          verdict: bool = False) -> list[str]:
    """A markdown table: one row per (name, values)."""
    head = [first, *[c[0] for c in cols]] + (["thresholds"] if verdict else [])
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, vals in rows:
        cells = [_cell(vals.get(key), fmt) for _, key, fmt in cols]
        if verdict:
            cells.append(_cell(bool(vals.get("passed")), ""))
        out.append("| " + " | ".join([name, *cells]) + " |")
    return out


def markdown(runs: dict[str, dict[str, Any]], paper: dict[str, Any] | None,
             stamp: dict[str, Any], generality: list[str] | None = None) -> str:
    """docs/results.md from the runs, the paper rows and the tables of
    `benchmarks/generality.py --markdown` (shown as they were written)."""
    lines = ["# Results", "",
             "Figures from runs, written by `benchmarks/results.py` (do not edit by hand; run the "
             "command below to bring them up to date). `docs/results.json` holds the same figures "
             "as data.", "",
             f"- Ran on {stamp['date']} ({stamp['machine']}): `{stamp['command']}`"]
    if stamp.get("check"):
        lines.append(f"- Scenarios: `{stamp['check']}` — each scenario's coarse mesh "
                     "(`fast_resolution_m`), servo execution; every figure read from its "
                     "`metrics.json`.")
    if stamp.get("paper"):
        lines.append(f"- Paper tables: `{stamp['paper']}`.")
    if stamp.get("missing"):
        lines.append("- **Not in the tables** (the check wrote no results for them; its output "
                     "says why): " + ", ".join(f"`{n}`" for n in stamp["missing"]) + ".")
    lines += ["", "Columns: planned and executed σ/μ of the judged film; the loss (executed − "
              "planned) and its time-law and servo shares; the judged area whose executed film "
              "lies inside the paint spec's window (the scenario's `[spec]`, ±20 % of the "
              "target film by default); the executed cycle time; honest "
              "reachability (a pose counts only if IK reached it, no joint jump or "
              "configuration flip led into it, nothing touched and the time law kept ≥ 90 % of "
              "the planned speed over the path nearest it, as the film sees it: ÷ the flow the "
              "brush table commands); poses reached through a jump or a flip; collision events; "
              "PASS when the scenario meets every one of its thresholds.", ""]
    groups = (("Library parts", "library", "The parts of `paintcell.surface.parts`, built "
               "from their closed-form or B-spline definitions."),
              ("Real parts", "real", "Parts read from mesh files: public scans and meshes "
               "(`../shared/meshes/`) and generated CAD-like parts (`scenarios/parts/`)."))
    for title, key, text in groups:
        rows = [(f"`{n}`", r["metrics"]) for n, r in runs.items() if r["part"] == key]
        if rows:
            lines += [f"## {title}", "", text, "", *table(rows, COLUMNS, "scenario", True), ""]
    booths = [(f"`{n}`", r["metrics"]) for n, r in runs.items() if r["booth"]]
    if booths:
        lines += ["## Booths", "", "Scenarios with several robots (their rows above are over the "
                  "whole body): the worst part, the bands where two robots' films meet, the "
                  "conveyor's share of the loss, the booth cycle against one robot running every "
                  "program back to back, and the closest two bells came.", "",
                  *table(booths, BOOTH_COLUMNS, "scenario"), ""]
    if paper:
        lines += ["## The paper's tables", "",
                  f"Atkar et al. (2004), simulated Tables 1 and 2, beside this planner on the "
                  f"library parts at {paper['resolution_m'] * 1000:.0f} mm with the "
                  f"`{paper['bell']}` bell: σ/μ over the whole part and over its interior "
                  f"(farther than {paper['band_m'] * 1000:.0f} mm from the boundary). The "
                  "paper's bell and surfaces are not these, so its figures are anchors; the "
                  "planar sheet must reach the paper's 2.64 %.", "",
                  "### Table 1: speed optimization", "",
                  *table([(r["case"], r) for r in paper["table1"]], TABLE1, "case"), "",
                  "### Table 2: index optimization (u_max = 4 %, 300 mm overspray)", "",
                  *table([(r["case"], r) for r in paper["table2"]], TABLE2, "case"), "",
                  f"Fig. 5: the planar sweet spot is {paper['fig5_sweet_spot_mm']:.0f} mm at "
                  f"σ/μ {paper['fig5_sweet_spot_nsd_pct']:.2f} %; the planner's planar index "
                  f"width is {paper['planar_index_width_mm']:.0f} mm.", ""]
    if generality:
        lines += ["## Any part a paint shop sends", "",
                  "Seeded part families of `paintcell generate` and the shared meshes, each "
                  "through `paintcell init` and `paintcell run --fast` with nothing edited "
                  "(`benchmarks/generality.py`): the verdict against the default paint spec, "
                  "the executed σ/μ, the judged area inside the spec window, honest "
                  "reachability, joint jumps, collisions, the sharpest turn of a pass between "
                  "two samples and the wall time of init + run on this machine.", ""]
        for text in generality:
            lines += [text.strip(), ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenarios", nargs="*", default=["scenarios/"],
                    help="scenario files or folders for `paintcell check` (default scenarios/)")
    ap.add_argument("--from", dest="from_dir", type=Path, default=None,
                    help="read the metrics of an existing `paintcell check --out` folder")
    ap.add_argument("--keep", type=Path, default=None,
                    help="run the check into this folder and keep it (for a later --from)")
    ap.add_argument("--jobs", type=int, default=1, help="scenarios run at once (check --jobs)")
    ap.add_argument("--no-paper", action="store_true", help="leave out the paper tables")
    ap.add_argument("--paper-json", type=Path, default=None,
                    help="read the paper rows of an earlier `paper_tables.py --json FILE` run")
    ap.add_argument("--paper-resolution", type=float, default=0.01,
                    help="mesh resolution of the paper tables' parts [m]")
    ap.add_argument("--generality", type=Path, nargs="+", default=[],
                    help="tables written by `benchmarks/generality.py --markdown FILE`, shown "
                         "under their own heading as written")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results.md",
                    help="markdown file to write; its .json sibling gets the figures as data")
    args = ap.parse_args(argv)
    from paintcell.core.atomic_io import atomic_write_text

    argv_txt = " ".join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    stamp: dict[str, Any] = {
        "date": dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{platform.system()} {platform.machine()}, {os.cpu_count()} CPUs, Python "
                   f"{platform.python_version()}",
        "command": f"python benchmarks/results.py {argv_txt}".strip()}
    with tempfile.TemporaryDirectory(prefix="paintcell-results-") as td:
        folder = args.from_dir
        expected: list[str] = []
        if folder is None:
            from paintcell.app.scenario_files import find_scenarios

            expected = [p.stem for p in find_scenarios(args.scenarios)]
            folder = args.keep if args.keep is not None else Path(td) / "runs"
            stamp["check"] = " ".join(run_check(args.scenarios, folder, args.jobs))
        else:
            stamp["check"] = f"paintcell check --fast --out {folder} (read, not run again)"
        runs = read_runs(folder)
        stamp["missing"] = [n for n in expected if n not in runs]
        if not runs:
            raise SystemExit(f"no DIR/NAME/metrics.json under {folder}: pass the --out folder of "
                             "`paintcell check --fast --out DIR`")
        paper = None
        if args.paper_json is not None:
            paper = json.loads(args.paper_json.read_text())
            stamp["paper"] = f"python benchmarks/paper_tables.py --json {args.paper_json} (read)"
        elif not args.no_paper:
            paper, cmd = run_paper(args.paper_resolution, Path(td))
            stamp["paper"] = " ".join(cmd)
    generality = [p.read_text() for p in args.generality]
    atomic_write_text(args.out, markdown(runs, paper, stamp, generality))
    atomic_write_text(args.out.with_suffix(".json"),
                      json.dumps({"stamp": stamp, "scenarios": runs, "paper": paper,
                                  "generality": generality}, indent=1,
                                 ensure_ascii=False) + "\n")
    print(f"written: {args.out} and {args.out.with_suffix('.json').name} ({len(runs)} scenarios"
          f"{', paper tables' if paper else ''})")
    if stamp["missing"]:
        print(f"not in the tables (no results): {', '.join(stamp['missing'])}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
