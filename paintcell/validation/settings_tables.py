"""One settings table of a scenario or booth (`[planner]`, `[fast_planner]`, `[trajectory]`,
`[servo]`, `[disturbances]`, a booth part's `[parts.planner]`) checked when it is loaded:
unknown keys, types, finiteness, the range of every number (`paintcell.core.setting_ranges`),
the settings class's own checks, and for the planner the memory of its index-width search
(`paintcell.core.budget.check_planner_budget`). Each refusal is one line naming the file, the
table, the key and what is valid.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

from paintcell.core.errors import PaintcellError, ScenarioDataError
from paintcell.core.setting_ranges import check_range
from paintcell.core.settings import check_types

__all__ = ["SETTINGS_TABLES", "check_settings_table", "settings_classes"]

SETTINGS_TABLES = ("planner", "fast_planner", "trajectory", "servo", "disturbances")


def settings_classes() -> dict[str, type]:
    """The settings dataclass each table builds."""
    from paintcell.coverage.coverage_settings import PlannerSettings
    from paintcell.execution.execute import Disturbances, ServoSettings
    from paintcell.motion.trajectory import TrajectorySettings

    return {"planner": PlannerSettings, "fast_planner": PlannerSettings,
            "trajectory": TrajectorySettings, "servo": ServoSettings,
            "disturbances": Disturbances}


def _check_finite(where: str, key: str, v: Any) -> None:
    if isinstance(v, float) and not math.isfinite(v) and not (v == math.inf and
                                                              key.startswith("turnaround")):
        raise ScenarioDataError(f"{where}: {key} = {v!r} is not a finite number")
    if isinstance(v, list | tuple):
        for x in v:
            _check_finite(where, key, x)


def check_settings_table(table: str, values: Any, where: str,
                         base: dict[str, Any] | None = None,
                         footprint_radius_m: float | None = None) -> Any:
    """The settings object of `[table]` (values: its keys), checked (module doc); `where` names
    the file. base: the planner a fast_planner table overrides. footprint_radius_m: the
    applicator's, for the planner's budget (None: the default bell's)."""
    cls = settings_classes()[table]
    if not isinstance(values, dict):
        raise ScenarioDataError(f"{where}: {table} must be a table [{table}] of settings")
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - names)
    if unknown:
        raise ScenarioDataError(f"{where}: unknown {table} setting(s) {unknown}; valid: "
                                f"{', '.join(sorted(names))}")
    check_types(cls, values, f"{where} [{table}]")
    for key, v in values.items():
        _check_finite(f"{where} [{table}]", key, v)
        bad = check_range(table, key, v)
        if bad is not None:
            raise ScenarioDataError(f"{where} [{table}]: {bad}")
    try:
        built = cls(**{**(base or {}), **values})
    except PaintcellError as exc:
        raise ScenarioDataError(f"{where} [{table}]: {exc}") from exc
    except (TypeError, ValueError) as exc:
        raise ScenarioDataError(f"{where} [{table}]: {exc}") from exc
    if table in ("planner", "fast_planner"):
        from paintcell.core.budget import check_planner_budget
        from paintcell.coverage.index_width import DEFAULT_FOOTPRINT_M, search_size

        check_planner_budget(search_size(built, footprint_radius_m or DEFAULT_FOOTPRINT_M),
                             f"{where} [{table}]")
    return built
