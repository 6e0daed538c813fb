"""The README is a guide a new user can follow: short, and what it shows works — its scenario
example loads as written, its commands are the command line's, its Python example calls the real
signatures, its exit codes are the ones the parser documents."""

from __future__ import annotations

import argparse
import inspect
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _block(lang: str) -> str:
    m = re.search(rf"```{lang}\n(.*?)```", README, re.S)
    assert m, f"README has no ```{lang} block"
    return m.group(1)


def test_readme_is_a_guide_not_a_notebook() -> None:
    assert len(README.splitlines()) <= 250


def test_scenario_example_loads_as_written(tmp_path: Path) -> None:
    from paintcell.app.scenario_files import load_scenario

    path = tmp_path / "example.toml"
    path.write_text(_block("toml"))
    scn = load_scenario(path)
    # the annotated values are the ones loaded (read back independently of the loader's code)
    assert scn.name == "door" and scn.part == "door" and scn.robot == "abb_paint"
    assert scn.resolution_m == 0.01 and scn.fast_resolution_m == 0.025
    assert scn.thresholds.max_executed_nsd_pct == 5.3
    assert scn.thresholds.max_abs_loss_pp == 0.5
    assert scn.planner == {"orientation": "zero-curvature"}


def test_every_command_listed_is_a_command_and_every_command_is_listed() -> None:
    from paintcell.cli.main import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    section = README.split("## Commands", 1)[1].split("\n## ", 1)[0]
    listed = re.findall(r"^\| `paintcell (\w+)", section, re.M)
    assert sorted(listed) == sorted(sub.choices), (listed, sorted(sub.choices))


def test_exit_codes_are_the_parsers() -> None:
    from paintcell.cli.main import build_parser

    section = README.split("## Exit codes", 1)[1].split("\n## ", 1)[0]
    codes = re.findall(r"^\| (\d+) \|", section, re.M)
    epilog = build_parser().epilog or ""
    assert codes == re.findall(r"^\s*(\d+)\s", epilog, re.M) == ["0", "1", "2", "130"]


def test_python_example_calls_the_real_signatures() -> None:
    from paintcell.app.pipeline import RunResult, run_scenario
    from paintcell.app.scenario_files import load_scenario

    code = _block("python")
    assert "load_scenario(" in code and "run_scenario(" in code
    call = re.search(r"run_scenario\((.*?)\)\n", code).group(1)
    kwargs = set(re.findall(r"(\w+)=", call))
    params = inspect.signature(run_scenario).parameters
    assert kwargs <= set(params), kwargs - set(params)
    assert len(inspect.signature(load_scenario).parameters) == 1
    for attr in re.findall(r"result\.(\w+)", code):
        assert attr in {f.name for f in RunResult.__dataclass_fields__.values()} \
            or isinstance(getattr(RunResult, attr, None), property), attr
