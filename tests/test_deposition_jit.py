"""The compiled film kernel (paintcell.paint.deposition_jit) against the numpy kernel and
the literal DESIGN.md formula.

- numba vs the numpy kernel (same culling, an independent implementation of the arithmetic) on a
  curved patch with back-facing points and points behind the gun: within 1e-9 of the peak;
- numba vs `deposition_rate_reference` (ω, q and cosines written out, every pair) where no pair
  is culled: within 1e-9 of the peak;
- the branch-free 2^y against numpy's exp2; zero amplitudes, a last group of fewer than four
  samples, and the count of evaluated pairs against the numpy kernel's culling;
- the result does not depend on the thread count (bit for bit);
- the GPU kernel agrees with the CPU one — only where a CUDA GPU is present (none on the 2-core
  development machine: that test skips there).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from paintcell.paint import deposition_cpu as cpu
from paintcell.paint import deposition_jit as jit
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate_reference, thickness
from paintcell.paint.deposition_samples import DepositionError, GunSamples

pytestmark = pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba is a dependency")


def _patch(n: int = 90, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A 0.9 × 0.9 m saddle-ish patch (z up), normals +z side, a strip flipped to face away."""
    x, y = np.meshgrid(np.linspace(-0.45, 0.45, n), np.linspace(-0.45, 0.45, n), indexing="ij")
    z = 0.08 * x * x - 0.05 * y * y + 0.03 * np.sin(3 * x)
    p = np.c_[x.ravel(), y.ravel(), z.ravel()]
    dzdx = (0.16 * x + 0.09 * np.cos(3 * x)).ravel()
    dzdy = (-0.1 * y).ravel()
    nrm = np.c_[-dzdx, -dzdy, np.ones(len(p))]
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm[(p[:, 0] > 0.3)] *= -1.0          # back-facing strip: no paint
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(p))         # the kernel must not rely on the input order
    return p[order], nrm[order]


def _program() -> GunSamples:
    """Tilted passes 0.25 m above the patch, plus one segment below it (behind the gun)."""
    tilt = np.array([0.15, -0.1, -1.0])
    tilt /= np.linalg.norm(tilt)
    parts = [GunSamples.straight_pass([-0.7, y, 0.26], [0.7, y + 0.05, 0.24], tilt, 0.6, 0.004)
             for y in (-0.3, 0.0, 0.3)]
    parts.append(GunSamples.straight_pass([-0.2, 0.0, -0.3], [0.2, 0.0, -0.3], [0, 0, -1], 0.5))
    return GunSamples(*(np.concatenate([getattr(q, f) for q in parts]) for f in
                        ("positions", "spray_axes", "travel_dirs", "dwell_s")))


def test_numba_agrees_with_numpy_kernel() -> None:
    app = Applicator.default()
    p, n = _patch()
    gun = _program()
    ref = thickness(app, gun, p, n, backend="numpy")
    got = thickness(app, gun, p, n, backend="numba")
    assert ref.max() > 0 and np.any(ref == 0)      # painted, and the back-facing strip is bare
    assert np.max(np.abs(got - ref)) <= 1e-9 * ref.max()
    np.testing.assert_array_equal(got[ref == 0], 0.0)


def test_numba_agrees_with_the_literal_formula_where_nothing_is_culled() -> None:
    app = Applicator.default()
    x, y = np.meshgrid(np.linspace(-0.1, 0.1, 15), np.linspace(-0.1, 0.1, 15), indexing="ij")
    p = np.c_[x.ravel(), y.ravel(), 0.02 * x.ravel() ** 2]
    n = np.tile([0.0, 0.0, 1.0], (len(p), 1))
    gun = GunSamples.straight_pass([-0.05, 0.01, 0.25], [0.05, -0.01, 0.25],
                                   [0.05, 0.0, -1.0] / np.linalg.norm([0.05, 0.0, -1.0]), 0.4,
                                   0.005)
    dense = gun.dwell_s @ deposition_rate_reference(app, gun.positions, gun.spray_axes,
                                                    gun.travel_dirs, p, n)
    got = thickness(app, gun, p, n, backend="numba")
    assert np.max(np.abs(got - dense)) <= 1e-9 * dense.max()


def test_branch_free_exp2_matches_numpy() -> None:
    """2^y of the CPU kernel (the film's e^x computed as 2^(x·log2 e), four values at a time)
    against numpy's exp2 over the whole clamped range; the clamp at e^−700 as the numpy
    kernel's, and exactly 0 at the zero-amplitude clamp."""
    lo = cpu.Y_FLOOR
    ys = np.concatenate([np.linspace(lo, 0.0, 20001), -np.geomspace(1e-12, -lo, 499),
                         np.linspace(-3.0, 0.0, 20000)])
    assert len(ys) % 4 == 0
    got = np.array([cpu.exp2_x4(*(float(v) for v in q), lo) for q in ys.reshape(-1, 4)]).ravel()
    want = np.exp2(ys)
    assert np.max(np.abs(got / want - 1.0)) < 1e-14
    assert cpu.exp2_x4(-1e4, -2e3, -1e3, lo, lo) == pytest.approx(
        (math.exp(-jit.EXP_FLOOR),) * 4, rel=1e-12)
    assert cpu.exp2_x4(-math.inf, -1e4, -1023.5, -1023.0, cpu.Y_ZERO) == (0.0,) * 4


def test_zero_amplitudes_and_a_partial_last_group_of_samples() -> None:
    """A bell without its central Gaussian (A0 = 0) and with one ring off: the compiled kernel's
    terms of zero amplitude are exactly 0 (not the e^−700 floor); a program of 4k + 1, + 2, + 3
    samples (the kernel takes four at a time, padding the last group with zero dwell): same film
    as the numpy kernel, and the pairs it reports evaluated are the culling's (padding not
    counted), checked against the numpy kernel's candidate blocks."""
    from paintcell.paint.deposition_kernel import (
        BLOCK_POINTS,
        CHUNK_SAMPLES,
        candidate_blocks,
        make_blocks,
    )
    from paintcell.paint.deposition_samples import tool_axes

    base = Applicator.default()
    app = Applicator(base.standoff_m, 0.0, base.sigma_x_m, base.sigma_y_m,
                     np.array([base.ring_amplitudes_m_s[0], 0.0]), base.ring_radii_m,
                     base.ring_sigmas_m)
    p, n = _patch(40)
    full = _program()
    tan_cone = app.footprint_radius_m / app.standoff_m
    for extra in (1, 2, 3):
        k = 4 * 37 + extra
        gun = GunSamples(full.positions[:k], full.spray_axes[:k], full.travel_dirs[:k],
                         full.dwell_s[:k])
        ref = thickness(app, gun, p, n, backend="numpy")
        got = thickness(app, gun, p, n, backend="numba")
        assert ref.max() > 0
        assert np.max(np.abs(got - ref)) <= 1e-9 * ref.max()
        x_hat, y_hat, a = tool_axes(gun.spray_axes, gun.travel_dirs)
        _, evaluated = jit.film_cpu(p, n, gun.positions, x_hat, y_hat, a, gun.dwell_s,
                                    CHUNK_SAMPLES, tan_cone, jit.params(app))
        blocks = make_blocks(p, n, BLOCK_POINTS)
        sizes = np.minimum(len(p) - np.arange(len(blocks.radii)) * BLOCK_POINTS, BLOCK_POINTS)
        want = sum(int(sizes[candidate_blocks(blocks, gun.positions[c:c + CHUNK_SAMPLES],
                                               a[c:c + CHUNK_SAMPLES], tan_cone)].sum())
                   * len(gun.positions[c:c + CHUNK_SAMPLES]) for c in range(0, k, CHUNK_SAMPLES))
        assert evaluated == want


def test_thread_count_does_not_change_the_film() -> None:
    app = Applicator.default()
    p, n = _patch(60)
    gun = _program()
    one = thickness(app, gun, p, n, backend="numba", threads=1)
    two = thickness(app, gun, p, n, backend="numba", threads=2)
    np.testing.assert_array_equal(one, two)


_CONCURRENT = """
import sys, threading
import numpy as np, numba
from paintcell.paint import deposition_jit as jit
rng = np.random.default_rng(0); N, S = 6000, 1500
p = np.c_[rng.uniform(0, 1, N), rng.uniform(0, 1, N), np.zeros(N)]; n = np.tile([0, 0, 1.0], (N, 1))
g = np.c_[rng.uniform(0, 1, S), rng.uniform(0, 1, S), np.full(S, 0.2)]
xh = np.tile([1.0, 0, 0], (S, 1)); yh = np.tile([0, 1.0, 0], (S, 1))
a = np.tile([0, 0, -1.0], (S, 1))
dw = np.full(S, 1e-3); prm = np.array([0.2, 1.0, 50.0, 50.0])
film = lambda: jit.film_cpu(p, n, g, xh, yh, a, dw, 64, 0.5, prm, 2)[0]
ref = film()
assert numba.threading_layer() == "workqueue", numba.threading_layer()
out = [None] * 4
def work(i): out[i] = film()
ths = [threading.Thread(target=work, args=(i,)) for i in range(4)]
[t.start() for t in ths]; [t.join() for t in ths]
assert all(np.array_equal(o, ref) for o in out)
print("ok")
"""


def test_concurrent_launches_survive_the_workqueue_layer() -> None:
    """numba's fallback threading layer aborts the process (SIGABRT) when two threads launch a
    parallel kernel at once; `paintcell run` computes films on a background thread and a Dask
    worker may run samples in threads. Four threads at once, forced onto that layer, in a fresh
    process: it survives and every film equals the lone launch's bit for bit."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "NUMBA_THREADING_LAYER": "workqueue", "NUMBA_NUM_THREADS": "2"}
    r = subprocess.run([sys.executable, "-c", _CONCURRENT], env=env, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0 and r.stdout.strip() == "ok", (r.returncode, r.stderr[-800:])


def test_backend_choice_errors_are_one_line() -> None:
    app = Applicator.default()
    p, n = _patch(10)
    gun = _program()
    with pytest.raises(DepositionError, match="backend 'fortran' is not one of"):
        thickness(app, gun, p, n, backend="fortran")
    import trimesh

    mesh = trimesh.creation.box()
    with pytest.raises(DepositionError, match="no occlusion"):
        thickness(app, gun, p, n, occluder=mesh, backend="numba")
    if not jit.gpu_available():
        with pytest.raises(DepositionError, match="CUDA GPU"):
            thickness(app, gun, p, n, backend="gpu")


@pytest.mark.skipif(not jit.gpu_available(), reason="needs a CUDA GPU (none on the dev machine)")
def test_gpu_agrees_with_cpu() -> None:  # pragma: no cover - runs only where a GPU is present
    app = Applicator.default()
    p, n = _patch()
    gun = _program()
    cpu = thickness(app, gun, p, n, backend="numba")
    gpu = thickness(app, gun, p, n, backend="gpu")
    assert np.max(np.abs(gpu - cpu)) <= 1e-9 * cpu.max()
