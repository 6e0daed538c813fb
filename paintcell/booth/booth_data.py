"""Booths as data: the TOML booth format (the scenario format of docs/interfaces.md, extended).

    name = "booth"
    resolution_m = 0.01
    fast_resolution_m = 0.025
    applicator = "bells/my_bell.toml"                  # optional; relative to the booth file
    [body_placement]  xyz_m = [..], rpy_rad = [..]     # the body frame at conveyor position 0
    [conveyor]        speed_m_s = 0.05, direction = [1, 0, 0]   (+ mass_kg, force_max_n, ...)
    [[parts]]         part = "door", xyz_m = [..], rpy_rad = [..]   (+ [parts.planner])
                      or a mesh/CAD part: [parts.part] file = "..", units, pieces, side, judge
                      (the `[part]` table of a scenario; file relative to the booth file)
    [[robots]]        name = "side_a", model = "irb5500", home = [..], rail = [-1.2, 1.2]
                      [robots.base] xyz_m = [..], rpy_rad = [..]
    [planner] [trajectory] [servo] [disturbances] [thresholds]

A `[[robots]]` table with `rail` puts the arm on a linear rail with that carriage travel [m]
(the base is then the rail frame, `paintcell.robots.rail`); `carriage = [lower, upper]` keeps the
carriage of the program as planned to that stretch of it (`BoothRobot.carriage_m`: robots
sharing a rail line, kept in order). `allocation` (optional table: robot name
→
[part index, first pass, end pass], or a list of them) fixes the jobs; `max_jobs_per_robot`
(default 1) lets the automatic allocation give a robot up to that many jobs, run one after the
other (`paintcell.booth.booth_chain`). Every key is checked: unknown names are refused
with one line naming the file, the table and the valid keys. A TOML file is a booth when it has
`[[robots]]` tables. `common_film_build` (default true) and `film_target_um` (default: the body's
area-weighted planned mean) set one film build over the parts (`paintcell.booth.booth_build`);
`blend_seams` (default true) blends the seams between parts (`paintcell.booth.booth_seams`);
`seam_shares` ("one", the default, or "per seam") gives the whole body one seam share or each
seam its own (`Booth.seam_shares`).
`film_refine_pace` (default false) refines each part's film with every pass's duration held,
then every part together against the body's film after the seam step, the durations free
(`paintcell.coverage.film_refine`, `paintcell.booth.booth_plans.refine_body`).
`robot_aware_speeds` (default true) re-plans the parts' speeds under what the robots' programs
reach (`paintcell.motion.speed_feedback`).
`body_clearance_m` (default 0.01 m; false: no check) keeps every robot's program that far from
the whole body (`paintcell.booth.booth_clearance`). `[generated_body]` (seed, read, areas_m2;
written by `paintcell init BODY --line` for a generated body) writes the parts' panel files
again from the body generator when they are missing (`paintcell.surface.generated_body`).
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path
from typing import Any

from paintcell.booth.booth import (
    SEAM_SHARE_MODES,
    BodyPart,
    Booth,
    BoothRobot,
    BoothThresholds,
)
from paintcell.booth.booth_checks import (
    BoothDataError,
    check_allocation,
    check_parts_once,
    check_robot,
    check_structure,
    number,
    numbers,
)
from paintcell.booth.conveyor import Conveyor
from paintcell.core.data_text import DataTextError, read_toml
from paintcell.core.errors import PaintcellError, ScenarioDataError
from paintcell.core.placement import Placement
from paintcell.core.setting_ranges import check_range
from paintcell.surface.part_spec import MeshPart
from paintcell.surface.parts import PART_NAMES
from paintcell.validation.paint_spec import PaintSpec
from paintcell.validation.validate_report import check_thresholds

_TOP = ("name", "resolution_m", "fast_resolution_m", "body_placement", "conveyor", "parts",
        "robots", "planner", "trajectory", "servo", "disturbances", "thresholds", "allocation",
        "common_film_build", "film_target_um", "blend_seams", "seam_shares", "body_clearance_m",
        "sweep",
        "applicator", "film_refine_pace", "max_jobs_per_robot", "robot_aware_speeds",
        "spec", "generated_body")
_PART = ("part", "xyz_m", "rpy_rad", "planner", "reverse", "robots")
_ROBOT = ("name", "model", "base", "home", "rail", "carriage")
_PLACEMENT = ("xyz_m", "rpy_rad")


def _jobs_per_robot(v: Any, where: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 3:
        raise BoothDataError(f"{where} = {v!r} must be 1, 2 or 3 (jobs one robot runs one after "
                             "the other)")
    return v


def _seam_shares(v: Any, where: str) -> str:
    if v not in SEAM_SHARE_MODES:
        raise BoothDataError(f"{where} = {v!r} must be "
                             f"{' or '.join(repr(m) for m in SEAM_SHARE_MODES)}")
    return str(v)


def _check_keys(d: Any, valid: tuple[str, ...], where: str) -> dict[str, Any]:
    if not isinstance(d, dict):
        raise BoothDataError(f"{where} must be a table of keys, got {type(d).__name__}")
    unknown = sorted(set(d) - set(valid))
    if unknown:
        raise BoothDataError(f"{where}: unknown key(s) {unknown}; valid: {sorted(valid)}")
    return d


def _placement(d: Any, where: str) -> Placement:
    d = _check_keys(d, _PLACEMENT, where)
    xyz = numbers(d.get("xyz_m", [0.0, 0.0, 0.0]), 3, f"{where} xyz_m", -1e3, 1e3, "m",
                  "[0.0, -0.9, 0.5]")
    rpy = numbers(d.get("rpy_rad", [0.0, 0.0, 0.0]), 3, f"{where} rpy_rad", -100.0, 100.0,
                  "rad", "[0.0, 0.0, 1.5708]")
    return Placement(xyz, rpy)  # type: ignore[arg-type]


def _table(d: Any, key: str, where: str) -> dict[str, Any]:
    v = d.get(key, {})
    if not isinstance(v, dict):
        raise BoothDataError(f"{where}: {key} must be a table [{key}], got {type(v).__name__}")
    return v


def _resolution(d: dict[str, Any], key: str, default: float, where: str) -> float:
    return number(d.get(key, default), f"{where} {key}", 0.0005, 0.5, "m")


def _settings(table: str, values: Any, where: str) -> dict[str, Any]:
    """A booth's (or a part's) settings table, checked as a scenario's is."""
    from paintcell.validation.settings_tables import check_settings_table

    try:
        check_settings_table(table, values, where)
    except ScenarioDataError as exc:
        raise BoothDataError(str(exc)) from exc
    return {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}


def booth_from_dict(d: dict[str, Any], where: str, source: str | None = None) -> Booth:
    """A `Booth` from the TOML's dict (`where` names the file in errors); every key is checked
    here, before any work (`paintcell.booth.booth_checks`)."""
    d = _check_keys(d, _TOP, where)
    check_structure(d, where)
    if "generated_body" in d and source is not None:
        _generated_files(d, where, Path(source).parent)
    parts = []
    for i, p in enumerate(d["parts"]):
        p = _check_keys(p, _PART, f"{where} [[parts]] #{i}")
        if "part" not in p:
            raise BoothDataError(f"{where} [[parts]] #{i}: give `part` (a library part name or "
                                 "a [parts.part] table with file = \"...\")")
        mesh = _mesh_part(p["part"], f"{where} [[parts]] #{i}", source)
        if mesh is None and p["part"] not in PART_NAMES:
            raise BoothDataError(f"{where} [[parts]] #{i}: part = {p['part']!r} is not a library "
                                 f"part ({', '.join(PART_NAMES)}); or give a [parts.part] table "
                                 "with file = \"...\"")
        pl = _placement({k: p[k] for k in _PLACEMENT if k in p}, f"{where} [[parts]] #{i}")
        who = p.get("robots")
        if who is not None and (not isinstance(who, list) or not who
                                or not all(isinstance(x, str) for x in who)):
            raise BoothDataError(f"{where} [[parts]] #{i}: robots = {who!r} must be a list of "
                                 "robot names, e.g. [\"roof_l\", \"roof_r\"]")
        planner = _settings("planner", p.get("planner", {}), f"{where} [[parts]] #{i}")
        parts.append(BodyPart(str(p["part"]) if mesh is None else mesh.stem, pl, planner,
                              _bool(p.get("reverse", False), f"{where} [[parts]] #{i} reverse"),
                              None if who is None else tuple(who), mesh))
    check_parts_once(d["parts"], where)
    robots: list[BoothRobot] = []
    seen: set[str] = set()
    for i, r in enumerate(d["robots"]):
        r = _check_keys(r, _ROBOT, f"{where} [[robots]] #{i}")
        name, model, rail, home = check_robot(r, i, where, seen)
        carriage = None
        if "carriage" in r:
            if rail is None:
                raise BoothDataError(f"{where} [[robots]] {name}: carriage needs rail = [lower, "
                                     "upper] (a stretch of the robot's rail)")
            lo, hi = numbers(r["carriage"], 2, f"{where} [[robots]] {name} carriage", rail[0],
                             rail[1], "m", example=f"[{rail[0]:g}, {rail[1]:g}]")
            carriage = (lo, hi)
        try:
            robots.append(BoothRobot(name, model, _placement(r.get("base", {}), f"{where} "
                                                             f"[[robots]] {name} base"), home,
                                     rail, carriage))
        except PaintcellError as exc:
            raise BoothDataError(f"{where}: {exc}") from exc
    conv = _check_keys(d.get("conveyor", {}), tuple(f.name for f in fields(Conveyor)),
                       f"{where} [conveyor]")
    for k, v in conv.items():
        if (bad := check_range("conveyor", k, v)) is not None:
            raise BoothDataError(f"{where} [conveyor]: {bad}")
    if "direction" in conv:
        numbers(conv["direction"], 3, f"{where} [conveyor] direction", example="[1, 0, 0]")
    th = _check_keys(d.get("thresholds", {}), tuple(f.name for f in fields(BoothThresholds)),
                     f"{where} [thresholds]")
    # the one-robot scenario's ranges: a limit no run can meet, or one that cannot fail, refused
    check_thresholds(BoothThresholds(**th), f"{where} [thresholds]")
    alloc = None if d.get("allocation") is None else check_allocation(
        d["allocation"], [r.name for r in robots], len(parts), where)
    sweep = _table(d, "sweep", where)
    app = d.get("applicator")
    if app is not None:
        if not isinstance(app, str):
            raise BoothDataError(f"{where}: applicator = {app!r} must be a path to an applicator "
                                 "TOML file, e.g. \"bells/my_bell.toml\"")
        app = str((Path(where).parent / app).resolve())
    planner = _settings("planner", _table(d, "planner", where), where)
    trajectory = _settings("trajectory", _table(d, "trajectory", where), where)
    servo = _settings("servo", _table(d, "servo", where), where)
    disturbances = _settings("disturbances", _table(d, "disturbances", where), where)
    body = _placement(_table(d, "body_placement", where), f"{where} [body_placement]")
    try:
        if sweep:
            from paintcell.validation.sweep_spec import check_sweep_table

            check_sweep_table(sweep)
        conv_kw: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v
                                   for k, v in conv.items()}
        conveyor = Conveyor(**conv_kw)
        return Booth(
            name=str(d.get("name", Path(where).stem)), parts=tuple(parts), robots=tuple(robots),
            body_placement=body,
            conveyor=conveyor,
            resolution_m=_resolution(d, "resolution_m", 0.01, where),
            fast_resolution_m=_resolution(d, "fast_resolution_m", 0.025, where),
            planner=planner, trajectory=trajectory, servo=servo, disturbances=disturbances,
            thresholds=BoothThresholds(**th), allocation=alloc,
            max_jobs_per_robot=_jobs_per_robot(d.get("max_jobs_per_robot", 1),
                                               f"{where} max_jobs_per_robot"),
            common_film_build=_bool(d.get("common_film_build", True),
                                    f"{where} common_film_build"),
            blend_seams=_bool(d.get("blend_seams", True), f"{where} blend_seams"),
            seam_shares=_seam_shares(d.get("seam_shares", "one"), f"{where} seam_shares"),
            robot_aware_speeds=_bool(d.get("robot_aware_speeds", True),
                                     f"{where} robot_aware_speeds"),
            film_refine_pace=_bool(d.get("film_refine_pace", False),
                                   f"{where} film_refine_pace"),
            body_clearance_m=_clearance(d.get("body_clearance_m", 0.01),
                                        f"{where} body_clearance_m"),
            film_target_um=(None if d.get("film_target_um") is None
                            else _positive(d["film_target_um"], f"{where} film_target_um")),
            spec=PaintSpec.from_table(d.get("spec"), where),
            source=source, sweep=dict(sweep), applicator=app)
    except PaintcellError as exc:
        raise BoothDataError(str(exc) if str(exc).startswith(where) else f"{where}: {exc}") \
            from exc


def _generated_files(d: dict[str, Any], where: str, base: Path) -> None:
    """The panel files of a generated body's line, in the booth file's folder, written again
    when missing, never over a file that is there
    (`paintcell.surface.generated_body.ensure_panel_files`)."""
    from paintcell.surface.generated_body import ensure_panel_files

    files = [p.get("part", {}).get("file") if isinstance(p, dict)
             and isinstance(p.get("part"), dict) else None for p in d["parts"]]
    if not all(isinstance(f, str) for f in files):
        raise BoothDataError(f"{where} [generated_body]: every [[parts]] needs a [parts.part] "
                             "file (the body's panels, as `paintcell init BODY --line` writes "
                             "them)")
    names = [str(f) for f in files]
    root = base.resolve()
    for f in names:
        if Path(f).is_absolute() or ".." in Path(f).parts \
                or not (root / f).resolve().is_relative_to(root):
            raise BoothDataError(f"{where} [generated_body]: file = {f!r} must lie in the booth "
                                 "file's folder (a relative path without '..'), where `paintcell "
                                 "init BODY --line` writes the panels")
    try:
        ensure_panel_files(d["generated_body"], [base / f for f in names], where)
    except PaintcellError as exc:
        raise BoothDataError(str(exc)) from exc


def _mesh_part(v: Any, where: str, source: str | None) -> MeshPart | None:
    """None for a library part name; the `MeshPart` of a `[parts.part]` table (the `[part]`
    table of a scenario, checked by the same loader; `file` relative to the booth file)."""
    if not isinstance(v, dict):
        return None
    try:
        mp = MeshPart.from_dict(v, base_dir=None if source is None else Path(source).parent)
    except PaintcellError as exc:
        raise BoothDataError(f"{where}: {str(exc).replace('[part]', '[parts.part]')}") from exc
    if source is not None and not Path(mp.file).is_file():
        raise BoothDataError(f"{where} [parts.part]: file {mp.file} does not exist; check file "
                             "(relative to the booth file)")
    return mp


def _bool(v: Any, where: str) -> bool:
    if not isinstance(v, bool):
        raise BoothDataError(f"{where} must be true or false, got {v!r}")
    return v


def _positive(v: Any, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v <= 1e4:
        raise BoothDataError(f"{where} must be a number > 0 and ≤ 1e4 [µm], got {v!r}")
    return float(v)


def _clearance(v: Any, where: str) -> float | None:
    if v is False:
        return None
    if isinstance(v, bool) or not isinstance(v, int | float) or not 0 <= v <= 2:
        raise BoothDataError(f"{where} must be a distance in [0, 2] m or false (no check), "
                             f"got {v!r}")
    return float(v)


def load_toml_booth(path: str | Path) -> Booth:
    """The `Booth` of a booth TOML file (module doc)."""
    path = Path(path)
    try:
        d = read_toml(path)
    except DataTextError as exc:
        raise BoothDataError(str(exc)) from exc
    return booth_from_dict(d, str(path), source=str(path.resolve()))


#: Version of the booth snapshot a booth run writes into its results folder's `scenario.json`.
BOOTH_SNAPSHOT_VERSION = 1


def booth_snapshot(booth: Booth, run: dict[str, Any]) -> dict[str, Any]:
    """The booth as JSON-safe data for its results folder's `scenario.json` (`kind` "booth",
    the run settings `run`: fast, mode); `booth_from_snapshot` reads it back."""
    return {**booth.to_dict(), "kind": "booth", "snapshot_version": BOOTH_SNAPSHOT_VERSION,
            "run": dict(run)}


def _tuples(v: Any) -> Any:
    """JSON lists back to the tuples the booth's dataclasses hold (dict values too)."""
    if isinstance(v, list):
        return tuple(_tuples(x) for x in v)
    if isinstance(v, dict):
        return {k: _tuples(x) for k, x in v.items()}
    return v


def booth_from_snapshot(d: Any, where: str) -> Booth:
    """The `Booth` of a booth results folder's `scenario.json` (never imports its source);
    a snapshot of another version or kind is refused in one line."""
    if not isinstance(d, dict) or d.get("kind") != "booth" \
            or d.get("snapshot_version") != BOOTH_SNAPSHOT_VERSION:
        raise BoothDataError(f"{where} holds no booth snapshot of this paintcell version "
                             f"(snapshot_version {BOOTH_SNAPSHOT_VERSION}); re-run `paintcell run`")
    try:
        kw = {f.name: d[f.name] for f in fields(Booth) if f.name in d}
        kw["parts"] = tuple(BodyPart(**{
            **p, "placement": Placement(**_tuples(p["placement"])),
            "planner": _tuples(p.get("planner", {})),
            "robots": None if p.get("robots") is None else tuple(p["robots"]),
            "mesh": None if p.get("mesh") is None else MeshPart(**_tuples(p["mesh"]))})
            for p in d["parts"])
        kw["robots"] = tuple(BoothRobot(**{**_tuples(r), "base": Placement(**_tuples(r["base"]))})
                             for r in d["robots"])
        kw["body_placement"] = Placement(**_tuples(d["body_placement"]))
        kw["conveyor"] = Conveyor(**_tuples(d["conveyor"]))
        kw["thresholds"] = BoothThresholds(**d["thresholds"])
        kw["spec"] = PaintSpec.from_table(d.get("spec"), where)
        for key in ("planner", "trajectory", "servo", "disturbances", "allocation"):
            if kw.get(key) is not None:
                kw[key] = _tuples(kw[key])
        return Booth(**kw)
    except (KeyError, TypeError, ValueError, PaintcellError) as exc:
        raise BoothDataError(f"{where}: the booth snapshot cannot be read ({exc}); re-run "
                             "`paintcell run`") from exc
