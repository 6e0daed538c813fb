"""The compiled film kernel (paintcell.planning.paint.deposition_jit) against the numpy kernel and
the literal DESIGN.md formula.

- numba vs the numpy kernel (same culling, an independent implementation of the arithmetic) on a
  curved patch with back-facing points and points behind the gun: within 1e-9 of the peak;
- numba vs `deposition_rate_reference` (ω, q and cosines written out, every pair) where no pair
  is culled: within 1e-9 of the peak;
- the branch-free 2^y against numpy's exp2;
- the result does not depend on the thread count (bit for bit);
- the GPU kernel agrees with the CPU one — only where a CUDA GPU is present (none on the 2-core
  development machine: that test skips there).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from paintcell.planning.paint import deposition_jit as jit
from paintcell.planning.paint.applicator import Applicator
from paintcell.planning.paint.deposition import (
    DepositionError,
    GunSamples,
    deposition_rate_reference,
    thickness,
)

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
    """2^y of the kernel (the film's e^x computed as 2^(x·log2 e)) against numpy's exp2 over
    the whole clamped range, and the clamp at e^−700 as the numpy kernel's."""
    lo = -jit.EXP_FLOOR * jit.LOG2E
    ys = np.concatenate([np.linspace(lo, 0.0, 20001), -np.geomspace(1e-12, -lo, 500),
                         np.linspace(-3.0, 0.0, 20001)])
    got = np.array([jit._exp2_neg(float(v)) for v in ys])
    want = np.exp2(ys)
    assert np.max(np.abs(got / want - 1.0)) < 1e-14
    assert jit._exp2_neg(-1e4) == pytest.approx(math.exp(-jit.EXP_FLOOR), rel=1e-12)


def test_thread_count_does_not_change_the_film() -> None:
    app = Applicator.default()
    p, n = _patch(60)
    gun = _program()
    one = thickness(app, gun, p, n, backend="numba", threads=1)
    two = thickness(app, gun, p, n, backend="numba", threads=2)
    np.testing.assert_array_equal(one, two)


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
