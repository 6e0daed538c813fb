"""Fixtures shared by several test modules."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def door_fast(tmp_path_factory) -> Path:
    """The results folder of `paintcell run scenarios/door.toml --fast` (one run per session)."""
    out = tmp_path_factory.mktemp("door_fast") / "door"
    proc = subprocess.run([sys.executable, "-m", "paintcell", "run", "scenarios/door.toml",
                           "--fast", "--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                          timeout=1200, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode in (0, 1), proc.stderr[-3000:]
    return out
