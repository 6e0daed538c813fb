"""The scenario file's keys as data: every table, key, TOML type, default and range it accepts.

`paintcell.app.scenario_data` checks scenario files against this table (the top-level keys, the
required ones, the placements' keys and the top-level lengths' range), and the documentation's
scenario reference is generated from it (docs/tools/gen_reference.py). The settings tables take
their keys, types and defaults from the fields of the classes that check them
(`PlannerSettings`, `TrajectorySettings`, `ServoSettings`, `Disturbances`, `Thresholds`,
`MeshPart`), the thresholds their ranges from `paintcell.validation.validate_report`, and
`[sweep]` its keys from `paintcell.validation.sweep_spec`: one table, the loader's own.
"""

from __future__ import annotations

import types
import typing
from dataclasses import MISSING, Field, dataclass, fields
from typing import Any

from paintcell.validation.settings_tables import SETTINGS_TABLES

__all__ = ["LENGTH_RANGE_M", "ScenarioKey", "TABLES", "TOP_LEVEL", "scenario_keys",
           "table_class", "toml_type"]

#: Valid range of the top-level mesh resolutions `resolution_m` and `fast_resolution_m` [m].
LENGTH_RANGE_M = (0.0005, 0.5)


@dataclass(frozen=True)
class ScenarioKey:
    """One key a scenario file accepts.

    table: the TOML table it belongs to ("" for the top level, "part", "planner", …).
    name: the key.
    kind: its TOML type in words ("number", "integer", "boolean", "string", "array of numbers",
        "table", or several joined by " or ").
    default: the value used when the key is absent, as TOML writes it (None: unset, the
        meaning the key's description gives; `required` keys have none).
    valid: the values the loader accepts, in words ("" where the type is the whole rule and the
        settings class checks the rest).
    low, high, low_closed, high_closed: a numeric range the loader checks, bounds included
        where closed (None: no range checked here).
    required: the loader refuses a scenario without it.
    default_text: the default in words where it is not a value (e.g. "the file's stem").
    doc: one line of meaning for keys that have no settings-class field to describe them.
    owner: the class whose field the key is (its docstring describes the key), or None.
    """

    table: str
    name: str
    kind: str
    default: Any = None
    valid: str = ""
    low: float | None = None
    high: float | None = None
    low_closed: bool = True
    high_closed: bool = True
    required: bool = False
    default_text: str = ""
    doc: str = ""
    owner: type | None = None


#: The top-level scalar keys of a scenario file (the tables follow in `TABLES`).
TOP_LEVEL = ("name", "part", "robot", "resolution_m", "fast_resolution_m", "applicator")

#: The tables of a scenario file, in the order the reference lists them.
TABLES = ("part", "part_placement", "base", "planner", "fast_planner", "trajectory", "servo",
          "disturbances", "thresholds", "spec", "sweep")

#: The tables that hold a placement (`paintcell.core.placement.Placement`).
PLACEMENTS = ("part_placement", "base")

#: The settings tables built into a settings class (checked by `check_settings`).
SETTINGS = SETTINGS_TABLES


def table_class(table: str) -> type | None:
    """The class whose fields are the keys of `table` (None for `sweep` and the top level)."""
    from paintcell.core.placement import Placement
    from paintcell.surface.part_spec import MeshPart
    from paintcell.validation.paint_spec import PaintSpec
    from paintcell.validation.settings_tables import settings_classes
    from paintcell.validation.validate_report import Thresholds

    if table in SETTINGS:
        return settings_classes()[table]
    return {"part": MeshPart, "part_placement": Placement, "base": Placement,
            "thresholds": Thresholds, "spec": PaintSpec}.get(table)


def toml_type(annotation: Any) -> str:
    """A field's annotated type as the TOML type a file writes ("number or string", …)."""
    alts = (typing.get_args(annotation) if isinstance(annotation, types.UnionType)
            or typing.get_origin(annotation) is typing.Union else (annotation,))
    words = []
    for t in alts:
        if t is type(None):
            continue
        if typing.get_origin(t) in (tuple, list):
            inner = {a for a in typing.get_args(t) if a is not Ellipsis}
            words.append("array of strings" if inner == {str} else "array of numbers")
        else:
            words.append({bool: "boolean", int: "integer", float: "number",
                          str: "string"}.get(t, getattr(t, "__name__", str(t))))
    return " or ".join(dict.fromkeys(words))


def _default(f: Field[Any]) -> Any:
    """A field's default (its factory's value for a mutable one); MISSING when it has none."""
    if f.default is not MISSING:
        return f.default
    if f.default_factory is not MISSING:
        return f.default_factory()
    return MISSING


def _toml_value(v: Any) -> Any:
    """A default as TOML holds it: tuples as lists."""
    return [_toml_value(x) for x in v] if isinstance(v, tuple | list) else v


def _top_level() -> list[ScenarioKey]:
    from paintcell.app.scenario import Scenario
    from paintcell.robots.catalog import ROBOT_NAMES

    d = {f.name: f.default for f in fields(Scenario)}
    lo, hi = LENGTH_RANGE_M
    return [
        ScenarioKey("", "name", "string", None, "letters, digits, '_' or '-'",
                    default_text="the file's stem", doc="names the results folder"),
        ScenarioKey("", "part", "string or table", None,
                    "a library part name, a mesh or CAD file path, or a [part] table",
                    required=True,
                    doc="the part to paint; a path is relative to the scenario file"),
        ScenarioKey("", "robot", "string", d["robot"], " | ".join(ROBOT_NAMES),
                    doc="the robot model (`paintcell.robots.catalog.load_robot`)"),
        ScenarioKey("", "resolution_m", "number", d["resolution_m"], "", lo, hi,
                    doc="mesh resolution of a full run [m]"),
        ScenarioKey("", "fast_resolution_m", "number", d["fast_resolution_m"], "", lo, hi,
                    doc="mesh resolution of a `--fast` run [m]"),
        ScenarioKey("", "applicator", "string", None, "a path to an applicator TOML file",
                    doc="the bell (relative to the scenario file); unset: the default bell"),
    ]


def _placement(table: str) -> list[ScenarioKey]:
    from paintcell.core.placement import Placement

    what = {"xyz_m": "position [m]", "rpy_rad": "roll, pitch, yaw about fixed x, y, z [rad]"}
    frame = "the part frame" if table == "part_placement" else "the robot base"
    return [ScenarioKey(table, f.name, "array of numbers", _toml_value(f.default),
                        "three finite numbers",
                        doc=f"{frame} in the world: {what[f.name]}", owner=Placement)
            for f in fields(Placement)]


def _part() -> list[ScenarioKey]:
    from paintcell.surface.part_spec import (
        CAD_SUFFIXES,
        CHORD_TOLERANCE_RANGE_M,
        FILL_HOLES_RANGE_M,
        MESH_SUFFIXES,
        PIECES_GAP_RANGE_M,
        REGIONS,
        UNITS_M,
        MeshPart,
    )

    hints = typing.get_type_hints(MeshPart)
    valid = {"file": "a file ending in " + ", ".join(MESH_SUFFIXES + CAD_SUFFIXES),
             "units": " | ".join((*UNITS_M, "auto")),
             "pieces": "\"auto\" | \"largest\" | \"all\" | an array of piece indices ≥ 0",
             "side": "\"auto\" | three numbers, not all zero",
             "judge": "a non-empty array of " + ", ".join(REGIONS),
             "name": "a non-empty string"}
    ranges = {"chord_tolerance_m": CHORD_TOLERANCE_RANGE_M,
              "fill_holes_m": FILL_HOLES_RANGE_M, "pieces_gap_m": PIECES_GAP_RANGE_M}
    out = []
    for f in fields(MeshPart):
        lo, hi = ranges.get(f.name, (None, None))
        default = _default(f)
        out.append(ScenarioKey("part", f.name, toml_type(hints[f.name]),
                               None if default is MISSING else _toml_value(default),
                               valid.get(f.name, ""), lo, hi, required=default is MISSING,
                               owner=MeshPart))
    return out


def _settings(table: str) -> list[ScenarioKey]:
    from paintcell.core.setting_ranges import RANGES
    from paintcell.validation.validate_report import THRESHOLD_RANGES

    cls = table_class(table)
    assert cls is not None
    hints = typing.get_type_hints(cls)
    out = []
    for f in fields(cls):
        key = ScenarioKey(table, f.name, toml_type(hints[f.name]), _toml_value(_default(f)),
                          owner=cls)
        if table == "thresholds" and f.name in THRESHOLD_RANGES:
            lo, hi, lo_closed, _ = THRESHOLD_RANGES[f.name]
            key = _with_range(key, lo, hi, lo_closed, f.name != "tolerance")
            if f.name.startswith("max_"):
                key = _replace(key, valid="inf: not checked" if key.default is not None
                               else "unset or inf: not checked")
        rng = RANGES.get(("planner" if table == "fast_planner" else table, f.name))
        if rng is not None and f.name != "seed":     # a seed is any 64-bit integer
            key = _ranged(key, table, f.name, rng)
        out.append(key)
    return out


def _spec() -> list[ScenarioKey]:
    from paintcell.validation.paint_spec import SPEC_RANGES, PaintSpec

    hints = typing.get_type_hints(PaintSpec)
    out = []
    for f in fields(PaintSpec):
        lo, hi, what = SPEC_RANGES[f.name]
        out.append(ScenarioKey("spec", f.name, toml_type(hints[f.name]),
                               _toml_value(_default(f)), what, lo, hi, low_closed=False,
                               high_closed=f.name == "min_inside_pct",
                               default_text="the plan's own target film"
                               if f.name == "target_film_um" else "", owner=PaintSpec))
    return out


#: Settings whose range holds together with another key's (v_min ≤ v_nominal ≤ v_max, w_min ≤
#: w_max on multiples of w_res, band_curves odd, the width search's memory): their range is
#: written in words, since a bound alone is not always a valid file.
_COUPLED = {"v_nominal_m_s": "v_min_m_s ≤ v_nominal_m_s ≤ v_max_m_s",
            "v_min_m_s": "v_min_m_s ≤ v_nominal_m_s ≤ v_max_m_s",
            "v_max_m_s": "v_min_m_s ≤ v_nominal_m_s ≤ v_max_m_s",
            "w_min_m": "w_min_m ≤ w_max_m, a multiple of w_res_m between them",
            "w_max_m": "w_min_m ≤ w_max_m, a multiple of w_res_m between them",
            "w_res_m": "a multiple of it between w_min_m and w_max_m",
            "n_future": "future_grid_n^(n_future − 1) widths sets within the memory budget",
            "future_grid_n": "future_grid_n^(n_future − 1) widths sets within the memory budget",
            "band_curves": "odd"}


def _ranged(key: ScenarioKey, table: str, name: str,
            rng: tuple[float, float, str]) -> ScenarioKey:
    """`key` with the range of `paintcell.core.setting_ranges` (both bounds included): as an
    interval where a value at either bound alone is a valid file, else in words."""
    from paintcell.core.setting_ranges import INF_ALLOWED

    lo, hi, what = rng
    listy = key.kind.startswith("array")
    if name in _COUPLED or key.kind == "integer" or listy or (table, name) in INF_ALLOWED:
        words = f"{'each ' if listy else ''}{lo:g} to {hi:g} {what}".replace("inf", "∞")
        extra = _COUPLED.get(name, "")
        return _replace(key, valid="; ".join(x for x in (key.valid, words, extra) if x))
    return _with_range(key, lo, hi, True, True)


def _with_range(key: ScenarioKey, lo: float, hi: float, lo_closed: bool,
                hi_closed: bool) -> ScenarioKey:
    return _replace(key, low=lo, high=hi, low_closed=lo_closed, high_closed=hi_closed)


def _replace(key: ScenarioKey, **kw: Any) -> ScenarioKey:
    from dataclasses import replace

    return replace(key, **kw)


def _sweep() -> list[ScenarioKey]:
    from paintcell.validation.sweep_names import METHODS
    from paintcell.validation.sweep_spec import SCENARIO_DEFAULTS

    kinds = {"factors": "table", "limits": "table", "method": "string"}
    valid = {"factors": "NAME = \"DIST\" per disturbance (the [disturbances] keys)",
             "limits": "max_pNN_<figure>, min_pNN_<figure>, min_yield_pct, "
                       "min_yield_lower_pct = a number",
             "method": " | ".join(METHODS),
             "samples": "an integer ≥ 1", "fast_samples": "an integer ≥ 1",
             "seed": "an integer ≥ 0", "workers": "an integer ≥ 0"}
    doc = {"factors": "the disturbances to vary and their distributions ([sweep.factors]; "
                      "`paintcell sweep --vary` adds or replaces factors)",
           "samples": "how many executions the sweep runs",
           "fast_samples": "samples of a `--fast` sweep (unset: `samples`)",
           "method": "the design: Latin hypercube (lhs) or plain Monte Carlo (mc)",
           "seed": "seeds the design and each sample's disturbance directions",
           "limits": "quantile and yield limits `paintcell check` holds the scenario to "
                     "([sweep.limits])",
           "workers": "local Dask worker processes (0: the samples run in this process)"}
    return [ScenarioKey("sweep", k, kinds.get(k, "integer"), _toml_value(v), valid[k],
                        doc=doc[k])
            for k, v in SCENARIO_DEFAULTS.items()]


def scenario_keys() -> list[ScenarioKey]:
    """Every key a scenario file accepts: the top level, then each table of `TABLES`."""
    out = _top_level()
    for table in TABLES:
        if table == "part":
            out += _part()
        elif table in PLACEMENTS:
            out += _placement(table)
        elif table == "sweep":
            out += _sweep()
        elif table == "spec":
            out += _spec()
        else:
            out += _settings(table)
    return out
