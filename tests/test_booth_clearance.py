"""The booth's clearance to the whole body (paintcell.booth.booth_clearance), the reversed
pass order of a part (BodyPart.reverse) and the home on the other wrist branch, against
independent truth: capsule-to-plane distances in closed form, the film of the same samples, the
forward kinematics of both homes."""

from __future__ import annotations

import numpy as np
import pytest

from paintcell.booth.booth_build import reversed_plan
from paintcell.booth.booth_clearance import BodyProbe, wrist_flipped_home
from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.paint.applicator import Applicator
from paintcell.paint.deposition import thickness
from paintcell.robots import load_robot
from paintcell.surface import parts

HOME = np.array([0.0, -0.6, 0.3, 0.0, 0.9, 0.0])
#: the arm reaching forward, its spray axis ≈ +x (the whole arm behind a plane across it).
REACH = np.array([0.0, 0.3, 0.0, 0.0, -1.0, 0.0])
#: half the thickness of the part's collision slabs (paintcell.execution.cell_part) [m].
HALF_SHELL_M = 0.001


def _panel_facing_the_bell(robot, q, gap_m):
    """The library panel (flat, +z painted) in the plane through the TCP of FK(q), facing the
    bell, moved gap_m [m] farther along the spray axis; returns (surface, T_world_part, n, p0):
    the plane's unit normal toward the robot and a point of it."""
    s = parts.get_part("panel", resolution_m=0.05)
    T_tcp = robot.fk(q)
    z = T_tcp[:3, 2]                        # spray axis, toward the part
    T = np.eye(4)
    T[:3, :3] = T_tcp[:3, :3] @ np.diag([1.0, -1.0, -1.0])   # part +z = −spray axis
    T[:3, 3] = T_tcp[:3, 3] + gap_m * z
    return s, T, -z, T[:3, 3]


def _capsule_plane_distance(probe, q, n, p0):
    """Smallest distance [m] from the robot's capsule and sphere collision geoms to the plane
    (n, p0), in closed form from MuJoCo's geom poses; and a lower bound for its other collision
    geoms (their bounding spheres)."""
    import mujoco

    m = probe.bcell.cell.model
    d = mujoco.MjData(m)
    d.qpos[probe.bcell.cell.qpos_adr[probe.bcell.columns[0]]] = q
    mujoco.mj_kinematics(m, d)
    best, others = np.inf, np.inf
    for g in probe._robot_geoms:
        c = d.geom_xpos[g]
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
            axis = d.geom_xmat[g].reshape(3, 3)[:, 2]
            ends = [c + m.geom_size[g][1] * axis, c - m.geom_size[g][1] * axis]
            best = min(best, min(float(n @ (e - p0)) for e in ends) - m.geom_size[g][0])
        elif m.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE:
            best = min(best, float(n @ (c - p0)) - m.geom_size[g][0])
        else:
            others = min(others, float(n @ (c - p0)) - m.geom_rbound[g])
    return best, others


@pytest.mark.parametrize("gap_m", [0.05, 0.2])
def test_body_distance_is_the_closed_form_capsule_to_plane_distance(gap_m):
    """A flat panel across the spray axis: the probe's robot–body distance equals the smallest
    capsule-to-plane distance of the robot's collision geoms (minus the slab's half thickness);
    a distance beyond the margin reads as the margin; pushed into the panel it is negative."""
    robot = load_robot("irb5500")
    s, T, n, p0 = _panel_facing_the_bell(robot, REACH, gap_m)
    probe = BodyProbe(robot, s, T, np.zeros(len(s.vertices), int))
    want, others = _capsule_plane_distance(probe, REACH, n, p0)
    assert want > 0 and others > want + 0.05     # the nearest geom is a capsule or a sphere
    got = probe.distance(REACH[None], margin_m=0.5)
    assert got == pytest.approx(want - HALF_SHELL_M, abs=2e-4)
    assert probe.distance(REACH[None], margin_m=0.5 * want) == 0.5 * want
    c = probe.clearance(np.repeat(REACH[None], 3, axis=0), np.array([0.0, 0.01, 0.02]), 0.5)
    assert c.min_distance_m == pytest.approx(got) and c.n_close == 3 and c.parts == (0,)
    assert c.first_t_s == 0.0 and not c.clear
    assert probe.clearance(REACH[None], np.zeros(1), 0.5 * want).clear
    s, T, n, p0 = _panel_facing_the_bell(robot, REACH, -(gap_m + 0.1))   # the bell through it
    assert BodyProbe(robot, s, T, np.zeros(len(s.vertices), int)).distance(REACH[None], 0.5) < 0


def test_reversed_part_paints_the_same_film():
    """Reversed order and direction: the first sample is the old last one, every pass keeps its
    length and duration, and the film of the reversed plan is the film of the plan (the same
    samples; the bell's footprint is symmetric under reversed travel) to round-off."""
    s = parts.get_part("hood", resolution_m=0.06)
    plan = plan_coverage(s, Applicator.default(),
                         PlannerSettings(optimize_speed=False, film_guard=False))
    rev = reversed_plan(plan)
    assert len(rev.passes) == len(plan.passes)
    np.testing.assert_array_equal(rev.passes[0].positions[0], plan.passes[-1].positions[-1])
    for a, b in zip(rev.passes, plan.passes[::-1], strict=True):
        assert a.times_s[0] == 0.0 and a.times_s[-1] == pytest.approx(b.times_s[-1], rel=1e-12)
        np.testing.assert_allclose(np.diff(a.times_s), np.diff(b.times_s)[::-1], rtol=1e-9)
    f0 = thickness(plan.applicator, plan.gun_samples(), s.vertices, s.normals)
    f1 = thickness(rev.applicator, rev.gun_samples(), s.vertices, s.normals)
    np.testing.assert_allclose(f1, f0, rtol=1e-9, atol=1e-12 * f0.max())


def test_home_on_the_other_wrist_branch_is_the_same_pose():
    """(q4 ± π, −q5, q6 ± π) is the same TCP pose (forward kinematics), inside the limits, on the
    branch of the passes; a home already on that branch is kept (None)."""
    robot = load_robot("irb5500")
    near = HOME.copy()
    near[3:] = [-2.0, -1.5, -1.4]
    h = wrist_flipped_home(robot, HOME, near)
    assert h is not None and np.sign(h[4]) == np.sign(near[4])
    np.testing.assert_allclose(robot.fk(h), robot.fk(HOME), atol=1e-9)
    assert np.all(h >= robot.q_lower) and np.all(h <= robot.q_upper)
    assert abs(h[3] - HOME[3]) == pytest.approx(np.pi)
    assert abs(h[5] - HOME[5]) == pytest.approx(np.pi)
    assert wrist_flipped_home(robot, HOME, HOME) is None


def test_a_back_off_rung_out_of_reach_does_not_end_the_ladder(monkeypatch):
    """`booth_job_programs._clear_program` climbs its ladder (as set, folded moves, farther
    back-offs) until a program keeps clear of the body. A rung whose program cannot be built (a
    2x back-off's via pose out of reach raises) must not end the climb: the 3x rung that keeps
    clear is returned, and the tries record the programs that were measured."""
    from types import SimpleNamespace

    from paintcell.booth import booth_job_programs as bjp
    from paintcell.booth.booth_clearance import CLEAR_FACTORS, Clearance
    from paintcell.motion import trajectory
    from paintcell.motion.joint_trajectory import TrajectoryError
    from paintcell.motion.trajectory import TrajectorySettings

    built = []

    def fake_build(robot, plan, T, st, ik_results=None):
        built.append(st)
        if len(built) == 3:                                 # the 2x back-off rung
            raise TrajectoryError("a backed-off via pose is not reachable within the limits")
        return SimpleNamespace(q=np.zeros((2, 6)), t_s=np.array([0.0, 1.0]), meta={},
                               rung=len(built))

    def fake_clearance(q, t, margin):
        clear = len(built) == 4
        return Clearance(margin if clear else 0.004, 0 if clear else 3,
                         None if clear else 0.5, () if clear else ("link4",), ())

    monkeypatch.setattr(trajectory, "build_program", fake_build)
    robot = SimpleNamespace(q_home=HOME, rail=None)
    booth = SimpleNamespace(body_clearance_m=0.01, parts=[])
    probe = SimpleNamespace(clearance=fake_clearance)
    traj = bjp._clear_program(booth, "r", robot, None, np.eye(4), TrajectorySettings(), probe)
    assert traj.rung == 4 and len(built) == 4 and CLEAR_FACTORS[:2] == (2.0, 3.0)
    tries = traj.meta["body_clearance"]["tries"]
    assert [t["backoff_factor"] for t in tries] == [1.0, 1.0, 3.0]
    assert tries[-1]["min_distance_m"] == 0.01 and tries[0]["min_distance_m"] == 0.004
