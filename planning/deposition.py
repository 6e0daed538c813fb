"""Film thickness on a surface from a sampled gun trajectory (paper §2.2, DESIGN.md).

For gun position g, spray axis a, travel direction x̂ (re-orthogonalized against a), ŷ = a × x̂, a
surface point p with unit normal n (toward the painted side) and d = p − g, ω = d/|d|, the ray
through p meets the reference plane at q = g + ω·h/(a·ω), and

    rate(p) = f(q) · |n·ω| · h² / ((a·ω)³ · |d|²)     if a·ω > 0 and n·ω < 0, else 0.

With dx = d·x̂, dy = d·ŷ, dz = d·a this is f(h·dx/dz, h·dy/dz) · (−n·d) · h² / dz³, which is what
the fast kernel evaluates (no square roots beyond the ring radius).
Thickness is Σ_s rate_s · dwell_s.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from planning.applicator import Applicator
from planning.errors import PaintcellError

#: points per spatial block: the culling unit (≈ 4 × 4 cm at 5 mm resolution). Block, chunk and
#: call sizes measured on the door benchmark (benchmarks/deposition.py): 64 × 16 × 2^14 beat
#: 128 × 8 × 2^18 by ~1.3× (the temporaries stay in L2).
BLOCK_POINTS = 64
#: gun samples evaluated together against the union of their candidate blocks (stays in cache).
CHUNK_SAMPLES = 16
#: at most this many (sample, point) pairs in one kernel call (128 kB per temporary).
MAX_PAIRS_PER_CALL = 1 << 14
#: exponents are clamped here: exp below -708 underflows and numpy's exp is then 10-20x slower
#: (measured); e^-700 ≈ 1e-304 is zero for any film.
_EXP_MIN = -700.0
#: h/dz is clipped to this (dz ≈ +0: the pattern coordinates are then huge and f underflows).
_INV_MAX = 1e12


class DepositionError(PaintcellError):
    """Gun samples, points or normals passed to the deposition model are invalid."""


@dataclass(frozen=True, eq=False)
class GunSamples:
    """A sampled gun trajectory.

    positions: (S, 3) spray points (TCP) [m], in the same frame as the surface points.
    spray_axes: (S, 3) unit spray directions (tool +z).
    travel_dirs: (S, 3) unit travel directions (tool +x), orthogonal to the spray axis.
    dwell_s: (S,) time attributed to each sample [s] (≥ 0).
    """

    positions: np.ndarray
    spray_axes: np.ndarray
    travel_dirs: np.ndarray
    dwell_s: np.ndarray

    def __post_init__(self) -> None:
        pos = _as_vectors(self.positions, "positions")
        s = len(pos)
        axes = _as_vectors(self.spray_axes, "spray_axes", s)
        trav = _as_vectors(self.travel_dirs, "travel_dirs", s)
        dwell = np.asarray(self.dwell_s, float).reshape(-1)
        if len(dwell) != s:
            raise DepositionError(f"dwell_s has {len(dwell)} entries, expected {s} (one a sample)")
        if not np.all(np.isfinite(dwell)) or np.any(dwell < 0):
            raise DepositionError("dwell_s must be finite and >= 0 [s]")
        if s and np.any(np.abs(np.linalg.norm(axes, axis=1) - 1) > 1e-6):
            raise DepositionError("spray_axes must be unit vectors; normalize them")
        if s and np.any(np.abs(np.linalg.norm(trav, axis=1) - 1) > 1e-6):
            raise DepositionError("travel_dirs must be unit vectors; normalize them")
        if s and np.any(np.abs(np.sum(axes * trav, axis=1)) > 1e-6):
            raise DepositionError("travel_dirs must be orthogonal to spray_axes")
        for name, arr in (("positions", pos), ("spray_axes", axes), ("travel_dirs", trav),
                          ("dwell_s", dwell)):
            object.__setattr__(self, name, arr)

    def __len__(self) -> int:
        return len(self.positions)

    @property
    def total_time_s(self) -> float:
        """Σ dwell [s]."""
        return float(self.dwell_s.sum())

    @classmethod
    def straight_pass(cls, start_m: npt.ArrayLike, end_m: npt.ArrayLike, spray_axis: npt.ArrayLike,
                      speed_m_s: float, spacing_m: float = 0.005) -> GunSamples:
        """Constant-speed straight pass from `start_m` to `end_m` (3,) [m], spray axis (3,),
        sample spacing [m]; dwell by the trapezoid rule (half intervals at the ends)."""
        a = np.asarray(start_m, float)
        b = np.asarray(end_m, float)
        z = np.asarray(spray_axis, float)
        for name, v in (("start_m", a), ("end_m", b), ("spray_axis", z)):
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise DepositionError(f"straight_pass: {name} = {v.tolist()} must be a finite "
                                      "3-vector; give finite coordinates [m]")
        for name, x_ in (("speed_m_s", speed_m_s), ("spacing_m", spacing_m)):
            if not (isinstance(x_, int | float | np.floating) and math.isfinite(x_) and x_ > 0):
                raise DepositionError(f"straight_pass: {name} = {x_!r} must be a finite number "
                                      "> 0")
        length = float(np.linalg.norm(b - a))
        nz = float(np.linalg.norm(z))
        if length <= 0 or nz <= 0:
            raise DepositionError("straight_pass needs distinct end points and a nonzero spray "
                                  "axis; check start_m, end_m and spray_axis")
        z = z / nz
        x = (b - a) / length
        x = x - np.dot(x, z) * z
        nx = float(np.linalg.norm(x))
        if nx < 1e-9:
            raise DepositionError("straight_pass: the spray axis is parallel to the travel "
                                  "direction end_m - start_m; give a spray axis across the pass")
        x = x / nx
        n = max(2, int(math.ceil(length / spacing_m)) + 1)
        t = np.linspace(0.0, 1.0, n)
        pos = a + t[:, None] * (b - a)
        dt = length / (n - 1) / speed_m_s
        dwell = np.full(n, dt)
        dwell[[0, -1]] = dt / 2
        return cls(pos, np.tile(z, (n, 1)), np.tile(x, (n, 1)), dwell)


def _as_vectors(x: npt.ArrayLike, name: str, rows: int | None = None) -> np.ndarray:
    arr = np.ascontiguousarray(x, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise DepositionError(f"{name} must have shape (n, 3), got {arr.shape}")
    if rows is not None and len(arr) != rows:
        raise DepositionError(f"{name} has {len(arr)} rows, expected {rows}")
    if not np.all(np.isfinite(arr)):
        raise DepositionError(f"{name} contains NaN or inf")
    return arr


#: |‖n‖ − 1| allowed for a surface normal: the rate scales with |n·ω|, so a non-unit normal
#: scales the film by ‖n‖; 1e-6 admits float32-stored unit normals (eps 6e-8) with margin.
UNIT_NORMAL_TOL = 1e-6


def _as_normals(x: npt.ArrayLike, rows: int) -> np.ndarray:
    n = _as_vectors(x, "normals", rows)
    bad = np.abs(np.linalg.norm(n, axis=1) - 1.0) > UNIT_NORMAL_TOL
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DepositionError(
            f"normals must be unit vectors (|n| - 1 within {UNIT_NORMAL_TOL:g}); {int(bad.sum())} "
            f"are not (first: row {i}, |n| = {np.linalg.norm(n[i]):.6g}); normalize them")
    return n


def _tool_axes(spray_axes: np.ndarray, travel_dirs: np.ndarray) -> tuple[np.ndarray, ...]:
    """Unit (x̂, ŷ, â) per sample: x̂ re-orthogonalized against â, ŷ = â × x̂."""
    a = spray_axes / np.linalg.norm(spray_axes, axis=1, keepdims=True)
    x = travel_dirs - np.sum(travel_dirs * a, axis=1, keepdims=True) * a
    nx = np.linalg.norm(x, axis=1, keepdims=True)
    if np.any(nx < 1e-9):
        raise DepositionError("a travel direction is parallel to its spray axis; give x ⟂ z")
    x = x / nx
    return x, np.cross(a, x), a


def deposition_rate(app: Applicator, positions: npt.ArrayLike, spray_axes: npt.ArrayLike,
                    travel_dirs: npt.ArrayLike, points: npt.ArrayLike,
                    normals: npt.ArrayLike) -> np.ndarray:
    """Dense rate matrix (S, N) [m/s]: film-thickness rate at each point from each gun sample.

    positions: (S, 3) gun positions [m]; spray_axes: (S, 3) unit; travel_dirs: (S, 3) unit ⟂ axis;
    points: (N, 3) surface points [m]; normals: (N, 3) unit normals toward the painted side.
    Every pair is evaluated (no culling), by the same in-place arithmetic as `thickness`, in
    calls of ≤ `MAX_PAIRS_PER_CALL` pairs; memory is the (S, N) result.
    """
    g = _as_vectors(positions, "positions")
    s = len(g)
    x_hat, y_hat, a = _tool_axes(_as_vectors(spray_axes, "spray_axes", s),
                                 _as_vectors(travel_dirs, "travel_dirs", s))
    p = _as_vectors(points, "points")
    n = _as_normals(normals, len(p))
    out = np.empty((s, len(p)))
    if s == 0 or len(p) == 0:
        return out
    feats = np.empty((8, len(p)))
    feats[0:3] = p.T
    feats[3] = 1.0
    feats[4:7] = n.T
    feats[7] = np.einsum("ij,ij->i", n, p)
    step_p = min(len(p), MAX_PAIRS_PER_CALL)
    step_s = max(1, MAX_PAIRS_PER_CALL // step_p)
    for i in range(0, s, step_s):
        sl = slice(i, min(i + step_s, s))
        w = _projection_rows(g[sl], x_hat[sl], y_hat[sl], a[sl])
        for j in range(0, len(p), step_p):
            out[sl, j:j + step_p] = _rates(app, w, feats[:, j:j + step_p])
    out *= 1.0 / app.standoff_m
    return out


def deposition_rate_reference(app: Applicator, positions: npt.ArrayLike,
                              spray_axes: npt.ArrayLike, travel_dirs: npt.ArrayLike,
                              points: npt.ArrayLike, normals: npt.ArrayLike) -> np.ndarray:
    """`deposition_rate` written literally from DESIGN.md (ω, q, cosines): slow (memory
    O(S·N·3)), an independent reference for tests and checks.
    """
    g = _as_vectors(positions, "positions")
    s = len(g)
    x_hat, y_hat, a = _tool_axes(_as_vectors(spray_axes, "spray_axes", s),
                                 _as_vectors(travel_dirs, "travel_dirs", s))
    p = _as_vectors(points, "points")
    n = _as_normals(normals, len(p))
    h = app.standoff_m
    d = p[None, :, :] - g[:, None, :]                        # (S, N, 3)
    dist = np.linalg.norm(d, axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        omega = d / dist[..., None]
        cos_a = np.einsum("snk,sk->sn", omega, a)              # a·ω
        n_dot_w = np.einsum("snk,nk->sn", omega, n)            # n·ω
        valid = (cos_a > 0) & (n_dot_w < 0) & (dist > 0)
        q_rel = omega * (h / np.where(valid, cos_a, 1.0))[..., None]   # q − g
        qx = np.einsum("snk,sk->sn", q_rel, x_hat)
        qy = np.einsum("snk,sk->sn", q_rel, y_hat)
        mag = np.abs(n_dot_w) * h * h / (np.where(valid, cos_a, 1.0) ** 3
                                         * np.where(valid, dist, 1.0) ** 2)
    rate = app.flux(np.where(valid, qx, 0.0), np.where(valid, qy, 0.0)) * mag
    return np.where(valid, rate, 0.0)


# --- the fast kernel ------------------------------------------------------------------------------
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
class _Blocks:
    order: np.ndarray       # (N,) original index of each sorted point
    feats: np.ndarray       # (nb, 8, B): p (3), 1, n (3), n·p ; pads have n = 0, n·p = 0
    centers: np.ndarray     # (nb, 3) block bounding-sphere centres [m]
    radii: np.ndarray       # (nb,) bounding-sphere radii [m]


def _make_blocks(p: np.ndarray, n: np.ndarray, block: int) -> _Blocks:
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
    return _Blocks(order, feats_t, centers, radii)


def _candidate_blocks(blocks: _Blocks, g: np.ndarray, a: np.ndarray, tan_cone: float) -> np.ndarray:
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


def _projection_rows(g: np.ndarray, x_hat: np.ndarray, y_hat: np.ndarray,
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


def _kernel(app: Applicator, w_mat: np.ndarray, coef: np.ndarray, feats: np.ndarray) -> np.ndarray:
    """Σ_k coef_k · (h · rate_k) for K samples and a batch of point blocks: (nb, B).

    w_mat: (4, K, 8) from `_projection_rows`; coef: (K,) dwell / h [s/m]; feats: (nb, 8, B).
    """
    return np.matmul(coef, _rates(app, w_mat, feats))


def _rates(app: Applicator, w_mat: np.ndarray, feats: np.ndarray) -> np.ndarray:
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
    np.clip(inv, 0.0, _INV_MAX, out=inv)                         # h/dz
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
        np.maximum(t1, _EXP_MIN, out=t1)
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
        np.maximum(t2, _EXP_MIN, out=t2)
        np.exp(t2, out=t2)
        t1 += t2
    # rate·h = f · (−n·d) · (h/dz)³ ; coef carries dwell/h
    np.multiply(inv, inv, out=t2)
    t2 *= inv
    t2 *= nd
    t1 *= t2
    return t1


def _sample_chunks(s: int, k: int) -> Iterator[slice]:
    for i in range(0, s, k):
        yield slice(i, min(i + k, s))


#: kernels `thickness` can run: "auto" picks the GPU when present, else numba; numpy is the
#: reference (and the occlusion path: trimesh's rays are Python calls per chunk).
BACKENDS = ("auto", "numba", "gpu", "numpy")


def thickness(app: Applicator, gun: GunSamples, points: npt.ArrayLike, normals: npt.ArrayLike,
              occluder: Any = None, *, threads: int = 2, backend: str = "auto") -> np.ndarray:
    """Film thickness (N,) [m] at each point: Σ_s rate_s(p) · dwell_s.

    app: the deposition model; gun: the sampled trajectory (same frame as the points);
    points: (N, 3) [m]; normals: (N, 3) unit normals toward the painted side.
    occluder: optional `trimesh.Trimesh` (or object with `.mesh`, e.g. a `Surface`): a point gets
        nothing from a chunk of `CHUNK_SAMPLES` gun samples when the segment from the point to the
        chunk's middle gun position hits the mesh (visibility is evaluated once per chunk, for
        the points inside some spray cone of the chunk; points outside every cone get nothing
        from that chunk, as if culled). Rays cost ~10 µs each with trimesh's intersector (no
        embree here), so this is ~100× slower than the unoccluded kernel.
    threads: worker threads (numba's pool, or numpy's over sample chunks); the summation order
        is fixed, so the result does not depend on it.
    backend: "auto" (a CUDA GPU when `numba.cuda` sees one, else the numba CPU kernel; the numpy
        kernel when an occluder is given or numba is missing), "numba", "gpu" or "numpy" (the
        reference kernel). All evaluate the same pairs and agree to round-off
        (`planning.deposition_jit`).

    Points are grouped into Z-order blocks of `BLOCK_POINTS`; for every chunk of `CHUNK_SAMPLES`
    samples only blocks whose bounding sphere meets a spray cone of half-angle
    atan(footprint_radius / h) are evaluated (exactly, with no truncation inside them); the culled
    pairs all have f(q) < 1e-4 · peak. Memory is O(N + MAX_PAIRS_PER_CALL).
    """
    if not isinstance(gun, GunSamples):
        raise DepositionError(f"gun must be a GunSamples, got {type(gun).__name__}")
    if backend not in BACKENDS:
        raise DepositionError(f"backend {backend!r} is not one of {', '.join(BACKENDS)}")
    p = _as_vectors(points, "points")
    n = _as_normals(normals, len(p))
    out = np.zeros(len(p))
    keep = gun.dwell_s > 0
    if len(p) == 0 or not np.any(keep):
        return out
    g = gun.positions[keep]
    x_hat, y_hat, a = _tool_axes(gun.spray_axes[keep], gun.travel_dirs[keep])
    coef_all = gun.dwell_s[keep] / app.standoff_m
    blocks = _make_blocks(p, n, BLOCK_POINTS)
    tan_cone = app.footprint_radius_m / app.standoff_m
    kind = _pick_backend(backend, occluder, app)
    if kind != "numpy":
        out[blocks.order] = _thickness_jit(kind, app, blocks, p, n, g, x_hat, y_hat, a,
                                           gun.dwell_s[keep], tan_cone, threads)[0]
        return out
    mesh = None
    if occluder is not None:
        mesh = getattr(occluder, "mesh", occluder)
        if not hasattr(mesh, "ray"):
            raise DepositionError("occluder must be a trimesh.Trimesh or have a `.mesh` one")
        threads = 1  # trimesh's ray engine is not known to be thread-safe

    def chunk(sl: slice) -> tuple[np.ndarray, np.ndarray]:
        gk, ak = g[sl], a[sl]
        kk = len(gk)
        cand = _candidate_blocks(blocks, gk, ak, tan_cone)
        contrib = np.zeros((len(cand), BLOCK_POINTS))
        if len(cand) == 0:
            return cand, contrib
        w = _projection_rows(gk, x_hat[sl], y_hat[sl], ak)
        per_call = max(1, MAX_PAIRS_PER_CALL // (kk * BLOCK_POINTS))
        for j in range(0, len(cand), per_call):
            ids = cand[j:j + per_call]
            feats = blocks.feats[ids]
            if mesh is not None:
                pts = feats[:, 0:3, :].transpose(0, 2, 1).reshape(-1, 3)
                # rays only for points some sample of the chunk can paint (facing, in the cone);
                # the others would only get the culled tail (f < 1e-4·peak): treat as culled
                need = _reached(np.matmul(w[:, None], feats[None]), tan_cone).reshape(-1)
                vis = np.zeros(len(pts), bool)
                vis[need] = _visible(mesh, pts[need], gk[kk // 2])
                feats[:, 4:8, :] *= vis.reshape(len(ids), 1, BLOCK_POINTS)   # n = 0 ⇒ no paint
            contrib[j:j + len(ids)] = _kernel(app, w, coef_all[sl], feats)
        return cand, contrib

    out_blocks = np.zeros((len(blocks.centers), BLOCK_POINTS))
    chunks = list(_sample_chunks(len(g), CHUNK_SAMPLES))
    if threads <= 1 or len(chunks) < 2:
        for sl in chunks:
            ids, c = chunk(sl)
            out_blocks[ids] += c
    else:
        # at most 2·threads chunks in flight (memory bound); results summed in chunk order, so
        # the floating-point sum is the same for any thread count
        with ThreadPoolExecutor(max_workers=threads) as pool:
            pending: deque[Future[tuple[np.ndarray, np.ndarray]]] = deque()
            for sl in chunks:
                pending.append(pool.submit(chunk, sl))
                if len(pending) >= 2 * threads:
                    ids, c = pending.popleft().result()
                    out_blocks[ids] += c
            while pending:
                ids, c = pending.popleft().result()
                out_blocks[ids] += c
    out[blocks.order] = out_blocks.reshape(-1)[:len(p)]
    return out


def _pick_backend(backend: str, occluder: Any, app: Applicator) -> str:
    from planning import deposition_jit as jit

    if backend == "numpy" or (backend == "auto" and (occluder is not None or not jit.HAVE_NUMBA)):
        return "numpy"
    if backend in ("auto", "numba") and not jit.gpu_available() \
            and (len(jit.params(app)) - 4) // 3 > jit.MAX_RINGS:
        if backend == "numba":
            raise DepositionError(f"backend 'numba' takes at most {jit.MAX_RINGS} rings; use "
                                  "backend='numpy' or 'auto'")
        return "numpy"
    if occluder is not None:
        raise DepositionError(f"backend {backend!r} has no occlusion; use backend='numpy' or "
                              "'auto' with an occluder")
    if backend == "gpu" and not jit.gpu_available():
        raise DepositionError("backend 'gpu' needs a CUDA GPU visible to numba.cuda; use 'auto'")
    if backend in ("numba", "gpu") and not jit.HAVE_NUMBA:
        raise DepositionError("numba is not installed; pip install numba or use backend='numpy'")
    if backend == "auto":
        return "gpu" if jit.gpu_available() else "numba"
    return backend


def _thickness_jit(kind: str, app: Applicator, blocks: _Blocks, p: np.ndarray, n: np.ndarray,
                   g: np.ndarray, x_hat: np.ndarray, y_hat: np.ndarray, a: np.ndarray,
                   dwell: np.ndarray, tan_cone: float, threads: int) -> tuple[np.ndarray, int]:
    """(film (N,) in Z-order [m], pairs evaluated) by the compiled kernel `kind`."""
    from planning import deposition_jit as jit

    ps = np.ascontiguousarray(p[blocks.order])
    ns = np.ascontiguousarray(n[blocks.order])
    starts = np.minimum(np.arange(len(blocks.radii) + 1) * BLOCK_POINTS, len(p)).astype(np.int64)
    coef = np.ascontiguousarray(dwell / app.standoff_m)
    prm = jit.params(app)
    args = (np.ascontiguousarray(g), np.ascontiguousarray(x_hat), np.ascontiguousarray(y_hat),
            np.ascontiguousarray(a))
    if kind == "gpu":
        cand = jit.candidates_cpu(blocks.centers, blocks.radii, args[0], args[3], CHUNK_SAMPLES,
                                  tan_cone)
        film = jit.film_gpu(ps, ns, starts, cand, *args, coef, CHUNK_SAMPLES, prm)
        evaluated = int((cand * np.diff(starts)[None, :]).sum()) * CHUNK_SAMPLES
        return film, evaluated
    return jit.film_cpu(ps, ns, starts, blocks.centers, blocks.radii, *args, coef,
                        CHUNK_SAMPLES, tan_cone, prm, threads)


def _reached(m: np.ndarray, tan_cone: float) -> np.ndarray:
    """(nb, B) True where any of the K samples has the point in front, facing it, and inside
    its spray cone; m: (4, nb, K, B) dx, dy, dz, −n·d."""
    dx, dy, dz, nd = m
    ok = (dz > 0) & (nd > 0) & (dx * dx + dy * dy <= (tan_cone * dz) ** 2)
    return np.asarray(ok.any(axis=1))


def _visible(mesh: Any, pts: np.ndarray, g: np.ndarray) -> np.ndarray:
    """(n,) True where the segment from each point to the gun position g misses the mesh."""
    if len(pts) == 0:
        return np.ones(0, bool)
    d = g[None, :] - pts
    dist = np.linalg.norm(d, axis=1)
    ok = dist > 0
    dirs = np.where(ok[:, None], d / np.where(ok, dist, 1.0)[:, None], np.array([0.0, 0.0, 1.0]))
    eps = 1e-6 * max(1.0, float(np.max(np.abs(pts))))  # leave the point's own triangles
    origins = pts + dirs * max(eps, 1e-5)
    locs, index_ray, _ = mesh.ray.intersects_location(origins, dirs, multiple_hits=False)
    vis = np.ones(len(pts), bool)
    if len(index_ray):
        hit_d = np.linalg.norm(locs - origins[index_ray], axis=1)
        blocked = hit_d < dist[index_ray] - 1e-5
        vis[index_ray[blocked]] = False
    return vis
