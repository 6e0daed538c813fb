"""The SQP solve of eq. 2 for one pass (`optimize_speed_from_rates`): Gauss–Newton steps, each an
OSQP problem in the knot speeds under the speed [m/s] and acceleration [m/s²] bounds with a trust
region, then the projection onto the average-film equality."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import osqp
import scipy.sparse as sp

from paintcell.coverage.speed_qp_objective import (
    SpeedObjective,
    band_nsd,
    build_speed_objective,
    knot_interpolation,
)
from paintcell.coverage.speed_qp_settings import (
    BOUND_MARGIN,
    CONSTRAINT_RTOL,
    EQUALITY_PENALTY,
    SpeedQPError,
    SpeedResult,
    SpeedSettings,
)


def optimize_speed_from_rates(rates: Sequence[npt.ArrayLike],
                              curve_lengths: Sequence[npt.ArrayLike], seg_lengths: npt.ArrayLike,
                              settings: SpeedSettings,
                              v_upper_m_s: npt.ArrayLike | None = None) -> SpeedResult:
    """Solve eq. 2 for one pass given the band's rate matrices.

    rates: J matrices D_j (m_j, n) [m/s]; curve_lengths: J arrays (m_j,) [m];
    seg_lengths: (n,) pass segment lengths [m], > 0; settings: SpeedSettings;
    v_upper_m_s: optional (n + 1,) per-sample speed upper bounds [m/s] (e.g. what the robot's
        time law can follow); where one is below the start profile, the first accepted step is
        the best feasible profile even if the band σ/μ rises.
    """
    t0 = time.perf_counter()
    s = np.asarray(seg_lengths, dtype=float).reshape(-1)
    n = len(s)
    if n < 2 or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise SpeedQPError(f"seg_lengths must be ≥ 2 finite lengths > 0 [m], got {n} values")
    if len(rates) != len(curve_lengths) or not rates:
        raise SpeedQPError(f"{len(rates)} rate matrices for {len(curve_lengths)} curves; "
                           "give one (m_j, n) matrix per sub-offset curve")
    ells = [np.asarray(c, dtype=float).reshape(-1) for c in curve_lengths]
    for j, Dj in enumerate(rates):
        Dj = np.asarray(Dj)
        if Dj.shape != (len(ells[j]), n) or not np.all(np.isfinite(Dj)) or np.any(Dj < 0):
            raise SpeedQPError(f"rate matrix {j} has shape {Dj.shape}, expected "
                               f"({len(ells[j])}, {n}) with finite rates ≥ 0 [m/s]")
    obj = build_speed_objective(rates, ells, s, settings)
    M = obj.interp
    K = M.shape[1]
    vn = settings.v_nominal_m_s
    z_lo, z_hi = settings.v_min_m_s / vn, settings.v_max_m_s / vn
    cap = np.full(n + 1, z_hi)
    if v_upper_m_s is not None:
        ub = np.asarray(v_upper_m_s, dtype=float).reshape(-1)
        if len(ub) != n + 1 or not np.all(ub > 0):
            raise SpeedQPError(f"v_upper_m_s needs {n + 1} speeds > 0 [m/s] (one per sample)")
        cap = np.minimum(cap, ub / vn)
    floor = np.minimum(z_lo, 0.9 * cap)
    dv_max = settings.a_max_m_s2 * s / (settings.v_max_m_s * vn)       # |Δy| per segment
    Dm = M[1:] - M[:-1]
    w_used = np.flatnonzero(obj.weights > 0)

    def violation(y: np.ndarray) -> float:
        v = M @ y
        return float(max(np.max(v / cap - 1), np.max(floor / v - 1),
                         np.max(np.abs(Dm @ y) / dv_max - 1), 0.0))

    def feasible(y: np.ndarray) -> bool:
        return violation(y) <= CONSTRAINT_RTOL

    def mean0(y: np.ndarray) -> float:
        return float(obj.r[0] @ (obj.rates[0] @ obj.segment_times(y)))

    def rescale(y: np.ndarray) -> np.ndarray:
        """Meet the average-film equality exactly by scaling all knot speeds (film ∝ 1/speed)
        when that keeps every bound; else keep y (its QP met the equality to first order, and
        the SQP steps drive the remainder to zero)."""
        c = mean0(y) / obj.k[0]
        return y * c if feasible(y * c) else y

    def result(y: np.ndarray, status: str, iters: int) -> SpeedResult:
        t = obj.segment_times(y)
        w = obj.weights * obj.k**2
        return SpeedResult(sample_speeds_m_s=vn * (M @ y), segment_times_s=t,
                           nsd_constant_pct=100 * band_nsd(obj.rates, ells, s / vn, w),
                           nsd_optimized_pct=100 * band_nsd(obj.rates, ells, t, w),
                           curve_weights=w, knot_indices=knot_interpolation(
                               np.concatenate([[0.0], np.cumsum(s)]), settings.n_knots)[1],
                           objective_constant=obj.value(np.ones(K)),
                           objective_optimized=obj.value(y), status=status, iterations=iters,
                           solve_time_s=time.perf_counter() - t0)

    y = np.ones(K)
    start_ok = feasible(y)
    if z_hi - z_lo <= 1e-9 and start_ok:
        return result(y, "constant: speed window closed (v_min = v_max)", 0)
    def merit(y: np.ndarray) -> float:
        # eq. 2's objective plus a stiff penalty on the average-film equality, so that a step
        # is not accepted for lowering J by letting the (second-order) equality error grow
        return obj.value(y) + EQUALITY_PENALTY * (mean0(y) / obj.k[0] - 1.0) ** 2

    J = merit(y) if start_ok else math.inf
    # a start that breaks the speed caps is first moved onto them (restoration steps, no trust
    # region, accepted while the violation shrinks); then the usual descent
    tr = settings.trust_region if start_ok else 10.0
    lo_m, hi_m = floor * (1 + BOUND_MARGIN), cap * (1 - BOUND_MARGIN)
    accepted, converged = 0, False
    for _ in range(settings.max_iter):
        t, jac = obj.jacobians(y)
        res = obj._residuals(t)
        P = np.zeros((K, K))
        q = np.zeros(K)
        for j in w_used.tolist():
            Jf = jac[j]
            if obj.objective == "centred":
                Jf = Jf - obj.r[j] @ Jf
            wr = obj.weights[j] * obj.r[j]
            P += 2.0 * Jf.T @ (wr[:, None] * Jf)
            q += 2.0 * Jf.T @ (wr * res[j])
        # linearized average-film equality, relative to k_0 (O(1): OSQP's tolerances are absolute)
        eq = (obj.r[0] @ jac[0]) / obj.k[0]
        e0 = 1.0 - (obj.r[0] @ (obj.rates[0] @ t)) / obj.k[0]
        dm = dv_max * (1 - BOUND_MARGIN)
        A = sp.vstack([sp.csc_matrix(M), sp.csc_matrix(Dm), sp.identity(K, format="csc"),
                       sp.csc_matrix(eq[None, :])], format="csc")
        lo = np.concatenate([lo_m - M @ y, -dm - Dm @ y, np.full(K, -tr), [e0]])
        hi = np.concatenate([hi_m - M @ y, dm - Dm @ y, np.full(K, tr), [e0]])
        lo = np.minimum(lo, hi)
        solver = osqp.OSQP()
        solver.setup(sp.triu(sp.csc_matrix(P + 1e-12 * np.eye(K)), format="csc"), q, A, lo, hi,
                     verbose=False, eps_abs=settings.eps, eps_rel=settings.eps, max_iter=20000,
                     polishing=True)
        sol = solver.solve(raise_error=False)
        if sol.info.status_val not in (1, 2) or sol.x is None or not np.all(np.isfinite(sol.x)):
            tr *= 0.5
            if tr < 1e-4:
                break
            continue
        cand = rescale(y + np.asarray(sol.x))
        J_new = merit(cand) if feasible(cand) else math.inf
        if not math.isfinite(J) and not math.isfinite(J_new):
            if violation(cand) < violation(y) * (1 - 1e-3):
                y = cand                              # restoration: closer to the caps
                continue
            break
        if not math.isfinite(J):
            tr = settings.trust_region               # feasible now: descend from here
            y, J, accepted = cand, J_new, accepted + 1
            continue
        if J_new < J:
            step = float(np.max(np.abs(cand - y)))
            y, J, accepted = cand, J_new, accepted + 1
            if step < 1e-6 or (math.isfinite(J) and J_new > (1 - 1e-9) * J and step < 1e-3):
                converged = True
                break
        else:
            tr *= 0.5
            if tr < 1e-4:
                converged = True
                break
    if not math.isfinite(J):
        return result(np.ones(K), "constant: no profile meets the speed upper bounds", accepted)
    y = _project_equality(y, obj, M, Dm, dv_max, lo_m, hi_m, feasible, mean0, settings.eps)
    if accepted == 0:
        return result(y, "constant: no step improved eq. 2 on this band", 0)
    return result(y, "optimal" if converged else "iteration limit", accepted)


def _project_equality(y: np.ndarray, obj: SpeedObjective, M: np.ndarray, Dm: np.ndarray,
                      dv_max: np.ndarray, lo_m: np.ndarray, hi_m: np.ndarray, feasible: Any,
                      mean0: Any, eps: float) -> np.ndarray:
    """Newton projection onto the average-film equality: the smallest knot change meeting the
    linearized equality within the bounds, repeated while the residual shrinks (≤ 8 times)."""
    K = len(y)
    for _ in range(8):
        err = abs(mean0(y) / obj.k[0] - 1)
        if err < 1e-12:
            break
        _, jac = obj.jacobians(y)
        eq = (obj.r[0] @ jac[0]) / obj.k[0]
        e0 = 1.0 - mean0(y) / obj.k[0]
        dm = dv_max * (1 - BOUND_MARGIN / 2)
        A = sp.vstack([sp.csc_matrix(M), sp.csc_matrix(Dm), sp.csc_matrix(eq[None, :])],
                      format="csc")
        lo = np.concatenate([np.minimum(lo_m - M @ y, 0), np.minimum(-dm - Dm @ y, 0), [e0]])
        hi = np.concatenate([np.maximum(hi_m - M @ y, 0), np.maximum(dm - Dm @ y, 0), [e0]])
        solver = osqp.OSQP()
        solver.setup(sp.identity(K, format="csc"), np.zeros(K), A, lo, hi, verbose=False,
                     eps_abs=min(eps, 1e-9), eps_rel=min(eps, 1e-9), max_iter=20000,
                     polishing=True)
        sol = solver.solve(raise_error=False)
        if sol.x is None or not np.all(np.isfinite(sol.x)):
            break
        cand = y + np.asarray(sol.x)
        if not feasible(cand) or abs(mean0(cand) / obj.k[0] - 1) >= err:
            break
        y = cand
    return y
