"""Benchmark of the thickness kernel: the door at 5 mm under a raster of ≥ 2,000 gun samples.

Prints, one figure a line, in one run: problem size; the pairs the kernels evaluate after culling;
the compiled numba kernel (2 threads and 1), today's numpy kernel, and a plain chunked numpy
evaluation of all pairs (the simplified formula, and the literal `deposition_rate_reference`):
time, evaluated pairs per second (wall and per CPU-second: other jobs share this machine, and
the load average is printed), the thread count and what the threads' CPU time says 2 idle cores
would give, speed-ups, and the agreement relative to the peak film: between the kernels, with
the all-pairs evaluations (they differ by the paint the culling leaves out, f < FOOTPRINT_REL of
the peak, by design) and with the literal formula on exactly the kernels' pairs (round-off).

    .venv/bin/python benchmarks/deposition.py [--threads 2] [--repeat 3] [--plain-fraction 0.25]
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

import numba
import numpy as np

from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate_reference, thickness
from paintcell.paint.deposition_kernel import (
    BLOCK_POINTS,
    CHUNK_SAMPLES,
    candidate_blocks,
    make_blocks,
)
from paintcell.paint.deposition_samples import GunSamples, tool_axes


def door_points() -> tuple[str, np.ndarray, np.ndarray]:
    """The door part at 5 mm, or an equivalent 1.1 × 0.8 m grid when
    `paintcell.surface.parts` is absent."""
    try:
        from paintcell.surface.parts import door
        s = door()
        return "paintcell.surface.parts.door()", s.vertices, s.normals
    except ImportError:
        x, y = np.meshgrid(np.linspace(-0.55, 0.55, 221), np.linspace(-0.4, 0.4, 161),
                           indexing="ij")
        p = np.c_[x.ravel(), y.ravel(), 0.02 * np.cos(np.pi * y.ravel() / 0.8)]
        return "1.1 x 0.8 m grid", p, np.tile([0.0, 0.0, 1.0], (len(p), 1))


def raster(spacing_m: float = 0.35, step_m: float = 0.003, speed_m_s: float = 0.5) -> GunSamples:
    """Boustrophedon passes along x at 0.25 m above z = 0, spraying −z, 0.25 m overspray."""
    parts = []
    ys = np.arange(-0.525, 0.526, spacing_m)
    for i, y in enumerate(ys):
        a, b = np.array([-0.8, y, 0.25]), np.array([0.8, y, 0.25])
        if i % 2:
            a, b = b, a
        parts.append(GunSamples.straight_pass(a, b, [0, 0, -1], speed_m_s, step_m))
    return GunSamples(*(np.concatenate([getattr(p, f) for p in parts]) for f in
                        ("positions", "spray_axes", "travel_dirs", "dwell_s")))


def evaluated_pairs(app: Applicator, gun: GunSamples, p: np.ndarray, n: np.ndarray) -> int:
    """Pairs the fast kernel actually evaluates (candidate blocks × samples of each chunk)."""
    blocks = make_blocks(p, n, BLOCK_POINTS)
    _, _, a = tool_axes(gun.spray_axes, gun.travel_dirs)
    tan_cone = app.footprint_radius_m / app.standoff_m
    total = 0
    for i in range(0, len(gun), CHUNK_SAMPLES):
        sl = slice(i, min(i + CHUNK_SAMPLES, len(gun)))
        cand = candidate_blocks(blocks, gun.positions[sl], a[sl], tan_cone)
        total += len(cand) * BLOCK_POINTS * (sl.stop - sl.start)
    return total


def plain_broadcast(app: Applicator, gun: GunSamples, p: np.ndarray, n: np.ndarray,
                    chunk: int = 16) -> np.ndarray:
    """All S × N pairs with the literal DESIGN.md formula (`deposition_rate_reference`), `chunk`
    samples at a time."""
    out = np.zeros(len(p))
    for i in range(0, len(gun), chunk):
        sl = slice(i, i + chunk)
        out += gun.dwell_s[sl] @ deposition_rate_reference(
            app, gun.positions[sl], gun.spray_axes[sl], gun.travel_dirs[sl], p, n)
    return out


def plain_same_pairs(app: Applicator, gun: GunSamples, p: np.ndarray,
                     n: np.ndarray) -> np.ndarray:
    """The literal DESIGN.md formula (`deposition_rate_reference`) on exactly the pairs the
    kernels evaluate: every sample of a `CHUNK_SAMPLES` chunk against the points of the blocks
    the cone test keeps for that chunk (the kernels' culling, and nothing else, applied to an
    independent all-pairs evaluation) — so the kernels' arithmetic can be held to round-off."""
    blocks = make_blocks(p, n, BLOCK_POINTS)
    block_of = np.empty(len(p), np.int64)
    block_of[blocks.order] = np.arange(len(p)) // BLOCK_POINTS
    _, _, a = tool_axes(gun.spray_axes, gun.travel_dirs)
    tan_cone = app.footprint_radius_m / app.standoff_m
    out = np.zeros(len(p))
    for i in range(0, len(gun), CHUNK_SAMPLES):
        sl = slice(i, min(i + CHUNK_SAMPLES, len(gun)))
        keep = np.zeros(len(blocks.radii), bool)
        keep[candidate_blocks(blocks, gun.positions[sl], a[sl], tan_cone)] = True
        pts = np.flatnonzero(keep[block_of])
        if len(pts):
            out[pts] += gun.dwell_s[sl] @ deposition_rate_reference(
                app, gun.positions[sl], gun.spray_axes[sl], gun.travel_dirs[sl], p[pts], n[pts])
    return out


def plain_simplified(app: Applicator, gun: GunSamples, p: np.ndarray, n: np.ndarray,
                     chunk: int = 16) -> np.ndarray:
    """All S × N pairs with the simplified formula f(h·dx/dz, h·dy/dz)·(−n·d)·h²/dz³ written as
    plain numpy expressions (GEMMs for the projections; no culling, no in-place work), `chunk`
    samples at a time."""
    x_hat, y_hat, a = tool_axes(gun.spray_axes, gun.travel_dirs)
    h = app.standoff_m
    out = np.zeros(len(p))
    for i in range(0, len(gun), chunk):
        sl = slice(i, i + chunk)
        g = gun.positions[sl]
        dx = x_hat[sl] @ p.T - np.sum(g * x_hat[sl], axis=1)[:, None]     # (K, N) by GEMM
        dy = y_hat[sl] @ p.T - np.sum(g * y_hat[sl], axis=1)[:, None]
        dz = a[sl] @ p.T - np.sum(g * a[sl], axis=1)[:, None]
        nd = np.sum(n * p, axis=1)[None, :] - g @ n.T
        ok = (dz > 0) & (nd < 0)
        dzs = np.where(ok, dz, 1.0)
        rate = app.flux(h * dx / dzs, h * dy / dzs) * (-nd) * h * h / dzs**3
        out += gun.dwell_s[sl] @ np.where(ok, rate, 0.0)
    return out


def timed(fn: Callable[[], np.ndarray], repeat: int) -> tuple[float, float, np.ndarray]:
    """(best wall time [s], CPU time of that call [s], result) of `repeat` calls."""
    best, cpu, out = float("inf"), 0.0, np.zeros(0)
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        out = fn()
        t, c = time.perf_counter() - t0, time.process_time() - c0
        if t < best:
            best, cpu = t, c
    return best, cpu, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--plain-fraction", type=float, default=0.25,
                    help="fraction of the samples the all-pairs references run on (1 = all)")
    args = ap.parse_args()
    app = Applicator.default()
    label, p, n = door_points()
    gun = raster()
    s, npts = len(gun), len(p)
    print(f"part: {label}")
    print(f"points: {npts}")
    print(f"gun samples: {s}")
    print(f"full problem pairs (S x N): {s * npts / 1e6:.1f} M")
    print(f"load average before (1 min, all helpers on this machine): {os.getloadavg()[0]:.2f} "
          f"on {os.cpu_count()} cores")
    n_eval = evaluated_pairs(app, gun, p, n)
    print(f"evaluated pairs (after culling, numba and numpy kernels alike): {n_eval / 1e6:.1f} M "
          f"({100 * n_eval / (s * npts):.1f} %)")
    thickness(app, gun, p, n, threads=args.threads, backend="numba")  # compile / load cache
    ref = None
    rows = []
    for name, kw in ((f"numba kernel, {args.threads} threads",
                      dict(backend="numba", threads=args.threads)),
                     ("numba kernel, 1 thread", dict(backend="numba", threads=1)),
                     (f"numpy kernel (today's), {args.threads} threads",
                      dict(backend="numpy", threads=args.threads))):
        t, c, out = timed(lambda kw=kw: thickness(app, gun, p, n, **kw), args.repeat)
        rows.append((name, t, c, out))
        print(f"{name}: {t * 1e3:.1f} ms wall (best of {args.repeat}), {c * 1e3:.1f} ms CPU")
        print(f"{name} evaluated throughput: {n_eval / t / 1e6:.0f} M pairs/s wall, "
              f"{n_eval / c / 1e6:.0f} M pairs per CPU-second")
    c2, c1 = rows[0][2], rows[1][2]
    print(f"numba threads: {args.threads} asked, {int(numba.config.NUMBA_NUM_THREADS)} in the "
          f"pool, {os.cpu_count()} CPUs")
    print(f"CPU time of the {args.threads}-thread run / 1-thread run: {c2 / c1:.2f} (1.00: the "
          "extra threads add no work; above: parallel overhead)")
    print(f"estimate for {args.threads} idle cores: {args.threads} x the {args.threads}-thread "
          f"run's pairs per CPU-second = {args.threads * n_eval / c2 / 1e6:.0f} M evaluated "
          "pairs/s (target >= 300 M on 2 cores; the wall figure above is that only on an idle "
          "machine)")
    ref = rows[2][3]
    for name, _, _, out in rows[:2]:
        print(f"max |{name} - numpy kernel| / max thickness: "
              f"{float(np.max(np.abs(out - ref)) / np.max(ref)):.2e}")
    print(f"speed-up numba / numpy kernel (wall): {rows[2][1] / rows[0][1]:.2f} x")
    # the all-pairs plain numpy evaluation costs exactly S·N work: time it on a prefix
    sub = max(CHUNK_SAMPLES, int(round(args.plain_fraction * s)))
    gsub = GunSamples(gun.positions[:sub], gun.spray_axes[:sub], gun.travel_dirs[:sub],
                      gun.dwell_s[:sub])
    t_sub = thickness(app, gsub, p, n, threads=args.threads, backend="numpy")
    print(f"plain chunked numpy timed on: {sub} of {s} samples (all pairs, time scaled by "
          f"{s / sub:.2f})")
    for name, fn in (("plain chunked numpy, simplified formula", plain_simplified),
                     ("plain chunked numpy, literal formula", plain_broadcast)):
        t0 = time.perf_counter()
        t_plain = fn(app, gsub, p, n)
        t_pl = (time.perf_counter() - t0) * s / sub
        err = float(np.max(np.abs(t_sub - t_plain)) / np.max(t_plain))
        print(f"{name}: {t_pl * 1e3:.1f} ms (all S x N pairs)")
        print(f"{name} evaluated throughput: {s * npts / t_pl / 1e6:.0f} M pairs/s")
        print(f"speed-up numba (evaluated pairs/s) / {name}: "
              f"{n_eval / rows[0][1] / (s * npts / t_pl):.1f} x")
        print(f"max |numpy kernel - {name}| / max thickness: {err:.2e}")
    # the all-pairs references differ from the kernels by what the culling leaves out (f below
    # FOOTPRINT_REL of the peak, by design); on the kernels' own pairs they must agree to round-off
    same = plain_same_pairs(app, gsub, p, n)
    numba_sub = thickness(app, gsub, p, n, threads=args.threads, backend="numba")
    for name, t_k in (("numba kernel", numba_sub), ("numpy kernel", t_sub)):
        print(f"max |{name} - literal formula on the kernels' pairs| / max thickness: "
              f"{float(np.max(np.abs(t_k - same)) / np.max(same)):.2e} (on {sub} samples)")
    print(f"max thickness: {np.max(ref) * 1e6:.2f} um")
    print(f"load average after (1 min): {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
