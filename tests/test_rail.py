"""A paint arm on a linear rail (paintcell.robots.rail): the same robot as on a fixed base at a
fixed rail
position (Pinocchio, MuJoCo), the per-pass rail position against a brute-force scan, and joint
and rail limits re-measured on a produced program.

(MuJoCo vs Pinocchio FK, gravity, random-torque stepping and the Jacobian of `irb5500_rail` are in
tests/test_robot_model.py.)
"""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.app.scenario_files import load_scenario
from paintcell.core.placement import pose
from paintcell.execution.cell import build_cell
from paintcell.execution.execute import execute
from paintcell.motion.joint_trajectory import PAINT
from paintcell.motion.trajectory import TrajectorySettings, build_program
from paintcell.robots import load_robot
from paintcell.robots.ik import IKSettings
from paintcell.robots.rail import RailSpec, best_rail_position, load_rail_robot, rail_cost
from paintcell.surface.parts import get_part
from tests.helpers import FK_AGREEMENT_ATOL_M

T_RAIL = pose((-0.5, 0.2, 1.0), (0.0, 0.0, 0.3))
ROOF_RAIL = "scenarios/roof_rail.toml"


@pytest.fixture(scope="module")
def rail_robot():
    return load_rail_robot("irb5500", T_world_rail=T_RAIL)


def _fixed_at(s_m: float):
    """The plain 6-axis arm, its base where the carriage at s_m puts it (computed here, not by
    paintcell.robots.rail: the rail frame's +y times s)."""
    T = T_RAIL.copy()
    T[:3, 3] += s_m * T_RAIL[:3, 1]
    return load_robot("irb5500", T_world_base=T)


def test_rail_at_a_fixed_position_is_the_fixed_base_robot(rail_robot):
    rng = np.random.default_rng(30)
    for s in (-1.7, 0.0, 0.8):
        fixed = _fixed_at(s)
        Q = rng.uniform(fixed.q_lower, fixed.q_upper, (100, 6))
        Q7 = np.column_stack([np.full(len(Q), s), Q])
        assert np.abs(rail_robot.fk_many(Q7) - fixed.fk_many(Q)).max() < FK_AGREEMENT_ATOL_M
        # The arm's Jacobian columns are the same; the rail's column is the rail direction.
        J7, J6 = rail_robot.jacobian(Q7[0]), fixed.jacobian(Q[0])
        assert np.abs(J7[:, 1:] - J6).max() < 1e-9
        assert np.allclose(J7[:3, 0], T_RAIL[:3, 1]) and np.allclose(J7[3:, 0], 0.0)
    # the carriage plans inside the rail's travel (±2 m by default), off its hard stops
    assert -2.0 < rail_robot.q_lower[0] < -1.998 and 1.998 < rail_robot.q_upper[0] < 2.0
    assert rail_robot.joint_names[0] == "rail" and rail_robot.wrist_joint_index == 5


def test_a_pass_past_the_travel_end_keeps_the_carriage_off_the_hard_stop(rail_robot):
    """A pass the arm paints best from 0.3 m beyond the rail's end: the carriage goes to the end
    of its travel but stays off the hard stop MuJoCo reads from the generated MJCF (a servo
    holding a joint on its stop presses it past, and a controller stops there)."""
    import mujoco

    hard = mujoco.MjModel.from_xml_path(str(rail_robot.mjcf_path)).jnt_range[0]
    fixed = _fixed_at(float(hard[1]) + 0.3)
    Q = np.tile(fixed.q_home, (30, 1))
    Q[:, 0] += np.linspace(-0.15, 0.15, 30)        # a sweep of J1 about the home pose
    s_m, feasible = best_rail_position(rail_robot, fixed.fk_many(Q), rail_robot.rail.arm.q_home,
                                       IKSettings())
    assert feasible
    assert hard[1] - 0.05 < s_m <= hard[1] - 0.0005


def test_a_carriage_parked_at_the_rails_end_starts_its_moves_inside_the_travel():
    """A home keyframe with the carriage at the rail's end (its hard stop, as MuJoCo reads the
    generated MJCF): the robot's home starts inside the planned travel, and a jerk-limited move
    from it, held to the robot's limits, is planned (ruckig) instead of refused."""
    import mujoco

    from paintcell.motion.moves import plan_move

    robot = load_rail_robot("irb5500", T_world_rail=T_RAIL, rail=RailSpec(home_m=2.0))
    model = mujoco.MjModel.from_xml_path(str(robot.mjcf_path))
    assert model.key_qpos[0, 0] == 2.0 == model.jnt_range[0, 1]
    assert robot.q_home[0] == robot.q_upper[0] < 2.0
    target = robot.q_home - np.array([0.5, 0.2, 0.1, 0.1, 0.0, 0.1, 0.0])
    z = np.zeros(robot.nq)
    move = plan_move(robot.q_home, z, z, target, z, z, robot.v_max, robot.a_max,
                     10 * robot.a_max, robot.q_lower, robot.q_upper)
    lo, hi = move.position_bounds()
    assert np.all(lo >= robot.q_lower - 1e-9) and np.all(hi <= robot.q_upper + 1e-9)


def test_rail_spec_rejects_bad_values():
    with pytest.raises(Exception, match="lower_m"):
        RailSpec(lower_m=1.0, upper_m=-1.0)
    with pytest.raises(Exception, match="home_m"):
        RailSpec(home_m=5.0)


@pytest.fixture(scope="module")
def roof_case():
    from paintcell.app.pipeline import load_robot_for, load_surface, make_plan

    scn = load_scenario(ROOF_RAIL)
    surface = load_surface(scn, fast=True)
    plan = make_plan(scn, surface, fast=True)
    return scn, surface, plan, load_robot_for(scn)


def test_rail_position_is_the_minimum_of_its_cost(roof_case):
    """The scan + Brent search lands on the minimum of the cost; a dense brute-force scan of the
    whole rail finds nothing lower."""
    scn, _, plan, robot = roof_case
    s = IKSettings()
    pref = robot.rail.arm.q_home
    for i in (0, 2):
        T = scn.part_placement.matrix @ plan.tcp_frames(i)
        sub = T[np.unique(np.linspace(0, len(T) - 1, 40).astype(int))]
        s_best, feasible = best_rail_position(robot, T, pref, s)
        assert feasible
        c_best = rail_cost(robot, sub, s_best, pref, s, (len(T) - 1) / (len(sub) - 1))[0]
        js = (len(T) - 1) / (len(sub) - 1)
        brute = min(rail_cost(robot, sub, x, pref, s, js)[0] for x in np.linspace(-2, 2, 401))
        assert c_best <= brute + 1e-6


def test_program_respects_joint_and_rail_limits(roof_case):
    """Limits re-measured on the produced program by finite differences of q alone."""
    scn, _, plan, robot = roof_case
    settings = TrajectorySettings(**scn.trajectory)
    traj = build_program(robot, plan, scn.part_placement.matrix, settings)
    assert traj.meta["reachability"]["all_reachable"]
    q, dt = traj.q, traj.dt_s
    assert np.all(q >= robot.q_lower - 1e-9) and np.all(q <= robot.q_upper + 1e-9)
    qd = np.diff(q, axis=0) / dt
    qdd = np.diff(q, 2, axis=0) / dt**2
    # Finite differences of the 1 kHz samples: within the robot's limits (rail: 1.5 m/s,
    # 4 m/s²). The planning margins (95 % / 90 %) hold on the paint passes; a ruckig
    # turn-around of this program uses 95.6 % of J3's speed (0.6 % over its margin, noted in
    # the closing note), so the hard limit is what is asserted here.
    assert np.all(np.abs(qd).max(axis=0) <= robot.v_max)
    assert np.all(np.abs(qdd).max(axis=0) <= robot.a_max * 1.001)
    paint = traj.segment[1:] == PAINT
    assert np.all(np.abs(qd[paint]).max(axis=0) <= settings.velocity_margin * robot.v_max * 1.001)
    # The rail moves between passes and stands still while painting.
    rail_in_pass = [np.ptp(q[traj.pass_index == i, 0]) for i in range(len(plan.passes))]
    assert max(rail_in_pass) < 1e-9
    assert np.ptp(q[:, 0]) > 0.1


def test_a_program_homed_at_the_rails_end_starts_just_inside_it(roof_case):
    """A home written with the carriage at the rail's end (a booth's `home`, the scenario's
    `[trajectory] q_home`), the end as MuJoCo reads it from the robot's MJCF: the program is
    built, starts and ends at that home moved onto the planned travel, and stays in it."""
    import dataclasses

    import mujoco

    scn, _, plan, robot = roof_case
    end = float(mujoco.MjModel.from_xml_path(str(robot.mjcf_path)).jnt_range[0, 1])
    home = (end, *robot.q_home[1:])
    settings = dataclasses.replace(TrajectorySettings(**scn.trajectory), q_home=home)
    traj = build_program(robot, plan, scn.part_placement.matrix, settings)
    want = np.array([robot.q_upper[0], *robot.q_home[1:]])
    assert robot.q_upper[0] < end
    assert np.array_equal(traj.q[0], want) and np.allclose(traj.q[-1], want, rtol=0, atol=1e-12)
    assert np.all(traj.q >= robot.q_lower - 1e-9) and np.all(traj.q <= robot.q_upper + 1e-9)


def test_rail_and_fixed_cells_execute_the_same_tcp_path(roof_case):
    """MuJoCo: a program with the carriage held at s in the rail cell gives the TCP trace of the
    same arm program in a fixed-base cell at that position (kinematic execution)."""
    scn, surface, plan, robot = roof_case
    s = 0.4
    fixed = _fixed_at(s).placed(_fixed_at(s).T_world_base)
    rail = robot.placed(T_RAIL)
    traj6 = build_program(fixed, plan, scn.part_placement.matrix,
                          TrajectorySettings(q_home=(0.0, -0.6, 0.3, 0.0, 0.9, 0.0),
                                             approach_clearance_m=0.15,
                                             retract_clearance_m=0.3))
    from paintcell.motion.joint_trajectory import JointTrajectory

    K = 6000   # the approach and the first pass (6 s) keep the test short
    arrays = {name: getattr(traj6, name)[:K] for name in JointTrajectory._ARRAYS}
    traj6 = JointTrajectory(**arrays, robot_name=traj6.robot_name,
                            joint_names=traj6.joint_names, meta=traj6.meta)
    arrays["q"] = np.column_stack([np.full(K, s), traj6.q])
    arrays["qd"] = np.column_stack([np.zeros(K), traj6.qd])
    arrays["qdd"] = np.column_stack([np.zeros(K), traj6.qdd])
    traj7 = JointTrajectory(**arrays, robot_name=rail.name, joint_names=rail.joint_names,
                            meta=traj6.meta)
    part = get_part("roof", resolution_m=0.05)
    tr6 = execute(build_cell(fixed, part, scn.part_placement.matrix), traj6, mode="kinematic")
    tr7 = execute(build_cell(rail, part, scn.part_placement.matrix), traj7, mode="kinematic")
    assert np.abs(tr6.tcp_pos_world - tr7.tcp_pos_world).max() < FK_AGREEMENT_ATOL_M
    assert np.abs(tr6.tcp_rot_world - tr7.tcp_rot_world).max() < FK_AGREEMENT_ATOL_M


def test_refined_pass_keeps_the_carriage_still(roof_case):
    """Where the spline through a pass's IK samples strays, knots are inserted and the TCP moved
    back onto the plan: on a rail robot by the arm alone (the carriage stays where the rail
    placement put it for the pass). Every 8th IK sample of a roof pass leaves the spline
    centimetres off the path, so knots are inserted; re-measured: the rail column is exactly
    constant, and the inserted knots are on the path."""
    from paintcell.motion.trajectory import refined_path
    from paintcell.robots.paths import solve_paths

    scn, _, plan, robot = roof_case
    T = scn.part_placement.matrix @ plan.tcp_frames(1)
    q = solve_paths(robot, [T])[0].q
    p = T[:, :3, 3]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    keep = np.unique(np.r_[np.arange(0, len(T), 8), len(T) - 1])

    def fk_pos(Q):
        return robot.fk_many(Q)[:, :3, 3]

    path, dev = refined_path(robot, fk_pos, s[keep], p[keep], q[keep], 1e-4)
    assert len(path.s_knots) > len(keep)                  # knots were inserted
    assert np.ptp(path.q_knots[:, 0]) == 0.0              # the carriage did not move
    on = np.isin(path.s_knots, s[keep], invert=True)
    p_new = fk_pos(path.q_knots[on])
    p_lin = np.column_stack([np.interp(path.s_knots[on], s[keep], p[keep][:, k]) for k in range(3)])
    assert np.linalg.norm(p_new - p_lin, axis=1).max() < 1e-4


def test_rail_scan_in_one_call_is_the_cost_at_each_position(rail_robot):
    """The carriage scan solves the closed-form IK of every rail position in one call, without
    re-placing the arm. Checked at each position against the plain 6-axis arm standing where the
    carriage puts it (`_fixed_at`, its own closed-form branches): the same feasibility, the
    chosen branch is one of that arm's feasible branches, and the cost is the docstring's, mean
    Σ_{J1..J3} ((q − q_pref) / range)² (+ the margin term, zero at a comfortable margin), along a
    horizontal pass 1.1 m in front of the rail, feasible somewhere and not everywhere."""
    from paintcell.robots.ik import branch_feasibility, opw_branches
    from paintcell.robots.rail import COMFORT_MARGIN_RAD, rail_branch, rail_branches

    y = np.linspace(-0.6, 0.6, 40)
    T = np.tile(np.eye(4), (len(y), 1, 1))
    T[:, :3, :3] = [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]   # spray axis +x
    T[:, :3, 3] = np.column_stack([np.full_like(y, 1.1), y + 0.2, np.full_like(y, 1.2)])
    s = IKSettings()
    pref = rail_robot.rail.arm.q_home
    grid = np.linspace(-2.0, 2.0, 21)
    got = rail_branches(rail_robot, T, grid, pref, s, jump_scale=1.5)
    feasible = 0
    for s_m, (c, ok, Q) in zip(grid, got, strict=True):
        assert rail_branch(rail_robot, T, float(s_m), pref, s, 1.5)[:2] == (c, ok)
        arm = _fixed_at(float(s_m))
        Qf, _, within = opw_branches(arm, T, pref)
        st = branch_feasibility(arm, Qf, within, s, jump_scale=1.5)
        assert ok == bool(st.feasible.any())
        if not ok:
            assert Q is None and c >= 1e3
            continue
        feasible += 1
        b = [k for k in range(len(Qf)) if st.feasible[k] and np.allclose(Qf[k], Q, atol=1e-9)]
        assert b, "the chosen branch is none of the fixed arm's feasible branches"
        span = (arm.q_upper - arm.q_lower)[:3]
        dev = np.mean(np.sum(((Q[:, :3] - pref[:3]) / span) ** 2, axis=1))
        short = max(0.0, COMFORT_MARGIN_RAD - float(st.margin[b[0]])) / COMFORT_MARGIN_RAD
        assert c == pytest.approx(dev + short ** 2, rel=1e-9, abs=1e-12)
    assert 0 < feasible < len(grid)


def _pass_with_spin(spin_rad: float) -> np.ndarray:
    """A horizontal pass of 400 poses 1.1 m in front of the rail (spray axis +x), the tool
    spun by spin_rad about its spray axis in one step between poses 199 and 200."""
    y = np.linspace(-0.6, 0.6, 400)
    T = np.tile(np.eye(4), (len(y), 1, 1))
    T[:, :3, :3] = [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]
    c, s = np.cos(spin_rad), np.sin(spin_rad)
    T[200:, :3, :3] = T[200:, :3, :3] @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T[:, :3, 3] = np.column_stack([np.full_like(y, 1.1), y + 0.2, np.full_like(y, 1.2)])
    return T


def test_a_joint_jump_between_skipped_poses_is_not_feasible(rail_robot):
    """A 1.5 rad spin of the tool in one step needs some joint to turn by at least 1.5 / 6 =
    0.25 rad in that step (a rotation's angle is at most the sum of its joints' turns), above
    the 0.2 rad jump threshold, however the arm stands; the step lies between two of the 40
    poses the carriage search scores. Neither the rail search nor the booth's pass check calls
    it feasible; the same pass without the spin is, and the position the search returns is
    re-checked on every pose with the plain arm standing there (its own closed-form branches)."""
    from paintcell.booth.booth import pass_feasible
    from paintcell.robots.ik import branch_feasibility, opw_branches

    s = IKSettings()
    pref = rail_robot.rail.arm.q_home
    smooth, spun = _pass_with_spin(0.0), _pass_with_spin(1.5)
    s_m, ok = best_rail_position(rail_robot, smooth, pref, s)
    assert ok and pass_feasible(rail_robot, smooth)
    arm = _fixed_at(s_m)
    Q, _, within = opw_branches(arm, smooth, pref)
    assert branch_feasibility(arm, Q, within, s).feasible.any()
    assert pass_feasible(arm, smooth)
    assert not best_rail_position(rail_robot, spun, pref, s)[1]
    assert not pass_feasible(rail_robot, spun)
    assert not pass_feasible(arm, spun)


def test_rail_scan_of_no_positions_is_empty(rail_robot):
    """A scan over no carriage positions (e.g. none of a grid passed a screen) gives no results,
    not an error."""
    from paintcell.robots.rail import feasible_positions, rail_branches

    T = _pass_with_spin(0.0)
    pref = rail_robot.rail.arm.q_home
    assert rail_branches(rail_robot, T, np.array([]), pref, IKSettings()) == []
    assert feasible_positions(rail_robot, T, np.array([]), pref, IKSettings()).shape == (0,)


def test_feasible_positions_any_and_ends_agree_with_every_position(rail_robot):
    """need="any" finds a position exactly when some position is feasible on every pose, and
    need="ends" the least and the most of them, as confirming every position does."""
    from paintcell.robots.rail import feasible_positions

    pref = rail_robot.rail.arm.q_home
    grid = np.linspace(-2.0, 2.0, 35)
    for T in (_pass_with_spin(0.0), _pass_with_spin(1.5)):
        every = feasible_positions(rail_robot, T, grid, pref, IKSettings())
        anyone = feasible_positions(rail_robot, T, grid, pref, IKSettings(), need="any")
        ends = feasible_positions(rail_robot, T, grid, pref, IKSettings(), need="ends")
        assert anyone.any() == every.any() and not (anyone & ~every).any()
        assert anyone.sum() <= 1 and not (ends & ~every).any()
        if every.any():
            assert grid[ends].min() == grid[every].min()
            assert grid[ends].max() == grid[every].max()
    assert every.sum() == 0 and feasible_positions(rail_robot, _pass_with_spin(0.0), grid, pref,
                                                   IKSettings()).sum() > 2


def test_a_pass_of_steps_under_the_jump_threshold_is_not_screened_out(rail_robot):
    """A 57-pose pass drawn by FK from the home pose with joint 1 swinging 0.15 rad a step (a
    triangle wave, 0 → 0.3 → 0 rad): every step is under the 0.2 rad jump threshold, so it is
    feasible on every pose. The 40 poses the search scores leave gaps of one and two steps (mean
    56/39 = 1.44): joint 1 turns 0.3 rad across the gap from pose 2 to pose 4, above a threshold
    scaled by the mean gap (0.287 rad) and under one scaled by the widest (0.4 rad). The booth's
    pass check and the carriage search call it feasible, on the fixed arm and on the rail."""
    from paintcell.booth.booth import pass_feasible
    from paintcell.robots.ik import branch_feasibility, opw_branches
    from paintcell.robots.rail import feasible_positions

    arm = _fixed_at(0.0)
    wave = 0.15 * np.abs((np.arange(57) + 2) % 4 - 2)       # 0, .15, .3, .15, 0, ...
    Q = np.tile(arm.q_home, (57, 1))
    Q[:, 0] += wave - wave[0]
    assert np.abs(np.diff(Q, axis=0)).max() == pytest.approx(0.15)
    T = arm.fk_many(Q)
    Qb, _, within = opw_branches(arm, T, arm.q_home)
    stats = branch_feasibility(arm, Qb, within, IKSettings())
    assert stats.feasible.any() and stats.jump[stats.feasible].min() < 0.2
    assert pass_feasible(arm, T)
    assert feasible_positions(rail_robot, T, np.array([0.0]), rail_robot.rail.arm.q_home,
                              IKSettings()).all()


def test_the_search_falls_back_to_the_best_position_confirmed_on_every_pose(rail_robot,
                                                                            monkeypatch):
    """Where the position the search picks on its 40 poses fails on the whole pass (a joint jump
    between skipped poses; here that position is declared infeasible on the whole pass), the
    search returns the scan position of least cost among those feasible on every pose: the
    same as a brute force over the 41 positions of the scan, each judged on all 400 poses."""
    from paintcell.robots import rail

    s = IKSettings()
    pref = rail_robot.rail.arm.q_home
    T = _pass_with_spin(0.0)
    s0, ok = best_rail_position(rail_robot, T, pref, s)
    assert ok
    grid = np.linspace(*rail.travel_m(rail_robot), 41)
    whole = rail.rail_branches(rail_robot, T, grid, pref, s)
    want = min(((c, g) for g, (c, f, _) in zip(grid, whole, strict=True)
                if f and abs(g - s0) > 1e-9), key=lambda cg: cg[0])[1]
    real = rail.rail_branches

    def jump_at_s0(robot, T_world_tcp, s_grid, *args, **kwargs):
        out = real(robot, T_world_tcp, s_grid, *args, **kwargs)
        if len(T_world_tcp) == len(T):
            out = [(1e3, False, None) if abs(g - s0) < 1e-9 else r
                   for g, r in zip(s_grid, out, strict=True)]
        return out

    monkeypatch.setattr(rail, "rail_branches", jump_at_s0)
    s1, ok1 = best_rail_position(rail_robot, T, pref, s)
    assert ok1 and s1 == pytest.approx(want, abs=1e-12) and abs(s1 - s0) > 1e-6
    assert real(rail_robot, T, np.array([s1]), pref, s)[0][1]
