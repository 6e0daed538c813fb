"""The run report: figures of a results folder and one self-contained `report.html`.

`make_figures` (called by `paintcell run`, with the objects in memory) writes the renders, the
execution video and the plots into the results folder, and `figures.json` (captions, and why a
figure was skipped). `write_report` (also `paintcell report DIR`) needs only files: it reads
`metrics.json` (the `ValidationReport` dict plus context), `scenario.json`, `plan.json`,
`trajectory.npz`, `trace.npz` when present, and embeds every `*.png` / `*.gif` of the folder as a
base64 data URI: the HTML references nothing outside itself.

Units: values are shown as stored (SI, or the unit in the key name: `_pct` %, `_um` µm, `_mm`
mm, `_s` s, `_m` m, ...); film thickness in metres is also shown in µm.
"""

from __future__ import annotations

import base64
import html
import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from planning.atomic_io import atomic_path, atomic_write_text
from planning.errors import PaintcellError

FIGURES_JSON = "figures.json"
REPORT_NAME = "report.html"
# Lists longer than this are summarized (count, min, mean, max) instead of printed in full.
MAX_LIST_ITEMS = 16

# Key-name suffix → unit shown in the tables (longest suffix first).
_UNITS = (
    ("_m_s2", "m/s²"), ("_m_s", "m/s"), ("_rad_s2", "rad/s²"), ("_rad_s", "rad/s"),
    ("_1_m", "1/m"), ("_m2", "m²"), ("_m3_s", "m³/s"), ("_um", "µm"), ("_mm", "mm"),
    ("_pct", "%"), ("_pp", "percentage points"), ("_rad", "rad"), ("_deg", "deg"),
    ("_hz", "Hz"), ("_nm", "N·m"), ("_ms", "ms"), ("_s", "s"), ("_m", "m"),
)


class ReportError(PaintcellError):
    """The report cannot be written (missing or malformed results files)."""


# --- figures ----------------------------------------------------------------------------------
def make_figures(out_dir: str | os.PathLike[str], *, surface: Any = None, plan: Any = None,
                 trajectory: Any = None, trace: Any = None, report: Any = None, cell: Any = None,
                 robot: Any = None, size: tuple[int, int] = (640, 480), video: bool = True,
                 video_size: tuple[int, int] = (320, 240), video_fps: float = 10.0,
                 video_max_frames: int = 150, index_curve: bool = True) -> list[Path]:
    """Write renders, the execution video and plots into `out_dir`; return the files written.

    surface: `Surface` (part frame); plan: `CoveragePlan`; trajectory: `JointTrajectory`;
    trace: `ExecutedTrace`; report: `ValidationReport` (its per-vertex thickness arrays [m]);
    cell: `sim.cell.Cell` for robot renders and the video (None: part-only renders);
    robot: `robots.Robot` for joint limits (default: `load_robot(trajectory.robot_name)`);
    size, video_size: (width, height) [px]; video_fps: frames per second [1/s] (the video runs
    faster than real time so it has at most `video_max_frames` frames).
    A figure whose inputs are missing, or every render when no GL backend works, is skipped and
    the reason recorded in `figures.json` (the report shows it); other errors propagate.
    """
    from sim import plots

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figs: list[dict[str, str]] = []
    skipped: list[dict[str, str]] = []

    def add(path: Path, caption: str, kind: str) -> None:
        figs.append({"file": path.name, "caption": caption, "kind": kind})

    planned = _arr(getattr(report, "planned_thickness_m", None))
    executed = _arr(getattr(report, "executed_thickness_m", None))
    n_vert = len(surface.vertices) if surface is not None else -1
    have_film = planned is not None and len(planned) == n_vert
    have_exec = executed is not None and len(executed) == n_vert
    vmin_um = vmax_um = None
    if have_film and planned is not None:
        vmin_um, vmax_um = plots.thickness_range_um(
            planned, *([executed] if have_exec and executed is not None else []))
        p = plots.plot_thickness_maps(out / "thickness_maps.png", surface, planned,
                                      executed if have_exec else None, vmin_um, vmax_um)
        add(p, f"Film thickness on the unfolded part, planned / executed / difference; shared "
               f"scale {vmin_um:.3g}–{vmax_um:.3g} µm", "plot")
    else:
        skipped.append({"figure": "thickness maps", "reason": "no per-vertex thickness arrays "
                        "(surface and validation report needed)"})

    if trajectory is not None:
        p = plots.plot_tcp_speed(out / "tcp_speed.png", trajectory, trace)
        add(p, "TCP speed along each pass: planned, time law and executed [mm/s]", "plot")
        if trace is not None:
            p = plots.plot_tracking_error(out / "tracking_error.png", trajectory, trace)
            add(p, "TCP tracking error, executed vs commanded [mm]", "plot")
        lim = _joint_limits(robot, trajectory)
        if lim is not None:
            src = trace if trace is not None else trajectory
            p = plots.plot_joints(out / "joints.png", src.t_s, src.q, src.qd, *lim,
                                  joint_names=list(trajectory.joint_names),
                                  t_planned_s=trajectory.t_s, q_planned=trajectory.q)
            add(p, "Joint positions [deg] and velocities [deg/s] against their limits", "plot")
        else:
            skipped.append({"figure": "joints", "reason": "robot limits unavailable"})

    if index_curve and plan is not None:
        from planning.index_width import nsd_vs_index_width

        app = plan.applicator
        widths = np.linspace(0.15, 1.6, 30) * app.footprint_radius_m
        chosen = plan.index_widths_m[np.isfinite(plan.index_widths_m)]
        p = plots.plot_index_width_curve(out / "index_width_curve.png", widths,
                                         nsd_vs_index_width(app, widths),
                                         float(np.median(chosen)) if chosen.size else None,
                                         app.name)
        add(p, "σ/μ versus index width for parallel passes on a plane (paper Fig. 5) [%, mm]",
            "plot")

    if surface is not None:
        from sim.render import RenderBackendError

        figs_r: list[dict[str, str]] = []
        try:
            skip_r = _renders(figs_r, out, surface, planned if have_film else None,
                              executed if have_exec else None, vmin_um, vmax_um, plan, trace,
                              cell, size, video, video_size, video_fps, video_max_frames)
        except RenderBackendError as e:  # e.g. an explicit MUJOCO_GL that cannot start
            skip_r = [{"figure": "remaining renders and video", "reason": str(e)}]
        figs.extend(figs_r)
        skipped.extend(skip_r)
    atomic_write_text(out / FIGURES_JSON, json.dumps({"figures": figs, "skipped": skipped},
                                                     indent=2))
    return [out / f["file"] for f in figs]


def _renders(figs: list[dict[str, str]], out: Path, surface: Any, planned: np.ndarray | None,
             executed: np.ndarray | None, vmin_um: float | None, vmax_um: float | None,
             plan: Any, trace: Any, cell: Any, size: tuple[int, int], video: bool,
             video_size: tuple[int, int], video_fps: float,
             video_max_frames: int) -> list[dict[str, str]]:
    """Append the renders written to `figs`; return the skipped figures with reasons."""
    from sim import render

    try:
        render.backend_name()
    except render.RenderBackendError as e:
        return [{"figure": "renders and video", "reason": str(e)}]
    T = getattr(cell, "T_world_part", None)
    travel = None
    if plan is not None:
        travel = np.asarray(plan.passes[0].travel_dirs, float).mean(0)
    presets = render.part_cameras(surface, T, travel)
    film_rows = [("planned", planned), ("executed", executed)]
    for label, th in film_rows:
        if th is None or vmin_um is None or vmax_um is None:
            continue
        film = render.film_from_surface(surface, th, vmin_um, vmax_um, T)
        # The part alone in the booth: the robot would stand between the front camera and the
        # painted side. The robot renders below show the film in the cell.
        with render.SceneRenderer(None, film, size, False, presets) as r:
            cams = ["front", "along_passes"] if label == "planned" else ["front", "top",
                                                                          "along_passes"]
            for cam in cams:
                img = render.add_colorbar(r.render(cam), vmin_um, vmax_um)
                p = render.write_png(out / f"render_{label}_{cam}.png", img)
                figs.append({"file": p.name, "kind": "render",
                             "caption": f"{label} film thickness [µm], camera {cam} "
                                        f"({vmin_um:.3g}–{vmax_um:.3g} µm)"})
        if label == "executed" and cell is not None and trace is not None:
            with render.SceneRenderer(cell, film, size, False, presets) as r:
                for name, k in _moments(trace):
                    img = r.render(None, np.asarray(trace.q)[k])
                    img = render.add_colorbar(img, vmin_um, vmax_um)
                    p = render.write_png(out / f"robot_{name}.png", img)
                    figs.append({"file": p.name, "kind": "render",
                                 "caption": f"robot at t = {float(trace.t_s[k]):.2f} s ({name}),"
                                            " part with the executed film [µm]"})
    if video and cell is not None and trace is not None:
        t = np.asarray(trace.t_s, float)
        speedup = max(1.0, (t[-1] - t[0]) * video_fps / video_max_frames)
        video_film = None
        if executed is not None and vmin_um is not None and vmax_um is not None:
            video_film = render.film_from_surface(surface, executed, vmin_um, vmax_um, T)
        p = render.render_execution_video(out / "execution.gif", cell, t, trace.q, None,
                                          fps=video_fps, speedup=speedup, size=video_size,
                                          film=video_film, max_frames=video_max_frames)
        figs.append({"file": p.name, "kind": "video",
                     "caption": f"execution at {video_fps:g} fps, {speedup:.1f}× real time "
                                "(part coloured by the executed film)"})
    return []


def _moments(trace: Any) -> list[tuple[str, int]]:
    """Trace indices of the first, middle and last paint-on samples (or start/middle/end)."""
    on = np.flatnonzero(np.asarray(trace.paint_on, bool))
    idx = on if on.size else np.arange(len(trace.t_s))
    return [("first_paint", int(idx[0])), ("mid_paint", int(idx[len(idx) // 2])),
            ("last_paint", int(idx[-1]))]


def _joint_limits(robot: Any, trajectory: Any) -> tuple[Any, Any, Any] | None:
    if robot is None:
        try:
            from robots import load_robot

            robot = load_robot(trajectory.robot_name)
        except (ImportError, PaintcellError):
            return None
    return robot.q_lower, robot.q_upper, robot.v_max


def _arr(x: Any) -> np.ndarray | None:
    if x is None:
        return None
    a = np.asarray(x, float).reshape(-1)
    return a if a.size else None


# --- formatting -------------------------------------------------------------------------------
def unit_of(key: str) -> str:
    """Unit of a metric from its key name's suffix ("" when the name carries none)."""
    k = key.lower()
    for suffix, unit in _UNITS:
        if k.endswith(suffix):
            return unit
    return ""


def format_value(v: Any) -> str:
    """Text of one scalar as the report prints it (floats to 6 significant digits)."""
    if v is None:
        return "—"
    if isinstance(v, bool | np.bool_):
        return "yes" if v else "no"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        return f"{float(v):.6g}"
    return str(v)


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


def _table(headers: Iterable[str], rows: Iterable[Iterable[str]], cls: str = "") -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "\n".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    c = f' class="{cls}"' if cls else ""
    return f"<table{c}>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>"


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


def _checks_table(checks: list[Any]) -> str:
    rows = []
    for c in checks:
        if isinstance(c, dict):
            name, value, limit, unit = (c.get(k) for k in ("name", "value", "limit", "unit"))
            passed, kind = c.get("passed"), c.get("kind", "max")
        else:
            name, value, limit, unit, passed = list(c)[:5]
            kind = "max"
        op = "≥" if kind == "min" else "≤"
        verdict = ('<span class="pass">PASS</span>' if passed
                   else '<span class="fail">FAIL</span>')
        rows.append((html.escape(str(name)), html.escape(format_value(value)),
                     f"{op} {html.escape(format_value(limit))}",
                     html.escape(str(unit) if unit else "—"), verdict))
    if not rows:
        return "<p>no thresholds enabled</p>"
    return _table(["check", "value", "limit", "unit", "result"], rows, "checks")


# --- the HTML ---------------------------------------------------------------------------------
_CSS = """
body { font-family: sans-serif; max-width: 1100px; margin: 1.5em auto; color: #222; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: 0.2em; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
th { background: #f0f0f0; }
.pass { color: #11772d; font-weight: bold; } .fail { color: #b3141b; font-weight: bold; }
.verdict { font-size: 1.3em; }
figure { display: inline-block; margin: 0.5em; max-width: 100%; vertical-align: top; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.85em; color: #555; max-width: 640px; }
details { margin: 0.5em 0; }
"""

_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}


def _data_uri(path: Path) -> str:
    mime = _MIME[path.suffix.lower()]
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def _figure(path: Path, caption: str) -> str:
    return (f'<figure><img src="{_data_uri(path)}" alt="{html.escape(path.name)}">'
            f"<figcaption>{html.escape(caption)} <code>{html.escape(path.name)}</code>"
            "</figcaption></figure>")


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ReportError(f"{path} is not readable JSON ({e}); re-run `paintcell run`") from e


def _collisions_html(metrics: dict[str, Any], d: Path) -> str:
    events = metrics.get("collisions")
    if events is None and (d / "trace.npz").exists():
        from sim.trace import ExecutedTrace

        trace = ExecutedTrace.load_npz(d / "trace.npz")
        events = [{"body1": c.body1, "body2": c.body2, "t_start_s": c.time_s,
                   "t_end_s": c.time_s, "max_depth_m": c.depth_m, "samples": 1}
                  for c in trace.contacts]
    if not events:
        return "<p>No robot contact with the part, the booth or itself during execution.</p>"
    rows = [(html.escape(str(e.get("body1", ""))), html.escape(str(e.get("body2", ""))),
             html.escape(format_value(e.get("t_start_s"))),
             html.escape(format_value(e.get("t_end_s"))),
             html.escape(format_value(1e3 * float(e["max_depth_m"])) if e.get("max_depth_m")
                         is not None else "—"),
             html.escape(format_value(e.get("samples")))) for e in events]
    return (f"<p>{len(events)} collision event(s).</p>"
            + _table(["body 1", "body 2", "start [s]", "end [s]", "max depth [mm]", "samples [-]"],
                     rows))


def _slowdowns_html(d: Path) -> str:
    path = d / "trajectory.npz"
    if not path.exists():
        return "<p>trajectory.npz not found: slowdowns unknown.</p>"
    from sim.joint_trajectory import JointTrajectory

    traj = JointTrajectory.load_npz(path)
    head = (f"<p>Program: {traj.duration_s:.2f} s cycle time, {traj.paint_time_s:.2f} s with the "
            f"brush on, robot {html.escape(traj.robot_name)}.</p>")
    if not traj.slowdowns:
        return head + "<p>No slowdown: the time law followed the planned TCP speed.</p>"
    rows = [(html.escape(format_value(s.get("pass"))), html.escape(format_value(s.get(
        "s_start_m"))), html.escape(format_value(s.get("s_end_m"))),
             html.escape(format_value(s.get("t_start_s"))),
             html.escape(format_value(s.get("duration_s"))),
             html.escape(format_value(s.get("max_speed_deficit_pct"))),
             html.escape(", ".join(map(str, s.get("limiting", []))) if isinstance(
                 s.get("limiting"), list) else str(s.get("limiting", ""))))
            for s in traj.slowdowns]
    return head + _table(["pass [-]", "from [m]", "to [m]", "start [s]", "duration [s]",
                          "max speed deficit [%]", "limited by"], rows)


def _plan_html(d: Path) -> str:
    path = d / "plan.json"
    if not path.exists():
        return "<p>plan.json not found.</p>"
    meta = _read_json(path)
    rows = [(html.escape(str(i)), html.escape(format_value(p.get("side"))),
             html.escape(format_value(None if p.get("index_width_m") is None
                                      else 1e3 * p["index_width_m"])),
             html.escape(format_value(p.get("length_m"))),
             html.escape(format_value(p.get("duration_s"))),
             html.escape(format_value(p.get("nsd_constant_pct"))),
             html.escape(format_value(p.get("nsd_optimized_pct"))))
            for i, p in enumerate(meta.get("passes", []))]
    head = (f"<p>Part {html.escape(str(meta.get('surface_name', '')))}: "
            f"{len(rows)} passes, paint time {format_value(meta.get('paint_time_s'))} s; start "
            f"curve: {html.escape(str(meta.get('start_rule', '')))}.</p>")
    return head + _table(["pass [-]", "side [-]", "index width [mm]", "length [m]",
                          "duration [s]", "σ/μ constant speed [%]", "σ/μ optimized [%]"], rows)


def write_report(results_dir: str | os.PathLike[str], title: str | None = None) -> Path:
    """Write `results_dir/report.html` from the folder's files; return its path.

    Needs `metrics.json`; uses `scenario.json`, `plan.json`, `trajectory.npz`, `trace.npz`,
    `figures.json` and every `*.png`/`*.gif` when present (embedded as data URIs).
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
    name = (metrics.get("scenario") or {}).get("name") if isinstance(metrics.get("scenario"),
                                                                     dict) else None
    name = name or (scenario or {}).get("name") or d.name
    title = title or f"paintcell report — {name}"

    parts = [f"<h1>{html.escape(title)}</h1>"]
    passed = metrics.get("passed")
    if passed is not None:
        verdict = '<span class="pass">PASS</span>' if passed else '<span class="fail">FAIL</span>'
        parts.append(f'<p class="verdict">Verdict: {verdict} (every enabled threshold '
                     f'{"met" if passed else "checked; see the failures below"})</p>')

    parts.append("<h2>Thresholds (pass/fail)</h2>")
    parts.append(_checks_table(list(metrics.get("checks") or [])))

    skip_keys = {"checks", "reachability", "collisions", "scenario", "plan_summary", "passed"}
    headline = {k: v for k, v in metrics.items() if k not in skip_keys}
    parts.append("<h2>Metrics</h2>")
    parts.append(_kv_table(headline))

    parts.append("<h2>Reachability</h2>")
    parts.append(_kv_table(metrics.get("reachability"), "no reachability summary in metrics.json"))
    parts.append("<h2>Collisions</h2>")
    parts.append(_collisions_html(metrics, d))
    parts.append("<h2>Slowdowns and cycle time</h2>")
    parts.append(_slowdowns_html(d))

    figures = _read_json(d / FIGURES_JSON) if (d / FIGURES_JSON).exists() else {}
    captions = {f["file"]: f.get("caption", "") for f in figures.get("figures", [])}
    # figures.json order first (how make_figures grouped them), then any other image by name
    order = {f["file"]: i for i, f in enumerate(figures.get("figures", []))}
    images = sorted((p for p in d.iterdir() if p.suffix.lower() in _MIME and p.is_file()
                     and not p.name.startswith(".")),
                    key=lambda p: (order.get(p.name, len(order)), p.name))
    renders = [p for p in images if p.name.startswith(("render_", "robot_"))
               or p.suffix.lower() == ".gif"]
    plots = [p for p in images if p not in renders]
    parts.append("<h2>Renders (film thickness in µm)</h2>")
    parts.append("\n".join(_figure(p, captions.get(p.name, p.stem.replace("_", " ")))
                           for p in renders) or "<p>no renders in this folder</p>")
    parts.append("<h2>Plots</h2>")
    parts.append("\n".join(_figure(p, captions.get(p.name, p.stem.replace("_", " ")))
                           for p in plots) or "<p>no plots in this folder</p>")
    for s in figures.get("skipped", []):
        parts.append(f"<p>Skipped {html.escape(str(s.get('figure')))}: "
                     f"{html.escape(str(s.get('reason')))}</p>")

    parts.append("<h2>Coverage plan</h2>")
    parts.append(_plan_html(d))
    if metrics.get("plan_summary") is not None:
        parts.append("<details><summary>plan summary (metrics.json)</summary>"
                     + _kv_table(metrics["plan_summary"]) + "</details>")
    parts.append("<h2>Scenario settings</h2>")
    if metrics.get("scenario") is not None:
        parts.append(_kv_table(metrics["scenario"]))
    parts.append(_kv_table(scenario, "scenario.json not found") if scenario is not None
                 else "<p>scenario.json not found.</p>")

    parts.append("<h2>All metrics (metrics.json)</h2>")
    parts.append("<details open><summary>every value of metrics.json, as stored</summary>"
                 + _kv_table(metrics) + "</details>")

    doc = ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
           f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
           + "\n".join(parts) + "\n</body>\n</html>\n")
    out = d / REPORT_NAME
    with atomic_path(out) as tmp:
        tmp.write_text(doc, encoding="utf-8")
    from sim.plots import readable

    return readable(out)
