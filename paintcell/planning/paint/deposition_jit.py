"""The compiled film kernel: `paintcell.planning.paint.deposition.thickness` in numba (CPU) or CUDA
(GPU).

Same formula, same culling and the same pairs as the numpy kernel of
`paintcell.planning.paint.deposition`
(see its module doc): points in Z-order blocks of `BLOCK_POINTS`, gun samples in consecutive
chunks of `CHUNK_SAMPLES`; a (chunk, block) pair is evaluated, every sample of the chunk against
every point of the block, when the block's bounding sphere meets the spray cone of any sample of
the chunk. Per evaluated pair

    thickness += dwell · f(h·dx/dz, h·dy/dz) · max(−n·d, 0) · clip(h/dz, 0, 1e12)³ / h,

exponents clamped at −700 as in the numpy kernel. The CPU inner loop has no branches (a
vectorizing 2^y of < 1e-14 relative error, the exponents scaled by log2 e once per call), so
the result agrees with the numpy kernel to round-off (tests: 1e-12 relative per point on a flat
plate, 1e-9 of the peak on curved parts); the sum over samples runs in sample order for every
point, so it does not depend on the number of threads.

CPU: `numba.njit(parallel=True)`, one block of points a task (threads from `numba`'s pool:
`NUMBA_NUM_THREADS` or the `threads` argument). GPU: a `numba.cuda` kernel, one point a thread,
chosen at run time when `numba.cuda.is_available()` (and `PAINTCELL_GPU` is not `0`).
"""

from __future__ import annotations

import functools
import math
import os
from typing import Any

import numpy as np


def _prefer_512_bit_vectors() -> None:
    """On AVX-512 hosts let LLVM use 512-bit vectors (its x86 tuning prefers 256-bit; the
    branch-free film loop runs ~1.5× faster per core with 512, benchmarks/deposition.py). Only
    when the user has not set NUMBA_CPU_FEATURES and before numba compiles anything."""
    if "NUMBA_CPU_FEATURES" in os.environ:
        return
    try:
        import llvmlite.binding as llvm
        import numba.core.config as cfg

        feats = llvm.get_host_cpu_features().flatten()
        if "+avx512f" in feats.split(",") and getattr(cfg, "CPU_FEATURES", None) is None:
            setattr(cfg, "CPU_FEATURES", feats + ",-prefer-256-bit")  # noqa: B010 (untyped)
    except Exception:  # any trouble: numba's defaults
        return


try:  # numba is a dependency; the numpy kernel stays as the reference if it cannot load
    _prefer_512_bit_vectors()
    import numba
    from numba import njit, prange
    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only without numba
    HAVE_NUMBA = False

#: exponents are clamped here, as in the numpy kernel (e^-700 ≈ 1e-304: zero for any film).
EXP_FLOOR = 700.0
#: h/dz is clipped to this (as in the numpy kernel).
#: rings the CPU kernel evaluates inline (the Applicator model has two).
MAX_RINGS = 2
INV_MAX = 1e12


def params(app: Any) -> np.ndarray:
    """Packed applicator parameters (float64): h, A0, 1/(2σx²), 1/(2σy²), then per ring A, μ,
    1/(σ√2) (rings with A ≤ 0 dropped)."""
    rings = [(float(a), float(m), 1.0 / (float(s) * math.sqrt(2.0)))
             for a, m, s in zip(app.ring_amplitudes_m_s, app.ring_radii_m, app.ring_sigmas_m,
                                strict=True) if a > 0]
    head = [app.standoff_m, app.a0_m_s, 0.5 / app.sigma_x_m**2, 0.5 / app.sigma_y_m**2]
    return np.array(head + [v for r in rings for v in r], float)


if HAVE_NUMBA:
    #: log2(e): the kernel's exponents are scaled by it once per call, so that e^x = 2^(x·log2 e)
    #: is computed as 2^y with no range-reduction multiply per pair.
    LOG2E = 1.4426950408889634
    #: 2^y is clamped at y = −EXP_FLOOR·log2(e), i.e. e^x at x = −EXP_FLOOR (as numpy's kernel).
    _Y_FLOOR = -EXP_FLOOR * LOG2E
    #: 1.5·2^52: y + _ROUND − _ROUND rounds y to the nearest integer k, and the low bits of
    #: y + _ROUND hold k (no float-to-int conversion).
    _ROUND = 6755399441055744.0

    @njit(cache=True, inline="always", fastmath={"contract"})
    def _exp2_neg(y: float) -> float:
        """2^y for y ≤ 0, branch-free (so loops of it vectorize): y clamped at `_Y_FLOOR` (e^−700,
        as numpy's kernel clamps), 2^y = 2^k · 2^f with k = round(y) and f = y − k ∈ [−½, ½]
        (both exact), 2^f by the degree-10 Chebyshev interpolant of 2^f on [−½, ½] (relative
        error 4.4e-16, below the degree-11 Taylor polynomial of e^r it replaces: 6.3e-15)
        evaluated by Estrin's scheme (4 dependent steps instead of 10: the three exponentials of
        a pair no longer wait on long multiply-add chains), 2^k built in the exponent bits.
        Relative error below 1e-14 (tests/test_deposition_jit.py); 1.12× the kernel's speed of
        the e^r Taylor/Horner form (benchmarks/film_kernel_profile.py)."""
        y = max(y, _Y_FLOOR)
        t = y + _ROUND
        k = t - _ROUND
        f = y - k
        f2 = f * f
        f4 = f2 * f2
        q0 = 1.0 + 0.69314718055995 * f
        q1 = 0.24022650695910097 + 0.05550410866444772 * f
        q2 = 0.009618129107606888 + 0.0013333558230164974 * f
        q3 = 0.0001540353044173605 + 1.5252657260200837e-05 * f
        q4 = 1.321544258792169e-06 + 1.0208690299958306e-07 * f
        s0 = q0 + q1 * f2
        s1 = q2 + q3 * f2
        s2 = q4 + 7.072585949269223e-09 * f2
        p = (s0 + s1 * f4) + s2 * (f4 * f4)
        bits = np.int64((np.float64(t).view(np.int64) + 1023) << 52)
        return p * bits.view(np.float64)

    @njit(cache=True, inline="always")
    def _cone_hit(cx: float, cy: float, cz: float, rho: float, g: np.ndarray, a: np.ndarray,
                  s: int, tan_cone: float) -> bool:
        d0, d1, d2 = cx - g[s, 0], cy - g[s, 1], cz - g[s, 2]
        dz = d0 * a[s, 0] + d1 * a[s, 1] + d2 * a[s, 2]
        lat = math.sqrt(max(d0 * d0 + d1 * d1 + d2 * d2 - dz * dz, 0.0))
        far = dz + rho
        return far > 0.0 and lat - rho <= tan_cone * far

    @njit(cache=True, parallel=True, fastmath={"contract"})
    def _film_cpu(pts: np.ndarray, nrm: np.ndarray, starts: np.ndarray, centers: np.ndarray,
                  radii: np.ndarray, g: np.ndarray, xh: np.ndarray, yh: np.ndarray,
                  a: np.ndarray, coef: np.ndarray, chunk: int, tan_cone: float,
                  prm: np.ndarray, out: np.ndarray, evaluated: np.ndarray) -> None:
        """out[i] = Σ_s coef_s · h·rate_s(p_i) over the evaluated (chunk, block) pairs.

        pts, nrm: (3, N) sorted into blocks (rows x, y, z); starts: (nb + 1,) block offsets;
        centers (nb, 3), radii (nb,): bounding spheres; g, xh, yh, a: (S, 3); coef: (S,)
        dwell/h [s/m]; prm: `params`. evaluated: (nb,) pairs evaluated per block (output).
        The inner loop (the points of a block for one sample) has no branches: points behind
        the gun or facing away get weight 0 exactly as in the numpy kernel.
        """
        nb = len(starts) - 1
        s_all = len(g)
        # exponents in base 2 (`_exp2_neg`): the Gaussian's and the rings' scales times log2(e)
        h, amp0, cx2, cy2 = prm[0], prm[1], prm[2] * LOG2E, prm[3] * LOG2E
        rs = math.sqrt(LOG2E)
        nr = (len(prm) - 4) // 3
        # up to two rings inline (the Applicator's model); a third would be dropped: guarded
        # by the caller
        ra1 = prm[4] if nr > 0 else 0.0
        rm1 = prm[5] if nr > 0 else 0.0
        rc1 = prm[6] * rs if nr > 0 else 1.0
        ra2 = prm[7] if nr > 1 else 0.0
        rm2 = prm[8] if nr > 1 else 0.0
        rc2 = prm[9] * rs if nr > 1 else 1.0
        for b in prange(nb):
            i0, i1 = starts[b], starts[b + 1]
            cx, cy, cz, rho = centers[b, 0], centers[b, 1], centers[b, 2], radii[b]
            count = 0
            px, py, pz = pts[0, i0:i1], pts[1, i0:i1], pts[2, i0:i1]
            qx, qy, qz = nrm[0, i0:i1], nrm[1, i0:i1], nrm[2, i0:i1]
            m = i1 - i0
            acc = np.zeros(m)
            for c0 in range(0, s_all, chunk):
                c1 = min(c0 + chunk, s_all)
                hit = False
                for s in range(c0, c1):
                    if _cone_hit(cx, cy, cz, rho, g, a, s, tan_cone):
                        hit = True
                        break
                if not hit:
                    continue
                count += (c1 - c0) * m
                for s in range(c0, c1):
                    gs0, gs1, gs2 = g[s, 0], g[s, 1], g[s, 2]
                    x0, x1, x2 = xh[s, 0], xh[s, 1], xh[s, 2]
                    y0, y1, y2 = yh[s, 0], yh[s, 1], yh[s, 2]
                    a0, a1, a2 = a[s, 0], a[s, 1], a[s, 2]
                    w = coef[s]
                    for i in range(m):
                        d0, d1, d2 = px[i] - gs0, py[i] - gs1, pz[i] - gs2
                        dz = d0 * a0 + d1 * a1 + d2 * a2
                        nd = max(-(qx[i] * d0 + qy[i] * d1 + qz[i] * d2), 0.0)
                        inv = min(max(h / dz, 0.0), INV_MAX)
                        u = (d0 * x0 + d1 * x1 + d2 * x2) * inv
                        v = (d0 * y0 + d1 * y1 + d2 * y2) * inv
                        u2 = u * u
                        v2 = v * v
                        r = math.sqrt(u2 + v2)
                        t1 = (r - rm1) * rc1
                        t2 = (r - rm2) * rc2
                        f = (amp0 * _exp2_neg(-(u2 * cx2 + v2 * cy2))
                             + ra1 * _exp2_neg(-t1 * t1) + ra2 * _exp2_neg(-t2 * t2))
                        acc[i] += w * (f * (nd * inv * inv * inv))
            out[i0:i1] = acc
            evaluated[b] = count


def film_cpu(blocks_pts: np.ndarray, blocks_nrm: np.ndarray, starts: np.ndarray,
             centers: np.ndarray, radii: np.ndarray, g: np.ndarray, xh: np.ndarray,
             yh: np.ndarray, a: np.ndarray, coef: np.ndarray, chunk: int, tan_cone: float,
             prm: np.ndarray, threads: int | None = None) -> tuple[np.ndarray, int]:
    """(film (N,) [m] in block order, pairs evaluated) on the CPU (numba); at most
    `MAX_RINGS` rings in `prm`."""
    if (len(prm) - 4) // 3 > MAX_RINGS:
        raise ValueError(f"the compiled kernel takes at most {MAX_RINGS} rings")
    out = np.zeros(len(blocks_pts))
    evaluated = np.zeros(len(starts) - 1, np.int64)
    old = numba.get_num_threads()
    if threads is not None:
        most = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
        numba.set_num_threads(max(1, min(int(threads), most)))
    try:
        # dynamic scheduling: blocks under the program cost far more than blocks outside it
        with numba.parallel_chunksize(1):
            _film_cpu(np.ascontiguousarray(blocks_pts.T), np.ascontiguousarray(blocks_nrm.T),
                      starts, centers, radii, g, xh, yh, a, coef,
                      int(chunk), float(tan_cone), prm, out, evaluated)
    finally:
        numba.set_num_threads(old)
    return out, int(evaluated.sum())


# --- GPU -----------------------------------------------------------------------------------------
_GPU_KERNEL: Any = None


def gpu_available() -> bool:
    """True when numba.cuda sees a GPU and `PAINTCELL_GPU` is not "0"."""
    if not HAVE_NUMBA or os.environ.get("PAINTCELL_GPU", "1") == "0":
        return False
    return _cuda_present()


@functools.lru_cache(maxsize=1)
def _cuda_present() -> bool:
    """Asked once a process (loading the driver costs time on a machine without one)."""
    try:
        from numba import cuda
        return bool(cuda.is_available())
    except Exception:  # no driver, no toolkit: the CPU kernel it is
        return False


def _gpu_kernel() -> Any:
    global _GPU_KERNEL
    if _GPU_KERNEL is None:
        from numba import cuda

        @cuda.jit
        def kern(pts: Any, nrm: Any, block_of: Any, cand: Any, g: Any, xh: Any, yh: Any,
                 a: Any, coef: Any, chunk: int, prm: Any, out: Any) -> None:
            i: int = cuda.grid(1)  # type: ignore[call-arg]
            if i >= pts.shape[0]:
                return
            b = block_of[i]
            acc = 0.0
            nr = (prm.shape[0] - 4) // 3
            for c in range(cand.shape[0]):
                if not cand[c, b]:
                    continue
                c1 = min((c + 1) * chunk, g.shape[0])
                for s in range(c * chunk, c1):
                    d0 = pts[i, 0] - g[s, 0]
                    d1 = pts[i, 1] - g[s, 1]
                    d2 = pts[i, 2] - g[s, 2]
                    dz = d0 * a[s, 0] + d1 * a[s, 1] + d2 * a[s, 2]
                    nd = -(nrm[i, 0] * d0 + nrm[i, 1] * d1 + nrm[i, 2] * d2)
                    if dz <= 0.0 or nd <= 0.0:
                        continue
                    inv = min(prm[0] / dz, INV_MAX)
                    u = (d0 * xh[s, 0] + d1 * xh[s, 1] + d2 * xh[s, 2]) * inv
                    v = (d0 * yh[s, 0] + d1 * yh[s, 1] + d2 * yh[s, 2]) * inv
                    u2 = u * u
                    v2 = v * v
                    f = prm[1] * math.exp(max(-(u2 * prm[2] + v2 * prm[3]), -EXP_FLOOR))
                    r = math.sqrt(u2 + v2)
                    for k in range(nr):
                        t = (r - prm[5 + 3 * k]) * prm[6 + 3 * k]
                        f += prm[4 + 3 * k] * math.exp(max(-t * t, -EXP_FLOOR))
                    acc += coef[s] * f * nd * inv * inv * inv
            out[i] = acc

        _GPU_KERNEL = kern
    return _GPU_KERNEL


def film_gpu(blocks_pts: np.ndarray, blocks_nrm: np.ndarray, starts: np.ndarray,
             cand: np.ndarray, g: np.ndarray, xh: np.ndarray, yh: np.ndarray, a: np.ndarray,
             coef: np.ndarray, chunk: int, prm: np.ndarray) -> np.ndarray:
    """The same sums on a CUDA GPU; cand: (n_chunks, nb) bool, the evaluated (chunk, block)
    pairs (from `candidates_cpu`). Not run on the 2-core development machine (no GPU there)."""
    from numba import cuda

    block_of = np.repeat(np.arange(len(starts) - 1), np.diff(starts)).astype(np.int64)
    out = cuda.device_array(len(blocks_pts))
    kern = _gpu_kernel()
    tpb = 128
    kern[(len(blocks_pts) + tpb - 1) // tpb, tpb](
        cuda.to_device(blocks_pts), cuda.to_device(blocks_nrm), cuda.to_device(block_of),
        cuda.to_device(cand), cuda.to_device(g), cuda.to_device(xh), cuda.to_device(yh),
        cuda.to_device(a), cuda.to_device(coef), int(chunk), cuda.to_device(prm), out)
    return np.asarray(out.copy_to_host())


if HAVE_NUMBA:
    @njit(cache=True, parallel=True)
    def _cand(centers: np.ndarray, radii: np.ndarray, g: np.ndarray, a: np.ndarray, chunk: int,
              tan_cone: float, cand: np.ndarray) -> None:
        nb = len(radii)
        s_all = len(g)
        for b in prange(nb):
            cx, cy, cz, rho = centers[b, 0], centers[b, 1], centers[b, 2], radii[b]
            for c in range(cand.shape[0]):
                for s in range(c * chunk, min((c + 1) * chunk, s_all)):
                    d0, d1, d2 = cx - g[s, 0], cy - g[s, 1], cz - g[s, 2]
                    dz = d0 * a[s, 0] + d1 * a[s, 1] + d2 * a[s, 2]
                    lat = math.sqrt(max(d0 * d0 + d1 * d1 + d2 * d2 - dz * dz, 0.0))
                    far = dz + rho
                    if far > 0.0 and lat - rho <= tan_cone * far:
                        cand[c, b] = True
                        break


def candidates_cpu(centers: np.ndarray, radii: np.ndarray, g: np.ndarray, a: np.ndarray,
                   chunk: int, tan_cone: float) -> np.ndarray:
    """(n_chunks, nb) bool: the (chunk, block) pairs the kernel evaluates (same test as the
    numpy kernel's `_candidate_blocks`)."""
    cand = np.zeros((-(-len(g) // chunk), len(radii)), np.bool_)
    _cand(centers, radii, g, a, int(chunk), float(tan_cone), cand)
    return cand
