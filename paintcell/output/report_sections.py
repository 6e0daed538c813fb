"""The HTML pieces of `report.html`: the first screen a paint engineer reads, then the detail.

First screen (`first_screen`): the verdict with the reasons for any failure, the executed film
map, the film histogram against the spec window with the share of area inside it, and the
per-pass table (speed, index width, slowdowns). Detail: thresholds, the headline metrics under
human names, collisions, slowdowns, the coverage plan. Every piece reads the results folder's
files only (metrics.json, plan.json, trajectory.npz, trace.npz, film.npz, the images); an image
is embedded only when it is a regular file the folder's marker lists (`embeddable`), read without
following a link, so a link planted in the folder never carries its target into the report.
"""

from __future__ import annotations

import base64
import html
import io
import os
import stat
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.core.results_dir import marker_files, read_marker
from paintcell.core.safe_paths import read_regular_bytes
from paintcell.output.report_film import FilmData, histogram_png
from paintcell.output.report_names import (
    HEADLINE,
    check_cells,
    check_reason,
    headline_rows,
    number,
    with_unit,
)

_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}
#: PNGs at least this large are embedded with a 256-colour palette [bytes].
PALETTE_MIN_BYTES = 20_000
#: the images shown as the film map, best first (names `report_figures.make_figures` writes; a
#: cell of several parts: the body's film, `plots.plot_body_film`).
FILM_MAP_FILES = ("render_executed_spec.png", "render_executed_front.png", "thickness_maps.png",
                  "render_planned_front.png", "body_film.png")


# Lists longer than this are summarized (count, min, mean, max) instead of printed in full.
MAX_LIST_ITEMS = 16

# Key-name suffix → unit shown in the tables (longest suffix first).
_UNITS = (
    ("_m_s2", "m/s²"), ("_m_s", "m/s"), ("_rad_s2", "rad/s²"), ("_rad_s", "rad/s"),
    ("_1_m", "1/m"), ("_m2", "m²"), ("_m3_s", "m³/s"), ("_um", "µm"), ("_mm", "mm"),
    ("_pct", "%"), ("_pp", "percentage points"), ("_rad", "rad"), ("_deg", "deg"),
    ("_hz", "Hz"), ("_nm", "N·m"), ("_ms", "ms"), ("_s", "s"), ("_m", "m"),
)


def format_value(v: Any) -> str:
    """Text of one scalar as the detail tables print it (floats to 6 significant digits)."""
    if v is None:
        return "—"
    if isinstance(v, bool | np.bool_):
        return "yes" if v else "no"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        return f"{float(v):.6g}"
    return str(v)


def table(headers: Iterable[str], rows: Iterable[Iterable[str]], cls: str = "",
          ident: str = "") -> str:
    """An HTML table; `rows` cells are HTML already (escape text before)."""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "\n".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    c = f' class="{cls}"' if cls else ""
    i = f' id="{ident}"' if ident else ""
    return f"<table{i}{c}>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>"


def values_table(headers: Sequence[str], rows: Iterable[Iterable[Any]], ident: str = "",
                 digits: int | Sequence[int] = 2) -> str:
    """An HTML table of plain values: a float at `digits` decimals (one for every column, or a
    column's own), an int as it is, None "—", anything else as escaped text."""
    dig = [digits] * len(headers) if isinstance(digits, int) else list(digits)

    def cell(v: Any, k: int) -> str:
        if isinstance(v, float):
            return html.escape(number(v, dig[k]))
        return "—" if v is None else html.escape(format_value(v))

    return table(headers, ([cell(v, k) for k, v in enumerate(r)] for r in rows), ident=ident)


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


def kv_table(d: Any, empty: str = "none") -> str:
    rows = [(html.escape(k), _value_cell(k, v), html.escape(_path_unit(k) or "—"))
            for k, v in flatten(d)]
    if not rows:
        return f"<p>{html.escape(empty)}</p>"
    return table(["quantity", "value", "unit"], rows)


def embeddable(path: Path) -> bool:
    """Whether the report may embed `path`: a regular file (not a link, FIFO or device) that the
    folder's marker lists (a folder being built, with no marker yet: any regular file)."""
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            return False
    except OSError:
        return False
    marker = read_marker(path.parent)
    return marker is None or path.name in marker_files(marker)


def compact_png(path: Path) -> bytes:
    """The PNG's bytes for embedding: re-encoded with a 256-colour palette (median cut, no
    dithering; Pillow) when that is smaller, which is a third of the size for renders and plots.
    The file in the results folder keeps its full colour depth."""
    raw = read_regular_bytes(path)
    if len(raw) < PALETTE_MIN_BYTES:
        return raw
    from PIL import Image

    with Image.open(io.BytesIO(raw)) as im:
        pal = im.convert("RGB").quantize(256, method=Image.Quantize.MEDIANCUT,
                                         dither=Image.Dither.NONE)
    buf = io.BytesIO()
    pal.save(buf, "PNG", optimize=True)
    return buf.getvalue() if buf.tell() < len(raw) else raw


def data_uri(path: Path) -> str:
    """The file as a base64 data URI (png, gif, jpeg); PNGs through `compact_png`."""
    mime = _MIME[path.suffix.lower()]
    data = compact_png(path) if mime == "image/png" else read_regular_bytes(path)
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


def figure(path: Path, caption: str) -> str:
    """A <figure> embedding `path` with its caption and file name."""
    return (f'<figure><img src="{data_uri(path)}" alt="{html.escape(path.name)}">'
            f"<figcaption>{html.escape(caption)} <code>{html.escape(path.name)}</code>"
            "</figcaption></figure>")


# --- first screen -----------------------------------------------------------------------------
def verdict_html(metrics: dict[str, Any]) -> str:
    """The verdict block: PASS/FAIL, the reason for each failed check, the key numbers."""
    passed = metrics.get("passed")
    checks = [c for c in metrics.get("checks") or [] if isinstance(c, dict)]
    failed = [c for c in checks if not c.get("passed")]
    if passed is None:
        word, cls = "NOT JUDGED", "unjudged"
        lines = ["metrics.json holds no verdict: run `paintcell validate` on this folder"]
    elif passed:
        word, cls = "PASS", "pass"
        lines = [f"Every enabled threshold met ({len(checks)} checked)."]
    else:
        word, cls = "FAIL", "fail"
        lines = [check_reason(c) for c in failed] or ["a threshold was not met"]
    inside = ("executed_inside_spec_pct" if "executed_inside_spec_pct" in metrics
              else "executed_within_tolerance_pct")   # a folder made without a paint spec
    keys = [(inside, "area in spec window", "%", 1),
            ("executed_nsd_pct", "executed σ/μ", "%", 2),
            ("loss_pp", "loss of uniformity plan → execution", "pp", 2),
            ("executed_cycle_time_s", "cycle time", "s", 1)]
    facts = " · ".join(f"{label} <b>{html.escape(with_unit(metrics[k], u, d))}</b>"
                       for k, label, u, d in keys if k in metrics)
    items = "".join(f"<li>{html.escape(s)}</li>" for s in lines)
    return (f'<div id="verdict" class="verdict-box {cls}">'
            f'<p class="verdict">Verdict: <span class="{cls}">{word}</span></p>'
            f'<ul id="reasons" class="reasons">{items}</ul><p class="facts">{facts}</p></div>')


def film_map_html(d: Path, captions: dict[str, str]) -> str:
    """The executed film map (the first of `FILM_MAP_FILES` the folder has)."""
    for name in FILM_MAP_FILES:
        p = d / name
        if embeddable(p):
            cap = captions.get(name, "film thickness [µm]")
            return (f'<figure id="film-map"><img src="{data_uri(p)}" alt="{name}">'
                    f"<figcaption>Film map: {html.escape(cap)}</figcaption></figure>")
    return ('<figure id="film-map"><p>No film map: renders were skipped (see the detail '
            "below).</p></figure>")


def histogram_html(film: FilmData | None) -> str:
    """The thickness histogram against the spec window, with the share of area inside it."""
    if film is None:
        return ('<figure id="film-histogram"><p>No film.npz in this folder (made by an older '
                "paintcell): run `paintcell validate` on it, then `paintcell report`.</p>"
                "</figure>")
    lo, hi = (1e6 * x for x in film.window_m)
    below, above = film.below_above_pct()
    uri = "data:image/png;base64," + base64.b64encode(histogram_png(film)).decode("ascii")
    return (f'<figure id="film-histogram"><img src="{uri}" alt="film histogram">'
            f'<figcaption><b id="inside-pct">{film.inside_pct():.1f} %</b> of the judged area '
            f"inside the spec window {lo:.1f}–{hi:.1f} µm (target "
            f"{1e6 * film.target_m:.1f} µm ± {100 * film.tolerance:g} %); "
            f"{below:.1f} % below, {above:.1f} % above. Planned: "
            f"{film.inside_pct('planned'):.1f} % inside.</figcaption></figure>")


def pieces_html(metrics: dict[str, Any]) -> str:
    """What of the part file was painted and what was not, with areas [m²] (metrics.json
    `pieces`); "" for a library part (all of it painted and judged)."""
    pieces = metrics.get("pieces")
    if not isinstance(pieces, list) or not pieces:
        return ""
    rows = [(html.escape(str(p.get("piece"))), html.escape(number(p.get("area_m2"), 4)),
             "painted" if p.get("painted") else "<b>not painted</b>",
             html.escape(str(p.get("why", "")))) for p in pieces]
    judged = metrics.get("judged_area_m2")
    head = (f"<p>Painted {number(metrics.get('painted_area_m2'), 3)} m² of the file's pieces, "
            f"judged {number(judged, 3)} m² (the judged regions); not painted "
            f"{number(metrics.get('not_painted_area_m2'), 3)} m².</p>")
    return head + table(["piece", "area [m²]", "painted", "why"], rows, "pieces", "piece-table")


def pass_rows(d: Path) -> list[dict[str, Any]]:
    """Per pass: side, index width [m], length [m], sharpest turn of its TCP path between two
    samples [°], planned speed range and time-law mean speed [m/s], slowdowns (count, slowed
    share of the pass [%], worst speed deficit [%]).

    From plan.json (index widths, lengths, planned durations) and trajectory.npz (its
    per-pass summary and planned TCP speed samples); [] when plan.json is missing."""
    import json

    p = d / "plan.json"
    if not p.exists():
        return []
    passes = json.loads(p.read_text()).get("passes", [])
    summary: dict[int, dict[str, Any]] = {}
    v_lo: dict[int, float] = {}
    v_hi: dict[int, float] = {}
    if (d / "trajectory.npz").exists():
        from paintcell.motion.joint_trajectory import JointTrajectory

        traj = JointTrajectory.load_npz(d / "trajectory.npz")
        summary = {int(s["pass"]): s for s in traj.pass_summary}
        on = traj.pass_index >= 0
        idx, v = traj.pass_index[on], traj.v_tcp_planned[on]
        for i in np.unique(idx):
            vi = v[idx == i]
            vi = vi[vi > 0]
            if vi.size:
                v_lo[int(i)], v_hi[int(i)] = float(vi.min()), float(vi.max())
    rows = []
    for i, mp in enumerate(passes):
        s = summary.get(i, {})
        length = mp.get("length_m")
        dur = s.get("duration_s")
        rows.append({
            "pass": i, "side": mp.get("side"), "index_width_m": mp.get("index_width_m"),
            "length_m": length, "max_turn_deg": mp.get("max_turn_deg"),
            "planned_speed_min_m_s": v_lo.get(i), "planned_speed_max_m_s": v_hi.get(i),
            "mean_speed_m_s": (length / dur) if length and dur else None,
            "n_slowdowns": s.get("n_slowdowns"),
            "slowed_pct": None if s.get("slowed_fraction") is None
            else 100.0 * s["slowed_fraction"],
            "max_speed_deficit_pct": s.get("max_speed_deficit_pct"),
        })
    return rows


def _side(side: Any) -> str:
    """A pass's place from plan.json's `side`: "start curve", "2 left", "1 right"."""
    if side is None:
        return "—"
    k = int(side)
    return "start curve" if k == 0 else f"{abs(k)} {'right' if k > 0 else 'left'}"


def pass_table_html(d: Path) -> str:
    """The per-pass table of the first screen."""
    rows = pass_rows(d)
    if not rows:
        return '<div id="passes"><p>plan.json not found: no per-pass table.</p></div>'

    def mm(x: Any, dec: int = 0) -> str:
        return "—" if x is None else number(1e3 * float(x), dec)

    cells = []
    for r in rows:
        lo, hi = r["planned_speed_min_m_s"], r["planned_speed_max_m_s"]
        speed = "—" if lo is None else (mm(lo) if round(1e3 * lo) == round(1e3 * hi)
                                        else f"{mm(lo)}–{mm(hi)}")
        n = r["n_slowdowns"]
        slow = ("—" if n is None else "none" if n == 0
                else f"{n} ({number(r['slowed_pct'], 0)} % of pass, −"
                     f"{number(r['max_speed_deficit_pct'], 0)} %)")
        cls = ' class="slow"' if n else ""
        turn = "—" if r["max_turn_deg"] is None else number(r["max_turn_deg"], 1)
        cells.append((str(r["pass"] + 1), html.escape(_side(r["side"])),
                      mm(r["index_width_m"]), number(r["length_m"], 2), turn, speed,
                      mm(r["mean_speed_m_s"]), f"<span{cls}>{html.escape(slow)}</span>"))
    total = sum(int(r["n_slowdowns"] or 0) for r in rows)
    head = (f"<p><b>{len(rows)} passes</b>; {total} slowdown(s) where a joint limit made the "
            "TCP slower than planned.</p>")
    return ('<div id="passes">' + head
            + table(["pass", "position", "index width [mm]", "length [m]", "worst turn [°]",
                     "planned speed [mm/s]",
                     "mean speed, time law [mm/s]", "slowdowns"], cells, "passes", "pass-table")
            + "</div>")


def first_screen(d: Path, metrics: dict[str, Any], film: FilmData | None,
                 captions: dict[str, str], third: str) -> str:
    """Verdict, film map, histogram and `third` (HTML: the pass table of one robot, the robots
    of a cell of several): what fits a 1280×800 window."""
    return (verdict_html(metrics) + '<section class="first">' + film_map_html(d, captions)
            + histogram_html(film) + third + "</section>")


# --- detail -----------------------------------------------------------------------------------
def headline_html(metrics: dict[str, Any], sections: Sequence[Any] = HEADLINE) -> str:
    """The headline metrics (`sections` of `report_names`) under human names (machine key in
    the last column)."""
    out = []
    for section, rows in headline_rows(metrics, sections):
        cells = [(html.escape(label), html.escape(value),
                  f"<code>{html.escape(key)}</code>") for label, value, key in rows]
        out.append(f"<h3>{html.escape(section)}</h3>"
                   + table(["quantity", "value", "metrics.json key"], cells, "headline"))
    return "\n".join(out) or "<p>no headline metrics in metrics.json</p>"


def checks_table(checks: list[Any]) -> str:
    """The thresholds, each with its value, limit and PASS/FAIL."""
    rows = []
    for c in checks:
        if not isinstance(c, dict):
            c = dict(zip(("name", "value", "limit", "unit", "passed"), list(c)[:5], strict=False))
        name, value, limit = check_cells(c)
        verdict = ('<span class="pass">PASS</span>' if c.get("passed")
                   else '<span class="fail">FAIL</span>')
        rows.append((html.escape(name), html.escape(value), html.escape(limit), verdict))
    if not rows:
        return "<p>no thresholds enabled</p>"
    return table(["check", "value", "limit", "result"], rows, "checks")


def collisions_html(metrics: dict[str, Any], d: Path, prefix: str = "") -> str:
    """Collision events (from metrics.json, else trace.npz contacts); prefix: only the events of
    the bodies whose names start with it (one robot of several)."""
    events = metrics.get("collisions")
    if events is None and (d / "trace.npz").exists():
        from paintcell.execution.trace import ExecutedTrace

        trace = ExecutedTrace.load_npz(d / "trace.npz")
        events = [{"body1": c.body1, "body2": c.body2, "t_start_s": c.time_s,
                   "t_end_s": c.time_s, "max_depth_m": c.depth_m, "samples": 1}
                  for c in trace.contacts]
    events = [e for e in events or [] if str(e.get("body1", "")).startswith(prefix)
              or str(e.get("body2", "")).startswith(prefix)]
    if not events:
        return "<p>No robot contact with the part, the booth or itself during execution.</p>"
    rows = [(e.get("body1", ""), e.get("body2", ""), e.get("t_start_s"), e.get("t_end_s"),
             None if e.get("max_depth_m") is None else 1e3 * float(e["max_depth_m"]),
             e.get("samples")) for e in events]
    return (f"<p>{len(events)} collision event(s).</p>" + values_table(
        ["body 1", "body 2", "start [s]", "end [s]", "max depth [mm]", "samples [-]"], rows,
        digits=(0, 0, 3, 3, 1, 0)))


def slowdowns_html(path: Path) -> str:
    """Cycle time and every slowdown run of a robot's program (`path`: its trajectory npz)."""
    if not path.exists():
        return f"<p>{html.escape(path.name)} not found: slowdowns unknown.</p>"
    from paintcell.motion.joint_trajectory import JointTrajectory

    traj = JointTrajectory.load_npz(path)
    head = (f"<p>Program: {traj.duration_s:.2f} s cycle time, {traj.paint_time_s:.2f} s with the "
            f"brush on, robot {html.escape(traj.robot_name)}.</p>")
    if not traj.slowdowns:
        return head + "<p>No slowdown: the time law followed the planned TCP speed.</p>"
    rows = [(None if s.get("pass") is None else int(s["pass"]) + 1, s.get("s_start_m"),
             s.get("s_end_m"), s.get("t_start_s"), s.get("duration_s"),
             s.get("max_speed_deficit_pct"), ", ".join(map(str, s["limiting"]))
             if isinstance(s.get("limiting"), list) else s.get("limiting", ""))
            for s in traj.slowdowns]
    return head + values_table(["pass", "from [m]", "to [m]", "start [s]", "duration [s]",
                                "max speed deficit [%]", "limited by"], rows,
                               digits=(0, 3, 3, 2, 2, 1, 0))


def plan_html(d: Path, meta: dict[str, Any] | None) -> str:
    """The coverage plan's passes as plan.json states them."""
    if meta is None:
        return "<p>plan.json not found.</p>"
    keys = ("length_m", "duration_s", "nsd_constant_pct", "nsd_optimized_pct")
    rows = [(i + 1, p.get("side"), None if p.get("index_width_m") is None
             else 1e3 * float(p["index_width_m"]), *map(p.get, keys))
            for i, p in enumerate(meta.get("passes", []))]
    head = (f"<p>Part {html.escape(str(meta.get('surface_name', '')))}: "
            f"{len(rows)} passes, paint time {number(meta.get('paint_time_s'), 1)} s; start "
            f"curve: {html.escape(str(meta.get('start_rule', '')))}.</p>")
    return head + values_table(["pass", "side", "index width [mm]", "length [m]", "duration [s]",
                                "σ/μ constant speed [%]", "σ/μ optimized [%]"], rows,
                               digits=(0, 0, 0, 3, 2, 2, 2))


# --- the parts of a body painted by several robots --------------------------------------------
def parts_html(metrics: dict[str, Any]) -> str:
    """Each part's film, loss split and paint, the seams between parts, the film build and the
    paint spec (metrics.json `part_film`, `seam_film`, `film_build`, `seams`); "" for a run
    of one part."""
    m = metrics
    if "part_film" not in m:
        return ""
    cols = {"planned_nsd_pct": "planned σ/μ [%]", "executed_nsd_pct": "executed σ/μ [%]",
            "planned_inside_spec_pct": "planned in spec window [%]",
            "executed_inside_spec_pct": "executed in spec window [%]", "loss_pp": "loss [pp]",
            "loss_time_law_pp": "time law [pp]", "loss_servo_pp": "servo [pp]",
            "loss_conveyor_pp": "conveyor [pp]", "seam_executed_mean_um": "seam mean [µm]",
            "seam_executed_nsd_pct": "seam σ/μ [%]",
            "interior_executed_mean_um": "interior mean [µm]",
            "interior_executed_nsd_pct": "interior σ/μ [%]", "paint_used_l": "paint sent [L]",
            "film_on_part_l": "film on the part [L]"}
    rows = [[k, *({**f, **m.get("part_paint", {}).get(k, {})}.get(c) for c in cols)]
            for k, f in m["part_film"].items()]
    sf = m["seam_film"]
    out = ["<h2 id='part-film'>Parts</h2>"
           f"<p>Seams: each part's points within {100 * m['seam_band_m']:.0f} cm of another part "
           f"({sf['seam_area_pct']:.1f} % of the body): executed mean "
           f"{number(sf['seam_executed_mean_um'], 2)} µm, σ/μ "
           f"{number(sf['seam_executed_nsd_pct'], 2)} % against the interiors' "
           f"{number(sf['interior_executed_mean_um'], 2)} µm, "
           f"{number(sf['interior_executed_nsd_pct'], 2)} %. Whole body in the spec window: "
           f"{number(m.get('planned_inside_spec_pct'), 1)} % planned, "
           f"{number(m.get('executed_inside_spec_pct'), 1)} % executed.</p>"
           + values_table(["part", *cols.values()], rows, digits=4)]
    fb = m.get("film_build", {})
    out.append("<h2>Film build</h2>"
               f"<p>{html.escape(str(fb.get('rule', '')))}"
               + (f": target {fb['target_um']:.2f} µm" if "target_um" in fb else "") + ".</p>")
    if "parts" in fb:
        inside = m.get("part_executed_inside_spec_pct", {})
        out.append(values_table(
            ["part", "planned mean at default flow [µm]", "bell flow factor",
             "executed mean [µm]", "executed σ/μ [%]", "in the spec window [% of area]"],
            [[k, v["planned_mean_um"], v["flow_factor"],
              m["part_executed_mean_um"].get(k), m["part_executed_nsd_pct"].get(k),
              inside.get(k)] for k, v in fb["parts"].items()]))
    if "spec_low_um" in m:
        out.append(f"<p>Paint spec: {m['spec_low_um']:.1f}–{m['spec_high_um']:.1f} µm (target "
                   f"{m['spec_target_um']:.1f} µm ± {m['spec_window_pct']:g} %: the scenario's "
                   "target, else the body's planned mean film) on at least "
                   f"{m['spec_min_inside_pct']:g} % of each part's judged area, σ/μ at most "
                   f"{m['spec_max_nsd_pct']:g} %.</p>")
    sm = m.get("seams", {})
    if "unblended_planned_nsd_pct" in sm:
        share = sm.get("share")
        out.append(
            "<h2>Seams between parts</h2><p>Each part is planned alone, so its edge passes also "
            "paint its neighbours; a brush-on sample that paints other parts more than "
            "<i>share</i> × its own part is switched off (the motion is unchanged). "
            + (f"Share {share:g}: planned whole-body σ/μ <b id='seam-nsd'>"
               f"{sm.get('single_share_planned_nsd_pct', sm['body_planned_nsd_pct']):.2f} "
               f"%</b> against {sm['unblended_planned_nsd_pct']:.2f} % unblended."
               if share is not None else
               "No share improves the planned whole-body σ/μ "
               f"({sm['unblended_planned_nsd_pct']:.2f} %): "
               + ("one share for the whole body switches nothing off." if "seams" in sm
                  else "nothing is switched off."))
            + "</p>" + values_table(
                ["part", "samples switched off" + (" (per seam)" if "seams" in sm else "")]
                + (["still off after the body's refinement"]
                   if "samples_off_after_refinement" in sm else []),
                ([nm, n, *([sm["samples_off_after_refinement"].get(nm)]
                           if "samples_off_after_refinement" in sm else [])]
                 for nm, n in sm["samples_switched_off"].items())))
    if "seams" in sm:
        out.append(
            "<p>Per seam: each seam (two parts; a sample's seam is the part it paints most after "
            "its own) its own share, by coordinate descent from the single share "
            f"({sm['single_share_planned_nsd_pct']:.2f} %): planned whole-body σ/μ "
            f"<b id='seam-nsd-per-seam'>{sm['body_planned_nsd_pct']:.2f} %</b>, "
            f"{len(sm['steps']) - 1} change(s) kept"
            + (f" in {sm['sweeps']} sweep(s)" if "sweeps" in sm else "")
            + ("" if sm.get("converged", True) else " (the last sweep still changed a share)")
            + f", {sm['film_evaluations']} film evaluations.</p>"
            + values_table(["seam", "share"], [(k, "none" if v is None else f"{v:g}")
                                               for k, v in sm["seams"].items()]))
    return "\n".join(out)
