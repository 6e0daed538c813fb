"""The run report: one self-contained `report.html` a paint engineer reads first.

`make_figures` (`paintcell.output.report_figures`, called by `paintcell run` with the objects in
memory) writes the renders, the optional execution video and the plots into the results folder.
`write_report` (also `paintcell report DIR`) needs only files: `metrics.json` (the
`ValidationReport` dict plus context), `film.npz`, `scenario.json`, `plan.json`,
`trajectory.npz`, `trace.npz` when present, and embeds the folder's images as base64 data URIs:
the HTML references nothing outside itself.

The first screen (1280×800) holds the verdict with the reasons for any failure, the executed film
map, the film histogram against the spec window with the share of area inside it, and the
per-pass table (`paintcell.output.report_sections`); below it the interactive 3-D view of
`film.glb` (`paintcell.output.film_view`); the detail follows: thresholds, headline
metrics under
human names with units (`paintcell.output.report_names`), collisions, slowdowns, every figure,
the plan, the
scenario, and every value of metrics.json under its machine key. The execution GIF is embedded
only on request (`video=True`, `paintcell run/report --video`): without it the report stays
under 2 MB.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.core.atomic_io import atomic_path
from paintcell.core.data_text import DataTextError, parse_json
from paintcell.core.errors import PaintcellError
from paintcell.core.safe_paths import read_regular_bytes
from paintcell.output.film_view import film_view_html
from paintcell.output.gltf_film import FILM_GLB_NAME
from paintcell.output.report_figures import FIGURES_JSON
from paintcell.output.report_film import load_film
from paintcell.output.report_sections import (
    FILM_MAP_FILES,
    checks_table,
    collisions_html,
    embeddable,
    figure,
    first_screen,
    format_value,
    headline_html,
    pieces_html,
    plan_html,
    slowdowns_html,
)
from paintcell.output.report_sections import table as _table

__all__ = ["MAX_LIST_ITEMS", "REPORT_NAME", "ReportError", "flatten", "unit_of", "write_report"]

REPORT_NAME = "report.html"
VIDEO_NAME = "execution.gif"
# Lists longer than this are summarized (count, min, mean, max) instead of printed in full.
MAX_LIST_ITEMS = 16
_IMAGES = (".png", ".gif", ".jpg", ".jpeg")

# Key-name suffix → unit shown in the tables (longest suffix first).
_UNITS = (
    ("_m_s2", "m/s²"), ("_m_s", "m/s"), ("_rad_s2", "rad/s²"), ("_rad_s", "rad/s"),
    ("_1_m", "1/m"), ("_m2", "m²"), ("_m3_s", "m³/s"), ("_um", "µm"), ("_mm", "mm"),
    ("_pct", "%"), ("_pp", "percentage points"), ("_rad", "rad"), ("_deg", "deg"),
    ("_hz", "Hz"), ("_nm", "N·m"), ("_ms", "ms"), ("_s", "s"), ("_m", "m"),
)


class ReportError(PaintcellError):
    """The report cannot be written (missing or malformed results files)."""


# --- formatting -------------------------------------------------------------------------------
def unit_of(key: str) -> str:
    """Unit of a metric from its key name's suffix ("" when the name carries none)."""
    k = key.lower()
    for suffix, unit in _UNITS:
        if k.endswith(suffix):
            return unit
    return ""


def flatten(obj: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """(key path, scalar or summary string) rows of a nested JSON value.

    Dicts recurse with "a.b"; lists of dicts with "a[0].b"; lists of scalars of at most
    `MAX_LIST_ITEMS` items are joined; longer numeric lists are summarized.
    """
    rows: list[tuple[str, Any]] = []
    if isinstance(obj, dict):
        if not obj and prefix:
            rows.append((prefix, "{}"))
        for k, v in obj.items():
            rows.extend(flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(obj, list | tuple):
        if not obj:
            rows.append((prefix, "[]"))
        elif all(not isinstance(x, dict | list | tuple) for x in obj):
            if len(obj) <= MAX_LIST_ITEMS:
                rows.append((prefix, ", ".join(format_value(x) for x in obj)))
            else:
                nums = np.array([x for x in obj if isinstance(x, int | float)
                                 and not isinstance(x, bool)], float)
                if nums.size:
                    rows.append((prefix, f"{len(obj)} values: min {format_value(nums.min())}, "
                                         f"mean {format_value(nums.mean())}, "
                                         f"max {format_value(nums.max())}"))
                else:
                    rows.append((prefix, f"{len(obj)} values: "
                                 + ", ".join(format_value(x) for x in obj[:MAX_LIST_ITEMS])
                                 + ", …"))
        else:
            for i, v in enumerate(obj):
                rows.extend(flatten(v, f"{prefix}[{i}]"))
    else:
        rows.append((prefix, obj))
    return rows


def _leaf(key: str) -> str:
    return key.rsplit(".", 1)[-1].split("[", 1)[0]


def _value_cell(key: str, v: Any) -> str:
    text = html.escape(format_value(v))
    leaf = _leaf(key)
    if ("thickness" in leaf and leaf.endswith("_m") and isinstance(v, int | float)
            and not isinstance(v, bool)):
        text += f" ({float(v) * 1e6:.4g} µm)"
    return text


def _path_unit(key: str) -> str:
    """Unit of a flattened key: its leaf's suffix, else the nearest parent's ("stage_times_s.plan"
    is in s)."""
    for part in reversed(key.split(".")):
        u = unit_of(part.split("[", 1)[0])
        if u:
            return u
    return ""


def _kv_table(d: Any, empty: str = "none") -> str:
    rows = [(html.escape(k), _value_cell(k, v), html.escape(_path_unit(k) or "—"))
            for k, v in flatten(d)]
    if not rows:
        return f"<p>{html.escape(empty)}</p>"
    return _table(["quantity", "value", "unit"], rows)


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

    Needs `metrics.json`; uses `film.npz`, `film.glb` (the 3-D view), `scenario.json`,
    `plan.json`, `trajectory.npz`, `trace.npz`, `figures.json` and the folder's `*.png`
    (embedded as data URIs).
    video: also embed the execution video `execution.gif` (a few MB); without it the report
    names the file and how to embed it.
    """
    d = Path(results_dir)
    mpath = d / "metrics.json"
    if not mpath.exists():
        raise ReportError(f"{mpath} is missing; run `paintcell run` (or `paintcell validate`) "
                          "on this folder first")
    metrics = _read_json(mpath)
    if not isinstance(metrics, dict):
        raise ReportError(f"{mpath} must hold a JSON object (the validation report)")
    if video and not embeddable(d / VIDEO_NAME):
        raise ReportError(f"{d / VIDEO_NAME} is missing; make it with `paintcell run --video`")
    scenario = _read_json(d / "scenario.json") if (d / "scenario.json").exists() else None
    name = (metrics.get("scenario") or {}).get("name") if isinstance(metrics.get("scenario"),
                                                                     dict) else None
    name = name or (scenario or {}).get("name") or d.name
    title = title or f"paintcell report — {name}"
    figures = _read_json(d / FIGURES_JSON) if (d / FIGURES_JSON).exists() else {}
    captions = {f["file"]: f.get("caption", "") for f in figures.get("figures", [])}
    film = load_film(d)

    parts = [f"<h1>{html.escape(title)}</h1>", first_screen(d, metrics, film, captions)]
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
    parts.append("<h2>Reachability</h2>")
    reach = metrics.get("reachability")
    if isinstance(reach, dict):
        parts.append(f"<p>{html.escape(str(reach.get('verdict', '')))}</p><details><summary>"
                     "reachability details (metrics.json)</summary>" + _kv_table(reach)
                     + "</details>")
    else:
        parts.append("<p>no reachability summary in metrics.json</p>")
    parts.append("<h2>Collisions</h2>")
    parts.append(collisions_html(metrics, d))
    parts.append("<h2>Slowdowns and cycle time</h2>")
    parts.append(slowdowns_html(d))

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
    if not video:
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
    parts.append(plan_html(d, _read_json(d / "plan.json") if (d / "plan.json").exists()
                           else None))
    if metrics.get("plan_summary") is not None:
        parts.append("<details><summary>plan summary (metrics.json)</summary>"
                     + _kv_table(metrics["plan_summary"]) + "</details>")
    parts.append("<h2>Scenario settings</h2>")
    if metrics.get("scenario") is not None:
        parts.append(_kv_table(metrics["scenario"]))
    parts.append(_kv_table(scenario, "scenario.json not found") if scenario is not None
                 else "<p>scenario.json not found.</p>")

    parts.append("<h2>All metrics (metrics.json)</h2>")
    parts.append("<details><summary>every value of metrics.json under its machine key, as "
                 "stored</summary>" + _kv_table(metrics) + "</details>")

    doc = ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
           f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
           + "\n".join(parts) + "\n</body>\n</html>\n")
    out = d / REPORT_NAME
    with atomic_path(out) as tmp:
        tmp.write_text(doc, encoding="utf-8")
    return out
