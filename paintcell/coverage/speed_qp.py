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

The code lives in `speed_qp_settings` (tolerances, settings, band, result), `speed_qp_objective`
(eq. 2 and its Jacobians) and `speed_qp_solve` (the SQP); this module is the entry point
`optimize_pass_speed` (rates from the deposition model, then the solve) and re-exports their
public names.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

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
    MIN_CURVE_FILM_REL,
    OBJECTIVES,
    SpeedQPError,
    SpeedResult,
    SpeedSettings,
    SubOffsetBand,
)
from paintcell.coverage.speed_qp_solve import optimize_speed_from_rates
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import deposition_rate

__all__ = [
    "BOUND_MARGIN", "CONSTRAINT_RTOL", "EQUALITY_PENALTY", "MIN_CURVE_FILM_REL", "OBJECTIVES",
    "SpeedObjective", "SpeedQPError", "SpeedResult", "SpeedSettings", "SubOffsetBand",
    "band_nsd", "build_speed_objective", "knot_interpolation", "optimize_pass_speed",
    "optimize_speed_from_rates",
]


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
