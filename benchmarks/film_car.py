"""Benchmark: the whole-car film map — ≈ 8 m² of skin at 5 mm under a full program.

The car is built from library parts (a two-door coupé's skin): hood, roof, trunk lid (the flat
panel), two doors and two front fenders, 8.0 m² together, laid out side by side 0.3 m apart,
painted side up. Each part is planned with the default planner (at 25 mm, the plan's gun path
does not need the fine mesh), its program moved with it, and all programs joined into one (the
full program), sampled every 5 ms as `paintcell.validation.validate` bins an executed trace. The
film map is then
computed on every 5 mm vertex of every part from every gun sample (overspray from a part's
program onto its neighbours included) with the compiled kernel and, for the baseline, today's
numpy kernel on a share of the program (time scaled).

    .venv/bin/python benchmarks/film_car.py [--threads 2] [--dt 0.005] [--numpy-fraction 0.05]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import thickness
from paintcell.paint.deposition_samples import GunSamples
from paintcell.surface import parts

#: (part, copies) of the coupé's skin.
CAR = (("hood", 1), ("roof", 1), ("panel", 1), ("door", 2), ("fender", 2))
GAP_M = 0.3


def resample(plan: object, dt_s: float) -> GunSamples:
    """The plan's paint-on path at a fixed time step dt_s [s] (linear interpolation of
    positions and axes in time, dwell dt_s each): the density of an executed trace's samples as
    `paintcell.validation.validate` bins them (5 ms)."""
    out = []
    for p in plan.passes:  # type: ignore[attr-defined]
        on = np.asarray(p.paint_on, bool)
        t = np.asarray(p.times_s, float)[on]
        if len(t) < 2:
            continue
        tt = np.arange(t[0], t[-1], dt_s)

        def lerp(v: np.ndarray, on: np.ndarray = on, t: np.ndarray = t,
                 tt: np.ndarray = tt) -> np.ndarray:
            return np.column_stack([np.interp(tt, t, v[on][:, k]) for k in range(3)])

        z = lerp(p.spray_axes)
        z /= np.linalg.norm(z, axis=1, keepdims=True)
        x = lerp(p.travel_dirs)
        x -= np.sum(x * z, axis=1, keepdims=True) * z
        x /= np.linalg.norm(x, axis=1, keepdims=True)
        out.append(GunSamples(lerp(p.positions), z, x, np.full(len(tt), dt_s)))
    return GunSamples(*(np.concatenate([getattr(q, f) for q in out]) for f in
                        ("positions", "spray_axes", "travel_dirs", "dwell_s")))


def build_car(res_m: float, plan_res_m: float, dt_s: float) -> tuple[np.ndarray, np.ndarray,
                                                                    float, GunSamples, float]:
    """(points (N, 3), normals (N, 3), area [m²], the full program, planning time [s])."""
    app = Applicator.default()
    pts, nrms, guns = [], [], []
    area, x0, t_plan = 0.0, 0.0, 0.0
    for name, copies in CAR:
        fine = parts.get_part(name, resolution_m=res_m)
        t0 = time.perf_counter()
        plan = plan_coverage(parts.get_part(name, resolution_m=plan_res_m), app,
                             PlannerSettings())
        t_plan += time.perf_counter() - t0
        g = resample(plan, dt_s)
        lo, hi = fine.vertices.min(axis=0), fine.vertices.max(axis=0)
        for _ in range(copies):
            off = np.array([x0 - lo[0], 0.0, 0.0])
            pts.append(fine.vertices + off)
            nrms.append(fine.normals)
            guns.append(GunSamples(g.positions + off, g.spray_axes, g.travel_dirs, g.dwell_s))
            area += fine.area
            x0 += hi[0] - lo[0] + GAP_M
    gun = GunSamples(*(np.concatenate([getattr(q, f) for q in guns]) for f in
                       ("positions", "spray_axes", "travel_dirs", "dwell_s")))
    return np.concatenate(pts), np.concatenate(nrms), area, gun, t_plan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--resolution", type=float, default=0.005, help="film mesh resolution [m]")
    ap.add_argument("--dt", type=float, default=0.005,
                    help="time step of the program's samples [s] (5 ms: as validate bins a trace)")
    ap.add_argument("--numpy-fraction", type=float, default=0.05,
                    help="share of the program the numpy baseline runs on (time scaled)")
    args = ap.parse_args()
    app = Applicator.default()
    p, n, area, gun, t_plan = build_car(args.resolution, 0.025, args.dt)
    print(f"car skin: {' + '.join(f'{c} x {k}' for k, c in CAR)}")
    print(f"area: {area:.2f} m2 at {args.resolution * 1e3:.0f} mm: {len(p)} points")
    print(f"full program: {len(gun)} gun samples ({args.dt * 1e3:g} ms apart), "
          f"{gun.total_time_s:.1f} s of paint "
          f"(planning, not timed below: {t_plan:.1f} s)")
    print(f"load average before (1 min, shared machine): {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} cores")
    small = GunSamples(gun.positions[:64], gun.spray_axes[:64], gun.travel_dirs[:64],
                       gun.dwell_s[:64])
    thickness(app, small, p[:1000], n[:1000], backend="numba")  # compile / load the cache
    c0, t0 = time.process_time(), time.perf_counter()
    film = thickness(app, gun, p, n, threads=args.threads, backend="numba")
    t_jit, c_jit = time.perf_counter() - t0, time.process_time() - c0
    print(f"whole-car film map, numba kernel, {args.threads} threads: {t_jit:.2f} s wall, "
          f"{c_jit:.2f} s CPU (target <= 30 s on 2 cores)")
    k = max(16, int(args.numpy_fraction * len(gun)))
    sub = GunSamples(gun.positions[:k], gun.spray_axes[:k], gun.travel_dirs[:k], gun.dwell_s[:k])
    t0 = time.perf_counter()
    ref = thickness(app, sub, p, n, threads=args.threads, backend="numpy")
    t_np = (time.perf_counter() - t0) * len(gun) / k
    part_jit = thickness(app, sub, p, n, threads=args.threads, backend="numba")
    print(f"whole-car film map, numpy kernel (timed on {k} of {len(gun)} samples, scaled): "
          f"{t_np:.1f} s wall")
    print(f"speed-up numba / numpy kernel: {t_np / t_jit:.1f} x")
    print(f"max |numba - numpy| / max film on that share: "
          f"{np.max(np.abs(part_jit - ref)) / np.max(ref):.2e}")
    painted = film > 0
    print(f"film: max {film.max() * 1e6:.1f} um, painted points {100 * painted.mean():.1f} %")
    print(f"load average after (1 min): {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
