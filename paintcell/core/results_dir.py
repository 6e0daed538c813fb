"""The results-folder contract: ownership marker, one writer at a time, atomic replacement.

Every paintcell command that writes into a results folder goes through this module:

- **Ownership.** A folder is paintcell's only if it holds the marker file `.paintcell-results`
  (JSON: run id, command, time, the files paintcell wrote). `run` and `plan` replace a folder only
  when it is missing, empty, or marked and holding no file paintcell did not write; anything else
  is refused and left untouched. `validate`, `export` and `report` write only into marked folders.
- **One writer.** A writer holds an exclusive `flock` on `.NAME.lock` beside the folder (beside,
  not inside, because the folder itself is swapped); a second writer is refused at once with one
  line naming the holder. The kernel drops the lock when the holder dies, even by SIGKILL.
- **Atomic replacement.** `run`/`plan` build the new folder as the hidden sibling
  `.NAME.tmp-PID-RANDOM`, then swap it in with `renameat2(RENAME_EXCHANGE)` (Linux ≥ 3.15; ext4,
  xfs, btrfs, tmpfs): the two directory entries trade places in one step, so `NAME` is never
  missing and always a real folder (a symlink flip would also be atomic but would turn the user's
  results folder into a link and leave versioned folders beside it). Where the exchange is not
  supported the old folder is renamed aside and the new one renamed in (a moment without `NAME`).
  Single files are written by temp file + `os.replace`.
- **Leftovers.** The lock file records its holder ("paintcell run (pid PID, …)"); a holder that
  ends normally removes it, so a lock file found with a record means its writer was killed. The
  next writer removes exactly what that record owns: the hidden siblings `.NAME.tmp-PID-*` /
  `.NAME.old-PID-*` and, inside a marked folder, the temp files `.FILE.tmp-PID-*` of in-place
  writes (`paintcell.core.atomic_io.TEMP_NAME`) of files the marker lists. Nothing else is
  removed: a user's `.metrics.json.bak` survives.
- **No write through a link.** The lock file and the marker are opened with `O_NOFOLLOW` and
  only when they are regular files or absent (`paintcell.core.safe_paths`).
"""

from __future__ import annotations

import ctypes
import errno
import fcntl
import json
import os
import re
import secrets
import shutil
import stat
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from paintcell.core.atomic_io import TEMP_NAME, atomic_write_text
from paintcell.core.errors import PaintcellError
from paintcell.core.interrupts import raise_if_interrupted
from paintcell.core.safe_paths import kind_of, read_regular_bytes

__all__ = ["MARKER", "ResultsDirError", "exchange_dirs", "lock_results", "marker_files",
           "new_results", "note_files", "read_marker", "require_results"]

MARKER = ".paintcell-results"
_LEFTOVER = re.compile(r"^\.(?P<name>.+)\.(?:tmp|old)-(?P<pid>\d+)-[0-9a-f]+$")
_HOLDER_PID = re.compile(rb"\(pid (\d+)")
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


class ResultsDirError(PaintcellError):
    """A folder is not paintcell's, is busy, or cannot be replaced safely."""


def read_marker(d: Path) -> dict[str, Any] | None:
    """The ownership marker of folder `d` (None when there is none, it is unreadable, or it is
    not a regular file: a linked marker is never believed)."""
    try:
        m = json.loads(read_regular_bytes(Path(d) / MARKER, limit_bytes=16 << 20))
    except (OSError, ValueError, RecursionError, PaintcellError):
        return None
    return m if isinstance(m, dict) and isinstance(m.get("run_id"), str) else None


def marker_files(marker: dict[str, Any]) -> set[str]:
    """The file names (relative to the folder) a marker records as paintcell's."""
    files = marker.get("files")
    return {f for f in files if isinstance(f, str)} if isinstance(files, list) else set()


def _stale_pid(record: bytes) -> int | None:
    """The PID a lock file's record names (None: no record, or not a paintcell record)."""
    m = _HOLDER_PID.search(record)
    return int(m.group(1)) if m else None


def _clean_leftovers(out: Path, pid: int | None) -> list[Path]:
    """Remove what the killed writer `pid` (the stale lock's record) left of results folder
    `out`: its hidden sibling folders and, inside a marked folder, its temp files of files the
    marker lists. Nothing whose name does not carry `pid` is touched."""
    removed: list[Path] = []
    if pid is None or pid == os.getpid() or not out.parent.is_dir():
        return removed
    for p in out.parent.iterdir():
        m = _LEFTOVER.match(p.name)
        if m is None or m["name"] != out.name or int(m["pid"]) != pid:
            continue
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)
        removed.append(p)
    marker = read_marker(out) if out.is_dir() and not out.is_symlink() else None
    if marker is not None:
        known = marker_files(marker) | {MARKER}
        known |= {Path(k).stem for k in known}
        for p in out.iterdir():
            m = TEMP_NAME.match(p.name)
            if m is None or int(m["pid"]) != pid or m["base"] not in known:
                continue
            if p.is_symlink() or p.is_file():
                p.unlink(missing_ok=True)
                removed.append(p)
    return removed


def _open_lock(lock_path: Path, out: Path) -> int:
    """Open (create) the lock file without following a link; refuse anything but a regular
    file."""
    try:
        st = os.lstat(lock_path)
    except FileNotFoundError:
        st = None
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise ResultsDirError(f"the lock file {lock_path} of {out} is a {kind_of(st.st_mode)}, "
                              "not a regular file; paintcell never writes through it — remove "
                              "it and run again")
    try:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK
                     | os.O_CLOEXEC, 0o666)
    except OSError as exc:
        if exc.errno != errno.ELOOP:
            raise
        raise ResultsDirError(f"the lock file {lock_path} of {out} is a symbolic link; "
                              "paintcell never writes through it — remove it and run again") \
            from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        kind = kind_of(os.fstat(fd).st_mode)
        os.close(fd)
        raise ResultsDirError(f"the lock file {lock_path} of {out} is a {kind}, not a regular "
                              "file; remove it and run again")
    return fd


@contextmanager
def lock_results(out: Path, command: str) -> Iterator[None]:
    """Hold the exclusive writer lock of results folder `out` (refuse at once if held).

    The lock file is removed on release while still locked; a writer that locked a file which
    was meanwhile unlinked (inode no longer at the path) retries, so two writers can never hold
    two different lock files of one folder. A SIGKILLed holder leaves the file; the kernel drops
    its lock, and the next writer takes and removes it.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    lock_path = out.parent / f".{out.name}.lock"
    while True:
        fd = _open_lock(lock_path, out)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = "".join(c if c.isprintable() else " " for c in os.pread(fd, 200, 0).decode(
                errors="replace")).strip() or "another process"
            os.close(fd)
            if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                raise
            raise ResultsDirError(f"{out} is being written by {holder}; wait for it to finish "
                                  "or choose another --out") from None
        try:
            same = os.stat(lock_path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        stale = _stale_pid(os.pread(fd, 4096, 0))  # a record left means its writer was killed
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"paintcell {command} (pid {os.getpid()}, since "
                      f"{time.strftime('%H:%M:%S')})".encode(), 0)
        _clean_leftovers(out, stale)
        yield
    finally:
        lock_path.unlink(missing_ok=True)
        os.close(fd)  # releases the flock


def _check_replaceable(out: Path) -> None:
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise ResultsDirError(f"--out {out} is a file or link, not a folder; give a folder for "
                              "the results")
    if not out.exists():
        return
    entries = {p.name for p in out.iterdir()}
    if not entries:
        return
    marker = read_marker(out)
    if marker is None:
        raise ResultsDirError(f"--out {out} exists and is not a paintcell results folder (no "
                              f"{MARKER} marker; results of paintcell before this marker lack "
                              "it too); choose another folder, or empty or delete it yourself")
    foreign = sorted(entries - marker_files(marker) - {MARKER})
    if foreign:
        shown = ", ".join(foreign[:3]) + (" …" if len(foreign) > 3 else "")
        raise ResultsDirError(f"--out {out} holds files paintcell did not write ({shown}); move "
                              "them out or choose another --out")


def _libc() -> Any:
    try:
        return ctypes.CDLL(None, use_errno=True)
    except OSError:
        return None


def exchange_dirs(a: Path, b: Path) -> bool:
    """Atomically swap directory entries `a` and `b` (renameat2 RENAME_EXCHANGE).

    Returns False when the platform or filesystem does not support it (nothing changed).
    """
    libc = _libc()
    fn = getattr(libc, "renameat2", None) if libc is not None else None
    if fn is None:
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    rc = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(err, f"cannot swap {a} and {b}: {os.strerror(err)}")


def _files_of(d: Path) -> list[str]:
    return sorted(str(p.relative_to(d)) for p in d.rglob("*") if p.name != MARKER)


@contextmanager
def new_results(out: Path | None, command: str) -> Iterator[Path | None]:
    """Yield a fresh hidden folder that atomically replaces `out` when the block succeeds.

    Takes the writer lock, refuses a folder that is not paintcell's, cleans leftovers of killed
    writers, writes the ownership marker (new run id, the files written) and swaps the folder in.
    On any exception (a KeyboardInterrupt or SIGTERM included) the temp folder is removed and
    `out` is left as it was. `out` None: nothing is written (yields None).
    """
    if out is None:
        yield None
        return
    out = Path(out)
    with lock_results(out, command):
        _check_replaceable(out)
        tmp = out.parent / f".{out.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}"
        tmp.mkdir()
        try:
            yield tmp
            raise_if_interrupted()  # a signal a library swallowed: keep the old results
            atomic_write_text(tmp / MARKER, json.dumps({
                "run_id": uuid.uuid4().hex, "command": command,
                "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "files": _files_of(tmp)},
                indent=2))
            if not out.exists():
                tmp.rename(out)
            elif exchange_dirs(tmp, out):
                pass  # `tmp` now holds the previous results
            else:
                old = out.parent / f".{out.name}.old-{os.getpid()}-{secrets.token_hex(4)}"
                out.rename(old)
                tmp.rename(out)
                tmp = old
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)


def require_results(d: Path) -> dict[str, Any]:
    """The marker of results folder `d`; a clear error when `d` is missing or not paintcell's."""
    d = Path(d)
    if not d.is_dir():
        raise ResultsDirError(f"results folder {d} does not exist; run `paintcell run` first")
    marker = read_marker(d)
    if marker is None:
        raise ResultsDirError(f"{d} is not a paintcell results folder (no {MARKER} marker); "
                              "give a folder written by `paintcell run`")
    return marker


def note_files(d: Path, names: list[str]) -> None:
    """Record files written into results folder `d` in place (`validate`, `export`, `report`),
    so a later `run` may replace them. Call while holding the lock."""
    marker = require_results(d)
    files = sorted(marker_files(marker) | set(names))
    if files != marker.get("files"):
        atomic_write_text(d / MARKER, json.dumps({**marker, "files": files}, indent=2))
