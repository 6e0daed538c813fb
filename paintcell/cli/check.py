"""`paintcell check`: every scenario in its own process group, one row each, a JUnit that fails
closed.

Each scenario runs as `python -m paintcell run SCENARIO --row-fd N` in a child process that leads
its own process group (setsid), so anything a scenario does — an exception that is not
paintcell's, `sys.exit` on import, a MemoryError, a crash, a kill, a child process of its own that
hangs — becomes an ERROR row and a JUnit error case, and the check goes on to the next scenario.
The whole group is stopped (SIGTERM, then SIGKILL after a grace period) when the scenario
exceeds `--timeout`, when it ends (what it left running), when the check is interrupted and on
every other way out of the check; the child dies with the check, even a SIGKILLed one
(`paintcell.cli.process_group`). The check keeps no named temporary files: the row and the
child's stderr travel through unnamed files.

The JUnit file fails closed: before the first scenario runs it holds an error case saying the
check did not finish, so a killed check never leaves a green (or an earlier run's) file; an
interrupted check writes its finished cases, the stopped one as an error case and a suite error
case "interrupted (SIGTERM): N scenarios not run"; a usage error is an error case too.
With `--jobs N` up to N scenarios run at once (a thread waits on each child process); the rows
and the JUnit cases keep the scenarios' order, and every figure is the same as run one by one.
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

from paintcell.cli.common import fmt_value, number_option, one_line
from paintcell.cli.junit import clean_text, write_junit
from paintcell.cli.process_group import Children, stop_group, wait_exit
from paintcell.core.errors import PaintcellError

__all__ = ["add_check", "format_table", "row", "run_isolated"]

_JOBS = number_option("--jobs", int, low=0, high=256, example="2",
                      note="0: one per CPU core")


def add_check(add_parser: Any) -> None:
    """Register `paintcell check`."""
    c = add_parser("check", help="run every scenario and hold it to its thresholds (CI)",
                   description=(
                       "Run every scenario found in PATHs, each in its own process group, and "
                       "print one row per scenario with each threshold and its measured value. A "
                       "scenario that cannot be loaded, errors, crashes or times out is an ERROR "
                       "row and the check goes on. Exits 1 if any scenario fails or errors."))
    c.add_argument("paths", nargs="*", default=["scenarios"],
                   help="scenario files (.toml or .py) or folders of them")
    c.add_argument("--junit", type=Path, default=None,
                   help="also write JUnit XML to this file; written on every way out (usage "
                   "errors, interrupts) and never all-green unless every scenario passed")
    c.add_argument("--fast", action="store_true",
                   help="each scenario's coarse mesh resolution (fast_resolution_m, 25 mm unless "
                   "the scenario says otherwise) and fast planner overrides (CI budget)")
    c.add_argument("--out", type=Path, default=None,
                   help="also write each scenario's results under this folder (no report)")
    c.add_argument("--timeout", default=None,
                   type=number_option("--timeout", float, low=0.0, low_open=True, unit="s",
                                      example="600"),
                   help="wall-clock limit per scenario [s]; a scenario over it is stopped with "
                   "every process it started and is an ERROR row")
    c.add_argument("--jobs", "-j", type=_jobs, default=1, metavar="N",
                   help="scenarios run at once, each in its own process (default 1; 0 = one "
                   "per CPU core). Each needs ~1-2 GB of memory; the figures do not change")
    c.set_defaults(func=_cmd_check)


def _jobs(text: str) -> int:
    return int(_JOBS(text)) or (os.cpu_count() or 1)


_jobs.allowed, _jobs.example = _JOBS.allowed, _JOBS.example  # type: ignore[attr-defined]


# --- the command --------------------------------------------------------------------------------

def _cmd_check(args: argparse.Namespace) -> int:
    from paintcell.app.scenario_files import find_scenarios
    from paintcell.core import interrupts

    if args.junit is not None:
        _claim_junit(args.junit)
    scripts: list[Path] | None = None
    done: dict[int, tuple[dict[str, Any], float]] = {}
    started: dict[int, float] = {}
    children = Children()
    stopping = threading.Event()

    def one(i: int) -> None:
        if stopping.is_set():
            return
        assert scripts is not None
        started[i] = t0 = time.perf_counter()
        r = run_isolated(scripts[i], fast=args.fast, out_under=args.out,
                         timeout_s=args.timeout, children=children)
        if not stopping.is_set():  # a scenario the interrupt stopped is not a result
            done[i] = (r, time.perf_counter() - t0)

    ended: BaseException | None = None
    pool = None
    try:
        scripts = find_scenarios(args.paths)
        jobs = max(1, min(args.jobs, len(scripts)))
        pool = ThreadPoolExecutor(max_workers=jobs) if jobs > 1 else None
        if pool is None:  # one at a time, from this thread
            for i in range(len(scripts)):
                one(i)
        else:
            for f in [pool.submit(one, i) for i in range(len(scripts))]:
                f.result()
    except BaseException as exc:
        ended = exc
        stopping.set()
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)
        raise
    finally:
        children.stop_all()   # every way out: no scenario's process group outlives the check
        if pool is not None:
            pool.shutdown(wait=True)
        if args.junit is not None:
            _final_junit(args.junit, scripts, done, started, ended, interrupts.pending())
    assert scripts is not None
    rows = [done[i][0] for i in range(len(scripts))]
    print(format_table(rows))
    failed = [r["name"] for r in rows if not r["passed"]]
    print(f"{len(rows) - len(failed)} passed, {len(failed)} failed")
    return 1 if failed else 0


def _claim_junit(path: Path) -> None:
    """Refuse a --junit path that cannot be written, before any scenario runs, by writing the
    file a check that never finishes leaves: one error case, never green."""
    if path.is_dir():
        raise PaintcellError(f"--junit {path} is a folder; give a file path such as "
                             f"{path / 'junit.xml'}")
    try:
        write_junit(path, [], suite_error=("incomplete", "paintcell check started and did not "
                                           "finish (killed, or still running)"))
    except OSError as exc:
        from paintcell.cli.common import os_error_line

        raise PaintcellError(f"--junit {path} cannot be written ({os_error_line(exc)}); no "
                             "scenario was run") from exc


def _final_junit(path: Path, scripts: list[Path] | None,
                 done: dict[int, tuple[dict[str, Any], float]], started: dict[int, float],
                 ended: BaseException | None, signal_name: str | None) -> None:
    cases = [(r["name"], dt, r["checks"], r.get("error")) for _, (r, dt) in sorted(done.items())]
    suite_error = None
    if isinstance(ended, KeyboardInterrupt):
        why = f"interrupted ({signal_name or str(ended) or 'SIGINT'})"
        now = time.perf_counter()
        stopped = sorted(i for i in started if i not in done)
        assert scripts is not None or not stopped
        for i in stopped:
            assert scripts is not None
            cases.append((scripts[i].stem, now - started[i], [],
                          f"{why} while running; no result"))
        not_run = "?" if scripts is None else str(len(scripts) - len(done) - len(stopped))
        suite_error = ("interrupted", f"{why}: {not_run} scenario(s) not run"
                       + (f", {len(stopped)} stopped while running" if stopped else ""))
    elif ended is not None:
        suite_error = ("error", f"paintcell check stopped: {one_line(ended)}")
    try:
        write_junit(path, cases, suite_error=suite_error)
    except OSError as exc:
        if ended is None:
            raise
        from paintcell.cli.common import os_error_line

        sys.stderr.write(f"paintcell: error: --junit not written: {os_error_line(exc)}\n")


def run_isolated(script: Path, *, fast: bool, out_under: Path | None = None,
                 timeout_s: float | None = None,
                 children: Children | None = None) -> dict[str, Any]:
    """Run one scenario in a child process group; its table row, or an ERROR row saying what
    happened. `children`: where the running process is registered (so an interrupt can stop
    it). The group is stopped before this returns or raises."""
    import paintcell

    cmd = [sys.executable, "-m", "paintcell", "run", str(script), "--parent-pid",
           str(os.getpid())]
    if fast:
        cmd.append("--fast")
    if out_under is not None:
        cmd += ["--out-under", str(out_under)]
    env = dict(os.environ)
    root = str(Path(paintcell.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join([root, *filter(None, [env.get("PYTHONPATH")])])
    # Unnamed files (nothing to leave behind) rather than pipes: a grandchild that keeps a pipe
    # open would hold the check until it ends.
    with tempfile.TemporaryFile() as row_f, tempfile.TemporaryFile() as err_f:
        cmd += ["--row-fd", str(row_f.fileno())]
        proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                stderr=err_f, pass_fds=(row_f.fileno(),), env=env,
                                start_new_session=True)
        timed_out = False
        try:
            if children is not None:
                children.add(proc)
            timed_out = not wait_exit(proc, timeout_s)
        finally:
            stop_group(proc)   # on time-out, on an interrupt, and what it left running
            if children is not None:
                children.discard(proc)
        if timed_out:
            return _error_row(script, f"exceeded --timeout {timeout_s:g} s and was stopped "
                              "with every process it started")
        rc = proc.returncode
        row_f.seek(0)
        raw = row_f.read()
        err_f.seek(0)
        err = err_f.read().decode("utf-8", errors="replace")
    if rc in (0, 1) and raw:
        try:
            return dict(json.loads(raw))
        except ValueError:
            pass
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    last = lines[-1].removeprefix("paintcell: error: ") if lines else ""
    if rc < 0:
        why = f"killed by {signal.Signals(-rc).name}"
    elif rc == 2 and last:
        return _error_row(script, last)
    else:
        why = f"exited with code {rc} without a result"
    return _error_row(script, why + (f" ({last})" if last else ""))


def _error_row(script: Path, msg: str) -> dict[str, Any]:
    return {"name": script.stem, "error": clean_text(msg), "passed": False, "checks": []}


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


_fmt = fmt_value


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
                         f"{'':>8}  ERROR   {clean_text(r['error'])}")
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
