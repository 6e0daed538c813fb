"""Data of the per-pass speed QP (paper §3): its tolerances, `SpeedSettings` (speeds in m/s,
acceleration in m/s²), the sub-offset band it is given (`SubOffsetBand`, m) and the profile it
returns (`SpeedResult`, m/s and s); `SpeedQPError` for bad inputs."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from paintcell.core.errors import PlanError

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
