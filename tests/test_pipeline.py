"""End to end through the CLI: run, validate, export, report and check on a small panel job."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from paintcell.coverage.plan import CoveragePlan
from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.joint_trajectory import JointTrajectory

SCENARIO = '''
from paintcell.cli.main import run_script
from paintcell.app.scenario import Scenario, facing_robot
from paintcell.core.placement import Placement
from paintcell.validation.validate_report import Thresholds

SCENARIO = Scenario(
    name="{name}",
    part="panel",
    part_placement=Placement(xyz_m=(1.4, 0.0, 1.0), rpy_rad=facing_robot()),
    fast_resolution_m=0.04,
    fast_planner={{"sample_spacing_m": 0.04}},
    trajectory={{"q_home": (0.0, -0.6, 0.3, 0.0, 0.9, 0.0)}},
    thresholds=Thresholds(max_executed_nsd_pct={nsd}, max_loss_pp=1.0, max_cycle_time_s=90.0),
    spec={{"window_pct": 99.0, "min_inside_pct": 1.0, "max_nsd_pct": 99.0}},  # LOOSE_SPEC_TABLE
)

if __name__ == "__main__":
    raise SystemExit(run_script(SCENARIO))
'''


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "paintcell", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=600)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("e2e")
    (d / "small_panel.py").write_text(SCENARIO.format(name="small_panel", nsd=30.0))
    out = _cli("run", "small_panel.py", "--fast", "--out", "res", "--no-report", cwd=d)
    assert out.returncode == 0, out.stderr
    return d


@pytest.mark.slow
def test_run_writes_every_result_file(run_dir: Path) -> None:
    res = run_dir / "res"
    for name in ("plan.json", "plan.npz", "trajectory.npz", "trajectory.csv", "trace.npz",
                 "metrics.json", "scenario.json", "film.npz", "film.glb"):
        assert (res / name).is_file(), name
    # No temp folders or temp files left behind.
    assert not [p for p in run_dir.iterdir() if p.name.startswith(".")]
    m = json.loads((res / "metrics.json").read_text())
    assert m["passed"] is True and m["reachability_pct"] == 100.0
    plan = CoveragePlan.load(res / "plan.json")
    traj = JointTrajectory.load_npz(res / "trajectory.npz")
    trace = ExecutedTrace.load_npz(res / "trace.npz")
    assert m["plan_summary"]["passes"] == len(plan.passes)
    assert m["executed_cycle_time_s"] == pytest.approx(trace.t_s[-1] - trace.t_s[0], abs=0.01)
    # film.npz: the arrays behind the report's histogram agree with metrics.json
    with np.load(res / "film.npz") as z:
        w = np.where(z["judged"], z["vertex_areas_m2"], 0.0)
        target = float(np.sum(w * z["planned_thickness_m"]) / w.sum())
        ok = np.abs(z["executed_thickness_m"] - target) <= float(z["tolerance"]) * target
    assert 1e6 * target == pytest.approx(m["planned_mean_um"], rel=1e-9)
    assert 100 * w[ok].sum() / w.sum() == pytest.approx(m["executed_within_tolerance_pct"])
    # The CSV holds the same program as the npz, row for row.
    csv = np.loadtxt(res / "trajectory.csv", delimiter=",", skiprows=1)
    assert csv.shape[0] == len(traj.t_s)
    assert np.allclose(csv[:, 1:7], traj.q, atol=1e-6)


@pytest.mark.slow
def test_validate_export_and_report_on_the_results(run_dir: Path) -> None:
    res = run_dir / "res"
    before = json.loads((res / "metrics.json").read_text())
    (res / "film.glb").unlink()
    out = _cli("validate", "res", cwd=run_dir)
    assert out.returncode == 0, out.stderr
    after = json.loads((res / "metrics.json").read_text())
    assert after["executed_nsd_pct"] == pytest.approx(before["executed_nsd_pct"], rel=1e-9)
    assert (res / "film.glb").read_bytes()[:4] == b"glTF"  # validate writes the 3-D film again
    out = _cli("export", "res", "--rapid", "--style", "paintl", cwd=run_dir)
    assert out.returncode == 0, out.stderr
    text = (res / "small_panel.mod").read_text()
    plan = CoveragePlan.load(res / "plan.json")
    assert text.startswith("MODULE small_panel") and text.count("SetBrush 1;") == len(plan.passes)
    out = _cli("report", "res", "--video", cwd=run_dir)  # the run made no GIF (--no-report)
    assert out.returncode == 2 and "paintcell run --video" in out.stderr, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1
    out = _cli("report", "res", cwd=run_dir)
    assert out.returncode == 0, out.stderr
    from paintcell.output.report_sections import format_value

    html = (res / "report.html").read_text()
    assert "small_panel" in html and format_value(after["executed_nsd_pct"]) in html


@pytest.mark.slow
def test_check_exits_1_on_an_over_tight_threshold_with_junit(run_dir: Path) -> None:
    # σ/μ ≤ 0.01 % cannot be met by any real coat: the check must fail, not crash.
    (run_dir / "tight").mkdir()
    (run_dir / "tight" / "tight_panel.py").write_text(
        SCENARIO.format(name="tight_panel", nsd=0.01))
    out = _cli("check", "tight", "--fast", "--junit", "junit.xml", cwd=run_dir)
    assert out.returncode == 1, out.stderr
    assert "FAIL" in out.stdout and "0 passed, 1 failed" in out.stdout
    root = ET.parse(run_dir / "junit.xml").getroot()
    (case,) = list(root.iter("testcase"))
    assert case.get("name") == "tight_panel"
    assert "executed" in case.find("failure").get("message")  # type: ignore[union-attr]


@pytest.mark.slow
def test_a_failed_run_keeps_the_previous_results(run_dir: Path) -> None:
    res = run_dir / "res"
    before = (res / "metrics.json").read_text()
    bad = run_dir / "bad.py"
    bad.write_text(SCENARIO.format(name="bad", nsd=30.0).replace('part="panel"',
                                                                 'part="no_such_part"'))
    out = _cli("run", "bad.py", "--fast", "--out", "res", cwd=run_dir)
    assert out.returncode == 2 and "neither a library part" in out.stderr
    assert out.stderr.count("\n") == 1
    assert (res / "metrics.json").read_text() == before


@pytest.mark.slow
def test_disturbed_run_loses_more_uniformity(run_dir: Path) -> None:
    # A 30 mm part placement error and a 10 mm TCP calibration error must cost uniformity that the
    # nominal run does not lose (the plan was made for the nominal placement).
    nominal = json.loads((run_dir / "res" / "metrics.json").read_text())
    out = _cli("run", "small_panel.py", "--fast", "--out", "dist", "--no-report",
               "--disturb", "part_offset_m=0.03", "--disturb", "tcp_offset_m=0.01",
               "--disturb", "seed=1", cwd=run_dir)
    assert out.returncode in (0, 1), out.stderr
    m = json.loads((run_dir / "dist" / "metrics.json").read_text())
    assert m["part_placement_error_mm"] == pytest.approx(30.0, rel=1e-6)
    assert abs(m["loss_pp"]) > abs(nominal["loss_pp"]) + 0.01
    out = _cli("run", "small_panel.py", "--fast", "--disturb", "part_offset_m", cwd=run_dir)
    assert out.returncode == 2 and "KEY=VALUE" in out.stderr
    out = _cli("run", "small_panel.py", "--fast", "--disturb", "wobble=1", cwd=run_dir)
    assert out.returncode == 2 and "unknown disturbances setting(s) ['wobble']" in out.stderr


@pytest.mark.slow
def test_out_dir_that_is_not_results_is_never_replaced(run_dir: Path) -> None:
    docs = run_dir / "mydocs"
    docs.mkdir()
    (docs / "thesis.txt").write_text("precious")
    out = _cli("run", "small_panel.py", "--fast", "--out", "mydocs", "--no-report", cwd=run_dir)
    assert out.returncode == 2 and "not a paintcell results folder" in out.stderr
    assert (docs / "thesis.txt").read_text() == "precious"
    # The results folder itself gets ordinary permissions (mkdtemp would leave 0700).
    assert (run_dir / "res").stat().st_mode & 0o055 == 0o055


@pytest.mark.slow
def test_files_of_different_runs_are_not_mixed(run_dir: Path, tmp_path: Path) -> None:
    import shutil

    mixed = tmp_path / "mixed"
    shutil.copytree(run_dir / "res", mixed)
    # A full-resolution plan (the run was --fast) dropped beside the old trajectory and trace.
    out = _cli("plan", str(run_dir / "small_panel.py"), "--out", str(tmp_path / "other"),
               cwd=run_dir)
    assert out.returncode == 0, out.stderr
    for name in ("plan.json", "plan.npz"):
        shutil.copy(tmp_path / "other" / name, mixed / name)
    out = _cli("validate", str(mixed), cwd=run_dir)
    assert out.returncode == 2 and "made from another plan" in out.stderr
    # A truncated trace is named in one line, not a zip traceback.
    shutil.copytree(run_dir / "res", tmp_path / "broken")
    trace = tmp_path / "broken" / "trace.npz"
    trace.write_bytes(trace.read_bytes()[:100])
    out = _cli("validate", str(tmp_path / "broken"), "--debug", cwd=run_dir)
    assert out.returncode == 2 and "cannot read" in out.stderr and "trace.npz" in out.stderr
    assert "Traceback" in out.stderr  # --debug after the subcommand works too
