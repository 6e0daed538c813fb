"""Honest reachability (paintcell.validation.honest_reach): jumps, wrist flips, contacts and
slowdowns count
against reachability, in the verdict and in the check row; a run with any of them is below 100 %.

The program is the real one (paintcell.robots.ik → paintcell.motion.trajectory.build_program) on
straight passes in front
of the ABB-style arm; the faults are real ones: a 2π turn of J6 inside a pass (same TCP pose, so
IK calls it reachable, but the arm must spin the wrist a full turn between two samples), and a
contact at a known time of the program.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import numpy as np
import pytest

from paintcell.execution.trace import Contact, ExecutedTrace
from paintcell.motion.joint_trajectory import PAINT, JointTrajectory
from paintcell.motion.trajectory import build_program
from paintcell.robots.catalog import load_robot
from paintcell.robots.ik import IKPathResult
from paintcell.robots.paths import solve_paths
from paintcell.robots.reachability import ReachabilityReport
from paintcell.surface.analytic import plane
from paintcell.validation.honest_reach import honest_reachability
from paintcell.validation.validate import validate
from paintcell.validation.validate_report import Thresholds
from tests.test_trajectory import N_PASSES, _plan


@functools.lru_cache(maxsize=1)
def _robot() -> Any:
    return load_robot("abb_paint")


@functools.lru_cache(maxsize=4)
def _program(jump: bool) -> tuple[Any, JointTrajectory]:
    robot, plan = _robot(), _plan()
    # x = travel: the arm poses these tests were built around (the wrist half-turns at each
    # turn-around; the elbow-flip test sweeps J3 of pass 1 through the stretched arm from there)
    paths = [plan.tcp_frames(i, keep_roll=False) for i in range(N_PASSES)]
    ik = solve_paths(robot, paths, q_seed=robot.q_home)
    if jump:
        q = ik[1].q.copy()
        half = len(q) // 2
        # J6 one full turn further from mid-pass on: the same TCP poses (FK is 2π-periodic),
        # inside J6's ±400° range, but a 2π step between two consecutive samples.
        q[half:, 5] += 2 * np.pi if q[half, 5] < 0 else -2 * np.pi
        rep = ReachabilityReport.measure(robot, q, paths[1])
        ik[1] = IKPathResult(q=q, reachability=rep, branch=ik[1].branch, method=ik[1].method)
    return plan, build_program(robot, plan, np.eye(4), ik_results=ik)


def _replay(traj: JointTrajectory, contacts: tuple[Contact, ...] = ()) -> ExecutedTrace:
    """The ideal execution of `traj` (what a kinematic replay records), with given contacts."""
    return ExecutedTrace(t_s=traj.t_s, q=traj.q, qd=traj.qd, tau=np.zeros_like(traj.q),
                         tcp_pos_world=traj.tcp_pos_world, tcp_rot_world=traj.tcp_rot_world,
                         paint_on=traj.paint_on, pass_index=traj.pass_index, mode="kinematic",
                         contacts=contacts)


def test_clean_program_is_fully_reachable() -> None:
    plan, traj = _program(False)
    h = honest_reachability(plan, traj, _replay(traj), traj.meta["reachability"])
    assert h is not None and h["per_pose"]
    assert h["n_lost"] == 0 and h["reachability_pct"] == 100.0


def test_joint_jump_is_not_100_percent() -> None:
    plan, traj = _program(True)
    reach = traj.meta["reachability"]
    assert reach["all_reachable"] and reach["n_jumps"] == 1   # IK alone would say 100 %
    h = honest_reachability(plan, traj, _replay(traj), reach)
    assert h is not None
    assert h["n_joint_jumps"] == 1 and h["reachability_pct"] < 100.0
    assert "joint jump" in h["verdict"]
    # The 2π wrist spin forces the time law far below the planned speed around the jump:
    # re-measured on the trajectory, independently of the module's own bookkeeping.
    sel = (traj.segment == PAINT) & (traj.pass_index == 1)
    v = np.linalg.norm(np.gradient(traj.tcp_pos_world, traj.t_s, axis=0), axis=1)[sel]
    assert np.min(v / traj.v_tcp_planned[sel]) < 0.5
    assert h["n_slowed_poses"] >= 1


def test_contact_is_not_100_percent_and_shows_in_the_check_row() -> None:
    plan, traj = _program(False)
    paint_t = traj.t_s[(traj.segment == PAINT) & (traj.pass_index == 2)]
    move_t = traj.t_s[traj.segment != PAINT]
    hits = (Contact(float(paint_t[len(paint_t) // 2]), "robot/flange", "part", 0.002),
            Contact(float(move_t[len(move_t) // 2]), "robot/link5", "booth", 0.001))
    h = honest_reachability(plan, traj, _replay(traj, hits), traj.meta["reachability"])
    assert h is not None and h["reachability_pct"] < 100.0
    assert 2 <= h["n_contact_poses"] <= 3        # the painted pose; the ends the move links
    # Through validate: the reachability check fails and says why.
    T = np.eye(4)        # a plate under the passes, at standoff, facing the bell
    T[:3, 3] = plan.passes[1].positions.mean(axis=0) - [0.0, 0.0, plan.applicator.standoff_m]
    surface = dataclasses.replace(plane(0.6, 1.0, 0.03).transformed(T), name=plan.surface_name)
    rep = validate(plan, surface, traj, _replay(traj, hits), np.eye(4),
                   Thresholds(max_executed_nsd_pct=None, max_loss_pp=None),
                   reachability=traj.meta["reachability"])
    check = next(c for c in rep.checks if c.name == "reachability")
    assert not check.passed and check.value < 100.0 and "in contact" in check.detail
    assert rep.metrics["ik_reachability_pct"] == pytest.approx(100.0)
    assert "in contact" in rep.reachability["verdict"]


def test_without_per_pose_arrays_the_losses_add_up() -> None:
    plan, traj = _program(False)
    summary = {k: v for k, v in traj.meta["reachability"].items() if k != "poses"}
    summary["n_reachable"] = summary["n_poses"] - 3
    h = honest_reachability(plan, traj, _replay(traj), summary)
    assert h is not None and not h["per_pose"]
    assert h["reachability_pct"] == pytest.approx(
        100.0 * (summary["n_poses"] - 3) / summary["n_poses"], abs=0.01)


def test_wrist_flip_on_a_rail_robot_is_the_arms_j5() -> None:
    """A rail robot's trajectory has the prismatic rail first: a sign change of sin of the
    arm's J5 (column 5) inside a pass is a wrist flip; one of the arm's J4 (column 4) is not."""
    plan, traj = _program(False)
    sel = np.flatnonzero((traj.segment == PAINT) & (traj.pass_index == 1))
    mid = sel[len(sel) // 2]

    def rail_traj(col: int) -> JointTrajectory:
        q = np.concatenate([np.zeros((len(traj.q), 1)), traj.q], axis=1)
        # the column's sin made positive before mid-pass and negative from it on
        q[sel, col] = np.where(sel < mid, 0.3, -0.3)
        return dataclasses.replace(traj, q=q, qd=np.zeros_like(q), qdd=np.zeros_like(q),
                                   joint_names=("rail", *traj.joint_names))

    reach = traj.meta["reachability"]
    wrist = rail_traj(5)
    h = honest_reachability(plan, wrist, _replay(wrist), reach)
    assert h is not None and h["n_config_flips"] == 1 and h["reachability_pct"] < 100.0
    elbow_side = rail_traj(4)
    h4 = honest_reachability(plan, elbow_side, _replay(elbow_side), reach)
    assert h4 is not None and h4["n_config_flips"] == 0


def test_configuration_signs_tell_the_eight_closed_form_branches_apart() -> None:
    """The 8 closed-form solutions of one flange pose (opw.inverse: shoulder t1 / t1 + π,
    elbow ±φ, wrist ±t5) are 8 configurations: their (shoulder, elbow, wrist) signs are 8
    distinct triples, and each solution's forward kinematics gives back the pose."""
    from paintcell.robots.opw import IRB4600_60_205, configuration_signs, forward, inverse

    p = IRB4600_60_205
    rng = np.random.default_rng(3)
    n_checked = 0
    for q in rng.uniform(-1.2, 1.2, size=(12, 6)):
        T = forward(p, q)[0]
        Q, ok = inverse(p, T)
        if not ok[0].all():
            continue
        assert np.allclose(forward(p, Q[0]), T, atol=1e-9)
        sg = configuration_signs(p, Q[0])
        assert np.all(sg != 0)
        assert len({tuple(r) for r in sg}) == 8
        n_checked += 1
    assert n_checked >= 6


def test_an_elbow_flip_mid_pass_is_not_100_percent() -> None:
    """A real flip: along pass 1 the elbow joint sweeps through the arm's stretched pose (J3 from
    0.3 rad on one side of it to 0.3 rad on the other, the other joints as programmed).
    Re-measured with Pinocchio's joint frames: the wrist centre (J5's origin) changes the side of
    the upper arm's line (J2 → J3) it lies on, about J2's axis — and honest reachability counts
    an elbow flip (and no shoulder flip) and is below 100 %; the unmodified program has none."""
    import pinocchio as pin

    from paintcell.robots.opw import IRB4600_60_205 as P

    robot = _robot()
    plan, traj = _program(False)
    h0 = honest_reachability(plan, traj, _replay(traj), traj.meta["reachability"])
    assert h0 is not None and h0["n_elbow_flips"] == 0 and h0["n_shoulder_flips"] == 0
    sel = np.flatnonzero((traj.segment == PAINT) & (traj.pass_index == 1))
    q3_stretched = (-np.arctan2(P.a2, P.c3) - P.offsets[2]) / P.signs[2]
    q = traj.q.copy()
    q[sel, 2] = q3_stretched + np.linspace(0.3, -0.3, len(sel))
    assert np.all(q[sel, 2] > robot.q_lower[2]) and np.all(q[sel, 2] < robot.q_upper[2])
    flipped = dataclasses.replace(traj, q=q)
    pm, pd = robot.pin_model, robot.pin_model.createData()
    side = []
    for j in sel[::25]:
        pin.forwardKinematics(pm, pd, q[j])
        j2, j3, wc = (pd.oMi[i].translation for i in (2, 3, 5))
        axis = pd.oMi[2].rotation[:, 1]              # J2 turns about its local y
        side.append(np.sign(np.cross(j3 - j2, wc - j2) @ axis))
    assert side[0] == -side[-1] != 0                 # the wrist centre crossed the upper arm's line
    h = honest_reachability(plan, flipped, _replay(flipped), traj.meta["reachability"])
    assert h is not None and h["n_elbow_flips"] == 1 and h["n_shoulder_flips"] == 0
    assert h["n_config_flips"] >= 1 and h["reachability_pct"] < 100.0
    assert "elbow" in h["verdict"]
