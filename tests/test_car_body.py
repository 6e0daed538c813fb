"""The generated car body (`paintcell generate body`) and reading a body into its panels
(`paintcell.surface.body_panels.load_body`), against independent truth: the written files read
back with trimesh's own readers, panel areas against the truth file and against closed forms (a
developed cylinder keeps its outline's area; a bumper's area from its wrap), the gaps re-measured
between the panels' surfaces, and the panels `load_body` finds in one mesh against those the
truth names."""

from __future__ import annotations

import itertools
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.integrate import quad
from scipy.spatial import cKDTree

from paintcell.cli.main import main
from paintcell.core.errors import PaintcellError
from paintcell.surface.body_panels import SIDE_DIRECTIONS, BodyError, load_body

_BODIES: dict[int, dict] = {}


def _generated(seed: int, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """`paintcell generate body --seed N` written to a folder (once per module), its truth read
    back and the body read with `load_body`."""
    if seed not in _BODIES:
        d = tmp_path_factory.mktemp(f"body{seed}")
        assert main(["generate", "body", "--seed", str(seed), "--out", str(d / "body.stl")]) == 0
        truth = json.loads((d / "body.truth.json").read_text())
        _BODIES[seed] = {"dir": d, "seed": seed, "truth": truth,
                         "panels": {r["name"]: r for r in truth["panels"]},
                         "loaded": load_body(d / "body.stl")}
    return _BODIES[seed]


@pytest.fixture(scope="module", params=[0, 1], ids=["compact", "suv"])
def body(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The compact (seed 0) and the SUV (seed 1)."""
    return _generated(request.param, tmp_path_factory)


@pytest.fixture(scope="module")
def compact(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The compact body alone, for what the body's kind does not change (the reader)."""
    return _generated(0, tmp_path_factory)


def _panel_mesh(body: dict, name: str) -> trimesh.Trimesh:
    return trimesh.load(body["dir"] / "body_panels" / f"{name}.stl", force="mesh")


def test_kind_size_and_frame(body: dict) -> None:
    t = body["truth"]
    assert t["seed"] == body["seed"] and t["units"] == "mm"
    m = trimesh.load(body["dir"] / "body.stl", force="mesh")
    lo, hi = m.bounds
    length, width, height = hi - lo
    # origin on the floor under the body's centre (the bumpers stand in from the plan outline
    # by different amounts), the car's front at +x
    assert abs(lo[0] + hi[0]) < 30.0 and abs(lo[1] + hi[1]) < 1e-6 and 150 < lo[2] < 400
    names = set(body["panels"])
    if body["seed"] % 2 == 0:
        assert t["kind"] == "compact" and "trunk_lid" in names and "tailgate" not in names
        assert 4100 < length < 4400 and 1650 < width < 1800 and height + lo[2] < 1520
    else:
        assert t["kind"] == "suv" and "tailgate" in names and "trunk_lid" not in names
        assert 4200 < length < 4450 and height + lo[2] > 1580
    front = m.vertices[:, 0] > hi[0] - 50
    assert m.vertices[front, 2].max() < 900   # the front bumper is the body's foremost panel


def test_panel_files_hold_the_truths_areas(body: dict) -> None:
    t = body["truth"]
    assert len(body["panels"]) == 13
    manifest = json.loads((body["dir"] / "body_panels" / "body.json").read_text())
    assert manifest["units"] == "mm"
    assert {p["name"] for p in manifest["panels"]} == set(body["panels"])
    total = 0.0
    for rec in manifest["panels"]:
        m = _panel_mesh(body, rec["name"])
        r = body["panels"][rec["name"]]
        assert m.area / 1e6 == pytest.approx(r["area_m2"], rel=1e-6)
        assert np.allclose(m.bounds, r["bbox_mm"], atol=1e-3)  # float32 in the STL
        assert rec["side"] == r["side"]
        assert rec["placement"] == {"xyz_m": [0.0, 0.0, 0.0], "rpy_rad": [0.0, 0.0, 0.0]}
        # faces wound toward the painter: the mean normal leans to the side named
        n = (m.face_normals * m.area_faces[:, None]).sum(0)
        assert n @ SIDE_DIRECTIONS[r["side"]] / np.linalg.norm(n) > 0.9
        total += m.area / 1e6
    whole = trimesh.load(body["dir"] / "body.stl", force="mesh")
    assert whole.area / 1e6 == pytest.approx(total, rel=1e-6)
    assert total == pytest.approx(t["total_area_m2"], rel=1e-6)
    assert 10.0 <= total <= 12.0


def test_developed_panels_keep_their_outline_area(body: dict) -> None:
    """The wall is a cylinder along the sides and the rear, so a panel cut from its developed
    plane has its outline's area (the triangles' chords lose a little to the curvature)."""
    developed = [r for r in body["truth"]["panels"] if "developed_area_m2" in r]
    assert len(developed) == 8 + (body["seed"] % 2)
    for r in developed:
        assert r["area_m2"] == pytest.approx(r["developed_area_m2"], rel=2e-3), r["name"]
    doors = [r for r in developed if "door" in r["name"]]
    assert all(len(r["openings_m2"]) == 1 and r["openings_m2"][0] > 0.15 for r in doors)


def test_bumper_area_matches_its_closed_form(body: dict) -> None:
    """A fascia is the wall over the arc length ±S of its plan outline (two 90° corners of
    radius Rc) between heights z0 and z1; the wall lies inset(z) inside the outline, so
    area = 2 S ∫ √(1 + inset'²) dz − π ∫ inset √(1 + inset'²) dz over [z0, z1]."""
    w = body["truth"]["wall"]
    zb, r_low, r_top = w["z_belt_mm"], w["R_low_mm"], w["R_top_mm"]

    def inset(z: float) -> float:
        return (z - zb) ** 2 / (2 * (r_low if z < zb else r_top))

    def slope(z: float) -> float:
        return (z - zb) / (r_low if z < zb else r_top)

    for name in ("front_bumper", "rear_bumper"):
        r = body["panels"][name]
        z0, z1 = r["z_mm"]
        run = quad(lambda z: np.sqrt(1 + slope(z) ** 2), z0, z1)[0]
        lost = quad(lambda z: inset(z) * np.sqrt(1 + slope(z) ** 2), z0, z1)[0]
        closed = (2 * r["s_half_mm"] * run - r["corner_turn_rad"] * lost) / 1e6
        assert r["area_m2"] == pytest.approx(closed, rel=3e-3), name


def _gap(a: trimesh.Trimesh, b: trimesh.Trimesh) -> float:
    """Closest distance between two panels' surfaces [mm]: each one's vertices near the other
    projected onto its triangles."""
    best = np.inf
    for p, q in ((a, b), (b, a)):
        near = cKDTree(q.vertices).query(p.vertices, distance_upper_bound=100.0)[0]
        if np.isfinite(near).any():
            best = min(best, float(trimesh.proximity.closest_point(
                q, p.vertices[np.isfinite(near)])[1].min()))
    return best


def test_gaps_between_neighbours_are_the_drawn_gaps(body: dict) -> None:
    meshes = {n: _panel_mesh(body, n) for n in body["panels"]}
    joints = body["truth"]["joints"]
    assert len(joints) == 20
    for j in joints:
        a, b = j["panels"]
        measured = _gap(meshes[a], meshes[b])
        assert 3.0 <= measured <= 5.0, (a, b, measured)
        assert measured == pytest.approx(j["gap_mm"], abs=0.1), (a, b)
    # every other pair of panels is well apart: the joints are exactly the neighbours
    pairs = {frozenset(j["panels"]) for j in joints}
    for a, b in itertools.combinations(meshes, 2):
        if frozenset((a, b)) not in pairs:
            d = cKDTree(meshes[a].vertices).query(meshes[b].vertices)[0].min()
            assert d > 20.0, (a, b, d)


def test_load_body_finds_the_truths_panels(body: dict) -> None:
    panels = body["loaded"]
    assert [p.name for p in panels] == sorted(body["panels"])
    for p in panels:
        r = body["panels"][p.name]
        assert p.area_m2 == pytest.approx(r["area_m2"], rel=0.01)
        assert p.side == r["side"]
        assert p.direction == SIDE_DIRECTIONS[r["side"]]
        assert np.allclose(p.mesh.bounds, np.asarray(r["bbox_mm"]) / 1e3, atol=1e-6)  # metres
        assert np.dot(p.normal, r["normal_mean"]) > 0.999
        assert p.source.endswith("body.stl")


def test_the_manifest_folder_reads_to_the_same_panels(body: dict) -> None:
    folder = load_body(body["dir"] / "body_panels")
    single = body["loaded"]
    assert [p.name for p in folder] == [p.name for p in single]
    for a, b in zip(folder, single, strict=True):
        assert a.area_m2 == pytest.approx(b.area_m2, rel=1e-9)
        assert a.side == b.side and np.allclose(a.normal, b.normal, atol=1e-9)
        assert np.allclose(a.mesh.bounds, b.mesh.bounds, atol=1e-9)
        assert a.source.endswith(f"{a.name}.stl")


def test_same_seed_same_bytes(body: dict, tmp_path: Path) -> None:
    new = tmp_path / "not" / "yet"  # --out in a folder that does not exist: it is made
    out = new / "again.stl"
    assert main(["generate", "body", "--seed", str(body["seed"]), "--out", str(out)]) == 0
    d = body["dir"]
    assert out.read_bytes() == (d / "body.stl").read_bytes()
    assert (new / "again.truth.json").read_bytes() == (d / "body.truth.json").read_bytes()
    for f in sorted((d / "body_panels").iterdir()):
        assert (new / "again_panels" / f.name).read_bytes() == f.read_bytes(), f.name
    other = tmp_path / "other.stl"
    assert main(["generate", "body", "--seed", str(body["seed"] + 2), "--out", str(other)]) == 0
    assert other.read_bytes() != out.read_bytes()


def test_cracks_join_and_strays_drop(compact: dict, tmp_path: Path) -> None:
    body = compact
    """A panel split into two pieces less than 1 mm apart is one panel; 2 mm apart, two; a clip
    under 1 % of a panel's area is dropped."""
    meshes = {n: _panel_mesh(body, n) for n in sorted(body["panels"])}
    roof = meshes.pop("roof")
    back = roof.triangles_center[:, 0] < np.median(roof.triangles_center[:, 0])

    def split(lift_mm: float) -> list[trimesh.Trimesh]:
        halves = [roof.submesh([np.flatnonzero(k)], append=True) for k in (back, ~back)]
        halves[1].apply_translation([0.0, 0.0, lift_mm])
        return halves

    clip = trimesh.creation.box([20.0, 20.0, 5.0])
    clip.apply_translation(body["panels"]["front_door_left"]["bbox_mm"][1])
    for lift, n_roof in ((0.5, 1), (2.0, 2)):
        parts = [*meshes.values(), *split(lift), clip]
        path = tmp_path / f"split{lift}.stl"
        trimesh.util.concatenate(parts).export(path)
        found = load_body(path)
        assert len(found) == len(body["panels"]) + n_roof - 1
        if n_roof == 1:
            assert [p.name for p in found] == sorted(body["panels"])
            roof_area = next(p.area_m2 for p in found if p.name == "roof")
            assert roof_area == pytest.approx(body["panels"]["roof"]["area_m2"], rel=1e-6)


def test_metres_and_other_formats_read_alike(compact: dict, tmp_path: Path) -> None:
    body = compact
    m = trimesh.load(body["dir"] / "body.stl", force="mesh")
    m.apply_scale(1e-3)
    m.export(tmp_path / "body_m.ply")
    found = load_body(tmp_path / "body_m.ply")
    assert [p.name for p in found] == [p.name for p in body["loaded"]]
    assert [p.area_m2 for p in found] == pytest.approx([p.area_m2 for p in body["loaded"]],
                                                       rel=1e-6)


def _one_line_error(call, match: str) -> str:
    with pytest.raises(PaintcellError) as err:
        call()
    msg = str(err.value)
    assert "\n" not in msg and match in msg, msg
    return msg


def test_bad_inputs_are_one_line_errors(compact: dict, tmp_path: Path) -> None:
    body = compact
    empty = tmp_path / "empty.stl"
    empty.write_bytes(b"")
    _one_line_error(lambda: load_body(empty), "empty")
    lone = tmp_path / "lone"
    lone.mkdir()
    shutil.copy(body["dir"] / "body_panels" / "body.json", lone / "body.json")
    msg = _one_line_error(lambda: load_body(lone), "front_fender_left.stl")
    assert "not in" in msg
    _one_line_error(lambda: load_body(body["dir"] / "body_panels" / "hood.stl"), "1 panel")
    with pytest.raises(BodyError, match="furlong"):
        load_body(body["dir"] / "body.stl", units="furlong")
    _one_line_error(lambda: load_body(tmp_path / "nothing.stl"), "does not exist")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "body.json").write_text('{"panels": [{"name": "hood", "file": "h.stl", '
                                   '"side": "up"}]}')
    _one_line_error(lambda: load_body(bad), "side 'up'")


def test_generate_refuses_to_overwrite_and_inspect_lists_panels(
        body: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = body["dir"]
    before = (d / "body_panels" / "hood.stl").read_bytes()
    (tmp_path / "body.truth.json").write_text("mine")
    assert main(["generate", "body", "--seed", "5", "--out", str(tmp_path / "body.stl")]) == 2
    assert "--force" in capsys.readouterr().err
    assert (tmp_path / "body.truth.json").read_text() == "mine"   # nothing written
    assert not (tmp_path / "body.stl").exists() and not (tmp_path / "body_panels").exists()
    assert (d / "body_panels" / "hood.stl").read_bytes() == before
    # --force replaces regular files only: a link in the panel folder is refused, its target kept
    (tmp_path / "body.truth.json").unlink()
    (tmp_path / "body_panels").mkdir()
    target = tmp_path / "elsewhere.stl"
    target.write_text("keep")
    (tmp_path / "body_panels" / "roof.stl").symlink_to(target)
    assert main(["generate", "body", "--seed", "5", "--out", str(tmp_path / "body.stl"),
                 "--force"]) == 2
    assert "symbolic link" in capsys.readouterr().err
    assert target.read_text() == "keep" and not (tmp_path / "body.stl").exists()
    assert main(["inspect", str(d / "body.stl"), "--body"]) == 0
    out = capsys.readouterr().out
    for name, r in body["panels"].items():
        line = next(x for x in out.splitlines() if x.split()[:1] == [name])
        assert line.split()[1:] == [f"{r['area_m2']:.4f}", r["side"], "1"]
    with pytest.raises(SystemExit):
        main(["generate", "--help"])
    helptext = " ".join(capsys.readouterr().out.split())
    assert "body" in helptext.split("KIND")[1] and "body.json" in helptext
