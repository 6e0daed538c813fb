"""What the `paintcell` sub-command modules share: exit codes, option help and range-checked
option types, error lines, KEY=VALUE, the --out/--force pair of commands that write one file.

`paintcell.cli.main` and the sub-command modules (`paintcell.cli.run`,
`paintcell.cli.results`) import these, so no
sub-command module needs `paintcell.cli.main` (which imports them).
"""

from __future__ import annotations

import argparse
import errno
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from paintcell.core.errors import PaintcellError, one_line

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


FAST_HELP = ("the scenario's coarse mesh resolution (fast_resolution_m, 25 mm unless the "
             "scenario says otherwise) and fast planner overrides (CI budget)")
SCENARIO_HELP = "scenario file: TOML (e.g. scenarios/door.toml) or a Python script"
DIR_HELP = "results folder written by `paintcell run`"


def add_out_force(p: Any, what: str, required: bool = True, default: Any = None) -> None:
    """`--out` (the file written: `what`) and `--force` on parser `p`: an existing file is
    replaced only with --force (`paintcell.core.safe_paths.check_new_target`)."""
    p.add_argument("--out", type=Path, required=required, default=default,
                   help=f"{what}; an existing file is refused unless --force")
    p.add_argument("--force", action="store_true", help="replace an existing --out file")


def fmt_value(v: Any) -> str:
    """A figure of the check table and JUnit file: '-' for None, counts and whole percentages
    without decimals, other floats with two."""
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.0f}" if v.is_integer() and abs(v) < 1e9 else f"{v:.2f}"
    return str(v)


def number_option(option: str, kind: type[int] | type[float], *, low: float,
                  low_open: bool = False, high: float | None = None, unit: str = "",
                  example: str, note: str = "") -> Callable[[str], Any]:
    """An argparse `type=` that reads a finite number in [low, high] (or (low, high] when
    `low_open`) and refuses anything else — negative, zero where meaningless, nan, inf, text —
    as a usage error naming `option`, the allowed range and an example."""
    what = "a whole number" if kind is int else "a finite number"
    bounds = f"{'>' if low_open else '≥'} {low:g}" + ("" if high is None else f" and ≤ {high:g}")
    allowed = f"{what} {bounds}{f' {unit}' if unit else ''}{f' ({note})' if note else ''}"

    def parse(text: str) -> Any:
        try:
            value = kind(text.strip())
        except (TypeError, ValueError):
            value = None
        if value is None or not math.isfinite(value) or value < low \
                or (low_open and value == low) or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"{text!r} is out of range: give {allowed}, e.g. "
                                             f"{option} {example}")
        return value

    parse.__name__ = option.lstrip("-").replace("-", "_")
    parse.allowed = allowed   # type: ignore[attr-defined]
    parse.example = example   # type: ignore[attr-defined]
    return parse


# What a user can do about each OS error (the path is named before it).
_OS_FIXES = {
    errno.ENOSPC: "no space left on the device; free space there or write to another folder",
    errno.EDQUOT: "disk quota exceeded; free space there or write to another folder",
    errno.EACCES: "permission denied; make it readable/writable for you or use another path",
    errno.EPERM: "operation not permitted; use a path you own",
    errno.EROFS: "is on a read-only file system; write to another folder",
    errno.EEXIST: "already exists; remove it or choose another name",
    errno.EISDIR: "is a folder where a file belongs; give a file path",
    errno.ENOTDIR: "a part of the path is a file, not a folder; fix the path",
    errno.ENOENT: "does not exist; check the path",
    errno.ELOOP: "is a symbolic-link loop or a link where none is allowed; fix or remove the link",
    errno.ENAMETOOLONG: "the name is too long; use a shorter path",
    errno.EFBIG: "the file is too large for this file system or limit; write elsewhere",
    errno.EMFILE: "too many open files; raise the limit (ulimit -n) and retry",
}


def os_error_line(exc: OSError) -> str:
    """One line for an OS error: the path(s) it concerns, what happened and what to do."""
    # Of a rename or link (source -> destination), the destination is the path the user named.
    where = str(exc.filename2 if exc.filename2 is not None else exc.filename or "")
    fix = _OS_FIXES.get(exc.errno or -1)
    if fix is None:
        fix = f"{exc.strerror or one_line(exc)}; check the path and retry"
    return f"{where}: {fix}" if where else f"{fix} (errno {exc.errno})"


#: `--resolution` of inspect and init: a remesh edge length [m], 0 keeps the tessellation.
RESOLUTION_M = number_option("--resolution", float, low=0.0, high=1.0, unit="m", example="0.025",
                             note="0: keep the tessellation")
#: `--seed` of generate and sweep.
SEED = number_option("--seed", int, low=0, high=2**32 - 1, example="3")


def symlink_loop_path(exc: RuntimeError) -> str | None:
    """The path of pathlib's 'Symlink loop from …' RuntimeError (Python < 3.13), else None."""
    msg = str(exc)
    if msg.startswith("Symlink loop from "):
        return msg.removeprefix("Symlink loop from ").strip("'\"")
    return None


def default_out(name: str) -> Path:
    """The default results folder of a scenario: results/<name>."""
    return Path("results") / name


def key_values(items: list[str]) -> dict[str, Any]:
    """Parse KEY=VALUE options; values are ints, floats or strings."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise PaintcellError(f"option value {item!r} is not KEY=VALUE (e.g. "
                                 "part_offset_m=0.005)")
        value: Any = raw
        for conv in (int, float):
            try:
                value = conv(raw)
                break
            except ValueError:
                continue
        out[key.strip()] = value
    return out
