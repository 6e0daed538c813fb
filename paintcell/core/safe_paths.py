"""Which paths paintcell may write or read: a regular file or nothing, never through a link.

A path paintcell writes (results, scenarios, meshes, pictures, modules, locks) must be absent or
a regular file: a symbolic link is refused (the write would land on its target), and so are
device nodes, FIFOs, sockets and folders (replacing a device node with a file breaks the system;
opening a FIFO blocks until someone opens its other end). Reads of results-folder files open with
`O_NOFOLLOW | O_NONBLOCK` and check the opened file, so a link or FIFO planted in a folder is
refused at once instead of followed or waited on.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from paintcell.core.errors import PaintcellError

__all__ = ["UnsafePathError", "check_new_target", "check_write_target", "kind_of",
           "read_regular_bytes"]


class UnsafePathError(PaintcellError):
    """A path is a link, device, FIFO, socket or folder where paintcell needs a regular file."""


def kind_of(mode: int) -> str:
    """A word for the file type of `st_mode` ("symbolic link", "FIFO", "device node", ...)."""
    if stat.S_ISLNK(mode):
        return "symbolic link"
    if stat.S_ISFIFO(mode):
        return "FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "device node"
    if stat.S_ISSOCK(mode):
        return "socket"
    if stat.S_ISDIR(mode):
        return "folder"
    return "regular file" if stat.S_ISREG(mode) else "special file"


def check_write_target(path: str | os.PathLike[str], what: str = "") -> bool:
    """Refuse to write `path` unless it is absent or a regular file (links never followed).

    what: how the message names the path (e.g. "--out"); default: the path alone.
    Returns True when a regular file is there, False when nothing is.
    """
    p = Path(path)
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        return False
    if stat.S_ISREG(st.st_mode):
        return True
    label = f"{what} {p}" if what else str(p)
    raise UnsafePathError(f"{label} is a {kind_of(st.st_mode)}, not a regular file; paintcell "
                          "writes only new or regular files (never through a link or onto a "
                          "device or FIFO) — remove it or choose another path")


def check_new_target(path: str | os.PathLike[str], what: str, force: bool) -> None:
    """Refuse `path` unless it is absent, or a regular file and `force` (`init`, `generate` and
    `export --out` replace a user's file only when asked to)."""
    if check_write_target(path, what) and not force:
        raise UnsafePathError(f"{what} {path} exists; pass --force to replace it, or choose "
                              "another file")


def read_regular_bytes(path: str | os.PathLike[str], limit_bytes: int | None = None,
                       head_bytes: int | None = None) -> bytes:
    """The bytes of regular file `path`, opened without following a link or waiting on a FIFO.

    head_bytes: read only the first this many bytes (a magic number). Raises FileNotFoundError
    when it is absent, UnsafePathError when it is not a regular file or is larger than
    `limit_bytes`.
    """
    p = Path(path)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise UnsafePathError(f"{p} is a symbolic link; paintcell reads only the regular "
                                  "files it wrote there — remove the link") from None
        raise
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise UnsafePathError(f"{p} is a {kind_of(st.st_mode)}, not a regular file; remove "
                                  "it")
        if limit_bytes is not None and st.st_size > limit_bytes:
            raise UnsafePathError(f"{p} is {st.st_size} bytes, more than the {limit_bytes} "
                                  "expected; replace it with the file paintcell wrote")
        if head_bytes is not None:
            return os.read(fd, head_bytes)
        chunks = []
        while chunk := os.read(fd, 1 << 20):
            chunks.append(chunk)
        return b"".join(chunks)
    finally:
        os.close(fd)
