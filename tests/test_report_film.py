"""The report's first screen from files: film.npz, the spec-window share, the histogram, the
per-pass table and the human names, checked against numbers built independently."""

from __future__ import annotations

import html
import io
import json
import re
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.output import report
from paintcell.output.report_figures import make_figures
from paintcell.output.report_film import FilmFileError, histogram_png, load_film, save_film
from paintcell.output.report_names import check_reason, headline_rows, number, with_unit
from paintcell.output.report_sections import pass_rows
from paintcell.paint.metrics import uniformity
from paintcell.surface.analytic import plane
from tests.helpers import lattice_share


def _film(tmp_path, planned, executed, areas, judged, target, tol):
    np.savez(tmp_path / "film.npz", planned_thickness_m=planned, executed_thickness_m=executed,
             vertex_areas_m2=areas, judged=judged, target_m=target, tolerance=tol)
    return load_film(tmp_path)


def test_inside_share_by_construction(tmp_path):
    # target 30 µm, ±10 %: window 27–33 µm. Offsets of ±3 % and ±7 % are inside, ±13 % and
    # +20 % outside; the last vertex is inside but not judged.
    rel = np.array([-0.13, -0.07, -0.03, 0.0, 0.03, 0.07, 0.13, 0.20, 0.0])
    areas = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 100.0])
    judged = np.array([True] * 8 + [False])
    ex = 30e-6 * (1 + rel)
    film = _film(tmp_path, np.full(9, 30e-6), ex, areas, judged, 30e-6, 0.1)
    assert film.window_m == pytest.approx((27e-6, 33e-6))
    assert film.inside_pct() == pytest.approx(100 * (2 + 3 + 4 + 5 + 6) / 36)
    assert film.below_above_pct() == pytest.approx((100 * 1 / 36, 100 * 15 / 36))
    assert film.inside_pct("planned") == pytest.approx(100.0)


def test_save_film_matches_planning_metrics(tmp_path):
    """film.npz written from a surface and a report agrees with
    paintcell.paint.metrics.uniformity."""
    s = plane(0.6, 0.4, resolution_m=0.05)
    x = s.vertices[:, 0]
    planned = 20e-6 + 3e-6 * np.cos(9 * x)
    executed = planned * (1 + 0.08 * np.sin(13 * x))
    u_p = uniformity(planned, s.vertex_areas, tolerance=0.05)
    u_e = uniformity(executed, s.vertex_areas, target_m=u_p.mean_m, tolerance=0.05)
    rep = SimpleNamespace(planned_thickness_m=planned, executed_thickness_m=executed,
                          metrics={"planned_mean_um": 1e6 * u_p.mean_m,
                                   "tolerance_fraction": 0.05})
    save_film(tmp_path / "film.npz", s, rep)
    film = load_film(tmp_path)
    assert film is not None and film.judged.all() and film.faces is not None
    assert 0 < film.inside_pct() < 100
    # the share over the faces, the film linear on each: against a brute-force lattice
    lo, hi = film.window_m
    assert film.inside_pct() == pytest.approx(lattice_share(executed, s.vertices, s.faces,
                                                            lo, hi, n=40), abs=0.1)
    # a file without the surface: the share lumped on the vertex areas, as uniformity's
    with np.load(tmp_path / "film.npz") as z:
        old = {k: z[k] for k in z.files if k not in ("vertices_m", "faces", "judged_faces")}
    np.savez(tmp_path / "film.npz", **old)
    film = load_film(tmp_path)
    assert film is not None and film.faces is None
    assert film.inside_pct() == pytest.approx(100 * u_e.within_tolerance_fraction, abs=1e-9)
    png = histogram_png(film, (400, 300))
    with Image.open(io.BytesIO(png)) as im:
        assert im.size == (400, 300)


def test_bad_film_file_is_a_clear_error(tmp_path):
    (tmp_path / "film.npz").write_bytes(b"not a zip")
    with pytest.raises(FilmFileError, match="paintcell validate"):
        load_film(tmp_path)
    assert load_film(tmp_path / "nowhere") is None


def test_human_numbers():
    assert with_unit(0.00170501 * 100, "pp") == "0.17 pp"
    assert number(0.0012, 2) == "0.001" and number(0.0, 2) == "0.00"
    assert number(6.2e-5, 2) == "0.00006" and number(-0.004, 2) == "-0.004"
    rows = dict(headline_rows({"hem_executed_mean_um": 18.04, "loss_pp": 0.17}))
    assert ("Hem mean film, executed", "18.0 µm", "hem_executed_mean_um") in next(
        v for k, v in rows.items() if k.startswith("Hems"))
    assert with_unit(None, "s") == "—" and with_unit(3, "events") == "3 events"
    reason = check_reason({"name": "reachability", "value": 97.5, "limit": 100.0, "unit": "%",
                           "kind": "min", "detail": "2 poses out of reach"})
    assert reason == "Reachability 97.5 % is below the minimum 100.0 % (2 poses out of reach)"
    assert check_reason({"name": "uniformity loss", "value": 1.534, "limit": 1.0, "unit": "pp",
                         "kind": "max"}) == "Uniformity loss 1.53 pp is above the limit 1.00 pp"


def _traj(n_pass: int) -> JointTrajectory:
    """Two passes of 1 s at 1 kHz; pass 1 slowed on its second half."""
    k, n = 2 * 1000, 6
    t = np.arange(k) * 1e-3
    pidx = np.repeat(np.arange(n_pass), k // n_pass)
    v = np.where(pidx == 0, 0.4, np.linspace(0.3, 0.5, k))
    summary = ({"pass": 0, "duration_s": 1.0, "slowed_fraction": 0.0, "n_slowdowns": 0,
                "max_speed_deficit_pct": 0.0},
               {"pass": 1, "duration_s": 1.25, "slowed_fraction": 0.5, "n_slowdowns": 1,
                "max_speed_deficit_pct": 20.0})
    return JointTrajectory(
        t_s=t, q=np.zeros((k, n)), qd=np.zeros((k, n)), qdd=np.zeros((k, n)),
        tcp_pos_world=np.zeros((k, 3)), tcp_rot_world=np.tile(np.eye(3), (k, 1, 1)),
        v_tcp_planned=v, paint_on=np.ones(k, bool), pass_index=pidx,
        segment=np.ones(k, int), s_pass_m=np.zeros(k), robot_name="abb_paint",
        joint_names=tuple(f"j{i}" for i in range(n)), pass_summary=summary)


def test_first_screen_from_files(tmp_path):
    d = tmp_path
    metrics = {"passed": False, "loss_pp": 1.534, "executed_within_tolerance_pct": 61.25,
               "executed_nsd_pct": 7.123, "executed_cycle_time_s": 22.59,
               "checks": [{"name": "uniformity loss", "value": 1.534, "limit": 1.0,
                           "unit": "pp", "passed": False, "kind": "max"}]}
    (d / "metrics.json").write_text(json.dumps(metrics))
    (d / "plan.json").write_text(json.dumps({"passes": [
        {"side": 0, "index_width_m": None, "length_m": 0.5},
        {"side": 1, "index_width_m": 0.21, "length_m": 0.5, "max_turn_deg": 37.4}]}))
    _traj(2).save_npz(d / "trajectory.npz")
    rel = np.array([-0.2, 0.0, 0.05, 0.3])
    _film(d, np.full(4, 25e-6), 25e-6 * (1 + rel), np.array([1.0, 1.0, 2.0, 4.0]),
          np.ones(4, bool), 25e-6, 0.1)
    rows = pass_rows(d)
    assert rows[1]["index_width_m"] == 0.21
    assert rows[1]["planned_speed_min_m_s"] == pytest.approx(0.4, abs=1e-3)  # second half
    assert rows[1]["planned_speed_max_m_s"] == pytest.approx(0.5)
    assert rows[1]["mean_speed_m_s"] == pytest.approx(0.5 / 1.25)
    raw = html.unescape(report.write_report(d).read_text(encoding="utf-8"))
    text = re.sub(r"<[^>]+>", "", raw)
    assert "Verdict: FAIL" in text
    assert "Uniformity loss 1.53 pp is above the limit 1.00 pp" in text
    assert "Loss of uniformity plan → execution" in text and "1.53 pp" in text
    m = re.search(r'id="inside-pct">([0-9.]+) %<', raw)
    assert m is not None and float(m.group(1)) == pytest.approx(100 * 3 / 8, abs=0.05)
    assert "2 passes" in text and "1 (50 % of pass, −20 %)" in text
    assert "210" in text  # index width in mm
    assert rows[1]["max_turn_deg"] == 37.4 and rows[0]["max_turn_deg"] is None
    assert "37.4" in text   # the pass's sharpest turn, as plan.json says
    assert "start curve" in text and "1 right" in text


def test_spec_map_render_colours_the_window(tmp_path):
    """Executed film on a plate: left half 30 % thin (below the ±10 % window: blue), right half
    on target (inside: green); the spec render shows both hues and is the first-screen map."""
    s = plane(0.6, 0.4, resolution_m=0.02)
    x = s.vertices[:, 0]
    film = np.where(x < 0.0, 0.7 * 25e-6, 25e-6)
    rep = SimpleNamespace(planned_thickness_m=np.full(len(x), 25e-6), executed_thickness_m=film,
                          metrics={"planned_mean_um": 25.0, "tolerance_fraction": 0.1})
    files = make_figures(tmp_path, surface=s, report=rep, size=(200, 150),
                                index_curve=False)
    assert tmp_path / "render_executed_spec.png" in files
    img = np.asarray(Image.open(tmp_path / "render_executed_spec.png").convert("RGB"), int)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    blue = np.count_nonzero((b > r + 40) & (b > g + 20))
    green = np.count_nonzero((g > r + 40) & (g > b + 20))
    red = (r > g + 60) & (r > b + 60)
    assert blue > 500 and green > 500, (blue, green)
    w = img.shape[1]
    assert not red[:, : 2 * w // 3].any()  # nothing above the window (red: the colour bar only)
    assert red[:, 2 * w // 3:].any()
    save_film(tmp_path / "film.npz", s, rep)
    (tmp_path / "metrics.json").write_text(json.dumps({"passed": True, "checks": []}))
    text = report.write_report(tmp_path).read_text(encoding="utf-8")
    assert 'alt="render_executed_spec.png"' in text.split('id="film-histogram"')[0]


def test_report_names_the_pieces_painted_and_not(tmp_path):
    """metrics.json's pieces (a part file in pieces, a closed solid's back skin) become a table
    with their areas; the verdict's reason names the figure that missed the spec and by how
    much."""
    metrics = {"passed": False, "executed_inside_spec_pct": 84.25, "executed_nsd_pct": 6.1,
               "painted_area_m2": 0.6, "not_painted_area_m2": 0.45, "judged_area_m2": 0.58,
               "pieces": [
                   {"piece": "0", "area_m2": 0.48, "painted": True, "why": "the largest piece",
                    "on_painted_side": True},
                   {"piece": "1", "area_m2": 0.12, "painted": True, "on_painted_side": True,
                    "why": "joined: 12.0 mm from the part, facing its painted side"},
                   {"piece": "2", "area_m2": 0.0018, "painted": False, "on_painted_side": False,
                    "why": "stray bit: 0.0018 m², under 1 % of the largest piece"},
                   {"piece": "0 back side", "area_m2": 0.4482, "painted": False,
                    "on_painted_side": False, "why": "the back (inner) skin of a closed solid"}],
               "checks": [{"name": "film in spec window", "value": 84.25, "limit": 90.0,
                           "unit": "%", "passed": False, "kind": "min",
                           "detail": "5.8 points short: 84.2 % of the judged area in "
                                     "24.0–36.0 µm"}]}
    (tmp_path / "metrics.json").write_text(json.dumps(metrics))
    raw = html.unescape(report.write_report(tmp_path).read_text(encoding="utf-8"))
    text = re.sub(r"<[^>]+>", " ", raw)
    assert "Film in spec window 84.2 % is below the minimum 90.0 % (5.8 points short" in \
        re.sub(r"\s+", " ", text)
    assert "area in spec window 84.2 %" in re.sub(r"\s+", " ", text)
    table = raw[raw.index('id="piece-table"'):]
    table = table[:table.index("</table>")]
    rows = re.findall(r"<tr>(.*?)</tr>", table, re.S)[1:]
    cells = [re.findall(r"<td>(.*?)</td>", r) for r in rows]
    assert [c[0] for c in cells] == ["0", "1", "2", "0 back side"]
    assert [c[1] for c in cells] == ["0.4800", "0.1200", "0.0018", "0.4482"]
    assert [("not painted" in c[2]) for c in cells] == [False, False, True, True]
