"""A whole body on a paint line (`paintcell init BODY --line`): the fascias and top panels cut at
the car's centre line between the two sides' robots (each piece's passes re-measured on their
side), their passes run across the car (the planner's start curve measured against the axis),
a side's floor robots kept a stretch of the car apart, and a generated body's panel files
written again from the generator (their areas against the generator's own truth file)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from paintcell.booth.line_allocation import (
    FLOOR_ROBOTS_PER_SIDE,
    LinePanel,
    allocate_line,
)
from paintcell.core.errors import PaintcellError


def _side(name: str, y: float, x0: float, x1: float, n: int = 5) -> LinePanel:
    return LinePanel(name, (0.0, float(np.sign(y)), 0.0), ((x0 + x1) / 2, y, 0.8),
                     np.full(n, 3.0), np.full(n, y), (x0, x1))


def _across(name: str, side: tuple[float, float, float], x: float, n: int,
            y0: float = 0.85, z: float = 0.5) -> LinePanel:
    """A panel whose passes step across the car from y0 to −y0, centred z up [m]."""
    return LinePanel(name, side, (x, 0.0, z), np.full(n, 1.5), np.linspace(y0, -y0, n),
                     (x - 0.2, x + 0.2))


def _body() -> list[LinePanel]:
    return [_across("bumper_f", (1.0, 0.0, 0.0), 2.3, 9),
            _side("fender_l", 0.85, 0.8, 1.8), _side("door_l", 0.85, -1.2, 0.8, 7),
            _side("quarter_l", 0.85, -1.9, -1.2),
            _side("fender_r", -0.85, 0.8, 1.8), _side("door_r", -0.85, -1.2, 0.8, 7),
            _side("quarter_r", -0.85, -1.9, -1.2),
            _across("hood", (0.0, 0.0, 1.0), 1.4, 6, 0.75, 1.0),
            _across("roof", (0.0, 0.0, 1.0), -0.9, 5, 0.7, 1.6),
            _across("tailgate", (-1.0, 0.0, 0.0), -2.2, 5, 0.7, 1.1),   # above the belt
            _across("bumper_r", (-1.0, 0.0, 0.0), -2.3, 8)]


@pytest.mark.parametrize("n", [4, 6, 8, 10])
def test_fascias_and_tops_are_cut_at_the_centre_line(n: int) -> None:
    """Each piece of a panel whose passes step across the car lies on its robot's side: a
    floor or top robot on the left paints only passes at y > 0, on the right only y ≤ 0;
    every pass is painted once; the bumpers are the floor robots', the tailgate (centred above
    the side panels) the top robots'."""
    panels = _body()
    shares = allocate_line(panels, n)
    owned = [np.zeros(len(p.durations_s), int) for p in panels]
    for s in shares:
        for j in s.jobs:
            owned[j.part][j.first:j.end] += 1
            y = panels[j.part].pass_y_m[j.first:j.end]
            if panels[j.part].name in ("bumper_f", "tailgate", "hood", "roof") \
                    and s.zone in ("left", "right", "top_left", "top_right") \
                    and sum(r.zone.startswith("top") for r in shares) != 1:
                assert (y > 0).all() if s.zone.endswith("left") else (y <= 0).all(), \
                    (s.zone, panels[j.part].name, y)
    assert all((o == 1).all() for o in owned)
    def zones(name: str) -> set[str]:
        return {s.zone for s in shares for j in s.jobs if panels[j.part].name == name}

    assert zones("bumper_f") == zones("bumper_r") == {"left", "right"}
    assert zones("tailgate") <= {"top_left", "top_right"} and zones("tailgate")


def test_a_fascia_whose_passes_do_not_cross_the_car_goes_whole_to_one_side() -> None:
    panels = _body()[1:9] + [LinePanel("bumper_f", (1.0, 0.0, 0.0), (2.3, 0.0, 0.6),
                                       np.full(4, 3.0), np.zeros(4), (2.1, 2.5))]
    shares = allocate_line(panels, 4)
    pieces = [(s.zone, j) for s in shares for j in s.jobs if j.part == len(panels) - 1]
    assert len(pieces) == 1 and pieces[0][1].first == 0 and pieces[0][1].end == 4


def test_a_side_takes_no_more_floor_robots_than_its_rail_line_holds() -> None:
    """Counted on the shares, for every count: each side's floor robots, at least one and at
    most `FLOOR_ROBOTS_PER_SIDE`; the rest go to the top zones."""
    panels = _body()
    for n in range(4, 13):
        shares = allocate_line(panels, n)
        for zone in ("left", "right"):
            assert 1 <= sum(s.zone == zone for s in shares) <= FLOOR_ROBOTS_PER_SIDE


def test_pass_orientation_runs_the_planners_passes_along_the_axis() -> None:
    """A fascia curved up and down (a cylinder about the car's y axis, facing −x, as a
    tailgate) and a hood tilted 10° about y: the planner's start curve, at the angle
    `pass_orientation` gives, runs along the axis asked for (projected on the panel)."""
    from paintcell.app.init_line import pass_orientation
    from paintcell.coverage.start_curve import average_normal, select_start_curve
    from paintcell.surface import parts
    from paintcell.surface.analytic import plane

    cyl = parts.cylinder_section(0.025)            # axis x, R = 1 m
    nbar = average_normal(cyl)
    # turn the axis to y and the mean normal to −x
    a = np.cross(nbar, [0.0, 0.0, 1.0])
    R1 = trimesh.transformations.rotation_matrix(np.pi / 2, [0.0, 0.0, 1.0])  # x → y
    n1 = R1[:3, :3] @ nbar
    ang = np.arctan2(np.linalg.norm(np.cross(n1, [-1.0, 0.0, 0.0])), n1 @ [-1.0, 0.0, 0.0])
    R2 = trimesh.transformations.rotation_matrix(ang, np.cross(n1, [-1.0, 0.0, 0.0]))
    tail = cyl.transformed(R2 @ R1)
    del a
    hood = plane(1.2, 1.6, 0.025).transformed(
        trimesh.transformations.rotation_matrix(np.deg2rad(10.0), [0.0, 1.0, 0.0]))
    for surf, axis in ((tail, (0.0, 0.0, 1.0)), (hood, (1.0, 0.0, 0.0))):
        n = average_normal(surf)
        mesh = trimesh.Trimesh(surf.vertices, surf.faces, process=False)
        angle = pass_orientation(mesh, tuple(n), axis)
        sc = select_start_curve(surf, angle)
        want = np.asarray(axis) - (np.asarray(axis) @ n) * n
        assert abs(sc.pass_dir @ want / np.linalg.norm(want)) > np.cos(np.deg2rad(0.5))


def test_a_generated_bodys_panel_files_are_written_again(tmp_path: Path) -> None:
    """`ensure_panel_files` writes every missing panel file; each file's area equals the
    generator's truth file's area of that panel (computed there in mm, float64), and a table
    whose areas the generator does not give is refused in one line."""
    from paintcell.cli.main import main
    from paintcell.surface.body_panels import load_body
    from paintcell.surface.generated_body import ensure_panel_files, generated_origin

    assert main(["generate", "body", "--seed", "1", "--out", str(tmp_path / "car.stl")]) == 0
    truth = {p["name"]: p["area_m2"]
             for p in json.loads((tmp_path / "car.truth.json").read_text())["panels"]}
    panels = load_body(tmp_path / "car.stl")
    assert generated_origin(tmp_path / "car.stl", panels) == {"seed": 1, "read": "mesh"}
    assert generated_origin(tmp_path / "car_panels", load_body(tmp_path / "car_panels")) \
        == {"seed": 1, "read": "panels"}
    # a manifest of two of its panels is not the generator's body
    doc = json.loads((tmp_path / "car_panels" / "body.json").read_text())
    doc["panels"] = doc["panels"][:2]
    (tmp_path / "car_panels" / "two.json").write_text(json.dumps(doc))
    two = tmp_path / "car_panels" / "two.json"
    assert generated_origin(two, load_body(two)) is None

    files = [tmp_path / "line_panels" / f"{i:02d}_{p.name}.stl" for i, p in enumerate(panels)]
    areas = [truth[p.name] for p in panels]
    table = {"seed": 1, "read": "mesh", "areas_m2": areas}
    ensure_panel_files(table, files, "line.toml")
    for f, p in zip(files, panels, strict=True):
        assert trimesh.load(f, force="mesh").area == pytest.approx(truth[p.name], rel=1e-6)
    stamp = [f.stat().st_mtime_ns for f in files]
    ensure_panel_files(table, files, "line.toml")            # all there: nothing written
    assert [f.stat().st_mtime_ns for f in files] == stamp
    files[3].unlink()
    ensure_panel_files(table, files, "line.toml")
    assert files[3].is_file()
    with pytest.raises(PaintcellError) as bad:
        ensure_panel_files({**table, "areas_m2": [a * 1.01 for a in areas]}, files, "line.toml")
    assert "\n" not in str(bad.value) and "--seed 1" in str(bad.value)
    with pytest.raises(PaintcellError):
        ensure_panel_files({"seed": 1, "read": "mesh"}, files, "line.toml")
    # a user's own file where a panel belongs is refused and left as it was, never replaced
    files[5].write_bytes(b"solid mine\nendsolid mine\n")
    with pytest.raises(PaintcellError) as mine:
        ensure_panel_files(table, files, "line.toml")
    assert "\n" not in str(mine.value) and str(files[5]) in str(mine.value)
    assert files[5].read_bytes() == b"solid mine\nendsolid mine\n"


def test_a_generated_bodys_panel_files_stay_in_the_booth_folder(tmp_path: Path) -> None:
    """A booth file's [generated_body] panels outside its folder are refused in one line before
    anything is written (an absolute path, a '..')."""
    from paintcell.booth.booth_data import BoothDataError, _generated_files

    for bad in ("/tmp/elsewhere.stl", "../up.stl", "panels/../../up.stl"):
        d = {"generated_body": {"seed": 1, "read": "mesh", "areas_m2": [1.0]},
             "parts": [{"part": {"file": bad}}]}
        with pytest.raises(BoothDataError) as err:
            _generated_files(d, "line.toml", tmp_path)
        assert "\n" not in str(err.value) and repr(bad) in str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_floor_robots_of_a_side_chase_each_other_down_the_car() -> None:
    """Two floor robots a side: re-measured on the jobs' extents along the car, each robot
    runs its jobs front to rear (centroid x falling), holds its side panels whole (a panel's
    pieces would share one stretch of the car), and every job of the front robot lies ahead of
    every job of the rear robot, so their carriages can keep to disjoint stretches."""
    panels = _body()
    for n in (6, 8):
        shares = allocate_line(panels, n)
        for zone in ("left", "right"):
            side = [s for s in shares if s.zone == zone]
            assert len(side) == 2
            for s in side:
                x = [panels[j.part].centroid_m[0] for j in s.jobs]
                assert x == sorted(x, reverse=True), (zone, x)
                for j in s.jobs:
                    if panels[j.part].name.startswith(("fender", "door", "quarter")):
                        assert (j.first, j.end) == (0, len(panels[j.part].durations_s))
            front = min(panels[j.part].x_span_m[0] for j in side[0].jobs)
            rear = max(panels[j.part].x_span_m[1] for j in side[1].jobs)
            assert rear <= front + 1e-9, (zone, front, rear)


def test_carriage_stretches_keep_neighbours_apart_and_every_pass_reachable() -> None:
    """`carriage_stretches` on random reach intervals (each pass reachable from a carriage
    anywhere in [lo, hi] along x): re-measured, neighbouring stretches are at least the gap
    apart, in order front to rear, and each robot reaches every one of its passes from inside
    its stretch (the pass's interval meets it); where no boundary leaves both robots their
    passes, it says so."""
    from paintcell.app.init_line_robots import carriage_stretches

    rng = np.random.default_rng(5)
    gap = 1.5
    done = refused = 0
    for _ in range(200):
        k = int(rng.integers(2, 4))
        centres = np.sort(rng.uniform(-2.0, 2.0, k))[::-1] + np.arange(k)[::-1] * 0.5
        reach = []
        for c in centres:
            m = int(rng.integers(1, 6))
            mid = c + rng.uniform(-0.4, 0.4, m)
            half = rng.uniform(0.3, 1.2, m)
            reach.append(np.column_stack([mid - half, mid + half]))
        got = carriage_stretches(reach, gap)
        # brute force: a boundary pair exists iff every neighbour pair's room is wide enough
        feasible = all(np.min(reach[i][:, 1]) - np.max(reach[i + 1][:, 0]) >= gap - 1e-12
                       for i in range(k - 1))
        if isinstance(got, str):
            assert not feasible and "apart" in got
            refused += 1
            continue
        assert feasible
        done += 1
        assert got[0][1] == np.inf and got[-1][0] == -np.inf
        for i in range(k - 1):
            assert got[i][0] - got[i + 1][1] >= gap - 1e-9
        for (lo, hi), r in zip(got, reach, strict=True):
            assert np.all(r[:, 1] >= lo - 1e-9) and np.all(r[:, 0] <= hi + 1e-9)
    assert done > 20 and refused > 20


def test_a_body_off_the_lines_frame_is_refused_in_one_line(tmp_path: Path) -> None:
    """The zones tell the sides apart by the sign of y: a whole body off the centre line, a
    side panel on the other side of y = 0 than it faces (a body shifted past half its width),
    or a body turned across the line, is refused naming the offset; a centred one and a partial
    one (one side's panels: no centre line to measure) pass; `init --line` refuses such a body
    before planning, with nothing written."""
    from types import SimpleNamespace

    from paintcell.app.init_line_file import init_line
    from paintcell.booth.line_allocation import CENTRE_TOL_M, check_body_frame

    sides = [(0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0)]

    def body(dy: float) -> tuple[tuple[float, ...], ...]:
        return ((-2.2, -0.87 + dy, 0.3), (2.2, 0.87 + dy, 1.6),
                (0.0, 0.85 + dy, 0.8), (0.0, -0.85 + dy, 0.8), (0.0, dy, 1.6))

    for dy in (0.0, 0.9 * CENTRE_TOL_M):
        lo, hi, *cs = body(dy)
        check_body_frame(lo, hi, sides, cs)
    lo, hi, *cs = body(0.3)
    with pytest.raises(PaintcellError, match=r"y = \+0\.300 m.*by -0\.300 m in y") as off:
        check_body_frame(lo, hi, sides, cs)
    assert "\n" not in str(off.value)
    lo, hi, *cs = body(1.0)                       # the right side panel now at y > 0
    with pytest.raises(PaintcellError, match=r"facing −y lies at y = \+0\.150 m"):
        check_body_frame(lo, hi, sides, cs)
    check_body_frame((-2.2, 0.0, 0.3), (2.2, 0.87, 1.6), sides[:1], [(0.0, 0.85, 0.8)])
    with pytest.raises(PaintcellError, match="length along x"):
        check_body_frame((-0.87, -2.2, 0.3), (0.87, 2.2, 1.6))
    side = trimesh.creation.box((4.0, 0.01, 1.0))
    panels = [SimpleNamespace(name=n, mesh=side.copy().apply_translation((0.0, y, 0.8)),
                              direction=(0.0, float(np.sign(y - 0.4)), 0.0))
              for n, y in (("left", 1.2), ("right", -0.4))]         # centre line at y = 0.4
    out = tmp_path / "line.toml"
    with pytest.raises(PaintcellError, match=r"centre line lies at y = \+0\.400 m"):
        init_line(panels, out, 75.0, 10, False, "shifted.stl", say=lambda s: None)
    assert list(tmp_path.iterdir()) == []


def test_a_carriage_stretch_is_read_checked_and_limits_only_the_planning_rail(
        tmp_path: Path) -> None:
    """`carriage = [lower, upper]` in a booth file: read into `BoothRobot.carriage_m`; the
    planning model's rail is that stretch (within the rail less the tracking's shrink), the
    executing model's the whole rail; a stretch off the rail, or a home off the stretch, is
    refused in one line naming the robot."""
    from paintcell.booth.booth_data import BoothDataError, load_toml_booth
    from paintcell.booth.booth_job_programs import load_robots

    def booth_file(carriage: str, home0: float) -> Path:
        f = tmp_path / "b.toml"
        f.write_text(f"""name = "b"
[[parts]]
part = "roof"
[[robots]]
name = "a"
model = "irb5500"
rail = [-3.0, 3.0]
carriage = {carriage}
home = [{home0}, 0.0, -0.6, 0.9, 0.0, 0.6, 0.0]
[robots.base]
xyz_m = [0.0, 2.5, 0.3]
rpy_rad = [0.0, 0.0, -1.5707963267948966]
""")
        return f

    booth = load_toml_booth(booth_file("[0.5, 2.0]", 1.0))
    assert booth.robots[0].carriage_m == (0.5, 2.0)
    plan = load_robots(booth, 0.0, stretch=True)[0].rail.spec
    assert (plan.lower_m, plan.upper_m) == (0.5, 2.0)
    plan = load_robots(booth, 1.5, stretch=True)[0].rail.spec         # tracking: 3 − 1.5
    assert (plan.lower_m, plan.upper_m) == (0.5, 1.5)
    run = load_robots(booth)[0].rail.spec
    assert (run.lower_m, run.upper_m) == (-3.0, 3.0)
    for carriage, home0, words in (("[0.5, 4.0]", 1.0, "carriage"), ("[0.5, 2.0]", -1.0,
                                                                       "home")):
        with pytest.raises(BoothDataError, match=words) as bad:
            load_toml_booth(booth_file(carriage, home0))
        assert "\n" not in str(bad.value)
