"""Settings tables are checked against their dataclass fields' types at load, in one line.

TOML keeps types, so `moving_vias = "false"` is a non-empty string — truthy, the opposite of what
the user meant — and must be refused, not run. Every shipped scenario must still load.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from paintcell.app.scenario_files import load_scenario
from paintcell.booth.booth import Booth
from paintcell.core.errors import ScenarioDataError
from paintcell.core.settings import settings_from
from paintcell.validation.settings_tables import settings_classes

SCENARIOS = sorted((Path(__file__).resolve().parents[1] / "scenarios").glob("*.toml"))


@pytest.mark.parametrize(("table", "line", "message"), [
    ("trajectory", 'moving_vias = "false"',
     "[trajectory] moving_vias must be true or false (got the string 'false'); "
     "write moving_vias = false"),
    ("trajectory", "fold_moves = 1", "fold_moves must be true or false (got 1)"),
    ("trajectory", 'q_home = [0.0, "-0.6", 0.3, 0.0, 0.9, 0.0]',
     "q_home must be a list of numbers (got [0.0, the string '-0.6', 0.3, 0.0, 0.9, 0.0])"),
    ("servo", 'gain_scale = "2"', "gain_scale must be a number (got the string '2'); "
     "write gain_scale = 2.0 (no quotes)"),
    ("disturbances", "seed = 2.5", "[disturbances] seed must be a whole number (got 2.5)"),
    ("disturbances", "flow_scale = true", "flow_scale must be a number (got true)"),
    ("planner", "sample_spacing_m = false", "sample_spacing_m must be a number (got false)"),
])
def test_a_value_of_the_wrong_type_is_refused_in_one_line(
        tmp_path: Path, table: str, line: str, message: str) -> None:
    f = tmp_path / "s.toml"
    f.write_text(f'part = "panel"\n[part_placement]\nxyz_m = [1.4, 0.0, 1.0]\n'
                 f'rpy_rad = [0.0, 0.0, 0.0]\n[{table}]\n{line}\n', encoding="utf-8")
    with pytest.raises(ScenarioDataError) as exc:
        load_scenario(f)
    assert message in str(exc.value) and "\n" not in str(exc.value)
    assert str(f) in str(exc.value)


def test_settings_from_refuses_what_a_booth_or_sweep_passes() -> None:
    """Booth tables and sweep overrides reach the classes through settings_from, not the loader."""
    traj = settings_classes()["trajectory"]
    with pytest.raises(ScenarioDataError, match=r"^\[trajectory\] moving_vias must be true or "
                                                r"false \(got the string 'no'\); write "
                                                r"moving_vias = false$"):
        settings_from(traj, {"moving_vias": "no"}, "trajectory")
    # numpy scalars from a sweep's samples are numbers
    import numpy as np
    dist = settings_classes()["disturbances"]
    d = settings_from(dist, {"flow_scale": np.float64(1.1), "seed": np.int64(3)}, "disturbances")
    assert d.flow_scale == 1.1 and d.seed == 3


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_every_shipped_scenario_loads(path: Path) -> None:
    scn = load_scenario(path)
    if isinstance(scn, Booth):  # booth tables are built per robot: check them here
        classes = settings_classes()
        for table in ("planner", "trajectory", "servo"):
            settings_from(classes[table], getattr(scn, table), table)
