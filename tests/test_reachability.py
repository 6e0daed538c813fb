"""Reachability report and base placement."""

from __future__ import annotations

import json

import numpy as np
import pytest

from paintcell.coverage.plan import tcp_frames
from paintcell.robots import load_robot
from paintcell.robots.ik import combined_report
from paintcell.robots.paths import solve_paths
from paintcell.robots.placement import facing_grid, find_base_pose
from paintcell.robots.reachability import ReachabilityReport


def _panel_raster(T_world_part: np.ndarray, width=1.0, height=1.0, n_pass=6, step=0.01,
                  standoff=0.25) -> list[np.ndarray]:
    """Horizontal raster passes over a width × height panel whose painted side faces part +z."""
    paths = []
    for k, v in enumerate(np.linspace(-height / 2, height / 2, n_pass)):
        u = np.arange(-width / 2, width / 2 + 1e-9, step)
        if k % 2:
            u = u[::-1]
        p_part = np.stack([u, np.full_like(u, v), np.full_like(u, standoff)], axis=1)
        axis = np.tile([0.0, 0.0, -1.0], (len(u), 1))
        travel = np.tile([1.0 if k % 2 == 0 else -1.0, 0.0, 0.0], (len(u), 1))
        T_part = tcp_frames(p_part, axis, travel)
        paths.append(T_world_part @ T_part)
    return paths


def _vertical_panel_at(x: float, z: float) -> np.ndarray:
    """Part frame: origin at (x, 0, z), +z (painted side) facing -x world (toward a robot at 0)."""
    T = np.eye(4)
    T[:3, :3] = np.array([[0, 1, 0], [0, 0, -1], [-1, 0, 0]], float).T
    T[:3, 3] = [x, 0.0, z]
    return T


@pytest.fixture(scope="module")
def abb():
    return load_robot("abb_paint")


def test_report_measures_residuals_independently(abb):
    Q = np.random.default_rng(20).uniform(abb.q_lower, abb.q_upper, (30, 6))
    T = abb.fk_many(Q)
    rep = ReachabilityReport.measure(abb, Q, T)
    assert rep.all_reachable and np.nanmax(rep.pos_residual_m) < 1e-12
    # Displace one target by 1 mm and rotate another by 1 mrad: the report sees exactly that.
    T2 = T.copy()
    T2[3, :3, 3] += [0.001, 0.0, 0.0]
    c, s = np.cos(1e-3), np.sin(1e-3)
    T2[7, :3, :3] = T2[7, :3, :3] @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    rep2 = ReachabilityReport.measure(abb, Q, T2)
    assert np.isclose(rep2.pos_residual_m[3], 1e-3, rtol=1e-9)
    assert np.isclose(rep2.rot_residual_rad[7], 1e-3, rtol=1e-6)
    assert not rep2.reachable[3] and not rep2.reachable[7] and rep2.n_reachable == 28
    # Manipulability and wrist distance are the Jacobian's and |sin q5|.
    J = abb.jacobian(Q[0])
    assert np.isclose(rep.manipulability[0], np.sqrt(np.linalg.det(J @ J.T)))
    assert np.allclose(rep.wrist_sin, np.abs(np.sin(Q[:, 4])))
    assert np.allclose(rep.limit_margin_rad, abb.limit_margin(Q))
    assert np.isclose(rep.joint_jump_rad[5], np.abs(Q[5] - Q[4]).max())


def test_report_to_dict_is_json_and_concatenates(abb):
    T = _panel_raster(_vertical_panel_at(1.4, 1.0), width=0.6, height=0.4, n_pass=3)
    res = solve_paths(abb, T)
    rep = combined_report(res)
    d = json.loads(json.dumps(rep.to_dict(), allow_nan=False))
    assert d["n_poses"] == sum(len(p) for p in T) == rep.n_poses
    assert d["all_reachable"] and rep.all_reachable
    assert sorted(set(d["poses"]["pass_index"])) == [0, 1, 2]
    assert rep.verdict.startswith("abb_paint: all reachable")
    assert rep.joint_jump_rad[rep.pose_index == 0].max() == 0.0   # no jump across passes


def test_placement_finds_base_for_a_1m_panel_raster(abb):
    """A 1 m × 1 m horizontal panel (hood-like, painted side up) at 0.9 m: the search returns a
    base from which the full IK of every pass is reachable and continuous."""
    T_part = np.eye(4)
    T_part[:3, 3] = [0.0, 0.0, 0.9]
    paths = _panel_raster(T_part)
    T_base, rep = find_base_pose(abb, paths)
    assert rep.feasible, rep.verdict
    assert rep.reachability.all_reachable and rep.reachability.continuous
    assert np.isfinite(rep.scores[rep.best]) and rep.scores[rep.best] > 0.05
    # Independent check: re-solve at the returned base.
    again = combined_report(solve_paths(abb.placed(T_base), paths))
    assert again.all_reachable
    json.dumps(rep.to_dict(), allow_nan=False)


def test_placement_reports_when_nothing_is_feasible(abb):
    T_part = np.eye(4)
    T_part[:3, 3] = [0.0, 0.0, 0.9]
    paths = _panel_raster(T_part, width=5.0, height=1.0, n_pass=3, step=0.05)  # 5 m: too wide
    T_base, rep = find_base_pose(abb, paths, candidates=facing_grid([0, 0, 0.9], dx=[-1.5, -1.0],
                                                                    dy=[0.0], heights=[0.0]))
    assert not rep.feasible
    assert "NO fully reachable base" in rep.verdict
    assert not rep.reachability.all_reachable


def test_placement_with_dls_for_the_ur10():
    """Robots without closed-form IK are scored with DLS; a small panel 0.8 m in front of one of
    the candidates, out of reach of the other, is found from the right one."""
    ur = load_robot("ur10")
    T_part = np.eye(4)
    T_part[:3, :3] = np.array([[0, 1, 0], [0, 0, -1], [-1, 0, 0]], float).T   # faces -x world
    T_part[:3, 3] = [0.0, 0.0, 0.6]
    paths = _panel_raster(T_part, width=0.4, height=0.3, n_pass=3, step=0.02)
    cands = facing_grid([0.0, 0.0, 0.6], dx=[-3.0, -0.75], dy=[0.0], heights=[0.0])
    T_base, rep = find_base_pose(ur, paths, candidates=cands, n_refine=2)
    assert rep.feasible, rep.verdict
    assert np.isclose(T_base[0, 3], -0.75) and not np.isfinite(rep.scores[0])


def test_unreachable_verdict_says_where_and_how_far(abb):
    """All poses out of reach (panel 8 m away): the one-line verdict names the worst pose and
    its position residual [m], and holds no nan (no reachable pose has a limit margin)."""
    T = _panel_raster(_vertical_panel_at(8.0, 1.0), width=0.4, height=0.2, n_pass=2, step=0.05)
    rep = combined_report(solve_paths(abb, T))
    assert rep.n_reachable == 0
    v = rep.verdict
    p, i = rep.worst_pose()
    k = int(np.flatnonzero((rep.pass_index == p) & (rep.pose_index == i))[0])
    assert "nan" not in v.lower() and "\n" not in v
    assert f"worst pass {p} pose {i} is {rep.pos_residual_m[k]:.3f} m out of reach" in v
    assert rep.pos_residual_m[k] > 5.0 and "joint-limit margin" not in v
    # Partly reachable: the margin is that of the reachable poses, still finite.
    Q = np.random.default_rng(21).uniform(abb.q_lower, abb.q_upper, (10, 6))
    T2 = abb.fk_many(Q)
    T2[4, :3, 3] += [0.0, 0.0, 0.25]
    rep2 = ReachabilityReport.measure(abb, Q, T2)
    assert "worst pass 0 pose 4 is 0.250 m out of reach" in rep2.verdict
    assert f"min joint-limit margin {abb.limit_margin(np.delete(Q, 4, 0)).min():.3f}" in \
        rep2.verdict
    assert "nan" not in rep2.verdict.lower()


def test_coarse_scores_stop_at_the_first_infeasible_path_without_changing_any_score(abb):
    """The placement score of a base is the worst `path_margin` over the paths (−inf when one is
    infeasible); the search stops at the first infeasible path. Brute force, every path of every
    base of a grid where some bases reach everything and others lose some passes: the same
    scores and reachable fractions, to the bit."""
    from paintcell.robots.ik import IKSettings
    from paintcell.robots.opw import inverse
    from paintcell.robots.placement import _score, _subsample, path_margin

    T_part = np.eye(4)
    T_part[:3, 3] = [0.0, 0.0, 0.9]
    paths = _panel_raster(T_part, width=1.0, height=1.0, n_pass=5, step=0.02)
    C = facing_grid([0, 0, 0.9], dx=[-2.0, -1.4, -1.0, -0.7], dy=[-0.8, 0.0, 0.8],
                    heights=[0.0, 0.25, 0.5])
    sub, s = _subsample(paths, 25), IKSettings()
    scores, reached = _score(abb, C, sub, False, s)
    T_tcp_flange = np.linalg.inv(abb.T_flange_tcp)
    for c, T in enumerate(C):
        margins, posed = [], []
        for p, stride in sub:
            Q, reach = inverse(abb.opw, np.linalg.inv(T) @ p @ T_tcp_flange)
            margins.append(path_margin(abb, Q, reach, s, max(stride, 1.0)))
            posed.append(reach.any(axis=1))
        assert scores[c] == min(margins)
        assert reached[c] == (1.0 if np.isfinite(min(margins)) else np.concatenate(posed).mean())
    feasible = np.isfinite(scores)
    assert 0 < feasible.sum() < len(C)                      # both kinds of base in the grid
    assert (reached[~feasible] < 1.0).any()                 # and bases with poses out of reach


def test_an_infeasible_search_can_skip_the_dls_walk(abb):
    """check_infeasible=False (what `paintcell init` asks when it only quotes the refusal): with no
    feasible candidate the chosen base is the same, the verdict still says so, and the closed-form
    branch's count is an honest one — every pose it calls reached the damped-least-squares full
    check (an independent, iterative solver) reaches too, and every pose farther from the base's
    shoulder than the arm's stretched length (links + the tool, the geometric truth) is
    unreached in both."""
    T_part = np.eye(4)
    T_part[:3, 3] = [0.0, 0.0, 0.9]
    paths = _panel_raster(T_part, width=5.0, height=1.0, n_pass=3, step=0.05)  # 5 m: too wide
    cands = facing_grid([0, 0, 0.9], dx=[-1.5, -1.0], dy=[0.0], heights=[0.0])
    T_full, full = find_base_pose(abb, paths, candidates=cands)
    T_fast, fast = find_base_pose(abb, paths, candidates=cands, check_infeasible=False)
    assert np.array_equal(T_full, T_fast) and not fast.feasible
    assert "NO fully reachable base" in fast.verdict
    dls, cf = full.reachability.reachable, fast.reachability.reachable
    assert cf.any() and not cf.all() and np.all(dls[cf])
    opw = abb.opw
    shoulder = T_fast @ np.array([0.0, 0.0, opw.c1, 1.0])      # on J1's axis, J2's height
    stretch = (abs(opw.a1) + opw.c2 + np.hypot(opw.a2, opw.c3) + opw.c4
               + np.linalg.norm(abb.T_flange_tcp[:3, 3]))
    far = np.linalg.norm(np.concatenate(paths)[:, :3, 3] - shoulder[:3], axis=1) > stretch
    assert far.any() and not cf[far].any() and not dls[far].any()
