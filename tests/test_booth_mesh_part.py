"""A booth part read from a mesh file: the `[parts.part]` table is a scenario's `[part]` table,
read by the same loader (`MeshPart.from_dict`, `paintcell.surface.part_surface.part_surface`),
so the booth plans exactly the surface and passes a one-robot scenario of that file plans."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from paintcell.app.pipeline import load_surface, make_plan
from paintcell.app.scenario_files import load_scenario
from paintcell.booth.booth import Booth
from paintcell.booth.booth_data import BoothDataError
from paintcell.booth.booth_plans import plan_parts

PART = '''[parts.part]
file = "parts/bent_plate.stl"
units = "mm"
'''


def _plate(path: Path) -> None:
    """A 600 x 400 mm plate bent about its short axis (radius 1.5 m), in mm, convex side +z."""
    u, v = np.meshgrid(np.linspace(-300, 300, 31), np.linspace(-200, 200, 21), indexing="ij")
    r = 1500.0
    V = np.column_stack([(r * np.sin(u / r)).ravel(), v.ravel(),
                         (r * np.cos(u / r) - r).ravel()])
    i = np.arange(30)[:, None] * 21 + np.arange(20)[None, :]
    F = np.concatenate([np.column_stack([i.ravel(), (i + 21).ravel(), (i + 1).ravel()]),
                        np.column_stack([(i + 1).ravel(), (i + 21).ravel(), (i + 22).ravel()])])
    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.Trimesh(V, F, process=False).export(path)


def _booth(tmp_path: Path, part: str) -> Path:
    p = tmp_path / "cell.toml"
    p.write_text(f'''name = "plate_cell"
fast_resolution_m = 0.025
[[parts]]
xyz_m = [1.4, 0.0, 1.0]
{part}
[[robots]]
name = "r"
model = "irb5500"
''')
    return p


def test_mesh_part_in_a_booth_is_the_scenario_part(tmp_path):
    _plate(tmp_path / "parts" / "bent_plate.stl")
    booth = load_scenario(_booth(tmp_path, PART))
    assert isinstance(booth, Booth)
    bp = booth.parts[0]
    # the file is relative to the booth file; the label is the file's stem
    assert bp.part == "bent_plate" and bp.mesh is not None
    assert Path(bp.mesh.file) == tmp_path / "parts" / "bent_plate.stl"
    assert bp.mesh.units == "mm" and bp.mesh.judge == ("skin",)
    # the same part in a one-robot scenario
    scn_file = tmp_path / "one.toml"
    scn_file.write_text('name = "one"\nrobot = "irb5500"\nfast_resolution_m = 0.025\n'
                        '[part_placement]\nxyz_m = [1.4, 0.0, 1.0]\nrpy_rad = [0, 0, 0]\n'
                        + PART.replace("[parts.part]", "[part]"))
    scn = load_scenario(scn_file)
    surf = load_surface(scn, fast=True)
    pp = plan_parts(booth, fast=True)
    surfaces, plans = pp.surfaces, pp.plans
    np.testing.assert_array_equal(surfaces[0].vertices, surf.vertices)
    np.testing.assert_array_equal(surfaces[0].faces, surf.faces)
    # 0.6 x 0.4 m in m (units = "mm" applied), the same passes as the scenario's planner
    assert np.ptp(surf.vertices, axis=0)[:2] == pytest.approx([0.6 * np.sin(0.2) / 0.2, 0.4],
                                                              rel=0.02)
    plan = make_plan(scn, surf, fast=True)
    assert len(plans[0].passes) == len(plan.passes) >= 2
    for i in range(len(plan.passes)):
        np.testing.assert_allclose(plans[0].tcp_frames(i), plan.tcp_frames(i), atol=1e-12)


def test_bad_mesh_part_table_is_one_line(tmp_path):
    bad = _booth(tmp_path, PART + 'colour = "red"\n')
    with pytest.raises(BoothDataError) as e:
        load_scenario(bad)
    msg = str(e.value)
    assert "\n" not in msg and "[parts.part] has unknown key(s) ['colour']" in msg
    assert "cell.toml [[parts]] #0" in msg and "valid keys" in msg
    bad = _booth(tmp_path, '[parts.part]\nunits = "mm"\n')
    with pytest.raises(BoothDataError, match=r"\[parts.part\] has no file; add file ="):
        load_scenario(bad)


def test_booth_judges_a_mesh_part_on_its_skin():
    """The booth judges a mesh part's film where a one-robot run does (its skin, not its hem or
    turned edges): the body mask is each part's judged mask in stacking order, every vertex of a
    part without regions."""
    import dataclasses

    from paintcell.booth.booth_film import judged_body_mask
    from paintcell.paint.metrics import uniformity

    root = Path(__file__).resolve().parents[1]
    door = load_surface(load_scenario(root / "scenarios" / "cad_door.toml"), fast=True)
    own = door.judged_vertex_mask()
    assert own is not None and 0 < own.sum() < len(own)
    bare = dataclasses.replace(door, regions=None)
    mask = judged_body_mask([door, bare])
    np.testing.assert_array_equal(mask, np.concatenate([own, np.ones(len(own), bool)]))
    # zero area off the judged vertices (booth_metrics' weighting) is the one-robot run's mask
    film = np.random.default_rng(0).uniform(10e-6, 30e-6, len(mask))
    areas = np.concatenate([door.vertex_areas, door.vertex_areas])
    a = uniformity(film, areas * mask)
    b = uniformity(film, areas, mask=mask)
    assert a.nsd_pct == pytest.approx(b.nsd_pct, rel=1e-12)
    assert a.within_tolerance_fraction == pytest.approx(b.within_tolerance_fraction, rel=1e-12)
    # the common film build scales a part's flow by its planned mean on the skin alone: one
    # straight pass 0.25 m off the door's skin centroid, along the door (a plan's duck type)
    from paintcell.booth.booth_build import planned_mean_m
    from paintcell.paint.applicator import Applicator
    from paintcell.paint.deposition import thickness
    from paintcell.paint.deposition_samples import GunSamples

    c = door.vertices[own].mean(axis=0)
    n = door.normals[own].mean(axis=0)
    n /= np.linalg.norm(n)
    d = np.cross(n, [0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.cross(n, [1.0, 0.0, 0.0])
    d /= np.linalg.norm(d)
    s_m = np.linspace(-0.4, 0.4, 81)
    gun = GunSamples(positions=c + 0.25 * n + s_m[:, None] * d,
                     spray_axes=np.tile(-n, (81, 1)), travel_dirs=np.tile(d, (81, 1)),
                     dwell_s=np.full(81, 0.01 / 0.5))

    class _Pass:
        applicator = Applicator.default()

        def gun_samples(self) -> GunSamples:
            return gun

    f = thickness(_Pass.applicator, gun, door.vertices, door.normals)
    w = door.vertex_areas
    mean, area = planned_mean_m(_Pass(), door)        # type: ignore[arg-type]
    assert area == pytest.approx(w[own].sum(), rel=1e-12)
    assert mean == pytest.approx(float(f[own] @ w[own] / w[own].sum()), rel=1e-12)
    assert abs(mean - float(f @ w / w.sum())) > 0.01 * mean     # the hems do move it


def test_missing_mesh_part_file_is_one_line_at_load(tmp_path):
    """A booth part file that is not there is refused when the booth loads, naming the booth's
    table ([[parts]] #0 [parts.part]), not a scenario's [part] after the robots are loaded."""
    with pytest.raises(BoothDataError) as e:
        load_scenario(_booth(tmp_path, PART))          # parts/bent_plate.stl never written
    msg = str(e.value)
    assert "\n" not in msg and "[[parts]] #0 [parts.part]: file " in msg
    assert "bent_plate.stl does not exist" in msg and "[part] file" not in msg
