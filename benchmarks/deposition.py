"""Benchmark of the thickness kernel: the door at 5 mm under a raster of ≥ 2,000 gun samples.

Prints, one figure a line: problem size, fast-kernel time, pairs per second (S × N of the full
problem, and the pairs actually evaluated after culling), the plain broadcast numpy evaluation
(all pairs in chunks of samples: the literal formula `deposition_rate_reference`, the
simplified formula as plain numpy, and the library's dense `deposition_rate`) time, the
speed-ups, and the agreement.

    .venv/bin/python benchmarks/deposition.py [--threads 2] [--repeat 3] [--plain-fraction 0.25]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from planning.applicator import Applicator
from planning.deposition import (
    BLOCK_POINTS,
    CHUNK_SAMPLES,
    GunSamples,
    _candidate_blocks,
    _make_blocks,
    _tool_axes,
    deposition_rate,
    deposition_rate_reference,
    thickness,
)


def door_points() -> tuple[str, np.ndarray, np.ndarray]:
    """The door part at 5 mm, or an equivalent 1.1 × 0.8 m grid when `planning.parts` is absent."""
    try:
        from planning.parts import door
        s = door()
        return "planning.parts.door()", s.vertices, s.normals
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
    blocks = _make_blocks(p, n, BLOCK_POINTS)
    _, _, a = _tool_axes(gun.spray_axes, gun.travel_dirs)
    tan_cone = app.footprint_radius_m / app.standoff_m
    total = 0
    for i in range(0, len(gun), CHUNK_SAMPLES):
        sl = slice(i, min(i + CHUNK_SAMPLES, len(gun)))
        cand = _candidate_blocks(blocks, gun.positions[sl], a[sl], tan_cone)
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


def dense_rate(app: Applicator, gun: GunSamples, p: np.ndarray, n: np.ndarray,
               chunk: int = 64) -> np.ndarray:
    """All S × N pairs with the library's dense `deposition_rate` (in-place, no culling)."""
    out = np.zeros(len(p))
    for i in range(0, len(gun), chunk):
        sl = slice(i, i + chunk)
        out += gun.dwell_s[sl] @ deposition_rate(app, gun.positions[sl], gun.spray_axes[sl],
                                                 gun.travel_dirs[sl], p, n)
    return out


def plain_simplified(app: Applicator, gun: GunSamples, p: np.ndarray, n: np.ndarray,
                     chunk: int = 16) -> np.ndarray:
    """All S × N pairs with the simplified formula f(h·dx/dz, h·dy/dz)·(−n·d)·h²/dz³ written as
    plain numpy expressions (GEMMs for the projections; no culling, no in-place work), `chunk`
    samples at a time."""
    x_hat, y_hat, a = _tool_axes(gun.spray_axes, gun.travel_dirs)
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
    thickness(app, gun, p, n, threads=args.threads)  # warm-up
    times = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        t_fast = thickness(app, gun, p, n, threads=args.threads)
        times.append(time.perf_counter() - t0)
    t_best = min(times)
    n_eval = evaluated_pairs(app, gun, p, n)
    print(f"fast kernel threads: {args.threads}")
    print(f"fast kernel time (best of {args.repeat}): {t_best * 1e3:.1f} ms")
    print(f"fast kernel throughput (S x N / time): {s * npts / t_best / 1e6:.0f} M pairs/s")
    print(f"actually evaluated pairs: {n_eval / 1e6:.1f} M ({100 * n_eval / (s * npts):.1f} %)")
    print(f"actually evaluated throughput: {n_eval / t_best / 1e6:.0f} M pairs/s")
    # the all-pairs references cost exactly S·N work: time them on a prefix of the samples
    sub = max(CHUNK_SAMPLES, int(round(args.plain_fraction * s)))
    gsub = GunSamples(gun.positions[:sub], gun.spray_axes[:sub], gun.travel_dirs[:sub],
                      gun.dwell_s[:sub])
    t_sub = thickness(app, gsub, p, n, threads=args.threads)
    print(f"plain references timed on: {sub} of {s} samples (time scaled by {s / sub:.2f})")
    for name, fn in (("plain broadcast, literal formula", plain_broadcast),
                     ("plain broadcast, simplified formula", plain_simplified),
                     ("dense deposition_rate (no culling)", dense_rate)):
        t0 = time.perf_counter()
        t_plain = fn(app, gsub, p, n)
        t_pl = (time.perf_counter() - t0) * s / sub
        err = float(np.max(np.abs(t_sub - t_plain)) / np.max(t_plain))
        print(f"{name} time: {t_pl * 1e3:.1f} ms")
        print(f"{name} throughput: {s * npts / t_pl / 1e6:.0f} M pairs/s")
        print(f"speed-up fast / {name}: {t_pl / t_best:.1f} x")
        print(f"max |fast - {name}| / max thickness: {err:.2e}")
    print(f"max thickness: {np.max(t_fast) * 1e6:.2f} um")


if __name__ == "__main__":
    main()
