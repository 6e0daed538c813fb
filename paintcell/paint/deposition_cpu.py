"""The numba CPU film kernel: the formula of `paintcell.paint.deposition_jit`, laid out
for the vector units.

Inputs are structures of arrays: the points, Z-ordered into blocks of `BLOCK_POINTS` (padded with
zero-normal points), as 7 contiguous rows (x, y, z, nx, ny, nz, n·p); the gun samples as one
16-float row each (h·x̂, −h·g·x̂, h·ŷ, −h·g·ŷ, â, −g·â, g, dwell·h²). Per evaluated pair

    X, Y, dz = h·(p−g)·x̂, h·(p−g)·ŷ, (p−g)·â        (affine in p: three fused multiply-adds)
    1/dz (0 behind the gun, clipped as h/dz ≤ 1e12),  u, v = X/dz, Y/dz,  r = √(u² + v²)
    film += dwell·h² · max(n·g − n·p, 0) / dz³ · Σ_j 2^(log2 A_j − q_j(u, v))

the amplitudes folded into the exponents as the numpy kernel folds them (exp(ln A − q), clamped
at e^−700; a zero amplitude gives exactly 0). The inner loop runs over the 64 points of a block
(LLVM vectorizes it, 8 pairs a 512-bit register) for four samples at once, the four written out
statement by statement so that their independent chains (a division, a square root and three
2^y each) overlap instead of waiting on each other (the loop of one sample at a time was
latency-bound: ~11 cycles a pair against a ~5-cycle port bound, llvm-mca); with √(X² + Y²)
started beside the division, 1.35-1.4× the previous kernel's pairs per CPU-second
(benchmarks/deposition.py). The sum per point stays in sample order, so the film does
not depend on the thread count (one block of points a task, `numba.prange`).
"""

from __future__ import annotations

import math
import os

import numpy as np

from paintcell.paint.deposition_kernel import EXP_MIN, INV_MAX


def _prefer_512_bit_vectors() -> None:
    """On AVX-512 hosts let LLVM use 512-bit vectors (its x86 tuning prefers 256-bit; the
    branch-free film loop runs ~1.5× faster per core with 512, benchmarks/deposition.py).

    Process-wide: numba has one code generator a process, so this also applies to every other
    numba function compiled after it (results are the same; only the vector width changes), and
    it has no effect if something was compiled before this module was imported. Left alone when
    the user chose the target (`NUMBA_CPU_NAME`, `NUMBA_CPU_FEATURES`) or switched AVX off
    (`NUMBA_ENABLE_AVX=0`): the features come from numba's own `get_host_cpu_features`, which
    applies that switch."""
    if "NUMBA_CPU_FEATURES" in os.environ or "NUMBA_CPU_NAME" in os.environ:
        return
    try:
        import numba.core.config as cfg
        from numba.core.codegen import get_host_cpu_features

        if not getattr(cfg, "ENABLE_AVX", True) or getattr(cfg, "CPU_FEATURES", None) is not None:
            return
        feats = get_host_cpu_features()
        if "+avx512f" in feats.split(","):
            setattr(cfg, "CPU_FEATURES", feats + ",-prefer-256-bit")  # noqa: B010 (untyped)
    except Exception:  # any trouble: numba's defaults
        return


_prefer_512_bit_vectors()
from numba import njit, prange  # noqa: E402 (after choosing the vector width)

#: points a block (the numpy kernel's `BLOCK_POINTS`; the inner loop's trip count).
BLOCK = 64
#: samples the inner loop takes at once (chunks of `CHUNK_SAMPLES` must be a multiple).
LANES = 4
LOG2E = 1.4426950408889634
#: 2^y is clamped at y = −700·log2(e), i.e. e^x at x = −700 (the numpy kernel's `EXP_MIN`).
Y_FLOOR = EXP_MIN * LOG2E
#: the clamp of a zero-amplitude term: 2^−1023 is built with exponent bits 0, i.e. exactly 0.
Y_ZERO = -1023.0
#: 1.5·2^52 + 1023: y + _ROUND rounds y to the integer k and leaves k + 1023 (the biased
#: exponent of 2^k) in the low bits, with no float-to-int conversion.
_ROUND = 6755399441055744.0 + 1023.0
#: the degree-10 Chebyshev interpolant of 2^f on [−½, ½] (relative error 4.4e-16), highest first.
C10, C9, C8, C7 = (7.072585949269223e-09, 1.0208690299958306e-07, 1.321544258792169e-06,
                   1.5252657260200837e-05)
C6, C5, C4, C3 = (0.0001540353044173605, 0.0013333558230164974, 0.009618129107606888,
                  0.05550410866444772)
C2, C1 = 0.24022650695910097, 0.69314718055995


@njit(cache=True, inline="always")
def _pow2i(t: float) -> float:
    """2^k from t = y + _ROUND (k + 1023 in the low bits of t) shifted into the exponent."""
    return np.int64(np.float64(t).view(np.int64) << 52).view(np.float64)


@njit(cache=True, inline="always", fastmath={"contract"})
def exp2_x4(y0: float, y1: float, y2: float, y3: float,
            lo: float) -> tuple[float, float, float, float]:
    """2^y of four independent values, branch-free, y clamped at `lo` (≤ 0, ≥ −1023; see
    `Y_FLOOR`, `Y_ZERO`): 2^y = 2^k·2^f, k = round(y), f = y − k ∈ [−½, ½] (exact), 2^f by the
    Chebyshev polynomial in Horner's form. The four chains are written side by side so the
    CPU overlaps them. Relative error < 1e-14 (tests/test_deposition_jit.py)."""
    y0, y1, y2, y3 = max(y0, lo), max(y1, lo), max(y2, lo), max(y3, lo)
    t0, t1, t2, t3 = y0 + _ROUND, y1 + _ROUND, y2 + _ROUND, y3 + _ROUND
    f0, f1, f2, f3 = y0 - (t0 - _ROUND), y1 - (t1 - _ROUND), y2 - (t2 - _ROUND), y3 - (t3 - _ROUND)
    p0, p1, p2, p3 = C10 * f0 + C9, C10 * f1 + C9, C10 * f2 + C9, C10 * f3 + C9
    p0, p1, p2, p3 = p0 * f0 + C8, p1 * f1 + C8, p2 * f2 + C8, p3 * f3 + C8
    p0, p1, p2, p3 = p0 * f0 + C7, p1 * f1 + C7, p2 * f2 + C7, p3 * f3 + C7
    p0, p1, p2, p3 = p0 * f0 + C6, p1 * f1 + C6, p2 * f2 + C6, p3 * f3 + C6
    p0, p1, p2, p3 = p0 * f0 + C5, p1 * f1 + C5, p2 * f2 + C5, p3 * f3 + C5
    p0, p1, p2, p3 = p0 * f0 + C4, p1 * f1 + C4, p2 * f2 + C4, p3 * f3 + C4
    p0, p1, p2, p3 = p0 * f0 + C3, p1 * f1 + C3, p2 * f2 + C3, p3 * f3 + C3
    p0, p1, p2, p3 = p0 * f0 + C2, p1 * f1 + C2, p2 * f2 + C2, p3 * f3 + C2
    p0, p1, p2, p3 = p0 * f0 + C1, p1 * f1 + C1, p2 * f2 + C1, p3 * f3 + C1
    p0, p1, p2, p3 = p0 * f0 + 1.0, p1 * f1 + 1.0, p2 * f2 + 1.0, p3 * f3 + 1.0
    return p0 * _pow2i(t0), p1 * _pow2i(t1), p2 * _pow2i(t2), p3 * _pow2i(t3)


@njit(cache=True, inline="always")
def _row(rows: np.ndarray, s: int) -> tuple[float, ...]:
    """Sample s's 16 floats as scalars (loaded once, outside the loop over points)."""
    return (rows[s, 0], rows[s, 1], rows[s, 2], rows[s, 3], rows[s, 4], rows[s, 5], rows[s, 6],
            rows[s, 7], rows[s, 8], rows[s, 9], rows[s, 10], rows[s, 11], rows[s, 12],
            rows[s, 13], rows[s, 14], rows[s, 15])


@njit(cache=True, inline="always", fastmath={"contract"})
def _project(point: tuple[float, ...], row: tuple[float, ...]) -> tuple[float, float, float, float]:
    """(h·dx, h·dy, dz, dwell·h²·max(−n·d, 0)) of one pair; point: x, y, z, nx, ny, nz, n·p;
    row: the sample's 16 floats."""
    px, py, pz, qx, qy, qz, qp = point
    x0, x1, x2, xo, y0, y1, y2, yo, a0, a1, a2, ao, g0, g1, g2, w = row
    return (xo + px * x0 + py * x1 + pz * x2, yo + px * y0 + py * y1 + pz * y2,
            ao + px * a0 + py * a1 + pz * a2, w * max(qx * g0 + qy * g1 + qz * g2 - qp, 0.0))


@njit(cache=True, inline="always")
def _inv(dz: float, dz_min: float) -> float:
    """1/dz clipped at 1/dz_min, 0 for dz ≤ 0 (behind the gun)."""
    iz = 1.0 / max(dz, dz_min)
    return iz if dz > 0.0 else 0.0


@njit(cache=True, parallel=True, fastmath={"contract"})
def _film(pts: np.ndarray, counts: np.ndarray, centers: np.ndarray, radii: np.ndarray,
          rows: np.ndarray, n_samples: int, chunk: int, tan_cone: float, k: np.ndarray,
          out: np.ndarray, evaluated: np.ndarray) -> None:
    """out[block points] = Σ_s dwell_s·rate_s(p) over the evaluated (chunk, block) pairs.

    pts (7, nb·BLOCK); counts (nb,) real points a block; centers (nb, 3), radii (nb,) [m];
    rows (S padded to LANES, 16) with zero dwell on the padding; k: `constants`.
    evaluated: (nb,) pairs evaluated per block (output; padding samples not counted).
    """
    cx2, cy2, l0, rc1, rm1, l1, rc2, rm2, l2 = k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7], k[8]
    lo0, lo1, lo2, dz_min = k[9], k[10], k[11], k[12]
    for b in prange(len(counts)):
        i0 = b * BLOCK
        bx, by, bz, rho = centers[b, 0], centers[b, 1], centers[b, 2], radii[b]
        px, py, pz = pts[0, i0:i0 + BLOCK], pts[1, i0:i0 + BLOCK], pts[2, i0:i0 + BLOCK]
        qx, qy, qz = pts[3, i0:i0 + BLOCK], pts[4, i0:i0 + BLOCK], pts[5, i0:i0 + BLOCK]
        qp = pts[6, i0:i0 + BLOCK]
        acc = np.zeros(BLOCK)
        count = 0
        for c0 in range(0, n_samples, chunk):
            c1 = min(c0 + chunk, n_samples)
            hit = False
            for s in range(c0, c1):  # the numpy kernel's cone test of the block's sphere
                d0, d1, d2 = bx - rows[s, 12], by - rows[s, 13], bz - rows[s, 14]
                dz = d0 * rows[s, 8] + d1 * rows[s, 9] + d2 * rows[s, 10]
                lat = math.sqrt(max(d0 * d0 + d1 * d1 + d2 * d2 - dz * dz, 0.0))
                far = dz + rho
                if far > 0.0 and lat - rho <= tan_cone * far:
                    hit = True
                    break
            if not hit:
                continue
            count += (c1 - c0) * counts[b]
            for s in range(c0, c1, LANES):  # padding rows (dwell 0) complete the last group
                r0 = _row(rows, s)
                r1 = _row(rows, s + 1)
                r2 = _row(rows, s + 2)
                r3 = _row(rows, s + 3)
                for i in range(BLOCK):  # four samples side by side (module doc)
                    pi = (px[i], py[i], pz[i], qx[i], qy[i], qz[i], qp[i])
                    x0, y0, z0, w0 = _project(pi, r0)
                    x1, y1, z1, w1 = _project(pi, r1)
                    x2, y2, z2, w2 = _project(pi, r2)
                    x3, y3, z3, w3 = _project(pi, r3)
                    z0, z1, z2, z3 = (_inv(z0, dz_min), _inv(z1, dz_min), _inv(z2, dz_min),
                                      _inv(z3, dz_min))                      # 1/dz
                    x0, x1, x2, x3 = x0 * x0, x1 * x1, x2 * x2, x3 * x3      # X²
                    y0, y1, y2, y3 = y0 * y0, y1 * y1, y2 * y2, y3 * y3      # Y²
                    # √(X² + Y²) runs beside the division; r = √(X² + Y²)/dz = √(u² + v²)
                    q0, q1, q2, q3 = (math.sqrt(x0 + y0), math.sqrt(x1 + y1),
                                      math.sqrt(x2 + y2), math.sqrt(x3 + y3))
                    x0, x1, x2, x3 = (x0 * cx2 + y0 * cy2, x1 * cx2 + y1 * cy2,
                                      x2 * cx2 + y2 * cy2, x3 * cx2 + y3 * cy2)
                    y0, y1, y2, y3 = z0 * z0, z1 * z1, z2 * z2, z3 * z3      # 1/dz²
                    w0, w1, w2, w3 = (w0 * (y0 * z0), w1 * (y1 * z1), w2 * (y2 * z2),
                                      w3 * (y3 * z3))
                    g0, g1, g2, g3 = exp2_x4(l0 - x0 * y0, l0 - x1 * y1, l0 - x2 * y2,
                                             l0 - x3 * y3, lo0)
                    z0, z1, z2, z3 = q0 * z0, q1 * z1, q2 * z2, q3 * z3      # r
                    x0, x1, x2, x3 = z0 * rc1 - rm1, z1 * rc1 - rm1, z2 * rc1 - rm1, z3 * rc1 - rm1
                    h0, h1, h2, h3 = exp2_x4(l1 - x0 * x0, l1 - x1 * x1, l1 - x2 * x2, l1 - x3 * x3,
                                             lo1)
                    x0, x1, x2, x3 = z0 * rc2 - rm2, z1 * rc2 - rm2, z2 * rc2 - rm2, z3 * rc2 - rm2
                    e0, e1, e2, e3 = exp2_x4(l2 - x0 * x0, l2 - x1 * x1, l2 - x2 * x2, l2 - x3 * x3,
                                             lo2)
                    acc[i] += ((w0 * (g0 + h0 + e0) + w1 * (g1 + h1 + e1))
                               + (w2 * (g2 + h2 + e2) + w3 * (g3 + h3 + e3)))
        out[i0:i0 + BLOCK] = acc
        evaluated[b] = count


@njit(cache=True)
def _morton_codes(p: np.ndarray) -> np.ndarray:
    """The numpy kernel's Z-order codes (`deposition_kernel._morton_order`), bit for bit."""
    lo0, lo1, lo2 = p[:, 0].min(), p[:, 1].min(), p[:, 2].min()
    span = max(p[:, 0].max() - lo0, p[:, 1].max() - lo1, p[:, 2].max() - lo2)
    lo = (lo0, lo1, lo2)
    code = np.zeros(len(p), np.uint64)
    for i in range(len(p)):
        c = np.uint64(0)
        for axis in range(3):
            q = np.uint64(0)
            if span != 0:
                q = np.uint64(min((p[i, axis] - lo[axis]) / span * 1023.0, 1023.0))
            for bit in range(10):
                c |= ((q >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
        code[i] = c
    return code


@njit(cache=True)
def _gather(p: np.ndarray, n: np.ndarray, order: np.ndarray, pts: np.ndarray,
            centers: np.ndarray, radii: np.ndarray) -> None:
    """pts (7, nb·BLOCK) in block order, padding = the last point with a zero normal; block
    bounding spheres as the numpy kernel's `_make_blocks` (bit for bit)."""
    npts = len(order)
    for b in range(len(radii)):
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for j in range(BLOCK):
            i = b * BLOCK + j
            src = order[min(i, npts - 1)]
            real = i < npts
            dot = 0.0
            for k in range(3):
                v = p[src, k]
                pts[k, i] = v
                pts[3 + k, i] = n[src, k] if real else 0.0
                lo[k] = min(lo[k], v)
                hi[k] = max(hi[k], v)
            if real:  # n·p as numpy's einsum sums it
                dot = (n[src, 0] * p[src, 0] + n[src, 1] * p[src, 1]) + n[src, 2] * p[src, 2]
            pts[6, i] = dot
        c = 0.5 * (lo + hi)
        centers[b] = c
        best = 0.0
        for j in range(BLOCK):
            i = b * BLOCK + j
            d0, d1, d2 = pts[0, i] - c[0], pts[1, i] - c[1], pts[2, i] - c[2]
            best = max(best, (d0 * d0 + d1 * d1) + d2 * d2)
        radii[b] = math.sqrt(best)


def blocks(p: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                  np.ndarray, np.ndarray]:
    """(order (N,), pts (7, nb·BLOCK), counts (nb,), centers (nb, 3), radii (nb,)): the numpy
    kernel's blocks (same order, same spheres) as the compiled kernel's structure of arrays."""
    order = np.argsort(_morton_codes(p), kind="stable")
    nb = -(-len(p) // BLOCK)
    pts = np.empty((7, nb * BLOCK))
    centers = np.empty((nb, 3))
    radii = np.empty(nb)
    _gather(p, n, order, pts, centers, radii)
    counts = np.full(nb, BLOCK, np.int64)
    counts[-1] = len(p) - (nb - 1) * BLOCK
    return order, pts, counts, centers, radii


def sample_rows(g: np.ndarray, x_hat: np.ndarray, y_hat: np.ndarray, a: np.ndarray,
                dwell: np.ndarray, h: float) -> np.ndarray:
    """(S padded to a multiple of LANES, 16) per-sample rows (module doc); padding: copies of
    the last sample with zero dwell."""
    s = len(g)
    rows = np.zeros((-(-s // LANES) * LANES, 16))
    rows[:s, 0:3] = h * x_hat
    rows[:s, 3] = -h * np.einsum("ij,ij->i", g, x_hat)
    rows[:s, 4:7] = h * y_hat
    rows[:s, 7] = -h * np.einsum("ij,ij->i", g, y_hat)
    rows[:s, 8:11] = a
    rows[:s, 11] = -np.einsum("ij,ij->i", g, a)
    rows[:s, 12:15] = g
    rows[:s, 15] = dwell * h * h
    rows[s:, :15] = rows[s - 1, :15]
    return rows


def constants(prm: np.ndarray) -> np.ndarray:
    """The kernel's 13 constants from `deposition_jit.params` (≤ 2 rings): log2 e/(2σx²),
    log2 e/(2σy²), log2 A0, then per ring c·√log2 e, μ·c·√log2 e, log2 A; the three clamps;
    the smallest dz [m] (h/dz ≤ 1e12). A missing or zero term gets log2 A = −∞ and clamp
    `Y_ZERO`: exactly 0."""
    h, a0 = float(prm[0]), float(prm[1])
    rs = math.sqrt(LOG2E)
    terms = [(0.0, 0.0, -math.inf)] * 2
    for j in range((len(prm) - 4) // 3):
        amp, mu, c = prm[4 + 3 * j: 7 + 3 * j]
        terms[j] = (c * rs, mu * c * rs, math.log2(amp))
    l0 = math.log2(a0) if a0 > 0 else -math.inf
    lows = [Y_FLOOR if v > -math.inf else Y_ZERO for v in (l0, terms[0][2], terms[1][2])]
    return np.array([prm[2] * LOG2E, prm[3] * LOG2E, l0, *terms[0], *terms[1], *lows,
                     h / INV_MAX], float)


def film(pts: np.ndarray, counts: np.ndarray, centers: np.ndarray, radii: np.ndarray,
         rows: np.ndarray, n_samples: int, chunk: int, tan_cone: float,
         k: np.ndarray) -> tuple[np.ndarray, int]:
    """(film (nb·BLOCK,) [m] in block order, pairs evaluated); threads: numba's current count."""
    if chunk % LANES:
        raise ValueError(f"chunk {chunk} is not a multiple of {LANES}")
    out = np.zeros(pts.shape[1])
    evaluated = np.zeros(len(counts), np.int64)
    _film(pts, counts, centers, radii, rows, int(n_samples), int(chunk), float(tan_cone), k,
          out, evaluated)
    return out, int(evaluated.sum())
