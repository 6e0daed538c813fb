"""What a booth run measures beside its film checks (paintcell.booth.booth_usage,
paintcell.validation.validate_motion.robots_motion,
paintcell.booth.booth_part_film, paintcell.booth.booth_seams.seam_band,
paintcell.output.export_rapid.cell_modules): each robot's time and paint, each part's film
and loss split, the seams, the report's tables and the conveyor-tracked RAPID modules.

The booth figures are checked on one `--fast` run of scenarios/booth.toml (four robots, servo
execution), each re-measured from the results folder's files (traces, plans, film.npz, the
RAPID text through the rapidchecker grammar); paint and seams also against closed forms on
plates.
"""

from __future__ import annotations

import html
import json
import math
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from paintcell.booth.booth_film import gun_in_body
from paintcell.booth.booth_part_film import part_film_figures
from paintcell.booth.booth_seams import seam_band
from paintcell.booth.booth_usage import paint_sent_m3, time_shares
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import thickness
from paintcell.surface.analytic import plane
from paintcell.validation.paint_spec import PaintSpec

ROOT = Path(__file__).resolve().parents[1]
NAMES = ("side_a", "side_b", "roof_l", "roof_r")


@pytest.fixture(scope="module")
def booth_dir(tmp_path_factory):
    """One `--fast` servo run of scenarios/booth.toml, its results folder."""
    from paintcell import run_scenario
    from paintcell.app.scenario_files import load_scenario

    out = tmp_path_factory.mktemp("line") / "booth"
    run_scenario(load_scenario(ROOT / "scenarios" / "booth.toml"), out, fast=True,
                 progress=False)
    return out


def _metrics(d: Path) -> dict:
    return json.loads((d / "metrics.json").read_text())


def _closed_form_flow(app: Applicator) -> float:
    """∫∫ f dA of the bell [m³/s]: the central Gaussian's 2π A0 σx σy and each ring's
    2π A ∫ r exp(−(r − μ)²/2σ²) dr, integrated numerically (not the applicator's formula)."""
    q = 2 * math.pi * app.a0_m_s * app.sigma_x_m * app.sigma_y_m
    for a, mu, s in zip(app.ring_amplitudes_m_s, app.ring_radii_m, app.ring_sigmas_m,
                        strict=True):
        q += 2 * math.pi * a * quad(lambda r, mu=mu, s=s: r * math.exp(-(r - mu) ** 2
                                                                       / (2 * s * s)),
                                    0, np.inf)[0]
    return q


@pytest.mark.parametrize("edge, want_te", [(False, 1.0), (True, 0.5)])
def test_paint_sent_and_laid_on_a_plate_closed_form(edge, want_te):
    """A straight pass at standoff over a flat plate, brush on for 2 s: paint sent = the bell's
    flow × 2 s exactly, and the film on the plate (∫ film dA) = all of it when the plate holds
    the whole footprint, half of it when the pass runs along the plate's edge (the footprint is
    symmetric across the travel)."""
    app = Applicator.from_toml(ROOT / "scenarios" / "bells" / "narrow_bell.toml")
    plate = plane(1.8, 0.6 if edge else 1.2, resolution_m=0.01)
    if edge:                                                # the plate spans y ∈ [0, 0.6]
        T = np.eye(4)
        T[1, 3] = 0.3
        plate = plate.transformed(T)
    dt, v = 0.001, 0.3
    t = np.arange(2000) * dt
    pos = np.column_stack([-0.3 + v * t, np.zeros_like(t), np.full_like(t, app.standoff_m)])
    rot = np.repeat(np.diag([1.0, -1.0, -1.0])[None], len(t), axis=0)   # spray −z, travel +x
    on = np.ones(len(t), bool)
    sent = paint_sent_m3([(app, on)], t)
    assert sent == pytest.approx(_closed_form_flow(app) * len(t) * dt, rel=1e-9)
    g = gun_in_body(t, pos, rot, on, np.eye(4), np.zeros(len(t)), np.array([1.0, 0.0, 0.0]))
    film = thickness(app, g, plate.vertices, plate.normals)
    laid = float(film @ plate.vertex_areas)
    assert laid / sent == pytest.approx(want_te, rel=5e-3)


def test_time_shares_of_a_held_program():
    """A 10 s trace at 1 ms, a program from 2 s to 7 s with passes 3–4 s and 5–6.5 s, a 0.5 s
    settle: painting 2.5 s, moving 2.5 s, waiting 5.5 s of an 10.5 s cycle (counted by hand)."""
    t = np.arange(10001) * 0.001
    in_pass = ((t >= 3.0 - 1e-9) & (t < 4.0 - 1e-9)) | ((t >= 5.0 - 1e-9) & (t < 6.5 - 1e-9))
    s = time_shares(t, in_pass, 2.0, 5.0, 10.5)
    assert s["painting_s"] == pytest.approx(2.5, abs=1e-9)
    assert s["moving_s"] == pytest.approx(2.5, abs=1e-9)
    assert s["waiting_s"] == pytest.approx(5.5, abs=1e-9)
    assert (s["painting_share_pct"] + s["moving_share_pct"] + s["waiting_share_pct"]
            == pytest.approx(100.0, abs=1e-12))


def test_seam_band_and_seam_film_closed_form():
    """Two plates 0.045 m apart along x at 0.01 m spacing; a vertex is in the seam band when the
    other plate is within 0.10 m: the last 6 columns of each (up to 0.055 m from its edge). A
    film linear across the seam, 30 µm + 10 µm/m · x: the band's and the interior's means,
    measured here from the grid's own columns and areas."""
    a = plane(0.5, 0.4, resolution_m=0.01)
    T = np.eye(4)
    T[0, 3] = -0.2725
    left = a.transformed(T)
    T[0, 3] = 0.2725
    right = a.transformed(T)
    from paintcell.booth.booth_film import merge_surfaces

    body = merge_surfaces([left, right], [np.eye(4), np.eye(4)], "two")
    n = len(left.vertices)
    band = seam_band(body.vertices, [n, n])
    x = body.vertices[:, 0]
    want = np.abs(x) <= 0.0225 + 0.055 + 1e-9
    assert want.sum() == 2 * 6 * 41
    np.testing.assert_array_equal(band, want)
    film = 30e-6 + 10e-6 * x
    tot = {k: film for k in ("plan", "trajectory", "servo", "executed")}
    out = part_film_figures(body, tot, body.vertex_areas, None, np.array([0, n, 2 * n]),
                            ["0:left", "1:right"], 30e-6, PaintSpec())
    w = body.vertex_areas
    for key, sl in (("0:left", slice(0, n)), ("1:right", slice(n, 2 * n))):
        f = out["part_film"][key]
        b = np.zeros(len(w), bool)
        b[sl] = want[sl]
        i = np.zeros(len(w), bool)
        i[sl] = ~want[sl]
        assert f["seam_executed_mean_um"] == pytest.approx(1e6 * (film[b] @ w[b]) / w[b].sum(),
                                                           rel=1e-12)
        assert f["interior_executed_mean_um"] == pytest.approx(
            1e6 * (film[i] @ w[i]) / w[i].sum(), rel=1e-12)
        assert f["loss_pp"] == 0.0 and f["executed_inside_spec_pct"] == pytest.approx(100.0)
    assert out["seam_film"]["seam_area_pct"] == pytest.approx(100 * w[want].sum() / w.sum())
    # the ratio the line's max_seam_nsd_ratio checks: the band's σ/μ over the interior's,
    # each measured here from the film and the areas
    assert out["seam_nsd_ratio"] == pytest.approx(
        _nsd(film, w * want) / _nsd(film, w * ~want), rel=1e-9)
    assert 0.0 < out["seam_nsd_ratio"] < 1.0      # the band is the narrower stretch of x


def test_panels_meet_only_within_the_seam_band():
    """`init --line` judges the seams only where panels meet: two 0.5 m plates 0.045 m apart
    meet (their facing columns are 0.045 m apart, under SEAM_BAND_M = 0.10 m) and keep an
    interior (their far columns are 0.545 m from the other plate); 0.30 m apart they do not
    meet; a gap under the band where every vertex is within it (0.05 m strips) leaves no
    interior."""
    from paintcell.app.init_line_file import panels_meet

    def pair(gap_m: float, width_m: float = 0.5):
        a = plane(width_m, 0.4, resolution_m=0.01)
        T = np.eye(4)
        T[0, 3] = -(width_m + gap_m) / 2
        left = a.transformed(T)
        T[0, 3] = (width_m + gap_m) / 2
        return [left, a.transformed(T)]

    assert panels_meet(pair(0.045))
    assert not panels_meet(pair(0.30))
    assert not panels_meet(pair(0.02, width_m=0.05))


def _nsd(film: np.ndarray, w: np.ndarray) -> float:
    mu = film @ w / w.sum()
    return 100.0 * math.sqrt(((film - mu) ** 2) @ w / w.sum()) / mu


def test_booth_time_shares_re_measured_from_the_traces(booth_dir):
    """Each robot's painting / moving / waiting shares sum to 100 % and match the traces: waiting
    where the executed arm stands at its home pose before and after its program (the settle
    included), painting where the trace is on a pass; painting + moving is its busy share."""
    from paintcell.execution.trace import ExecutedTrace

    m = _metrics(booth_dir)
    cycle = m["executed_cycle_time_s"]
    for name in NAMES:
        r = m["robots"][name]
        assert (r["painting_share_pct"] + r["moving_share_pct"] + r["waiting_share_pct"]
                == pytest.approx(100.0, abs=1e-9))
        assert r["painting_share_pct"] + r["moving_share_pct"] == pytest.approx(
            r["busy_share_pct"], abs=1e-6)
        tr = ExecutedTrace.load_npz(booth_dir / f"trace_{name}.npz")
        arm = tr.q[:, 1:]                                  # every booth robot rides a rail
        left = np.abs(arm - arm[0]).max(axis=1) > 2e-3
        back = np.abs(arm - arm[-1]).max(axis=1) > 2e-3
        t0, t1 = tr.t_s[np.argmax(left)], tr.t_s[len(back) - np.argmax(back[::-1])]
        waiting = (t0 - tr.t_s[0]) + (tr.t_s[-1] - t1) + (cycle - (tr.t_s[-1] - tr.t_s[0]))
        assert 100 * waiting / cycle == pytest.approx(r["waiting_share_pct"], abs=0.25)
        dt = np.diff(tr.t_s, append=tr.t_s[0] + cycle)
        assert 100 * dt[tr.pass_index >= 0].sum() / cycle == pytest.approx(
            r["painting_share_pct"], abs=1e-6)


def test_booth_paint_re_measured_from_plans_traces_and_film(booth_dir):
    """Paint sent per robot = its part's bell flow (the plan file's applicator) × its brush-on
    time in its trace, each step at the flow its brush table commanded (the trace's `flow`); the
    film on the body = ∫ film dA of film.npz; the transfer efficiency is
    their ratio and the parts' sent paint adds up to the booth's."""
    from paintcell.coverage.plan import CoveragePlan
    from paintcell.execution.trace import ExecutedTrace

    m = _metrics(booth_dir)
    parts = {p.split(":")[1]: int(p.split(":")[0]) for p in m["part_film"]}
    sent = {}
    for name in NAMES:
        r = m["robots"][name]
        plan = CoveragePlan.load(booth_dir / f"plan_{parts[r['part']]}.json")
        tr = ExecutedTrace.load_npz(booth_dir / f"trace_{name}.npz")
        assert tr.flow is not None
        on_s = float(tr.flow[tr.paint_on].sum()) * float(tr.t_s[1] - tr.t_s[0])
        sent[name] = _closed_form_flow(plan.applicator) * on_s * 1e3
        assert r["paint_used_l"] == pytest.approx(sent[name], rel=1e-6)
        assert 0 < r["transfer_efficiency_pct"] < 100
    assert m["paint_used_l"] == pytest.approx(sum(sent.values()), rel=1e-6)
    assert sum(p["paint_used_l"] for p in m["part_paint"].values()) == pytest.approx(
        m["paint_used_l"], rel=1e-12)
    with np.load(booth_dir / "film.npz") as z:
        laid = 1e3 * float(z["executed_thickness_m"] @ z["vertex_areas_m2"])
    assert m["film_on_body_l"] == pytest.approx(laid, rel=1e-9)
    assert m["executed_transfer_efficiency_pct"] == pytest.approx(
        100 * laid / sum(sent.values()), rel=1e-6)


def test_booth_motion_re_measured_from_the_traces(booth_dir):
    """Each robot's TCP error on paint samples = the largest distance between its trace's and its
    tracked program's TCP there; its speed error is the TCP's speed over the body (the line's
    nominal motion, from the program's conveyor record, taken off) against the planned speed."""
    from paintcell.execution.trace import ExecutedTrace
    from paintcell.motion.joint_trajectory import JointTrajectory

    m = _metrics(booth_dir)
    for name in NAMES:
        r = m["robots"][name]
        ex = ExecutedTrace.load_npz(booth_dir / f"trace_{name}.npz")
        tr = JointTrajectory.load_npz(booth_dir / f"trajectory_{name}.npz")
        on = tr.paint_on
        err = np.linalg.norm(ex.tcp_pos_world - tr.tcp_pos_world, axis=1)
        assert r["tracking_error_max_mm"] == pytest.approx(1e3 * err[on].max(), rel=1e-9)
        c = tr.meta["conveyor"]
        line = np.outer(c["speed_m_s"] * (ex.t_s - c["t_ref_s"]), c["direction"])
        v = np.linalg.norm(np.gradient(ex.tcp_pos_world - line, ex.t_s, axis=0), axis=1)
        use = on & (tr.v_tcp_planned > 1e-6)
        rel = (v[use] - tr.v_tcp_planned[use]) / tr.v_tcp_planned[use]
        assert r["speed_error_rms_pct"] == pytest.approx(100 * np.sqrt(np.mean(rel ** 2)),
                                                         rel=1e-6)
        assert r["speed_error_rms_pct"] < 1.0      # the line's 0.05 m/s is not counted as error
    assert m["tracking_error_max_mm"] == max(m["robots"][n]["tracking_error_max_mm"]
                                             for n in NAMES)


def test_booth_loss_split_and_part_figures_re_measured(booth_dir):
    """Per part and over the body, time law + servo + conveyor = executed − planned σ/μ within
    rounding; each part's planned and executed σ/μ and mean re-measured from film.npz over its
    judged vertices (cell.npz); the check row's figures unchanged."""
    m = _metrics(booth_dir)
    assert m["executed_nsd_pct"] == pytest.approx(5.49, abs=0.005)
    assert m["planned_nsd_pct"] == pytest.approx(5.39, abs=0.005)
    with np.load(booth_dir / "cell.npz") as c, np.load(booth_dir / "film.npz") as z:
        counts, judged = c["part_vertex_counts"], c["judged"]
        plan, ex, areas = z["planned_thickness_m"], z["executed_thickness_m"], z["vertex_areas_m2"]
    offs = np.cumsum([0, *counts])
    for f in [m, *m["part_film"].values()]:
        assert (f["loss_time_law_pp"] + f["loss_servo_pp"] + f["loss_conveyor_pp"]
                == pytest.approx(f["loss_pp"], abs=1e-12))
    assert any(abs(f["loss_servo_pp"]) > 1e-4 for f in m["part_film"].values())
    for i, (key, f) in enumerate(m["part_film"].items()):
        sl = slice(offs[i], offs[i + 1])
        w = areas[sl] * judged[sl]
        assert f["planned_nsd_pct"] == pytest.approx(_nsd(plan[sl], w), rel=1e-9)
        assert f["executed_nsd_pct"] == pytest.approx(_nsd(ex[sl], w), rel=1e-9)
        assert f["executed_nsd_pct"] == pytest.approx(m["part_executed_nsd_pct"][key], rel=1e-12)
        assert f["executed_mean_um"] == pytest.approx(1e6 * (ex[sl] @ w) / w.sum(), rel=1e-9)
        assert f["loss_pp"] == pytest.approx(f["executed_nsd_pct"] - f["planned_nsd_pct"],
                                             abs=1e-12)
    # the fender meets the door: both have a seam band, the roof and hood none within 10 cm
    assert m["part_film"]["0:fender"]["seam_area_pct"] > 0
    assert m["part_film"]["1:door"]["seam_area_pct"] > 0


def test_booth_seam_ratio_re_measured(booth_dir):
    """metrics.json's seam_nsd_ratio (what max_seam_nsd_ratio checks) re-measured from the
    run's files: the seam band from the body's vertices and the parts' vertex counts (another
    part's vertex within 0.10 m, by brute force over every pair), the executed film's σ/μ over
    the judged band and the judged rest."""
    m = _metrics(booth_dir)
    with np.load(booth_dir / "cell.npz") as c, np.load(booth_dir / "film.npz") as z:
        counts, judged = c["part_vertex_counts"], c["judged"]
        ex, areas, V = z["executed_thickness_m"], z["vertex_areas_m2"], z["vertices_m"]
    part = np.repeat(np.arange(len(counts)), counts)
    band = np.zeros(len(V), bool)
    for k in range(len(counts)):
        mine, other = V[part == k], V[part != k]
        d2 = np.concatenate([((mine[i:i + 256, None, :] - other[None, :, :]) ** 2).sum(-1)
                             .min(axis=1) for i in range(0, len(mine), 256)])
        band[part == k] = d2 <= 0.10 ** 2
    w = areas * judged
    assert band.any() and (~band).any()
    assert m["seam_nsd_ratio"] == pytest.approx(_nsd(ex, w * band) / _nsd(ex, w * ~band),
                                                rel=1e-9)


class _Tables(HTMLParser):
    """Every table of a page as rows of cell texts, keyed by its own id, else the h2 id before
    it."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[str]]] = {}
        self._id, self._row, self._cell = "", None, None

    def handle_starttag(self, tag, attrs):
        if tag == "h2":
            self._id = dict(attrs).get("id", "")
        elif tag == "table" and dict(attrs).get("id"):
            self._id = dict(attrs)["id"]
        elif tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = ""

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._row is not None:
            self._row.append(self._cell.strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.tables.setdefault(self._id, []).append(self._row)
            self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data


def test_booth_report_shows_the_robot_and_part_tables(booth_dir):
    """report.html's per-robot time-and-paint table and per-part table, read back with an HTML
    parser, give metrics.json's figures (to their printed digits); the whole-body film map is
    beside it."""
    m = _metrics(booth_dir)
    p = _Tables()
    p.feed((booth_dir / "report.html").read_text(encoding="utf-8"))
    head, *rows = p.tables["robot-use"]
    assert head[0] == "robot" and [r[0] for r in rows] == list(NAMES)
    for r in rows:
        got = m["robots"][r[0]]
        for col, key in ((1, "painting_share_pct"), (2, "moving_share_pct"),
                         (3, "waiting_share_pct"), (6, "transfer_efficiency_pct")):
            assert float(r[col]) == pytest.approx(got[key], abs=0.005)
        assert float(r[4]) == pytest.approx(got["paint_used_l"], abs=5e-5)
    head, *rows = p.tables["part-film"]
    assert [r[0] for r in rows] == list(m["part_film"])
    for r in rows:
        f = m["part_film"][r[0]]
        assert float(r[2]) == pytest.approx(f["executed_nsd_pct"], abs=0.005)
        assert float(r[4]) == pytest.approx(f["executed_inside_spec_pct"], abs=0.005)
        assert float(r[5]) == pytest.approx(f["loss_pp"], abs=5e-4)
    assert (booth_dir / "body_film.png").stat().st_size > 0


def _npz(path: Path) -> tuple[dict, dict]:
    """(arrays, the `_json` header) of a trajectory or trace file, read with numpy alone."""
    with np.load(path) as z:
        return {k: z[k] for k in z.files if k != "_json"}, json.loads(str(z["_json"]))


def test_booth_report_has_a_section_per_robot_re_measured(booth_dir):
    """The one report writer gives every robot of the booth its own section, and its figures are
    the ones re-measured from the folder's arrays (read with numpy, not paintcell's loaders): the
    own program's length and brush-on time (static_<robot>.npz), the busy share (own program ÷
    the booth cycle of metrics.json), the brush-on share of the booth clock
    (trajectory_<robot>.npz), the peak torque ÷ limit over its own joints of the booth's
    trace.npz, no collision event among its bodies (trace.npz contacts); its reach verdict and
    its RAPID module are named. Each to the digits the report prints."""
    m = _metrics(booth_dir)
    text = (booth_dir / "report.html").read_text(encoding="utf-8")
    trace, head = _npz(booth_dir / "trace.npz")
    names, tau_max = head["meta"]["joint_names"], np.asarray(head["meta"]["tau_max"], float)
    sections = re.findall(r"<section id='robot-([^']+)'>(.*?)</section>", text, re.S)
    assert [s[0] for s in sections] == list(NAMES)
    for i, (name, sec) in enumerate(sections):
        shown = {k: float(v.split()[0]) for v, k in re.findall(
            r"<td>([-\d.]+(?: \S+)?)</td>\s*<td><code>(\w+)</code></td>", sec)}
        static, _ = _npz(booth_dir / f"static_{name}.npz")
        program = float(static["t_s"][-1] - static["t_s"][0])
        dt = float(static["t_s"][1] - static["t_s"][0])
        assert shown["program_s"] == pytest.approx(program, abs=0.005)
        assert shown["busy_share_pct"] == pytest.approx(
            100 * program / m["executed_cycle_time_s"], abs=0.005)
        tracked, _ = _npz(booth_dir / f"trajectory_{name}.npz")
        assert shown["paint_share_pct"] == pytest.approx(100 * tracked["paint_on"].mean(),
                                                         abs=0.005)
        own = [k for k, j in enumerate(names) if j.startswith(f"r{i}/")]
        assert own and shown["max_torque_utilization"] == pytest.approx(
            np.abs(trace["tau_demand"][:, own] / tau_max[own]).max(), abs=0.005)
        brush = re.search(r"Program: ([\d.]+) s cycle time, ([\d.]+) s with the brush on", sec)
        assert float(brush[1]) == pytest.approx(program, abs=0.005)
        assert float(brush[2]) == pytest.approx(static["paint_on"].sum() * dt, abs=0.005)
        hits = [c for c in head["contacts"]
                if any(str(c.get(b, "")).startswith(f"r{i}/") for b in ("body1", "body2"))]
        assert ("No robot contact" in sec) == (not hits)
        assert html.escape(m["robots"][name]["honest_reachability"]["verdict"]) in sec
        assert f"T_{name.upper()}.mod" in sec and (booth_dir / f"T_{name.upper()}.mod").is_file()


def _pose(text: str) -> np.ndarray:
    """(4, 4) of a RAPID pose [[x,y,z],[q1,q2,q3,q4]] [mm] in metres."""
    from scipy.spatial.transform import Rotation

    v = [float(x) for x in re.findall(r"-?[\d.]+(?:E[+-]?\d+)?", text)]
    T = np.eye(4)
    T[:3, 3] = np.asarray(v[:3]) / 1000.0
    w, x, y, z = v[3:7]
    T[:3, :3] = Rotation.from_quat([x, y, z, w]).as_matrix()
    return T


def test_booth_rapid_is_conveyor_tracked_in_the_body_frame(booth_dir):
    """Every robot's module: a conveyor work object (robhold FALSE, ufprog FALSE, ufmec "CNV1"),
    WaitWObj before the first move toward the body and DropWObj right after the last tracked
    move, WaitSyncTask at the start and end; every pass's first target, carried through
    wobjcnv1's frames to the world, is where the robot's static program starts that pass. One
    module also passes rapidchecker's independent RAPID grammar (one: it parses ~1 k lines a
    second)."""
    from paintcell.motion.joint_trajectory import PAINT, JointTrajectory
    from tests.trust_cases import flat, rapid_parse

    tokens = flat(rapid_parse((booth_dir / "T_SIDE_B.mod").read_text()))
    assert {"WaitWObj", "DropWObj", "WaitSyncTask", "ActUnit"} <= set(tokens)
    for name in NAMES:
        text = (booth_dir / f"T_{name.upper()}.mod").read_text()
        lines = [ln.strip() for ln in text.splitlines()]
        wo = re.search(r'PERS wobjdata wobjcnv1 := \[(\w+),(\w+),"(\w+)",(\[\[.*?\]\]),'
                       r'(\[\[.*?\]\])\];', text)
        assert wo and wo.group(1, 2, 3) == ("FALSE", "FALSE", "CNV1")
        tracked = [i for i, ln in enumerate(lines) if ln.endswith(r"\WObj:=wobjcnv1;")]
        moves = [i for i, ln in enumerate(lines) if re.match(r"(MoveAbsJ|MoveL|TriggL) ", ln)]
        pick = lines.index("WaitWObj wobjcnv1;")
        assert moves[0] < lines.index("WaitSyncTask sync_start, booth_tasks;") < pick
        assert pick < moves[1] and lines[tracked[-1] + 1] == "DropWObj wobjcnv1;"
        assert lines.count("DropWObj wobjcnv1;") == 1
        end = lines.index("ENDPROC")
        assert lines[end - 2:end] == ["DeactUnit CNV1;", "WaitSyncTask sync_end, booth_tasks;"]
        # the conveyor's base frame: the world (the line runs along +x); uframe, oframe in it
        T_world_obj = _pose(wo.group(4)) @ _pose(wo.group(5))
        static = JointTrajectory.load_npz(booth_dir / f"static_{name}.npz")
        for mt in re.finditer(r"CONST robtarget p(\d+)_0 := (\[\[[^\]]*\],\[[^\]]*\])", text):
            k = int(mt.group(1))
            T = T_world_obj @ _pose(mt.group(2))
            first = np.flatnonzero((static.segment == PAINT) & (static.pass_index == k))[0]
            np.testing.assert_allclose(T[:3, 3], static.tcp_pos_world[first], atol=2e-5)
            np.testing.assert_allclose(T[:3, :3], static.tcp_rot_world[first], atol=1e-5)
