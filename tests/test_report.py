"""paintcell.output.report: a self-contained HTML report built from files only; make_figures end
to end."""

from __future__ import annotations

import html
import json
import os
from html.parser import HTMLParser
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.output import report, report_sections
from paintcell.output.render import write_png, write_video
from paintcell.output.report_figures import make_figures
from paintcell.output.report_sections import format_value
from paintcell.surface.analytic import plane

METRICS = {
    "planned_nsd_pct": 3.21,
    "executed_nsd_pct": 3.456789,
    "loss_pp": 0.246789,
    "cycle_time_s": 42.5,
    "planned_mean_thickness_um": 25.0,
    "min_thickness_m": 1.2e-5,
    "passed": False,
    "checks": [
        {"name": "executed σ/μ", "value": 3.456789, "limit": 20.0, "unit": "%", "passed": True,
         "kind": "max"},
        {"name": "reachability", "value": 97.5, "limit": 100.0, "unit": "%", "passed": False,
         "kind": "min"},
    ],
    "reachability": {"all_reachable": False, "verdict": "2 poses out of reach",
                     "reachable_pct": 97.5, "worst": {"pass": 3, "position_error_m": 0.0123}},
    "collisions": [{"body1": "robot/link6", "body2": "part", "t_start_s": 1.25, "t_end_s": 1.5,
                    "max_depth_m": 0.002, "samples": 250}],
    "joint_range_utilization": [0.5, 0.61, 0.7, 0.2, 0.33, 0.9],
    "long_series_s": list(np.linspace(0.0, 1.0, 40)),
    "scenario": {"name": "synthetic", "part": "panel", "robot": "abb_paint"},
    "plan_summary": {"passes": 5, "settings": {"u_max": 0.04, "nested": {"w_min_m": 0.1}}},
    "stage_times_s": {"plan": 1.5, "execute": 3.25},
}


class _Collect(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.srcs: list[str] = []
        self.hrefs: list[str] = []
        self.text: list[str] = []
        self.stack: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag not in ("img", "meta", "br", "link"):
            self.stack.append(tag)
        if tag == "img":
            self.srcs.append(a.get("src", ""))
        if "href" in a:
            self.hrefs.append(a["href"])
        if tag in ("script", "link", "iframe"):
            self.srcs.append(a.get("src", a.get("href", "")))

    def handle_endtag(self, tag):
        assert self.stack and self.stack[-1] == tag, f"unbalanced </{tag}>"
        self.stack.pop()

    def handle_data(self, data):
        self.text.append(data)


def _leaves(obj, key=""):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _leaves(v, k)
    elif isinstance(obj, list):
        if all(not isinstance(x, dict | list) for x in obj):
            yield key, obj
        else:
            for v in obj:
                yield from _leaves(v, key)
    else:
        yield key, obj


@pytest.fixture()
def results(tmp_path):
    d = tmp_path / "run"
    d.mkdir()
    (d / "metrics.json").write_text(json.dumps(METRICS))
    (d / "scenario.json").write_text(json.dumps({"name": "synthetic", "part": "panel",
                                                 "resolution_m": 0.01}))
    rng = np.random.default_rng(1)
    write_png(d / "render_executed_front.png", rng.integers(0, 255, (40, 60, 3), np.uint8))
    write_png(d / "thickness_maps.png", rng.integers(0, 255, (30, 50, 3), np.uint8))
    write_video(d / "execution.gif", [rng.integers(0, 255, (20, 30, 3), np.uint8)
                                      for _ in range(3)], 10)
    (d / "figures.json").write_text(json.dumps({"figures": [
        {"file": "thickness_maps.png", "caption": "maps [µm]", "kind": "plot"}],
        "skipped": [{"figure": "joints", "reason": "robot limits unavailable"}]}))
    return d


def test_report_is_self_contained_html_with_every_metric(results):
    path = report.write_report(results)
    assert path == results / "report.html"
    mask = os.umask(0)
    os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask  # shareable, not the temp file's 0600
    text = path.read_text(encoding="utf-8")
    p = _Collect()
    p.feed(text)
    p.close()
    assert not p.stack, f"unclosed tags {p.stack}"
    # every PNG of the folder is embedded, the execution GIF only on request (a
    # report under 2 MB by default), and nothing is fetched from outside
    images = sorted(x for x in results.iterdir() if x.suffix in (".png", ".gif"))
    assert len(p.srcs) == len(images) - 1 == 2
    assert all(s.startswith("data:image/png;base64,") for s in p.srcs)
    assert "paintcell report DIR --video" in html.unescape(text)
    with_video = _Collect()
    with_video.feed(report.write_report(results, video=True).read_text(encoding="utf-8"))
    assert len(with_video.srcs) == len(images) == 3
    assert sum(s.startswith("data:image/gif;base64,") for s in with_video.srcs) == 1
    assert not [h for h in p.hrefs if not h.startswith(("#", "data:"))]
    body = html.unescape("".join(p.text))
    # the thresholds: every check's name, value, limit and unit, and the overall verdict
    for c in METRICS["checks"]:
        for field in ("name", "value", "limit", "unit"):
            assert format_value(c[field]) in body, f"check {c['name']} {field} missing"
    assert "Verdict: FAIL" in body
    # every metric, nested ones included: its key and its value
    for key, value in _leaves(METRICS):
        assert key in body, f"metric {key} missing"
        if isinstance(value, list) and len(value) > report_sections.MAX_LIST_ITEMS:
            assert f"{len(value)} values" in body
        elif isinstance(value, list):
            assert ", ".join(format_value(x) for x in value) in body
        else:
            assert format_value(value) in body, f"value of {key} missing"
    # pass/fail per threshold and units in the headers
    assert body.count("PASS") >= 1 and body.count("FAIL") >= 2
    assert "max depth [mm]" in body and "2 (" not in body
    assert "12 µm" in body  # thickness in metres also shown in µm
    assert "robot limits unavailable" in body


def test_one_robot_motion_figures_are_shown_once(results):
    """A one-robot run's motion figures appear once, under Key figures, and not again in its
    robot's section (whose figures are the run's)."""
    from paintcell.output.report_names import ROBOT_MOTION

    m = json.loads((results / "metrics.json").read_text())
    m.update({key: 0.25 + 0.1 * i for i, (key, _, _, _) in enumerate(ROBOT_MOTION)})
    (results / "metrics.json").write_text(json.dumps(m))
    body = html.unescape(report.write_report(results).read_text(encoding="utf-8"))
    for _, label, _, _ in ROBOT_MOTION:
        assert body.count(label) == 1, label


def test_report_reads_trajectory_slowdowns(results):
    k, n = 50, 6
    t = np.arange(k) * 0.01
    traj = JointTrajectory(
        t_s=t, q=np.zeros((k, n)), qd=np.zeros((k, n)), qdd=np.zeros((k, n)),
        tcp_pos_world=np.zeros((k, 3)), tcp_rot_world=np.tile(np.eye(3), (k, 1, 1)),
        v_tcp_planned=np.zeros(k), paint_on=np.ones(k, bool), pass_index=np.zeros(k, int),
        segment=np.ones(k, int), s_pass_m=np.zeros(k), robot_name="abb_paint",
        joint_names=tuple(f"j{i}" for i in range(n)),
        slowdowns=({"pass": 2, "s_start_m": 0.1, "s_end_m": 0.3, "t_start_s": 4.0,
                    "duration_s": 0.75, "max_speed_deficit_pct": 12.5, "limiting": ["j4 qd"]},))
    traj.save_npz(results / "trajectory.npz")
    body = results.joinpath("report.html")
    report.write_report(results)
    text = html.unescape(body.read_text(encoding="utf-8"))
    assert "max speed deficit [%]" in text and "12.5" in text and "j4 qd" in text


def test_missing_metrics_is_a_clear_error(tmp_path):
    with pytest.raises(report.ReportError, match="paintcell run"):
        report.write_report(tmp_path)


def test_flatten_and_units():
    rows = dict(report_sections.flatten({"a": {"b_m_s": 1.5, "c": [1, 2]}, "d": [{"e_pct": 3}]}))
    assert rows == {"a.b_m_s": 1.5, "a.c": "1, 2", "d[0].e_pct": 3}
    unit_of = report_sections.unit_of
    assert unit_of("v_max_m_s") == "m/s" and unit_of("nsd_pct") == "%"
    assert unit_of("thickness_um") == "µm" and unit_of("count") == ""
    assert report_sections._path_unit("stage_times_s.plan") == "s"
    assert report_sections._path_unit("settings.u_max") == ""


def test_make_figures_without_cell(tmp_path):
    """Plots and part renders from in-memory objects; then the report embeds them all."""
    s = plane(0.6, 0.4, resolution_m=0.05)
    planned = 20e-6 + 5e-6 * np.cos(6 * s.vertices[:, 0])
    rep = SimpleNamespace(planned_thickness_m=planned, executed_thickness_m=planned * 1.05)
    files = make_figures(tmp_path, surface=s, report=rep, size=(160, 120),
                                index_curve=False)
    names = {f.name for f in files}
    assert {"thickness_maps.png", "render_planned_front.png", "render_executed_top.png"} <= names
    for f in files:
        img = np.asarray(Image.open(f).convert("RGB"))
        assert img.reshape(-1, 3).std(0).max() > 5
    (tmp_path / "metrics.json").write_text(json.dumps({"passed": True, "checks": []}))
    text = report.write_report(tmp_path).read_text(encoding="utf-8")
    assert text.count("<img ") == len(files)


def test_make_figures_with_cell_robot_and_video(tmp_path):
    """The real paint cell: robot renders at three moments and an execution GIF."""
    from paintcell.execution.cell import build_cell
    from paintcell.robots import load_robot

    s = plane(0.6, 0.4, resolution_m=0.05)
    T = np.eye(4)
    T[:3, 3] = [1.4, 0.0, 0.9]
    robot = load_robot("abb_paint")
    cell = build_cell(robot, s, T)
    k = 3000  # 3 s at 1 kHz
    t = np.arange(k) * 1e-3
    q = cell.q_home + np.outer(np.sin(np.pi * t / t[-1]), np.full(cell.nq, 0.3))
    on = (t > 0.5) & (t < 2.5)
    trace = SimpleNamespace(t_s=t, q=q, paint_on=on)
    planned = 20e-6 + 5e-6 * np.cos(6 * s.vertices[:, 0])
    rep = SimpleNamespace(planned_thickness_m=planned, executed_thickness_m=planned * 0.9)
    files = make_figures(tmp_path, surface=s, trace=trace, report=rep, cell=cell,
                                size=(160, 120), video_size=(96, 72), video_max_frames=12,
                                index_curve=False)
    names = {f.name for f in files}
    assert {"robot_first_paint.png", "robot_mid_paint.png", "robot_last_paint.png",
            "execution.gif"} <= names
    a = np.asarray(Image.open(tmp_path / "robot_first_paint.png"), int)
    b = np.asarray(Image.open(tmp_path / "robot_mid_paint.png"), int)
    assert np.abs(a - b).sum() > 0  # the arm moved between the two moments
    with Image.open(tmp_path / "execution.gif") as im:
        assert 2 <= im.n_frames <= 12


def test_no_gl_backend_skips_renders_but_keeps_plots(tmp_path, monkeypatch):
    from paintcell.output import render

    def no_backend() -> str:
        raise render.RenderBackendError("no offscreen OpenGL backend: install libosmesa6")

    monkeypatch.setattr(render, "backend_name", no_backend)
    s = plane(0.6, 0.4, resolution_m=0.05)
    planned = np.full(len(s.vertices), 2e-5)
    rep = SimpleNamespace(planned_thickness_m=planned, executed_thickness_m=planned)
    files = make_figures(tmp_path, surface=s, report=rep, index_curve=False)
    assert [f.name for f in files] == ["thickness_maps.png"]
    (tmp_path / "metrics.json").write_text(json.dumps({"passed": True}))
    text = html.unescape(report.write_report(tmp_path).read_text(encoding="utf-8"))
    assert "Skipped renders and video: no offscreen OpenGL backend: install libosmesa6" in text


def test_video_on_request_needs_the_gif(results):
    (results / "execution.gif").unlink()
    with pytest.raises(report.ReportError, match="paintcell run --video"):
        report.write_report(results, video=True)


def test_joints_plot_draws_the_mjcf_range_execution_is_judged_on():
    """The joints plot's limits are the joint ranges MuJoCo reads from the robot's MJCF (the
    range an executed trace's joint range use is measured against), not the planned range
    1 mrad inside them."""
    import mujoco

    from paintcell.output.report_figures import _joint_limits
    from paintcell.robots import load_robot
    from paintcell.robots.robot import ABB_PAINT_MJCF

    robot = load_robot("abb_paint")
    lo, hi, v_max = _joint_limits(robot, None)
    rng = mujoco.MjModel.from_xml_path(str(ABB_PAINT_MJCF)).jnt_range[: robot.nq]
    np.testing.assert_array_equal(lo, rng[:, 0])
    np.testing.assert_array_equal(hi, rng[:, 1])
    assert np.all(robot.q_lower > lo) and np.all(robot.q_upper < hi)
    np.testing.assert_array_equal(v_max, robot.v_max)
