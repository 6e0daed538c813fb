"""TOML and JSON text read as data, with one-line errors for what a parser answers badly.

A parser recurses once per nesting level, so `a = [[[[…]]]]` a few thousand deep (or a
`metrics.json` written that way) ends in RecursionError instead of an error naming the file;
a UTF-8 byte-order mark (Windows editors write one) is not TOML; non-UTF-8 bytes come back as a
codec's message without the file. These readers strip the mark (a TOML file's text comes from
`paintcell.core.toml_text`), name the file in every error, and refuse data nested deeper than
`MAX_DEPTH` (no paintcell file nests more than 4 levels).
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

from paintcell.core.errors import PaintcellError
from paintcell.core.toml_text import toml_text

__all__ = ["MAX_DEPTH", "DataTextError", "check_depth", "parse_json", "parse_toml", "read_toml"]

#: Deepest nesting of tables and arrays accepted (a scenario nests 3 levels: [sweep.limits]).
MAX_DEPTH = 32
_BOM = "\ufeff"


class DataTextError(PaintcellError):
    """A TOML or JSON file cannot be read as data."""


def check_depth(obj: Any, where: str, max_depth: int = MAX_DEPTH) -> None:
    """Refuse data nested deeper than `max_depth` tables/arrays (iterative: no recursion)."""
    stack: list[tuple[Any, int]] = [(obj, 0)]
    while stack:
        x, depth = stack.pop()
        if isinstance(x, dict | list | tuple):
            if depth >= max_depth:
                raise DataTextError(f"{where} nests tables or arrays more than {max_depth} "
                                    "levels deep; no paintcell file does, check the file")
            stack.extend((v, depth + 1) for v in (x.values() if isinstance(x, dict) else x))


def _nesting_guard(text: str, where: str, max_depth: int) -> None:
    """Refuse text whose brackets open deeper than the parsers recurse, before parsing (counts
    every `[`/`{` — in strings too, so it over-counts, which only matters beyond `max_depth`)."""
    depth = peak = 0
    for ch in text:
        if ch in "[{":
            depth += 1
            peak = max(peak, depth)
        elif ch in "]}":
            depth = max(0, depth - 1)
    if peak > 8 * max_depth:     # far past any real file; a parser would recurse this deep
        raise DataTextError(f"{where} nests brackets {peak} levels deep; no paintcell file "
                            f"nests more than {max_depth}, check the file")


def parse_toml(text: str, where: str) -> dict[str, Any]:
    """A TOML document's table; errors name `where` (the file)."""
    text = text.removeprefix(_BOM)
    _nesting_guard(text, where, MAX_DEPTH)
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DataTextError(f"{where}: not valid TOML ({exc}); fix the line named") from exc
    except RecursionError:
        raise DataTextError(f"{where} nests tables or arrays too deep to read; check the "
                            "file") from None
    check_depth(d, where)
    return d


def read_toml(path: str | Path) -> dict[str, Any]:
    """The table of a TOML file (UTF-8, an optional byte-order mark); one-line errors."""
    return parse_toml(toml_text(path, DataTextError), str(Path(path)))


def parse_json(text: str, where: str) -> Any:
    """A JSON document's value; errors name `where` (the file)."""
    text = text.removeprefix(_BOM)
    _nesting_guard(text, where, MAX_DEPTH)
    try:
        d = json.loads(text)
    except RecursionError:
        raise DataTextError(f"{where} nests objects or arrays too deep to read; check the "
                            "file") from None
    except ValueError as exc:
        lines = str(exc).strip().splitlines()
        raise DataTextError(f"{where} is not valid JSON ({lines[0] if lines else 'empty'})") \
            from exc
    check_depth(d, where)
    return d
