"""paintcell.motion.trajectory: the whole program re-measured by finite differences of its 1 kHz
samples."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from paintcell.coverage.plan import CoveragePlan, PassPlan
from paintcell.motion.joint_trajectory import (
    APPROACH,
    PAINT,
    RETRACT,
    TURNAROUND,
    JointTrajectory,
    TrajectoryError,
)
from paintcell.motion.trajectory import TrajectorySettings, build_program
from paintcell.paint.applicator import Applicator
from paintcell.robots import load_robot
from paintcell.robots.errors import UnreachableError
from tests.helpers import FD_LIMIT_RTOL, SPEED_FOLLOW_RTOL, TCP_PATH_ATOL_M

# Straight passes 1 m long, 20 mm samples (the planner's default spacing), spray straight down,
# alternating travel direction, in front of the ABB-style arm at its base frame.
N_PASSES, LENGTH_M, SAMPLES, OVERSPRAY_M = 3, 1.0, 51, 0.1


def _plan(v_m_s: float | np.ndarray = 0.5, x0: float = 0.9, spacing: float = 0.2,
          z: float = 1.0) -> CoveragePlan:
    passes = []
    for k in range(N_PASSES):
        y = np.linspace(-LENGTH_M / 2, LENGTH_M / 2, SAMPLES)
        if k % 2:
            y = y[::-1]
        pos = np.column_stack([np.full(SAMPLES, x0 + k * spacing), y, np.full(SAMPLES, z)])
        speeds = np.broadcast_to(np.asarray(v_m_s, float), (SAMPLES,)).copy()
        seg = np.linalg.norm(np.diff(pos, axis=0), axis=1)
        times = np.concatenate([[0.0], np.cumsum(seg / (0.5 * (speeds[1:] + speeds[:-1])))])
        passes.append(PassPlan(
            positions=pos, spray_axes=np.tile([0.0, 0.0, -1.0], (SAMPLES, 1)),
            travel_dirs=np.tile([0.0, np.sign(y[-1] - y[0]), 0.0], (SAMPLES, 1)),
            speeds_m_s=speeds, times_s=times, on_part=np.abs(y) <= LENGTH_M / 2 - OVERSPRAY_M,
            paint_on=np.abs(y) <= LENGTH_M / 2 - OVERSPRAY_M / 2, side=k))
    return CoveragePlan(surface_name="test-strip", applicator=Applicator.default(),
                        passes=tuple(passes))


def _ik(robot, T_world_tcp: np.ndarray, q0: np.ndarray) -> np.ndarray:
    """Warm-started Gauss-Newton IK along a path (test-local, so the trajectory tests do not
    depend on paintcell.robots.ik), clipped to the joint limits."""
    m, d, fid = robot.pin_model, robot.pin_data, robot.tcp_frame_id
    q, out = np.array(q0, float), []
    for T in T_world_tcp:
        target = pin.SE3(T[:3, :3], T[:3, 3])
        for _ in range(50):
            pin.forwardKinematics(m, d, q)
            err = pin.log6(pin.updateFramePlacement(m, d, fid).actInv(target)).vector
            if np.linalg.norm(err) < 1e-11:
                break
            J = pin.computeFrameJacobian(m, d, q, fid, pin.ReferenceFrame.LOCAL)
            q = np.clip(q + np.linalg.solve(J.T @ J + 1e-10 * np.eye(len(q)), J.T @ err),
                        robot.q_lower, robot.q_upper)
        out.append(q.copy())
    return np.array(out)


@pytest.fixture(scope="module")
def robot():
    return load_robot("abb_paint")


def _build(robot, plan: CoveragePlan, keep_roll: bool = True, **kw) -> JointTrajectory:
    """The plan's program from the test-local IK, each pass seeded with the end of the one
    before; keep_roll=False: IK of x = travel frames, each pass from home (the bell half-turns
    at every turn-around: a program whose turn-arounds reconfigure the wrist)."""
    ik, seed = [], robot.q_home
    for i in range(len(plan.passes)):
        ik.append(_ik(robot, plan.tcp_frames(i, keep_roll=keep_roll), seed))
        seed = ik[-1][-1] if keep_roll else robot.q_home
    return build_program(robot, plan, np.eye(4), TrajectorySettings(**kw), ik_results=ik)


@pytest.fixture(scope="module")
def plan() -> CoveragePlan:
    return _plan()


@pytest.fixture(scope="module")
def traj(robot, plan) -> JointTrajectory:
    return _build(robot, plan)


@pytest.fixture(scope="module")
def fast_traj(robot) -> JointTrajectory:
    """Planned at 2.5 m/s: beyond what the arm's joint limits allow on these passes."""
    return _build(robot, _plan(2.5))


def _limits(traj: JointTrajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    lim = traj.meta["limits"]
    return (np.array(lim["v_used_rad_s"]), np.array(lim["a_used_rad_s2"]),
            np.array(lim["j_used_rad_s3"]))


@pytest.mark.parametrize("which", ["traj", "fast_traj"])
def test_joint_limits_hold_by_finite_differences(which: str, request) -> None:
    tr = request.getfixturevalue(which)
    v, a, _ = _limits(tr)
    dt = tr.dt_s
    assert np.all(np.abs(np.diff(tr.q, axis=0)) / dt <= v * (1 + FD_LIMIT_RTOL))
    assert np.all(np.abs(np.diff(tr.q, 2, axis=0)) / dt**2 <= a * (1 + FD_LIMIT_RTOL))
    # The margins are the stated fractions of the robot's limits.
    robot_v = np.array(tr.meta["limits"]["v_max_rad_s"])
    np.testing.assert_allclose(v, TrajectorySettings().velocity_margin * robot_v)


def test_jerk_bounded_on_moves(traj: JointTrajectory) -> None:
    _, _, j = _limits(traj)
    jerk = np.diff(traj.q, 3, axis=0) / traj.dt_s**3
    seg = traj.segment
    window_off_paint = (seg[:-3] != PAINT) & (seg[1:-2] != PAINT) & (seg[2:-1] != PAINT) \
        & (seg[3:] != PAINT)
    assert window_off_paint.sum() > 1000
    assert np.all(np.abs(jerk[window_off_paint]) <= j * (1 + FD_LIMIT_RTOL))


def test_continuity_at_every_junction(traj: JointTrajectory) -> None:
    v, a, j = _limits(traj)
    dt = traj.dt_s
    junctions = np.flatnonzero(np.diff(traj.segment) != 0) + 1
    kinds = [(int(traj.segment[k - 1]), int(traj.segment[k])) for k in junctions]
    assert kinds[0] == (APPROACH, PAINT) and kinds[-1] == (PAINT, RETRACT)
    assert kinds.count((PAINT, TURNAROUND)) == N_PASSES - 1
    for k in junctions:
        # Over one control period, each quantity changes by at most its derivative's limit.
        assert np.all(np.abs(traj.q[k] - traj.q[k - 1]) <= v * dt * (1 + FD_LIMIT_RTOL))
        assert np.all(np.abs(traj.qd[k] - traj.qd[k - 1]) <= a * dt * (1 + FD_LIMIT_RTOL))
        assert np.all(np.abs(traj.qdd[k] - traj.qdd[k - 1]) <= j * dt * (1 + FD_LIMIT_RTOL))
        # The stored velocity is the derivative of the stored positions across the junction.
        fd = (traj.q[k + 1] - traj.q[k - 1]) / (2 * dt)
        np.testing.assert_allclose(fd, traj.qd[k], atol=a.max() * dt)


def test_program_starts_and_ends_at_home_at_rest(traj: JointTrajectory, robot) -> None:
    for k in (0, -1):
        np.testing.assert_allclose(traj.q[k], robot.q_home, atol=1e-9)
        np.testing.assert_allclose(traj.qd[k], 0.0, atol=1e-9)
        np.testing.assert_allclose(traj.qdd[k], 0.0, atol=1e-6)


def test_tcp_on_planned_path_during_paint(traj: JointTrajectory, plan: CoveragePlan) -> None:
    worst = 0.0
    for i, p in enumerate(plan.passes):
        idx = traj.pass_index == i
        s_plan = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                                 axis=1))])
        want = np.column_stack([np.interp(traj.s_pass_m[idx], s_plan, p.positions[:, c])
                                for c in range(3)])
        worst = max(worst, float(np.linalg.norm(traj.tcp_pos_world[idx] - want, axis=1).max()))
    assert worst < TCP_PATH_ATOL_M
    assert traj.meta["max_path_deviation_m"] < TCP_PATH_ATOL_M
    assert traj.meta["warnings"] == []


def test_tcp_speed_follows_plan_where_no_limit_binds(traj: JointTrajectory) -> None:
    assert traj.slowdowns == ()
    v = np.linalg.norm(traj.tcp_pos_world[2:] - traj.tcp_pos_world[:-2], axis=1) / (2 * traj.dt_s)
    mid = (traj.segment[1:-1] == PAINT) & (traj.segment[:-2] == PAINT) \
        & (traj.segment[2:] == PAINT)
    np.testing.assert_allclose(v[mid], traj.v_tcp_planned[1:-1][mid], rtol=SPEED_FOLLOW_RTOL)
    for s in traj.pass_summary:
        assert s["time_ratio"] == pytest.approx(1.0, rel=SPEED_FOLLOW_RTOL)


def test_varying_planned_speed_is_followed(robot) -> None:
    y = np.linspace(0.0, 1.0, SAMPLES)
    tr = _build(robot, _plan(0.4 + 0.3 * np.sin(np.pi * y) ** 2))
    assert tr.slowdowns == ()
    v = np.linalg.norm(np.diff(tr.tcp_pos_world, axis=0), axis=1) / tr.dt_s
    both = (tr.segment[1:] == PAINT) & (tr.segment[:-1] == PAINT)
    v_plan = 0.5 * (tr.v_tcp_planned[1:] + tr.v_tcp_planned[:-1])
    np.testing.assert_allclose(v[both], v_plan[both], rtol=SPEED_FOLLOW_RTOL)


def test_slowdowns_reported_when_limits_bind(fast_traj: JointTrajectory) -> None:
    assert len(fast_traj.slowdowns) >= 1
    names = {f"{j} {k}" for j in fast_traj.joint_names for k in ("velocity", "acceleration")}
    names.add("TCP acceleration")
    v = np.linalg.norm(np.diff(fast_traj.tcp_pos_world, axis=0), axis=1) / fast_traj.dt_s
    for sd in fast_traj.slowdowns:
        assert sd["max_speed_deficit_pct"] > 100 * TrajectorySettings().slowdown_threshold
        assert sd["limiting"] and set(sd["limiting"]) <= names
        assert sd["duration_s"] >= 0 and sd["s_end_m"] >= sd["s_start_m"]
        # Re-measure: inside the reported run the TCP is slower than planned.
        k0 = int(round(sd["t_start_s"] / fast_traj.dt_s))
        k1 = int(round(sd["t_end_s"] / fast_traj.dt_s))
        assert np.all(v[k0:k1] < fast_traj.v_tcp_planned[k0:k1])
    assert any(s["time_ratio"] > 1.01 for s in fast_traj.pass_summary)
    # Outside the reported runs the plan is still followed.
    slow = np.zeros(len(fast_traj.t_s), bool)
    for sd in fast_traj.slowdowns:
        slow[int(round(sd["t_start_s"] / fast_traj.dt_s)) - 1:
             int(round(sd["t_end_s"] / fast_traj.dt_s)) + 2] = True
    ok = (fast_traj.segment[1:] == PAINT) & (fast_traj.segment[:-1] == PAINT) & ~slow[1:] \
        & ~slow[:-1]
    v_plan = 0.5 * (fast_traj.v_tcp_planned[1:] + fast_traj.v_tcp_planned[:-1])
    np.testing.assert_allclose(v[ok], v_plan[ok], rtol=SPEED_FOLLOW_RTOL)


def test_paint_on_exactly_over_the_planned_samples(traj: JointTrajectory,
                                                   plan: CoveragePlan) -> None:
    assert not np.any(traj.paint_on & (traj.segment != PAINT))
    for i, p in enumerate(plan.passes):
        idx = traj.pass_index == i
        s_plan = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                                 axis=1))])
        on = s_plan[p.paint_on]
        s = traj.s_pass_m[idx]
        np.testing.assert_array_equal(traj.paint_on[idx], (s >= on[0]) & (s <= on[-1]))
    expected = sum(
        np.ptp(np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                               axis=1))])[p.paint_on])
        / p.speeds_m_s[0] for p in plan.passes)
    assert traj.paint_time_s == pytest.approx(expected, abs=N_PASSES * 2 * traj.dt_s)


def test_arrays_are_consistent(traj: JointTrajectory) -> None:
    off = traj.segment != PAINT
    assert np.all(traj.pass_index[off] == -1) and np.all(np.isnan(traj.s_pass_m[off]))
    assert np.all(traj.v_tcp_planned[off] == 0)
    np.testing.assert_allclose(np.diff(traj.t_s), traj.dt_s)
    assert traj.dt_s == pytest.approx(1e-3)
    assert traj.meta["cycle_time_s"] == traj.duration_s
    assert set(np.unique(traj.segment)) == {APPROACH, PAINT, TURNAROUND, RETRACT}
    # Direct turn-arounds (this strip's dip is below the default 50 mm), each measured.
    assert traj.meta["turnaround_max_dip_m"] <= TrajectorySettings().turnaround_max_dip_m
    assert [x["mode"] for x in traj.meta["turnarounds"]] == ["direct"] * (N_PASSES - 1)
    assert traj.meta["warnings"] == []


def test_save_load_round_trip(traj: JointTrajectory, tmp_path: Path) -> None:
    traj.save_npz(tmp_path / "t.npz")
    back = JointTrajectory.load_npz(tmp_path / "t.npz")
    for name in JointTrajectory._ARRAYS:
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name))
    assert back.pass_summary == traj.pass_summary and back.slowdowns == traj.slowdowns
    assert back.meta["settings"] == traj.meta["settings"]
    traj.save_csv(tmp_path / "t.csv")
    rows = np.loadtxt(tmp_path / "t.csv", delimiter=",", skiprows=1)
    assert rows.shape[0] == len(traj.t_s)


def test_build_is_deterministic(robot, plan, traj) -> None:
    again = _build(robot, plan)
    np.testing.assert_array_equal(again.q, traj.q)


def test_settings_round_trip_and_validation() -> None:
    s = TrajectorySettings(q_home=[0.0, 0.1, 0.2, 0.0, 0.5, 0.0], turnaround_clearance_m=0.05)
    assert TrajectorySettings.from_dict(s.to_dict()) == s
    with pytest.raises(TrajectoryError, match="acceleration_margin"):
        TrajectorySettings(acceleration_margin=1.5)
    with pytest.raises(TrajectoryError, match="unknown"):
        TrajectorySettings.from_dict({"rate": 1})


def test_wrong_ik_results_raise(robot, plan) -> None:
    with pytest.raises(TrajectoryError, match="passes"):
        build_program(robot, plan, np.eye(4), ik_results=[np.zeros((SAMPLES, 6))])
    bad = [np.tile(robot.q_home, (SAMPLES, 1))] * N_PASSES
    with pytest.raises(TrajectoryError, match="does not move"):
        build_program(robot, plan, np.eye(4), ik_results=bad)


def test_turnaround_via_clearance(robot, plan) -> None:
    # the wrist half-turns at each turn-around: a direct move dips below the passes
    tr = _build(robot, plan, keep_roll=False, turnaround_clearance_m=0.1,
                turnaround_max_dip_m=0.0)
    assert all(x["mode"] == "backed-off" for x in tr.meta["turnarounds"])
    assert tr.meta["turnaround_max_dip_m"] < 1e-3
    v, a, _ = _limits(tr)
    assert np.all(np.abs(np.diff(tr.q, 2, axis=0)) / tr.dt_s**2 <= a * (1 + FD_LIMIT_RTOL))
    # Backed off 0.1 m at both ends, the turn-around rises well above the pass ends.
    rise = []
    for i in range(N_PASSES - 1):
        k = np.flatnonzero(tr.pass_index == i)[-1] + 1
        turn = np.flatnonzero(tr.segment[k:] != TURNAROUND)[0] + k
        rise.append(tr.tcp_pos_world[k:turn, 2].max() - tr.tcp_pos_world[k - 1, 2])
    assert min(rise) > 0.09


def test_near_singular_wrist_pass_is_slowed_and_reported(robot) -> None:
    # A straight pass at constant orientation that passes 20 mm beside the wrist singularity
    # (q5 = 0): q5 dips to ~0.015 rad and joint 4 turns by ~3 rad within a few centimetres.
    q_s = np.array([0.3, 0.2, 0.0, 0.0, 0.03, 0.0])
    T = robot.fk(q_s)
    m = SAMPLES
    s = np.linspace(-0.4, 0.4, m)
    pos = T[:3, 3] + 0.02 * T[:3, 1] + s[:, None] * T[:3, 0]
    p = PassPlan(positions=pos, spray_axes=np.tile(T[:3, 2], (m, 1)),
                 travel_dirs=np.tile(T[:3, 0], (m, 1)), speeds_m_s=np.full(m, 0.5),
                 times_s=(s - s[0]) / 0.5, on_part=np.ones(m, bool), paint_on=np.ones(m, bool))
    plan = CoveragePlan(surface_name="wrist", applicator=Applicator.default(), passes=(p,))
    Tw = plan.tcp_frames(0)
    mid = m // 2
    q_mid = _ik(robot, Tw[mid:mid + 1], q_s + np.array([0, 0, 0, 0.5, 0, -0.5]))[0]
    q = np.vstack([_ik(robot, Tw[mid::-1], q_mid)[::-1], _ik(robot, Tw[mid + 1:], q_mid)])
    assert np.abs(q[:, 4]).min() < 0.05 and np.ptp(q[:, 3]) > 2.0  # near-singular indeed
    tr = build_program(robot, plan, np.eye(4), TrajectorySettings(), ik_results=[q])
    wrist = [sd for sd in tr.slowdowns if any(lim.startswith("joint4") for lim in sd["limiting"])]
    assert wrist and max(sd["max_speed_deficit_pct"] for sd in wrist) > 10.0
    assert tr.pass_summary[0]["time_ratio"] > 1.05
    v, a, _ = _limits(tr)
    assert np.all(np.abs(np.diff(tr.q, axis=0)) / tr.dt_s <= v * (1 + FD_LIMIT_RTOL))
    assert np.all(np.abs(np.diff(tr.q, 2, axis=0)) / tr.dt_s**2 <= a * (1 + FD_LIMIT_RTOL))
    assert tr.meta["max_path_deviation_m"] < TCP_PATH_ATOL_M


def test_passes_can_start_and_end_at_rest(robot, plan) -> None:
    tr = _build(robot, plan, join_at_speed=False)
    for i in range(N_PASSES):
        idx = np.flatnonzero(tr.pass_index == i)
        # First/last samples lie within one control period of the pass ends.
        v, a, _ = _limits(tr)
        assert np.all(np.abs(tr.qd[idx[0]]) <= a * tr.dt_s * (1 + FD_LIMIT_RTOL))
        assert np.all(np.abs(tr.qd[idx[-1]]) <= a * tr.dt_s * (1 + FD_LIMIT_RTOL))
    # Speeding up from rest is below the planned speed: reported, limited by acceleration.
    assert tr.slowdowns and all(any("acceleration" in lim for lim in sd["limiting"])
                                for sd in tr.slowdowns)


@pytest.mark.parametrize("max_dip", [np.inf, 0.005])
def test_turnaround_choice_is_measured_and_honoured(robot, plan, max_dip: float) -> None:
    tr = _build(robot, plan, turnaround_max_dip_m=max_dip)
    recs = tr.meta["turnarounds"]
    assert len(recs) == N_PASSES - 1
    for r in recs:
        assert r["dip_m"] <= max_dip or any(f"after pass {r['after_pass']}" in w
                                            for w in tr.meta["warnings"])
        assert r["mode"] == "direct" or r["direct_dip_m"] > max_dip
    # The dip re-measured on the sampled program agrees with the per-move records (the program
    # samples the moves on the 1 ms grid, the records at 1 ms from each move's start).
    assert tr.meta["turnaround_max_dip_m"] == pytest.approx(max(r["dip_m"] for r in recs),
                                                            abs=1e-3)
    if max_dip < 0.02:
        assert all(r["mode"] != "direct" for r in recs)
    v, a, j = _limits(tr)
    assert np.all(np.abs(np.diff(tr.q, 2, axis=0)) / tr.dt_s**2 <= a * (1 + FD_LIMIT_RTOL))


def _far(dx_m: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = dx_m
    return T


def test_part_out_of_reach_raises_unreachable_with_the_ik_verdict(robot, plan) -> None:
    """Panel 8 m away: no pose is reachable, so the error is the IK verdict and the fix, not a
    joint-limit message of some move between passes."""
    with pytest.raises(UnreachableError) as info:
        build_program(robot, plan, _far(8.0))
    msg = str(info.value)
    assert "UNREACHABLE 153/153 poses" in msg and "m out of reach" in msg
    assert "paintcell.robots.placement.find_base_pose" in msg and "\n" not in msg
    assert "nan" not in msg.lower()


def test_partly_unreachable_plan_that_cannot_be_built_raises_unreachable(robot, plan) -> None:
    """0.8 m further: 2 of 3 passes out of reach; the moves between them leave the joint limits.
    The error says so and carries the verdict (a `TrajectoryError` used to hide it)."""
    from paintcell.robots.paths import solve_paths

    T = _far(0.8)
    ik = solve_paths(robot, [T @ plan.tcp_frames(i) for i in range(N_PASSES)],
                     q_seed=robot.q_home)
    with pytest.raises(UnreachableError, match=r"UNREACHABLE \d+/153 poses.*the program cannot "
                                               r"be built \(.+\); move the part or the robot "
                                               r"base"):
        build_program(robot, plan, T, ik_results=ik)


def test_partly_unreachable_plan_is_still_timed_with_warnings(robot, plan) -> None:
    """A few poses off by millimetres: the program is built, the pass is named in
    meta['warnings'] and the reachability summary says not all poses are reachable."""
    from paintcell.robots.ik import IKPathResult
    from paintcell.robots.paths import solve_paths
    from paintcell.robots.reachability import ReachabilityReport

    paths = [plan.tcp_frames(i) for i in range(N_PASSES)]
    ik = solve_paths(robot, paths, q_seed=robot.q_home)
    q = ik[1].q.copy()
    q[24:27, 1] += 0.004                     # ~ 5 mm off the path at three samples
    rep = ReachabilityReport.measure(robot, q, paths[1])
    ik[1] = IKPathResult(q=q, reachability=rep, branch=ik[1].branch, method=ik[1].method)
    tr = build_program(robot, plan, np.eye(4), ik_results=ik)
    assert not tr.meta["reachability"]["all_reachable"]
    assert tr.meta["reachability"]["n_unreachable"] == 3
    assert any(w.startswith("pass 1: joint path") for w in tr.meta["warnings"])


def test_moving_vias_are_faster_and_keep_their_clearance(robot, plan) -> None:
    """Approach and retract pass their backed-off via moving, turn-arounds pick the fastest
    midpoint via within the dip limit; re-measured on the 1 kHz samples (FK), against the same
    program with stops at the vias."""
    # the wrist half-turns at each turn-around: a direct move dips below the passes
    at_rest = _build(robot, plan, keep_roll=False, moving_vias=False, turnaround_max_dip_m=0.01)
    tr = _build(robot, plan, keep_roll=False, turnaround_max_dip_m=0.01)
    for kind, end in ((APPROACH, 0), (RETRACT, -1)):
        sel = np.flatnonzero(tr.segment == kind)
        assert len(sel) < np.sum(at_rest.segment == kind)           # shorter than stopping
        T_pass = plan.tcp_frames(0 if kind == APPROACH else N_PASSES - 1)[end]
        c = TrajectorySettings().approach_clearance_m if kind == APPROACH \
            else TrajectorySettings().retract_clearance_m
        via = T_pass[:3, 3] - c * T_pass[:3, 2]
        gap = np.linalg.norm(tr.tcp_pos_world[sel] - via, axis=1)
        k = sel[np.argmin(gap)]
        assert gap.min() < 1e-3 and np.abs(tr.qd[k]).max() > 0.05   # through the via, moving
        # never nearer the part (along the spray axis) than the pass end
        assert np.max((tr.tcp_pos_world[sel] - T_pass[:3, 3]) @ T_pass[:3, 2]) < 1e-6
    assert tr.duration_s < at_rest.duration_s
    # at the default settings (turnaround_max_dip_m = 50 mm) too: a moving via never brings the
    # TCP nearer the part than the stop at it does (0 here: never nearer than the pass end)
    default = _build(robot, plan, keep_roll=False)
    for kind, end in ((APPROACH, 0), (RETRACT, -1)):
        T_pass = plan.tcp_frames(0 if kind == APPROACH else N_PASSES - 1)[end]
        rest_dip, dip = (np.max((t.tcp_pos_world[t.segment == kind] - T_pass[:3, 3])
                                @ T_pass[:3, 2]) for t in (at_rest, default))
        assert dip <= max(rest_dip, 0.0) + 1e-6 and rest_dip < 1e-6
    assert default.meta["approach_retract"]["approach"]["mode"] == "moving via"
    for i, t in enumerate(tr.meta["turnarounds"]):
        assert t["mode"] == "via" and t["direct_dip_m"] > 0.03       # direct would dip ~40 mm
        k0 = np.flatnonzero(tr.pass_index == i)[-1] + 1
        k1 = np.flatnonzero(tr.pass_index == i + 1)[0]
        a, b = plan.tcp_frames(i)[-1], plan.tcp_frames(i + 1)[0]
        z = (a[:3, 2] + b[:3, 2]) / np.linalg.norm(a[:3, 2] + b[:3, 2])
        deeper = max(0.0, float((b[:3, 3] - a[:3, 3]) @ z))
        assert np.max((tr.tcp_pos_world[k0:k1] - a[:3, 3]) @ z) - deeper <= 0.01 + 1e-6
    # stopping behind both pass ends (the only kind within a zero dip) is slower
    stop = _build(robot, plan, keep_roll=False, turnaround_max_dip_m=0.0)
    assert sum(t["duration_s"] for t in tr.meta["turnarounds"]) < \
        sum(t["duration_s"] for t in stop.meta["turnarounds"])
