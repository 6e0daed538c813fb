"""The `paintcell` command line: run, check, plan, validate, export, report.

Each subcommand is registered by one `add_<name>(sub)` function (its options, its help and the
function that runs it) in its own module — `paintcell.cli.run` (run, plan),
`paintcell.cli.check` (check),
`paintcell.cli.results` (validate, export, report), `paintcell.cli.part_commands`,
`paintcell.cli.sweep`; shared exit
codes and helpers are in `paintcell.cli.common`. `build_parser` calls them in order, so a
new subcommand is one more function and one more line there. Exit codes are in `EXIT_HELP`.
Errors print one line; `--debug` shows the traceback.
"""

from __future__ import annotations

import argparse
import signal
import sys
import traceback
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.cli.check import add_check
from paintcell.cli.common import (
    EXIT_INTERRUPTED,
    EXIT_USAGE,
    one_line,
    os_error_line,
    symlink_loop_path,
)
from paintcell.cli.junit import write_junit
from paintcell.cli.part_commands import register as add_part_commands
from paintcell.cli.results import add_export, add_report, add_validate
from paintcell.cli.run import add_plan, add_run
from paintcell.core import interrupts
from paintcell.core.errors import PaintcellError

__all__ = ["UsageExit", "build_parser", "error_line", "main", "run_script"]

EXIT_HELP = """\
exit codes:
  0    success (run/check/validate: every threshold met)
  1    a threshold was not met (run, check, validate), or a check scenario errored
  2    usage or input error (bad option, scenario, mesh, results folder; a busy folder)
  130  interrupted (Ctrl-C or SIGTERM); nothing half-written is left behind

results folders: a folder is paintcell's only if it holds the .paintcell-results marker;
run/plan replace only such a folder (or a missing or empty one), atomically, one writer at a
time; validate/export/report read the scenario snapshot in scenario.json, never a script."""


class UsageExit(SystemExit):
    """A command line argparse refused (exit code 2); `message` says why."""

    def __init__(self, message: str) -> None:
        super().__init__(EXIT_USAGE)
        self.message = message


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        message = " ".join(message.split())
        sys.stderr.write(f"paintcell: error: {message} (see `paintcell --help`)\n")
        raise UsageExit(message)


class _Help(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Shows a default only where it tells something (not None, False or an empty list)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default in (None, False, [], argparse.SUPPRESS) or action.required:
            return action.help
        return super()._get_help_string(action)


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

    from paintcell.cli.sweep import add_sweep_parser

    for register in (add_run, add_check, add_plan, add_validate, add_export, add_report,
                     add_part_commands,  # inspect, init, generate
                     add_sweep_parser):
        register(add_parser)
    return p


def main(argv: list[str] | None = None) -> int:
    """Console entry point; returns the exit code."""
    interrupts.reset()
    previous = {s: signal.signal(s, interrupts.on_signal)
                for s in (signal.SIGINT, signal.SIGTERM)}
    debug = "--debug" in (sys.argv[1:] if argv is None else argv)
    try:
        with warnings.catch_warnings():
            # A library's warning (numpy's RuntimeWarning on a mesh with inf vertices, …) is not
            # the user's business: the error that follows says what is wrong, in one line.
            if not debug:
                warnings.simplefilter("ignore")
            with np.errstate(all="ignore" if not debug else "warn"):
                code = _main(argv)
        # A signal that a library swallowed (see paintcell.core.interrupts) still ends the
        # command as one.
        return EXIT_INTERRUPTED if interrupts.pending() is not None else code
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM (paintcell.core.interrupts)
        sys.stderr.write(f"paintcell: interrupted ({str(exc) or 'SIGINT'}); nothing "
                         "half-written was left\n")
        return EXIT_INTERRUPTED
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except UsageExit as exc:
        _junit_of_usage_error(sys.argv[1:] if argv is None else argv, exc.message)
        raise
    try:
        return int(args.func(args))
    except (PaintcellError, OSError, UnicodeDecodeError) as exc:
        return _error(args.debug, error_line(exc))
    except RuntimeError as exc:
        loop = symlink_loop_path(exc)
        if loop is None:
            return _internal(exc, args.debug)
        return _error(args.debug, f"{loop}: is a symbolic-link loop; fix or remove the link")
    except ValueError as exc:
        return _error(args.debug, one_line(exc))
    except MemoryError:
        return _error(args.debug, "out of memory; use a coarser resolution_m or smaller sample "
                      "settings in the scenario")
    except Exception as exc:  # a bug, not bad input: still one line unless --debug
        return _internal(exc, args.debug)


def _error(debug: bool, line: str, kind: str = "error") -> int:
    """Print `line` as the command's one error line (the traceback too with --debug) while an
    exception is being handled; the usage exit code."""
    if debug:
        traceback.print_exc()
    sys.stderr.write(f"paintcell: {kind}: {line}\n")
    return EXIT_USAGE


def _internal(exc: BaseException, debug: bool) -> int:
    return _error(debug, f"{type(exc).__name__}: {one_line(exc)} (rerun with --debug for the "
                  "traceback)", "internal error")


def error_line(exc: BaseException) -> str:
    """The one line of an input error: OS errors name the path and what to do about it."""
    if isinstance(exc, OSError) and exc.errno is not None:
        return os_error_line(exc)
    if isinstance(exc, UnicodeDecodeError):
        return (f"a file is not {exc.encoding} text (byte 0x{exc.object[exc.start]:02x} at "
                f"position {exc.start}); save it as UTF-8")
    return one_line(exc)


def _junit_of_usage_error(argv: list[str], message: str) -> None:
    """`paintcell check … --junit FILE` refused by the parser still writes FILE (one error case),
    so that a CI never reads an earlier run's file as this one's."""
    words = [w for w in argv if not w.startswith("-")]
    if not words or words[0] != "check":
        return
    pre = argparse.ArgumentParser(add_help=False, exit_on_error=False)
    pre.add_argument("--junit", type=Path, default=None)
    try:
        junit = pre.parse_known_args(argv)[0].junit
    except (argparse.ArgumentError, SystemExit):
        return
    if junit is None or junit.is_dir():
        return
    try:
        write_junit(junit, [], suite_error=("usage", f"usage error: {message}"))
    except OSError as exc:
        sys.stderr.write(f"paintcell: error: --junit not written: {os_error_line(exc)}\n")


def run_script(scenario: Any, argv: list[str] | None = None) -> int:
    """Entry point of a scenario script: `paintcell run <the script>` with the script's command-line
    arguments (or `argv`). A script ends with `raise SystemExit(run_script(SCENARIO))`."""
    src = scenario.source or sys.argv[0]
    return main(["run", src, *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    raise SystemExit(main())
