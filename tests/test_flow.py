"""paintcell.motion.flow: the brush table that follows the time law, re-measured on programs
whose plan the arm cannot follow, on their film and on their RAPID text."""

from __future__ import annotations

import re

import numpy as np
import pytest

from paintcell.execution.execute import Disturbances
from paintcell.execution.trace import ExecutedTrace
from paintcell.motion.flow import FLOW_STEP, FLOW_STRETCH_M, brush_flow, cap_speed
from paintcell.motion.joint_trajectory import JointTrajectory, TrajectoryError
from paintcell.motion.trajectory import TrajectorySettings
from paintcell.output.export_rapid import brush_flow_of, brush_numbers, rapid_module
from paintcell.paint.deposition import thickness
from paintcell.robots import load_robot
from paintcell.validation.honest_reach import honest_reachability
from paintcell.validation.validate_samples import trajectory_gun_samples
from tests.test_trajectory import _build, _plan

LOAD = (7.0, np.array([0.0, 0.0, 0.12]))


@pytest.fixture(scope="module")
def robot():
    return load_robot("abb_paint")


@pytest.fixture(scope="module")
def slowed(robot) -> dict[float, JointTrajectory]:
    """The same plan at 2.5 m/s, beyond the arm's limits, with the flow free down to half, to
    0.9 and held constant."""
    plan = _plan(2.5)
    return {f: _build(robot, plan, flow_min=f) for f in (0.5, 0.9, 1.0)}


def _stretches(traj: JointTrajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per (pass, 20 mm stretch) of brush-on samples: Σ flow·dt [s], the plan's time over the
    same TCP travel Σ |Δp| / v_plan [s], and the program's time Σ dt [s]."""
    on = np.flatnonzero(traj.paint_on[1:] & traj.paint_on[:-1]
                        & (traj.pass_index[1:] == traj.pass_index[:-1])) + 1
    ds = np.linalg.norm(traj.tcp_pos_world[on] - traj.tcp_pos_world[on - 1], axis=1)
    key = traj.pass_index[on] * 10_000 + np.floor(traj.s_pass_m[on] / FLOW_STRETCH_M)
    _, k = np.unique(key, return_inverse=True)
    dt = traj.dt_s
    return (np.bincount(k, traj.flow[on] * dt), np.bincount(k, ds / traj.v_tcp_planned[on]),
            np.bincount(k, np.full(len(on), dt)))


def test_flow_makes_up_for_the_time_law_stretch_by_stretch(slowed) -> None:
    traj = slowed[0.5]
    assert traj.flow.min() < 0.9                     # the arm is slower than the plan somewhere
    laid, planned, took = _stretches(traj)
    need = planned / took                            # the flow the plan's film asks for
    free = (need > 0.5 + FLOW_STEP) & (took > 0.004)  # not clamped, 4 samples or more
    assert free.sum() > 10
    # the flow levels are FLOW_STEP apart: within half a step (+ sampling) of the plan's film
    np.testing.assert_allclose(laid[free], planned[free], rtol=FLOW_STEP / 2 / 0.5 + 0.01)
    # where the plan asks less than the lowest level the flow sits there
    low = need < 0.5 - FLOW_STEP
    assert np.allclose(laid[low] / took[low], 0.5)
    # off the brush the flow is full; the levels are the table's
    assert np.all(traj.flow[~traj.paint_on] == 1.0)
    assert np.allclose(np.round((1 - traj.flow) / FLOW_STEP) * FLOW_STEP, 1 - traj.flow)


def test_constant_flow_is_one_everywhere(slowed) -> None:
    assert np.all(slowed[1.0].flow == 1.0)
    # the same program otherwise: the flow changes nothing the arm does
    np.testing.assert_array_equal(slowed[0.5].q, slowed[1.0].q)


def test_the_film_of_the_slowed_program_is_the_plans_again(slowed) -> None:
    """The deposition model on a grid under the strip: the program's film at its own timing
    against the plan's, with the flow following the time law and without."""
    plan = _plan(2.5)
    x, y = np.meshgrid(np.linspace(0.85, 1.35, 26), np.linspace(-0.3, 0.3, 31))
    pts = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 0.75)])   # 250 mm standoff
    nrm = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    app = plan.applicator
    film_plan = thickness(app, plan.gun_samples(), pts, nrm)
    err = {f: np.abs(thickness(app, trajectory_gun_samples(tr, np.eye(4)), pts, nrm)
                     / film_plan - 1).max() for f, tr in slowed.items() if f != 0.9}
    assert err[1.0] > 0.1                            # constant flow: far thicker where slowed
    assert err[0.5] < 0.25 * err[1.0]


def _ideal(traj: JointTrajectory) -> ExecutedTrace:
    return ExecutedTrace(t_s=traj.t_s, q=traj.q, qd=traj.qd, tau=np.zeros_like(traj.q),
                         tcp_pos_world=traj.tcp_pos_world, tcp_rot_world=traj.tcp_rot_world,
                         paint_on=traj.paint_on, pass_index=traj.pass_index, mode="kinematic",
                         flow=traj.flow)


def test_honest_reach_counts_a_slowdown_the_flow_makes_up_for_as_reached(slowed) -> None:
    plan = _plan(2.5)
    lost = {f: honest_reachability(plan, tr, _ideal(tr), {})["n_slowed_poses"]
            for f, tr in slowed.items() if f != 0.9}
    assert lost[1.0] > 0 and lost[0.5] < lost[1.0]


def test_brush_flow_levels_by_hand() -> None:
    # one pass, 1 m at 1 mm a sample (half-way between the 20 mm stretch edges): the arm at
    # 60 % of the plan over its middle third, 30 % near its end
    s = np.linspace(0.0005, 1.0005, 1001)
    v_plan = np.ones_like(s)
    v_prog = np.where((s > 0.35) & (s < 0.66), 0.6, 1.0)
    v_prog[s > 0.9] = 0.3
    on = s < 0.98
    f = brush_flow(s, v_prog, v_plan, on, np.zeros(len(s), int), flow_min=0.45)
    assert np.all(f[(s > 0.36) & (s < 0.64)] == pytest.approx(0.60))
    assert np.all(f[(s > 0.92) & on] == pytest.approx(0.46))   # the lowest level ≥ flow_min
    assert np.all(f[s < 0.34] == 1.0) and np.all(f[~on] == 1.0)
    # the stretch [0.34, 0.36) m is slowed over 10 of its 20 samples: (10 + 10 · 0.6) / 20 = 0.8
    # over the whole stretch
    mixed = (s > 0.34) & (s < 0.36)
    assert mixed.sum() == 20 and np.all(f[mixed] == pytest.approx(0.80))
    assert np.all(brush_flow(s, v_prog, v_plan, on, np.zeros(len(s), int), 1.0) == 1.0)


def test_invalid_flows_are_refused() -> None:
    with pytest.raises(TrajectoryError, match="flow_min"):
        TrajectorySettings(flow_min=0.0)
    with pytest.raises(TrajectoryError, match="flow_min"):
        TrajectorySettings(flow_min=1.5)


def test_the_trigger_delay_shifts_the_flow_with_the_brush(slowed) -> None:
    traj = slowed[0.5]
    dist = Disturbances(trigger_delay_s=0.02)
    shifted = dist.flow(traj.flow, traj.dt_s)
    np.testing.assert_array_equal(shifted[20:], traj.flow[:-20])
    assert np.all(shifted[:20] == 1.0)
    g = _ideal(traj).gun_samples()
    assert g.dwell_s.sum() == pytest.approx(traj.dt_s * traj.flow[traj.paint_on].sum())


def test_save_load_and_csv_keep_the_flow(slowed, tmp_path) -> None:
    traj = slowed[0.5]
    traj.save_npz(tmp_path / "t.npz")
    np.testing.assert_array_equal(JointTrajectory.load_npz(tmp_path / "t.npz").flow, traj.flow)
    traj.save_csv(tmp_path / "t.csv")
    with open(tmp_path / "t.csv") as f:
        assert f.readline().strip().split(",")[-1] == "flow"
    np.testing.assert_allclose(np.loadtxt(tmp_path / "t.csv", delimiter=",", skiprows=1)[:, -1],
                               traj.flow, atol=0.005)


@pytest.mark.parametrize("style", ["paintl", "trigg"])
def test_rapid_brush_events_carry_the_flow_levels(slowed, robot, style: str) -> None:
    """Walk the exported targets in order, keep the brush level each event sets, and compare it
    with the program's flow at the sample each target was taken from."""
    traj = slowed[0.5]
    text = rapid_module(traj, robot, load=LOAD, style=style)
    assert "Brush table" in text
    targets = {n: np.array(v.split(","), float) for n, v in
               re.findall(r"CONST robtarget (\w+) := \[\[([-\d.,]+)\]", text)}
    T_base_world = np.linalg.inv(robot.T_world_base)
    pos_mm = (traj.tcp_pos_world @ T_base_world[:3, :3].T + T_base_world[:3, 3]) * 1000
    if style == "paintl":
        events = re.findall(r"PaintL (\w+), \w+, z1, tBell;(?:\n    SetBrush (\d+);)?", text)
        level_of = {b: int(b) for _, b in events if b}
    else:
        events = [(n, (t2 or t1 or "")) for n, t1, t2 in re.findall(
            r"(?:TriggL|MoveL) (\w+), \w+, (?:(?:tBrushOn \\T2:=tFlow(\d+))|tFlow(\d+)|"
            r"tBrushOff|)(?:, )?z1, tBell;", text)]
        level_of = {b: int(b) for _, b in events if b}
        assert "\\AOp:=aoFlow" in text
    level, checked = 0, 0
    for name, b in events:
        if b:
            level = level_of[b]
        k = int(np.argmin(np.linalg.norm(pos_mm - targets[name], axis=1)))
        if traj.paint_on[k] and level:
            assert brush_flow_of(level) == pytest.approx(traj.flow[k], abs=1e-9)
            checked += 1
    assert checked > 50
    assert set(brush_numbers(traj.flow[traj.paint_on]).tolist()) - {1}


def test_caps_take_the_tcp_speed_where_the_flow_is_at_its_floor(slowed) -> None:
    """`cap_speed` by hand on the slowed program: ÷ the flow above the lowest level, the TCP's
    own speed at it (unless the floor is trusted)."""
    traj = slowed[0.9]
    idx = np.flatnonzero(traj.paint_on)
    v = np.full(len(idx), 0.3)
    floor = traj.flow[idx] <= 0.9 + 1e-9
    assert floor.any() and (~floor & (traj.flow[idx] < 1)).any()
    got = cap_speed(v, traj, idx)
    np.testing.assert_allclose(got[floor], 0.3)
    np.testing.assert_allclose(got[~floor], 0.3 / traj.flow[idx][~floor])
    np.testing.assert_allclose(cap_speed(v, traj, idx, trust_floor=True), 0.3 / traj.flow[idx])
    # constant flow: the TCP speed everywhere
    np.testing.assert_allclose(cap_speed(v, slowed[1.0], idx), 0.3)
