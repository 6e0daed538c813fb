"""`[part] pieces = "auto"` (paintcell.surface.pieces, part_import): pieces that lie close and
face the painted side are one part, stray bits and far, hidden or sideways pieces are left out
and named; a closed thin solid paints and judges its outer skin alone. Truth from the
generators below (flat grids: their areas are exact)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from paintcell.output.report_figures import judged_view
from paintcell.surface.part_import import import_part
from paintcell.surface.part_spec import MeshPart, PartSpecError
from paintcell.surface.regions import face_areas
from paintcell.validation.painted_side import (
    painted_side_checks,
    painted_side_metrics,
    parts_painted_side,
)


def _grid(x0: float, x1: float, y0: float, y1: float, z: float = 0.0, h: float = 0.02,
          flip: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """A flat rectangle [x0, x1] × [y0, y1] at height z [m], triangles of ~h, wound +z
    (flip: −z)."""
    nx, ny = max(2, round((x1 - x0) / h) + 1), max(2, round((y1 - y0) / h) + 1)
    x, y = np.meshgrid(np.linspace(x0, x1, nx), np.linspace(y0, y1, ny), indexing="ij")
    v = np.c_[x.ravel(), y.ravel(), np.full(x.size, z)]
    a = (np.arange(nx - 1)[:, None] * ny + np.arange(ny - 1)[None, :]).ravel()
    f = np.r_[np.c_[a, a + ny, a + ny + 1], np.c_[a, a + ny + 1, a + 1]]
    return v, (f[:, ::-1] if flip else f)


def _write(path: Path, parts: list[tuple[np.ndarray, np.ndarray]], scale: float = 1.0) -> None:
    v, f, off = [], [], 0
    for pv, pf in parts:
        v.append(pv * scale)
        f.append(pf + off)
        off += len(pv)
    trimesh.Trimesh(np.vstack(v), np.vstack(f), process=False).export(path)


def plate_in_pieces(path: Path, seed: int) -> dict[str, object]:
    """A 1.2 × 0.8 m plate cut across into 4 strips with seeded gaps of 5–30 mm (every other
    strip wound the other way, as pieces of a file often are), clips and a sealer bead lying on
    it, a strip 150 mm beyond its end, a panel hidden 12 mm behind it and a flange standing
    sideways 10 mm off its edge; written in mm. Returns the truth [m, m²]."""
    rng = np.random.default_rng(seed)
    gaps = rng.uniform(0.005, 0.030, 3)
    widths = np.array([0.45, 0.3, 0.15, 0.2])
    x0, strips, parts = 0.0, [], []
    for i, (w, g) in enumerate(zip(widths, [*gaps, 0.0], strict=True)):
        parts.append(_grid(x0, x0 + w, 0.0, 0.8, flip=bool(i % 2)))
        strips.append(w * 0.8)
        x0 += w + g
    end = x0                                  # the plate's far edge [m]
    stray = [_grid(0.1, 0.125, 0.3, 0.325, z=0.003, h=0.01),       # clips 25 × 25 mm
             _grid(0.5, 0.52, 0.6, 0.62, z=0.002, h=0.01),
             _grid(0.2, 0.206, 0.05, 0.35, z=0.001, h=0.006)]      # a 6 mm sealer bead
    far = _grid(end + 0.15, end + 0.4, 0.0, 0.8)                   # 150 mm past the end
    hidden = _grid(0.1, 0.4, 0.1, 0.7, z=-0.012)                   # an inner panel behind it
    # a flange standing in the xz plane (facing ±y), 10 mm off the plate's y = 0 edge
    fv, ff = _grid(0.2, 0.6, -0.01, 0.19)
    fv = np.c_[fv[:, 0], np.full(len(fv), -0.01), fv[:, 1] + 0.01 - 0.2]
    _write(path, [*parts, *stray, far, hidden, (fv, ff)], scale=1000.0)
    return {"strips_m2": strips, "gaps_m": gaps, "stray_m2": [0.025**2, 0.02**2, 0.006 * 0.3],
            "far_m2": 0.25 * 0.8, "hidden_m2": 0.3 * 0.6, "flange_m2": 0.4 * 0.2}


def _by_area(rep: object, area: float) -> object:
    hits = [p for p in rep.pieces if abs(p.area_m2 - area) < 1e-9 + 1e-6 * area]  # type: ignore[attr-defined]
    assert len(hits) == 1, (area, rep.pieces)  # type: ignore[attr-defined]
    return hits[0]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_auto_joins_close_pieces_and_names_what_it_leaves_out(tmp_path: Path, seed: int) -> None:
    path = tmp_path / "plate.stl"
    truth = plate_in_pieces(path, seed)
    surf, rep = import_part(MeshPart(file=str(path)), resolution_m=None)
    assert rep.units.units == "mm"
    strips = [_by_area(rep, a) for a in truth["strips_m2"]]   # type: ignore[attr-defined]
    assert all(p.painted for p in strips)
    joined = [p.why for p in strips if p.why != "the largest piece"]
    gaps_mm = sorted(float(w.split("joined: ")[1].split(" mm")[0]) for w in joined)
    assert gaps_mm == pytest.approx(sorted(1e3 * truth["gaps_m"]), abs=0.1)  # type: ignore[operator]
    for a in truth["stray_m2"]:                                # type: ignore[attr-defined]
        p = _by_area(rep, a)
        assert not p.painted and p.why.startswith("stray bit")
    far = _by_area(rep, truth["far_m2"])                      # type: ignore[arg-type]
    assert not far.painted and "more than 40 mm from the part" in far.why
    hidden = _by_area(rep, truth["hidden_m2"])                # type: ignore[arg-type]
    assert not hidden.painted and "hidden behind the part" in hidden.why
    flange = _by_area(rep, truth["flange_m2"])                # type: ignore[arg-type]
    assert not flange.painted and "faces another side" in flange.why
    # the judged skin is the four strips, seen from one side
    judged = face_areas(surf.vertices, surf.faces[surf.regions.face_mask()]).sum()
    assert judged == pytest.approx(sum(truth["strips_m2"]), rel=1e-6)  # type: ignore[arg-type]
    view, _ = judged_view(surf)
    n = np.cross(*(view.vertices[view.faces[:, k]] - view.vertices[view.faces[:, 0]]
                   for k in (1, 2)))
    assert np.all(n @ np.asarray(rep.painted_direction) > 0)
    m = painted_side_metrics(surf)
    assert m["painted_area_m2"] == pytest.approx(sum(truth["strips_m2"]), rel=1e-6)  # type: ignore[arg-type]
    assert m["painted_side_left_out_m2"] == 0.0 and painted_side_checks(m)[0].passed


def test_largest_alone_leaves_the_painted_side_out_and_cannot_pass(tmp_path: Path) -> None:
    path = tmp_path / "plate.stl"
    truth = plate_in_pieces(path, 0)
    surf, rep = import_part(MeshPart(file=str(path), pieces="largest"), resolution_m=None)
    m = painted_side_metrics(surf)
    left_out = sum(truth["strips_m2"][1:])                    # type: ignore[index]
    assert m["painted_side_left_out_m2"] == pytest.approx(left_out, rel=1e-6)
    check = painted_side_checks(m)[0]
    assert not check.passed and "write [part] pieces = \"auto\"" in check.detail
    # a booth's body: every part's pieces named by part, the areas summed (reported)
    auto, _ = import_part(MeshPart(file=str(path)), resolution_m=None)
    body = parts_painted_side({"0:a": auto, "1:b": surf})
    assert body["painted_side_left_out_m2"] == pytest.approx(left_out, rel=1e-6)
    assert {p["piece"].split(" ")[0] for p in body["pieces"]} == {"0:a", "1:b"}
    assert "1:b 1" in painted_side_checks(body)[0].detail
    # a gap tolerance below the smallest gap joins nothing either
    surf, rep = import_part(MeshPart(file=str(path), pieces_gap_m=0.004), resolution_m=None)
    assert rep.selected == (0,)


def test_pieces_gap_is_checked() -> None:
    with pytest.raises(PartSpecError, match="pieces_gap_m = -0.1 must be a length"):
        MeshPart(file="a.stl", pieces_gap_m=-0.1)
    with pytest.raises(PartSpecError, match="write pieces = \"auto\""):
        MeshPart(file="a.stl", pieces="most")


def closed_thin_box(path: Path, size_m: tuple[float, float, float]) -> None:
    """A closed thin solid: a box L × W × t (outer skin on top, inner skin below, walls)."""
    box = trimesh.creation.box(extents=size_m)
    for _ in range(3):
        box = box.subdivide()
    box.export(path)


@pytest.mark.parametrize("res", [None, 0.025])
def test_closed_thin_solid_paints_and_judges_its_outer_skin(tmp_path: Path, res: float | None
                                                             ) -> None:
    L, W, t = 0.9, 0.6, 0.02
    closed_thin_box(tmp_path / "box.stl", (L, W, t))
    surf, rep = import_part(MeshPart(file=str(tmp_path / "box.stl"), units="m"),
                            resolution_m=res)
    assert rep.closed_shell
    judged = face_areas(surf.vertices, surf.faces[surf.regions.face_mask()]).sum()
    assert judged == pytest.approx(L * W, rel=1e-6 if res is None else 5e-3)  # STL: float32
    m = painted_side_metrics(surf)
    back = [p for p in m["pieces"] if not p["painted"]]
    assert len(back) == 1 and "back (inner) skin" in back[0]["why"]
    assert back[0]["area_m2"] >= L * W * (1 - 1e-6)          # the inner skin is not painted
    # the file's solid is split between its painted side and its back skin, nothing twice
    assert m["painted_area_m2"] + m["not_painted_area_m2"] == pytest.approx(
        2 * (L * W + L * t + W * t), rel=1e-6)
    assert m["painted_area_m2"] < L * W + 2 * (L + W) * t
    # the figures draw the judged outer skin alone, every face toward the painted side
    view, keep = judged_view(surf)
    n = np.cross(*(view.vertices[view.faces[:, k]] - view.vertices[view.faces[:, 0]]
                   for k in (1, 2)))
    d = np.asarray(rep.painted_direction)
    assert np.all(n @ d > 0.999 * np.linalg.norm(n, axis=1))
    assert face_areas(view.vertices, view.faces).sum() == pytest.approx(judged, rel=1e-12)
    assert np.array_equal(view.vertices, surf.vertices[keep])


@pytest.mark.parametrize("seed", range(4))
def test_generated_door_in_pieces_is_painted_whole(tmp_path: Path, seed: int) -> None:
    """`paintcell generate door_pieces` (paintcell.surface.part_families): the lower panel and
    the window frame's members 15-35 mm from it are painted, their areas the generator's; the
    clips and the sealer bead are not (mm or m, z- or y-up, as the seed draws)."""
    from paintcell.surface.part_families import make_family_part

    part = make_family_part("door_pieces", seed)
    path = tmp_path / "door.stl"
    part.mesh.export(path)
    surf, rep = import_part(MeshPart(file=str(path)), resolution_m=None)
    skins = sorted(x["area_m2"] for x in part.truth["pieces"] if x["role"] == "skin")
    strays = sorted(x["area_m2"] for x in part.truth["pieces"] if x["role"] == "stray")
    # STL stores float32: a 6 mm bead's area in metres to ~1e-6
    assert sorted(p.area_m2 for p in rep.pieces if p.painted) == pytest.approx(skins, rel=1e-5)
    assert sorted(p.area_m2 for p in rep.pieces if not p.painted) == pytest.approx(strays,
                                                                                  rel=1e-5)
    judged = face_areas(surf.vertices, surf.faces[surf.regions.face_mask()]).sum()
    assert judged == pytest.approx(part.truth["painted_area_m2"], rel=1e-5)


@pytest.mark.parametrize("seed", range(4))
def test_generated_closed_door_judges_its_outer_skin(tmp_path: Path, seed: int) -> None:
    """`door_solid`: a curved door as a closed solid 30-60 mm thick. The painted side is the
    outer (convex) skin, the generator's +z, and the judged skin is its area; the inner skin is
    named as not painted."""
    from paintcell.surface.part_families import make_family_part

    part = make_family_part("door_solid", seed)
    path = tmp_path / "door.stl"
    part.mesh.export(path)
    surf, rep = import_part(MeshPart(file=str(path)), resolution_m=0.025)
    up = np.asarray(part.truth["R_file_part"]) @ [0.0, 0.0, 1.0]
    assert float(up @ np.asarray(rep.painted_direction)) > 0.95
    judged = face_areas(surf.vertices, surf.faces[surf.regions.face_mask()]).sum()
    assert judged == pytest.approx(part.truth["painted_area_m2"], rel=5e-3)
    back = [p for p in surf.regions.pieces if not p["painted"]]
    assert len(back) == 1 and back[0]["area_m2"] >= part.truth["inner_skin_area_m2"]
