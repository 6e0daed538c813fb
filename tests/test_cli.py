"""The `paintcell` command line: help, one-line errors with exit code 2, JUnit XML."""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from paintcell.cli.common import EXIT_OK, EXIT_USAGE
from paintcell.cli.junit import write_junit
from paintcell.cli.main import build_parser, main

COMMANDS = ["run", "check", "plan", "validate", "export", "report"]


def _run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "paintcell", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=120)


@pytest.mark.parametrize("cmd", COMMANDS)
def test_help_explains_every_option(cmd: str) -> None:
    sub = build_parser()._subparsers._group_actions[0].choices[cmd]  # type: ignore[union-attr]
    for action in sub._actions:
        if action.dest != "help":
            assert action.help, f"{cmd} option {action.dest} has no help"
    out = _run(cmd, "--help")
    assert out.returncode == 0 and "usage: paintcell" in out.stdout


def test_unknown_scenario_is_one_line_exit_2(tmp_path: Path) -> None:
    out = _run("run", str(tmp_path / "nope.py"))
    assert out.returncode == EXIT_USAGE
    assert out.stderr.count("\n") == 1 and "does not exist" in out.stderr
    assert "Traceback" not in out.stderr


def test_script_without_scenario_and_bad_option(tmp_path: Path) -> None:
    script = tmp_path / "empty.py"
    script.write_text("x = 1\n")
    out = _run("run", str(script))
    assert out.returncode == EXIT_USAGE and "defines no SCENARIO" in out.stderr
    out = _run("run", str(script), "--mode", "telepathy")
    assert out.returncode == EXIT_USAGE and out.stderr.count("\n") == 1
    out = _run("report", str(tmp_path / "missing_dir"))
    assert out.returncode == EXIT_USAGE and "metrics.json" in out.stderr


_PAIR = """name = "roof_pair"
fast_resolution_m = 0.025
common_film_build = false
[planner]
orientation = "zero-curvature"
[[parts]]
part = "roof"
xyz_m = [0.0, 0.0, 1.45]
[[robots]]
name = "left"
[robots.base]
xyz_m = [0.0, 1.8, 0.0]
[[robots]]
name = "right"
[robots.base]
xyz_m = [0.0, -1.8, 0.0]
"""
_ROOF = """name = "roof_one"
part = "roof"
fast_resolution_m = 0.025
[part_placement]
xyz_m = [1.4, 0.0, 1.0]
[planner]
orientation = "zero-curvature"
"""


def test_plan_of_a_booth_writes_each_parts_plan(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """`paintcell plan` on a booth writes each part's plan as its robots get it and the booth's
    snapshot: a one-part booth without a common film build plans exactly what a one-robot
    scenario of that part plans; validate on the plan-only folder names the missing file."""
    import json

    from paintcell.booth.booth_data import booth_from_snapshot
    from paintcell.coverage.plan import CoveragePlan

    (tmp_path / "pair.toml").write_text(_PAIR)
    (tmp_path / "one.toml").write_text(_ROOF)
    assert main(["plan", str(tmp_path / "pair.toml"), "--fast", "--out", str(tmp_path / "p")]) \
        == EXIT_OK
    assert main(["plan", str(tmp_path / "one.toml"), "--fast", "--out", str(tmp_path / "q")]) \
        == EXIT_OK
    out = capsys.readouterr().out
    assert "roof_pair: plan_0: " in out and "roof_one: " in out
    booth_plan = CoveragePlan.load(tmp_path / "p" / "plan_0.json")
    one_plan = CoveragePlan.load(tmp_path / "q" / "plan.json")
    assert len(booth_plan.passes) == len(one_plan.passes) > 0
    assert booth_plan.content_digest() == one_plan.content_digest()
    snap = json.loads((tmp_path / "p" / "scenario.json").read_text())
    assert snap["run"] == {"fast": True, "mode": "none"}
    assert [r.name for r in booth_from_snapshot(snap, "scenario.json").robots] == \
        ["left", "right"]
    assert main(["validate", str(tmp_path / "p")]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cell.npz is missing" in err


def test_debug_shows_traceback(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--debug", "run", str(tmp_path / "nope.py")]) == EXIT_USAGE
    assert "Traceback" in capsys.readouterr().err


def test_junit_xml_is_valid_with_one_case_per_scenario(tmp_path: Path) -> None:
    ok = [{"name": "executed_nsd_pct", "value": 8.0, "limit": 12.0, "unit": "%", "passed": True}]
    bad = [{"name": "loss_pp", "value": 2.5, "limit": 1.0, "unit": "pp", "passed": False}]
    path = tmp_path / "junit.xml"
    write_junit(path, [("door", 3.0, ok, None), ("hood", 2.0, bad, None),
                       ("roof", 0.1, [], "pose 3 of pass 2 unreachable")])
    root = ET.parse(path).getroot()
    assert root.tag == "testsuite" and root.get("tests") == "3"
    assert root.get("failures") == "1" and root.get("errors") == "1"
    cases = {c.get("name"): c for c in root.iter("testcase")}
    assert set(cases) == {"door", "hood", "roof"}
    assert cases["door"].find("failure") is None
    assert "loss_pp" in cases["hood"].find("failure").get("message")  # type: ignore[union-attr]
    assert cases["roof"].find("error") is not None


BROKEN = {
    "typo.py": '''
from paintcell.app.scenario import Scenario
from paintcell.core.placement import Placement
SCENARIO = Scenario(name="typo", part="panel", part_placement=Placement(),
                    planner={"v_nominl_m_s": 0.4})
''',
    "syntax.py": "SCENARIO = Scenario(\n",
    "badvalue.py": '''
from paintcell.app.scenario import Scenario
from paintcell.core.placement import Placement
SCENARIO = Scenario(name="badvalue", part="panel", part_placement=Placement(),
                    fast_resolution_m=-0.01)
''',
}


def test_check_reports_broken_scenarios_as_errors_and_still_writes_junit(tmp_path: Path) -> None:
    for name, text in BROKEN.items():
        (tmp_path / name).write_text(text)
    out = _run("check", str(tmp_path), "--fast", "--junit", str(tmp_path / "j.xml"))
    assert out.returncode == 1, out.stderr
    assert "Traceback" not in out.stderr + out.stdout
    assert "unknown planner setting(s) ['v_nominl_m_s']" in out.stdout
    assert "cannot import scenario" in out.stdout and "SyntaxError" in out.stdout
    assert "fast_resolution_m = -0.01 must be a positive length" in out.stdout
    root = ET.parse(tmp_path / "j.xml").getroot()
    assert root.get("tests") == "3" and root.get("errors") == "3"
    # Three at once: the same rows in the same (the files') order, the same JUnit cases.
    par = _run("check", str(tmp_path), "--fast", "--jobs", "3", "--junit", str(tmp_path / "k.xml"))
    assert par.returncode == 1 and par.stdout == out.stdout, par.stdout
    names = [c.get("name") for c in root.iter("testcase")]
    assert [c.get("name") for c in ET.parse(tmp_path / "k.xml").getroot().iter("testcase")] \
        == names == sorted(names)
    bad = _run("check", str(tmp_path), "--jobs", "two")
    assert bad.returncode == 2 and "argument --jobs/-j: 'two' is out of range" in bad.stderr


def test_help_shows_only_meaningful_defaults() -> None:
    for cmd in COMMANDS:
        text = _run(cmd, "--help").stdout
        assert "(default: None)" not in text and "(default: False)" not in text
        assert "(default: [])" not in text and "--debug" in text
