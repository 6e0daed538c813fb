"""The seeded part families (`paintcell generate FAMILY`): their truth re-measured on the mesh
through independent paths (trimesh's components and volumes, nearest-neighbour gaps, normals,
boundary vertices), in the file's units and frame as a user receives it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from paintcell.surface.cad_like import PART_KINDS
from paintcell.surface.part_families import FAMILIES, make_family_part
from paintcell.surface.sheet_mesh import boundary_edges

SEEDS = (0, 1, 2, 3)


def _part_frame(part) -> tuple[np.ndarray, trimesh.Trimesh]:
    """Vertices back in the part frame [mm] (painted side +z), and the mesh there."""
    t = part.truth
    R = np.asarray(t["R_file_part"])
    scale = 1.0 if t["units"] == "mm" else 1e3
    v = (np.asarray(part.mesh.vertices) * scale) @ R
    return v, trimesh.Trimesh(v, part.mesh.faces, process=False)


@pytest.mark.parametrize("family", FAMILIES)
def test_same_seed_same_part_and_seeds_differ(family: str) -> None:
    a, b, c = (make_family_part(family, s) for s in (5, 5, 6))
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
    assert np.array_equal(a.mesh.faces, b.mesh.faces)
    assert a.truth == b.truth
    assert a.mesh.vertices.shape != c.mesh.vertices.shape or \
        not np.allclose(a.mesh.vertices, c.mesh.vertices)


@pytest.mark.parametrize("family", FAMILIES)
def test_units_orientation_and_painted_side(family: str) -> None:
    units, ups = set(), set()
    for seed in SEEDS:
        p = make_family_part(family, seed)
        t = p.truth
        units.add(t["units"])
        ups.add(t["up_axis"])
        ext = np.ptp(np.asarray(p.mesh.vertices), axis=0).max()
        assert (300 < ext < 4000) if t["units"] == "mm" else (0.3 < ext < 4.0), (seed, ext)
        R = np.asarray(t["R_file_part"])
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-9) and np.isclose(np.linalg.det(R), 1)
        _, m = _part_frame(p)
        skin = m.split(only_watertight=False)[0] if family != "door_solid" else m
        # the painted side faces +z in the part frame: area-weighted normals point up
        n = (skin.face_normals * skin.area_faces[:, None]).sum(0)
        if family != "door_solid":
            assert n[2] > 0.5 * np.linalg.norm(n), (seed, n)
    assert units == {"mm", "m"} and ups == {"z", "y"}


@pytest.mark.parametrize("family", [f for f in FAMILIES if f not in ("door_pieces",
                                                                      "door_solid")])
def test_one_sheet_whose_area_is_the_painted_area(family: str) -> None:
    for seed in SEEDS[:2]:
        p = make_family_part(family, seed)
        _, m = _part_frame(p)
        comps = m.split(only_watertight=False)
        assert len(comps) == 1
        assert m.area / 1e6 == pytest.approx(p.truth["painted_area_m2"], rel=1e-9)
        assert len(p.truth["pieces"]) == 1


@pytest.mark.parametrize("seed", SEEDS)
def test_pieces_their_areas_roles_and_gaps(seed: int) -> None:
    p = make_family_part("door_pieces", seed)
    _, m = _part_frame(p)
    comps = sorted(m.split(only_watertight=False), key=lambda c: -c.area)
    truth = sorted(p.truth["pieces"], key=lambda x: -x["area_m2"])
    assert len(comps) == len(truth)
    assert np.allclose([c.area / 1e6 for c in comps], [x["area_m2"] for x in truth], rtol=1e-6)
    skins = [c for c, x in zip(comps, truth, strict=True) if x["role"] == "skin"]
    strays = [x for x in truth if x["role"] == "stray"]
    assert len(skins) >= 3 and len(strays) >= 3
    assert sum(x["area_m2"] for x in truth if x["role"] == "skin") == \
        pytest.approx(p.truth["painted_area_m2"], rel=1e-9)
    # every frame piece stands off the lower panel by the recorded gap (boundary points lie on
    # the cut lines, so the nearest vertices are the gap apart, up to the rounded corners)
    gap = p.truth["gap_m"] * 1e3
    panel = cKDTree(skins[0].vertices)
    for member in skins[1:]:
        d = panel.query(member.vertices)[0].min()
        near = min(cKDTree(o.vertices).query(member.vertices)[0].min()
                   for o in skins if o is not member)
        assert near == pytest.approx(gap, abs=0.5), (seed, near, gap)
        assert d >= gap - 0.5
    assert 15 <= gap <= 35


@pytest.mark.parametrize("seed", SEEDS[:3])
def test_closed_solid_volume_and_skins(seed: int) -> None:
    p = make_family_part("door_solid", seed)
    _, m = _part_frame(p)
    assert m.is_watertight and m.is_winding_consistent
    t = p.truth
    A, th = t["painted_area_m2"] * 1e6, t["thickness_m"] * 1e3
    # a thin shell of curvature radius ≥ 0.8 m: V = A·t (1 − t·H + …), |t·H| < 4 %
    assert abs(m.volume) == pytest.approx(A * th, rel=0.05)
    assert m.area / 1e6 == pytest.approx(A / 1e6 + t["inner_skin_area_m2"] + t["rim_area_m2"],
                                         rel=1e-9)
    assert t["inner_skin_area_m2"] == pytest.approx(t["painted_area_m2"], rel=0.08)
    assert m.volume > 0        # outward normals: the painted skin faces out of the solid


@pytest.mark.parametrize("seed", SEEDS)
def test_member_widths_on_the_boundary(seed: int) -> None:
    p = make_family_part("door_frame", seed)
    v, m = _part_frame(p)
    b = np.unique(boundary_edges(np.asarray(m.faces)).ravel())
    bu, bw = v[b, 0], v[b, 1]
    widths = {x["name"]: x["width_m"] * 1e3 for x in p.truth["members"]}
    assert all(40 <= w <= 120 for w in widths.values())
    top = bw.max()
    band = (bw > top - 200) & (bw < top - 150) & (bu > 0)
    us = np.sort(np.unique(bu[band].round(3)))[::-1]
    inner = us[us < us[0] - 5][0]
    assert us[0] - inner == pytest.approx(widths["b_pillar"], abs=0.01)
    mid = np.abs(bu) < 100
    ws = np.sort(np.unique(bw[mid].round(3)))[::-1]
    assert ws[0] - ws[ws < ws[0] - 5][0] == pytest.approx(widths["sash_top"], abs=0.01)
    # the window: the opening's area recorded equals the notch left in the frame's outline
    assert p.truth["openings"][0]["area_m2"] > 0.2


@pytest.mark.parametrize("seed", SEEDS)
def test_bumper_wraps_past_120_degrees(seed: int) -> None:
    p = make_family_part("bumper", seed)
    _, m = _part_frame(p)
    n = m.face_normals
    ang = np.degrees(np.arctan2(n[:, 0], n[:, 2]))    # plan-view turn of the outward normal
    # flat faces across the corners' vertical bulge tilt a little past the analytic normals
    assert np.ptp(ang) == pytest.approx(p.truth["wrap_deg"], abs=4.0)
    assert p.truth["wrap_deg"] > 120


@pytest.mark.parametrize("seed", SEEDS)
def test_hood_front_corners_roll_steeply(seed: int) -> None:
    p = make_family_part("hood_rolled", seed)
    _, m = _part_frame(p)
    slope = np.degrees(np.arccos(np.clip(m.face_normals[:, 2], -1, 1)))
    truth = p.truth["max_edge_slope_deg"]
    assert truth - 10 < slope.max() <= truth + 1.0
    assert slope.max() > 45


@pytest.mark.parametrize("family,key", [("roof_sunroof", "sunroof"),
                                        ("fender_arch", "wheel_arch")])
def test_openings_area_against_the_outline(family: str, key: str) -> None:
    p = make_family_part(family, 0)
    v, m = _part_frame(p)
    # projected area of the sheet on the part plane + the opening = the bounding rectangle's
    proj = trimesh.Trimesh(np.c_[v[:, :2], np.zeros(len(v))], m.faces, process=False).area
    box = np.prod(np.ptp(v[:, :2], axis=0))
    opening = next(o for o in p.truth["openings"] if o["name"] == key)["area_m2"] * 1e6
    assert proj + opening == pytest.approx(box, rel=0.01)


def test_generate_writes_the_mesh_and_its_truth(tmp_path: Path) -> None:
    out = tmp_path / "door.obj"
    proc = subprocess.run([sys.executable, "-m", "paintcell", "generate", "door_pieces",
                           "--seed", "2", "--out", str(out)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    truth = json.loads((tmp_path / "door.truth.json").read_text())
    again = make_family_part("door_pieces", 2)
    assert truth == json.loads(json.dumps(again.truth))
    loaded = trimesh.load(out, force="mesh", process=False)
    assert len(loaded.faces) == len(again.mesh.faces)
    # the command line offers exactly the CAD-like kinds and the families
    proc = subprocess.run([sys.executable, "-m", "paintcell", "generate", "--help"],
                          capture_output=True, text=True)
    for kind in (*PART_KINDS, *FAMILIES):
        assert kind in proc.stdout
