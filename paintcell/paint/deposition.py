"""Film thickness on a surface from a sampled gun trajectory (paper §2.2, DESIGN.md).

For gun position g, spray axis a, travel direction x̂ (re-orthogonalized against a), ŷ = a × x̂, a
surface point p with unit normal n (toward the painted side) and d = p − g, ω = d/|d|, the ray
through p meets the reference plane at q = g + ω·h/(a·ω), and

    rate(p) = f(q) · |n·ω| · h² / ((a·ω)³ · |d|²)     if a·ω > 0 and n·ω < 0, else 0.

With dx = d·x̂, dy = d·ŷ, dz = d·a this is f(h·dx/dz, h·dy/dz) · (−n·d) · h² / dz³, which is what
the fast kernel evaluates (no square roots beyond the ring radius).
Thickness is Σ_s rate_s · dwell_s.

The entry points are here (`thickness`, `deposition_rate`, its literal reference and the choice
of kernel); the gun samples and input checks are in `paintcell.paint.deposition_samples`,
the numpy kernel in `paintcell.paint.deposition_kernel`, the compiled one in
`paintcell.paint.deposition_jit`.
"""

from __future__ import annotations

from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np
import numpy.typing as npt

from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition_kernel import (
    BLOCK_POINTS,
    CHUNK_SAMPLES,
    MAX_PAIRS_PER_CALL,
    Blocks,
    candidate_blocks,
    film_kernel,
    make_blocks,
    projection_rows,
    sample_chunks,
    sample_rates,
)
from paintcell.paint.deposition_samples import (
    DepositionError,
    GunSamples,
    as_normals,
    as_vectors,
    tool_axes,
)

__all__ = ["BACKENDS", "deposition_rate", "deposition_rate_reference", "thickness"]


def deposition_rate(app: Applicator, positions: npt.ArrayLike, spray_axes: npt.ArrayLike,
                    travel_dirs: npt.ArrayLike, points: npt.ArrayLike,
                    normals: npt.ArrayLike) -> np.ndarray:
    """Dense rate matrix (S, N) [m/s]: film-thickness rate at each point from each gun sample.

    positions: (S, 3) gun positions [m]; spray_axes: (S, 3) unit; travel_dirs: (S, 3) unit ⟂ axis;
    points: (N, 3) surface points [m]; normals: (N, 3) unit normals toward the painted side.
    Every pair is evaluated (no culling), by the same in-place arithmetic as `thickness`, in
    calls of ≤ `MAX_PAIRS_PER_CALL` pairs; memory is the (S, N) result.
    """
    g = as_vectors(positions, "positions")
    s = len(g)
    x_hat, y_hat, a = tool_axes(as_vectors(spray_axes, "spray_axes", s),
                                 as_vectors(travel_dirs, "travel_dirs", s))
    p = as_vectors(points, "points")
    n = as_normals(normals, len(p))
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
        w = projection_rows(g[sl], x_hat[sl], y_hat[sl], a[sl])
        for j in range(0, len(p), step_p):
            out[sl, j:j + step_p] = sample_rates(app, w, feats[:, j:j + step_p])
    out *= 1.0 / app.standoff_m
    return out


def deposition_rate_reference(app: Applicator, positions: npt.ArrayLike,
                              spray_axes: npt.ArrayLike, travel_dirs: npt.ArrayLike,
                              points: npt.ArrayLike, normals: npt.ArrayLike) -> np.ndarray:
    """`deposition_rate` written literally from DESIGN.md (ω, q, cosines): slow (memory
    O(S·N·3)), an independent reference for tests and checks.
    """
    g = as_vectors(positions, "positions")
    s = len(g)
    x_hat, y_hat, a = tool_axes(as_vectors(spray_axes, "spray_axes", s),
                                 as_vectors(travel_dirs, "travel_dirs", s))
    p = as_vectors(points, "points")
    n = as_normals(normals, len(p))
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
        (`paintcell.paint.deposition_jit`).

    Points are grouped into Z-order blocks of `BLOCK_POINTS`; for every chunk of `CHUNK_SAMPLES`
    samples only blocks whose bounding sphere meets a spray cone of half-angle
    atan(footprint_radius / h) are evaluated (exactly, with no truncation inside them); the culled
    pairs all have f(q) < 1e-4 · peak. Memory is O(N + MAX_PAIRS_PER_CALL).
    """
    if not isinstance(gun, GunSamples):
        raise DepositionError(f"gun must be a GunSamples, got {type(gun).__name__}")
    if backend not in BACKENDS:
        raise DepositionError(f"backend {backend!r} is not one of {', '.join(BACKENDS)}")
    p = as_vectors(points, "points")
    n = as_normals(normals, len(p))
    out = np.zeros(len(p))
    keep = gun.dwell_s > 0
    if len(p) == 0 or not np.any(keep):
        return out
    g = gun.positions[keep]
    x_hat, y_hat, a = tool_axes(gun.spray_axes[keep], gun.travel_dirs[keep])
    coef_all = gun.dwell_s[keep] / app.standoff_m
    tan_cone = app.footprint_radius_m / app.standoff_m
    kind = _pick_backend(backend, occluder, app)
    if kind == "numba":  # builds its own blocks (the same ones)
        from paintcell.paint import deposition_jit as jit

        return jit.film_cpu(p, n, g, x_hat, y_hat, a, gun.dwell_s[keep], CHUNK_SAMPLES, tan_cone,
                            jit.params(app), threads)[0]
    blocks = make_blocks(p, n, BLOCK_POINTS)
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
        cand = candidate_blocks(blocks, gk, ak, tan_cone)
        contrib = np.zeros((len(cand), BLOCK_POINTS))
        if len(cand) == 0:
            return cand, contrib
        w = projection_rows(gk, x_hat[sl], y_hat[sl], ak)
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
            contrib[j:j + len(ids)] = film_kernel(app, w, coef_all[sl], feats)
        return cand, contrib

    out_blocks = np.zeros((len(blocks.centers), BLOCK_POINTS))
    chunks = list(sample_chunks(len(g), CHUNK_SAMPLES))
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
    from paintcell.paint import deposition_jit as jit

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


def _thickness_jit(kind: str, app: Applicator, blocks: Blocks, p: np.ndarray, n: np.ndarray,
                   g: np.ndarray, x_hat: np.ndarray, y_hat: np.ndarray, a: np.ndarray,
                   dwell: np.ndarray, tan_cone: float, threads: int) -> tuple[np.ndarray, int]:
    """(film (N,) in Z-order [m], pairs evaluated) by the GPU kernel."""
    from paintcell.paint import deposition_jit as jit

    ps = np.ascontiguousarray(p[blocks.order])
    ns = np.ascontiguousarray(n[blocks.order])
    starts = np.minimum(np.arange(len(blocks.radii) + 1) * BLOCK_POINTS, len(p)).astype(np.int64)
    coef = np.ascontiguousarray(dwell / app.standoff_m)
    prm = jit.params(app)
    args = (np.ascontiguousarray(g), np.ascontiguousarray(x_hat), np.ascontiguousarray(y_hat),
            np.ascontiguousarray(a))
    cand = jit.candidates_cpu(blocks.centers, blocks.radii, args[0], args[3], CHUNK_SAMPLES,
                              tan_cone)
    film = jit.film_gpu(ps, ns, starts, cand, *args, coef, CHUNK_SAMPLES, prm)
    evaluated = int((cand * np.diff(starts)[None, :]).sum()) * CHUNK_SAMPLES
    return film, evaluated


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
