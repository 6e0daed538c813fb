"""The booth at a glance (`booth.png` in a booth's results folder).

Left: a Gantt chart of the booth cycle — per robot its start delay, its moves and its paint
passes on the common clock, against the cycle one robot would need for all the programs back to
back. Right: per robot its busy share, paint share and paint credit [%].
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from paintcell.core.atomic_io import atomic_path


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) index pairs of the True runs of a boolean array."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True))


def booth_figure(result: Any, path: Path) -> Path:
    """Write the figure of a `paintcell.booth.booth_run.BoothResult` to `path` (PNG,
    atomically)."""
    m = result.report.metrics
    names = [r.name for r in result.scenario.robots]
    fig = Figure(figsize=(11, 0.6 * len(names) + 2.4))
    FigureCanvasAgg(fig)
    ax, bx = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2.2, 1]})
    for i, tr in enumerate(result.trajectories):
        t = tr.t_s
        active = np.zeros(len(t), bool)
        start = int(round(tr.meta.get("start_delay_s", 0.0) / tr.dt_s))
        own = len(result.static_trajectories[i].t_s)
        active[start:start + own] = True
        for a, b in _runs(active):
            ax.broken_barh([(t[a], t[b - 1] - t[a])], (i - 0.3, 0.6), color="#c8d3e0")
        for a, b in _runs(tr.paint_on):
            ax.broken_barh([(t[a], t[b - 1] - t[a])], (i - 0.3, 0.6), color="#d9534f")
    ax.axvline(m["executed_cycle_time_s"], color="k", lw=1)
    ax.text(m["executed_cycle_time_s"], len(names) - 0.45,
            f"booth cycle {m['executed_cycle_time_s']:.1f} s\n one robot, all programs: "
            f"{m['one_robot_cycle_s']:.1f} s ", va="top", ha="right", fontsize=8,
            bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8})
    ax.set_yticks(range(len(names)), names)
    ax.set_xlabel("time [s] (grey: program, red: brush on)")
    ax.set_title(f"{result.scenario.name}: conveyor {m['conveyor_speed_m_s']:.3f} m/s")
    rob = m["robots"]
    y = np.arange(len(names))
    for k, (key, label) in enumerate((("busy_share_pct", "busy"), ("paint_share_pct", "paint"),
                                      ("paint_credit_pct", "film credit"))):
        bx.barh(y + (k - 1) * 0.25, [rob[n][key] for n in names], height=0.25, label=label)
    bx.set_yticks(y, names)
    bx.set_xlabel("% of the cycle / of the film")
    bx.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    return path
