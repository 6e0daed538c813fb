"""Figures of a run, written into its results folder for `report.html`
(`paintcell.output.report`).

`make_figures` (called by `paintcell run`, with the objects in memory) writes the renders, the
optional execution video and the plots into the results folder, and `figures.json` (captions,
and why a figure was skipped).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from paintcell.core.atomic_io import atomic_write_text
from paintcell.core.errors import PaintcellError

FIGURES_JSON = "figures.json"


def judged_view(surface: Any) -> tuple[Any, np.ndarray]:
    """(the judged faces of `surface` as a surface of their own, the (M,) indices of its
    vertices in `surface`): what the film maps and renders draw. A surface without regions is
    judged whole: itself and every index."""
    from types import SimpleNamespace

    regs = getattr(surface, "regions", None)
    if regs is None:
        return surface, np.arange(len(surface.vertices))
    faces = np.asarray(surface.faces)[regs.face_mask()]
    used, inv = np.unique(faces, return_inverse=True)
    uv = getattr(surface, "uv", None)
    return SimpleNamespace(
        name=surface.name, vertices=np.asarray(surface.vertices)[used],
        faces=inv.reshape(-1, 3).astype(np.int64), normals=np.asarray(surface.normals)[used],
        vertex_areas=np.asarray(surface.vertex_areas)[used],
        uv=None if uv is None else np.asarray(uv)[used], regions=None), used


# --- figures---------------------------------------------------------------------------
def make_figures(out_dir: str | os.PathLike[str], *, surface: Any = None, plan: Any = None,
                 trajectory: Any = None, trace: Any = None, report: Any = None, cell: Any = None,
                 robot: Any = None, size: tuple[int, int] = (640, 480), video: bool = True,
                 video_size: tuple[int, int] = (320, 240), video_fps: float = 10.0,
                 video_max_frames: int = 150, index_curve: bool = True) -> list[Path]:
    """Write renders, the execution video and plots into `out_dir`; return the files written.

    surface: `Surface` (part frame); plan: `CoveragePlan`; trajectory: `JointTrajectory`;
    trace: `ExecutedTrace`; report: `ValidationReport` (its per-vertex thickness arrays [m]);
    cell: `paintcell.execution.cell.Cell` for robot renders and the video (None: part-only
    renders);
    robot: `paintcell.robots.Robot` for joint limits (default: `load_robot(trajectory.robot_name)`);
    size, video_size: (width, height) [px]; video_fps: frames per second [1/s] (the video runs
    faster than real time so it has at most `video_max_frames` frames).
    A figure whose inputs are missing, or every render when no GL backend works, is skipped and
    the reason recorded in `figures.json` (the report shows it); other errors propagate.
    """
    from paintcell.output import plots

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
    if surface is not None:
        # the film is drawn on the judged region alone, seen from the painted side: a hem, a
        # turned edge or an inner skin never hides the film that is judged
        surface, keep = judged_view(surface)
        planned = planned[keep] if have_film and planned is not None else planned
        executed = executed[keep] if have_exec and executed is not None else executed
    vmin_um = vmax_um = None
    if have_film and planned is not None:
        vmin_um, vmax_um = plots.thickness_range_um(
            planned, *([executed] if have_exec and executed is not None else []))
        p = plots.plot_thickness_maps(out / "thickness_maps.png", surface, planned,
                                      executed if have_exec else None, vmin_um, vmax_um)
        add(p, f"Film thickness on the unfolded judged region, planned / executed / difference; "
               f"shared scale {vmin_um:.3g}–{vmax_um:.3g} µm", "plot")
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
        from paintcell.coverage.index_width import nsd_vs_index_width

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
        from paintcell.output.render import RenderBackendError

        figs_r: list[dict[str, str]] = []
        try:
            skip_r = _renders(figs_r, out, surface, planned if have_film else None,
                              executed if have_exec else None, vmin_um, vmax_um, plan, trace,
                              cell, size, video, video_size, video_fps, video_max_frames,
                              _spec(report))
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
             video_size: tuple[int, int], video_fps: float, video_max_frames: int,
             spec: tuple[float, float] | None = None) -> list[dict[str, str]]:
    """Append the renders written to `figs`; return the skipped figures with reasons."""
    from paintcell.output import render

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
        if label == "executed" and spec is not None:
            # the same film against the spec window: blue thin, green in spec, red thick
            from paintcell.output.report_film import register_spec_cmap, spec_range_um

            cmap = register_spec_cmap()
            lo_um, hi_um = spec_range_um(*spec)
            sfilm = render.film_from_surface(surface, th, lo_um, hi_um, T, cmap)
            with render.SceneRenderer(None, sfilm, size, False, presets) as r:
                img = render.add_colorbar(r.render("front"), lo_um, hi_um, cmap)
                p = render.write_png(out / "render_executed_spec.png", img)
            w_lo, w_hi = spec[0] * (1 - spec[1]), spec[0] * (1 + spec[1])
            figs.append({"file": p.name, "kind": "render", "caption": (
                f"executed film against the spec window {w_lo:.1f}–{w_hi:.1f} µm (green): "
                "blue thinner, red thicker; camera front [µm]")})
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


def _spec(report: Any) -> tuple[float, float] | None:
    """(window centre [µm], half-width [-]) of the paint spec from a `ValidationReport`'s
    metrics, or None."""
    m = getattr(report, "metrics", None)
    if not isinstance(m, dict):
        return None
    if "spec_target_um" in m and "spec_window_pct" in m:
        target, tol = float(m["spec_target_um"]), 0.01 * float(m["spec_window_pct"])
    elif "planned_mean_um" in m and "tolerance_fraction" in m:
        target, tol = float(m["planned_mean_um"]), float(m["tolerance_fraction"])
    else:
        return None
    return (target, tol) if np.isfinite(target) and target > 0 and 0 < tol < 1 else None


def _moments(trace: Any) -> list[tuple[str, int]]:
    """Trace indices of the first, middle and last paint-on samples (or start/middle/end)."""
    on = np.flatnonzero(np.asarray(trace.paint_on, bool))
    idx = on if on.size else np.arange(len(trace.t_s))
    return [("first_paint", int(idx[0])), ("mid_paint", int(idx[len(idx) // 2])),
            ("last_paint", int(idx[-1]))]


def _joint_limits(robot: Any, trajectory: Any) -> tuple[Any, Any, Any] | None:
    """(lower, upper, v_max) the joints plot draws: the MJCF range the execution and its
    joint range use are measured against (the planned range lies 1 mm or 1 mrad inside it)."""
    if robot is None:
        try:
            from paintcell.robots import load_robot

            robot = load_robot(trajectory.robot_name)
        except (ImportError, PaintcellError):
            return None
    hard = getattr(robot, "q_range_mjcf", None)
    if hard is not None:
        return hard[:, 0], hard[:, 1], robot.v_max
    return robot.q_lower, robot.q_upper, robot.v_max


def _arr(x: Any) -> np.ndarray | None:
    if x is None:
        return None
    a = np.asarray(x, float).reshape(-1)
    return a if a.size else None
