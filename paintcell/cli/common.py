"""What the `paintcell` sub-command modules share: exit codes, option help, error lines, KEY=VALUE,
the --out/--force pair of commands that write one file.

`paintcell.cli.main` and the sub-command modules (`paintcell.cli.run`,
`paintcell.cli.results`) import these, so no
sub-command module needs `paintcell.cli.main` (which imports them).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from paintcell.core.errors import PaintcellError

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


def one_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type name when empty)."""
    msg = str(exc).strip().splitlines()
    return msg[0] if msg else type(exc).__name__


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
