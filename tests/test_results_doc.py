"""docs/results.md is written by `benchmarks/results.py` from the metrics of runs: its tables are
read back here by a separate markdown parser and every cell is compared with the metric it shows,
to the decimals it prints — on metrics folders built here (known values, each part kind) and on
the committed page against the figures it was written from (docs/results.json)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "results.py"

#: What each scenario column means: its metrics.json key (stated here, not taken from the script).
SCENARIO_KEYS = {"planned σ/μ %": "planned_nsd_pct", "executed σ/μ %": "executed_nsd_pct",
                 "loss pp": "loss_pp", "time law pp": "loss_time_law_pp",
                 "servo pp": "loss_servo_pp", "in spec window %": "executed_inside_spec_pct",
                 "cycle s": "executed_cycle_time_s", "honest reach %": "reachability_pct",
                 "jumps": "reach_n_joint_jumps", "flips": "reach_n_config_flips",
                 "collisions": "n_collisions", "thresholds": "passed",
                 "whole body σ/μ %": "executed_nsd_pct",
                 "worst part σ/μ %": "max_part_executed_nsd_pct",
                 "overlap bands σ/μ %": "overlap_executed_nsd_pct",
                 "conveyor pp": "loss_conveyor_pp", "booth cycle s": "executed_cycle_time_s",
                 "one robot s": "one_robot_cycle_s", "closest bells m": "min_bell_distance_m"}
PAPER_KEYS = {"paper constant %": "paper_constant_pct", "paper optimized %": "paper_optimized_pct",
              "paper %": "paper_pct", "whole constant %": "whole_constant_pct",
              "whole optimized %": "whole_optimized_pct",
              "whole Algorithm 1 %": "whole_optimized_pct",
              "interior constant %": "interior_constant_pct",
              "interior optimized %": "interior_optimized_pct",
              "interior Algorithm 1 %": "interior_optimized_pct", "passes": "passes",
              "min / mean": "min_over_mean"}


def parse_tables(text: str) -> dict[str, list[dict[str, str]]]:
    """{section heading: rows as {column header: cell text}} of every markdown table; a table
    belongs to the nearest heading (any level) above it."""
    out: dict[str, list[dict[str, str]]] = {}
    heading, header = "", None
    for line in text.splitlines():
        if line.startswith("#"):
            heading, header = line.lstrip("#").strip(), None
            continue
        if not line.startswith("|"):
            header = None
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if header is None:
            header = cells
        elif all(re.fullmatch(r"-+", c) for c in cells):
            continue
        else:
            assert len(cells) == len(header), line
            out.setdefault(heading, []).append(dict(zip(header, cells, strict=True)))
    return out


def agrees(cell: str, value: object) -> bool:
    """The printed cell shows `value`: PASS/FAIL for a verdict, '-' for a missing figure, else the
    number to the decimals printed (half a unit of the last digit)."""
    if isinstance(value, bool):
        return cell == ("PASS" if value else "FAIL")
    if value is None:
        return cell == "-"
    decimals = len(cell.split(".")[1]) if "." in cell else 0
    return abs(float(cell) - float(value)) <= 0.5 * 10.0 ** -decimals + 1e-9


def check_scenario_tables(tables: dict[str, list[dict[str, str]]],
                          scenarios: dict[str, dict]) -> int:
    """Every scenario cell equals its metric; the count of cells compared."""
    n = 0
    for heading, rows in tables.items():
        for row in rows:
            name = row.get("scenario", "").strip("`")
            if name not in scenarios:
                continue
            for col, cell in row.items():
                if col == "scenario":
                    continue
                value = scenarios[name][SCENARIO_KEYS[col]]
                assert agrees(cell, value), f"{heading} / {name} / {col}: {cell} vs {value}"
                n += 1
    return n


def _write_run(folder: Path, name: str, metrics: dict, part: object) -> None:
    d = folder / name
    d.mkdir(parents=True)
    (d / "metrics.json").write_text(json.dumps(metrics))
    (d / "scenario.json").write_text(json.dumps({"name": name, "part": part}))


RUNS = {
    "panel": ({"planned_nsd_pct": 1.9412, "executed_nsd_pct": 1.9534, "loss_pp": 0.0122,
               "loss_time_law_pp": 0.0101, "loss_servo_pp": 0.0021,
               "executed_inside_spec_pct": 100.0, "executed_cycle_time_s": 20.394,
               "reachability_pct": 100.0, "reach_n_joint_jumps": 0, "reach_n_config_flips": 0,
               "n_collisions": 0, "passed": True, "torque_source": "ignored"}, "panel"),
    "scan": ({"planned_nsd_pct": 10.137, "executed_nsd_pct": 10.186, "loss_pp": 0.0486,
              "loss_time_law_pp": 0.0434, "loss_servo_pp": 0.0052,
              "executed_inside_spec_pct": 88.5, "executed_cycle_time_s": 13.877,
              "reachability_pct": 97.5, "reach_n_joint_jumps": 2, "reach_n_config_flips": 1,
              "n_collisions": 3, "passed": False},
             {"file": "/data/meshes/scan.PLY", "units": "auto"}),
    "line": ({"planned_nsd_pct": 6.3, "executed_nsd_pct": 6.41, "loss_pp": -0.0044,
              "loss_time_law_pp": -0.002, "loss_servo_pp": -0.0024,
              "executed_inside_spec_pct": 97.4, "executed_cycle_time_s": 36.06,
              "reachability_pct": 100.0, "reach_n_joint_jumps": 0, "reach_n_config_flips": 0,
              "n_collisions": 0, "passed": True, "max_part_executed_nsd_pct": 8.404,
              "overlap_executed_nsd_pct": 10.17, "loss_conveyor_pp": 0.0001,
              "one_robot_cycle_s": 111.2, "min_bell_distance_m": 0.651,
              "robots": {"a": {}, "b": {}}}, "door"),
}

PAPER = {"resolution_m": 0.01, "band_m": 0.1, "bell": "default_bell",
         "fig5_sweet_spot_mm": 350.0, "fig5_sweet_spot_nsd_pct": 1.1, "planar_index_width_mm": 360,
         "failures": [],
         "table1": [{"case": "Excursion door (door)", "paper_constant_pct": 21.82,
                     "paper_optimized_pct": 15.73, "whole_constant_pct": 5.123,
                     "whole_optimized_pct": 4.456, "interior_constant_pct": 3.21,
                     "interior_optimized_pct": 2.987, "plan_time_s": 1.5},
                    {"case": "Plane 235 mm overspray (panel)", "paper_constant_pct": 3.88,
                     "paper_optimized_pct": None, "whole_constant_pct": 2.5,
                     "whole_optimized_pct": 2.4, "interior_constant_pct": 1.0,
                     "interior_optimized_pct": 0.9, "plan_time_s": 1.0}],
         "table2": [{"case": "Planar sheet (panel)", "paper_pct": 2.64, "whole_constant_pct": 2.1,
                     "whole_optimized_pct": 1.94, "interior_constant_pct": 1.2,
                     "interior_optimized_pct": 1.1, "passes": 4, "min_over_mean": 0.914,
                     "plan_time_s": 2.0}]}


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, dict]:
    tmp = tmp_path_factory.mktemp("results")
    for name, (m, part) in RUNS.items():
        _write_run(tmp / "runs", name, m, part)
    (tmp / "paper.json").write_text(json.dumps(PAPER))
    out = tmp / "results.md"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--from", str(tmp / "runs"),
                           "--paper-json", str(tmp / "paper.json"), "--out", str(out)],
                          capture_output=True, text=True, cwd=ROOT,
                          env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stderr
    return out.read_text(), json.loads(out.with_suffix(".json").read_text())


def test_every_cell_shows_its_metric(written: tuple[str, dict]) -> None:
    text, _ = written
    tables = parse_tables(text)
    n = check_scenario_tables(tables, {k: m for k, (m, _) in RUNS.items()})
    assert n == 3 * 12 + 7      # three scenario rows of 12 cells, one booth row of 7


def test_parts_are_grouped_by_where_they_come_from(written: tuple[str, dict]) -> None:
    tables = parse_tables(written[0])
    names = {h: [r["scenario"].strip("`") for r in rows] for h, rows in tables.items()
             if "scenario" in rows[0]}
    assert names["Library parts"] == ["line", "panel"]   # a library door in a booth, a panel
    assert names["Real parts"] == ["scan"]               # a mesh file (any case of its suffix)
    assert names["Booths"] == ["line"]


def check_paper_tables(tables: dict[str, list[dict[str, str]]], paper: dict) -> None:
    """Both paper tables show the rows of `paper`, cell by cell."""
    for heading, rows in (("Table 1: speed optimization", paper["table1"]),
                          ("Table 2: index optimization (u_max = 4 %, 300 mm overspray)",
                           paper["table2"])):
        assert [r["case"] for r in tables[heading]] == [r["case"] for r in rows]
        for shown, truth in zip(tables[heading], rows, strict=True):
            for col, cell in shown.items():
                if col != "case":
                    assert agrees(cell, truth[PAPER_KEYS[col]]), (heading, col, cell)


def test_paper_tables_show_their_rows(written: tuple[str, dict]) -> None:
    check_paper_tables(parse_tables(written[0]), PAPER)
    assert "350 mm at σ/μ 1.10 %" in written[0]


def test_page_is_stamped_with_its_commands_and_date(written: tuple[str, dict]) -> None:
    text, data = written
    assert re.search(r"Ran on \d{4}-\d\d-\d\d \d\d:\d\d UTC", text)
    assert "`python benchmarks/results.py --from " in text
    assert data["stamp"]["date"] in text


def test_parser_catches_a_wrong_cell(written: tuple[str, dict]) -> None:
    """The comparison is not vacuous: one digit changed in the page is found."""
    text, _ = written
    bad = text.replace("| 20.39 |", "| 20.41 |")
    assert bad != text
    with pytest.raises(AssertionError, match="cycle s"):
        check_scenario_tables(parse_tables(bad), {k: m for k, (m, _) in RUNS.items()})


def test_committed_page_matches_its_figures() -> None:
    """docs/results.md shows exactly the figures of docs/results.json it was written with."""
    text = (ROOT / "docs" / "results.md").read_text()
    data = json.loads((ROOT / "docs" / "results.json").read_text())
    scenarios = {k: v["metrics"] for k, v in data["scenarios"].items()}
    assert scenarios, "docs/results.json holds no scenario"
    tables = parse_tables(text)
    assert check_scenario_tables(tables, scenarios) >= 12 * len(scenarios)
    shown = {r["scenario"].strip("`") for rows in tables.values() for r in rows
             if "scenario" in r}
    assert shown == set(scenarios)
    assert data["stamp"]["date"] in text and data["stamp"]["command"] in text
    if data.get("paper"):
        check_paper_tables(tables, data["paper"])


def test_generality_tables_are_shown_as_written(tmp_path: Path) -> None:
    """`--generality FILE` puts the table `benchmarks/generality.py --markdown` wrote on the
    page under its own heading, unchanged, and into the JSON beside it."""
    for name, (m, part) in RUNS.items():
        _write_run(tmp_path / "runs", name, m, part)
    table = ("`benchmarks/generality.py --seeds 1` on 2026-01-01\n\n| part | verdict |\n"
             "|---|---|\n| door_frame_0 | PASS |\n\n- generated parts passing the spec: 1 of 1")
    (tmp_path / "gen.md").write_text(table + "\n")
    out = tmp_path / "results.md"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--from", str(tmp_path / "runs"),
                           "--no-paper", "--generality", str(tmp_path / "gen.md"),
                           "--out", str(out)], capture_output=True, text=True, cwd=ROOT,
                          env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stderr
    text = out.read_text()
    assert "## Any part a paint shop sends" in text and table in text
    assert json.loads(out.with_suffix(".json").read_text())["generality"] == [table + "\n"]
