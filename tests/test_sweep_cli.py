"""`paintcell sweep` on the command line: every option explained, bad input refused in one line
(exit 2) before any planning starts (in this process: main() is what the console script runs)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from paintcell.cli.common import EXIT_USAGE
from paintcell.cli.main import build_parser, main

ROOT = Path(__file__).resolve().parent.parent


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "paintcell", *args], capture_output=True,
                          text=True, cwd=ROOT, timeout=120)


def test_sweep_help_explains_every_option() -> None:
    sub = build_parser()._subparsers._group_actions[0].choices["sweep"]  # type: ignore[union-attr]
    for action in sub._actions:
        if action.dest != "help":
            assert action.help, f"sweep option {action.dest} has no help"
    out = _run("sweep", "--help")
    assert out.returncode == 0 and "usage: paintcell sweep" in out.stdout
    for name in ("standoff_error_m [m]", "trigger_delay_s [s]", "Clopper-Pearson"):
        assert name in " ".join(out.stdout.split())


def test_bad_factors_are_one_line_errors(capsys: pytest.CaptureFixture[str]) -> None:
    for vary, words in (("part_offset_m=gauss(0, 1)", "unknown distribution"),
                        ("conveyor_speed_m_s=normal(0, 0.01)", "no conveyor"),
                        ("part_offset_m", "not NAME=DIST")):
        code = main(["sweep", str(ROOT / "scenarios" / "door.toml"), "--fast", "--vary", vary])
        err = capsys.readouterr().err
        assert code == EXIT_USAGE, err
        assert err.count("\n") == 1 and words in err and "Traceback" not in err
