"""`paintcell init` with several robots (`paintcell.app.init_layout`): the part laid crown up,
rails beside it, every layout re-measured here independently of the booth's checks — the arms'
collision capsules posed by MuJoCo's own kinematics of the robot file and measured against the
part's triangle mesh by trimesh — and the written cell re-read by `tomllib`."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from paintcell.app import init_layout
from paintcell.app.init_layout import (
    HOME,
    HOME_CLEARANCE_M,
    PART_LOW_Z_M,
    choose_layout,
    crown_up,
    layout_problem,
    rail_angle,
    rail_robots,
)
from paintcell.booth.booth import BodyPart, Booth
from paintcell.booth.booth_plans import plan_parts
from paintcell.core.errors import PaintcellError
from paintcell.core.placement import Placement
from paintcell.surface.part_import import import_part
from paintcell.surface.part_spec import MeshPart


def _arch(path: Path, yaw_deg: float = 0.0, radius_m: float = 0.8, length_m: float = 1.4,
          half_deg: float = 70.0) -> None:
    """An arch (a cylinder's skin ±half_deg about its axis), crown at z = 0 toward +z, its
    straight axis along x turned by yaw_deg about z; in m."""
    u, v = np.meshgrid(np.linspace(-length_m / 2, length_m / 2, 29),
                       np.radians(np.linspace(-half_deg, half_deg, 41)), indexing="ij")
    V = np.column_stack([u.ravel(), (radius_m * np.sin(v)).ravel(),
                         (radius_m * np.cos(v) - radius_m).ravel()])
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    V = V @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T
    i = np.arange(28)[:, None] * 41 + np.arange(40)[None, :]
    F = np.concatenate([np.column_stack([i.ravel(), (i + 41).ravel(), (i + 1).ravel()]),
                        np.column_stack([(i + 1).ravel(), (i + 41).ravel(), (i + 42).ravel()])])
    trimesh.Trimesh(V, F, process=False).export(path)


@pytest.fixture(scope="module")
def arch(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    path = tmp_path_factory.mktemp("arch") / "arch.stl"
    _arch(path)
    return path, import_part(MeshPart(file=str(path), units="m"), resolution_m=0.025)[0]


def _arm_gap_m(robot_file: Path, T_world_base: np.ndarray, q: np.ndarray,
               part: trimesh.Trimesh) -> float:
    """Smallest distance [m] between the robot's collision geoms (capsules, cylinders, boxes,
    spheres) at joint values q — posed by MuJoCo's kinematics of its own file, each drawn as a
    trimesh solid and sampled on its surface — and the part's triangles (trimesh)."""
    m = mujoco.MjModel.from_xml_path(str(robot_file))
    d = mujoco.MjData(m)
    d.qpos[:len(q)] = q
    mujoco.mj_kinematics(m, d)
    G = mujoco.mjtGeom
    pts = []
    for g in range(m.ngeom):
        if (m.geom_contype[g] | m.geom_conaffinity[g]) == 0:
            continue
        size, kind = m.geom_size[g], m.geom_type[g]
        if kind == G.mjGEOM_CAPSULE:
            solid = trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[16, 24])
            solid.apply_translation(-solid.bounds.mean(0))   # centred, as MuJoCo's
        elif kind == G.mjGEOM_CYLINDER:
            solid = trimesh.creation.cylinder(radius=size[0], height=2 * size[1], sections=32)
        elif kind == G.mjGEOM_BOX:
            solid = trimesh.creation.box(extents=2 * size[:3]).subdivide().subdivide()
        elif kind == G.mjGEOM_SPHERE:
            solid = trimesh.creation.icosphere(subdivisions=3, radius=size[0])
        else:
            raise AssertionError(f"collision geom type {kind} not drawn here")
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = d.geom_xmat[g].reshape(3, 3), d.geom_xpos[g]
        pts.append(trimesh.transform_points(solid.vertices, T_world_base @ T))
    _, dist, _ = trimesh.proximity.closest_point(part, np.concatenate(pts))
    return float(dist.min())


def test_an_arch_turned_off_the_files_axes_lies_with_its_axis_along_x_and_crown_up(tmp_path):
    path = tmp_path / "turned.stl"
    _arch(path, yaw_deg=40.0)
    surf = import_part(MeshPart(file=str(path), units="m"), resolution_m=0.025)[0]
    R, why = crown_up(surf)
    axis = np.array([np.cos(np.radians(40.0)), np.sin(np.radians(40.0)), 0.0])
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-9) and np.linalg.det(R) == pytest.approx(1.0)
    assert abs((R @ axis)[0]) > 0.99            # the straight axis along the rails (x)
    assert (R @ [0.0, 0.0, 1.0])[2] > 0.99       # the crown up
    assert "kept" not in why                    # 40° off the file's axes: not snapped


def test_an_arch_square_to_the_files_axes_keeps_them(arch):
    R, why = crown_up(arch[1])
    assert np.allclose(R, np.eye(3)) and "kept" in why


def test_passes_at_the_rail_angle_run_along_the_rails(tmp_path):
    """The planner's orientation from `rail_angle`, on an arch turned 40° off the file's axes:
    every pass's on-part chord, laid by crown_up's rotation, runs along world x within 5°."""
    from paintcell.coverage.algorithm import plan_coverage
    from paintcell.coverage.coverage_settings import PlannerSettings
    from paintcell.paint.applicator import Applicator

    path = tmp_path / "turned.stl"
    _arch(path, yaw_deg=40.0, half_deg=40.0)
    surf = import_part(MeshPart(file=str(path), units="m"), resolution_m=0.025)[0]
    R, _ = crown_up(surf)
    st = PlannerSettings(orientation=rail_angle(surf, R), film_refine=False,
                         optimize_speed=False)
    plan = plan_coverage(surf.region_surface(("skin",)), Applicator.default(), st)
    over = [p.positions[np.asarray(p.on_part, bool)] for p in plan.passes]
    over = [on for on in over if len(on) >= 2]       # an edge pass runs wholly past the part
    assert len(over) >= 3
    for on in over:
        d = R @ (on[-1] - on[0])
        assert abs(d[0]) / np.linalg.norm(d) > np.cos(np.radians(5.0)), d


def test_a_pass_is_as_long_as_its_run_over_the_part():
    """A pass 1 m long at 0.1 m steps whose samples 2–7 lie over the part: 0.5 m; the run past
    the part's ends (the overspray a table asks for) is no run round the part."""
    from types import SimpleNamespace

    x = np.arange(11) * 0.1
    on = (np.arange(11) >= 2) & (np.arange(11) <= 7)
    plan = SimpleNamespace(passes=[SimpleNamespace(positions=np.column_stack(
        [x, np.zeros(11), np.full(11, 0.25)]), on_part=on)])
    assert init_layout._pass_length(plan, 0) == pytest.approx(0.5, abs=1e-12)


def test_a_programs_joint_jumps_are_the_poses_over_the_ik_reports_threshold():
    """Poses whose jump exceeds the report's own threshold, a missing pose (None) not counted;
    a program without a report has none."""
    from types import SimpleNamespace

    rep = {"thresholds": {"max_joint_jump_rad": 0.2},
           "poses": {"joint_jump_rad": [0.0, 0.05, 0.2, 0.2015, None, 0.9, 0.199]}}
    assert init_layout._jumps(SimpleNamespace(meta={"reachability": rep})) == 2
    assert init_layout._jumps(SimpleNamespace(meta={})) == 0


@pytest.mark.parametrize("n", [2, 3, 4])
def test_rails_stand_beside_the_part_facing_it_and_share_its_length(n):
    lo, hi = np.array([-0.9, -1.1, 1.0]), np.array([0.9, 1.1, 2.0])
    robots = rail_robots(n, lo, hi, gap_m=1.3, drop_m=0.45)
    assert len(robots) == n and len({r.name for r in robots}) == n
    for side in (+1, -1):
        mine = sorted((r for r in robots if np.sign(r.base.xyz_m[1]) == side),
                      key=lambda r: r.base.xyz_m[0])
        assert len(mine) == ((n + 1) // 2 if side > 0 else n // 2)
        for r in mine:
            T = r.base.matrix
            assert T[1, 3] == pytest.approx(hi[1] + 1.3 if side > 0 else lo[1] - 1.3, abs=1e-4)
            assert T[2, 3] == pytest.approx(hi[2] - 0.45, abs=1e-4)
            assert T[:3, 0] @ [0.0, -side, 0.0] == pytest.approx(1.0)   # the arm faces the part
            assert abs(T[:3, 1] @ [1.0, 0.0, 0.0]) == pytest.approx(1.0)  # carriage along x
        # each side's carriages sweep disjoint shares of the part's length, inside it
        spans = [(r.base.xyz_m[0] + r.rail_m[0], r.base.xyz_m[0] + r.rail_m[1]) for r in mine]
        assert all(a[1] <= b[0] + 1e-9 for a, b in zip(spans, spans[1:], strict=False))
        if len(mine) > 1:
            assert spans[0][0] >= lo[0] - 1e-9 and spans[-1][1] <= hi[0] + 1e-9


@pytest.fixture(scope="module")
def planned(arch):
    path, surf = arch
    pl = Placement((0.0, 0.0, PART_LOW_Z_M - float(surf.vertices[:, 2].min())))
    part = BodyPart("arch", pl, {**init_layout.PLANNER_TRIES[0], "film_refine": False},
                    mesh=MeshPart(file=str(path), units="m"))
    lo = surf.vertices.min(0) + pl.xyz_m
    hi = surf.vertices.max(0) + pl.xyz_m
    booth = Booth("arch", (part,), tuple(rail_robots(2, lo, hi, 1.3, 0.1)))
    mesh = trimesh.load(path)
    mesh.apply_translation(pl.xyz_m)
    return booth, plan_parts(booth, fast=True), lo, hi, mesh


def test_a_clear_layout_is_clear_when_measured_independently(planned):
    from paintcell.booth.booth_programs import load_robots

    booth, pp, lo, hi, mesh = planned
    problem, reach = layout_problem(booth, pp)
    assert problem is None
    n = len(pp.plans[0].passes)
    assert all(0 < k <= n for k in reach) and sum(reach) >= n
    from paintcell.booth.booth_clearance import BodyProbe

    origins = []
    T_part = booth.parts[0].placement.matrix
    for robot, br in zip(load_robots(booth), booth.robots, strict=True):
        probe = BodyProbe(robot, pp.surfaces[0], T_part, np.zeros(len(pp.surfaces[0].vertices)))
        for s in (br.rail_m[0], 0.0, br.rail_m[1]):
            q = np.array([s, *HOME[1:]])
            gap = _arm_gap_m(robot.mjcf_path, br.base.matrix, q, mesh)
            assert gap >= HOME_CLEARANCE_M - 0.01
            # the booth's MuJoCo distance and this one agree where the arm is near the part
            assert gap == pytest.approx(probe.distance(q[None], 2.0), abs=0.03)
        robot.fk(np.array([0.0, *HOME[1:]]))
        origins.append(np.array([o.translation for o in robot.pin_data.oMi[1:]]))
    # the two arms at home, joint origin to joint origin, farther than the bell distance
    gap = np.linalg.norm(origins[0][:, None] - origins[1][None], axis=2).min()
    assert gap >= booth.thresholds.min_bell_distance_m


def test_an_arm_at_home_near_the_part_is_refused_with_the_distance_measured_here(
        planned, monkeypatch):
    import re

    from paintcell.booth.booth_programs import load_robots

    booth, pp, lo, hi, mesh = planned
    monkeypatch.setattr(init_layout, "HOME", (0.0, 0.0, 0.9, 0.0, 0.0, 0.0, 0.0))  # leaning out
    problem, _ = layout_problem(booth, pp)
    found = re.fullmatch(r"left at home comes (-?\d+) mm from the part", problem or "")
    assert found, problem
    robot, br = load_robots(booth)[0], booth.robots[0]
    gap = min(_arm_gap_m(robot.mjcf_path, br.base.matrix, np.array([s, *init_layout.HOME[1:]]),
                         mesh) for s in (br.rail_m[0], 0.0, br.rail_m[1]))
    assert gap < HOME_CLEARANCE_M
    assert gap == pytest.approx(int(found[1]) / 1e3, abs=0.03)


def test_arms_at_home_that_meet_each_other_are_refused(planned, monkeypatch):
    import re

    from paintcell.booth.booth_programs import load_robots

    booth, pp, lo, hi, mesh = planned
    monkeypatch.setattr(init_layout, "HOME", (0.0, 0.0, 0.6, 0.3, 0.0, 0.9, 0.0))  # bells out
    problem, _ = layout_problem(booth, pp)
    found = re.fullmatch(r"left and right at home come (\d+\.\d+) m apart \(< 0.8 m\)",
                         problem or "")
    assert found, problem
    points = []
    for robot in load_robots(booth):
        tcp = robot.fk(np.array([0.0, *init_layout.HOME[1:]]))[:3, 3]
        points.append(np.vstack([[o.translation for o in robot.pin_data.oMi[1:]], tcp]))
    apart = np.linalg.norm(points[0][:, None] - points[1][None], axis=2).min()
    assert apart <= float(found[1]) + 0.005 and apart < 0.8


def test_no_layout_up_to_the_cap_is_refused_in_one_line(arch, monkeypatch):
    path, surf = arch
    monkeypatch.setattr(init_layout, "RAIL_GAPS_M", (6.0,))       # rails out of every reach
    monkeypatch.setattr(init_layout, "RAIL_DROPS_M", (0.45,))
    monkeypatch.setattr(init_layout, "PLANNER_TRIES", init_layout.PLANNER_TRIES[:1])
    with pytest.raises(PaintcellError) as err:
        choose_layout("arch", MeshPart(file=str(path), units="m"), surf, (2, 3), say=lambda s: None)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith("no layout of 2 to 3 irb5500 robots on rails paints")
    assert "2 robots:" in msg and "3 robots:" in msg and "out of every robot's reach" in msg
    assert "write the cell by hand" in msg and "--robots N" in msg


def _init(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "paintcell", "init", *args],
                          capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize(("extra", "needle"), [
    (["--robots", "0"], "argument --robots: '0' is out of range: give a whole number ≥ 1 and ≤ 4"),
    (["--robots", "5"], "argument --robots: '5' is out of range: give a whole number ≥ 1 and ≤ 4"),
    (["--robots", "2", "--robot", "ur10"], "several robots need closed-form IK")])
def test_a_bad_robot_count_is_refused_in_one_line_before_any_planning(tmp_path, extra, needle):
    out = tmp_path / "cell.toml"
    r = _init(str(tmp_path / "missing.stl"), "--out", str(out), *extra)
    assert r.returncode != 0 and needle in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not out.exists()


@pytest.mark.slow
def test_init_lays_out_two_robots_and_run_passes_as_written(arch, tmp_path):
    """End to end: `init --robots 2` on the arch, then `run --fast` on the file as written."""
    path = tmp_path / "arch.stl"
    path.write_bytes(arch[0].read_bytes())
    out = tmp_path / "cell" / "arch2.toml"
    out.parent.mkdir()
    r = _init(str(path), "--units", "m", "--robots", "2", "--out", str(out))
    assert r.returncode == 0, r.stderr
    cell = tomllib.loads(out.read_text())
    assert len(cell["robots"]) == 2 and cell["parts"][0]["part"]["file"] == "../arch.stl"
    head = out.read_text().split("\nname =")[0]
    for why in ("Why 2 robots", "Which model", "Where: rails", "Allocation is automatic"):
        assert why in head
    res = tmp_path / "res"
    r = subprocess.run([sys.executable, "-m", "paintcell", "run", str(out), "--fast", "--out",
                        str(res)], capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stdout + r.stderr
    m = json.loads((res / "metrics.json").read_text())
    assert m["passed"] and m["n_collisions"] == 0 and m["n_robot_robot_collisions"] == 0
    for rob in m["robots"].values():
        assert rob["honest_reachability"]["reachability_pct"] == 100.0
    # every pass of the plan painted by exactly one robot: the jobs tile [0, n) without overlap
    jobs = sorted(tuple(j[1:]) for js in m["allocation"]["chosen"].values()
                  for j in (js if isinstance(js[0], list) else [js]))
    n = max(b for _, b in jobs)
    assert jobs[0][0] == 0 and all(a[1] == b[0] for a, b in zip(jobs, jobs[1:], strict=False))
    assert sum(b - a for a, b in jobs) == n


@pytest.mark.slow
def test_a_planner_table_whose_film_is_over_the_spec_gives_way_to_an_even_one(arch, monkeypatch):
    """A table whose passes stand 0.45 m apart (wider than the bell lays an even film across)
    comes first: init plans it, measures its film over the spec and lays the cell out with the
    next table; the σ/μ it gives for each equals the film re-measured here (each table's plan as
    `run` plans it, the bell's film summed over the skin, σ/μ area-weighted by hand)."""
    from paintcell.app.init_toml import SPEC
    from paintcell.coverage import family_geometry
    from paintcell.paint.deposition import thickness

    path, surf = arch
    wide = {"orientation": "zero-curvature", "w_min_m": 0.45, "w_max_m": 0.45}
    even = dict(init_layout.PLANNER_TRIES[0])
    monkeypatch.setattr(init_layout, "PLANNER_TRIES", (wide, even))
    mesh = MeshPart(file=str(path), units="m")
    cell = choose_layout("arch", mesh, surf, (2,), say=lambda s: None)
    family_geometry.forget()                # each plan made again here, not taken from init's
    nsd = []
    for table in (wide, even):
        booth = Booth(name="arch", parts=(BodyPart("arch", Placement((0.0,) * 3, (0.0,) * 3),
                                                   table, mesh=mesh),),
                      robots=cell.booth.robots)
        pp = plan_parts(booth, fast=True)
        skin = pp.surfaces[0].region_surface(("skin",))
        f = thickness(pp.plans[0].applicator, pp.plans[0].gun_samples(), skin.vertices,
                      skin.normals)
        w = skin.vertex_areas
        mean = (w @ f) / w.sum()
        nsd.append(100.0 * float(np.sqrt((w @ (f - mean) ** 2) / w.sum()) / mean))
    assert nsd[0] > SPEC.max_nsd_pct >= nsd[1]
    assert cell.planner == even
    assert f"planner table 1 lays a film of {nsd[0]:.1f} % σ/μ" in cell.why["plan"]
    assert cell.planned_nsd_pct == pytest.approx(nsd[1], rel=1e-9)
