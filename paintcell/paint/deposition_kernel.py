"""The numpy film kernel of `paintcell.paint.deposition`: surface points in Z-order blocks,
blocks culled
against the spray cones of a chunk of gun samples, and the rate arithmetic done in place on
batched small matrix products (positions [m], rates [m/s], h·rate [m²/s], dwell [s]).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from paintcell.paint.applicator import Applicator

#: points per spatial block: the culling unit (≈ 4 × 4 cm at 5 mm resolution). Block, chunk and
#: call sizes measured on the door benchmark (benchmarks/deposition.py): 64 × 16 × 2^14 beat
#: 128 × 8 × 2^18 by ~1.3× (the temporaries stay in L2).
BLOCK_POINTS = 64
#: gun samples evaluated together against the union of their candidate blocks (stays in cache).
CHUNK_SAMPLES = 16
#: at most this many (sample, point) pairs in one kernel call (128 kB per temporary).
MAX_PAIRS_PER_CALL = 1 << 14
#: exponents are clamped here: exp below -708 underflows and numpy's exp is then 10-20x slower
#: (measured); e^-700 ≈ 1e-304 is zero for any film. The compiled kernels
#: (`deposition_jit`, `deposition_cpu`) import this and `INV_MAX`, so every backend clamps alike.
EXP_MIN = -700.0
#: h/dz is clipped to this (dz ≈ +0: the pattern coordinates are then huge and f underflows).
INV_MAX = 1e12


def _morton_order(p: np.ndarray) -> np.ndarray:
    """Permutation that sorts points along a 3-D Z-order curve (10 bits an axis)."""
    lo = p.min(axis=0)
    span = float(np.max(p.max(axis=0) - lo))
    q = np.zeros(p.shape, np.uint64) if span == 0 else \
        np.minimum((p - lo) / span * 1023.0, 1023.0).astype(np.uint64)
    code = np.zeros(len(p), np.uint64)
    for bit in range(10):
        for axis in range(3):
            code |= ((q[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
    return np.argsort(code, kind="stable")


@dataclass(frozen=True)
class Blocks:
    """Surface points sorted along a Morton curve into blocks of equal size, each with its
    bounding sphere, so whole blocks outside a spray cone are skipped."""

    order: np.ndarray       # (N,) original index of each sorted point
    feats: np.ndarray       # (nb, 8, B): p (3), 1, n (3), n·p ; pads have n = 0, n·p = 0
    centers: np.ndarray     # (nb, 3) block bounding-sphere centres [m]
    radii: np.ndarray       # (nb,) bounding-sphere radii [m]


def make_blocks(p: np.ndarray, n: np.ndarray, block: int) -> Blocks:
    """Points p (N, 3) with unit normals n (N, 3) as `Blocks` of `block` points each (the last
    block padded with zero-normal points, which receive no film)."""
    order = _morton_order(p)
    npts = len(p)
    nb = -(-npts // block)
    pad = nb * block - npts
    idx = np.concatenate([order, np.full(pad, order[-1])])
    ps = p[idx]
    ns = n[idx].copy()
    if pad:
        ns[npts:] = 0.0
    pb = ps.reshape(nb, block, 3)
    nbk = ns.reshape(nb, block, 3)
    feats_t = np.empty((nb, 8, block))
    feats_t[:, 0:3, :] = pb.transpose(0, 2, 1)
    feats_t[:, 3, :] = 1.0
    feats_t[:, 4:7, :] = nbk.transpose(0, 2, 1)
    feats_t[:, 7, :] = np.einsum("bij,bij->bi", nbk, pb)
    lo, hi = pb.min(axis=1), pb.max(axis=1)
    centers = 0.5 * (lo + hi)
    radii = np.sqrt(np.max(np.sum((pb - centers[:, None, :]) ** 2, axis=2), axis=1))
    return Blocks(order, feats_t, centers, radii)


def candidate_blocks(blocks: Blocks, g: np.ndarray, a: np.ndarray, tan_cone: float) -> np.ndarray:
    """Blocks whose bounding sphere may meet the spray cone of any of the K samples (conservative).

    A point p is reached only if dz = (p−g)·a > 0 and its lateral distance ≤ tan_cone · dz. For
    any p in a sphere (c, ρ): lateral(p) ≥ lateral(c) − ρ and dz(p) ≤ dz(c) + ρ.
    """
    c, rho = blocks.centers, blocks.radii
    d = c[None, :, :] - g[:, None, :]                           # (K, nb, 3)
    dz = np.einsum("knj,kj->kn", d, a)
    lat = np.sqrt(np.maximum(np.einsum("knj,knj->kn", d, d) - dz * dz, 0.0))
    far = dz + rho
    ok = (far > 0) & (lat - rho <= tan_cone * far)
    return np.flatnonzero(ok.any(axis=0))


def projection_rows(g: np.ndarray, x_hat: np.ndarray, y_hat: np.ndarray,
                    a: np.ndarray) -> np.ndarray:
    """(4, K, 8) rows that map point features (p, 1, n, n·p) to dx, dy, dz and −n·d of K samples.
    """
    w = np.zeros((4, len(g), 8))              # p·e − g·e for e = x̂, ŷ, â; then −n·d
    for row, e in enumerate((x_hat, y_hat, a)):
        w[row, :, 0:3] = e
        w[row, :, 3] = -np.einsum("ij,ij->i", g, e)
    w[3, :, 4:7] = g                          # −n·d = n·g − n·p
    w[3, :, 7] = -1.0
    return w


def film_kernel(app: Applicator, w_mat: np.ndarray, coef: np.ndarray, feats: np.ndarray
                ) -> np.ndarray:
    """Σ_k coef_k · (h · rate_k) for K samples and a batch of point blocks: (nb, B).

    w_mat: (4, K, 8) from `projection_rows`; coef: (K,) dwell / h [s/m]; feats: (nb, 8, B).
    """
    return np.matmul(coef, sample_rates(app, w_mat, feats))


def sample_rates(app: Applicator, w_mat: np.ndarray, feats: np.ndarray) -> np.ndarray:
    """h · rate [m²/s] of K samples at points with features feats (..., 8, B): (..., K, B).

    Four (batched) (K, 8) @ (8, B) products into contiguous arrays (small GEMMs keep BLAS
    single-threaded, so it does not fight the worker threads; strided views would cost ~5× more
    per element op), then everything in place.
    """
    h = app.standoff_m
    dx, dy, inv, nd = (np.matmul(w_mat[i], feats) for i in range(4))   # (..., K, B) each
    shape = dx.shape
    # weight (−n·d)·(h/dz)³ ≥ 0: zero for back-facing points (n·d ≥ 0); points behind the gun
    # (dz ≤ 0) get h/dz clipped to 0, and dz = +0 gives a huge h/dz where f underflows to 0.
    np.maximum(nd, 0.0, out=nd)
    with np.errstate(divide="ignore"):
        np.divide(h, inv, out=inv)
    np.clip(inv, 0.0, INV_MAX, out=inv)                         # h/dz
    u2 = np.multiply(dx, inv, out=dx)
    np.square(u2, out=u2)
    v2 = np.multiply(dy, inv, out=dy)
    np.square(v2, out=v2)
    t1 = np.empty(shape)
    t2 = np.empty(shape)
    # central Gaussian: A0·exp(−u²/2σx² − v²/2σy²) = exp(ln A0 − …)
    if app.a0_m_s > 0:
        np.multiply(u2, -0.5 / app.sigma_x_m**2, out=t1)
        np.multiply(v2, -0.5 / app.sigma_y_m**2, out=t2)
        t1 += t2
        t1 += math.log(app.a0_m_s)
        np.maximum(t1, EXP_MIN, out=t1)
        np.exp(t1, out=t1)
    else:
        t1.fill(0.0)
    r = np.add(u2, v2, out=u2)
    np.sqrt(r, out=r)
    for amp, mu, sg in zip(app.ring_amplitudes_m_s, app.ring_radii_m, app.ring_sigmas_m,
                           strict=True):
        if amp <= 0:
            continue
        # A·exp(−(r−μ)²/2σ²) = exp(ln A − (r·c − μ·c)²), c = 1/(σ√2)
        c = 1.0 / (sg * math.sqrt(2.0))
        np.multiply(r, c, out=t2)
        t2 -= mu * c
        np.square(t2, out=t2)
        np.subtract(math.log(amp), t2, out=t2)
        np.maximum(t2, EXP_MIN, out=t2)
        np.exp(t2, out=t2)
        t1 += t2
    # rate·h = f · (−n·d) · (h/dz)³ ; coef carries dwell/h
    np.multiply(inv, inv, out=t2)
    t2 *= inv
    t2 *= nd
    t1 *= t2
    return t1


def sample_chunks(s: int, k: int) -> Iterator[slice]:
    """Slices of at most `k` of `s` gun samples, in order."""
    for i in range(0, s, k):
        yield slice(i, min(i + k, s))

