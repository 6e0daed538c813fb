"""Per-pass speed optimization: the paper's eq. 2 (Atkar et al. 2004, §3) as a QP solved by OSQP.

A pass is cut into n segments of length s_i; the TCP sits at each segment centre for a time t_i
(speed v_i = s_i / t_i). A band of J sub-offset curves around the pass (curve 0 is the pass's own
foot-point curve) samples the surface; D_j[e, f] is the film-thickness rate on segment e of curve j
while the TCP is at the centre of pass segment f, so the film on curve j is D_j T.

Objective (the paper's weighted normalized deviation, squared so that it is the QP the paper calls
it), with segment-length weights ℓ_e / Σℓ on every curve (the continuous σ along the curve):

    J(T) = Σ_j (w_j / k_j²) · Σ_e (ℓ_e / Σℓ) · ((D_j T)_e − mean_ℓ(D_j T))²

k_j = mean_ℓ(D_j T_beg) and w_j = k_j / Σ k are fixed at the constant nominal speed T_beg.
Constraints: mean_ℓ(D_0 T) = k_0 (the average film along the pass, one scalar);
s_i / v_max ≤ t_i ≤ s_i / v_min; the paper's linearized acceleration bound
|s_{i+1} t_i − s_i t_{i+1}| ≤ a_max s_{i+1} s_i² / v_max³.

The paper optimizes over a sub-sample of segments with linear interpolation between them. Here the
knots carry the slowness u = 1/v, interpolated linearly in arc length to the fine segments, so
T = diag(s) · L · u_knots stays linear in the decision variables. The variable OSQP sees is
z = u_knots / u_nominal (1 at constant speed): every term is O(1), whatever the units of D.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import osqp
import scipy.sparse as sp

from planning.applicator import Applicator
from planning.deposition import deposition_rate
from planning.errors import PlanError

#: Relative tolerance of the re-measured constraints of an accepted solution: the equality
#: |mean(D_0 T) / k_0 − 1| and the acceleration rows as a fraction of their bound. OSQP's polished
#: solutions meet them to ~1e-10; ADMM-only solutions at eps 1e-8 to ~1e-7.
CONSTRAINT_RTOL = 1e-6

#: Curves whose mean film at nominal speed is below this fraction of the largest curve's receive
#: (almost) no paint from this pass: 1/k_j² would blow their weight up, so they leave the objective.
MIN_CURVE_FILM_REL = 1e-3

class SpeedQPError(PlanError):
    """Speed-optimization inputs or settings are invalid."""


@dataclass(frozen=True)
class SpeedSettings:
    """Settings of the per-pass speed QP.

    v_nominal_m_s: constant start speed v_nom [m/s]; it sets the target film (T_beg = s / v_nom).
    v_min_m_s: lowest TCP speed allowed on the pass [m/s], > 0.
    v_max_m_s: highest TCP speed allowed on the pass [m/s], ≥ v_min.
    a_max_m_s2: TCP acceleration bound of the paper's linearized constraint [m/s²], > 0.
    n_knots: optimized sub-sample of segments (≥ 2); slowness 1/v is linear in arc length between
        knots. The paper's trick: fine segments for the objective, few variables for the solver.
    eps: OSQP absolute and relative tolerance (the problem is scaled to O(1)).
    max_iter: OSQP iteration limit.
    """

    v_nominal_m_s: float = 0.5
    v_min_m_s: float = 0.25
    v_max_m_s: float = 1.0
    a_max_m_s2: float = 5.0
    n_knots: int = 30
    eps: float = 1e-8
    max_iter: int = 20000

    def __post_init__(self) -> None:
        for name in ("v_nominal_m_s", "v_min_m_s", "v_max_m_s", "a_max_m_s2", "eps"):
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
                raise SpeedQPError(f"SpeedSettings.{name} = {v!r} must be a finite number > 0")
        if self.v_min_m_s > self.v_max_m_s:
            raise SpeedQPError(f"SpeedSettings: v_min_m_s = {self.v_min_m_s} > v_max_m_s = "
                               f"{self.v_max_m_s}; choose v_min ≤ v_nominal ≤ v_max")
        if not self.v_min_m_s <= self.v_nominal_m_s <= self.v_max_m_s:
            raise SpeedQPError(f"SpeedSettings: v_nominal_m_s = {self.v_nominal_m_s} lies outside "
                               f"[v_min, v_max] = [{self.v_min_m_s}, {self.v_max_m_s}]; "
                               "choose v_min ≤ v_nominal ≤ v_max")
        if not isinstance(self.n_knots, int) or self.n_knots < 2:
            raise SpeedQPError(f"SpeedSettings.n_knots = {self.n_knots!r} must be an int ≥ 2")
        if not isinstance(self.max_iter, int) or self.max_iter < 1:
            raise SpeedQPError(f"SpeedSettings.max_iter = {self.max_iter!r} must be an int ≥ 1")


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
            p = np.asarray(p, dtype=float)
            n = np.asarray(n, dtype=float)
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
    """Optimized (or constant, on fallback) speed profile of one pass.

    segment_times_s: (n,) time t_i the TCP spends in pass segment i [s].
    speeds_m_s: (n,) TCP speed v_i = s_i / t_i in segment i [m/s].
    nsd_constant_pct / nsd_optimized_pct: band σ/μ at constant nominal speed and at the returned
        profile [%]: sqrt(Σ_j w_j (σ_j/μ_j)²), the square root of the QP objective with each curve's
        mean re-measured (w_j fixed at constant speed, length-weighted σ_j and μ_j).
    nsd_constant_per_curve_pct / nsd_optimized_per_curve_pct: (J,) σ_j/μ_j of each curve [%]
        (nan for curves that get almost no paint from this pass and so leave the objective).
    curve_weights: (J,) w_j (0 for curves left out).
    status: "optimal", "optimal (unpolished ADMM solution)" when OSQP's polishing failed but the
        ADMM solution re-measured feasible and better, or "constant: <why>" on fallback.
    solve_time_s: wall time of the whole call (matrices, OSQP, re-measurement) [s].
    knot_indices: (K,) indices of the fine segments that carry the optimized knots.
    osqp_iterations: ADMM iterations (0 when OSQP did not run).
    """

    segment_times_s: np.ndarray
    speeds_m_s: np.ndarray
    nsd_constant_pct: float
    nsd_optimized_pct: float
    nsd_constant_per_curve_pct: np.ndarray
    nsd_optimized_per_curve_pct: np.ndarray
    curve_weights: np.ndarray
    status: str
    solve_time_s: float
    knot_indices: np.ndarray
    osqp_iterations: int = 0

    @property
    def optimized(self) -> bool:
        """True when the returned profile is the QP's, not the constant fallback."""
        return self.status.startswith("optimal")

    @property
    def seg_lengths_m(self) -> np.ndarray:
        """(n,) pass segment lengths s_i = v_i t_i [m]."""
        return self.speeds_m_s * self.segment_times_s


@dataclass(frozen=True, eq=False)
class SpeedObjective:
    """The QP in knot variables z = u_knots / u_nominal: J(z) = ½ zᵀ P z, A z ∈ [l, u].

    P: (K, K) dense Hessian of the band objective (OSQP's ½ convention: J = ½ zᵀPz).
    interp: (n, K) L, fine-segment relative slowness = L z (rows are convex combinations).
    t_beg_s: (n,) constant-speed segment times s_i / v_nominal [s].
    eq_row: (K,) the average-film equality eq_row · z = 1.
    curve_mats: J matrices G_j = D_j diag(T_beg) L, (m_j, K): the film on curve j is G_j z [m].
    curve_lengths: J arrays (m_j,) segment lengths [m].
    k: (J,) mean film of each curve at constant speed [m].
    weights: (J,) w_j (0 for curves left out).
    knot_indices: (K,) fine segments carrying the knots.
    """

    P: np.ndarray
    interp: np.ndarray
    t_beg_s: np.ndarray
    eq_row: np.ndarray
    curve_mats: tuple[np.ndarray, ...]
    curve_lengths: tuple[np.ndarray, ...]
    k: np.ndarray
    weights: np.ndarray
    knot_indices: np.ndarray

    def value(self, z: npt.ArrayLike) -> float:
        """J(z) = ½ zᵀ P z, dimensionless (σ²/μ² with means fixed at constant speed)."""
        z = np.asarray(z, dtype=float)
        return float(0.5 * z @ self.P @ z)

    def gradient(self, z: npt.ArrayLike) -> np.ndarray:
        """(K,) ∇J(z) = P z."""
        return self.P @ np.asarray(z, dtype=float)

    def segment_times(self, z: npt.ArrayLike) -> np.ndarray:
        """(n,) segment times T = T_beg ⊙ (L z) [s]."""
        return self.t_beg_s * (self.interp @ np.asarray(z, dtype=float))


def knot_interpolation(seg_lengths: npt.ArrayLike, n_knots: int) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation in arc length from knot segments to all segments.

    seg_lengths: (n,) pass segment lengths [m], > 0.
    n_knots: requested knots K (≥ 2); min(K, n) distinct segments are used, first and last
        included, spread evenly in arc length.
    Returns (L (n, K), knot_indices (K,)); L[i] holds the weights of segment i's centre on the two
    knots around it (a convex combination; L[knot_indices] = I).
    """
    s = np.asarray(seg_lengths, dtype=float)
    centres = np.cumsum(s) - 0.5 * s
    n = len(s)
    if n_knots >= n:
        return np.eye(n), np.arange(n)
    targets = np.linspace(centres[0], centres[-1], n_knots)
    idx = np.unique(np.clip(np.searchsorted(centres, targets), 0, n - 1))
    idx[0], idx[-1] = 0, n - 1
    idx = np.unique(idx)
    xk = centres[idx]
    k = len(idx)
    hi = np.clip(np.searchsorted(xk, centres, side="right"), 1, k - 1)
    lo = hi - 1
    frac = np.clip((centres - xk[lo]) / (xk[hi] - xk[lo]), 0.0, 1.0)
    L = np.zeros((n, k))
    rows = np.arange(n)
    L[rows, lo] = 1.0 - frac
    L[rows, hi] += frac
    return L, idx


def _curve_nsd(film: np.ndarray, lengths: np.ndarray) -> tuple[float, float]:
    """Length-weighted (mean [m], σ/μ) of a film along one curve."""
    w = lengths / lengths.sum()
    mu = float(w @ film)
    if mu <= 0:
        return mu, float("inf")
    return mu, float(np.sqrt(w @ (film - mu) ** 2) / mu)


def band_nsd(rates: Sequence[np.ndarray], curve_lengths: Sequence[np.ndarray],
             segment_times_s: npt.ArrayLike, weights: npt.ArrayLike) -> tuple[float, np.ndarray]:
    """Re-measured band uniformity of a time profile.

    rates: J matrices D_j (m_j, n) film-thickness rate [m/s].
    curve_lengths: J arrays (m_j,) segment lengths [m].
    segment_times_s: (n,) times per pass segment [s].
    weights: (J,) w_j; curves with w_j = 0 are reported as nan and left out.
    Returns (sqrt(Σ_j w_j (σ_j/μ_j)²) as a fraction, (J,) per-curve σ_j/μ_j as fractions).
    """
    t = np.asarray(segment_times_s, dtype=float)
    w = np.asarray(weights, dtype=float)
    per = np.full(len(rates), np.nan)
    for j, (D, ell) in enumerate(zip(rates, curve_lengths, strict=True)):
        if w[j] > 0:
            per[j] = _curve_nsd(D @ t, ell)[1]
    used = w > 0
    return float(np.sqrt(np.sum(w[used] * per[used] ** 2))), per


def build_speed_objective(rates: Sequence[npt.ArrayLike], curve_lengths: Sequence[npt.ArrayLike],
                          seg_lengths: npt.ArrayLike, settings: SpeedSettings) -> SpeedObjective:
    """Assemble the QP of eq. 2 in knot variables from the band's rate matrices.

    rates: J matrices D_j (m_j, n): film-thickness rate [m/s] on segment e of curve j while the
        TCP is at the centre of pass segment f (curve 0 = the pass's foot-point curve).
    curve_lengths: J arrays (m_j,) segment lengths of the curves [m].
    seg_lengths: (n,) pass segment lengths [m].
    settings: speed limits, a_max and knot count.
    """
    s = np.asarray(seg_lengths, dtype=float)
    t_beg = s / settings.v_nominal_m_s
    L, knots = knot_interpolation(s, settings.n_knots)
    # G_j = D_j diag(T_beg) L through a sparse L (≤ 2 entries a row): O(m_j n) work, and no small
    # dense GEMMs, which multi-threaded BLAS runs 100× slower on a loaded 2-core machine.
    TL_t = sp.csr_matrix((t_beg[:, None] * L).T)
    mats = []
    k = np.zeros(len(rates))
    for j, D in enumerate(rates):
        G = np.ascontiguousarray((TL_t @ np.asarray(D, dtype=float).T).T)
        mats.append(G)
        ell = np.asarray(curve_lengths[j], dtype=float)
        k[j] = (ell @ G.sum(axis=1)) / ell.sum()
    if not k[0] > 0:
        raise SpeedQPError("the pass deposits no paint on its own foot-point curve (j = 0); "
                           "check the standoff, spray axes and band points")
    used = k >= MIN_CURVE_FILM_REL * k.max()
    w = np.where(used, k, 0.0)
    w /= w.sum()
    blocks = []
    for j in np.flatnonzero(used).tolist():
        ell = np.asarray(curve_lengths[j], dtype=float)
        r = ell / ell.sum()
        C = mats[j] - r @ mats[j]           # (I − 1 rᵀ) G_j: centred film along curve j
        blocks.append(np.sqrt(r)[:, None] * C * (math.sqrt(w[j]) / k[j]))
    B = np.concatenate(blocks)
    P = 2.0 * np.einsum("ik,il->kl", B, B)  # J = ½ zᵀPz = Σ ‖B_j z‖²
    ell0 = np.asarray(curve_lengths[0], dtype=float)
    eq_row = (ell0 @ mats[0]) / (ell0.sum() * k[0])
    return SpeedObjective(P=0.5 * (P + P.T), interp=L, t_beg_s=t_beg, eq_row=eq_row,
                          curve_mats=tuple(mats),
                          curve_lengths=tuple(np.asarray(c, dtype=float) for c in curve_lengths),
                          k=k, weights=w, knot_indices=knots)


def accel_residuals(segment_times_s: npt.ArrayLike, seg_lengths: npt.ArrayLike,
                    settings: SpeedSettings) -> np.ndarray:
    """(n−1,) paper's linearized acceleration rows as a fraction of their bound.

    Row i: (s_{i+1} t_i − s_i t_{i+1}) / (a_max s_{i+1} s_i² / v_max³); feasible when |row| ≤ 1.
    """
    t = np.asarray(segment_times_s, dtype=float)
    s = np.asarray(seg_lengths, dtype=float)
    bound = settings.a_max_m_s2 * s[1:] * s[:-1] ** 2 / settings.v_max_m_s ** 3
    return (s[1:] * t[:-1] - s[:-1] * t[1:]) / bound


def _constraint_violation(rates: Sequence[np.ndarray], curve_lengths: Sequence[np.ndarray],
                          k0: float, t: np.ndarray, s: np.ndarray, settings: SpeedSettings) -> str:
    """Empty string when T meets every constraint of eq. 2 (within CONSTRAINT_RTOL), else why."""
    lo, hi = s / settings.v_max_m_s, s / settings.v_min_m_s
    if np.any(t < lo * (1 - CONSTRAINT_RTOL)) or np.any(t > hi * (1 + CONSTRAINT_RTOL)):
        return "speed bounds violated"
    acc = np.max(np.abs(accel_residuals(t, s, settings)))
    if acc > 1 + CONSTRAINT_RTOL:
        return f"acceleration bound violated ({acc:.3g} × bound)"
    ell0 = curve_lengths[0]
    eq = abs((ell0 @ (rates[0] @ t)) / (ell0.sum() * k0) - 1)
    if eq > CONSTRAINT_RTOL:
        return f"average-film equality off by {eq:.2g}"
    return ""


def _repair(x: np.ndarray, eq_row: np.ndarray, dL: np.ndarray, acc_b: np.ndarray,
            z_lo: float, z_hi: float) -> np.ndarray:
    """Move an ADMM solution (feasible only to OSQP's eps) onto the constraints of eq. 2.

    z = 1 (constant speed) meets every constraint with the acceleration rows slack (dL·1 = 0,
    eq_row·1 = 1). So: clip to the box; shift along 1 to meet the equality exactly (the shift
    leaves the acceleration rows unchanged and leaves the box by at most that shift, ~eps); then
    pull toward 1 just enough that every acceleration row meets its bound (the convex combination
    keeps the equality and the box).
    """
    z = np.clip(x, z_lo, z_hi)
    z = z + (1.0 - eq_row @ z)
    rows = np.abs(dL @ (z - 1.0))
    over = rows > acc_b
    if np.any(over):
        lam = float(np.min(acc_b[over] / rows[over]))
        z = 1.0 + lam * (z - 1.0)
    return z


def optimize_speed_from_rates(rates: Sequence[npt.ArrayLike],
                              curve_lengths: Sequence[npt.ArrayLike],
                              seg_lengths: npt.ArrayLike,
                              settings: SpeedSettings) -> SpeedResult:
    """Solve eq. 2 for one pass given the band's rate matrices (the solver half of the problem).

    rates: J matrices D_j (m_j, n) film-thickness rate [m/s] on curve j's segments per TCP
        position at the centre of pass segment f; curve 0 is the pass's foot-point curve.
    curve_lengths: J arrays (m_j,) segment lengths of the curves [m].
    seg_lengths: (n,) pass segment lengths [m], > 0.
    settings: SpeedSettings.
    Returns a SpeedResult; never worse (band σ/μ) than constant nominal speed.
    """
    t0 = time.perf_counter()
    s = np.asarray(seg_lengths, dtype=float).reshape(-1)
    n = len(s)
    if n < 2 or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise SpeedQPError(f"seg_lengths must be ≥ 2 finite lengths > 0 [m], got {n} values "
                           f"(min {s.min() if n else float('nan')})")
    if len(rates) != len(curve_lengths) or not rates:
        raise SpeedQPError(f"{len(rates)} rate matrices for {len(curve_lengths)} curves; "
                           "give one (m_j, n) matrix per sub-offset curve")
    D = [np.asarray(r, dtype=float) for r in rates]
    for j, Dj in enumerate(D):
        m = len(np.asarray(curve_lengths[j]).reshape(-1))
        if Dj.shape != (m, n) or not np.all(np.isfinite(Dj)) or np.any(Dj < 0):
            raise SpeedQPError(f"rate matrix {j} has shape {Dj.shape}, expected ({m}, {n}) with "
                               "finite rates ≥ 0 [m/s]")
    ells = [np.asarray(c, dtype=float).reshape(-1) for c in curve_lengths]

    obj = build_speed_objective(D, ells, s, settings)
    t_const = obj.t_beg_s
    nsd_c, per_c = band_nsd(D, ells, t_const, obj.weights)

    def result(t: np.ndarray, status: str, iters: int = 0) -> SpeedResult:
        if not status.startswith("optimal"):
            t = t_const
        nsd_o, per_o = band_nsd(D, ells, t, obj.weights)
        return SpeedResult(segment_times_s=t.copy(), speeds_m_s=s / t,
                           nsd_constant_pct=100 * nsd_c, nsd_optimized_pct=100 * nsd_o,
                           nsd_constant_per_curve_pct=100 * per_c,
                           nsd_optimized_per_curve_pct=100 * per_o,
                           curve_weights=obj.weights, status=status,
                           solve_time_s=time.perf_counter() - t0,
                           knot_indices=obj.knot_indices, osqp_iterations=iters)

    z_lo = settings.v_nominal_m_s / settings.v_max_m_s
    z_hi = settings.v_nominal_m_s / settings.v_min_m_s
    if z_hi - z_lo <= 1e-9:
        return result(t_const, "constant: speed window closed (v_min = v_max)")

    # A z ∈ [l, u]: the equality, the knot bounds (which bound every fine segment, L being a
    # convex interpolation), the acceleration rows through L divided by s_i s_{i+1} u_nominal.
    K = obj.P.shape[0]
    L = obj.interp
    dL = L[:-1] - L[1:]
    acc_b = settings.a_max_m_s2 * s[:-1] * settings.v_nominal_m_s / settings.v_max_m_s ** 3
    A = sp.vstack([sp.csc_matrix(obj.eq_row[None, :]), sp.identity(K, format="csc"),
                   sp.csc_matrix(dL)], format="csc")
    lo = np.concatenate([[1.0], np.full(K, z_lo), -acc_b])
    hi = np.concatenate([[1.0], np.full(K, z_hi), acc_b])
    P = sp.triu(sp.csc_matrix(obj.P), format="csc")
    solver = osqp.OSQP()
    solver.setup(P, np.zeros(K), A, lo, hi, verbose=False, eps_abs=settings.eps,
                 eps_rel=settings.eps, max_iter=settings.max_iter, polishing=True,
                 polish_refine_iter=10, scaling=10)
    solver.warm_start(x=np.ones(K))
    res = solver.solve(raise_error=False)
    iters = int(res.info.iter)
    if res.info.status_val not in (1, 2) or res.x is None or not np.all(np.isfinite(res.x)):
        return result(t_const, f"constant: OSQP {res.info.status}", iters)
    z = _repair(np.asarray(res.x, dtype=float), obj.eq_row, dL, acc_b, z_lo, z_hi)
    t = obj.segment_times(z)
    why = _constraint_violation(D, ells, obj.k[0], t, s, settings)
    if why:
        return result(t_const, f"constant: {why} after OSQP {res.info.status}", iters)
    nsd_o, _ = band_nsd(D, ells, t, obj.weights)
    if not nsd_o < nsd_c:
        return result(t_const, "constant: optimized profile no better than constant speed", iters)
    # Polishing may fail silently (status_polish = -1) and leave the ADMM solution; it is kept
    # because it re-measured feasible and better, and the status says so.
    polished = res.info.status_polish == 1
    return result(t, "optimal" if polished else "optimal (unpolished ADMM solution)", iters)


def optimize_pass_speed(app: Applicator, centers: npt.ArrayLike, spray_axes: npt.ArrayLike,
                        travel_dirs: npt.ArrayLike, seg_lengths: npt.ArrayLike,
                        band: SubOffsetBand, settings: SpeedSettings) -> SpeedResult:
    """Optimize the speed profile of one pass (paper §3, eq. 2) with OSQP.

    app: the deposition model.
    centers: (n, 3) TCP positions at the middle of the n pass segments [m] (part frame).
    spray_axes: (n, 3) unit spray directions at those positions.
    travel_dirs: (n, 3) unit travel directions, orthogonal to the spray axes.
    seg_lengths: (n,) pass segment lengths [m], > 0.
    band: the sub-offset curves (curve 0 = the pass's foot-point curve), same frame as centers.
    settings: speed limits, a_max and knot count.
    Returns the SpeedResult; constant nominal speed (and a status saying why) whenever the QP
    fails or does not improve the band σ/μ.
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
    # One dense call for the whole band, split per curve: D_j = rate.T, (m_j, n).
    rate = deposition_rate(app, c, a, d, np.concatenate(band.points),
                           np.concatenate(band.normals))
    splits = np.cumsum([len(p) for p in band.points])[:-1]
    rates = [r.T for r in np.split(np.asarray(rate), splits, axis=1)]
    return optimize_speed_from_rates(rates, band.lengths, s, settings)


def sample_pass_profile(result: SpeedResult, arc_m: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Speed and time of a SpeedResult at arbitrary arc-length positions along the pass.

    result: the pass's SpeedResult.
    arc_m: (M,) arc length from the start of the first segment [m], within [0, Σ s_i].
    Returns (speeds (M,) [m/s], times (M,) [s] from the pass start). Times integrate the
    piecewise-constant segment speeds, so the time spent in each segment is exactly
    `segment_times_s` (what the deposition model assumed); speeds interpolate the slowness 1/v
    linearly between segment centres (the smooth command for the robot; constant beyond the
    first and last centres). The two agree to first order in the segment length.
    """
    x = np.asarray(arc_m, dtype=float)
    s = result.seg_lengths_m
    t = result.segment_times_s
    edges = np.concatenate([[0.0], np.cumsum(s)])
    if np.any(x < -1e-9 * edges[-1]) or np.any(x > edges[-1] * (1 + 1e-9)):
        raise SpeedQPError(f"arc positions must lie in [0, {edges[-1]:.6g}] m (the pass length)")
    x = np.clip(x, 0.0, edges[-1])
    seg = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(s) - 1)
    times = np.concatenate([[0.0], np.cumsum(t)])[seg] + (x - edges[seg]) / result.speeds_m_s[seg]
    centres = edges[:-1] + 0.5 * s
    speeds = 1.0 / np.interp(x, centres, 1.0 / result.speeds_m_s)
    return speeds, times
