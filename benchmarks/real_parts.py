"""Per-part table of the real-part scenarios: film, loss, tolerance window, cycle time, honest
reachability, joint jumps and collisions, at the fast or the full resolution
(`benchmarks/results.py` writes docs/results.md from `paintcell check --fast` of every scenario).

Each scenario runs as `python -m paintcell run SCENARIO [--fast] --out DIR` in its own process (the
way `paintcell check` runs it) and the table is read back from the run's metrics.json, so the
figures are exactly the ones a user gets from `paintcell run`.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/real_parts.py            # fast resolution (CI)
    PYTHONPATH=$PWD .venv/bin/python benchmarks/real_parts.py --full     # full resolution
    PYTHONPATH=$PWD .venv/bin/python benchmarks/real_parts.py scenarios/cad_door.toml

Columns: planned and executed σ/μ over the judged skin [%]; loss = executed − planned σ/μ [pp];
area of the judged skin whose executed film lies within ±10 % of its mean [%]; executed cycle
time [s]; honest reachability [%] (`paintcell.validation.honest_reach`: IK reached, no jump or
flip into the pose,
no contact, time law ≥ 90 % of the planned speed); poses reached through a joint jump or a
configuration flip; collision events; and the PASS/FAIL of the scenario's own thresholds.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The real-part scenarios.
REAL_PARTS = ("cad_door", "cad_hood", "cad_fender", "cad_roof", "snp_panel", "reach_hood_panel",
              "crs_cowling_3_holes", "crs_cowling_creases")

_COLS = (("planned σ/μ %", "planned_nsd_pct", "{:.2f}"),
         ("executed σ/μ %", "executed_nsd_pct", "{:.2f}"),
         ("loss pp", "loss_pp", "{:+.3f}"),
         ("±10 % area %", "executed_within_tolerance_pct", "{:.1f}"),
         ("cycle s", "executed_cycle_time_s", "{:.2f}"),
         ("reach %", "reachability_pct", "{:.2f}"),
         ("jumps", "reach_n_joint_jumps", "{:.0f}"),
         ("flips", "reach_n_config_flips", "{:.0f}"),
         ("collisions", "n_collisions", "{:.0f}"))


def run_one(scenario: Path, *, fast: bool, out: Path) -> tuple[dict, float]:
    """Run one scenario in a child process; its metrics.json and the wall time [s]."""
    cmd = [sys.executable, "-m", "paintcell", "run", str(scenario), "--out", str(out),
           "--no-report"]
    if fast:
        cmd.append("--fast")
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    mfile = out / "metrics.json"
    if proc.returncode not in (0, 1) or not mfile.exists():
        last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        raise SystemExit(f"{scenario}: run exited {proc.returncode}: {last}")
    return json.loads(mfile.read_text()), wall


def _metrics(d: dict) -> dict:
    """metrics.json holds the validation report; its metrics may sit at the top or under a key."""
    for key in ("metrics", "validation"):
        if isinstance(d.get(key), dict) and "executed_nsd_pct" in d[key]:
            return _metrics(d[key]) if key != "metrics" else d[key]
    return d


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenarios", nargs="*", type=Path,
                    help="scenario files (default: the real-part scenarios)")
    ap.add_argument("--full", action="store_true",
                    help="full resolution (resolution_m) instead of the fast one")
    args = ap.parse_args(argv)
    paths = args.scenarios or [ROOT / "scenarios" / f"{n}.toml" for n in REAL_PARTS]
    head = "| part | " + " | ".join(c[0] for c in _COLS) + " | thresholds | run s |"
    print(f"resolution: {'full' if args.full else 'fast'}")
    print(head)
    print("|" + "---|" * (len(_COLS) + 3))
    with tempfile.TemporaryDirectory(prefix="paintcell-real-parts-") as td:
        for p in paths:
            if not p.exists():
                print(f"| {p.stem} | (no scenario) |")
                continue
            d, wall = run_one(p, fast=not args.full, out=Path(td) / p.stem)
            m = _metrics(d)
            cells = []
            for _, key, fmt in _COLS:
                v = m.get(key)
                cells.append("-" if v is None else fmt.format(float(v)))
            passed = d.get("passed", m.get("passed"))
            verdict = "PASS" if passed else ("FAIL" if passed is not None else "?")
            print(f"| {p.stem} | " + " | ".join(cells) + f" | {verdict} | {wall:.0f} |",
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
