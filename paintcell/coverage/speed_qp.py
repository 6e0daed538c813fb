"""Per-pass speed optimization: the paper's eq. 2 (Atkar et al. 2004, §3), solved by SQP + OSQP.

A pass is cut into n segments of length s_i between n + 1 samples. A band of J sub-offset curves
around the pass (curve 0 is the pass's own foot-point curve) samples the surface; D_j[e, f] is the
film-thickness rate on segment e of curve j while the TCP is at the centre of pass segment f, so
the film on curve j is D_j T for the segment times T.

Speed representation (paper: "linear variation in speed between the segments for which we
optimize"): K knot speeds at samples spread evenly in arc length, speed linear in arc length
between them, so every sample speed is v_p = v_nom · (M y)_p with y the relative knot speeds. The
TCP moves at constant tangential acceleration between samples (the robot's time law, the
`PassPlan` timing rule), so the time on segment i is t_i = 2 s_i / (v_p[i] + v_p[i+1]): the plan's
times rebuilt from its sample speeds equal the times this module optimizes, exactly.

Objective (eq. 2 squared, the quadratic form the paper names), with length weights r_e = ℓ_e/Σℓ:

    J(y) = Σ_j (w_j / k_j²) · Σ_e r_je · ((D_j T(y))_e − K_je)²

`objective="paper"`: K_j = k_j · 1 with k_j = mean_ℓ(D_j T_beg) fixed from the constant-speed
profile T_beg (paper §3), w_j = k_j / Σk. `objective="centred"` (a variant kept as an option):
K_j is the current mean of D_j T, so only the spread along each curve is penalized.
Equality D_0 T = K_0: its length-weighted mean holds exactly (the speeds are rescaled after every
step); the rest of the vector D_0 T − K_0 is curve 0's term of the objective. A vector equality of
m_0 rows in K < m_0 unknowns is infeasible in general (the paper itself says it makes the profiles
yield "approximately the same average paint deposition").
Bounds: v_min ≤ v ≤ v_max at the knots (and so everywhere between them); optional per-sample
upper bounds (robot-aware re-planning, `paintcell.motion.speed_feedback`); the paper's
conservative linear
acceleration bound in speed form, |v_{p+1} − v_p| ≤ a_max s_p / v_max, which guarantees
|a| = |v_{p+1}² − v_p²| / (2 s_p) ≤ a_max.

T(y) is not linear in y, so the problem is solved by Gauss–Newton SQP from y = 1 (constant
speed): each step is a QP in the knot speeds (OSQP) with a trust region, accepted when the true
objective decreases and every constraint re-measures feasible. The result is never worse on the
band than constant speed (the start point).

The module holds the QP's data (tolerances, `SpeedSettings`, `SubOffsetBand`, `SpeedResult`),
eq. 2 with its Jacobians (`SpeedObjective`), the SQP (`optimize_speed_from_rates`) and the
entry point `optimize_pass_speed` (rates from the deposition model, then the solve).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import osqp
import scipy.sparse as sp

from paintcell.core.errors import PlanError
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate

__all__ = [
    "BOUND_MARGIN", "CONSTRAINT_RTOL", "EQUALITY_PENALTY", "MIN_CURVE_FILM_REL", "OBJECTIVES",
    "SpeedObjective", "SpeedQPError", "SpeedResult", "SpeedSettings", "SubOffsetBand",
    "band_nsd", "build_speed_objective", "knot_interpolation", "optimize_pass_speed",
    "optimize_speed_from_rates",
]

#: Relative tolerance of re-measured constraints (bounds, acceleration) of an accepted profile.
CONSTRAINT_RTOL = 1e-6
#: The QP steps keep this relative margin inside the speed and acceleration bounds, so that the
#: exact rescaling for the average-film equality (a factor 1 + O(step²)) stays feasible.
BOUND_MARGIN = 0.01
#: Curves whose mean film at nominal speed is below this fraction of the largest curve's receive
#: (almost) no paint from this pass: 1/k_j² would blow their weight up, so they leave the objective.
MIN_CURVE_FILM_REL = 1e-3
#: Weight of (mean film on curve 0 / k_0 − 1)² in the SQP's merit function (J is ~1e-4..1e-2).
EQUALITY_PENALTY = 1e4
OBJECTIVES = ("paper", "centred")


class SpeedQPError(PlanError):
    """Speed-optimization inputs or settings are invalid."""


@dataclass(frozen=True)
class SpeedSettings:
    """Settings of the per-pass speed optimization.

    v_nominal_m_s: constant start speed v_nom [m/s]; it sets the target film (T_beg = s / v_nom).
    v_min_m_s / v_max_m_s: lowest / highest TCP speed allowed on the pass [m/s].
    a_max_m_s2: TCP acceleration bound [m/s²], > 0.
    n_knots: optimized knot speeds (≥ 2); speed is linear in arc length between knots.
    objective: "paper" (K_j fixed at constant speed) or "centred" (K_j the current mean).
    max_iter: SQP steps at most. trust_region: largest relative knot-speed change per step.
    eps: OSQP tolerance of each step's QP.
    """

    v_nominal_m_s: float = 0.5
    v_min_m_s: float = 0.25
    v_max_m_s: float = 1.0
    a_max_m_s2: float = 5.0
    n_knots: int = 30
    objective: str = "paper"
    max_iter: int = 12
    trust_region: float = 0.3
    eps: float = 1e-7

    def __post_init__(self) -> None:
        for name in ("v_nominal_m_s", "v_min_m_s", "v_max_m_s", "a_max_m_s2", "eps",
                     "trust_region"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                    or v <= 0:
                raise SpeedQPError(f"SpeedSettings.{name} = {v!r} must be a finite number > 0")
        if not self.v_min_m_s <= self.v_nominal_m_s <= self.v_max_m_s:
            raise SpeedQPError(f"SpeedSettings: need v_min ≤ v_nominal ≤ v_max, got "
                               f"{self.v_min_m_s}, {self.v_nominal_m_s}, {self.v_max_m_s} m/s")
        for name, lo in (("n_knots", 2), ("max_iter", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise SpeedQPError(f"SpeedSettings.{name} = {v!r} must be an int ≥ {lo}")
        if self.objective not in OBJECTIVES:
            raise SpeedQPError(f"SpeedSettings.objective = {self.objective!r}: use one of "
                               f"{', '.join(OBJECTIVES)}")


@dataclass(frozen=True, eq=False)
class SubOffsetBand:
    """Sub-offset curves sampling a band of the surface around one pass (paper Fig. 4).

    points: J arrays (m_j, 3), segment midpoints of sub-offset curve j on the surface [m];
        j = 0 is the foot-point curve of the pass itself.
    normals: J arrays (m_j, 3), unit surface normals at those points (painted side).
    lengths: J arrays (m_j,), segment lengths of curve j [m], > 0.
    """

    points: tuple[np.ndarray, ...]
    normals: tuple[np.ndarray, ...]
    lengths: tuple[np.ndarray, ...]

    def __post_init__(self) -> None:
        if not (len(self.points) == len(self.normals) == len(self.lengths)) or not self.points:
            raise SpeedQPError("SubOffsetBand needs the same number (≥ 1) of points, normals and "
                               f"lengths arrays, got {len(self.points)}, {len(self.normals)}, "
                               f"{len(self.lengths)}")
        pts, nrm, lens = [], [], []
        for j, (p, n, s) in enumerate(zip(self.points, self.normals, self.lengths, strict=True)):
            p, n = np.asarray(p, dtype=float), np.asarray(n, dtype=float)
            s = np.asarray(s, dtype=float).reshape(-1)
            if p.ndim != 2 or p.shape[1] != 3 or len(p) < 1 or n.shape != p.shape:
                raise SpeedQPError(f"sub-offset curve {j}: points {p.shape} and normals {n.shape} "
                                   "must both be (m_j, 3) with m_j ≥ 1")
            if len(s) != len(p):
                raise SpeedQPError(f"sub-offset curve {j}: {len(s)} lengths for {len(p)} points")
            if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n)) and np.all(np.isfinite(s))):
                raise SpeedQPError(f"sub-offset curve {j} contains NaN or inf; rebuild the band")
            if np.any(s <= 0):
                raise SpeedQPError(f"sub-offset curve {j} has segment lengths ≤ 0; drop them")
            pts.append(p)
            nrm.append(n)
            lens.append(s)
        object.__setattr__(self, "points", tuple(pts))
        object.__setattr__(self, "normals", tuple(nrm))
        object.__setattr__(self, "lengths", tuple(lens))

    @property
    def n_curves(self) -> int:
        """J, the number of sub-offset curves."""
        return len(self.points)


@dataclass(frozen=True, eq=False)
class SpeedResult:
    """Speed profile of one pass.

    sample_speeds_m_s: (n + 1,) TCP speed at the pass samples [m/s] (what the plan stores).
    segment_times_s: (n,) time on segment i, 2 s_i / (v_i + v_{i+1}) [s].
    speeds_m_s: (n,) mean speed s_i / t_i of each segment [m/s].
    nsd_constant_pct / nsd_optimized_pct: band σ/μ at constant speed and at the returned profile
        [%]: sqrt(Σ_j w_j (σ_j/μ_j)²), each curve's σ and μ re-measured (length weighted).
    curve_weights: (J,) w_j (0 for curves left out). knot_indices: (K,) samples carrying knots.
    objective_constant / objective_optimized: J(y) of eq. 2 at y = 1 and at the result.
    status: "optimal", "iteration limit" (a feasible improvement, not converged) or
        "constant: <why>". iterations: accepted SQP steps. solve_time_s: wall time [s].
    """

    sample_speeds_m_s: np.ndarray
    segment_times_s: np.ndarray
    nsd_constant_pct: float
    nsd_optimized_pct: float
    curve_weights: np.ndarray
    knot_indices: np.ndarray
    objective_constant: float
    objective_optimized: float
    status: str
    iterations: int
    solve_time_s: float

    @property
    def speeds_m_s(self) -> np.ndarray:
        """(n,) mean speed of each segment [m/s]."""
        v = self.sample_speeds_m_s
        return 0.5 * (v[1:] + v[:-1])

    @property
    def optimized(self) -> bool:
        """True when the returned profile is not the constant start profile."""
        return not self.status.startswith("constant")


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


def optimize_pass_speed(app: Applicator, centers: npt.ArrayLike, spray_axes: npt.ArrayLike,
                        travel_dirs: npt.ArrayLike, seg_lengths: npt.ArrayLike,
                        band: SubOffsetBand, settings: SpeedSettings,
                        v_upper_m_s: npt.ArrayLike | None = None) -> SpeedResult:
    """Optimize the speed profile of one pass (paper §3, eq. 2).

    app: the deposition model; centers: (n, 3) TCP positions at the middle of the n pass
    segments [m]; spray_axes: (n, 3) unit spray directions there; travel_dirs: (n, 3) unit travel
    directions; seg_lengths: (n,) [m]; band: the sub-offset curves (curve 0 = the pass's foot
    curve), same frame; settings: SpeedSettings; v_upper_m_s: optional (n + 1,) per-sample speed
    upper bounds [m/s].
    """
    c = np.asarray(centers, dtype=float)
    a = np.asarray(spray_axes, dtype=float)
    d = np.asarray(travel_dirs, dtype=float)
    s = np.asarray(seg_lengths, dtype=float).reshape(-1)
    n = len(s)
    for name, arr in (("centers", c), ("spray_axes", a), ("travel_dirs", d)):
        if arr.shape != (n, 3) or not np.all(np.isfinite(arr)):
            raise SpeedQPError(f"{name} has shape {arr.shape}, expected finite ({n}, 3) to match "
                               f"{n} seg_lengths")
    rate = deposition_rate(app, c, a, d, np.concatenate(band.points),
                           np.concatenate(band.normals))
    splits = np.cumsum([len(p) for p in band.points])[:-1]
    rates = [r.T for r in np.split(np.asarray(rate), splits, axis=1)]
    return optimize_speed_from_rates(rates, band.lengths, s, settings, v_upper_m_s)
