"""The checks every scenario's settings tables pass, from whichever source it comes (TOML file,
Python script, results-folder snapshot): each table builds its settings class.

A typo'd setting would run with its default, so it is refused in one line naming where (file,
table) and what is valid (the thresholds' ranges: `paintcell.validation.validate_report`).
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

from paintcell.core.errors import PaintcellError, ScenarioDataError
from paintcell.core.settings import check_types

__all__ = ["SETTINGS_TABLES", "SETTING_RANGES", "check_settings", "settings_classes"]

SETTINGS_TABLES = ("planner", "fast_planner", "trajectory", "servo", "disturbances")


#: Ranges the settings classes do not check themselves, both bounds excluded:
#: (table, key) → (low, high, what).
SETTING_RANGES: dict[tuple[str, str], tuple[float, float, str]] = {
    ("planner", "u_max"): (0.0, 1.0, "a fraction, 0.04 = 4 %"),
    ("planner", "band_half_width"): (0.0, 10.0, "a fraction of the index width"),
}


def settings_classes() -> dict[str, type]:
    """The class each settings table builds: table name → settings dataclass."""
    from paintcell.coverage.coverage import PlannerSettings
    from paintcell.execution.execute_settings import Disturbances, ServoSettings
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


def check_settings(scn: Any, where: str) -> None:
    """Validate every settings table of a scenario by building its settings class.

    Unknown keys name the valid ones; values must be finite and within the ranges the classes
    (and `SETTING_RANGES`) define. Raises ScenarioDataError naming `where` (the file) and the key.
    """
    classes = settings_classes()
    for table in SETTINGS_TABLES:
        values = getattr(scn, table)
        cls = classes[table]
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ScenarioDataError(f"{where}: unknown {table} setting(s) {unknown}; valid: "
                                    f"{', '.join(sorted(names))}")
        check_types(cls, values, f"{where} [{table}]")
        for key, v in values.items():
            _check_finite(f"{where} [{table}]", key, v)
            rng = SETTING_RANGES.get(("planner" if table == "fast_planner" else table, key))
            if rng is not None and isinstance(v, int | float) and not isinstance(v, bool) \
                    and not rng[0] < v < rng[1]:
                raise ScenarioDataError(f"{where} [{table}]: {key} = {v!r} is out of range; "
                                        f"valid: {rng[0]:g} < {key} < {rng[1]:g} ({rng[2]})")
        kw = {**scn.planner, **values} if table == "fast_planner" else values
        try:
            cls(**kw)
        except PaintcellError as exc:
            raise ScenarioDataError(f"{where} [{table}]: {exc}") from exc
        except (TypeError, ValueError) as exc:
            raise ScenarioDataError(f"{where} [{table}]: {exc}") from exc


