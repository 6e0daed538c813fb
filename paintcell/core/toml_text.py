"""The text of a TOML file: UTF-8, a leading byte-order mark accepted (editors on Windows write
one), anything else refused in one line naming the file, the byte and its line."""

from __future__ import annotations

import codecs
import os
from pathlib import Path

from paintcell.core.errors import PaintcellError

__all__ = ["toml_text"]


def toml_text(path: str | os.PathLike[str],
              error: type[PaintcellError] = PaintcellError) -> str:
    """The decoded text of the TOML file `path` (without a UTF-8 byte-order mark); a file that
    is not UTF-8 raises `error` naming the file, the first bad byte, its line and the fix."""
    raw = Path(path).read_bytes()
    raw = raw.removeprefix(codecs.BOM_UTF8)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise error(f"{path}: not UTF-8 text (byte 0x{raw[exc.start]:02x} on line {line}); save "
                    "the file as UTF-8") from None
