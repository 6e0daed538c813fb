"""`paintcell init`'s program check (`paintcell.app.init_verify.ProgramCheck`): a cell whose
program meets the part is refused — and the run's own MuJoCo cell, replayed pose by pose,
touches it; a cell whose default moves pass through the part but whose folded moves do not gets
`fold_moves` — and the replay of the folded program touches nothing.

Independent truth: the execution's MuJoCo model (`paintcell.execution.cell.build_cell`) and
its own collision detection (`mj_forward` contacts), not the clearance sweep's
`mj_geomDistance`."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from paintcell.app.init_verify import FOLD_BELOW_M, ProgramCheck
from paintcell.app.pipeline import (
    load_robot_for,
    load_surface,
    make_plan,
    make_trajectory,
)
from paintcell.app.scenario_files import load_scenario
from paintcell.execution.cell import build_cell
from paintcell.motion.joint_trajectory import PAINT, JointTrajectory
from paintcell.surface.analytic import plane
from paintcell.surface.surface_data import surface_from_triangles

PANEL = Path(__file__).resolve().parents[1] / "scenarios" / "panel.toml"


@pytest.fixture(scope="module")
def panel() -> tuple:
    scn = load_scenario(PANEL)
    surf = load_surface(scn, fast=True)
    return scn, surf, make_plan(scn, surf, fast=True)


def _with_plate(surf, centre_world: np.ndarray, normal_world: np.ndarray, size_m: float,
                T_world_part: np.ndarray):
    """The part plus a square plate (size_m, 25 mm grid) at centre_world facing normal_world,
    both in the part frame."""
    p = plane(size_m, size_m, 0.025)
    n = normal_world / np.linalg.norm(normal_world)
    a = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    R = np.column_stack([a, np.cross(n, a), n])
    world = p.vertices @ R.T + centre_world
    T_pw = np.linalg.inv(T_world_part)
    v = np.vstack([surf.vertices, world @ T_pw[:3, :3].T + T_pw[:3, 3]])
    f = np.vstack([surf.faces, p.faces + len(surf.vertices)])
    return surface_from_triangles(surf.name, v, f)


def _touches(scn, surf, traj) -> int:
    """Samples (every 10 ms) at which the run's cell has a robot–part contact, replayed
    kinematically."""
    robot = load_robot_for(scn)
    cell = build_cell(robot, surf, scn.part_placement.matrix, booth=False)
    m, d = cell.model, mujoco.MjData(cell.model)
    robot_body = np.zeros(m.nbody, bool)
    robot_body[cell.robot_body_ids] = True
    n = 0
    for q in traj.q[::max(1, int(round(0.01 / (traj.t_s[1] - traj.t_s[0]))))]:
        d.qpos[cell.qpos_adr] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        b = m.geom_bodyid[d.contact.geom[:d.ncon]]
        n += bool(np.any(robot_body[b[:, 0]] != robot_body[b[:, 1]]))
    return n


def _check(scn, plan, surf) -> ProgramCheck:
    return ProgramCheck(lambda name, T, tr: replace(scn, robot=name, trajectory={
        **scn.trajectory, **tr}), plan, surf)


def test_a_program_through_the_part_is_refused_and_a_clear_one_is_kept(panel) -> None:
    scn, surf, plan = panel
    T_base = scn.base.matrix
    # a 2 m wall halfway between the base and the panel: the arm reaches through it
    wall = _with_plate(surf, np.array([0.35, 0.0, 1.2]), np.array([1.0, 0.0, 0.0]), 2.0,
                       scn.part_placement.matrix)
    check = _check(scn, plan, wall)
    why = check("abb_paint", T_base)
    assert why is not None and why.startswith("its program meets the part (") and "\n" not in why
    traj = make_trajectory(scn, load_robot_for(scn), plan)
    assert _touches(scn, wall, traj) > 0                       # the truth: it does

    clear = _check(scn, plan, surf)
    assert clear("abb_paint", T_base) is None and clear.trajectory["abb_paint"] == {}
    assert _touches(scn, surf, traj) == 0                      # the truth: it does not


def test_moves_that_pass_through_the_part_are_folded(panel) -> None:
    """A small plate where the default program's flange passes, away from the folded
    program: init keeps the folded moves."""
    scn, surf, plan = panel
    robot = load_robot_for(scn)
    plain = make_trajectory(scn, robot, plan)
    folded = make_trajectory(replace(scn, trajectory={**scn.trajectory, "fold_moves": True}),
                             robot, plan)
    cell = build_cell(robot, surf, scn.part_placement.matrix, booth=False)
    m, d = cell.model, mujoco.MjData(cell.model)
    g = np.flatnonzero(np.isin(m.geom_bodyid, cell.robot_body_ids) & (m.geom_contype > 0))
    centre, axis = [], []
    for q in folded.q[::10]:                     # every 10 ms
        d.qpos[cell.qpos_adr] = q
        mujoco.mj_kinematics(m, d)
        centre.append(d.geom_xpos[g].copy())
        axis.append(d.geom_xmat[g].reshape(-1, 3, 3)[:, :, 2].copy())
    C, A = np.concatenate(centre), np.concatenate(axis)
    kind, size = np.tile(m.geom_type[g], len(centre)), np.tile(m.geom_size[g], (len(centre), 1))
    bound = np.tile(m.geom_rbound[g], len(centre))
    capsule = kind == mujoco.mjtGeom.mjGEOM_CAPSULE

    def folded_distance(p: np.ndarray) -> float:
        """From p to the folded program's geoms: exact for capsules, bounding spheres else."""
        v = p - C
        t = np.clip(np.sum(v * A, axis=1), -size[:, 1], size[:, 1])
        d_cap = np.linalg.norm(v - t[:, None] * A, axis=1) - size[:, 0]
        return float(np.min(np.where(capsule, d_cap, np.linalg.norm(v, axis=1) - bound)))

    flange = m.body("robot/flange").id
    spots = []
    for q in plain.q[::50]:                      # every 50 ms
        d.qpos[cell.qpos_adr] = q
        mujoco.mj_kinematics(m, d)
        spots.append(d.xpos[flange].copy())          # inside the flange's capsule
    far = [folded_distance(p) for p in spots]
    spot = spots[int(np.argmax(far))]            # the panel: on the default approach, 0.4 s
    assert max(far) > 0.06                       # the folded arm passes clear of a 40 mm plate
    plate = _with_plate(surf, spot, np.array([0.0, 0.0, 1.0]), 0.04, scn.part_placement.matrix)
    assert _touches(scn, plate, plain) > 0 and _touches(scn, plate, folded) == 0   # truth

    check = _check(scn, plan, plate)
    assert check("abb_paint", scn.base.matrix) is None
    assert check.trajectory["abb_paint"] == {"fold_moves": True}
    assert check.clearance_m["abb_paint"] >= 0.01
    assert FOLD_BELOW_M > 0.01


def test_a_program_the_time_law_cannot_follow_is_refused(panel) -> None:
    """The panel's plan asked at 8× its speeds (4 m/s) builds (the time law slows it down) but
    lays a different film: init refuses such a cell before it writes it. Truth: the TCP speed of the
    built program, re-measured by finite differences, is below 90 % of the planned one on more
    than MAX_LOST_SHARE of the brush-on samples; at the plan's own speeds the check passes."""
    from paintcell.app.init_verify import MAX_LOST_SHARE
    from paintcell.motion.joint_trajectory import PAINT

    scn, surf, plan = panel
    fast = replace(plan, passes=tuple(
        replace(p, speeds_m_s=8.0 * p.speeds_m_s, times_s=p.times_s / 8.0) for p in plan.passes))
    traj = make_trajectory(scn, load_robot_for(scn), fast)
    on = traj.segment == PAINT
    v = np.linalg.norm(np.gradient(traj.tcp_pos_world, traj.t_s, axis=0), axis=1)[on]
    assert np.mean(v < 0.9 * traj.v_tcp_planned[on]) > MAX_LOST_SHARE   # truth: it slows
    why = _check(scn, fast, surf)("abb_paint", scn.base.matrix)
    assert why is not None and why.startswith("its time law and joint path lose ")
    assert "slowed > 10 %" in why and "\n" not in why
    assert _check(scn, plan, surf)("abb_paint", scn.base.matrix) is None


def _held_program(robot, q_path: np.ndarray, dt: float = 1e-3) -> JointTrajectory:
    """A joint program through the poses q_path (K, n), one a millisecond (a replay needs no
    smooth derivatives: the kinematic mode sets the positions), with FK TCP."""
    T = robot.fk_many(q_path)
    K = len(q_path)
    z = np.zeros_like(q_path)
    return JointTrajectory(t_s=np.arange(K) * dt, q=q_path, qd=z, qdd=z,
                           tcp_pos_world=T[:, :3, 3], tcp_rot_world=T[:, :3, :3],
                           v_tcp_planned=np.zeros(K), paint_on=np.zeros(K, bool),
                           pass_index=np.full(K, -1), segment=np.full(K, PAINT),
                           s_pass_m=np.full(K, np.nan), robot_name=robot.name,
                           joint_names=robot.joint_names)


def test_a_program_that_folds_the_arm_into_itself_is_refused() -> None:
    """The part sweep sees only the part; the replay in `run`'s cell sees the arm itself. A UR10
    pose from a cell init once wrote (noether_wavy_with_hole): its wrist_2 link is inside its
    forearm — MuJoCo's own collision pass at that pose says so (the truth here) — and a program
    through it is refused naming both links; the same program held at home is not."""
    from paintcell.app.init_verify import _replay
    from paintcell.robots.catalog import load_robot

    ur = load_robot("ur10")
    q_bad = np.array([-0.649, -1.537, 1.116, 1.125, -5.551, -3.723])
    m = mujoco.MjModel.from_xml_path(str(ur.mjcf_path))
    d = mujoco.MjData(m)
    d.qpos[:6] = q_bad
    mujoco.mj_forward(m, d)
    pairs = {frozenset((mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.geom_bodyid[c.geom1]),
                        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.geom_bodyid[c.geom2])))
             for c in d.contact[:d.ncon] if c.dist < 0}
    assert frozenset(("forearm_link", "wrist_2_link")) in pairs
    far = np.eye(4)
    far[:3, 3] = [5.0, 5.0, 1.0]                   # the part well out of the arm's way
    part = plane(0.3, 0.3, 0.05)
    q_home = np.asarray(ur.q_home, float)
    through = np.vstack([q_home + (q_bad - q_home) * s for s in np.linspace(0, 1, 200)])
    why = _replay(ur, part, far, _held_program(ur, np.vstack([through, through[::-1]])))
    assert why is not None and "wrist_2_link" in why and "forearm_link" in why
    assert _replay(ur, part, far, _held_program(ur, np.repeat(q_home[None], 200, 0))) is None


def test_a_program_whose_run_still_slows_after_robot_aware_speeds_is_refused(panel) -> None:
    """The panel planned at 4× its speeds (2 m/s nominal): init's program slows 4 of its poses,
    under `MAX_LOST_SHARE` (the old check wrote the cell), and `run` cannot fix them: its
    robot-aware program (`pipeline.robot_aware_run`, what `run` executes) still runs some
    brush-on samples on the part more than 10 % below the planned speed — re-measured here by
    finite differences of its TCP positions (the truth) — so the run would fail the
    `reachability_pct = 100` init writes. init refuses the cell in one line, naming the pass;
    at the plan's own speeds it does not. The flow held constant (`flow_min = 1`): a brush table
    that makes up for the slowdown lays the planned film (`tests/test_flow.py`)."""
    from paintcell.app.pipeline import robot_aware_run

    scn0, surf, plan0 = panel
    k = 4.0
    scn = replace(scn0, planner={**scn0.planner, "v_nominal_m_s": 0.5 * k, "v_min_m_s": 0.2 * k,
                                 "v_max_m_s": 1.0 * k, "a_max_m_s2": 5.0 * k * k},
                  trajectory={**scn0.trajectory, "flow_min": 1.0})
    plan = make_plan(scn, surf, fast=True)
    robot = load_robot_for(scn)
    run_plan, run_traj = robot_aware_run(scn, surf, robot, plan,
                                         make_trajectory(scn, robot, plan), fast=True)
    on = run_traj.segment == PAINT
    v = np.linalg.norm(np.gradient(run_traj.tcp_pos_world, run_traj.t_s, axis=0), axis=1)
    on_part = np.zeros(len(on), bool)            # brush-on samples over the part's poses
    for i, p in enumerate(run_plan.passes):
        sel = np.flatnonzero(on & (run_traj.pass_index == i))
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.positions, axis=0),
                                                            axis=1))])
        k_pose = np.clip(np.searchsorted(0.5 * (s[1:] + s[:-1]), run_traj.s_pass_m[sel]), 0,
                         len(s) - 1)
        on_part[sel] = np.asarray(p.on_part, bool)[k_pose]
    slowed = on_part & (v < 0.9 * run_traj.v_tcp_planned)
    assert slowed.any()                                         # truth: the run slows poses
    why = _check(scn, plan, surf)("abb_paint", scn.base.matrix)
    assert why is not None and why.startswith("its run slows ") and "\n" not in why
    worst = int(np.argmax(np.bincount(run_traj.pass_index[slowed])))
    assert f"pass {worst} " in why
    assert _check(scn0, plan0, surf)("abb_paint", scn0.base.matrix) is None


def test_a_robot_aware_plan_whose_film_falls_out_of_spec_is_refused(panel) -> None:
    """A run's robot-aware speeds cap a plan where the arm cannot follow it; a capped plan that
    lays an uneven film would fail the spec init writes with no pose slowed. The panel's plan
    (σ/μ under `MAX_CAPPED_NSD_PCT`) is kept; the same plan with its middle pass at a third of
    its speeds (three times the film there) is refused, naming the σ/μ — re-measured here as
    the area-weighted σ/μ of the film over the skin."""
    from paintcell.app.init_verify import MAX_CAPPED_NSD_PCT, _capped_film, planned_nsd_pct
    from paintcell.paint.deposition import thickness

    _, surf, plan = panel
    skin = surf.region_surface(("skin",))

    def nsd(pl) -> float:
        f = thickness(pl.applicator, pl.gun_samples(), skin.vertices, skin.normals)
        w = skin.vertex_areas
        mean = (w @ f) / w.sum()
        return 100.0 * float(np.sqrt((w @ (f - mean) ** 2) / w.sum()) / mean)

    mid = len(plan.passes) // 2
    p = plan.passes[mid]
    slow = replace(p, speeds_m_s=p.speeds_m_s / 3.0, times_s=p.times_s * 3.0)
    capped = replace(plan, passes=(*plan.passes[:mid], slow, *plan.passes[mid + 1:]))
    assert nsd(plan) <= MAX_CAPPED_NSD_PCT < nsd(capped)
    assert planned_nsd_pct(plan, surf) == pytest.approx(nsd(plan), rel=1e-9)
    assert _capped_film(planned_nsd_pct(plan, surf)) is None
    why = _capped_film(planned_nsd_pct(capped, surf))
    assert why is not None and f"{nsd(capped):.1f} % σ/μ" in why and "\n" not in why
