"""The run report: one self-contained `report.html` a paint engineer reads first.

`make_figures` (`paintcell.output.report_figures`, called by `paintcell run` with the objects in
memory) writes the renders, the optional execution video and the plots into the results folder.
`write_report` (also `paintcell report DIR`) writes the report of a cell of one robot or of
several from files only: `metrics.json` (the `ValidationReport` dict plus context), `film.npz`,
`scenario.json`, the plans, the robots' programs and traces when present, and embeds the
folder's images as base64 data URIs: the HTML references nothing outside itself.

The first screen (1280×800) holds the verdict with the reasons for any failure, the executed film
map, the film histogram against the spec window with the share of area inside it, and the
per-pass table (several robots: the cell's cycle and each robot's share of the work;
`paintcell.output.report_sections`); below it the interactive 3-D view of `film.glb`
(`paintcell.output.film_view`); the detail follows: thresholds, headline metrics under human
names with units (`paintcell.output.report_names`), how several robots shared the work and each
part's film, a section a robot (`paintcell.output.report_robots`: its figures, reachability,
collisions and program), every figure, the plans, the scenario, and every value of metrics.json
under its machine key. The execution GIF is embedded only on request (`video=True`,
`paintcell run/report --video`; a one-robot run's): without it the report stays under 2 MB.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any

from paintcell.core.atomic_io import atomic_path
from paintcell.core.data_text import DataTextError, parse_json
from paintcell.core.errors import PaintcellError
from paintcell.core.safe_paths import read_regular_bytes
from paintcell.output.film_view import film_view_html
from paintcell.output.gltf_film import FILM_GLB_NAME
from paintcell.output.report_figures import FIGURES_JSON
from paintcell.output.report_film import load_film
from paintcell.output.report_robots import cell_html, robot_runs, robot_section, sharing_html
from paintcell.output.report_sections import (
    FILM_MAP_FILES,
    checks_table,
    embeddable,
    figure,
    first_screen,
    headline_html,
    kv_table,
    parts_html,
    pass_table_html,
    pieces_html,
    plan_html,
)

__all__ = ["REPORT_NAME", "ReportError", "write_report"]

REPORT_NAME = "report.html"
VIDEO_NAME = "execution.gif"
_IMAGES = (".png", ".gif", ".jpg", ".jpeg")


class ReportError(PaintcellError):
    """The report cannot be written (missing or malformed results files)."""


# --- the HTML ---------------------------------------------------------------------------------
_CSS = """
body { font-family: sans-serif; max-width: 1250px; margin: 0.6em auto; color: #222;
       font-size: 14px; }
h1 { margin: 0 0 0.2em; font-size: 1.4em; }
h2 { border-bottom: 1px solid #ccc; padding-bottom: 0.2em; margin-top: 1.2em; }
table { border-collapse: collapse; margin: 0.3em 0 0.8em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: left; vertical-align: top; }
th { background: #f0f0f0; }
.pass { color: #11772d; font-weight: bold; } .fail { color: #b3141b; font-weight: bold; }
.unjudged { color: #8a6d00; font-weight: bold; }
.verdict-box { border: 2px solid #ccc; border-radius: 6px; padding: 0.3em 0.8em;
               margin-bottom: 0.5em; }
.verdict-box.pass { border-color: #11772d; background: #eef8f0; }
.verdict-box.fail { border-color: #b3141b; background: #fbeeee; }
.verdict { font-size: 1.5em; margin: 0.1em 0; }
.reasons { margin: 0.2em 0; } .facts { margin: 0.3em 0 0.1em; }
.first { display: grid; grid-template-columns: 380px 400px 1fr; gap: 10px;
         align-items: start; }
.first figure { margin: 0; } .first img { width: 100%; }
.first #passes table { font-size: 0.82em; margin-top: 0; } .first #passes p { margin: 0 0 0.3em; }
#cell { min-width: 0; overflow-x: auto; } #cell table { font-size: 0.78em; margin-top: 0; }
#cell p { margin: 0 0 0.3em; }
.slow { color: #b35c00; }
figure { display: inline-block; margin: 0.5em; max-width: 100%; vertical-align: top; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.85em; color: #555; max-width: 640px; }
details { margin: 0.5em 0; }
"""


def _read_json(path: Path) -> Any:
    try:
        return parse_json(read_regular_bytes(path).decode("utf-8"), str(path))
    except (OSError, UnicodeDecodeError, DataTextError) as e:
        raise ReportError(f"{path} is not readable JSON ({e}); re-run `paintcell run`") from e


def write_report(results_dir: str | os.PathLike[str], title: str | None = None,
                 video: bool = False) -> Path:
    """Write `results_dir/report.html` from the folder's files; return its path.

    One report for a cell of one robot or of several (`paintcell.output.report_robots`: a
    section a robot). Needs `metrics.json`; uses `film.npz`, `film.glb` (the 3-D view),
    `scenario.json`, the plans (`plan.json`; several parts: `plan_<i>.json`), each robot's
    program and trace, `figures.json` and the folder's `*.png` (embedded as data URIs).
    video: also embed the execution video `execution.gif` (a few MB; a one-robot run's);
    without it the report names the file and how to embed it.
    """
    d = Path(results_dir)
    mpath = d / "metrics.json"
    if not mpath.exists():
        raise ReportError(f"{mpath} is missing; run `paintcell run` (or `paintcell validate`) "
                          "on this folder first")
    metrics = _read_json(mpath)
    if not isinstance(metrics, dict):
        raise ReportError(f"{mpath} must hold a JSON object (the validation report)")
    scenario = _read_json(d / "scenario.json") if (d / "scenario.json").exists() else None
    robots = robot_runs(d, metrics, scenario)
    # a booth (metrics.json lists its robots, one or more) or a one-robot run
    booth = isinstance(metrics.get("robots"), dict) and bool(metrics["robots"])
    if video and booth:
        raise ReportError(f"{d} is a booth of {len(robots)} robot(s): its run renders no "
                          "execution video (one is made for a one-robot cell only); run "
                          "`paintcell report` without --video")
    if video and not embeddable(d / VIDEO_NAME):
        raise ReportError(f"{d / VIDEO_NAME} is missing; make it with `paintcell run --video`")
    name = (metrics.get("scenario") or {}).get("name") if isinstance(metrics.get("scenario"),
                                                                     dict) else None
    name = name or (scenario or {}).get("name") or d.name
    title = title or f"paintcell report — {name}"
    figures = _read_json(d / FIGURES_JSON) if (d / FIGURES_JSON).exists() else {}
    captions = {f["file"]: f.get("caption", "") for f in figures.get("figures", [])}
    film = load_film(d)

    third = cell_html(metrics, scenario) if booth else pass_table_html(d)
    parts = [f"<h1>{html.escape(title)}</h1>", first_screen(d, metrics, film, captions, third)]
    if embeddable(d / FILM_GLB_NAME):
        parts.append("<h2>The film in 3-D</h2>")
        parts.append(film_view_html(d / FILM_GLB_NAME, film))
    parts.append("<h2>Thresholds (pass/fail)</h2>")
    parts.append(checks_table(list(metrics.get("checks") or [])))
    pieces = pieces_html(metrics)
    if pieces:
        parts.append("<h2>Pieces painted and not painted</h2>")
        parts.append(pieces)
    parts.append("<h2>Key figures</h2>")
    parts.append(headline_html(metrics))
    if booth:
        parts.append(sharing_html(metrics, scenario))
    parts.append(parts_html(metrics))
    parts.extend(robot_section(d, r, metrics) for r in robots)

    # figures.json order first (how make_figures grouped them), then any other image by name;
    # the film map shown on the first screen is not repeated.
    order = {f["file"]: i for i, f in enumerate(figures.get("figures", []))}
    shown = next((n for n in FILM_MAP_FILES if embeddable(d / n)), None)
    images = sorted((p for p in d.iterdir() if p.suffix.lower() in _IMAGES and embeddable(p)
                     and not p.name.startswith(".") and p.name != shown
                     and (video or p.name != VIDEO_NAME)),
                    key=lambda p: (order.get(p.name, len(order)), p.name))
    renders = [p for p in images if p.name.startswith(("render_", "robot_"))
               or p.suffix.lower() == ".gif"]
    plots = [p for p in images if p not in renders]
    parts.append("<h2>Renders (film thickness in µm)</h2>")
    parts.append("\n".join(figure(p, captions.get(p.name, p.stem.replace("_", " ")))
                           for p in renders) or "<p>no renders in this folder</p>")
    if not video and not booth:
        where = (f"<code>{VIDEO_NAME}</code> is in the folder;" if (d / VIDEO_NAME).is_file()
                 else "made on request with <code>paintcell run --video</code>;")
        parts.append(f"<p>Execution video: {where} <code>paintcell report DIR --video</code> "
                     "embeds it in this page.</p>")
    parts.append("<h2>Plots</h2>")
    parts.append("\n".join(figure(p, captions.get(p.name, p.stem.replace("_", " ")))
                           for p in plots) or "<p>no plots in this folder</p>")
    for s in figures.get("skipped", []):
        parts.append(f"<p>Skipped {html.escape(str(s.get('figure')))}: "
                     f"{html.escape(str(s.get('reason')))}</p>")

    parts.append("<h2>Coverage plan</h2>")
    # one robot's plan.json; a booth: each part's plan_<i>.json, in the parts' order
    plans = [d / "plan.json"] if (d / "plan.json").exists() else sorted(
        (p for p in d.glob("plan_*.json") if p.stem[5:].isdigit()), key=lambda p: int(p.stem[5:]))
    parts.extend([plan_html(d, _read_json(p)) for p in plans] if plans else [plan_html(d, None)])
    if metrics.get("plan_summary") is not None:
        parts.append("<details><summary>plan summary (metrics.json)</summary>"
                     + kv_table(metrics["plan_summary"]) + "</details>")
    parts.append("<h2>Scenario settings</h2>")
    if metrics.get("scenario") is not None:
        parts.append(kv_table(metrics["scenario"]))
    parts.append(kv_table(scenario, "scenario.json not found") if scenario is not None
                 else "<p>scenario.json not found.</p>")

    parts.append("<h2>All metrics (metrics.json)</h2>")
    parts.append("<details><summary>every value of metrics.json under its machine key, as "
                 "stored</summary>" + kv_table(metrics) + "</details>")

    doc = ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
           f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
           + "\n".join(parts) + "\n</body>\n</html>\n")
    out = d / REPORT_NAME
    with atomic_path(out) as tmp:
        tmp.write_text(doc, encoding="utf-8")
    return out
