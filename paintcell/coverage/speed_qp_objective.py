"""Eq. 2 of the paper as a function of the knot speeds: the knot-to-sample interpolation, the
objective J(y) with its Gauss–Newton Jacobians (`SpeedObjective`, built by
`build_speed_objective` from the band's rate matrices [m/s] and lengths [m]) and the band σ/μ
(`band_nsd`, a fraction)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from paintcell.coverage.speed_qp_settings import (
    MIN_CURVE_FILM_REL,
    SpeedQPError,
    SpeedSettings,
)


def knot_interpolation(sample_arc_m: npt.ArrayLike, n_knots: int) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation in arc length from knot samples to all samples.

    sample_arc_m: (N,) increasing arc length of the pass samples [m].
    n_knots: requested knots K (≥ 2); min(K, N) distinct samples, first and last included,
        spread evenly in arc length.
    Returns (M (N, K), knot_indices (K,)); row p of M holds the weights of sample p on the two
    knots around it (a convex combination; M[knot_indices] = I).
    """
    x = np.asarray(sample_arc_m, dtype=float)
    n = len(x)
    if n_knots >= n:
        return np.eye(n), np.arange(n)
    idx = np.unique(np.clip(np.searchsorted(x, np.linspace(x[0], x[-1], n_knots)), 0, n - 1))
    idx[0], idx[-1] = 0, n - 1
    idx = np.unique(idx)
    xk = x[idx]
    hi = np.clip(np.searchsorted(xk, x, side="right"), 1, len(idx) - 1)
    lo = hi - 1
    frac = np.clip((x - xk[lo]) / (xk[hi] - xk[lo]), 0.0, 1.0)
    M = np.zeros((n, len(idx)))
    rows = np.arange(n)
    M[rows, lo] = 1.0 - frac
    M[rows, hi] += frac
    return M, idx


@dataclass(frozen=True, eq=False)
class SpeedObjective:
    """Eq. 2 as a function of the relative knot speeds y (y = 1: constant v_nominal).

    rates: J matrices D_j (m_j, n) [m/s]. r: J arrays (m_j,) length weights ℓ/Σℓ.
    seg_lengths: (n,) [m]. interp: M (n + 1, K). k: (J,) mean film at constant speed [m].
    weights: (J,) w_j / k_j² (0 for curves left out). objective: "paper" or "centred".
    """

    rates: tuple[np.ndarray, ...]
    r: tuple[np.ndarray, ...]
    seg_lengths: np.ndarray
    v_nominal_m_s: float
    interp: np.ndarray
    k: np.ndarray
    weights: np.ndarray
    objective: str

    def segment_times(self, y: npt.ArrayLike) -> np.ndarray:
        """(n,) t_i = 2 s_i / (v_i + v_{i+1}) with sample speeds v = v_nom · M y [s]."""
        rho = self._avg @ np.asarray(y, dtype=float)
        return self.seg_lengths / (self.v_nominal_m_s * rho)

    @property
    def _avg(self) -> np.ndarray:
        return 0.5 * (self.interp[1:] + self.interp[:-1])

    def _residuals(self, t: np.ndarray) -> list[np.ndarray]:
        out = []
        for D, r, k, w in zip(self.rates, self.r, self.k, self.weights, strict=True):
            if w <= 0:
                out.append(np.zeros(0))
                continue
            f = D @ t
            out.append(f - (r @ f if self.objective == "centred" else k))
        return out

    def value(self, y: npt.ArrayLike) -> float:
        """J(y), dimensionless."""
        res = self._residuals(self.segment_times(y))
        return float(sum(w * (r @ e**2) for e, r, w in zip(res, self.r, self.weights, strict=True)
                         if w > 0))

    def jacobians(self, y: npt.ArrayLike) -> tuple[np.ndarray, list[np.ndarray]]:
        """(T (n,), per-curve dF_j/dy (m_j, K)) at y: dt_i/dy = −t_i · A_i / ρ_i."""
        y = np.asarray(y, dtype=float)
        A = self._avg
        t = self.segment_times(y)
        # A has ≤ 3 nonzeros a row: D_j · dT through a sparse dT, not small dense GEMMs (which
        # multi-threaded BLAS runs ~100× slower on a loaded 2-core machine)
        dT_t = sp.csr_matrix((-(t / (A @ y))[:, None] * A).T)
        return t, [np.ascontiguousarray((dT_t @ D.T).T) if w > 0 else np.zeros((0, len(y)))
                   for D, w in zip(self.rates, self.weights, strict=True)]

    def gradient(self, y: npt.ArrayLike) -> np.ndarray:
        """(K,) ∇J(y) (for the centred objective the mean's derivative drops out, Σ r e = 0)."""
        t, jac = self.jacobians(y)
        g = np.zeros(len(np.asarray(y)))
        for e, r, w, Jf in zip(self._residuals(t), self.r, self.weights, jac, strict=True):
            if w > 0:
                g += 2.0 * w * Jf.T @ (r * e)
        return g


def build_speed_objective(rates: Sequence[npt.ArrayLike], curve_lengths: Sequence[npt.ArrayLike],
                          seg_lengths: npt.ArrayLike, settings: SpeedSettings) -> SpeedObjective:
    """Eq. 2 for one pass from the band's rate matrices (see the module note).

    rates: J matrices D_j (m_j, n) [m/s]; curve_lengths: J arrays (m_j,) [m];
    seg_lengths: (n,) pass segment lengths [m]; settings: the speed settings.
    """
    s = np.asarray(seg_lengths, dtype=float)
    t_beg = s / settings.v_nominal_m_s
    D = tuple(np.asarray(d, dtype=float) for d in rates)
    r = tuple(np.asarray(c, dtype=float) / np.sum(c) for c in curve_lengths)
    k = np.array([ri @ (Dj @ t_beg) for Dj, ri in zip(D, r, strict=True)])
    if not k[0] > 0:
        raise SpeedQPError("the pass deposits no paint on its own foot-point curve (j = 0); "
                           "check the standoff, spray axes and band points")
    used = k >= MIN_CURVE_FILM_REL * k.max()
    w = np.where(used, k, 0.0) / np.sum(k[used])
    M, _ = knot_interpolation(np.concatenate([[0.0], np.cumsum(s)]), settings.n_knots)
    return SpeedObjective(rates=D, r=r, seg_lengths=s, v_nominal_m_s=settings.v_nominal_m_s,
                          interp=M, k=k, weights=np.where(used, w / np.where(used, k, 1) ** 2, 0),
                          objective=settings.objective)


def band_nsd(rates: Sequence[np.ndarray], curve_lengths: Sequence[np.ndarray],
             segment_times_s: npt.ArrayLike, weights: npt.ArrayLike) -> float:
    """sqrt(Σ_j w_j (σ_j/μ_j)²) of a time profile (fraction), curves with w_j = 0 left out;
    σ_j, μ_j length-weighted along curve j."""
    t = np.asarray(segment_times_s, dtype=float)
    total = 0.0
    for D, ell, w in zip(rates, curve_lengths, np.asarray(weights, float), strict=True):
        if w > 0:
            r = ell / ell.sum()
            f = D @ t
            mu = r @ f
            total += w * (r @ (f - mu) ** 2) / mu**2
    return math.sqrt(total)
