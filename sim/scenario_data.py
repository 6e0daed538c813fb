"""Scenarios as data: the TOML scenario format, the results-folder snapshot, and validation.

A TOML scenario maps one-to-one onto `sim.scenario.Scenario` (docs/interfaces.md):

    name = "door"                      # results-folder name (default: the file's stem)
    part = "door"                      # library part, mesh path, or a [part] table
    robot = "abb_paint"
    resolution_m = 0.01
    fast_resolution_m = 0.025
    applicator = "bells/my_bell.toml"  # optional
    [part_placement]  xyz_m = [..], rpy_rad = [..]
    [base]            xyz_m = [..], rpy_rad = [..]
    [planner] [fast_planner] [trajectory] [servo] [disturbances] [thresholds]

Relative paths are relative to the scenario file. Every key is checked on load: unknown names,
non-finite numbers and values out of range are refused with one line naming the file, the key and
what is valid. The same reader turns a results folder's `scenario.json` snapshot back into a
`Scenario`, so `validate`, `export` and `report` never execute code named in a results folder.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

from planning.errors import PaintcellError

__all__ = ["SNAPSHOT_VERSION", "check_settings", "check_thresholds", "load_toml_scenario",
           "scenario_from_dict", "snapshot_dict"]

#: Version of the `scenario.json` snapshot written into results folders.
SNAPSHOT_VERSION = 1

_SCALARS = ("name", "part", "robot", "resolution_m", "fast_resolution_m", "applicator")
_PLACEMENTS = ("part_placement", "base")
_SETTINGS = ("planner", "fast_planner", "trajectory", "servo", "disturbances")
_TABLES = (*_PLACEMENTS, *_SETTINGS, "thresholds", "sweep")
_KEYS = (*_SCALARS, *_TABLES)

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
}

# Ranges the settings classes do not check themselves: (table, key) → (low, high, what).
_SETTING_RANGES: dict[tuple[str, str], tuple[float, float, str]] = {
    ("planner", "u_max"): (0.0, 1.0, "a fraction, 0.04 = 4 %"),
    ("planner", "band_half_width"): (0.0, 10.0, "a fraction of the index width"),
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
        if f.name == "max_collisions" and math.isfinite(v) and v != int(v):
            raise ScenarioDataError(f"{where}: max_collisions = {v!r} must be a whole number")


def _settings_classes() -> dict[str, type]:
    from planning.coverage import PlannerSettings
    from sim.execute import Disturbances, ServoSettings
    from sim.trajectory import TrajectorySettings

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
    (and `_SETTING_RANGES`) define. Raises ScenarioDataError naming `where` (the file) and the key.
    """
    classes = _settings_classes()
    for table in _SETTINGS:
        values = getattr(scn, table)
        cls = classes[table]
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ScenarioDataError(f"{where}: unknown {table} setting(s) {unknown}; valid: "
                                    f"{', '.join(sorted(names))}")
        for key, v in values.items():
            _check_finite(f"{where} [{table}]", key, v)
            rng = _SETTING_RANGES.get(("planner" if table == "fast_planner" else table, key))
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


def _tuples(v: Any) -> Any:
    """Lists (TOML/JSON arrays) as tuples, recursively (settings classes are frozen)."""
    if isinstance(v, list | tuple):
        return tuple(_tuples(x) for x in v)
    return v


def scenario_from_dict(d: dict[str, Any], where: str, base_dir: Path | None = None,
                       source: str | None = None) -> Any:
    """A validated `Scenario` from a TOML table or a snapshot dict.

    where: the file, named in every error. base_dir: folder that relative paths (a mesh part,
    `[part] file`, `applicator`) are resolved against (None: keep them as written).
    """
    from sim.scenario import Placement, Scenario, Thresholds

    if not isinstance(d, dict):
        raise ScenarioDataError(f"{where}: a scenario must be a table of keys")
    unknown = sorted(set(d) - set(_KEYS))
    if unknown:
        raise ScenarioDataError(f"{where}: unknown key(s) {unknown}; valid: {', '.join(_KEYS)}")
    if "part" not in d:
        raise ScenarioDataError(f"{where}: no part; add part = \"door\" (a library part), a mesh "
                                "path, or a [part] table")
    if "part_placement" not in d:
        raise ScenarioDataError(f"{where}: no [part_placement]; add xyz_m = [x, y, z] and "
                                "rpy_rad = [r, p, y] for the part frame in the world")
    kw: dict[str, Any] = {}
    for key in _SCALARS:
        if key in d:
            kw[key] = d[key]
    for key in ("name", "robot"):
        if key in kw and not isinstance(kw[key], str):
            raise ScenarioDataError(f"{where}: {key} = {kw[key]!r} must be a string")
    for key in ("resolution_m", "fast_resolution_m"):
        v = kw.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)
                              or not math.isfinite(v) or not 0.0005 <= v <= 0.5):
            raise ScenarioDataError(f"{where}: {key} = {v!r} is out of range; valid: "
                                    "[0.0005, 0.5] m")
    if isinstance(kw.get("part"), dict):
        kw["part"] = dict(kw["part"])
        if base_dir is not None and isinstance(kw["part"].get("file"), str):
            kw["part"]["file"] = str((base_dir / kw["part"]["file"]).resolve())
    elif not isinstance(kw.get("part"), str):
        raise ScenarioDataError(f"{where}: part = {kw.get('part')!r} must be a part name, a mesh "
                                "path or a [part] table")
    elif base_dir is not None and _is_path(kw["part"]):
        kw["part"] = str((base_dir / kw["part"]).resolve())
    if kw.get("applicator") is not None:
        if not isinstance(kw["applicator"], str):
            raise ScenarioDataError(f"{where}: applicator = {kw['applicator']!r} must be a path "
                                    "to an applicator TOML file")
        if base_dir is not None:
            kw["applicator"] = str((base_dir / kw["applicator"]).resolve())
    for key in _PLACEMENTS:
        if key not in d:
            continue
        t = d[key]
        bad = sorted(set(t) - {"xyz_m", "rpy_rad"}) if isinstance(t, dict) else ["?"]
        if bad:
            raise ScenarioDataError(f"{where}: [{key}] unknown key(s) {bad}; valid: xyz_m, rpy_rad")
        try:
            kw[key] = Placement(**{k: tuple(v) for k, v in t.items()})
        except (PaintcellError, TypeError) as exc:
            raise ScenarioDataError(f"{where}: [{key}] {exc}") from exc
    for key in _SETTINGS:
        t = d.get(key, {})
        if not isinstance(t, dict):
            raise ScenarioDataError(f"{where}: {key} must be a table [{key}]")
        kw[key] = {k: _tuples(v) for k, v in t.items()}
    sw = d.get("sweep", {})
    if sw:  # [sweep], [sweep.factors], [sweep.limits]: checked now, not when a sweep starts
        from sim.sweep_spec import SweepError, check_sweep_table

        try:
            check_sweep_table(sw)
        except SweepError as exc:
            raise ScenarioDataError(f"{where}: [sweep] {exc}") from exc
        kw["sweep"] = {k: dict(v) if isinstance(v, dict) else v for k, v in sw.items()}
    th = d.get("thresholds", {})
    if not isinstance(th, dict):
        raise ScenarioDataError(f"{where}: thresholds must be a table [thresholds]")
    names = {f.name for f in fields(Thresholds)}
    unknown = sorted(set(th) - names)
    if unknown:
        raise ScenarioDataError(f"{where}: unknown [thresholds] key(s) {unknown}; valid: "
                                f"{', '.join(sorted(names))}")
    try:
        thresholds = Thresholds.__new__(Thresholds)
        # Range-check before Thresholds' own checks so the message names the file and range.
        for f in fields(Thresholds):
            object.__setattr__(thresholds, f.name, th.get(f.name, f.default))
        check_thresholds(thresholds, f"{where} [thresholds]")
        kw["thresholds"] = Thresholds(**th)
        kw["source"] = source
        scn = Scenario(**kw)
    except ScenarioDataError:
        raise
    except (PaintcellError, TypeError, ValueError) as exc:
        raise ScenarioDataError(f"{where}: {exc}") from exc
    check_settings(scn, where)
    return scn


def _is_path(part: str) -> bool:
    from planning.parts import PART_NAMES

    return part not in PART_NAMES


def load_toml_scenario(path: str | Path) -> Any:
    """Read a TOML scenario file (no code runs); relative paths are relative to the file."""
    path = Path(path)
    try:
        d = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioDataError(f"{path}: not valid TOML ({exc}); fix the line named") from exc
    except UnicodeDecodeError as exc:
        raise ScenarioDataError(f"{path}: not a UTF-8 text file ({exc.reason})") from exc
    d.setdefault("name", path.stem)
    return scenario_from_dict(d, str(path), base_dir=path.resolve().parent,
                              source=str(path.resolve()))


def snapshot_dict(scn: Any) -> dict[str, Any]:
    """The scenario as JSON-safe data for a results folder (paths already absolute)."""
    d = scn.to_dict()
    d["snapshot_version"] = SNAPSHOT_VERSION
    return d


def scenario_from_snapshot(d: Any, where: str) -> Any:
    """The `Scenario` recorded in a results folder's `scenario.json` (never imports its source)."""
    if not isinstance(d, dict) or d.get("snapshot_version") != SNAPSHOT_VERSION:
        raise ScenarioDataError(f"{where} holds no scenario snapshot of this paintcell version "
                                f"(snapshot_version {SNAPSHOT_VERSION}); re-run `paintcell run`")
    body = {k: v for k, v in d.items() if k in _KEYS}
    scn = scenario_from_dict(body, where, base_dir=None, source=d.get("source"))
    return replace(scn, source=d.get("source"))
