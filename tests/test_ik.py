"""IK: closed-form round trips, DLS warm/cold, paths (line, arc, free spin), UR10."""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.coverage.plan import tcp_frames
from paintcell.robots import RobotError, load_robot
from paintcell.robots.ik import (
    IKSettings,
    branch_feasibility,
    cold_start,
    dls,
    opw_branches,
    solve_path,
)
from paintcell.robots.opw import IRB4600_60_205, fit_to_limits, forward, inverse, wrap_pi
from paintcell.robots.paths import solve_paths
from tests.helpers import IK_POS_TOL_M, IK_ROT_TOL_RAD, OPW_ROUND_TRIP_ATOL

N_POSES = 1000
# Consecutive samples 5 mm apart on a smooth path: joints move ≲ 0.01 rad; a branch flip or a
# wrist flip would jump by ≳ 0.5 rad.
MAX_PATH_JUMP_RAD = 0.05


def _rot_err(T_a: np.ndarray, T_b: np.ndarray) -> float:
    R = T_a[:3, :3].T @ T_b[:3, :3]
    return float(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))


@pytest.fixture(scope="module")
def abb():
    return load_robot("abb_paint")


@pytest.fixture(scope="module")
def random_reachable(abb):
    """1,000 seeded joint configurations inside the limits and their TCP poses."""
    Q = np.random.default_rng(10).uniform(abb.q_lower, abb.q_upper, (N_POSES, 6))
    return Q, abb.fk_many(Q)


def test_opw_all_branches_round_trip(abb, random_reachable):
    Q, T = random_reachable
    Qs, valid = inverse(abb.opw, abb.flange_poses(T))
    assert Qs.shape == (N_POSES, 8, 6) and valid.shape == (N_POSES, 8)
    assert valid.all(axis=1).mean() > 0.5       # most poses have all 8 arm/wrist branches
    T_flange = forward(abb.opw, Qs.reshape(-1, 6)).reshape(N_POSES, 8, 4, 4)
    T_tcp = abb.T_world_base @ T_flange @ abb.T_flange_tcp
    err = np.abs(T_tcp - T[:, None]).max(axis=(2, 3))
    assert err[valid].max() < OPW_ROUND_TRIP_ATOL
    # Every valid branch is a distinct solution, and the sampled configuration is one of them.
    diff = np.abs(wrap_pi(Qs - Q[:, None])).max(axis=2)
    assert np.all(diff.min(axis=1) < 1e-7)
    # Cross-check with Pinocchio on a subset (the closed form does not know Pinocchio).
    for i in range(0, N_POSES, 50):
        for b in np.flatnonzero(valid[i]):
            assert np.abs(abb.fk(Qs[i, b]) - T[i]).max() < OPW_ROUND_TRIP_ATOL


def test_opw_branches_are_distinct(random_reachable):
    """Where all 8 branches exist, they are 8 different joint vectors."""
    Q, _ = random_reachable
    Qs, valid = inverse(IRB4600_60_205, forward(IRB4600_60_205, Q[:200]))
    full = np.flatnonzero(valid.all(axis=1))
    assert len(full) > 50
    for i in full:
        d = np.abs(wrap_pi(Qs[i][:, None] - Qs[i][None])).max(axis=2)
        assert np.all(d[~np.eye(8, dtype=bool)] > 1e-6)


def test_fit_to_limits_wraps_j4_j6_near_reference(abb):
    q = np.array([0.1, 0.2, -0.3, -3.0, 0.5, 3.0])
    ref = np.array([0.0, 0.0, 0.0, 6.0, 0.0, -6.0])
    qf, ok = fit_to_limits(q, abb.q_lower, abb.q_upper, ref)
    assert ok
    assert np.allclose(qf[[0, 1, 2, 4]], q[[0, 1, 2, 4]])
    assert np.isclose(qf[3], -3.0 + 2 * np.pi) and np.isclose(qf[5], 3.0 - 2 * np.pi)
    # 3.0 + 2π = 9.28 rad is beyond +400°: the closest equivalent inside the range is kept.
    qf, ok = fit_to_limits(np.array([0, 0, 0, 3.0, 0, 0.0]), abb.q_lower, abb.q_upper, ref)
    assert ok and np.isclose(qf[3], 3.0)
    _, ok = fit_to_limits(np.array([0, 0, 1.5, 0, 0, 0.0]), abb.q_lower, abb.q_upper)
    assert not ok                                  # J3 = 1.5 rad > 75°, no equivalent inside


def test_dls_warm_start_converges(abb, random_reachable):
    Q, T = random_reachable
    rng = np.random.default_rng(11)
    s = IKSettings()
    n_ok = 0
    for q, T_i in zip(Q, T, strict=True):
        q0 = np.clip(q + rng.normal(0, 0.03, 6), abb.q_lower, abb.q_upper)
        qs, ok = dls(abb, T_i, q0, max_iters=s.warm_iters)
        if ok:
            n_ok += 1
            T_s = abb.fk(qs)
            assert np.linalg.norm(T_s[:3, 3] - T_i[:3, 3]) <= IK_POS_TOL_M
            assert _rot_err(T_s, T_i) <= IK_ROT_TOL_RAD * 1.01
    # A few samples sit on a joint limit where a clamped warm start may stall.
    assert n_ok >= 0.98 * N_POSES


@pytest.mark.slow
def test_dls_cold_start_converges(abb, random_reachable):
    """All 1,000 random poses from q_home with up to 40 seeded restarts. Uniformly random joints
    include folded, near-limit arms where clamped DLS can stall: allow 0.5 % failures."""
    Q, T = random_reachable
    fails = 0
    for T_i in T:
        qs, ok = cold_start(abb, T_i)
        fails += not ok
        if ok:
            T_s = abb.fk(qs)
            assert np.linalg.norm(T_s[:3, 3] - T_i[:3, 3]) <= IK_POS_TOL_M
            assert _rot_err(T_s, T_i) <= IK_ROT_TOL_RAD * 1.01
    assert fails <= 5


def test_dls_cold_start_quick(abb, random_reachable):
    """Cold starts from home with restarts on a handful of random poses (fast subset)."""
    _, T = random_reachable
    for T_i in T[:25]:
        qs, ok = cold_start(abb, T_i)
        assert ok
        assert np.linalg.norm(abb.fk(qs)[:3, 3] - T_i[:3, 3]) <= IK_POS_TOL_M


def _line(p0, p1, axis, travel, step=0.005):
    n = int(np.ceil(np.linalg.norm(np.subtract(p1, p0)) / step)) + 1
    P = np.linspace(p0, p1, n)
    return tcp_frames(P, np.tile(axis, (n, 1)), np.tile(travel, (n, 1)))


def _arc(center, radius, angles, height):
    """Horizontal arc in front of the robot, spray axis pointing radially outward at the part."""
    a = np.asarray(angles)
    P = np.stack([center[0] + radius * np.cos(a), center[1] + radius * np.sin(a),
                  np.full_like(a, height)], axis=1)
    axis = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    travel = np.stack([-np.sin(a), np.cos(a), np.zeros_like(a)], axis=1)
    return tcp_frames(P, axis, travel)


def _assert_good_path(robot, res, T):
    rep = res.reachability
    assert rep.all_reachable, rep.verdict
    assert rep.continuous
    assert res.q.shape == (len(T), robot.nq)
    assert np.abs(np.diff(res.q, axis=0)).max() < MAX_PATH_JUMP_RAD
    assert np.nanmax(rep.pos_residual_m) <= IK_POS_TOL_M
    assert np.nanmax(rep.rot_residual_rad) <= IK_ROT_TOL_RAD
    assert np.all(res.q >= robot.q_lower - 1e-12) and np.all(res.q <= robot.q_upper + 1e-12)


def test_straight_line_is_continuous(abb):
    T = _line([1.15, -0.55, 1.0], [1.15, 0.55, 1.0], [1.0, 0, 0], [0, 1.0, 0])
    res = solve_path(abb, T)
    _assert_good_path(abb, res, T)
    assert res.method == "opw+dls" and 0 <= res.branch < 8


def test_no_branch_flip_inside_a_pass(abb):
    """Every sample of the pass is the chosen closed-form branch (mod 2π)."""
    T = _line([1.15, 0.55, 0.7], [1.15, -0.55, 1.3], [1.0, 0, 0], [0, -1.0, 0])
    res = solve_path(abb, T)
    Qb, _, within = opw_branches(abb, T, abb.q_home)
    assert within[res.branch].all()
    assert np.abs(wrap_pi(res.q - Qb[res.branch])).max() < 1e-6


def test_arc_in_front_of_the_robot_is_continuous(abb):
    T = _arc([0.0, 0.0], 1.2, np.linspace(-0.6, 0.6, 300), 0.9)
    res = solve_path(abb, T)
    _assert_good_path(abb, res, T)


def test_free_spin_matches_axis_and_moves_less(abb):
    T = _line([1.15, -0.5, 1.2], [1.15, 0.5, 0.8], [1.0, 0, 0], [0, 1.0, 0])
    # A spin that rotates along the path: fixed-spin tracking must turn the wrist with it.
    ang = np.linspace(0, 2.0, len(T))
    Rz = np.zeros((len(T), 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = (
        np.cos(ang), -np.sin(ang), np.sin(ang), np.cos(ang), 1.0)
    T = T.copy()
    T[:, :3, :3] = T[:, :3, :3] @ Rz
    fixed = solve_path(abb, T)
    free = solve_path(abb, T, free_spin=True)
    assert fixed.reachability.all_reachable and free.reachability.all_reachable
    axis_err = np.arccos(np.clip(np.sum(abb.fk_many(free.q)[:, :3, 2] * T[:, :3, 2], 1), -1, 1))
    assert axis_err.max() <= IK_ROT_TOL_RAD
    pos_err = np.linalg.norm(abb.fk_many(free.q)[:, :3, 3] - T[:, :3, 3], axis=1)
    assert pos_err.max() <= IK_POS_TOL_M
    # Joint-space path length: free spin lets DLS keep the least-motion spin.
    length = lambda q: np.linalg.norm(np.diff(q, axis=0), axis=1).sum()  # noqa: E731
    assert length(free.q) < 0.8 * length(fixed.q)


def test_unreachable_pose_is_flagged_not_skipped(abb):
    T = _line([1.15, -0.2, 1.0], [1.15, 0.2, 1.0], [1.0, 0, 0], [0, 1.0, 0])
    T[40, :3, 3] = [4.0, 0.0, 1.0]          # far outside the ~2.5 m reach
    res = solve_path(abb, T)
    rep = res.reachability
    assert rep.n_poses == len(T) and res.q.shape == (len(T), 6)
    assert np.all(np.isfinite(res.q))
    assert not rep.reachable[40] and rep.reachable[:40].all() and rep.reachable[41:].all()
    assert rep.worst_pose() == (0, 40)
    assert "UNREACHABLE 1/" in rep.verdict
    assert rep.pos_residual_m[40] > 1.0


def test_solve_paths_seeds_the_next_pass(abb):
    paths = [_line([1.15, -0.5, z], [1.15, 0.5, z], [1.0, 0, 0], [0, 1.0, 0])[:: 1 - 2 * (k % 2)]
             for k, z in enumerate([0.8, 1.0, 1.2])]
    res = solve_paths(abb, paths)
    assert len(res) == 3 and all(r.reachability.all_reachable for r in res)
    # The next pass starts close to where the previous one ended (same branch, nearby joints).
    for a, b in zip(res[:-1], res[1:], strict=True):
        assert np.abs(b.q[0] - a.q[-1]).max() < 1.0


def test_ur10_dls_path(abb):
    ur = load_robot("ur10")
    q_mid = np.array([0.0, -1.6, 1.8, -1.8, -1.5708, 0.0])
    T0 = ur.fk(q_mid)
    n = 120
    T = np.repeat(T0[None], n, axis=0)
    T[:, :3, 3] += np.linspace(-0.3, 0.3, n)[:, None] * T0[:3, 0]   # along the tool x (travel)
    res = solve_path(ur, T)                 # its closed form (paintcell.robots.ur_ik) + DLS
    assert res.method == "closed-form+dls" and 0 <= res.branch < 8
    _assert_good_path(ur, res, T)
    ur.closed_form = None                   # an arm with no closed form: DLS alone
    res = solve_path(ur, T)
    assert res.method == "dls" and res.branch == -1
    _assert_good_path(ur, res, T)


def test_bad_path_raises(abb):
    with pytest.raises(RobotError, match="M, 4, 4"):
        solve_path(abb, np.eye(4))
    with pytest.raises(RobotError, match="joint vector"):
        solve_path(abb, np.eye(4)[None], q_seed=np.zeros(3))


def test_seed_selects_the_nearest_comfortable_branch(abb):
    T = _line([1.15, -0.3, 1.0], [1.15, 0.3, 1.0], [1.0, 0, 0], [0, 1.0, 0])
    Q, _, within = opw_branches(abb, T, abb.q_home)
    s = IKSettings()
    good = []
    for b in range(8):
        if within[b].all():
            Qb = Q[b]
            margin = min(np.minimum(Qb - abb.q_lower, abb.q_upper - Qb).min(),
                         np.arcsin(np.abs(np.sin(Qb[:, 4])).min()))
            if margin >= s.comfort_margin_rad and np.abs(np.diff(Qb, axis=0)).max() < 0.2:
                good.append(b)
    assert len(good) >= 2
    for b in good:
        res = solve_path(abb, T, q_seed=Q[b][0])
        assert res.branch == b
        assert np.allclose(res.q[0], Q[b][0], atol=1e-9)


@pytest.fixture(scope="module")
def door_plan():
    from paintcell.coverage.algorithm import plan_coverage
    from paintcell.coverage.coverage_settings import PlannerSettings
    from paintcell.paint.applicator import Applicator
    from paintcell.surface.parts import get_part

    surface = get_part("door", resolution_m=0.02)
    return plan_coverage(surface, Applicator.default(), PlannerSettings(optimize_speed=False))


def test_planned_door_passes_are_continuous(abb, door_plan):
    """The planner's door passes, door upright 1.4 m in front of the robot (painted side facing
    it, centre 1.0 m high): every pass reachable, no jump, residuals within tolerance."""
    T_world_part = np.eye(4)
    T_world_part[:3, :3] = np.array([[0, 1, 0], [0, 0, -1], [-1, 0, 0]], float).T
    T_world_part[:3, 3] = [1.4, 0.0, 1.0]
    paths = [T_world_part @ door_plan.tcp_frames(i) for i in range(len(door_plan.passes))]
    results = solve_paths(abb, paths, q_seed=abb.q_home)
    for res, T in zip(results, paths, strict=True):
        _assert_good_path(abb, res, T)


@pytest.mark.parametrize(("field", "value"), [
    ("pos_tol_m", -1.0), ("rot_tol_rad", 0.0), ("damping", -1e-4), ("max_step_rad", 0.0),
    ("warm_iters", -3), ("warm_iters", 2.5), ("cold_iters", 0), ("cold_restarts", -1),
    ("wrist_sin_min", 1.5), ("max_joint_jump_rad", 0.0), ("comfort_margin_rad", -0.1),
    ("seed", 1.5), ("pos_tol_m", float("nan")),
])
def test_ik_settings_are_validated(field: str, value: float) -> None:
    with pytest.raises(RobotError, match=f"invalid IKSettings: {field}"):
        IKSettings(**{field: value})


def test_non_rigid_or_non_finite_pose_is_rejected(abb):
    T = _line([1.15, -0.2, 1.0], [1.15, 0.2, 1.0], [1.0, 0, 0], [0, 1.0, 0])
    scaled = T.copy()
    scaled[10, :3, :3] *= 2.0                # a scale-2 "pose": not a TCP pose at all
    with pytest.raises(RobotError, match=r"T_world_tcp \(pose 10\) is not a rigid transform"):
        solve_path(abb, scaled)
    nan = T.copy()
    nan[3, 0, 3] = np.nan
    with pytest.raises(RobotError, match=r"pose 3\) is not a rigid transform: non-finite"):
        solve_path(abb, nan, free_spin=True)


def _branch_stats_loop(robot, Q, within, s, jump_scale=1.0):
    """Per-branch reference of `branch_feasibility` (the loop `choose_branch` used to run)."""
    out = []
    for b in range(Q.shape[0]):
        Qb = Q[b][within[b]]
        if len(Qb) == 0:
            out.append((0, -np.inf, np.inf, -np.inf, False))
            continue
        wsin = float(np.abs(np.sin(Qb[:, 4])).min())
        margin = min(float(np.minimum(Qb - robot.q_lower, robot.q_upper - Qb).min()),
                     float(np.arcsin(min(wsin, 1.0))))
        jump = float(np.abs(np.diff(Qb, axis=0)).max()) if len(Qb) > 1 else 0.0
        feas = (len(Qb) == Q.shape[1] and wsin >= s.wrist_sin_min
                and jump <= s.max_joint_jump_rad * jump_scale)
        out.append((len(Qb), wsin, jump, margin, feas))
    return out


def test_branch_feasibility_matches_a_per_branch_loop(abb):
    """One vectorized feasibility function serves `choose_branch` and `placement.path_margin`;
    it equals the per-branch computation exactly, also with poses outside the limits."""
    rng = np.random.default_rng(30)
    s = IKSettings()
    n_partial = 0
    for k in range(60):
        q0 = rng.uniform(abb.q_lower, abb.q_upper)
        Q = np.linspace(q0, q0 + rng.normal(0, 0.3 if k % 2 else 1.5, 6), int(rng.integers(1, 25)))
        T = abb.fk_many(Q)
        if k % 3 == 0:
            T[:, :3, 3] *= rng.uniform(0.8, 1.6)      # push part of the path out of reach
        Qc, _, within = opw_branches(abb, T, abb.q_home)
        n_partial += int(np.any(within.any(axis=1) & ~within.all(axis=1)))
        for scale in (1.0, 3.0):
            st = branch_feasibility(abb, Qc, within, s, scale)
            ref = _branch_stats_loop(abb, Qc, within, s, scale)
            got = list(zip(st.n_ok, st.wrist_sin, st.jump, st.margin, st.feasible, strict=True))
            assert [tuple(float(x) for x in r) for r in got] == \
                [tuple(float(x) for x in r) for r in ref]
    assert n_partial > 5    # the masked (partly outside the limits) case is exercised
