"""The booth report: `report.html` in a booth's results folder, and its whole-body film map.

`body_film_figure` draws `body_film.png` from the run's arrays: the executed film over the whole
body on one colour scale (top row) and which robot laid most of it, with the overlap bands
outlined (bottom row), one column per view of the body (each part is seen along the body axis
nearest its mean normal: the side from −y, the roof from +z). `write_booth_report` writes the HTML
from `metrics.json` alone (so it can be rebuilt from a finished folder) and links the figures.
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from matplotlib.tri import Triangulation

from paintcell.booth.booth import APPROACH_RETRACT_S, TURN_S
from paintcell.core.atomic_io import atomic_write_text
from paintcell.output.gltf_film import FILM_GLB_NAME
from paintcell.output.plots import THICKNESS_CMAP, save_figure, thickness_range_um

_AXES = "xyz"
#: one colour per robot in the zone map (tab10).
_ZONE_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
                 "#7f7f7f", "#bcbd22", "#17becf")


def part_view(vertices: np.ndarray, normals: np.ndarray, areas: np.ndarray
              ) -> tuple[str, tuple[int, int]]:
    """(view label, the two body axes drawn) of a part: seen along the body axis (with its sign)
    nearest its area-weighted mean normal (vertices, normals (N, 3), areas (N,))."""
    n = (normals * areas[:, None]).sum(axis=0)
    k = int(np.argmax(np.abs(n)))
    sign = "+" if n[k] >= 0 else "−"
    shown = tuple(i for i in range(3) if i != k)
    return f"seen from {sign}{_AXES[k]}", (shown[0], shown[1])


def body_film_figure(body: Any, part_counts: list[int], films_m: np.ndarray,
                     robot_names: list[str], path: Path, band: np.ndarray | None = None,
                     title: str = "") -> Path:
    """Write the whole-body film map (module doc) to `path` (PNG) and return it.

    body: the merged body `Surface` (parts stacked in order, `part_counts` vertices each);
    films_m: (R, N) each robot's executed film [m]; band: (N,) overlap-band mask (outlined).
    """
    v, f = np.asarray(body.vertices), np.asarray(body.faces)
    total_um = 1e6 * films_m.sum(axis=0)
    lead = np.argmax(films_m, axis=0)
    offs = np.cumsum([0, *part_counts])
    views: dict[str, tuple[tuple[int, int], list[int]]] = {}
    for i in range(len(part_counts)):
        sl = slice(offs[i], offs[i + 1])
        label, ax2 = part_view(v[sl], np.asarray(body.normals)[sl],
                               np.asarray(body.vertex_areas)[sl])
        views.setdefault(label, (ax2, []))[1].append(i)
    vmin, vmax = thickness_range_um(total_um * 1e-6)
    ncol = len(views)
    width = [float(np.ptp(v[np.concatenate([np.arange(offs[i], offs[i + 1]) for i in mem]),
                             ax2[0]])) + 0.1 for ax2, mem in views.values()]
    fig = Figure(figsize=(4.5 * ncol + 1.5, 6.8), layout="constrained")
    axs = fig.subplots(2, ncol, squeeze=False, gridspec_kw={"width_ratios": width})
    cmap_zone = ListedColormap(list(_ZONE_COLOURS[:max(1, len(robot_names))]))
    pc = None
    for c, (label, (ax2, members)) in enumerate(views.items()):
        for i in members:
            fsel = f[(f >= offs[i]).all(axis=1) & (f < offs[i + 1]).all(axis=1)]
            tri = Triangulation(v[:, ax2[0]], v[:, ax2[1]], fsel)
            pc = axs[0, c].tripcolor(tri, total_um, shading="gouraud", cmap=THICKNESS_CMAP,
                                     vmin=vmin, vmax=vmax)
            axs[1, c].tripcolor(tri, facecolors=lead[fsel[:, 0]].astype(float),
                                cmap=cmap_zone, vmin=-0.5, vmax=len(robot_names) - 0.5)
            if band is not None and band[offs[i]:offs[i + 1]].any():
                axs[1, c].tricontour(tri, band.astype(float), levels=[0.5], colors="k",
                                     linewidths=0.8)
        sel = np.concatenate([np.arange(offs[i], offs[i + 1]) for i in members])
        for r in range(2):
            axs[r, c].set_xlim(v[sel, ax2[0]].min() - 0.05, v[sel, ax2[0]].max() + 0.05)
            axs[r, c].set_ylim(v[sel, ax2[1]].min() - 0.05, v[sel, ax2[1]].max() + 0.05)
            axs[r, c].set_aspect("equal")
            axs[r, c].xaxis.set_major_locator(MaxNLocator(5))
            axs[r, c].set_xlabel(f"body {_AXES[ax2[0]]} [m]")
            axs[r, c].set_ylabel(f"body {_AXES[ax2[1]]} [m]")
        axs[0, c].set_title(f"executed film [µm], {label}")
        axs[1, c].set_title(f"robot laying most film, {label}")
    if pc is not None:
        fig.colorbar(pc, ax=axs[0, :].tolist(), label="executed film thickness [µm]",
                     shrink=0.85)
    handles = [axs[1, 0].scatter([], [], color=_ZONE_COLOURS[k], marker="s", label=n)
               for k, n in enumerate(robot_names)]
    fig.legend(handles=handles, fontsize=8, loc="outside lower center",
               ncols=max(1, len(robot_names)),
               title="black outline: overlap band (two robots each ≥ 10 % of the film)",
               title_fontsize=8)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


def _fmt(v: Any, digits: int = 2) -> str:
    if v is None:
        return "—"
    if isinstance(v, float):
        return "—" if not np.isfinite(v) else f"{v:.{digits}f}"
    return html.escape(str(v))


def _table(header: list[str], rows: list[list[Any]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(
        f"<td>{_fmt(c)}</td>" if isinstance(c, int | float) or c is None
        else f"<td class='t'>{_fmt(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _jobs_text(jobs: dict[str, Any], names: list[str], parts: list[str],
               est: dict[str, float] | None = None) -> str:
    """'side_a: fender passes 0–5 (24.8 s); ...' from {robot (index or name): [part, first,
    end]} and optionally the estimated program time of each [s]."""
    out = []
    for r, v in jobs.items():
        rn = names[int(r)] if str(r).isdigit() else str(r)
        t = f" ({est[r]:.1f} s)" if est is not None and r in est else ""
        triples = v if isinstance(v[0], (list, tuple)) else [v]
        work = " then ".join(f"{parts[int(p)]} {_span([a, b])}" for p, a, b in triples)
        out.append(f"{rn}: {work}{t}")
    return "; ".join(out)


def _span(passes: list[Any]) -> str:
    """'pass 3' / 'passes 0–5' from [first, end] (a list of them: joined with '+')."""
    if passes and isinstance(passes[0], (list, tuple)):
        return " + ".join(_span(list(x)) for x in passes)
    a, b = passes
    return f"pass {a}" if b - a == 1 else f"passes {a}–{b - 1}"


def _usage_tables(m: dict[str, Any]) -> list[str]:
    """The per-robot time and paint table and the per-part film table
    (`paintcell.booth.booth_usage`, `paintcell.booth.booth_part_film`); none for a folder
    without those figures."""
    if "part_film" not in m:
        return []
    out = ["<h2 id='robot-use'>Robots: time and paint</h2>"
           f"<p>Paint (film volume) sent {m['paint_used_l']:.4f} L a body "
           f"({m['planned_paint_used_l']:.4f} L planned), {m['film_on_body_l']:.4f} L on the "
           f"body: transfer efficiency {m['executed_transfer_efficiency_pct']:.1f} % "
           f"({m['planned_transfer_efficiency_pct']:.1f} % planned).</p>" + _table(
               ["robot", "painting [% of cycle]", "moving [% of cycle]",
                "waiting at home [% of cycle]", "paint sent [L]", "film on the body [L]",
                "transfer efficiency [%]", "TCP error on passes, max [mm]",
                "speed error over the body, RMS [%]", "joint range use, max [-]"],
               [[n, r["painting_share_pct"], r["moving_share_pct"], r["waiting_share_pct"],
                 _fmt(r["paint_used_l"], 4), _fmt(r["film_on_body_l"], 4),
                 r["transfer_efficiency_pct"], r.get("tracking_error_max_mm"),
                 r.get("speed_error_rms_pct"), r.get("max_joint_range_utilization")]
                for n, r in m["robots"].items()])]
    paint = m.get("part_paint", {})
    rows = []
    for k, f in m["part_film"].items():
        u = paint.get(k, {})
        rows.append([k, f["planned_nsd_pct"], f["executed_nsd_pct"],
                     f["planned_inside_spec_pct"], f["executed_inside_spec_pct"],
                     _fmt(f["loss_pp"], 3), _fmt(f["loss_time_law_pp"], 3),
                     _fmt(f["loss_servo_pp"], 3), _fmt(f["loss_conveyor_pp"], 4),
                     f["seam_executed_mean_um"], f["seam_executed_nsd_pct"],
                     f["interior_executed_mean_um"], f["interior_executed_nsd_pct"],
                     _fmt(u.get("paint_used_l"), 4), _fmt(u.get("film_on_part_l"), 4)])
    sf = m["seam_film"]
    out.append("<h2 id='part-film'>Parts</h2>"
               f"<p>Seams: each part's points within {100 * m['seam_band_m']:.0f} cm of another "
               f"part ({sf['seam_area_pct']:.1f} % of the body): executed mean "
               f"{_fmt(sf['seam_executed_mean_um'])} µm, σ/μ "
               f"{_fmt(sf['seam_executed_nsd_pct'])} % against the interiors' "
               f"{_fmt(sf['interior_executed_mean_um'])} µm, "
               f"{_fmt(sf['interior_executed_nsd_pct'])} %. Whole body in the spec window: "
               f"{_fmt(m['planned_inside_spec_pct'], 1)} % planned, "
               f"{_fmt(m.get('executed_inside_spec_pct'), 1)} % executed.</p>" + _table(
                   ["part", "planned σ/μ [%]", "executed σ/μ [%]",
                    "planned in spec window [%]", "executed in spec window [%]", "loss [pp]",
                    "time law [pp]", "servo [pp]", "conveyor [pp]", "seam mean [µm]",
                    "seam σ/μ [%]", "interior mean [µm]", "interior σ/μ [%]",
                    "paint sent [L]", "film on the part [L]"], rows))
    return out


def booth_report_html(metrics: dict[str, Any], scenario: dict[str, Any],
                      images: list[str], film_3d: str = "") -> str:
    """The report's HTML from a booth's metrics.json and scenario.json dicts; images: figure
    file names in the same folder, shown in order; film_3d: the 3-D film view's HTML
    (`paintcell.output.film_view.film_view_html`), shown after the film figures."""
    m = metrics
    names = [r["name"] for r in scenario["robots"]]
    parts = [p["part"] for p in scenario["parts"]]
    verdict = "PASS" if metrics.get("passed") else "FAIL"
    s = [f"<h1>Booth {html.escape(str(scenario['name']))}: {verdict}</h1>",
         f"<p>{len(names)} robots paint {html.escape(' + '.join(parts))} on a conveyor at "
         f"{m['conveyor_speed_m_s']:.3f} m/s ({60 * m['conveyor_speed_m_s']:.1f} m/min). "
         f"Booth cycle <b id='cycle'>{m['executed_cycle_time_s']:.2f} s</b> against "
         f"{m['one_robot_cycle_s']:.2f} s for one robot running every program back to back "
         f"({m['speedup']:.2f}×). Whole-body executed σ/μ <b id='body-nsd'>"
         f"{m['executed_nsd_pct']:.2f} %</b>.</p>"]
    s.append("<h2>Checks</h2>" + _table(
        ["check", "value", "limit", "unit", "result"],
        [[c["name"], c["value"], c["limit"], c["unit"], "pass" if c["passed"] else
          "FAIL" + (f" ({c['detail']})" if c.get("detail") else "")]
         for c in metrics.get("checks", [])]))
    s.append("<h2>Robots</h2>" + _table(
        ["robot", "model", "part", "passes", "start delay [s]", "own program [s]",
         "busy [% of cycle]", "brush on [% of cycle]", "paint credit [% of film]",
         "coverage credit [% of area]", "peak torque [÷ limit]", "honest reach"],
        [[n, r["model"], r["part"],
          _span(r["passes"]).replace("passes ", "").replace("pass ", ""),
          r["start_delay_s"], r["program_s"], r["busy_share_pct"], r["paint_share_pct"],
          r["paint_credit_pct"], r["coverage_credit_pct"], r.get("max_torque_utilization"),
          (r.get("honest_reachability") or {}).get("verdict", "n/m")]
         for n, r in m["robots"].items()]))
    s.extend(_usage_tables(m))
    a = m.get("allocation", {})
    alloc = [f"<p>Rule: {html.escape(str(a.get('rule', '')))}.</p>"]
    if "candidates" in a:
        alloc.append(f"<p>{a['candidates']} assignments enumerated (each part whole or cut in "
                     f"two at a pass boundary, at most one job per robot); {a['feasible']} put "
                     "every pass within its robot's reach. They are ranked by their longest "
                     f"estimated program (paint time + {TURN_S} s per turn-around + "
                     f"{APPROACH_RETRACT_S} s approach and retract), then the next longest, and "
                     "so on:</p>")
        alloc.append(_table(["rank", "jobs (estimated program)", "longest estimate [s]"],
                            [[k + 1, _jobs_text(c["jobs"], names, parts, c.get("estimated_s")),
                              max(c["estimated_programs_s"])]
                             for k, c in enumerate(a.get("best_ranked", []))]))
    if "tried" in a:
        alloc.append("<p>The estimate knows nothing of the start delays that keep the arms "
                     "apart, so the best ranked were built, staggered and timed; the shortest "
                     "real cycle (start delay + own program, the longest robot) was taken:</p>")
        alloc.append(_table(["rank", "jobs", "start delays [s]", "real cycle [s]"],
                            [[t["rank"], _jobs_text(t["jobs"], names, parts),
                              (", ".join(f"{d:.2f}" for d in t["start_delays_s"])
                               if "start_delays_s" in t else
                               t.get("rejected", t.get("skipped", ""))),
                              t.get("real_cycle_s")]
                             for t in a["tried"]]))
    else:
        for rej in a.get("rejected", []):
            alloc.append(f"<p>Rejected: {html.escape(_jobs_text(rej['jobs'], names, parts))} — "
                         f"{html.escape(rej['rejected'])}</p>")
    if "chosen" in a:
        alloc.append(f"<p id='chosen'>Chosen: "
                     f"{html.escape(_jobs_text(a['chosen'], names, parts))}; start delays "
                     f"{', '.join(f'{d:.2f}' for d in a.get('start_delays_s', []))} s (each "
                     "the shortest cycle that keeps every two arms apart).</p>")
    s.append("<h2>How the work was shared</h2>" + "".join(alloc))
    sf = a.get("speed_feedback", {})
    if sf.get("rounds"):
        s.append("<h2>Robot-aware speeds</h2>"
                 f"<p>{html.escape(str(sf.get('rule', '')))}. Round 0 is the plans as the "
                 "planner made them; each later round is planned again under the speeds the "
                 "robots reached:</p>" + _table(
                     ["round", "newly capped samples", "largest speed deficit [%]",
                      "booth cycle [s]", "re-planned", "not taken"],
                     [[k, r["capped_samples"], r["max_deficit_pct"], r["cycle_s"],
                       ", ".join(r.get("replanned", [])), r.get("rejected", "")]
                      for k, r in enumerate(sf["rounds"])]))
    fb = m.get("film_build", {})
    s.append("<h2>Film build</h2>"
             f"<p>{html.escape(str(fb.get('rule', '')))}"
             + (f": target {fb['target_um']:.2f} µm" if "target_um" in fb else "") + ".</p>")
    if "parts" in fb:
        inside = m.get("part_executed_inside_spec_pct", {})
        s.append(_table(["part", "planned mean at default flow [µm]", "bell flow factor",
                         "executed mean [µm]", "executed σ/μ [%]",
                         "in the spec window [% of area]"],
                        [[k, v["planned_mean_um"], v["flow_factor"],
                          m["part_executed_mean_um"].get(k, float("nan")),
                          m["part_executed_nsd_pct"].get(k, float("nan")),
                          inside.get(k, float("nan"))]
                         for k, v in fb["parts"].items()]))
    if "spec_low_um" in m:
        s.append(f"<p>Paint spec: {m['spec_low_um']:.1f}–{m['spec_high_um']:.1f} µm (target "
                 f"{m['spec_target_um']:.1f} µm ± {m['spec_window_pct']:g} %: the scenario's "
                 "target, else the body's planned mean film) on at least "
                 f"{m['spec_min_inside_pct']:g} % of each part's judged area, σ/μ at most "
                 f"{m['spec_max_nsd_pct']:g} %.</p>")
    if m.get("pieces"):
        s.append("<h2>Pieces painted and not painted</h2>" + _table(
            ["piece", "area [m²]", "painted", "why"],
            [[p["piece"], f"{p['area_m2']:.4f}", "painted" if p["painted"] else "NOT painted",
              p["why"]]
             for p in m["pieces"]]))
    sm = m.get("seams", {})
    if "unblended_planned_nsd_pct" in sm:
        share = sm.get("share")
        s.append("<h2>Seams between parts</h2><p>Each part is planned alone, so its edge passes "
                 "also paint its neighbours; a brush-on sample that paints other parts more "
                 "than <i>share</i> × its own part is switched off (the motion is unchanged). "
                 + (f"Share {share:g}: planned whole-body σ/μ <b id='seam-nsd'>"
                    f"{sm.get('single_share_planned_nsd_pct', sm['body_planned_nsd_pct']):.2f} "
                    f"%</b> against {sm['unblended_planned_nsd_pct']:.2f} % unblended."
                    if share is not None else
                    f"No share improves the planned whole-body σ/μ "
                    f"({sm['unblended_planned_nsd_pct']:.2f} %): "
                    + ("one share for the whole body switches nothing off." if "seams" in sm
                       else "nothing is switched off."))
                 + "</p>" + _table(["part", "samples switched off"
                                   + (" (per seam)" if "seams" in sm else "")],
                                   [[k, v] for k, v in sm["samples_switched_off"].items()]))
    if "seams" in sm:
        s.append(f"<p>Per seam: each seam (two parts; a sample's seam is the part it paints most "
                 f"after its own) its own share, by coordinate descent from the single share "
                 f"({sm['single_share_planned_nsd_pct']:.2f} %): planned whole-body σ/μ "
                 f"<b id='seam-nsd-per-seam'>{sm['body_planned_nsd_pct']:.2f} %</b>, "
                 f"{len(sm['steps']) - 1} change(s) kept in {sm['sweeps']} sweep(s)"
                 f"{'' if sm['converged'] else ' (the last still changed a share)'}, "
                 f"{sm['film_evaluations']} film evaluations.</p>" + _table(
                     ["seam", "share"],
                     [[k, "none" if v is None else f"{v:g}"] for k, v in sm["seams"].items()]))
    s.append("<h2>Film over the whole body</h2>" + _table(
        ["figure", "planned", "trajectory", "servo", "executed"],
        [["σ/μ whole body [%]", m["planned_nsd_pct"], m["trajectory_nsd_pct"],
          m["servo_nsd_pct"], m["executed_nsd_pct"]],
         ["σ/μ overlap bands [%]", m["overlap_planned_nsd_pct"], "", "",
          m["overlap_executed_nsd_pct"]]]))
    s.append(f"<p>Overlap bands (two robots each ≥ 10 % of the film): "
             f"{m['overlap_band_area_pct']:.1f} % of the area. Loss (executed − planned σ/μ) "
             f"{m['loss_pp']:+.3f} pp = time law {m['loss_time_law_pp']:+.3f} + servo "
             f"{m['loss_servo_pp']:+.3f} + conveyor tracking {m['loss_conveyor_pp']:+.4f} pp "
             f"(carrier servo error ≤ {m['carrier_tracking_error_max_mm']:.3f} mm).</p>")
    s.append(f"<p>{m['n_collisions']} collision events, {m['n_robot_robot_collisions']} "
             f"robot–robot; closest bells while both paint {_fmt(m['min_bell_distance_m'])} m; "
             f"torque utilization {_fmt(m['max_torque_utilization'])}.</p>")
    if film_3d:
        s.append("<h2>The film in 3-D</h2>" + film_3d)
    for img in images:
        s.append(f"<figure><img src='{html.escape(img)}' alt='{html.escape(img)}'></figure>")
    style = ("body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:"
             "collapse}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}"
             "td.t{text-align:left}img{max-width:100%}")
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'><title>Booth "
            f"{html.escape(str(scenario['name']))}</title><style>{style}</style></head><body>"
            + "\n".join(s) + "</body></html>\n")


def write_booth_report(out: Path) -> Path:
    """Write `report.html` into a booth results folder from its metrics.json and scenario.json
    (figures booth.png and body_film.png linked when present, the 3-D view of film.glb
    embedded); returns its path."""
    out = Path(out)
    metrics = json.loads((out / "metrics.json").read_text())
    scenario = json.loads((out / "scenario.json").read_text())
    images = [n for n in ("booth.png", "body_film.png") if (out / n).exists()]
    film_3d = ""
    from paintcell.output.report_sections import embeddable

    if embeddable(out / FILM_GLB_NAME):
        from paintcell.output.film_view import film_view_html
        from paintcell.output.report_film import load_film

        film_3d = film_view_html(out / FILM_GLB_NAME, load_film(out))
    path = out / "report.html"
    atomic_write_text(path, booth_report_html(metrics, scenario, images, film_3d))
    return path
