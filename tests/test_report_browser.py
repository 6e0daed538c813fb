"""The door report in a real headless Chromium: no console error, the first screen holds the
verdict, the film map and the histogram, the page is under 2 MB, and its numbers are the ones an
independent computation from the results folder's files gives."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.helpers import report_tool

ROOT = Path(__file__).resolve().parents[1]



@pytest.fixture
def door(door_fast: Path) -> Path:
    """The door's `--fast` results folder (tests/conftest.py: one run a pytest run)."""
    return door_fast


@pytest.mark.slow
def test_door_report_in_headless_chromium(door, tmp_path):
    tool = report_tool()
    html_path = door / "report.html"
    assert html_path.stat().st_size < 2_000_000  # no execution GIF by default
    assert not (door / "execution.gif").exists()

    r = tool.inspect_report(html_path, tmp_path / "shot.png")
    errors = [m for m in r["console"] if m[0] in ("error", "pageerror", "warning")]
    assert not errors, errors
    w, h = tool.VIEWPORT
    for sel in ("#verdict", "#film-map", "#film-histogram"):
        box = r["boxes"][sel]
        assert box is not None, f"{sel} missing"
        assert box["x"] >= 0 and box["y"] >= 0, (sel, box)
        assert box["x"] + box["width"] <= w and box["y"] + box["height"] <= h, (sel, box)
        assert box["width"] > 200 or sel == "#verdict", (sel, box)
    assert r["boxes"]["#pass-table"]["y"] < h  # the per-pass table starts on the first screen
    assert all(r["images_ok"].values()), r["images_ok"]
    assert (tmp_path / "shot.png").stat().st_size > 10_000

    metrics = json.loads((door / "metrics.json").read_text())
    word = "PASS" if metrics["passed"] else "FAIL"
    assert f"Verdict: {word}" in r["texts"]["#verdict"]
    for c in metrics["checks"]:
        if not c["passed"]:
            assert c["name"].lower() in r["texts"]["#verdict"].lower()

    # the share of area in the spec window, recomputed from the film arrays of the folder
    with np.load(door / "film.npz") as z:
        planned, executed = z["planned_thickness_m"], z["executed_thickness_m"]
        areas, judged, tol = z["vertex_areas_m2"], z["judged"], float(z["tolerance"])
    w_j = np.where(judged, areas, 0.0)
    target = float(np.sum(w_j * planned) / np.sum(w_j))
    inside = np.abs(executed - target) <= tol * target
    pct = 100.0 * float(np.sum(w_j[inside]) / np.sum(w_j))
    # the page shows the paint spec's share (exact on the film's triangles); the vertex-lumped
    # share recomputed here agrees to within the lumping
    assert r["texts"]["#inside-pct"] == f"{metrics['executed_inside_spec_pct']:.1f} %"
    assert pct == pytest.approx(metrics["executed_inside_spec_pct"], abs=0.5)
    # one table row a planned pass
    plan = json.loads((door / "plan.json").read_text())
    assert r["pass_rows"] == len(plan["passes"]) > 0
