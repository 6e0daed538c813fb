"""The door's film.glb and the report's 3-D view of it (paintcell.output.gltf_film,
paintcell.output.film_view), from one `paintcell run scenarios/door.toml --fast`.

film.glb read back by trimesh's loader against the folder's other files and the part built
again: vertex count, bounds, colours (the executed film of film.npz through the spec scale,
recomputed), the passes of plan.json/.npz, the placements of scenario.json. The report in a
real headless Chromium: under 2 MB and fetching nothing, the view draws the film (pixels read
back from the canvas, in the spec scale's colours), nothing reaches the console, and pointing at
the part shows the film there in µm, within what film.npz holds."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import numpy as np
import pytest
from matplotlib import colormaps

from paintcell.output.report_film import register_spec_cmap
from tests.helpers import (
    GLB_COLOUR_ATOL,
    GLB_POSITION_ATOL_M,
    GLB_THICKNESS_ATOL_UM,
    R_GLTF_WORLD,
    line_strips,
    report_tool,
    spec_colours_linear,
)

ROOT = Path(__file__).resolve().parents[1]
#: the report's budget [bytes] at --fast (no execution video)
REPORT_MAX_BYTES = 2_000_000
# A pixel "is" a scale colour when each channel is within this of one (antialiasing at edges
# and 8-bit rounding move a few units; the scale's neighbouring entries differ by ~2-6).
SCALE_PIXEL_ATOL = 6



@pytest.fixture(scope="module")
def view(door_fast):
    """Open the door report, wait for the 3-D view, read its pixels and hover over the part."""
    from playwright.sync_api import sync_playwright

    tool = report_tool()
    out: dict = {"console": [], "requests": []}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=tool.find_chromium(),
                                    args=list(tool.CHROMIUM_ARGS))
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            page.on("console", lambda m: out["console"].append((m.type, m.text)))
            page.on("pageerror", lambda e: out["console"].append(("pageerror", str(e))))
            page.on("request", lambda r: out["requests"].append(r.url))
            page.goto((door_fast / "report.html").resolve().as_uri(), wait_until="load")
            page.wait_for_selector("#film-3d canvas[data-ready='1']", timeout=30_000)
            canvas = page.locator("#film-3d canvas")
            canvas.scroll_into_view_if_needed()
            out["png"] = canvas.screenshot()
            box = canvas.bounding_box()
            tip = page.locator("#film-3d .film-tip")
            out["tip"] = None
            # points over the canvas, from its middle outwards, until one lies on the part
            for fx, fy in [(0.5, 0.5), (0.45, 0.5), (0.55, 0.5), (0.5, 0.45), (0.5, 0.55),
                           (0.4, 0.4), (0.6, 0.6), (0.4, 0.6), (0.6, 0.4)]:
                page.mouse.move(box["x"] + fx * box["width"], box["y"] + fy * box["height"])
                page.wait_for_timeout(100)
                if tip.is_visible():
                    out["tip"] = tip.inner_text()
                    break
            page.wait_for_timeout(200)
        finally:
            browser.close()
    return out


@pytest.mark.slow
def test_door_report_with_the_3d_view_is_one_offline_file_under_2_mb(door_fast, view):
    html = (door_fast / "report.html").read_text(encoding="utf-8")
    assert (door_fast / "report.html").stat().st_size < REPORT_MAX_BYTES
    assert 'id="film-3d"' in html
    assert not re.search(r"<script[^>]*\bsrc=", html)
    # the browser asked for nothing but the page itself and its inline data
    fetched = [u for u in view["requests"] if not u.startswith(("data:", "blob:"))]
    assert fetched == [(door_fast / "report.html").resolve().as_uri()], fetched


@pytest.mark.slow
def test_3d_view_draws_the_film_without_console_messages(view):
    assert not view["console"], view["console"]
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(view["png"])).convert("RGB")).astype(int)
    background = np.array([0xF4, 0xF4, 0xF4])
    drawn = np.abs(img - background).max(axis=2) > 8
    assert drawn.mean() > 0.05, f"only {100 * drawn.mean():.1f} % of the canvas is drawn"
    # the part's pixels are the spec scale's colours (unlit: exactly as the legend)
    scale = np.round(255 * np.asarray(colormaps[register_spec_cmap()](np.linspace(0, 1, 258)))
                     [:, :3]).astype(int)
    px = img[drawn]
    near = (np.abs(px[:, None, :] - scale[None, :, :]).max(axis=2) <= SCALE_PIXEL_ATOL).any(1)
    assert near.sum() > 0.03 * img.shape[0] * img.shape[1], \
        f"{near.sum()} of {px.shape[0]} drawn pixels are in the film's colour scale"


@pytest.mark.slow
def test_pointing_at_the_part_shows_the_film_in_um(view, door_fast):
    assert view["tip"] is not None, "no point of the canvas showed a film value"
    m = re.fullmatch(r"(\d+\.\d) µm", view["tip"])
    assert m, view["tip"]
    with np.load(door_fast / "film.npz") as z:
        t_um = 1e6 * z["executed_thickness_m"]
    # a value interpolated inside one triangle lies within the film's range (0.05: the rounding)
    assert t_um.min() - 0.05 <= float(m[1]) <= t_um.max() + 0.05


@pytest.mark.slow
def test_door_film_glb_against_the_folder(door_fast):
    import trimesh

    from paintcell.app.pipeline import load_surface
    from paintcell.app.scenario_data import scenario_from_snapshot
    from paintcell.coverage.plan import CoveragePlan

    path = door_fast / "film.glb"
    marker = json.loads((door_fast / ".paintcell-results").read_text())
    assert "film.glb" in marker["files"]
    with np.load(door_fast / "film.npz") as z:
        planned, executed = z["planned_thickness_m"], z["executed_thickness_m"]
        areas, judged, tol = z["vertex_areas_m2"], z["judged"], float(z["tolerance"])
    w = np.where(judged, areas, 0.0)
    target_m = float(w @ planned / w.sum())  # the window's centre, recomputed from the arrays

    snap = json.loads((door_fast / "scenario.json").read_text())
    scn = scenario_from_snapshot(snap, str(door_fast / "scenario.json"))
    surface = load_surface(scn, fast=True)  # the judged surface, built again from the part

    scene = trimesh.load(path, force="scene")
    mesh = scene.geometry["film"]
    assert len(mesh.vertices) == len(surface.vertices) == len(executed)
    sv = np.asarray(surface.vertices)
    np.testing.assert_allclose(mesh.bounds, [sv.min(0), sv.max(0)], atol=GLB_POSITION_ATOL_M)
    rgb = np.asarray(mesh.visual.vertex_attributes["color"], float)[:, :3]
    np.testing.assert_allclose(rgb, spec_colours_linear(executed, target_m, tol),
                               atol=GLB_COLOUR_ATOL)
    np.testing.assert_allclose(mesh.vertex_attributes["_THICKNESS_UM"].reshape(-1), 1e6 * executed,
                               atol=GLB_THICKNESS_ATOL_UM)

    plan = CoveragePlan.load(door_fast / "plan.json")
    strips = line_strips(path)
    assert len(strips) == len(plan.passes) > 0
    for got, p in zip(strips, plan.passes, strict=True):
        np.testing.assert_allclose(got, p.positions, atol=GLB_POSITION_ATOL_M)
    T_part, _ = scene.graph["part"]
    np.testing.assert_allclose(T_part, R_GLTF_WORLD @ scn.part_placement.matrix, atol=1e-9)
    T_base, _ = scene.graph[f"robot base {scn.robot}"]
    np.testing.assert_allclose(T_base, R_GLTF_WORLD @ scn.base.matrix, atol=1e-9)
