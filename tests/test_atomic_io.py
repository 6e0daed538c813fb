"""Atomic writes: no half-written file on error, ordinary permissions on success."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from paintcell.core.atomic_io import atomic_path, atomic_write_npz, atomic_write_text


def test_failed_write_leaves_no_file(tmp_path: Path) -> None:
    target = tmp_path / "out.png"
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_bytes(b"partial")
        raise RuntimeError("writer crashed")
    assert not target.exists() and list(tmp_path.iterdir()) == []


def test_existing_file_survives_a_failed_rewrite(tmp_path: Path) -> None:
    target = tmp_path / "metrics.json"
    atomic_write_text(target, "old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("new but incomplete")
        raise RuntimeError("writer crashed")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["metrics.json"]


def test_files_get_umask_permissions_not_0600(tmp_path: Path) -> None:
    mask = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "a.txt", "x")
        atomic_write_npz(tmp_path / "a.npz", {"x": np.zeros(2)})
        with atomic_path(tmp_path / "a.png") as tmp:
            tmp.write_bytes(b"png")
    finally:
        os.umask(mask)
    for name in ("a.txt", "a.npz", "a.png"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o644
