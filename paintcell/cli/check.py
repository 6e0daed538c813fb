"""`paintcell check`: every scenario in its own process, one row each, JUnit XML always written.

Each scenario runs as `python -m paintcell run SCENARIO --row-json FILE` in a child process, so
anything a scenario does — an exception that is not paintcell's, `sys.exit` on import, a
MemoryError, a crash or a kill — becomes an ERROR row and a JUnit error case, and the check goes
on to the next scenario. The JUnit file is written even when the check is interrupted.
With `--jobs N` up to N scenarios run at once (a thread waits on each child process); the rows
and the JUnit cases keep the scenarios' order, and every figure is the same as run one by one
(a scenario's results do not depend on what else runs).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

__all__ = ["add_check", "format_table", "row", "run_isolated", "write_junit"]


def add_check(add_parser: Any) -> None:
    """Register `paintcell check`."""
    c = add_parser("check", help="run every scenario and hold it to its thresholds (CI)",
                   description=(
                       "Run every scenario found in PATHs, each in its own process, and print "
                       "one row per scenario with each threshold and its measured value. A "
                       "scenario that cannot be loaded, errors or crashes is an ERROR row and "
                       "the check goes on. Exits 1 if any scenario fails or errors."))
    c.add_argument("paths", nargs="*", default=["scenarios"],
                   help="scenario files (.toml or .py) or folders of them")
    c.add_argument("--junit", type=Path, default=None,
                   help="also write JUnit XML to this file (always written, even on errors)")
    c.add_argument("--fast", action="store_true",
                   help="each scenario's coarse mesh resolution (fast_resolution_m, 25 mm unless "
                   "the scenario says otherwise) and fast planner overrides (CI budget)")
    c.add_argument("--out", type=Path, default=None,
                   help="also write each scenario's results under this folder (no report)")
    c.add_argument("--timeout", type=float, default=None,
                   help="wall-clock limit per scenario [s]; a scenario over it is an ERROR row")
    c.add_argument("--jobs", "-j", type=_jobs, default=1, metavar="N",
                   help="scenarios run at once, each in its own process (default 1; 0 = one "
                   "per CPU core). Each needs ~1-2 GB of memory; the figures do not change")
    c.set_defaults(func=_cmd_check)


def _jobs(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = -1
    if n < 0:
        raise argparse.ArgumentTypeError(f"--jobs {text!r} must be a whole number >= 0 "
                                         "(0 = one per CPU core), e.g. --jobs 2")
    return n or (os.cpu_count() or 1)


class _Children:
    """The check's running scenario processes, so that an interrupt stops every one of them."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._procs: set[subprocess.Popen[str]] = set()

    def add(self, proc: subprocess.Popen[str]) -> None:
        with self._lock:
            self._procs.add(proc)

    def discard(self, proc: subprocess.Popen[str]) -> None:
        with self._lock:
            self._procs.discard(proc)

    def stop_all(self) -> None:
        with self._lock:
            procs = list(self._procs)
        for proc in procs:
            if proc.poll() is None:
                proc.terminate()
        for proc in procs:
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def _cmd_check(args: argparse.Namespace) -> int:
    from paintcell.app.scenario_files import find_scenarios

    scripts = find_scenarios(args.paths)
    done: dict[int, tuple[dict[str, Any], float]] = {}
    children = _Children()
    stopping = threading.Event()

    def one(i: int) -> None:
        t0 = time.perf_counter()
        r = run_isolated(scripts[i], fast=args.fast, out_under=args.out,
                         timeout_s=args.timeout, children=children)
        if not stopping.is_set():  # a scenario the interrupt stopped is not a result
            done[i] = (r, time.perf_counter() - t0)

    jobs = max(1, min(args.jobs, len(scripts) or 1))
    pool = ThreadPoolExecutor(max_workers=jobs) if jobs > 1 else None
    try:
        if pool is None:  # one at a time, from this thread
            for i in range(len(scripts)):
                one(i)
        else:
            for f in [pool.submit(one, i) for i in range(len(scripts))]:
                f.result()
    except BaseException:
        stopping.set()
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)
        children.stop_all()
        raise
    finally:
        if pool is not None:
            pool.shutdown(wait=True)
        # Written on every way out (an interrupted check reports the scenarios it finished),
        # in the scenarios' order.
        if args.junit is not None:
            write_junit(args.junit, [(r["name"], dt, r["checks"], r.get("error"))
                                     for _, (r, dt) in sorted(done.items())])
    rows = [done[i][0] for i in range(len(scripts))]
    print(format_table(rows))
    failed = [r["name"] for r in rows if not r["passed"]]
    print(f"{len(rows) - len(failed)} passed, {len(failed)} failed")
    return 1 if failed else 0


def run_isolated(script: Path, *, fast: bool, out_under: Path | None = None,
                 timeout_s: float | None = None,
                 children: _Children | None = None) -> dict[str, Any]:
    """Run one scenario in a child process; its table row, or an ERROR row saying what happened.
    `children`: where the running process is registered (so an interrupt can stop it)."""
    import paintcell

    with tempfile.TemporaryDirectory(prefix="paintcell-check-") as td:
        row_file = Path(td) / "row.json"
        cmd = [sys.executable, "-m", "paintcell", "run", str(script), "--row-json", str(row_file)]
        if fast:
            cmd.append("--fast")
        if out_under is not None:
            cmd += ["--out-under", str(out_under)]
        env = dict(os.environ)
        root = str(Path(paintcell.__file__).resolve().parents[1])
        env["PYTHONPATH"] = os.pathsep.join([root, *filter(None, [env.get("PYTHONPATH")])])
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True, env=env)
        if children is not None:
            children.add(proc)
        try:
            _, err = proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            return _error_row(script, f"exceeded --timeout {timeout_s:g} s and was stopped")
        finally:
            if proc.poll() is None:  # interrupted: stop the child before leaving
                proc.terminate()
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    proc.kill()
            if children is not None:
                children.discard(proc)
        rc = proc.returncode
        if rc in (0, 1) and row_file.exists():
            try:
                return dict(json.loads(row_file.read_text()))
            except ValueError:
                pass
        lines = [ln for ln in (err or "").strip().splitlines() if ln.strip()]
        last = lines[-1].removeprefix("paintcell: error: ") if lines else ""
        if rc < 0:
            why = f"killed by {signal.Signals(-rc).name}"
        elif rc == 2 and last:
            return _error_row(script, last)
        else:
            why = f"exited with code {rc} without a result"
        return _error_row(script, why + (f" ({last})" if last else ""))


def _error_row(script: Path, msg: str) -> dict[str, Any]:
    return {"name": script.stem, "error": msg, "passed": False, "checks": []}


def row(name: str, report: Any) -> dict[str, Any]:
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
            f"{_fmt(c['limit'])}{'' if c['passed'] else ' ✗'}"
            + (f" ({c['detail']})" if c.get("detail") else "") for c in r["checks"])
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

    from paintcell.core.atomic_io import atomic_write_text

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


