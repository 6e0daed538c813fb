"""Time law of one paint pass: TOPP-RA on a joint path parameterized by TCP arc length.

The pass is a joint path q(s), s ∈ [0, L] the arc length [m] of the planned TCP path, given as a
C² cubic spline through the IK samples. TOPP-RA (toppra 0.6, seidel solver) finds the fastest
ṡ(s) under, at every grid point,

- joint velocity      |q'(s) ṡ| ≤ v_lim                       (bound on x = ṡ²)
- TCP speed           |p'(s)| ṡ ≤ v_plan(s)                   (bound on x; p = FK position)
- joint acceleration  |q' s̈ + q'' ṡ²| ≤ a_lim                  (linear in u = s̈, x = ṡ²)
- TCP acceleration    |p' s̈ + p'' ṡ²| ≤ a_tcp                  (second-order cone, replaced by an
  inscribed 16-gon in the plane of its two orthogonal components, so the true norm is ≤ a_tcp)

Because s is TCP arc length, the TCP speed is |p'| ṡ ≈ ṡ: where no joint limit binds, TOPP-RA's
time-optimal ṡ sits on the planned speed bound, i.e. the robot follows the planned speed.

Sampling: the TOPP-RA solution is x = ṡ² linear in s on each grid interval (constant s̈), so
s(t) is piecewise quadratic in t and q, q̇, q̈ are evaluated analytically at any time from the
spline (no toppra parametrizer, whose spline fit overshoots acceleration limits by ~20 %).
Between grid points the constraints are not enforced, so `parameterize_pass` re-measures the
sampled joint velocity and acceleration and TCP acceleration at the control rate and tightens the
limits it hands to TOPP-RA until the sampled output respects the real limits (`PassTimeLaw`
records the shrink factor it needed); where tightening does not, the grid is halved.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import toppra
import toppra.algorithm
import toppra.constraint
from scipy.interpolate import CubicSpline
from toppra.constraint import DiscretizationType
from toppra.constraint.linear_constraint import LinearConstraint, canlinear_colloc_to_interpolate
from toppra.interpolator import AbstractGeometricPath

from paintcell.motion.joint_trajectory import TrajectoryError

# toppra logs a warning for every uncontrollable start velocity we probe; we handle those.
logging.getLogger("toppra").setLevel(logging.ERROR)

# the polygon inscribed in the TCP-acceleration circle: cos(π/16) = 0.981, < 2 % of its radius
_TCP_POLYGON_SIDES = 16
# Step of the central differences of the FK position along s [m]: truncation O(h²·p''') is
# ~1e-8 relative, round-off ~1e-16/h² · |p| ≈ 1e-8 m/m² on 1 m coordinates.
_FK_STEP_M = 1e-4
# Relative excess tolerated by the sampled re-measurement before the limits are tightened
# (float round-off of the analytic evaluation).
_SAMPLED_RTOL = 1e-9

# A pass longer than this many control periods is a broken joint path, not a paint pass
# (1e6 samples = 1000 s at 1 kHz).
_MAX_CHECK_SAMPLES = 1e6
GRID_HALVINGS = 3    #: halvings of a TOPP-RA grid whose pass still fails (0.01 m → 1.25 mm)

FkPositions = Callable[[np.ndarray], np.ndarray]


class JointPath(AbstractGeometricPath):
    """C² joint path q(s): a not-a-knot cubic spline through (s_knots [m], q_knots [rad]).

    toppra's `AbstractGeometricPath` protocol: `path(s, order)` → (K, n) q, q' [rad/m] or
    q'' [rad/m²].
    """

    def __init__(self, s_knots: npt.ArrayLike, q_knots: npt.ArrayLike) -> None:
        s = np.asarray(s_knots, float)
        q = np.asarray(q_knots, float)
        if s.ndim != 1 or q.ndim != 2 or len(s) != len(q) or len(s) < 2:
            raise TrajectoryError(f"joint path needs s (M,) and q (M, n) with M ≥ 2, got shapes "
                                  f"{s.shape} and {q.shape}")
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(q))):
            raise TrajectoryError("joint path contains NaN or inf; check the IK result")
        if np.any(np.diff(s) <= 0):
            raise TrajectoryError("joint path arc lengths must strictly increase; remove "
                                  "repeated TCP samples from the pass")
        bc = "not-a-knot" if len(s) > 3 else "natural"
        self.s_knots, self.q_knots = s, q
        self._spline = CubicSpline(s, q, axis=0, bc_type=bc)
        self._d1 = self._spline.derivative(1)
        self._d2 = self._spline.derivative(2)

    def __call__(self, path_positions: float | np.ndarray, order: int = 0) -> np.ndarray:
        f = (self._spline, self._d1, self._d2)[order]
        return f(np.clip(path_positions, self.s_knots[0], self.s_knots[-1]))

    @property
    def dof(self) -> int:
        return self.q_knots.shape[1]

    @property
    def path_interval(self) -> np.ndarray:
        return np.array([self.s_knots[0], self.s_knots[-1]])


def tcp_path_derivatives(path: JointPath, fk_pos: FkPositions,
                         s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """TCP position derivatives along the path by central differences of the FK.

    Returns p'(s) (K, 3) [m/m] and p''(s) (K, 3) [1/m] at arc lengths `s` (K,) [m].
    """
    lo, hi = path.path_interval
    h = _FK_STEP_M
    # Shift the stencil inside the interval at the ends (one-sided stencils are less accurate;
    # a shifted central stencil keeps O(h) bias over 1e-4 m, negligible).
    sc = np.clip(s, lo + h, hi - h)
    p0, pm, pp = (fk_pos(path(x)) for x in (sc, sc - h, sc + h))
    d1 = (pp - pm) / (2 * h) + (s - sc)[:, None] * (pp - 2 * p0 + pm) / h**2
    d2 = (pp - 2 * p0 + pm) / h**2
    return d1, d2


class _PathVelocityBound(LinearConstraint):
    """x = ṡ² ≤ x_max(s): joint velocity limits and the planned TCP speed, given on the grid."""

    def __init__(self, xmax: np.ndarray, dof: int) -> None:
        super().__init__()
        self.xmax = xmax
        self.dof = dof
        self._format_string = "    path velocity bound (joint velocity, planned TCP speed)\n"

    def compute_constraint_params(self, path: AbstractGeometricPath, gridpoints: np.ndarray,
                                  *args: object, **kwargs: object) -> tuple:
        if len(gridpoints) != len(self.xmax):
            raise TrajectoryError("internal: velocity bound built on another grid")
        xbound = np.column_stack([np.zeros(len(self.xmax)), self.xmax])
        return None, None, None, None, None, None, xbound


class _AccelerationBound(LinearConstraint):
    """Joint accelerations q'u + q''x in ±a_lim and the TCP acceleration inside a 16-gon.

    The TCP acceleration p'u + p''x is split along t = p'/|p'| and the rest of p'' (orthogonal),
    c1 = |p'| u + (p''·t) x, c2 = |p'' − (p''·t)t| x, so |a_tcp| = ‖(c1, c2)‖ exactly.
    """

    def __init__(self, q1: np.ndarray, q2: np.ndarray, p1: np.ndarray, p2: np.ndarray,
                 a_lim: np.ndarray, a_tcp: float) -> None:
        super().__init__()
        self.discretization_type = DiscretizationType.Interpolation
        self.identical = True
        self.dof = q1.shape[1]
        n = self.dof
        norm1 = np.linalg.norm(p1, axis=1)
        t = p1 / norm1[:, None]
        along = np.sum(p2 * t, axis=1)
        perp = np.linalg.norm(p2 - along[:, None] * t, axis=1)
        self.a = np.column_stack([q1, norm1, np.zeros_like(norm1)])
        self.b = np.column_stack([q2, along, perp])
        k = _TCP_POLYGON_SIDES
        ang = 2 * np.pi * (np.arange(k) + 0.5) / k
        F = np.zeros((2 * n + k, n + 2))
        F[:n, :n] = np.eye(n)
        F[n:2 * n, :n] = -np.eye(n)
        F[2 * n:, n] = np.cos(ang)
        F[2 * n:, n + 1] = np.sin(ang)
        g = np.concatenate([a_lim, a_lim, np.full(k, a_tcp * np.cos(np.pi / k))])
        self.F, self.g = F, g
        self._format_string = "    joint and TCP acceleration bound\n"

    def compute_constraint_params(self, path: AbstractGeometricPath, gridpoints: np.ndarray,
                                  *args: object, **kwargs: object) -> tuple:
        if len(gridpoints) != len(self.a):
            raise TrajectoryError("internal: acceleration bound built on another grid")
        return canlinear_colloc_to_interpolate(self.a, self.b, np.zeros_like(self.a), self.F,
                                               self.g, None, None, gridpoints, identical=True)


@dataclass(frozen=True, eq=False)
class PassTimeLaw:
    """Time law s(t) of one pass: ṡ² linear in s between grid points (constant s̈).

    path: the joint path q(s).
    s_grid: (N+1,) grid arc lengths [m]; sd_grid: (N+1,) ṡ there [m/s]; sdd: (N,) s̈ on each
        interval [m/s²]; t_grid: (N+1,) times of the grid points from the pass start [s].
    tcp_speed_scale_grid: (N+1,) |p'(s)| (TCP speed per unit ṡ, ≈ 1).
    limit_shrink: factor (≤ 1) applied to the joint/TCP limits handed to TOPP-RA so that the
        sampled output respects the limits (1 when no tightening was needed).
    sd_start_clipped / sd_end_clipped: True when the requested boundary speed was not reachable
        under the limits and a lower one was used.
    """

    path: JointPath
    s_grid: np.ndarray
    sd_grid: np.ndarray
    sdd: np.ndarray
    t_grid: np.ndarray
    tcp_speed_scale_grid: np.ndarray
    limit_shrink: float
    sd_start_clipped: bool
    sd_end_clipped: bool

    @property
    def duration_s(self) -> float:
        """Duration of the pass [s]."""
        return float(self.t_grid[-1])

    @property
    def length_m(self) -> float:
        """Arc length of the pass [m]."""
        return float(self.s_grid[-1] - self.s_grid[0])

    def path_state(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """s [m], ṡ [m/s], s̈ [m/s²] at times t (K,) [s] from the pass start (clamped)."""
        t = np.clip(np.asarray(t, float), 0.0, self.duration_s)
        i = np.clip(np.searchsorted(self.t_grid, t, side="right") - 1, 0, len(self.sdd) - 1)
        tau = t - self.t_grid[i]
        u = self.sdd[i]
        sd = self.sd_grid[i] + u * tau
        s = self.s_grid[i] + self.sd_grid[i] * tau + 0.5 * u * tau**2
        return np.minimum(s, self.s_grid[-1]), np.maximum(sd, 0.0), u

    def joint_state(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                     np.ndarray, np.ndarray]:
        """State at times t (K,) [s]: s [m], ṡ [m/s], q (K, n) [rad], q̇ [rad/s], q̈ [rad/s²]."""
        s, sd, sdd = self.path_state(t)
        q1 = self.path(s, 1)
        q = self.path(s, 0)
        qd = q1 * sd[:, None]
        qdd = q1 * sdd[:, None] + self.path(s, 2) * (sd**2)[:, None]
        return s, sd, q, qd, qdd


def make_grid(s_knots: np.ndarray, max_spacing_m: float) -> np.ndarray:
    """TOPP-RA grid: every knot, plus uniform points so no interval exceeds `max_spacing_m` [m]."""
    pieces = [s_knots[:1]]
    for a, b in zip(s_knots[:-1], s_knots[1:], strict=True):
        k = max(1, int(np.ceil((b - a) / max_spacing_m - 1e-9)))
        pieces.append(a + (b - a) * np.arange(1, k + 1) / k)
    g = np.concatenate(pieces)
    g[-1] = s_knots[-1]
    return g


def parameterize_pass(path: JointPath, fk_pos: FkPositions, v_planned_knots_m_s: npt.ArrayLike,
                      v_max_rad_s: npt.ArrayLike, a_max_rad_s2: npt.ArrayLike,
                      tcp_a_max_m_s2: float, *, grid_spacing_m: float = 0.01,
                      sd_start_m_s: float | None = None, sd_end_m_s: float | None = None,
                      check_dt_s: float = 1e-3, max_tightenings: int = 6) -> PassTimeLaw:
    """Time-optimal time law of one pass under joint and TCP limits (see the module docstring).

    path: joint path q(s) over TCP arc length [m]; its knots carry the plan samples.
    fk_pos: Q (K, n) [rad] → TCP positions (K, 3) [m] (world frame).
    v_planned_knots_m_s: (M,) planned TCP speed at the path knots [m/s]; between knots v² is
        linear in s (constant tangential acceleration between samples).
    v_max_rad_s, a_max_rad_s2: (n,) joint limits to respect [rad/s], [rad/s²] (margins already
        applied by the caller).
    tcp_a_max_m_s2: TCP acceleration limit [m/s²].
    grid_spacing_m: largest TOPP-RA grid interval [m] (every knot is also a grid point); halved
        up to GRID_HALVINGS times where the limits, tightened max_tightenings times, still fail.
    sd_start_m_s / sd_end_m_s: requested TCP speed at the ends [m/s] (None: the planned speed);
        lowered to the nearest reachable value when the limits do not allow it.
    check_dt_s: time step of the sampled re-measurement [s] (the control period).
    max_tightenings: how many times the limits may be tightened before giving up.
    """
    s_knots = path.s_knots
    v_knots = np.asarray(v_planned_knots_m_s, float)
    v_lim = np.asarray(v_max_rad_s, float)
    a_lim = np.asarray(a_max_rad_s2, float)
    if v_knots.shape != s_knots.shape or np.any(~np.isfinite(v_knots)) or np.any(v_knots <= 0):
        raise TrajectoryError("planned speeds must be (M,) positive values at the path knots "
                              "[m/s]; check the plan's speeds_m_s")
    if v_lim.shape != (path.dof,) or a_lim.shape != (path.dof,) or np.any(v_lim <= 0) \
            or np.any(a_lim <= 0):
        raise TrajectoryError(f"joint limits must be {path.dof} positive values; check the "
                              "robot's v_max/a_max and the trajectory margins")
    if not tcp_a_max_m_s2 > 0:
        raise TrajectoryError("tcp_a_max_m_s2 must be positive [m/s²]")
    if not grid_spacing_m > 0:
        raise TrajectoryError("grid_spacing_m must be positive [m]")

    # limits hold at the grid points: a path bending faster than the grid resolves, finer grids
    for spacing in grid_spacing_m / 2.0 ** np.arange(1 + GRID_HALVINGS):
        grid = make_grid(s_knots, spacing)
        v2_grid = np.interp(grid, s_knots, v_knots**2)
        q1, q2 = path(grid, 1), path(grid, 2)
        p1, p2 = tcp_path_derivatives(path, fk_pos, grid)
        scale = np.linalg.norm(p1, axis=1)
        if np.any(scale < 1e-6):
            raise TrajectoryError("the TCP does not move along the joint path (|dp/ds| ≈ 0); the "
                                  "IK samples do not follow the planned TCP path")
        x_tcp = v2_grid / scale**2
        v_start = np.sqrt(x_tcp[0]) if sd_start_m_s is None else sd_start_m_s / scale[0]
        v_end = np.sqrt(x_tcp[-1]) if sd_end_m_s is None else sd_end_m_s / scale[-1]

        shrink = 1.0
        for _ in range(max_tightenings + 1):
            with np.errstate(divide="ignore"):
                x_joint = np.min((shrink * v_lim)**2 / np.maximum(q1**2, 1e-300), axis=1)
            xmax = np.minimum(x_joint, x_tcp)
            constraints = [_PathVelocityBound(xmax, path.dof),
                           _AccelerationBound(q1, q2, p1, p2, shrink * a_lim,
                                              shrink * tcp_a_max_m_s2)]
            algo = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid,
                                           solver_wrapper="seidel")
            sd_end, K = _reachable_end(algo, min(v_end, np.sqrt(max(xmax[-1], 0.0))), v_start)
            sd_start = min(v_start, np.sqrt(max(K[0, 1], 0.0)) * (1 - 1e-9))
            sdd, sd, _, _ = algo.compute_parameterization(sd_start, sd_end, return_data=True)
            if sdd is None or np.any(~np.isfinite(sd)):
                raise TrajectoryError("TOPP-RA failed on a pass; check the joint limits and that "
                                      "the IK path is smooth")
            sd = np.maximum(sd, 0.0)
            ds = np.diff(grid)
            sdd = (sd[1:]**2 - sd[:-1]**2) / (2 * ds)
            vsum = sd[1:] + sd[:-1]
            if np.any(vsum <= 0):
                raise TrajectoryError("TOPP-RA stopped inside a pass (zero speed over an "
                                      "interval); the path is not traversable under the limits")
            t_grid = np.concatenate([[0.0], np.cumsum(2 * ds / vsum)])
            law = PassTimeLaw(path=path, s_grid=grid, sd_grid=sd, sdd=sdd, t_grid=t_grid,
                              tcp_speed_scale_grid=scale, limit_shrink=shrink,
                              sd_start_clipped=bool(sd_start < v_start * (1 - 1e-6)),
                              sd_end_clipped=bool(sd_end < v_end * (1 - 1e-6)))
            excess = _sampled_excess(law, fk_pos, v_lim, a_lim, tcp_a_max_m_s2, check_dt_s)
            if excess <= 1.0 + _SAMPLED_RTOL:
                return law
            shrink = shrink / excess * (1 - 1e-3)
    raise TrajectoryError(f"the sampled pass still exceeds a limit by {100 * (excess - 1):.2f} % "
                          f"after {max_tightenings} tightenings on grids down to "
                          f"{1e3 * spacing:.2f} mm; lower the part's v_max_m_s")


def _reachable_end(algo: toppra.algorithm.TOPPRA, sd_end: float,
                   sd_start: float) -> tuple[float, np.ndarray]:
    """The requested end speed if a start at ≤ `sd_start` can reach it, else the largest one
    that can (bisection on the backward controllable sets); with its controllable sets K."""

    def ok(sd: float) -> np.ndarray | None:
        K = algo.compute_controllable_sets(sd, sd)
        if np.any(np.isnan(K)) or K[0, 0] > sd_start**2 + 1e-12:
            return None
        return K

    K = ok(sd_end)
    if K is not None:
        return sd_end, K
    lo, hi = 0.0, sd_end
    K_lo = ok(0.0)
    if K_lo is None:
        raise TrajectoryError("TOPP-RA found no feasible time law for a pass (path not "
                              "controllable); check the joint limits and the IK path")
    for _ in range(30):  # bisection to ~1e-9 of the requested speed
        mid = 0.5 * (lo + hi)
        K_mid = ok(mid)
        if K_mid is None:
            hi = mid
        else:
            lo, K_lo = mid, K_mid
    # Step back from the edge of feasibility: there the controllable sets shrink to points and
    # toppra's forward pass fails on round-off.
    sd = lo * (1 - 1e-3)
    K = ok(sd)
    return (sd, K) if K is not None else (lo, K_lo)


def _sampled_excess(law: PassTimeLaw, fk_pos: FkPositions, v_lim: np.ndarray, a_lim: np.ndarray,
                    a_tcp: float, dt: float) -> float:
    """Largest ratio sampled/limit of joint speed, joint and TCP acceleration (≤ 1 is fine).

    Sampled at the control period and at every grid point and interval midpoint (where the
    acceleration is one-sided, both sides are taken).
    """
    if law.duration_s / dt > _MAX_CHECK_SAMPLES:
        raise TrajectoryError(f"a pass would take {law.duration_s:.3g} s; the joint path is "
                              "not a usable paint pass (check the IK result)")
    t = np.concatenate([np.arange(0.0, law.duration_s, dt), law.t_grid,
                        0.5 * (law.t_grid[1:] + law.t_grid[:-1])])
    s, sd, _, qd, _ = law.joint_state(t)
    ratio = np.max(np.abs(qd) / v_lim)
    # Acceleration on each interval is evaluated with that interval's s̈ at both of its ends.
    t0, t1 = law.t_grid[:-1], law.t_grid[1:]
    tt = np.concatenate([np.arange(0.0, law.duration_s, dt), t0, t1, 0.5 * (t0 + t1)])
    idx = np.concatenate([
        np.clip(np.searchsorted(law.t_grid, np.arange(0.0, law.duration_s, dt), "right") - 1,
                0, len(law.sdd) - 1),
        np.arange(len(t0)), np.arange(len(t0)), np.arange(len(t0))])
    tau = tt - law.t_grid[idx]
    u = law.sdd[idx]
    sdv = np.maximum(law.sd_grid[idx] + u * tau, 0.0)
    sv = np.minimum(law.s_grid[idx] + law.sd_grid[idx] * tau + 0.5 * u * tau**2, law.s_grid[-1])
    qdd = law.path(sv, 1) * u[:, None] + law.path(sv, 2) * (sdv**2)[:, None]
    ratio = max(ratio, float(np.max(np.abs(qdd) / a_lim)))
    p1, p2 = tcp_path_derivatives(law.path, fk_pos, sv)
    a_cart = p1 * u[:, None] + p2 * (sdv**2)[:, None]
    ratio = max(ratio, float(np.max(np.linalg.norm(a_cart, axis=1)) / a_tcp))
    return float(ratio)
