"""How general paintcell is: seeded part families and the shared meshes through `paintcell init`
and `paintcell run --fast`, nothing edited, one row each.

Each generated part is written by `paintcell generate FAMILY --seed N` (its truth beside it) in
the file format the seed picks (STL, OBJ, PLY); every part, generated or shared, then goes
through `python -m paintcell init FILE --out CELL.toml` and `python -m paintcell run CELL.toml
--fast`, each in its own process, as a user runs them. A row: the verdict (PASS, FAIL, REFUSED
by init with its reason, ERROR), executed σ/μ [%], the share of the judged area inside the spec
window [%], honest reachability [%], joint jumps, collisions, the worst turn of a pass between
consecutive plan samples [°] (re-measured from plan.npz), and init + run wall seconds.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/generality.py                  # 8 families × 5
    PYTHONPATH=$PWD .venv/bin/python benchmarks/generality.py --seeds 1 --no-shared
    PYTHONPATH=$PWD .venv/bin/python benchmarks/generality.py --no-shared --seeds 4 \\
        --only fender_arch_3 bumper_1
    PYTHONPATH=$PWD .venv/bin/python benchmarks/generality.py --families door_frame bumper \\
        --keep /tmp/generality --markdown /tmp/generality.md

The totals: the share of generated parts that PASS, the parts whose cell was written with 0 joint
jumps and 0 collisions, refusals that say no single robot reaches the part (counted apart), and
the median init + run seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT.parent / "shared" / "meshes"
sys.path.insert(0, str(ROOT))

from paintcell.surface.part_families import FAMILIES  # noqa: E402

_FORMATS = ("stl", "obj", "ply")
#: metrics.json keys of the share of the judged area inside the spec window [%], newest first.
_WINDOW_KEYS = ("executed_inside_spec_pct", "executed_within_tolerance_pct")


@dataclass
class Row:
    """One part's result."""

    name: str
    generated: bool
    verdict: str = "ERROR"
    why: str = ""
    nsd_pct: float = float("nan")
    in_window_pct: float = float("nan")
    reach_pct: float = float("nan")
    jumps: int = -1
    collisions: int = -1
    worst_turn_deg: float = float("nan")
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)


def _paintcell(args: list[str], timeout_s: float) -> tuple[subprocess.CompletedProcess, float]:
    t0 = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-m", "paintcell", *args], capture_output=True,
                              text=True, cwd=ROOT, timeout=timeout_s,
                              env={**os.environ, "PYTHONPATH": str(ROOT)})
    except subprocess.TimeoutExpired:
        proc = subprocess.CompletedProcess(args, 124, "", f"over the {timeout_s:g} s limit")
    return proc, time.perf_counter() - t0


def worst_turn_deg(plan_npz: Path) -> float:
    """The largest angle [°] between consecutive segments of any pass's TCP path."""
    worst = 0.0
    with np.load(plan_npz) as z:
        for key in (k for k in z.files if k.endswith("_positions")):
            p = z[key]
            d = np.diff(p, axis=0)
            n = np.linalg.norm(d, axis=1)
            d = d[n > 1e-9] / n[n > 1e-9, None]
            if len(d) > 1:
                c = np.clip((d[1:] * d[:-1]).sum(1), -1.0, 1.0)
                worst = max(worst, float(np.degrees(np.arccos(c)).max()))
    return worst


def _last_line(text: str) -> str:
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    return lines[-1] if lines else "?"


def run_part(name: str, mesh: Path, work: Path, generated: bool, timeout_s: float) -> Row:
    """init + run --fast of one part file; its row."""
    row = Row(name, generated)
    cell = work / "cells" / f"{name}.toml"
    out = work / "runs" / name
    cell.parent.mkdir(parents=True, exist_ok=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    proc, t_init = _paintcell(["init", str(mesh), "--out", str(cell)], timeout_s)
    row.seconds = t_init
    if proc.returncode != 0:
        row.verdict = "REFUSED" if proc.returncode == 2 else "ERROR"
        row.why = _last_line(proc.stderr)
        return row
    proc, t_run = _paintcell(["run", str(cell), "--fast", "--out", str(out)], timeout_s)
    row.seconds += t_run
    metrics = out / "metrics.json"
    if proc.returncode not in (0, 1) or not metrics.exists():
        row.why = _last_line(proc.stderr)
        return row
    m = json.loads(metrics.read_text())
    row.verdict = "PASS" if m.get("passed") else "FAIL"
    if not m.get("passed"):
        row.why = "; ".join(f"{c['name']} {c.get('value')} vs {c.get('limit')}"
                            for c in m.get("checks", []) if not c.get("passed", True))
    row.nsd_pct = float(m.get("executed_nsd_pct") or np.nan)
    row.in_window_pct = next((float(m[k]) for k in _WINDOW_KEYS if m.get(k) is not None),
                             float("nan"))
    honest = m.get("reachability_pct")          # honest: jumps, flips, contacts, slowdowns
    row.reach_pct = float(honest) if honest is not None else float("nan")
    row.jumps = int(m.get("reach_n_joint_jumps") or 0)
    row.collisions = int(m.get("n_collisions") or 0)
    plans = sorted(out.glob("plan*.npz"))      # a cell of several robots: plan_<part>.npz
    if plans:
        row.worst_turn_deg = max(worst_turn_deg(p) for p in plans)
    return row


def _fmt(x: float, spec: str) -> str:
    return "—" if x != x else format(x, spec)


def table(rows: list[Row]) -> list[str]:
    """Markdown table lines, one row a part."""
    head = ("| part | verdict | σ/μ % | in window % | honest reach % | jumps | collisions | "
            "worst turn ° | init + run s | why |")
    lines = [head, "|" + "---|" * 10]
    for r in rows:
        lines.append(f"| {r.name} | {r.verdict} | {_fmt(r.nsd_pct, '.2f')} | "
                     f"{_fmt(r.in_window_pct, '.1f')} | {_fmt(r.reach_pct, '.1f')} | "
                     f"{r.jumps if r.jumps >= 0 else '—'} | "
                     f"{r.collisions if r.collisions >= 0 else '—'} | "
                     f"{_fmt(r.worst_turn_deg, '.1f')} | {r.seconds:.1f} | "
                     f"{r.why.replace('|', '/')[:140]} |")
    return lines


def totals(rows: list[Row]) -> list[str]:
    """The summary figures, each with its label and unit."""
    gen = [r for r in rows if r.generated]
    lone = [r for r in rows if r.verdict == "REFUSED" and "robot" in r.why.lower()
            and ("no " in r.why.lower() or "reach" in r.why.lower())]
    written = [r for r in rows if r.verdict in ("PASS", "FAIL")]
    clean = [r for r in written if r.jumps == 0 and r.collisions == 0]
    secs = [r.seconds for r in rows]
    out = []
    if gen:
        n_pass = sum(r.verdict == "PASS" for r in gen)
        out.append(f"generated parts passing the spec: {n_pass} of {len(gen)} "
                   f"({100.0 * n_pass / len(gen):.1f} %)")
    out.append(f"cells written with 0 joint jumps and 0 collisions: {len(clean)} of "
               f"{len(written)}")
    out.append(f"refused as beyond a single robot's reach: {len(lone)} of {len(rows)}")
    out.append(f"errors (crash or time-out): {sum(r.verdict == 'ERROR' for r in rows)}")
    if secs:
        out.append(f"median init + run wall time: {statistics.median(secs):.1f} s "
                   f"(max {max(secs):.1f} s, {len(secs)} parts)")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--families", nargs="*", default=list(FAMILIES), choices=FAMILIES,
                    metavar="FAMILY", help=f"part families (default all: {', '.join(FAMILIES)})")
    ap.add_argument("--seeds", type=int, default=5,
                    help="seeds per family, 0…N-1 (default 5: 40 generated parts)")
    ap.add_argument("--only", nargs="*", default=None, metavar="PART",
                    help="only these generated parts, FAMILY_SEED (e.g. fender_arch_3 bumper_1)")
    ap.add_argument("--no-shared", action="store_true",
                    help="leave out the meshes in ../shared/meshes")
    ap.add_argument("--keep", type=Path, default=None,
                    help="folder for the parts, cells and runs (default: a temporary folder)")
    ap.add_argument("--markdown", type=Path, default=None, help="also write the table here")
    ap.add_argument("--timeout", type=float, default=900.0,
                    help="wall-clock limit of each init and each run [s] (default 900)")
    args = ap.parse_args()
    if args.seeds < 0:
        sys.exit("--seeds: give 0 or more")
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        parts: list[tuple[str, Path, bool]] = []
        (work / "parts").mkdir(parents=True, exist_ok=True)
        for fam in args.families:
            for seed in range(args.seeds):
                if args.only is not None and f"{fam}_{seed}" not in args.only:
                    continue
                f = work / "parts" / f"{fam}_{seed}.{_FORMATS[seed % len(_FORMATS)]}"
                proc, _ = _paintcell(["generate", fam, "--seed", str(seed), "--out", str(f)],
                                     args.timeout)
                if proc.returncode != 0:
                    sys.exit(f"generate {fam} --seed {seed} failed: {_last_line(proc.stderr)}")
                parts.append((f"{fam}_{seed}", f, True))
        if not args.no_shared:
            parts += [(p.stem, p, False) for p in sorted(MESHES.glob("*"))
                      if p.suffix in (".ply", ".stl", ".obj", ".step", ".stp")]
        rows = []
        for i, (name, mesh, generated) in enumerate(parts):
            r = run_part(name, mesh, work, generated, args.timeout)
            rows.append(r)
            print(f"[{i + 1}/{len(parts)}] {name}: {r.verdict} σ/μ {_fmt(r.nsd_pct, '.2f')} %, "
                  f"{r.seconds:.1f} s {r.why[:120]}", file=sys.stderr, flush=True)
        lines = table(rows)
        print("\n".join(lines))
        print()
        summary = totals(rows)
        print("\n".join(summary))
        if args.markdown is not None:
            cmd = "benchmarks/generality.py " + " ".join(sys.argv[1:])
            args.markdown.write_text(f"`{cmd.strip()}` on {time.strftime('%Y-%m-%d')}\n\n"
                                     + "\n".join(lines) + "\n\n"
                                     + "\n".join(f"- {s}" for s in summary) + "\n")


if __name__ == "__main__":
    main()
