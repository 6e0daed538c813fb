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
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.core.results_dir import marker_files, read_marker
from paintcell.core.safe_paths import read_regular_bytes
from paintcell.output.report_film import FilmData, histogram_png
from paintcell.output.report_names import (
    check_cells,
    check_reason,
    headline_rows,
    number,
    with_unit,
)

_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}
#: PNGs at least this large are embedded with a 256-colour palette [bytes].
PALETTE_MIN_BYTES = 20_000
#: the images shown as the film map, best first (names `report_figures.make_figures` writes).
FILM_MAP_FILES = ("render_executed_spec.png", "render_executed_front.png", "thickness_maps.png",
                  "render_planned_front.png")


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
                 captions: dict[str, str]) -> str:
    """Verdict, film map, histogram and pass table: what fits a 1280×800 window."""
    return (verdict_html(metrics) + '<section class="first">' + film_map_html(d, captions)
            + histogram_html(film) + pass_table_html(d) + "</section>")


# --- detail -----------------------------------------------------------------------------------
def headline_html(metrics: dict[str, Any]) -> str:
    """The headline metrics under human names (machine key in a tooltip and the last column)."""
    out = []
    for section, rows in headline_rows(metrics):
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


def collisions_html(metrics: dict[str, Any], d: Path) -> str:
    """Collision events (from metrics.json, else trace.npz contacts)."""
    events = metrics.get("collisions")
    if events is None and (d / "trace.npz").exists():
        from paintcell.execution.trace import ExecutedTrace

        trace = ExecutedTrace.load_npz(d / "trace.npz")
        events = [{"body1": c.body1, "body2": c.body2, "t_start_s": c.time_s,
                   "t_end_s": c.time_s, "max_depth_m": c.depth_m, "samples": 1}
                  for c in trace.contacts]
    if not events:
        return "<p>No robot contact with the part, the booth or itself during execution.</p>"
    rows = [(html.escape(str(e.get("body1", ""))), html.escape(str(e.get("body2", ""))),
             html.escape(number(e.get("t_start_s"), 3)), html.escape(number(e.get("t_end_s"), 3)),
             html.escape(number(1e3 * float(e["max_depth_m"]), 1)
                         if e.get("max_depth_m") is not None else "—"),
             html.escape(format_value(e.get("samples")))) for e in events]
    return (f"<p>{len(events)} collision event(s).</p>"
            + table(["body 1", "body 2", "start [s]", "end [s]", "max depth [mm]",
                     "samples [-]"], rows))


def slowdowns_html(d: Path) -> str:
    """Cycle time and every slowdown run of the trajectory."""
    path = d / "trajectory.npz"
    if not path.exists():
        return "<p>trajectory.npz not found: slowdowns unknown.</p>"
    from paintcell.motion.joint_trajectory import JointTrajectory

    traj = JointTrajectory.load_npz(path)
    head = (f"<p>Program: {traj.duration_s:.2f} s cycle time, {traj.paint_time_s:.2f} s with the "
            f"brush on, robot {html.escape(traj.robot_name)}.</p>")
    if not traj.slowdowns:
        return head + "<p>No slowdown: the time law followed the planned TCP speed.</p>"
    rows = [(html.escape(str(int(s["pass"]) + 1) if s.get("pass") is not None else "—"),
             html.escape(number(s.get("s_start_m"), 3)), html.escape(number(s.get("s_end_m"), 3)),
             html.escape(number(s.get("t_start_s"), 2)),
             html.escape(number(s.get("duration_s"), 2)),
             html.escape(number(s.get("max_speed_deficit_pct"), 1)),
             html.escape(", ".join(map(str, s.get("limiting", []))) if isinstance(
                 s.get("limiting"), list) else str(s.get("limiting", ""))))
            for s in traj.slowdowns]
    return head + table(["pass", "from [m]", "to [m]", "start [s]", "duration [s]",
                         "max speed deficit [%]", "limited by"], rows)


def plan_html(d: Path, meta: dict[str, Any] | None) -> str:
    """The coverage plan's passes as plan.json states them."""
    if meta is None:
        return "<p>plan.json not found.</p>"
    rows = [(html.escape(str(i + 1)), html.escape(format_value(p.get("side"))),
             html.escape(number(None if p.get("index_width_m") is None
                                else 1e3 * p["index_width_m"], 0)),
             html.escape(number(p.get("length_m"), 3)),
             html.escape(number(p.get("duration_s"), 2)),
             html.escape(number(p.get("nsd_constant_pct"), 2)),
             html.escape(number(p.get("nsd_optimized_pct"), 2)))
            for i, p in enumerate(meta.get("passes", []))]
    head = (f"<p>Part {html.escape(str(meta.get('surface_name', '')))}: "
            f"{len(rows)} passes, paint time {number(meta.get('paint_time_s'), 1)} s; start "
            f"curve: {html.escape(str(meta.get('start_rule', '')))}.</p>")
    return head + table(["pass", "side", "index width [mm]", "length [m]", "duration [s]",
                         "σ/μ constant speed [%]", "σ/μ optimized [%]"], rows)
