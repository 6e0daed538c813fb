"""What every fuzz case asserts, shared by the scenario and mesh fuzz files.

- `loader_outcome`: the loader either returns or raises a `PaintcellError` whose message is one
  line naming the file — never another exception type (a traceback for the user);
- `cli_refusal`: the real `paintcell` command in a subprocess exits 2 with exactly one line on
  stderr that names the file (or the setting), writes no results folder and leaves no hidden
  temporary sibling of it (the `--out` folder's parent is listed before and after).
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from paintcell.core.errors import PaintcellError

ROOT = Path(__file__).resolve().parents[2]
#: A case that hangs is a failure, not a wait: no refusal at load takes a minute.
CLI_TIMEOUT_S = 120


def loader_outcome(load: Callable[[], Any], name: str) -> str | None:
    """None when `load()` returns; the message when it raises a PaintcellError of one line
    naming `name`; any other exception fails the case."""
    try:
        load()
    except PaintcellError as exc:
        msg = str(exc)
        assert msg.strip() and "\n" not in msg.strip(), f"not one line: {msg!r}"
        assert name in msg, f"the message does not name {name}: {msg}"
        return msg
    return None


def run_cli(args: list[str], cwd: Path, env: dict[str, str] | None = None
            ) -> subprocess.CompletedProcess[str]:
    """`paintcell ARGS` in a subprocess with this tree's package first on the path."""
    full_env = {**os.environ, "PYTHONPATH": str(ROOT), **(env or {})}
    return subprocess.run([sys.executable, "-m", "paintcell", *args], cwd=cwd, env=full_env,
                          capture_output=True, text=True, timeout=CLI_TIMEOUT_S)


def cli_refusal(args: list[str], cwd: Path, names: str, out: Path | None = None,
                env: dict[str, str] | None = None) -> str:
    """Run `paintcell ARGS`; assert exit 2, one stderr line naming `names`, and that `out` (the
    results folder, when the command takes one) and no hidden sibling of it was written.
    Returns the line."""
    parent = out.parent if out is not None else None
    before = set(os.listdir(parent)) if parent is not None and parent.exists() else set()
    r = run_cli(args, cwd, env)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2, f"exit {r.returncode}, stderr: {r.stderr[-2000:]}"
    assert len(lines) == 1, f"{len(lines)} stderr lines: {r.stderr[-2000:]}"
    assert names in lines[0], f"{names!r} not named: {lines[0]}"
    if out is not None and parent is not None:
        assert not out.exists(), f"{out} was written"
        after = set(os.listdir(parent)) if parent.exists() else set()
        assert after == before, f"new entries beside {out}: {sorted(after - before)}"
    return lines[0]
