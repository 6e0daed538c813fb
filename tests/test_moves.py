"""paintcell.motion.moves: ruckig moves re-measured — boundary states, limits, agreement with
ruckig itself."""

from __future__ import annotations

import numpy as np
import pytest
import ruckig

from paintcell.motion.joint_trajectory import TrajectoryError
from paintcell.motion.moves import JointMove, plan_move
from tests.helpers import FD_LIMIT_RTOL, RUCKIG_STATE_ATOL

N = 6
V = np.array([3.0, 3.0, 3.0, 4.0, 4.0, 6.0])
A = np.array([6.0, 6.0, 8.0, 20.0, 20.0, 30.0])
J = A / 0.08


def _assert_matches_ruckig(m: JointMove, traj: ruckig.Trajectory, ts: np.ndarray) -> None:
    """Our vectorized samples of move `m` equal ruckig's own `at_time` at every time in `ts`."""
    q, qd, qdd = m.sample(ts)
    for k, t in enumerate(ts):
        p, v, acc = traj.at_time(float(t))
        np.testing.assert_allclose(q[k], p, atol=RUCKIG_STATE_ATOL)
        np.testing.assert_allclose(qd[k], v, atol=RUCKIG_STATE_ATOL)
        np.testing.assert_allclose(qdd[k], acc, atol=RUCKIG_STATE_ATOL)


def _random_state(rng: np.random.Generator, frac: float) -> tuple[np.ndarray, ...]:
    return (rng.uniform(-1, 1, N), frac * rng.uniform(-1, 1, N) * V,
            frac * rng.uniform(-1, 1, N) * A)


@pytest.mark.parametrize("seed", range(4))
def test_move_joins_states_and_respects_limits(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a, b = _random_state(rng, 0.9), _random_state(rng, 0.5)
    m = plan_move(*a, *b, V, A, J)
    q, qd, qdd = m.sample(np.array([0.0, m.duration_s]))
    for got, want in zip((q[0], qd[0], qdd[0], q[1], qd[1], qdd[1]), (*a, *b), strict=True):
        np.testing.assert_allclose(got, want, atol=RUCKIG_STATE_ATOL)
    dt = 1e-3
    t = np.arange(0.0, m.duration_s, dt)
    q, qd, qdd = m.sample(t)
    # Re-measure by finite differences of the sampled positions.
    assert np.all(np.abs(np.diff(q, axis=0)) / dt <= V * (1 + FD_LIMIT_RTOL))
    assert np.all(np.abs(np.diff(q, 2, axis=0)) / dt**2 <= A * (1 + FD_LIMIT_RTOL))
    assert np.all(np.abs(np.diff(q, 3, axis=0)) / dt**3 <= J * (1 + FD_LIMIT_RTOL))
    # The analytic derivatives agree with the positions' differences.
    np.testing.assert_allclose(np.diff(q, axis=0) / dt, 0.5 * (qd[1:] + qd[:-1]),
                               atol=J.max() * dt**2)


def test_vectorized_sampling_matches_ruckig_at_time() -> None:
    rng = np.random.default_rng(7)
    a, b = _random_state(rng, 1.0), _random_state(rng, 0.3)  # start at the limits: brake phase
    m = plan_move(*a, *b, V, A, J)
    inp = ruckig.InputParameter(N)
    (inp.current_position, inp.current_velocity, inp.current_acceleration, inp.target_position,
     inp.target_velocity, inp.target_acceleration) = (x.tolist() for x in (*a, *b))
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = V.tolist(), A.tolist(), J.tolist()
    traj = ruckig.Trajectory(N)
    ruckig.Ruckig(N).calculate(inp, traj)
    assert m.duration_s == pytest.approx(traj.duration, abs=1e-12)
    ts = rng.uniform(0, m.duration_s, 50)
    _assert_matches_ruckig(m, traj, ts)


def test_move_rejects_bad_input() -> None:
    z = np.zeros(N)
    with pytest.raises(TrajectoryError, match="positive"):
        plan_move(z, z, z, z + 1, z, z, V, -A, J)
    with pytest.raises(TrajectoryError, match="finite"):
        plan_move(z, z, z, z + np.nan, z, z, V, A, J)
    with pytest.raises(TrajectoryError, match="position limits"):
        plan_move(z, z, z, z + 0.5, z, z, V, A, J, q_lower=z - 1, q_upper=z + 0.2)
    # a move that starts at a limit still heading out of it: the line names the axis and by how
    # much it overshoots (the brake from 0.5 rad/s under the acceleration and jerk limits)
    qd0 = np.zeros(N)
    qd0[2] = 0.5
    hi = np.full(N, 1.0)
    hi[2] = 0.0
    with pytest.raises(TrajectoryError, match=rf"axis 3 of {N} by 0\.0\d+ rad\)"):
        plan_move(z, qd0, z, z, z, z, V, A, J, q_lower=z - 1, q_upper=hi)


def test_phase_tables_cover_brake_and_hold() -> None:
    """One phase-table helper for every joint: brake phases (when ruckig brakes first), the seven
    constant-jerk phases, then the hold (jerk 0); start times are the running phase durations."""
    from paintcell.motion.moves import _phase_table

    rng = np.random.default_rng(7)
    a, b = _random_state(rng, 1.0), _random_state(rng, 0.3)  # at the limits: a brake phase
    a = (a[0], 1.2 * V * np.sign(a[1]), a[2])                # faster than v_max: must brake
    inp = ruckig.InputParameter(N)
    (inp.current_position, inp.current_velocity, inp.current_acceleration, inp.target_position,
     inp.target_velocity, inp.target_acceleration) = (x.tolist() for x in (*a, *b))
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = V.tolist(), A.tolist(), J.tolist()
    traj = ruckig.Trajectory(N)
    ruckig.Ruckig(N).calculate(inp, traj)
    n_brake = 0
    for prof in traj.profiles[0]:
        tb = _phase_table(prof)
        brake = [t for t in prof.brake.t if t > 0] if prof.brake.duration > 0 else []
        n_brake += len(brake)
        durations = [*brake, *prof.t]
        assert tb.shape == (len(durations) + 1, 5)
        np.testing.assert_allclose(tb[:, 0], np.concatenate([[0.0], np.cumsum(durations)]),
                                   atol=1e-15)
        assert tb[-1, 4] == 0.0 and tb[-1, 1] == prof.p[7] and tb[-1, 3] == prof.a[7]
    assert n_brake > 0
    m = plan_move(*a, *b, V, A, J)
    ts = np.linspace(0.0, m.duration_s, 40)
    _assert_matches_ruckig(m, traj, ts)


#: A retract from a car bumper's last pass (an IRB 5500 on a rail, axis 3 its shoulder) into a
#: moving via: time-synchronized, axis 3 swings 0.009 rad past its 1.9199 rad limit while
#: ruckig's `Trajectory.position_extrema` reports a largest position of 1.9077 rad.
BUMPER_RETRACT = dict(
    q0=[1.3881, -1.0771, 1.6963, -1.4606, -4.5781, 1.6889, -0.6313],
    qd0=[0.0, 0.0212, 0.69, -1.2738, 0.0759, -0.0967, 0.5806],
    qdd0=[0.0, -0.0509, 2.8384, -5.0864, 0.2687, -0.237, 2.2361],
    q1=[1.3099, -1.0877, 1.6904, -1.4613, -4.5795, 1.6983, -0.6232],
    qd1=[-0.939, 0.7797, -1.3551, 1.1909, 3.2827, -0.7873, 0.4468],
    qdd1=[0.0] * 7,
    v=[1.425, 1.6581, 2.1555, 2.1555, 7.6271, 7.6271, 9.9484],
    a=[3.6, 4.05, 4.95, 5.85, 22.5, 22.5, 31.5],
    j=[45.0, 50.625, 61.875, 73.125, 281.25, 281.25, 393.75],
    lo=[-2.0, -2.618, -1.5708, -3.1416, -5.236, -2.1817, -5.236],
    hi=[2.0, 2.618, 1.9199, 1.1345, 5.236, 2.1817, 5.236])


def test_move_past_a_limit_is_refused_whatever_ruckig_reports() -> None:
    """The move's positions, sampled every 0.1 ms by ruckig's own `at_time`, leave axis 3's
    limit: plan_move refuses it (naming the axis and the overshoot) rather than trust ruckig's
    reported extrema."""
    c = {k: np.array(v) for k, v in BUMPER_RETRACT.items()}
    states = [c[k] for k in ("q0", "qd0", "qdd0", "q1", "qd1", "qdd1", "v", "a", "j")]
    m = plan_move(*states)                                  # no limits: the move as ruckig plans it
    inp = ruckig.InputParameter(7)
    (inp.current_position, inp.current_velocity, inp.current_acceleration, inp.target_position,
     inp.target_velocity, inp.target_acceleration, inp.max_velocity, inp.max_acceleration,
     inp.max_jerk) = (x.tolist() for x in states)
    traj = ruckig.Trajectory(7)
    ruckig.Ruckig(7).calculate(inp, traj)
    ts = np.arange(0.0, traj.duration, 1e-4)
    peak = max(traj.at_time(float(t))[0][2] for t in ts)
    assert peak > c["hi"][2] + 5e-3                         # it truly leaves the limit
    assert m.position_bounds()[1][2] == pytest.approx(peak, abs=1e-6)
    with pytest.raises(TrajectoryError, match=r"axis 3 of 7 by 0\.00\d+ rad"):
        plan_move(*states, q_lower=c["lo"], q_upper=c["hi"])


@pytest.mark.parametrize("seed", range(3))
def test_position_bounds_match_dense_sampling(seed: int) -> None:
    """Each joint's exact lowest and highest position equals the extremes of the move sampled
    every 50 µs (to the sampling's resolution), and is never inside them."""
    rng = np.random.default_rng(seed)
    for _ in range(20):
        m = plan_move(*_random_state(rng, 0.9), *_random_state(rng, 0.5), V, A, J)
        lo, hi = m.position_bounds()
        q, qd, _ = m.sample(np.arange(0.0, m.duration_s + 5e-5, 5e-5))
        step = np.abs(qd).max(axis=0) * 5e-5                  # the most a joint moves a sample
        assert np.all(hi >= q.max(axis=0) - 1e-12) and np.all(lo <= q.min(axis=0) + 1e-12)
        assert np.all(hi - q.max(axis=0) <= step + 1e-12)
        assert np.all(q.min(axis=0) - lo <= step + 1e-12)
