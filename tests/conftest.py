"""Fixtures that several test files share.

An expensive run that two files read the same way is a fixture here (package scope: the whole
`tests` package, so one run a pytest run), made once and only read by the tests that take it.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers import run_door_fast


@pytest.fixture(scope="package")
def door_fast(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The results folder of `paintcell run scenarios/door.toml --fast` (one run a pytest run,
    read by the report tests of test_report_browser.py and test_film_view.py; none writes into
    it)."""
    return run_door_fast(tmp_path_factory.mktemp("door_fast"))
