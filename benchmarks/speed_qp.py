"""Benchmark of the per-pass speed QP (paper §3, eq. 2) on a plane and on the door.

Prints, one figure a line: problem size, band σ/μ at constant and optimized speed [%], accepted
SQP steps and the wall time of one `optimize_pass_speed` call (rate matrices + SQP + checks), for
the paper's objective (K_j fixed at constant speed) and the centred variant, and the ratio of their
times measured in the same process.

- plane, 1 m panel, straight pass with 100 mm overspray (the paper's Table 1 row, 8.60 % → 3.88 %
  there), and with 235 mm overspray at constant speed (3.88 % there);
- door, one pass across it (along max curvature) with 100 mm overspray, band of 11 sub-offsets.

    .venv/bin/python benchmarks/speed_qp.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from paintcell.coverage.speed_qp import SpeedSettings, SubOffsetBand, optimize_pass_speed
from paintcell.paint.applicator import Applicator
from paintcell.surface.parts import door


def plane_pass(app: Applicator, over_m: float, panel_m: float = 1.0, ds_m: float = 0.005,
               n_curves: int = 11, half_band_m: float = 0.15):
    """Straight pass along x over a panel at z = 0; band of sub-offsets in y on the panel."""
    length = panel_m + 2 * over_m
    n = int(round(length / ds_m))
    s = np.full(n, length / n)
    x = -length / 2 + (np.arange(n) + 0.5) * length / n
    c = np.stack([x, np.zeros(n), np.full(n, app.standoff_m)], axis=1)
    a = np.tile([0.0, 0.0, -1.0], (n, 1))
    d = np.tile([1.0, 0.0, 0.0], (n, 1))
    m = int(round(panel_m / ds_m))
    xm = -panel_m / 2 + (np.arange(m) + 0.5) * panel_m / m
    ys = np.linspace(-half_band_m, half_band_m, n_curves)
    ys = np.concatenate([[0.0], ys[ys != 0]])      # curve 0 is the pass's foot-point curve
    band = SubOffsetBand(
        points=tuple(np.stack([xm, np.full(m, y), np.zeros(m)], axis=1) for y in ys),
        normals=tuple(np.tile([0.0, 0.0, 1.0], (m, 1)) for _ in ys),
        lengths=tuple(np.full(m, panel_m / m) for _ in ys))
    return c, a, d, s, band


def _row(grid: np.ndarray, normals: np.ndarray, i: int):
    """Segment midpoints, unit normals and lengths of grid row i (a curve along v)."""
    p, n = grid[i], normals[i]
    mid = 0.5 * (p[1:] + p[:-1])
    nm = n[1:] + n[:-1]
    nm /= np.linalg.norm(nm, axis=1, keepdims=True)
    return mid, nm, np.linalg.norm(np.diff(p, axis=0), axis=1)


def door_pass(app: Applicator, over_m: float = 0.1, n_curves: int = 11, step: int = 6):
    """A pass across the door along its curved direction (v) at x ≈ 0, extended straight along
    the end tangents by the overspray; band rows every `step` grid rows (5 mm grid)."""
    surf = door()
    nu, nv = surf.grid_shape
    grid = surf.vertices.reshape(nu, nv, 3)
    normals = surf.normals.reshape(nu, nv, 3)
    i0 = nu // 2
    foot, nrm = grid[i0], normals[i0]
    ds = np.linalg.norm(foot[1] - foot[0])
    k = int(round(over_m / ds))
    t0 = foot[0] - foot[1]
    t1 = foot[-1] - foot[-2]
    t0 /= np.linalg.norm(t0)
    t1 /= np.linalg.norm(t1)
    ext0 = foot[0] + ds * np.arange(k, 0, -1)[:, None] * t0
    ext1 = foot[-1] + ds * np.arange(1, k + 1)[:, None] * t1
    path_foot = np.concatenate([ext0, foot, ext1])
    path_n = np.concatenate([np.repeat(nrm[:1], k, 0), nrm, np.repeat(nrm[-1:], k, 0)])
    tcp = path_foot + app.standoff_m * path_n
    c = 0.5 * (tcp[1:] + tcp[:-1])
    s = np.linalg.norm(np.diff(tcp, axis=0), axis=1)
    a = -(path_n[1:] + path_n[:-1])
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    d = np.diff(tcp, axis=0)
    d -= np.sum(d * a, axis=1, keepdims=True) * a
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    offs = [0] + [o for o in range(-(n_curves // 2), n_curves // 2 + 1) if o != 0]
    rows = [_row(grid, normals, i0 + o * step) for o in offs]
    band = SubOffsetBand(points=tuple(r[0] for r in rows), normals=tuple(r[1] for r in rows),
                         lengths=tuple(r[2] for r in rows))
    return c, a, d, s, band


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="timing repeats (best is printed)")
    args = ap.parse_args()
    app = Applicator.default()
    settings = SpeedSettings()
    centred = SpeedSettings(objective="centred")
    print(f"settings: v_nom {settings.v_nominal_m_s} m/s, v in [{settings.v_min_m_s}, "
          f"{settings.v_max_m_s}] m/s, a_max {settings.a_max_m_s2} m/s^2, "
          f"n_knots {settings.n_knots}")
    cases = [("plane 100 mm overspray", plane_pass(app, 0.10)),
             ("plane 235 mm overspray", plane_pass(app, 0.235)),
             ("door across (max curvature), 100 mm overspray", door_pass(app))]
    for label, (c, a, d, s, band) in cases:
        times = {}
        for name, st in (("paper", settings), ("centred", centred)):
            best = np.inf
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                res = optimize_pass_speed(app, c, a, d, s, band, st)
                best = min(best, time.perf_counter() - t0)
            times[name] = best
            m = sum(len(p) for p in band.points)
            tag = f"{label} [{name}]"
            print(f"{tag}: segments {len(s)}, sub-offset curves {band.n_curves}, band points {m}")
            print(f"{tag}: sigma/mu constant speed {res.nsd_constant_pct:.2f} %")
            print(f"{tag}: sigma/mu optimized {res.nsd_optimized_pct:.2f} % ({res.status})")
            v = res.sample_speeds_m_s
            print(f"{tag}: speed range {v.min():.3f} .. {v.max():.3f} m/s")
            print(f"{tag}: SQP steps accepted {res.iterations}")
            print(f"{tag}: optimize_pass_speed time {best * 1e3:.1f} ms (best of {args.repeat})")
        print(f"{label}: time centred / paper = {times['centred'] / times['paper']:.2f}x")

if __name__ == "__main__":
    main()
