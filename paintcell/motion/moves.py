"""Jerk-limited, time-optimal joint moves between paint passes (ruckig, offline).

A move goes from one full joint state (q, q̇, q̈) to another, so it joins a TOPP-RA pass that is
already moving at the planned speed continuously in position, velocity and acceleration. All
joints are time-synchronized (ruckig's default): they start and finish together.

Sampling is vectorized: ruckig's per-joint profiles (an optional two-phase brake pre-profile and
seven constant-jerk phases) are evaluated as cubics at all sample times at once; a few samples
are cross-checked against `Trajectory.at_time`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import ruckig

from paintcell.core.errors import one_line
from paintcell.motion.joint_trajectory import TrajectoryError

# Agreement required between the vectorized profile evaluation and ruckig's own `at_time`
# (both evaluate the same cubics in float64; differences are round-off of ~1e-12).
_CROSSCHECK_ATOL = 1e-8
#: estimated duration of a turn-around between two passes and of a program's approach + retract
#: [s], for ranking programs before they are built (measured on the library parts' programs:
#: turn-arounds 0.8–1.8 s, approach + retract 3–5 s).
TURN_S = 1.2
APPROACH_RETRACT_S = 4.0


@dataclass(frozen=True, eq=False)
class JointMove:
    """One ruckig move: per joint, piecewise-cubic position over phases.

    duration_s: move duration [s].
    t_start: (n, P) phase start times [s]; p0, v0, a0, j: (n, P) position [rad], velocity
        [rad/s], acceleration [rad/s²] at the phase start and the phase's constant jerk [rad/s³].
    """

    duration_s: float
    t_start: np.ndarray
    p0: np.ndarray
    v0: np.ndarray
    a0: np.ndarray
    j: np.ndarray

    def sample(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q (K, n) [rad], q̇ [rad/s], q̈ [rad/s²] at times t (K,) [s] (clamped to the move)."""
        ts: np.ndarray = np.clip(np.asarray(t, float), 0.0, self.duration_s)
        n = self.t_start.shape[0]
        q = np.empty((len(ts), n))
        qd = np.empty_like(q)
        qdd = np.empty_like(q)
        for k in range(n):  # loop over joints only; samples are vectorized
            i = np.clip(np.searchsorted(self.t_start[k], ts, side="right") - 1, 0, None)
            tau = ts - self.t_start[k, i]
            j, a, v, p = self.j[k, i], self.a0[k, i], self.v0[k, i], self.p0[k, i]
            q[:, k] = p + tau * (v + tau * (a / 2 + tau * j / 6))
            qd[:, k] = v + tau * (a + tau * j / 2)
            qdd[:, k] = a + tau * j
        return q, qd, qdd

    def position_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Each joint's lowest and highest position over the move, (n,) each [rad], exact: every
        phase's cubic at its two ends and where its velocity is zero inside it."""
        t0 = self.t_start
        t_next = np.concatenate([t0[:, 1:], np.full((len(t0), 1), np.inf)], axis=1)
        live = t0 <= self.duration_s                    # padded phases start at t = inf
        dur = np.where(live, np.clip(np.minimum(t_next, self.duration_s) - t0, 0.0, None), 0.0)
        p, v, a, j = self.p0, self.v0, self.a0, self.j
        # v + a τ + j τ²/2 = 0: two roots where j ≠ 0, one where only a ≠ 0
        disc = np.sqrt(np.clip(a * a - 2.0 * j * v, 0.0, None))
        with np.errstate(divide="ignore", invalid="ignore"):
            quad = np.abs(j) > 1e-12
            lin = ~quad & (np.abs(a) > 1e-12)
            r1 = np.where(quad, (-a + disc) / j, np.where(lin, -v / a, 0.0))
            r2 = np.where(quad, (-a - disc) / j, 0.0)
        taus = np.stack([np.zeros_like(dur), dur, np.clip(r1, 0.0, dur), np.clip(r2, 0.0, dur)])
        q = p + taus * (v + taus * (a / 2 + taus * j / 6))
        q = np.where(live, q, np.nan)
        return np.nanmin(q, axis=(0, 2)), np.nanmax(q, axis=(0, 2))


def plan_move(q0: npt.ArrayLike, qd0: npt.ArrayLike, qdd0: npt.ArrayLike, q1: npt.ArrayLike,
              qd1: npt.ArrayLike, qdd1: npt.ArrayLike, v_max: npt.ArrayLike,
              a_max: npt.ArrayLike, j_max: npt.ArrayLike, q_lower: npt.ArrayLike | None = None,
              q_upper: npt.ArrayLike | None = None) -> JointMove:
    """Time-optimal jerk-limited move from state (q0, q̇0, q̈0) to (q1, q̇1, q̈1).

    All arrays (n,): positions [rad], velocities [rad/s], accelerations [rad/s²]; limits v_max
    [rad/s], a_max [rad/s²], j_max [rad/s³] (symmetric). q_lower/q_upper: optional joint
    position limits [rad] the move must stay within.
    """
    arrs = [np.asarray(x, float) for x in (q0, qd0, qdd0, q1, qd1, qdd1, v_max, a_max, j_max)]
    n = arrs[0].shape[0]
    if any(a.shape != (n,) or not np.all(np.isfinite(a)) for a in arrs):
        raise TrajectoryError(f"move states and limits must be finite ({n},) arrays; check the "
                              "joint states at the pass ends")
    if np.any(arrs[6] <= 0) or np.any(arrs[7] <= 0) or np.any(arrs[8] <= 0):
        raise TrajectoryError("move limits v_max, a_max, j_max must be positive")
    inp = ruckig.InputParameter(n)
    (inp.current_position, inp.current_velocity, inp.current_acceleration, inp.target_position,
     inp.target_velocity, inp.target_acceleration, inp.max_velocity, inp.max_acceleration,
     inp.max_jerk) = (a.tolist() for a in arrs)
    if q_lower is not None and q_upper is not None:
        inp.min_position = np.asarray(q_lower, float).tolist()
        inp.max_position = np.asarray(q_upper, float).tolist()
    otg = ruckig.Ruckig(n)
    traj = ruckig.Trajectory(n)
    try:
        result = otg.calculate(inp, traj)
    except (RuntimeError, ruckig.RuckigError) as exc:  # ruckig raises on invalid input
        raise TrajectoryError(f"ruckig rejected a move ({one_line(exc)}); check that the "
                              "boundary states lie within the move limits ([trajectory] "
                              "jerk_ramp_s, velocity_margin, acceleration_margin)") from exc
    if result == ruckig.Result.ErrorPositionalLimits:
        raise TrajectoryError("a move between passes would leave the joint position limits; "
                              "move the part or the robot base")
    if result not in (ruckig.Result.Working, ruckig.Result.Finished):
        raise TrajectoryError(f"ruckig failed on a move ({result}); check the boundary states "
                              "against the move limits")
    move = _from_profiles(traj, n)
    _crosscheck(move, traj)
    if q_lower is not None and q_upper is not None:
        # ruckig (community) neither enforces position limits nor always reports a
        # time-synchronized move's extrema right (`Trajectory.position_extrema` missed a
        # shoulder's overshoot by 0.021 rad, tests/test_moves.py): the move's own cubics are
        # measured.
        lo, hi = move.position_bounds()
        over = np.maximum(np.asarray(q_lower) - lo, hi - np.asarray(q_upper))
        if np.any(over > 1e-9):
            k = int(np.argmax(over))
            # paintcell's 7-axis robots are arms on a rail whose carriage is axis 1 (metres)
            unit = "m (the rail's carriage)" if n == 7 and k == 0 else "rad"
            raise TrajectoryError("a move between passes would leave the joint position limits "
                                  f"(axis {k + 1} of {n} by {over[k]:.3g} {unit}); move the part "
                                  "or the robot base")
    return move


def _phase_table(prof: ruckig.Profile) -> np.ndarray:
    """(P, 5) rows (t_start [s], p0, v0, a0, j) of one joint's profile: the brake pre-profile's
    phases (those with a duration), the seven constant-jerk phases, then a hold of the final
    state with jerk 0 after the profile (ruckig's own convention: the final acceleration holds)."""
    b = prof.brake
    brake = [(b.t[k], b.p[k], b.v[k], b.a[k], b.j[k])
             for k in range(2) if b.duration > 0 and b.t[k] > 0]
    main = [(prof.t[k], prof.p[k], prof.v[k], prof.a[k], prof.j[k]) for k in range(7)]
    rows = np.array(brake + main + [(0.0, prof.p[7], prof.v[7], prof.a[7], 0.0)], float)
    # Phase start times: the running sum of the durations before each phase.
    rows[:, 0] = np.concatenate([[0.0], np.cumsum(rows[:-1, 0])])
    return rows


def _from_profiles(traj: ruckig.Trajectory, n: int) -> JointMove:
    """Phase tables of a one-section ruckig trajectory (joints padded to the same phase count
    with phases that start at t = inf)."""
    if len(traj.profiles) != 1:
        raise TrajectoryError("internal: expected a ruckig trajectory without waypoints")
    tables = [_phase_table(prof) for prof in traj.profiles[0]]
    width = max(len(tb) for tb in tables)
    pad = np.array([np.vstack([tb, np.tile(tb[-1], (width - len(tb), 1))]) for tb in tables])
    for k, tb in enumerate(tables):
        pad[k, len(tb):, 0] = np.inf
    return JointMove(duration_s=float(traj.duration), t_start=pad[:, :, 0], p0=pad[:, :, 1],
                     v0=pad[:, :, 2], a0=pad[:, :, 3], j=pad[:, :, 4])


def _crosscheck(move: JointMove, traj: ruckig.Trajectory) -> None:
    """Compare the vectorized evaluation with ruckig's `at_time` at a few times."""
    ts = np.linspace(0.0, move.duration_s, 9)
    q, qd, qdd = move.sample(ts)
    for k, t in enumerate(ts):
        pr, vr, ar = traj.at_time(float(t))
        err = max(np.abs(q[k] - pr).max(), np.abs(qd[k] - vr).max(), np.abs(qdd[k] - ar).max())
        if err > _CROSSCHECK_ATOL:
            raise TrajectoryError(f"internal: ruckig profile evaluation differs from at_time by "
                                  f"{err:.3g}; unsupported ruckig profile layout")
