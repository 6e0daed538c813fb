"""The checks every scenario's settings tables pass, from whichever source it comes (TOML file,
Python script, results-folder snapshot): each table builds its settings class, every number in
its range (`paintcell.validation.settings_tables`).

A typo'd setting would run with its default, so it is refused in one line naming where (file,
table) and what is valid (the thresholds' ranges: `paintcell.validation.validate_report`).
"""

from __future__ import annotations

from typing import Any

from paintcell.validation.settings_tables import (
    SETTINGS_TABLES,
    check_settings_table,
    settings_classes,
)

__all__ = ["check_settings"]

_settings_classes = settings_classes     # tests/test_scenario_checks.py reads the classes here


def check_settings(scn: Any, where: str) -> None:
    """Validate every settings table of a scenario by building its settings class.

    Unknown keys name the valid ones; values must be finite and within the ranges the classes
    (and `paintcell.core.setting_ranges`) define, and the planner's index-width search must fit
    its memory budget (`paintcell.core.budget`). Raises ScenarioDataError (BudgetError for the
    budget) naming `where` (the file), the table and the key.
    """
    for table in SETTINGS_TABLES:
        check_settings_table(table, getattr(scn, table), where,
                             scn.planner if table == "fast_planner" else None)
