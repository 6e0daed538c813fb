"""Atomic file writes: a temp file in the target folder, then a rename (never half-written).

The target must be absent or a regular file (`paintcell.core.safe_paths.check_write_target`):
a link, device node, FIFO or folder there is refused before anything is written. The temp file is
created with `O_EXCL | O_NOFOLLOW` (`tempfile.mkstemp`) and named `.NAME.tmp-PID-RANDOM[.SUFFIX]`,
so the next writer of a results folder can tell a killed writer's temp file (its PID is the one
the stale lock records, `paintcell.core.results_dir`) from a user's file of a similar name.
"""

from __future__ import annotations

import os
import re
import tempfile
import zipfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np

from paintcell.core.safe_paths import check_write_target

#: A temp file of `atomic_*`: base name, writer PID, mkstemp's random part, optional suffix.
TEMP_NAME = re.compile(
    r"^\.(?P<base>.+)\.tmp-(?P<pid>\d+)-[a-z0-9_]{8}(?P<suffix>\.[A-Za-z0-9]+)?$")


def _umask_mode() -> int:
    """File mode a plain `open(path, "w")` would give (mkstemp makes 0600 files)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def _name_path(exc: BaseException, path: Path, tmp: str | None = None) -> None:
    """An OS error of a write names no file (ENOSPC from `write`) or the temporary file the user
    never named: name the target."""
    # only an error the OS raised (errno set): a bare OSError("…") would lose its message to
    # "[Errno None] None: path" once it carries a file name
    if isinstance(exc, OSError) and exc.errno is not None and exc.filename in (None, tmp):
        exc.filename = str(path)


def _temp(path: Path, base: str, suffix: str) -> tuple[int, str]:
    check_write_target(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        return tempfile.mkstemp(dir=path.parent, prefix=f".{base}.tmp-{os.getpid()}-",
                                suffix=suffix)
    except OSError as exc:
        _name_path(exc, path, exc.filename)   # not the random temporary name it tried
        raise


def _commit(tmp: str, path: Path) -> None:
    os.chmod(tmp, _umask_mode())
    check_write_target(path)  # again: something may have been planted while we wrote
    os.replace(tmp, path)


def _write(path: str | os.PathLike[str], suffix: str, mode: str,
           write: Callable[[IO[Any]], object]) -> None:
    path = Path(path)
    fd, tmp = _temp(path, path.name, suffix)
    try:
        with os.fdopen(fd, mode) as f:
            write(f)
        _commit(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        _name_path(exc, path, tmp)
        raise


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write text to `path` via a temp file in the same folder and a rename (never half-written)."""
    _write(path, "", "w", lambda f: f.write(text))


#: zlib level of the `.npz` files written: 1 writes a run's traces ~2.7× faster than
#: `numpy.savez_compressed`'s 6 (a 95 MB six-robot trace: 2.5 s against 6.9 s) for files
#: under 1 % larger; `numpy.load` reads either.
NPZ_COMPRESS_LEVEL = 1


def _savez(f: IO[bytes], arrays: dict[str, np.ndarray]) -> None:
    """`numpy.savez_compressed` at `NPZ_COMPRESS_LEVEL`: one `.npy` member per array."""
    with zipfile.ZipFile(f, "w", zipfile.ZIP_DEFLATED, compresslevel=NPZ_COMPRESS_LEVEL) as zf:
        for name, a in arrays.items():
            with zf.open(f"{name}.npy", "w", force_zip64=True) as m:
                np.lib.format.write_array(m, np.asanyarray(a), allow_pickle=False)


def atomic_write_npz(path: str | os.PathLike[str], arrays: dict[str, np.ndarray]) -> None:
    """Write an `.npz` atomically (temp file + rename), deflated at `NPZ_COMPRESS_LEVEL`."""
    _write(path, ".npz", "wb", lambda f: _savez(f, arrays))


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temp path beside `path`; on success rename it to `path`, on error delete it.

    For writers that want a file name (matplotlib's savefig, PIL, mujoco): `with atomic_path(p)
    as tmp: fig.savefig(tmp)`. The temp name keeps the suffix so format detection still works.
    """
    path = Path(path)
    fd, tmp = _temp(path, path.stem, path.suffix)
    os.close(fd)
    try:
        yield Path(tmp)
        _commit(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        _name_path(exc, path, tmp)
        raise
