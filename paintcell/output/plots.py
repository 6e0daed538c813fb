"""Matplotlib figures of a run: thickness maps, TCP speed and tracking, joints, σ/μ vs index width,
the robots of a cell on one clock and the film over a body of several parts.

Every function draws with the object-oriented API on the Agg canvas (no pyplot, no global
backend switch), writes one PNG atomically and returns its path. Film thickness is shown in µm,
speeds in mm/s, tracking errors in mm, joint positions in deg and velocities in deg/s, widths in
mm; every axis and colour bar names its unit.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator
from matplotlib.tri import Triangulation

from paintcell.core.atomic_io import atomic_path
from paintcell.core.errors import PaintcellError
from paintcell.coverage.offset_polyline import arc_length
from paintcell.motion.joint_trajectory import true_runs

# Screen/report resolution: 110 dpi keeps a 3-panel figure under ~200 kB as PNG.
DPI = 110
THICKNESS_CMAP = "viridis"
DIFF_CMAP = "RdBu_r"
#: one colour per robot in the map of which robot laid most film.
ROBOT_CMAP = "tab10"
_AXES = "xyz"


class PlotError(PaintcellError):
    """A plot cannot be drawn from the arrays given (shapes, NaN, empty)."""


def save_figure(fig: Figure, path: str | os.PathLike[str]) -> Path:
    """Write `fig` as a PNG at `path` atomically (DPI dots per inch); the path written."""
    path = Path(path)
    FigureCanvasAgg(fig)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=DPI, format="png")
    return path


def unfold(surface: Any) -> tuple[np.ndarray, tuple[str, str]]:
    """(N, 2) flat coordinates [m] of the surface vertices and the two axis names.

    The surface's (u, v) (arc length where the surface has it); else the projection on the
    area-weighted best-fit plane (principal axes of the vertices).
    """
    uv = getattr(surface, "uv", None)
    if uv is not None:
        return np.asarray(uv, float), ("u [m]", "v [m]")
    v = np.asarray(surface.vertices, float)
    areas = getattr(surface, "vertex_areas", None)
    w = np.ones(len(v)) if areas is None else np.asarray(areas, float)
    c = (w[:, None] * v).sum(0) / w.sum()
    cov = ((v - c) * w[:, None]).T @ (v - c)
    _, vecs = np.linalg.eigh(cov)
    axes = vecs[:, [2, 1]]  # largest spread first
    return (v - c) @ axes, ("best-fit plane x [m]", "best-fit plane y [m]")


def thickness_range_um(*thickness_m: npt.ArrayLike, lo_pct: float = 1.0,
                       hi_pct: float = 99.0) -> tuple[float, float]:
    """Shared colour range [µm] over several thickness arrays [m]: robust percentiles, finite
    values only, never empty."""
    vals = np.concatenate([np.asarray(t, float).ravel() for t in thickness_m]) * 1e6
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return 0.0, 1.0
    lo, hi = np.percentile(vals, [lo_pct, hi_pct])
    if hi - lo < 1e-6:
        lo, hi = lo - 0.5, hi + 0.5
    return float(lo), float(hi)


def plot_thickness_maps(path: str | os.PathLike[str], surface: Any, planned_m: npt.ArrayLike,
                        executed_m: npt.ArrayLike | None = None, vmin_um: float | None = None,
                        vmax_um: float | None = None, title: str = "") -> Path:
    """Planned, executed and executed − planned film thickness on the unfolded surface.

    surface: `Surface` (vertices, faces, uv or None); planned_m, executed_m: (N,) per vertex [m]
    (executed None → planned only); vmin_um/vmax_um: shared colour range [µm] (default: 1st–99th
    percentile of both). The difference panel has its own symmetric scale [µm].
    """
    flat, (xl, yl) = unfold(surface)
    faces = np.asarray(surface.faces)
    n = len(flat)
    maps = [("planned", np.asarray(planned_m, float).reshape(-1))]
    if executed_m is not None:
        maps.append(("executed", np.asarray(executed_m, float).reshape(-1)))
    for name, t in maps:
        if t.shape != (n,):
            raise PlotError(f"{name} thickness has {t.size} values, the surface has {n} vertices")
    if vmin_um is None or vmax_um is None:
        lo, hi = thickness_range_um(*(t for _, t in maps))
        vmin_um = lo if vmin_um is None else vmin_um
        vmax_um = hi if vmax_um is None else vmax_um
    tri = Triangulation(flat[:, 0], flat[:, 1], faces)
    ncol = 3 if executed_m is not None else 1
    fig = Figure(figsize=(5.0 * ncol, 4.2), layout="constrained")
    axs = fig.subplots(1, ncol, squeeze=False)[0]
    for ax, (name, t) in zip(axs, maps, strict=False):
        pc = ax.tripcolor(tri, np.nan_to_num(t * 1e6, nan=vmin_um), shading="gouraud",
                          cmap=THICKNESS_CMAP, vmin=vmin_um, vmax=vmax_um)
        ax.set_title(f"{name} film thickness [µm]")
        fig.colorbar(pc, ax=ax, label="film thickness [µm]", shrink=0.85)
    if executed_m is not None:
        diff = (maps[1][1] - maps[0][1]) * 1e6
        lim = float(np.nanpercentile(np.abs(diff), 99)) if np.any(np.isfinite(diff)) else 1.0
        lim = max(lim, 1e-3)
        pc = axs[2].tripcolor(tri, np.nan_to_num(diff), shading="gouraud", cmap=DIFF_CMAP,
                              vmin=-lim, vmax=lim)
        axs[2].set_title("executed − planned [µm]")
        fig.colorbar(pc, ax=axs[2], label="thickness difference [µm]", shrink=0.85)
    for ax in axs:
        ax.set_aspect("equal")
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


# Time series are drawn with at most this many points (a 1 kHz trace of a minute has 60,000):
# more than a figure's pixel width, so nothing visible is lost, and savefig stays fast.
MAX_PLOT_POINTS = 4000


def _stride(n: int, max_points: int = MAX_PLOT_POINTS) -> slice:
    return slice(None, None, max(1, -(-n // max_points)))


def _speed(t_s: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """(K,) |dp/dt| [m/s] by central differences."""
    if len(t_s) < 2:
        return np.zeros(len(t_s))
    return np.linalg.norm(np.gradient(pos, t_s, axis=0), axis=1)


def plot_tcp_speed(path: str | os.PathLike[str], trajectory: Any, trace: Any,
                   max_passes: int = 12) -> Path:
    """Planned vs executed TCP speed [mm/s] along each pass (x: arc length along the pass [m]),
    with the bell flow the program lowers where it is slower than planned (`paintcell.motion.flow`).

    trajectory: `JointTrajectory` (t_s, v_tcp_planned, pass_index, s_pass_m, tcp_pos_world);
    trace: `ExecutedTrace` (t_s, tcp_pos_world, pass_index) or None (planned only).
    Passes beyond `max_passes` are left out of the figure (named in the title).
    """
    pidx = np.asarray(trajectory.pass_index)
    passes = [int(p) for p in np.unique(pidx) if p >= 0]
    if not passes:
        raise PlotError("the trajectory has no paint pass (pass_index all -1)")
    shown = passes[:max_passes]
    fig = Figure(figsize=(8.0, 6.5), layout="constrained")
    ax, ax_dev = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    colours = [f"C{i % 10}" for i in range(len(shown))]
    v_plan = np.asarray(trajectory.v_tcp_planned, float)
    t_traj = np.asarray(trajectory.t_s, float)
    v_traj = _speed(t_traj, np.asarray(trajectory.tcp_pos_world, float))
    flow = np.asarray(getattr(trajectory, "flow", np.ones(len(t_traj))), float)
    if trace is not None:
        t_exe = np.asarray(trace.t_s, float)
        p_exe = np.asarray(trace.tcp_pos_world, float)
        v_exe = _speed(t_exe, p_exe)
        pidx_exe = np.asarray(trace.pass_index)
    for c, p in zip(colours, shown, strict=True):
        m = pidx == p
        s = np.asarray(trajectory.s_pass_m, float)[m]
        if not np.all(np.isfinite(s)):
            s = arc_length(np.asarray(trajectory.tcp_pos_world)[m])
        st = _stride(len(s), MAX_PLOT_POINTS // 4)
        ax.plot(s[st], v_plan[m][st] * 1e3, "--", color=c, lw=1.2)
        ax.plot(s[st], v_traj[m][st] * 1e3, ":", color=c, lw=1.0)
        # The curves overlap at this scale: the lower panel shows the deviations from the plan.
        ok = v_plan[m] > 0
        dev_traj = np.where(ok, (v_traj[m] - v_plan[m]) / np.where(ok, v_plan[m], 1.0), np.nan)
        ax_dev.plot(s[st], dev_traj[st] * 100.0, ":", color=c, lw=1.0)
        if np.any(flow[m] < 1.0):
            ax_dev.plot(s[st], (flow[m][st] - 1.0) * 100.0, "-.", color=c, lw=0.8)
        if trace is not None and len(t_exe) >= len(t_traj):
            # The trace is sampled at the program's steps (plus a final hold).
            v_e = v_exe[: len(t_traj)][m]
            dev_exe = np.where(ok, (v_e - v_plan[m]) / np.where(ok, v_plan[m], 1.0), np.nan)
            ax_dev.plot(s[st], dev_exe[st] * 100.0, "-", color=c, lw=1.0)
        if trace is not None:
            me = pidx_exe == p
            if np.count_nonzero(me) > 1:
                se = arc_length(p_exe[me])
                st = _stride(len(se), MAX_PLOT_POINTS // 4)
                ax.plot(se[st], v_exe[me][st] * 1e3, "-", color=c, lw=1.0, label=f"pass {p}")
    handles = [Line2D([], [], ls="--", color="k", label="planned (coverage plan)"),
               Line2D([], [], ls=":", color="k", label="time law (trajectory)")]
    if trace is not None:
        handles.append(Line2D([], [], ls="-", color="k", label="executed (MuJoCo)"))
    if np.any(flow[pidx >= 0] < 1.0):
        ax_dev.legend(handles=[Line2D([], [], ls="-.", color="k",
                                      label="bell flow (brush table) − 100 %")],
                      loc="lower center", fontsize=8)
    ax.legend(handles=handles, loc="lower center", fontsize=8)
    ax_dev.set_xlabel("arc length along the pass [m]")
    ax.set_ylabel("TCP speed [mm/s]")
    ax_dev.set_ylabel("deviation from plan [%]")
    ax_dev.grid(alpha=0.3)
    extra = f" (first {len(shown)} of {len(passes)} passes)" if len(shown) < len(passes) else ""
    ax.set_title(f"TCP speed along each pass, colour = pass{extra}")
    ax.grid(alpha=0.3)
    return save_figure(fig, path)


def tracking_error_m(trajectory: Any, trace: Any) -> tuple[np.ndarray, np.ndarray]:
    """(t_s (K,) [s], error (K,) [m]): distance between executed and commanded TCP positions,
    the command linearly interpolated at the trace times."""
    t_cmd = np.asarray(trajectory.t_s, float)
    p_cmd = np.asarray(trajectory.tcp_pos_world, float)
    t = np.asarray(trace.t_s, float)
    p = np.asarray(trace.tcp_pos_world, float)
    cmd = np.column_stack([np.interp(t, t_cmd, p_cmd[:, k]) for k in range(3)])
    return t, np.linalg.norm(p - cmd, axis=1)


def _rms_max_mm(err_m: np.ndarray, on: np.ndarray) -> tuple[float, float]:
    if not np.any(on):
        return float("nan"), float("nan")
    return float(np.sqrt(np.mean(err_m[on] ** 2))) * 1e3, float(err_m[on].max()) * 1e3


def plot_tracking_error(path: str | os.PathLike[str], trajectory: Any, trace: Any) -> Path:
    """TCP tracking error [mm] over time [s], paint-on intervals shaded, RMS/max on paint."""
    t, err = tracking_error_m(trajectory, trace)
    on = np.asarray(trace.paint_on, bool)
    rms_max = _rms_max_mm(err, on)
    k = _stride(len(t)).step or 1
    if k > 1:  # keep each bin's peak so the plotted maximum is the true one
        n = len(t) // k * k
        t = t[:n:k]
        err = err[:n].reshape(-1, k).max(1)
        on = np.asarray(on[:n].reshape(-1, k).any(1))
    fig = Figure(figsize=(8.0, 3.6), layout="constrained")
    ax = fig.subplots()
    ax.plot(t, err * 1e3, lw=0.8, color="C3", label="|executed − commanded| TCP")
    if np.any(on):
        lo, hi = float(np.nanmin(err * 1e3)), float(np.nanmax(err * 1e3))
        ax.fill_between(t, lo, hi if hi > lo else lo + 1, where=on, color="C2", alpha=0.12,
                        step="mid", label="brush on")
        ax.set_title(f"TCP tracking error (brush on: RMS {rms_max[0]:.3g} mm, "
                     f"max {rms_max[1]:.3g} mm)")
    else:
        ax.set_title("TCP tracking error")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tracking error [mm]")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    return save_figure(fig, path)


def plot_joints(path: str | os.PathLike[str], t_s: npt.ArrayLike, q: npt.ArrayLike,
                qd: npt.ArrayLike, q_lower: npt.ArrayLike, q_upper: npt.ArrayLike,
                v_max: npt.ArrayLike, joint_names: Sequence[str] | None = None,
                t_planned_s: npt.ArrayLike | None = None,
                q_planned: npt.ArrayLike | None = None) -> Path:
    """Joint positions [deg] and velocities [deg/s] against their limits, one row per joint.

    t_s: (K,) [s]; q, qd: (K, n) executed [rad], [rad/s]; q_lower, q_upper: (n,) [rad];
    v_max: (n,) [rad/s]; t_planned_s, q_planned: optional commanded (K', n) overlay [rad].
    """
    t = np.asarray(t_s, float)
    q = np.atleast_2d(np.asarray(q, float))
    qd = np.atleast_2d(np.asarray(qd, float))
    n = q.shape[1]
    lo, hi, vm = (np.asarray(a, float).reshape(-1) for a in (q_lower, q_upper, v_max))
    if q.shape != (len(t), n) or qd.shape != (len(t), n) or not (len(lo) == len(hi) == len(vm)
                                                                == n):
        raise PlotError(f"joint arrays disagree: t {t.shape}, q {q.shape}, qd {qd.shape}, "
                        f"limits {lo.shape}/{hi.shape}/{vm.shape}")
    names = list(joint_names) if joint_names is not None else [f"joint {i + 1}" for i in range(n)]
    # Utilizations from every sample; the curves from a decimated copy.
    use_q = 100 * np.max(np.abs(q - 0.5 * (lo + hi)), axis=0) / np.maximum(0.5 * (hi - lo), 1e-12)
    use_v = 100 * np.max(np.abs(qd), axis=0) / np.maximum(vm, 1e-12)
    st = _stride(len(t))
    t, q, qd = t[st], q[st], qd[st]
    if q_planned is not None and t_planned_s is not None:
        sp = _stride(len(np.asarray(t_planned_s)))
        t_planned_s = np.asarray(t_planned_s, float)[sp]
        q_planned = np.asarray(q_planned, float)[sp]
    fig = Figure(figsize=(9.0, 1.7 * n + 0.6), layout="constrained")
    axs = fig.subplots(n, 2, squeeze=False, sharex=True)
    deg = np.degrees
    for i in range(n):
        a, b = axs[i]
        if q_planned is not None and t_planned_s is not None:
            a.plot(np.asarray(t_planned_s, float), deg(np.asarray(q_planned, float)[:, i]),
                   color="0.6", lw=1.0, label="commanded")
        a.plot(t, deg(q[:, i]), color="C0", lw=0.9, label="executed")
        for lim in (lo[i], hi[i]):
            a.axhline(deg(lim), color="C3", ls="--", lw=0.9)
        a.set_ylabel(f"{names[i]}\n[deg]", fontsize=8)
        b.plot(t, deg(qd[:, i]), color="C1", lw=0.9)
        for lim in (-vm[i], vm[i]):
            b.axhline(deg(lim), color="C3", ls="--", lw=0.9)
        b.set_ylabel("[deg/s]", fontsize=8)
        a.set_title(f"position ({use_q[i]:.0f} % of half range)", fontsize=8)
        b.set_title(f"velocity ({use_v[i]:.0f} % of limit)", fontsize=8)
    axs[0, 0].legend(fontsize=7, loc="upper right")
    axs[-1, 0].set_xlabel("time [s]")
    axs[-1, 1].set_xlabel("time [s]")
    fig.suptitle("Joint positions and velocities; limits dashed red")
    return save_figure(fig, path)


def plot_index_width_curve(path: str | os.PathLike[str], widths_m: npt.ArrayLike,
                           nsd: npt.ArrayLike, chosen_width_m: float | None = None,
                           applicator_name: str = "") -> Path:
    """σ/μ [%] versus index width [mm] of parallel passes on a plane (the paper's Fig. 5).

    widths_m: (W,) index widths [m]; nsd: (W,) σ/μ as a fraction; chosen_width_m: the planner's
    width to mark [m], or None. The minimum ("sweet spot") is marked and labelled.
    """
    w = np.asarray(widths_m, float).reshape(-1)
    u = np.asarray(nsd, float).reshape(-1)
    if w.shape != u.shape or w.size < 2:
        raise PlotError(f"need ≥ 2 (width, σ/μ) pairs of equal length, got {w.size} and {u.size}")
    ok = np.isfinite(w) & np.isfinite(u)
    if not np.any(ok):
        raise PlotError("every σ/μ value is NaN or inf; check the applicator and widths")
    fig = Figure(figsize=(6.4, 4.0), layout="constrained")
    ax = fig.subplots()
    ax.plot(w[ok] * 1e3, u[ok] * 100, "-o", ms=3, color="C0", label="σ/μ of the film")
    k = int(np.flatnonzero(ok)[np.argmin(u[ok])])
    ax.plot(w[k] * 1e3, u[k] * 100, "*", ms=12, color="C3",
            label=f"sweet spot {w[k] * 1e3:.0f} mm ({u[k] * 100:.2f} %)")
    if chosen_width_m is not None and np.isfinite(chosen_width_m):
        ax.axvline(chosen_width_m * 1e3, color="C2", ls="--",
                   label=f"planner width {chosen_width_m * 1e3:.0f} mm")
    ax.set_xlabel("index width [mm]")
    ax.set_ylabel("σ/μ of film thickness [%]")
    ax.set_title("Uniformity vs index width" + (f" — {applicator_name}" if applicator_name else ""))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, path)


def plot_robot_timeline(path: str | os.PathLike[str], names: Sequence[str],
                        programs: Sequence[Any], own_samples: Sequence[int],
                        metrics: dict[str, Any], title: str) -> Path:
    """The robots of a cell at a glance (PNG, atomically). Left: a Gantt chart of the cycle, per
    robot its program (from its `meta["start_delay_s"]` [s], `own_samples[i]` samples long) and
    its brush-on runs on the common clock, against `metrics["executed_cycle_time_s"]` and
    `metrics["one_robot_cycle_s"]` (one robot running every program back to back) [s]. Right:
    per robot its busy share, paint share and paint credit [%] (`metrics["robots"][name]`).
    programs: each robot's `JointTrajectory` on the common clock."""
    fig = Figure(figsize=(11, 0.6 * len(names) + 2.4))
    FigureCanvasAgg(fig)                                  # tight_layout needs its renderer
    ax, bx = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2.2, 1]})
    for i, tr in enumerate(programs):
        t, active = tr.t_s, np.zeros(len(tr.t_s), bool)
        start = int(round(tr.meta.get("start_delay_s", 0.0) / tr.dt_s))
        active[start:start + own_samples[i]] = True
        for mask, colour in ((active, "#c8d3e0"), (tr.paint_on, "#d9534f")):
            for a, b in true_runs(mask):
                ax.broken_barh([(t[a], t[b - 1] - t[a])], (i - 0.3, 0.6), color=colour)
    cycle = metrics["executed_cycle_time_s"]
    ax.axvline(cycle, color="k", lw=1)
    ax.text(cycle, len(names) - 0.45, f"booth cycle {cycle:.1f} s\n one robot, all programs: "
            f"{metrics['one_robot_cycle_s']:.1f} s ", va="top", ha="right", fontsize=8,
            bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8})
    ax.set_yticks(range(len(names)), names)
    ax.set_xlabel("time [s] (grey: program, red: brush on)")
    ax.set_title(title)
    y = np.arange(len(names))
    for k, (key, label) in enumerate((("busy_share_pct", "busy"), ("paint_share_pct", "paint"),
                                      ("paint_credit_pct", "film credit"))):
        bx.barh(y + (k - 1) * 0.25, [metrics["robots"][n][key] for n in names], height=0.25,
                label=label)
    bx.set_yticks(y, names)
    bx.set_xlabel("% of the cycle / of the film")
    bx.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_body_film(path: str | os.PathLike[str], body: Any, part_counts: Sequence[int],
                   films_m: npt.ArrayLike, robot_names: Sequence[str],
                   band: npt.ArrayLike | None = None, title: str = "") -> Path:
    """The film over a body of several parts (PNG, atomically): the executed film on one colour
    scale [µm] (top row) and which robot laid most of it, the overlap band outlined (bottom
    row); one column per view, each part seen along the body axis nearest its area-weighted mean
    normal (the side from −y, the roof from +z).

    body: the merged body `Surface` (parts stacked in order, `part_counts` vertices each);
    films_m: (R, N) each robot's executed film [m]; band: (N,) bool overlap-band mask.
    """
    films_m = np.asarray(films_m, float)
    band = None if band is None else np.asarray(band, bool)
    v, f = np.asarray(body.vertices), np.asarray(body.faces)
    total_um = 1e6 * films_m.sum(axis=0)
    lead = np.argmax(films_m, axis=0)
    offs = np.cumsum([0, *part_counts])
    views: dict[str, tuple[tuple[int, int], list[int]]] = {}
    for i in range(len(part_counts)):   # seen along the axis (with its sign) nearest its normal
        sl = slice(offs[i], offs[i + 1])
        n = (np.asarray(body.normals)[sl] * np.asarray(body.vertex_areas)[sl, None]).sum(axis=0)
        k = int(np.argmax(np.abs(n)))
        a, b = (j for j in range(3) if j != k)
        ax2 = (a, b)
        views.setdefault(f"seen from {'+' if n[k] >= 0 else '−'}{_AXES[k]}", (ax2, []))[1].append(i)
    vmin, vmax = thickness_range_um(total_um * 1e-6)
    ncol = len(views)
    width = [float(np.ptp(v[np.concatenate([np.arange(offs[i], offs[i + 1]) for i in mem]),
                             ax2[0]])) + 0.1 for ax2, mem in views.values()]
    fig = Figure(figsize=(4.5 * ncol + 1.5, 6.8), layout="constrained")
    axs = fig.subplots(2, ncol, squeeze=False, gridspec_kw={"width_ratios": width})
    robot_cmap = colormaps[ROBOT_CMAP]
    assert isinstance(robot_cmap, ListedColormap)      # a qualitative map: its colours
    colours = np.asarray(robot_cmap.colors, float)             # (n, 3) RGB
    cmap_zone = ListedColormap(colours[:max(1, len(robot_names))])
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
    handles = [axs[1, 0].scatter([], [], color=colours[k], marker="s", label=n)
               for k, n in enumerate(robot_names)]
    fig.legend(handles=handles, fontsize=8, loc="outside lower center",
               ncols=max(1, len(robot_names)),
               title="black outline: overlap band (two robots each ≥ 10 % of the film)",
               title_fontsize=8)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)
