"""Scenarios as data: the TOML scenario format, the results-folder snapshot, and validation.

A TOML scenario maps one-to-one onto `paintcell.app.scenario.Scenario` (docs/interfaces.md):

    name = "door"                      # results-folder name (default: the file's stem)
    part = "door"                      # library part, mesh path, or a [part] table
    robot = "abb_paint"
    resolution_m = 0.01
    fast_resolution_m = 0.025
    applicator = "bells/my_bell.toml"  # optional
    [part_placement]  xyz_m = [..], rpy_rad = [..]
    [base]            xyz_m = [..], rpy_rad = [..]
    [planner] [fast_planner] [trajectory] [servo] [disturbances] [thresholds]
    [spec]            target_film_um, window_pct, min_inside_pct, max_nsd_pct (the paint spec)

Relative paths are relative to the scenario file. Every key is checked on load: unknown names,
non-finite numbers and values out of range are refused with one line naming the file, the key and
what is valid. The same reader turns a results folder's `scenario.json` snapshot back into a
`Scenario`, so `validate`, `export` and `report` never execute code named in a results folder.
"""

from __future__ import annotations

import math
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

from paintcell.app.scenario_checks import check_settings
from paintcell.app.scenario_keys import LENGTH_RANGE_M, PLACEMENTS, SETTINGS, TABLES, TOP_LEVEL
from paintcell.core.data_text import DataTextError, read_toml
from paintcell.core.errors import PaintcellError, ScenarioDataError
from paintcell.validation.validate_report import check_thresholds

__all__ = ["SNAPSHOT_VERSION", "load_toml_scenario", "scenario_from_dict", "snapshot_dict"]

#: Version of the `scenario.json` snapshot written into results folders.
SNAPSHOT_VERSION = 1

# The keys a scenario accepts (`paintcell.app.scenario_keys`); `part` may also be a table.
_KEYS = tuple(dict.fromkeys((*TOP_LEVEL, *TABLES)))

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
    from paintcell.app.scenario import Scenario
    from paintcell.core.placement import Placement
    from paintcell.validation.validate_report import Thresholds

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
    for key in TOP_LEVEL:
        if key in d:
            kw[key] = d[key]
    for key in ("name", "robot"):
        if key in kw and not isinstance(kw[key], str):
            raise ScenarioDataError(f"{where}: {key} = {kw[key]!r} must be a string")
    from paintcell.robots.catalog import ROBOT_NAMES

    if kw.get("robot", "abb_paint") not in ROBOT_NAMES:
        raise ScenarioDataError(f"{where}: robot = {kw['robot']!r} is not a known robot; valid: "
                                f"{', '.join(ROBOT_NAMES)}")
    for key in ("resolution_m", "fast_resolution_m"):
        v = kw.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)
                              or not math.isfinite(v)
                              or not LENGTH_RANGE_M[0] <= v <= LENGTH_RANGE_M[1]):
            raise ScenarioDataError(f"{where}: {key} = {v!r} is out of range; valid: "
                                    f"[{LENGTH_RANGE_M[0]:g}, {LENGTH_RANGE_M[1]:g}] m")
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
    for key in PLACEMENTS:
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
    for key in SETTINGS:
        t = d.get(key, {})
        if not isinstance(t, dict):
            raise ScenarioDataError(f"{where}: {key} must be a table [{key}]")
        kw[key] = {k: _tuples(v) for k, v in t.items()}
    sw = d.get("sweep", {})
    if sw:  # [sweep], [sweep.factors], [sweep.limits]: checked now, not when a sweep starts
        from paintcell.validation.sweep_spec import SweepError, check_sweep_table

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
        kw["spec"] = _spec(d.get("spec"), where)
        kw["source"] = source
        scn = Scenario(**kw)
    except ScenarioDataError:
        raise
    except (PaintcellError, TypeError, ValueError) as exc:
        raise ScenarioDataError(f"{where}: {exc}") from exc
    check_settings(scn, where)
    return scn


def _spec(table: Any, where: str) -> Any:
    """The `[spec]` table as a PaintSpec (its defaults when absent); errors name the file."""
    from paintcell.validation.paint_spec import PaintSpec, SpecError

    try:
        return PaintSpec.from_table(table, where)
    except SpecError as exc:
        raise ScenarioDataError(str(exc)) from exc


def _is_path(part: str) -> bool:
    from paintcell.surface.parts import PART_NAMES

    return part not in PART_NAMES


def load_toml_scenario(path: str | Path) -> Any:
    """Read a TOML scenario file (no code runs); relative paths are relative to the file."""
    path = Path(path)
    try:
        d = read_toml(path)
    except DataTextError as exc:
        raise ScenarioDataError(str(exc)) from exc
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
