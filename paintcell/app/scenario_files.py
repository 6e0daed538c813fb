"""Scenario files: find them in folders and load one — a TOML file read as data (a `Scenario`,
or a `paintcell.booth.booth.Booth` when it declares `[[robots]]`), or a Python script defining
`SCENARIO`."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

from paintcell.app.scenario import Scenario
from paintcell.app.scenario_checks import check_settings
from paintcell.app.scenario_data import load_toml_scenario
from paintcell.booth.booth import Booth
from paintcell.booth.booth_data import load_toml_booth
from paintcell.core.data_text import read_toml
from paintcell.core.errors import PaintcellError, ScenarioError
from paintcell.core.safe_paths import kind_of

__all__ = ["find_scenarios", "load_scenario"]


def load_scenario(path: str | Path) -> Any:
    """The scenario of a TOML file (read as data) or a Python script (imported; its `SCENARIO`),
    with `source` filled in and every setting and threshold validated: a `Scenario`, or a
    `paintcell.booth.booth.Booth` for a booth of several robots (a TOML file with `[[robots]]`
    tables)."""
    path = Path(path)
    if not path.exists():
        raise ScenarioError(f"scenario {path} does not exist; pass a scenario file such as "
                            "scenarios/door.toml, or a folder of them")
    if path.is_dir():
        raise ScenarioError(f"scenario {path} is a folder; pass one scenario file (`paintcell "
                            "check` takes folders)")
    if not path.is_file():   # a FIFO would block the reader until someone writes to it
        raise ScenarioError(f"scenario {path} is a {kind_of(path.stat().st_mode)}, not a "
                            "regular file; pass the scenario file itself")
    if path.suffix == ".toml":
        # several robots: imported only for a booth
        scn = load_toml_booth(path) if _is_booth_toml(path) else load_toml_scenario(path)
        check_applicator(scn, str(path))
        return scn
    if path.suffix != ".py":
        raise ScenarioError(f"scenario {path} is neither a .toml scenario nor a Python script "
                            "(.py defining SCENARIO)")
    mod_name = f"paintcell_scenario_{path.stem}"
    spec = importlib.util.spec_from_file_location(mod_name, path)
    if spec is None or spec.loader is None:
        raise ScenarioError(f"cannot import scenario {path}")
    module = importlib.util.module_from_spec(spec)
    # Run the script as a module, not as __main__, so it does not start a run on import.
    try:
        spec.loader.exec_module(module)
    except PaintcellError as exc:
        raise ScenarioError(f"scenario {path} is invalid: {exc}") from exc
    except SystemExit as exc:  # a script that exits on import must not end paintcell silently
        raise ScenarioError(f"scenario {path} called sys.exit({exc.code!r}) while loading; a "
                            "scenario script defines SCENARIO and runs nothing on import") \
            from exc
    except Exception as exc:  # a syntax or name error in the user's script
        raise ScenarioError(f"cannot import scenario {path}: {type(exc).__name__}: {exc}") \
            from exc
    scenario = getattr(module, "SCENARIO", None)
    if not isinstance(scenario, Scenario | Booth):
        raise ScenarioError(f"{path} defines no SCENARIO (a paintcell.app.scenario.Scenario "
                            "or a "
                            "paintcell.booth.booth.Booth); add one")
    from dataclasses import replace

    scenario = replace(scenario, source=str(path.resolve()))
    if isinstance(scenario, Scenario):
        check_settings(scenario, str(path))
    check_applicator(scenario, str(path))
    return scenario


def check_applicator(scn: Any, where: str) -> None:
    """Read the scenario's (or booth's) applicator file at load, before any work, and budget the
    planner's index-width curve and width search for its footprint (`paintcell.core.budget`);
    errors name `where` and the applicator file."""
    from paintcell.core.budget import check_profile_budget
    from paintcell.coverage.index_width import profile_size
    from paintcell.paint.applicator import Applicator
    from paintcell.validation.settings_tables import check_settings_table

    if scn.applicator is None:
        return
    app_path = Path(scn.applicator)
    if not app_path.is_absolute() and scn.source:
        app_path = Path(scn.source).parent / app_path
    try:
        app = Applicator.from_toml(app_path)
    except PaintcellError as exc:
        msg = str(exc)
        raise ScenarioError(f"{where}: applicator {app_path}: {msg}" if str(app_path) not in msg
                            else f"{where}: {msg}") from exc
    check_profile_budget(*profile_size(app), app.footprint_radius_m,
                         f"{where} applicator {app_path}")
    check_settings_table("planner", scn.planner, where,
                         footprint_radius_m=app.footprint_radius_m)


#: Tables only a booth file has: a file with one of them (or with [[parts]] tables) is read as
#: a booth, which then needs its [[robots]], not as a one-robot scenario with unknown keys.
_BOOTH_ONLY = ("robots", "conveyor", "body_placement", "allocation")


def _is_booth_toml(path: Path) -> bool:
    """Whether a TOML file declares a booth (`paintcell.booth.booth_data`)."""
    try:
        d = read_toml(path)
    except (OSError, PaintcellError):
        return False   # the scenario loader reports the file's own error
    parts = d.get("parts")
    return any(k in d for k in _BOOTH_ONLY) or (
        isinstance(parts, list) and any(isinstance(p, dict) for p in parts))


def find_scenarios(paths: list[str]) -> list[Path]:
    """Scenario files named by `paths` (files, or folders searched for `*.toml` and `*.py`),
    sorted by name within each folder."""
    found: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found.extend(sorted((q for q in [*p.glob("*.toml"), *p.glob("*.py")]
                                 if not q.name.startswith("_")), key=lambda q: q.name))
        elif p.exists():
            found.append(p)
        else:
            raise ScenarioError(f"scenario path {p} does not exist")
    if not found:
        raise ScenarioError(f"no scenario files (*.toml, *.py) found in {', '.join(paths)}")
    return found
