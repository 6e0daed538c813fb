"""Benchmark of the offscreen renders: frame time of a film-thickness render and a robot render.

Prints the GL backend, then one figure a line (label, value, unit): for each of
- "thickness": the part with its film colour map in the bare booth (one model),
- "robot": the paint cell (robot + part + booth) with the robot at a new pose every frame,
- "cell+film": the cell with the film composited by depth (two models, colour + depth each),
with shadows off and on, the mean and median time per frame [ms] over `--frames` frames after
3 warm-up frames, plus the one-off scene set-up time (compile + GL context) [ms].

    .venv/bin/python benchmarks/render.py [--part door] [--size 640x480] [--frames 30]
    MUJOCO_GL=egl .venv/bin/python benchmarks/render.py      # force a backend
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from paintcell.output import render
from paintcell.surface.parts import get_part


def _time_frames(r: render.SceneRenderer, camera: object, qs: np.ndarray | None,
                 frames: int) -> np.ndarray:
    for k in range(3):  # warm-up: first frames upload textures and compile shaders
        r.render(camera, None if qs is None else qs[k % len(qs)])
    dt = np.empty(frames)
    for k in range(frames):
        q = None if qs is None else qs[k % len(qs)]
        t0 = time.perf_counter()
        r.render(camera, q)
        dt[k] = time.perf_counter() - t0
    return dt * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", default="door",
                    help="library part (paintcell.surface.parts)")
    ap.add_argument("--resolution", type=float, default=0.01, help="part mesh resolution [m]")
    ap.add_argument("--size", default="640x480", help="frame size WxH [px]")
    ap.add_argument("--frames", type=int, default=30, help="timed frames per case")
    args = ap.parse_args()
    w, h = (int(x) for x in args.size.lower().split("x"))

    print(f"backend: {render.backend_name()}")
    surface = get_part(args.part, resolution_m=args.resolution)
    x = surface.vertices[:, 0]
    th = (10.0 + 40.0 * (x - x.min()) / np.ptp(x)) * 1e-6  # 10 → 50 µm ramp
    print(f"part: {args.part}, {len(surface.vertices)} vertices, {len(surface.faces)} faces")

    from paintcell.execution.cell import build_cell
    from paintcell.robots import load_robot

    T = np.eye(4)
    T[:3, 3] = [1.4, 0.0, 0.9]
    robot = load_robot("abb_paint")
    cell = build_cell(robot, surface, T)
    rng = np.random.default_rng(0)
    qs = cell.q_home + 0.3 * rng.uniform(-1, 1, (16, cell.nq))

    cases = [
        ("thickness", None, render.film_from_surface(surface, th, 10, 50, T), "front", None),
        ("robot", cell, None, None, qs),
        ("cell+film", cell, render.film_from_surface(surface, th, 10, 50, T), "front", qs),
    ]
    presets = render.part_cameras(surface, T)
    for label, scene, film, cam, q in cases:
        for shadows in (False, True):
            t0 = time.perf_counter()
            r = render.SceneRenderer(scene, film, (w, h), shadows, presets)
            setup_ms = (time.perf_counter() - t0) * 1e3
            try:
                dt = _time_frames(r, cam, q, args.frames)
            finally:
                r.close()
            tag = f"{label} {w}x{h} shadows {'on' if shadows else 'off'}"
            print(f"{tag} frame time mean: {dt.mean():.2f} ms")
            print(f"{tag} frame time median: {np.median(dt):.2f} ms")
            print(f"{tag} scene setup: {setup_ms:.0f} ms")


if __name__ == "__main__":
    main()
