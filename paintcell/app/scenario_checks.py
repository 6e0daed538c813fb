"""The checks every scenario passes, from whichever source it comes (TOML file, Python script,
results-folder snapshot): thresholds in range and settings tables that build their classes.

A NaN limit would silently remove its check and a typo'd setting would run with its default, so
both are refused in one line naming where (file, table) and what is valid.
"""

from __future__ import annotations

import functools
import math
import numbers
import types
import typing
from dataclasses import fields
from typing import Any

import numpy as np

from paintcell.app.setting_ranges import check_range
from paintcell.core.errors import PaintcellError

__all__ = ["ScenarioDataError", "check_settings", "check_settings_table", "check_thresholds",
           "check_types"]

_SETTINGS = ("planner", "fast_planner", "trajectory", "servo", "disturbances")


# Threshold ranges: (low, high, low inclusive, what it is). +inf disables a `max_*` check.
_THRESHOLD_RANGES: dict[str, tuple[float, float, bool, str]] = {
    "reachability_pct": (0.0, 100.0, True, "a share of poses [%]"),
    "max_collisions": (0.0, math.inf, True, "a count of collision events"),
    "max_executed_nsd_pct": (0.0, math.inf, False, "σ/μ [%]"),
    "max_loss_pp": (0.0, math.inf, True, "percentage points"),
    "max_abs_loss_pp": (0.0, math.inf, True, "percentage points"),
    "max_cycle_time_s": (0.0, math.inf, False, "seconds"),
    "max_tracking_error_mm": (0.0, math.inf, True, "mm"),
    "max_speed_error_pct": (0.0, math.inf, True, "%"),
    "max_torque_utilization": (0.0, math.inf, False, "|τ|/τ_max"),
    "max_joint_range_utilization": (0.0, math.inf, False, "a fraction of the joint range"),
    "tolerance": (0.0, 1.0, False, "a fraction of the mean thickness"),
    # a booth's (paintcell.booth.booth.BoothThresholds)
    "max_robot_collisions": (0.0, math.inf, True, "a count of robot–robot collision events"),
    "max_body_nsd_pct": (0.0, math.inf, False, "σ/μ [%]"),
    "min_bell_distance_m": (0.0, math.inf, True, "a distance [m]"),
}

class ScenarioDataError(PaintcellError):
    """A scenario file or snapshot holds an unknown key or an invalid value."""


def _fmt_range(lo: float, hi: float, lo_incl: bool = True) -> str:
    left = "[" if lo_incl else "("
    right = "]" if math.isfinite(hi) else ")"
    return f"{left}{lo:g}, {hi:g}{right}"


def check_thresholds(th: Any, where: str = "thresholds") -> None:
    """Refuse NaN, −inf, wrong types and out-of-range threshold values (ScenarioDataError).

    A NaN limit would silently remove its check (every comparison with NaN is False), so the gate
    could PASS without checking; `max_collisions = -1` could never pass. None or +inf disables a
    `max_*` check explicitly.
    """
    for f in fields(th):
        v = getattr(th, f.name)
        if v is None and f.name != "tolerance":
            continue
        lo, hi, lo_incl, what = _THRESHOLD_RANGES.get(f.name, (-math.inf, math.inf, True, ""))
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ScenarioDataError(f"{where}: {f.name} = {v!r} must be a number ({what})")
        if math.isnan(v) or v == -math.inf or (v == math.inf and not f.name.startswith("max_")):
            raise ScenarioDataError(f"{where}: {f.name} = {v!r} is not a finite number; valid: "
                                    f"{_fmt_range(lo, hi, lo_incl)} ({what})")
        if v < lo or (v == lo and not lo_incl) or (v > hi and math.isfinite(hi)) \
                or (f.name == "tolerance" and v >= hi):
            raise ScenarioDataError(f"{where}: {f.name} = {v!r} is out of range; valid: "
                                    f"{_fmt_range(lo, hi, lo_incl)} ({what})")
        if f.name in ("max_collisions", "max_robot_collisions") and math.isfinite(v) \
                and v != int(v):
            raise ScenarioDataError(f"{where}: {f.name} = {v!r} must be a whole number")


def _settings_classes() -> dict[str, type]:
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
    (and `paintcell.app.setting_ranges`) define, and the planner's index-width search must fit
    its memory budget (`paintcell.app.budget`). Raises ScenarioDataError (BudgetError for the
    budget) naming `where` (the file), the table and the key.
    """
    for table in _SETTINGS:
        check_settings_table(table, getattr(scn, table), where,
                             scn.planner if table == "fast_planner" else None)


def check_settings_table(table: str, values: dict[str, Any], where: str,
                         base: dict[str, Any] | None = None) -> Any:
    """Validate one settings table (`table` one of planner, fast_planner, trajectory, servo,
    disturbances) and return its settings object: unknown keys, types, finiteness, the ranges
    of `paintcell.app.setting_ranges`, the class's own checks and, for the planner, the width
    search's memory budget. base: the planner a fast_planner table overrides."""
    cls = _settings_classes()[table]
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
    kw = {**(base or {}), **values}
    try:
        built = cls(**kw)
    except PaintcellError as exc:
        raise ScenarioDataError(f"{where} [{table}]: {exc}") from exc
    except (TypeError, ValueError) as exc:
        raise ScenarioDataError(f"{where} [{table}]: {exc}") from exc
    if table in ("planner", "fast_planner"):
        from paintcell.app.budget import check_planner_budget

        check_planner_budget(built, f"{where} [{table}]")
    return built


def _toml(v: Any) -> str:
    """`v` as the user wrote it, for an error line ("the string 'false'", "true", "2.5")."""
    if isinstance(v, str):
        return f"the string {v!r}"
    if isinstance(v, bool | np.bool_):
        return "true" if v else "false"
    if isinstance(v, list | tuple | np.ndarray):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return repr(v)


def _is_real(v: Any) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool | np.bool_)


def _fits(v: Any, t: Any) -> bool:
    if t is type(None):
        return v is None
    if t is bool:
        return isinstance(v, bool | np.bool_)
    if t is int:
        return isinstance(v, numbers.Integral) and not isinstance(v, bool | np.bool_)
    if t is float:
        return _is_real(v)
    if t is str:
        return isinstance(v, str)
    if typing.get_origin(t) in (tuple, list):
        return isinstance(v, list | tuple | np.ndarray) and all(_is_real(x) for x in v)
    return True  # a type these tables do not use: the class checks it


_WHAT = {bool: "true or false", int: "a whole number", float: "a number", str: "a string"}


def _fix(key: str, v: Any, alts: tuple[Any, ...]) -> str:
    """What the user can write instead of `v`."""
    s = v.strip().lower() if isinstance(v, str) else None
    if bool in alts:
        if s in ("false", "no", "off", "0"):
            return f"write {key} = false"
        if s in ("true", "yes", "on", "1"):
            return f"write {key} = true"
        return f"write {key} = true or {key} = false"
    if int in alts and _is_real(v) and float(v).is_integer():
        return f"write {key} = {int(v)}"
    if (float in alts or int in alts) and s is not None:
        try:
            x = float(s)
        except ValueError:
            pass
        else:
            return f"write {key} = {int(x) if int in alts and x.is_integer() else x!r} " \
                   "(no quotes)"
    if any(typing.get_origin(t) in (tuple, list) for t in alts):
        return f"write {key} = [0.0, 1.5, …] (numbers, no quotes)"
    what = " or ".join(_WHAT.get(t, "a value of its type") for t in alts if t is not type(None))
    return f"write {key} as {what}"


@functools.cache
def _field_types(cls: type) -> dict[str, tuple[Any, ...]]:
    """Each field's annotated type as its union alternatives."""
    hints = typing.get_type_hints(cls)
    return {f.name: (typing.get_args(hints[f.name])
                     if isinstance(hints[f.name], types.UnionType)
                     or typing.get_origin(hints[f.name]) is typing.Union else (hints[f.name],))
            for f in fields(cls)}


def check_types(cls: type, values: dict[str, Any], where: str) -> None:
    """Refuse a settings value that is not of its dataclass field's annotated type, in one line.

    TOML keeps types, so `moving_vias = "false"` is a string — truthy, the opposite of what was
    meant. A bool must be a TOML boolean; a float any number but a boolean; an int a whole
    number; a tuple a list of numbers. `where` names the table, e.g. "door.toml [trajectory]".
    """
    types_ = _field_types(cls)
    for key, v in values.items():
        alts = types_.get(key)
        if alts is None or any(_fits(v, t) for t in alts):
            continue
        what = " or ".join(dict.fromkeys(
            "a list of numbers" if typing.get_origin(t) in (tuple, list) else _WHAT.get(t, str(t))
            for t in alts if t is not type(None)))
        raise ScenarioDataError(f"{where} {key} must be {what} (got {_toml(v)}); "
                                f"{_fix(key, v, alts)}")
