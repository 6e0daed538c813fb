"""paintcell.execution.execute: servo and kinematic execution of a joint trajectory on the
MuJoCo cell.

The test case (shared with tests/test_validate.py): the ABB-style arm paints a small plane with two
back-and-forth passes made in joint space (joint 1 sweeps, a Jacobian step indexes between them);
the plan is the trajectory's own forward kinematics at planned timing, sampled every 10 ms.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from paintcell.coverage.plan import CoveragePlan, PassPlan
from paintcell.execution.cell import Cell, build_cell
from paintcell.execution.execute import (
    SETTLE_MAX_S,
    Disturbances,
    ExecutionError,
    ServoSettings,
    execute,
)
from paintcell.execution.trace import ExecutedTrace, TraceError
from paintcell.motion.joint_trajectory import APPROACH, PAINT, JointTrajectory
from paintcell.paint.applicator import Applicator
from paintcell.robots.catalog import load_robot
from paintcell.surface.analytic import plane
from paintcell.surface.surface_data import Surface
from tests.helpers import REPLAY_TCP_ATOL_MM, SERVO_TRACKING_MAX_MM

DT_S = 1e-3
PASS_S = 1.6     # duration of one pass [s]
INDEX_S = 0.5    # index move between the passes [s]
SWEEP_RAD = 0.15  # joint 1 sweeps ±SWEEP_RAD: ±0.19 m of TCP travel at 1.25 m radius
INDEX_M = 0.08   # TCP index step between the passes [m]
PLAN_STRIDE = 10  # plan samples every 10 ms


@dataclass(frozen=True, eq=False)
class Case:
    robot: Any
    surface: Surface
    T_world_part: np.ndarray
    traj: JointTrajectory
    plan: CoveragePlan


def _min_jerk(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """s, ds/dτ, d²s/dτ² of the rest-to-rest minimum-jerk blend on τ ∈ [0, 1]."""
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    ds = 30 * tau**2 - 60 * tau**3 + 30 * tau**4
    dds = 60 * tau - 180 * tau**2 + 120 * tau**3
    return s, ds, dds


def _segment(qa: np.ndarray, qb: np.ndarray, T: float) -> tuple[np.ndarray, ...]:
    tau = np.arange(round(T / DT_S)) * DT_S / T
    s, ds, dds = _min_jerk(tau)
    dq = qb - qa
    return (qa + s[:, None] * dq, (ds / T)[:, None] * dq, (dds / T**2)[:, None] * dq)


@functools.lru_cache(maxsize=4)
def make_case(part_shift_m: float = 0.0) -> Case:
    """Robot, plane, placement, trajectory and plan; `part_shift_m` moves the part toward the
    robot along the spray axis (0.3 m puts it through the bell)."""
    robot = load_robot("abb_paint")
    q_home = robot.q_home.copy()
    T_home = robot.fk(q_home)
    z_home = T_home[:3, 2]
    # Index direction: in the plane ⟂ to the spray axis and to the travel (world y at home).
    e_index = np.cross(np.array([0.0, 1.0, 0.0]), z_home)
    e_index /= np.linalg.norm(e_index)
    J = robot.jacobian(q_home)
    dq_index = np.linalg.pinv(J) @ np.concatenate([INDEX_M * e_index, np.zeros(3)])
    sweep = np.zeros(robot.nq)
    sweep[0] = SWEEP_RAD
    qa0, qa1 = q_home - sweep, q_home + sweep
    qb0, qb1 = qa1 + dq_index, qa0 + dq_index
    segs = [_segment(qa0, qa1, PASS_S), _segment(qa1, qb0, INDEX_S), _segment(qb0, qb1, PASS_S)]
    q = np.vstack([s[0] for s in segs] + [qb1[None]])
    qd = np.vstack([s[1] for s in segs] + [np.zeros((1, robot.nq))])
    qdd = np.vstack([s[2] for s in segs] + [np.zeros((1, robot.nq))])
    K = len(q)
    t = np.arange(K) * DT_S
    T_tcp = robot.fk_many(q)
    pos, rot = T_tcp[:, :3, 3], T_tcp[:, :3, :3]
    speed = np.linalg.norm(np.gradient(pos, t, axis=0), axis=1)
    n_pass, n_index = round(PASS_S / DT_S), round(INDEX_S / DT_S)
    pass_index = np.full(K, -1)
    segment = np.full(K, APPROACH)
    paint = np.zeros(K, bool)
    for p, start in enumerate((0, n_pass + n_index)):
        # Brush on while the pass moves at > 40 % of its peak speed.
        sl = slice(start, start + n_pass)
        on = speed[sl] > 0.4 * speed[sl].max()
        paint[sl] = on
        pass_index[sl] = p
        segment[sl] = PAINT
    traj = JointTrajectory(
        t_s=t, q=q, qd=qd, qdd=qdd, tcp_pos_world=pos, tcp_rot_world=rot,
        v_tcp_planned=np.where(paint, speed, 0.0), paint_on=paint, pass_index=pass_index,
        segment=segment, s_pass_m=np.full(K, np.nan), robot_name=robot.name,
        joint_names=tuple(robot.joint_names))

    # Part: a 0.55 × 0.35 m plane ⟂ to the home spray axis, at standoff, between the passes.
    app = Applicator.default()
    T_world_part = np.eye(4)
    x_part = np.array([0.0, 1.0, 0.0])
    z_part = -z_home
    T_world_part[:3, :3] = np.column_stack([x_part, np.cross(z_part, x_part), z_part])
    T_world_part[:3, 3] = (T_home[:3, 3] + 0.5 * INDEX_M * e_index
                           + (app.standoff_m - part_shift_m) * z_home)
    surface = plane(0.55, 0.35, resolution_m=0.01)

    # Plan: the paint-on samples of each pass in the part frame, every PLAN_STRIDE steps.
    R_pw, p_pw = T_world_part[:3, :3].T, -T_world_part[:3, :3].T @ T_world_part[:3, 3]
    passes = []
    for p in range(2):
        idx = np.flatnonzero(paint & (pass_index == p))[::PLAN_STRIDE]
        passes.append(PassPlan(
            positions=pos[idx] @ R_pw.T + p_pw, spray_axes=rot[idx, :, 2] @ R_pw.T,
            travel_dirs=rot[idx, :, 0] @ R_pw.T, speeds_m_s=speed[idx], times_s=t[idx] - t[idx[0]],
            on_part=np.ones(len(idx), bool), paint_on=np.ones(len(idx), bool), side=p))
    plan = CoveragePlan(surface_name=surface.name, applicator=app, passes=tuple(passes))
    return Case(robot, surface, T_world_part, traj, plan)


@functools.lru_cache(maxsize=4)
def make_cell(part_shift_m: float = 0.0) -> Cell:
    c = make_case(part_shift_m)
    return build_cell(c.robot, c.surface, c.T_world_part)


@functools.lru_cache(maxsize=8)
def run(mode: str = "servo", gain_scale: float = 1.0, part_shift_m: float = 0.0,
        disturbances: Disturbances | None = None) -> ExecutedTrace:
    return execute(make_cell(part_shift_m), make_case(part_shift_m).traj, mode=mode,  # type: ignore[arg-type]
                   servo=ServoSettings(gain_scale=gain_scale), disturbances=disturbances)


@functools.lru_cache(maxsize=16)
def run_servo(**settings: Any) -> ExecutedTrace:
    """Servo run of the test case with these `ServoSettings` fields (defaults otherwise)."""
    return execute(make_cell(), make_case().traj, servo=ServoSettings(**settings))


def _tcp_err_mm(trace: ExecutedTrace, traj: JointTrajectory) -> np.ndarray:
    return 1e3 * np.linalg.norm(trace.tcp_pos_world - traj.tcp_pos_world, axis=1)


def test_kinematic_replay_follows_the_reference_exactly() -> None:
    case = make_case()
    tr = run("kinematic")
    np.testing.assert_array_equal(tr.q, case.traj.q)
    # MuJoCo's TCP site and Pinocchio's FK of the same MJCF agree to round-off.
    assert _tcp_err_mm(tr, case.traj).max() < REPLAY_TCP_ATOL_MM
    assert tr.mode == "kinematic" and tr.contacts == ()
    assert tr.meta["mujoco_warnings"] == {}


def test_servo_tracking_error_is_small_but_nonzero() -> None:
    case = make_case()
    tr = run("servo")
    err = _tcp_err_mm(tr, case.traj)
    # The realistic servo (latency, model error, Coulomb friction) tracks measurably worse than
    # the ideal one (exact model, no latency or friction: 0.021 mm here) but like a real arm.
    ideal = _tcp_err_mm(run_servo(**ServoSettings.ideal().to_dict()), case.traj)
    assert 3.0 * ideal.max() < err.max() < SERVO_TRACKING_MAX_MM
    assert tr.meta["mujoco_warnings"] == {} and ideal.max() > 0
    # Torques respect the actuator limits and hold the arm against gravity (not zero).
    assert np.all(np.abs(tr.tau) <= case.robot.tau_max * (1 + 1e-9))
    assert np.abs(tr.tau[:, 1]).max() > 10.0


def test_softer_servo_tracks_worse() -> None:
    case = make_case()
    e1 = _tcp_err_mm(run("servo", 1.0), case.traj)
    e01 = _tcp_err_mm(run("servo", 0.1), case.traj)
    assert e01.max() > 3.0 * e1.max()


# Each imperfection of the servo, switched off alone, and the least factor by which switching it
# on must raise the TCP error (RMS or max over the run) of the test case. Measured: latency 2 ms
# vs 0: max ×1.02 (slow disturbances, so latency costs little until it eats the phase margin,
# below); model error: RMS ×1.09; payload error: RMS ×1.29; Coulomb friction: max ×1.76. The
# factors are deterministic (seeded), so an effect that is ignored shows as exactly 1.
EFFECTS = {
    "latency_steps": (0, 1.01),
    "model_error": (0.0, 1.05),
    "payload_error": (0.0, 1.15),
    "coulomb_friction": (0.0, 1.4),
}


@pytest.mark.parametrize("field", sorted(EFFECTS))
def test_each_servo_imperfection_raises_the_tracking_error(field: str) -> None:
    case = make_case()
    off, factor = EFFECTS[field]
    e_on = _tcp_err_mm(run("servo"), case.traj)
    e_off = _tcp_err_mm(run_servo(**{field: off}), case.traj)
    ratio = max(e_on.max() / e_off.max(), np.sqrt((e_on**2).mean() / (e_off**2).mean()))
    assert ratio > factor, f"{field}: error ratio on/off {ratio:.3f}"


def test_latency_beyond_the_phase_margin_makes_the_servo_ring() -> None:
    # 15 Hz, ζ = 1 PD: crossover ≈ 194 rad/s, phase margin 76° without delay; 4 ms + the half
    # step of the zero-order hold leaves ≈ 26°, so the loop rings (measured ×11 the max error).
    case = make_case()
    e2 = _tcp_err_mm(run("servo"), case.traj)
    e4 = _tcp_err_mm(run_servo(latency_steps=4), case.traj)
    assert e4.max() > 5.0 * e2.max()


def test_servo_imperfections_are_seeded() -> None:
    a, b = run_servo(seed=1), run_servo(seed=1)
    np.testing.assert_array_equal(a.q, b.q)
    assert not np.array_equal(a.q, run("servo").q)  # another controller model
    assert run_servo(seed=1).meta["servo"]["seed"] == 1


def test_without_feedforward_the_error_grows() -> None:
    case = make_case()
    cell = make_cell()
    tr = execute(cell, case.traj, servo=ServoSettings(feedforward=False))
    assert _tcp_err_mm(tr, case.traj).max() > 3.0 * _tcp_err_mm(run("servo"), case.traj).max()
    # PD alone sags under gravity: the arm never settles within 0.1 mm of the last pose.
    assert not tr.meta["settled"] and tr.meta["settle_time_s"] == SETTLE_MAX_S
    assert run("servo").meta["settled"]


def test_part_in_the_arm_path_is_a_reported_collision() -> None:
    tr = run("kinematic", part_shift_m=0.3)
    assert len(tr.contacts) > 0
    cell = make_cell(0.3)
    for c in tr.contacts:
        assert c.body1 in cell.robot_body_names and c.body2 == "part"
        assert c.depth_m > 0
    # The servo run sees (and is pushed by) the same collision.
    assert len(run("servo", part_shift_m=0.3).contacts) > 0


#: J3 at its limit and J5 bent back: the bell folded into the upper arm (10 cm deep).
Q_FOLDED = (0.0, -0.2, 1.3, 0.0, 2.0, 0.0)


def _paint_off_program(robot: Any, q: np.ndarray, qd: np.ndarray,
                       qdd: np.ndarray) -> JointTrajectory:
    """A brush-off program (one approach segment) through the 1 kHz joint samples q, qd, qdd."""
    K = len(q)
    T_tcp = robot.fk_many(q)
    return JointTrajectory(
        t_s=np.arange(K) * DT_S, q=q, qd=qd, qdd=qdd, tcp_pos_world=T_tcp[:, :3, 3],
        tcp_rot_world=T_tcp[:, :3, :3], v_tcp_planned=np.zeros(K), paint_on=np.zeros(K, bool),
        pass_index=np.full(K, -1), segment=np.full(K, APPROACH), s_pass_m=np.full(K, np.nan),
        robot_name=robot.name, joint_names=tuple(robot.joint_names))


@functools.lru_cache(maxsize=1)
def make_fold() -> tuple[Cell, JointTrajectory]:
    """A cell with the part 3 m behind the robot (out of reach) and a 1.5 s rest-to-rest move
    from home to Q_FOLDED: the arm folds into itself and touches nothing else."""
    case = make_case()
    robot = case.robot
    T_away = case.T_world_part.copy()
    T_away[:3, 3] = (-3.0, 0.0, 1.0)
    cell = build_cell(robot, case.surface, T_away)
    q, qd, qdd = _segment(robot.q_home, np.array(Q_FOLDED), 1.5)
    q, qd = np.vstack([q, Q_FOLDED]), np.vstack([qd, np.zeros((1, robot.nq))])
    qdd = np.vstack([qdd, np.zeros((1, robot.nq))])
    traj = _paint_off_program(robot, q, qd, qdd)
    return cell, traj


@pytest.mark.parametrize("mode", ["kinematic", "servo"])
def test_arm_folded_into_itself_is_a_reported_self_collision(mode: str) -> None:
    cell, traj = make_fold()
    tr = execute(cell, traj, mode=mode)  # type: ignore[arg-type]
    assert len(tr.contacts) > 0
    # Both bodies are the robot's, the distal one first; the part and the floor are not touched.
    assert {(c.body1, c.body2) for c in tr.contacts} == {("robot/flange", "robot/link2")}
    assert all(c.depth_m > 0 for c in tr.contacts)
    # The bell reaches the upper arm after 1.08 s of the 1.5 s move (kinematic depth at the end:
    # 105 mm; the servo is stopped by the contact within millimetres).
    assert min(c.time_s for c in tr.contacts) == pytest.approx(1.081, abs=0.01)
    deepest = max(c.depth_m for c in tr.contacts)
    assert deepest == pytest.approx(0.105, abs=0.002) if mode == "kinematic" else deepest < 0.02
    # A normal program folds nothing: no contact of any kind, in either mode.
    assert run(mode).contacts == ()


def test_torque_demand_is_recorded_before_the_clamp() -> None:
    """`tau` is the applied (clamped) torque, `tau_demand` what the servo law asked for: equal
    where no joint saturates, and the clamp of the demand where one does."""
    case = make_case()
    tr = run("servo")
    assert tr.tau_demand is not None and tr.tau_demand.shape == tr.tau.shape
    tau_max = case.robot.tau_max
    np.testing.assert_allclose(tr.tau, np.clip(tr.tau_demand, -tau_max, tau_max), rtol=1e-12,
                               atol=1e-9)
    # Joint 1 limited to 1.2 % of its torque: it saturates on the sweep's accelerations, the
    # demand runs past the limit while the applied torque stays at it.
    scale = np.ones(case.robot.nq)
    scale[0] = 0.012
    weak = dataclasses.replace(make_cell(), tau_max=make_cell().tau_max * scale)
    sat = execute(weak, case.traj)
    assert sat.tau_demand is not None
    assert np.abs(sat.tau).max(axis=0)[0] == pytest.approx(weak.tau_max[0], rel=1e-9)
    assert np.abs(sat.tau_demand).max(axis=0)[0] > 2.0 * weak.tau_max[0]
    np.testing.assert_allclose(sat.tau, np.clip(sat.tau_demand, -weak.tau_max, weak.tau_max),
                               rtol=1e-12, atol=1e-9)
    # Kinematic replay: the demand is the inverse dynamics, the torque it reports.
    kin = run("kinematic")
    assert kin.tau_demand is not None
    np.testing.assert_array_equal(kin.tau_demand, kin.tau)


def test_contacts_during_the_settling_hold_are_reported() -> None:
    """The program stops 0.08 s before the bell would reach the upper arm on the fold move
    (make_fold), its last sample stepping to the folded pose: the servo gets there only during
    the settling hold after the program, and that collision is reported (times past the end)."""
    cell, fold = make_fold()
    robot = make_case().robot
    k = round(1.0 / DT_S)
    q = np.vstack([fold.q[:k], np.array(Q_FOLDED)[None]])
    qd = np.vstack([fold.qd[:k], np.zeros((1, robot.nq))])
    qdd = np.vstack([fold.qdd[:k], np.zeros((1, robot.nq))])
    traj = _paint_off_program(robot, q, qd, qdd)
    tr = execute(cell, traj)
    assert len(tr.contacts) > 0
    assert {(c.body1, c.body2) for c in tr.contacts} == {("robot/flange", "robot/link2")}
    assert min(c.time_s for c in tr.contacts) > traj.t_s[-1]
    assert max(c.time_s for c in tr.contacts) <= traj.t_s[-1] + SETTLE_MAX_S + 1e-9


def test_disturbances_are_seeded_and_applied() -> None:
    d = Disturbances(part_offset_m=0.01, part_rotation_rad=0.02, tcp_offset_m=0.005, seed=3)
    T1, o1 = d.realize()
    T2, o2 = d.realize()
    np.testing.assert_array_equal(T1, T2)
    np.testing.assert_array_equal(o1, o2)
    assert np.isclose(np.linalg.norm(T1[:3, 3]), 0.01) and np.isclose(np.linalg.norm(o1), 0.005)
    case = make_case()
    tr = run("kinematic", disturbances=d)
    # The TCP calibration offset moves the executed spray point by exactly its length.
    assert np.allclose(_tcp_err_mm(tr, case.traj), 5.0, atol=1e-6)
    actual = np.asarray(tr.meta["T_world_part_actual"])
    assert np.isclose(np.linalg.norm(actual[:3, 3] - case.T_world_part[:3, 3]), 0.01)


def test_bad_inputs_raise_project_errors() -> None:
    case = make_case()
    cell = make_cell()
    with pytest.raises(ExecutionError, match="mode"):
        execute(cell, case.traj, mode="teleport")  # type: ignore[arg-type]
    coarse = JointTrajectory(**{**{k: getattr(case.traj, k)[::2] for k in JointTrajectory._ARRAYS},
                                "robot_name": case.traj.robot_name,
                                "joint_names": case.traj.joint_names})
    with pytest.raises(ExecutionError, match="1 kHz"):
        execute(cell, coarse)
    with pytest.raises(ExecutionError, match="friction_compensation"):
        ServoSettings(friction_compensation=1.5)
    with pytest.raises(ExecutionError, match="model_error"):
        ServoSettings(model_error=-0.1)
    with pytest.raises(ExecutionError, match="latency_steps"):
        ServoSettings(latency_steps=-1)


@pytest.mark.parametrize("kw, field", [
    ({"seed": 1.5}, "seed"), ({"seed": True}, "seed"), ({"seed": "3"}, "seed"),
    ({"gain_scale": "abc"}, "gain_scale"), ({"gain_scale": 0.0}, "gain_scale"),
    ({"gain_scale": float("inf")}, "gain_scale"), ({"part_offset_m": float("nan")}, "part_offset"),
    ({"part_offset_m": -0.01}, "part_offset"), ({"part_rotation_rad": "0.1"}, "part_rotation"),
    ({"tcp_offset_m": float("inf")}, "tcp_offset"), ({"tcp_offset_m": None}, "tcp_offset"),
    ({"part_offset_m": True}, "part_offset"),
])
def test_bad_disturbances_raise_one_line_errors(kw: dict[str, Any], field: str) -> None:
    with pytest.raises(ExecutionError, match=field) as exc:
        Disturbances(**kw)
    assert "\n" not in str(exc.value)


def test_disturbances_accept_numpy_and_int_values() -> None:
    d = Disturbances(part_offset_m=np.float64(0.01), tcp_offset_m=0, gain_scale=2,
                     seed=np.int64(4))
    assert d.to_dict() == {"part_offset_m": 0.01, "part_rotation_rad": 0.0, "tcp_offset_m": 0.0,
                           "gain_scale": 2.0, "standoff_error_m": 0.0, "trigger_delay_s": 0.0,
                           "flow_scale": 1.0, "flow_drift": 0.0, "seed": 4}
    assert all(type(v) in (float, int) for v in d.to_dict().values())


def test_trace_save_load_round_trip(tmp_path: Any) -> None:
    tr = run("kinematic", part_shift_m=0.3)
    path = tmp_path / "trace.npz"
    tr.save_npz(path)
    back = ExecutedTrace.load_npz(path)
    for name in ExecutedTrace._ARRAYS + ExecutedTrace._OPTIONAL_ARRAYS:
        np.testing.assert_array_equal(getattr(back, name), getattr(tr, name))
    assert back.tau_demand is not None
    assert back.contacts == tr.contacts and back.mode == tr.mode
    assert back.meta["T_world_part_actual"] == tr.meta["T_world_part_actual"]
    # A trace without the demanded torque (written before it was recorded) still loads.
    old = dataclasses.replace(tr, tau_demand=None)
    old.save_npz(tmp_path / "old.npz")
    assert ExecutedTrace.load_npz(tmp_path / "old.npz").tau_demand is None
    with pytest.raises(TraceError, match="does not exist"):
        ExecutedTrace.load_npz(tmp_path / "missing.npz")


def test_progress_is_reported_to_completion() -> None:
    seen: list[float] = []
    case = make_case()
    execute(make_cell(), case.traj, progress=seen.append)
    assert seen and seen[-1] == 1.0 and all(np.diff(seen) > 0)
