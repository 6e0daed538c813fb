"""The compiled film kernel: `paintcell.paint.deposition.thickness` in numba (CPU) or CUDA
(GPU).

Same formula, same culling and the same pairs as the numpy kernel of
`paintcell.paint.deposition`
(see its module doc): points in Z-order blocks of `BLOCK_POINTS`, gun samples in consecutive
chunks of `CHUNK_SAMPLES`; a (chunk, block) pair is evaluated, every sample of the chunk against
every point of the block, when the block's bounding sphere meets the spray cone of any sample of
the chunk. Per evaluated pair

    thickness += dwell · f(h·dx/dz, h·dy/dz) · max(−n·d, 0) · clip(h/dz, 0, 1e12)³ / h,

exponents clamped at −700 as in the numpy kernel. The CPU kernel
(`paintcell.paint.deposition_cpu`: structure-of-arrays inputs, an inner loop over the
points of a block with no branches, four samples at once, a vectorizing 2^y of < 1e-14 relative
error) agrees with the numpy kernel to round-off (tests: 1e-12 relative per point on a flat
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
import threading
from typing import Any

import numpy as np

from paintcell.paint.deposition_kernel import EXP_MIN, INV_MAX

try:  # numba is a dependency; the numpy kernel stays as the reference if it cannot load
    import numba
    from numba import njit, prange

    # sets the vector width (before anything compiles)
    from paintcell.paint import deposition_cpu as cpu
    HAVE_NUMBA = True
    if "NUMBA_THREADING_LAYER_PRIORITY" not in os.environ:
        # OpenMP first: thread-safe, and it keeps numba from trying an old libtbb that another
        # package bundles (pymeshlab's: a NumbaWarning on every run); numba's order otherwise
        numba.config.THREADING_LAYER_PRIORITY = ["omp", "tbb", "workqueue"]  # type: ignore[attr-defined]
except ImportError:  # pragma: no cover - exercised only without numba
    HAVE_NUMBA = False

#: exponents are clamped at −EXP_FLOOR, the numpy kernel's `EXP_MIN` (e^-700 ≈ 1e-304: zero
#: for any film); h/dz is clipped to the numpy kernel's `INV_MAX`.
EXP_FLOOR = -EXP_MIN
#: rings the CPU kernel evaluates inline (the Applicator model has two).
MAX_RINGS = 2


def params(app: Any) -> np.ndarray:
    """Packed applicator parameters (float64): h, A0, 1/(2σx²), 1/(2σy²), then per ring A, μ,
    1/(σ√2) (rings with A ≤ 0 dropped)."""
    rings = [(float(a), float(m), 1.0 / (float(s) * math.sqrt(2.0)))
             for a, m, s in zip(app.ring_amplitudes_m_s, app.ring_radii_m, app.ring_sigmas_m,
                                strict=True) if a > 0]
    head = [app.standoff_m, app.a0_m_s, 0.5 / app.sigma_x_m**2, 0.5 / app.sigma_y_m**2]
    return np.array(head + [v for r in rings for v in r], float)


#: one parallel kernel launch at a time in a process. numba's `workqueue` threading layer (its
#: fallback where neither OpenMP nor TBB loads) aborts the process on launches from two threads
#: at once — `paintcell run` computes films on a background thread while MuJoCo steps, and a
#: Dask worker may run two samples in threads. Two launches at once would not be faster anyway:
#: each already uses every thread of numba's pool.
_LAUNCH = threading.Lock()


def film_cpu(p: np.ndarray, n: np.ndarray, g: np.ndarray, xh: np.ndarray, yh: np.ndarray,
             a: np.ndarray, dwell: np.ndarray, chunk: int, tan_cone: float, prm: np.ndarray,
             threads: int | None = None) -> tuple[np.ndarray, int]:
    """(film (N,) [m] at the points in their input order, pairs evaluated) on the CPU (numba,
    `paintcell.paint.deposition_cpu`); p, n: (N, 3) points [m] and unit normals; g, xh,
    yh, a: (S, 3) gun positions [m] and tool axes; dwell: (S,) [s]; prm: `params` (at most
    `MAX_RINGS` rings)."""
    if (len(prm) - 4) // 3 > MAX_RINGS:
        raise ValueError(f"the compiled kernel takes at most {MAX_RINGS} rings")
    if len(p) == 0 or len(g) == 0:
        return np.zeros(len(p)), 0
    with _LAUNCH:
        return _film_cpu_locked(p, n, g, xh, yh, a, dwell, chunk, tan_cone, prm, threads)


def _film_cpu_locked(p: np.ndarray, n: np.ndarray, g: np.ndarray, xh: np.ndarray,
                     yh: np.ndarray, a: np.ndarray, dwell: np.ndarray, chunk: int,
                     tan_cone: float, prm: np.ndarray,
                     threads: int | None) -> tuple[np.ndarray, int]:
    old = numba.get_num_threads()
    if threads is not None:
        most = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
        numba.set_num_threads(max(1, min(int(threads), most)))
    try:
        # C-contiguous float64 (one compiled specialization whatever the caller passes)
        order, pts, counts, centers, radii = cpu.blocks(np.ascontiguousarray(p, float),
                                                        np.ascontiguousarray(n, float))
        rows = cpu.sample_rows(g, xh, yh, a, dwell, float(prm[0]))
        # dynamic scheduling: blocks under the program cost far more than blocks outside it
        with numba.parallel_chunksize(1):
            film, evaluated = cpu.film(pts, counts, centers, radii, rows, len(g), chunk,
                                       tan_cone, cpu.constants(prm))
    finally:
        numba.set_num_threads(old)
    out = np.empty(len(p))
    out[order] = film[:len(p)]
    return out, evaluated


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
    with _LAUNCH:
        _cand(centers, radii, g, a, int(chunk), float(tan_cone), cand)
    return cand
