"""RAPID export: structure of the module and the speed profile it encodes, re-measured."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

from paintcell.core.transforms import quat_wxyz_from_matrix
from paintcell.motion.joint_trajectory import (
    APPROACH,
    PAINT,
    RETRACT,
    TURNAROUND,
    JointTrajectory,
)
from paintcell.output.export_rapid import confdata, rapid_module

DT = 1e-3


def _traj() -> JointTrajectory:
    """Two straight passes along world y at x = 1.2 m with a speed ramp, joined by a turn-around."""
    segs = []
    # approach: 0.2 s at rest at the first pass start
    t_app = np.arange(0, 0.2, DT)
    segs.append(("app", len(t_app)))
    n_pass = 1500
    s1 = np.cumsum(np.full(n_pass, 0.4 * DT) * np.linspace(1.0, 1.5, n_pass))  # 0.4→0.6 m/s
    s1 -= s1[0]
    y = np.concatenate([np.zeros(len(t_app)), s1 - 0.5, np.full(300, s1[-1] - 0.5),
                        (s1[-1] - 0.5) - s1, np.full(200, (s1[-1] - 0.5) - s1[-1])])
    z = np.concatenate([np.full(len(t_app) + n_pass, 1.0), np.linspace(1.0, 0.7, 300),
                        np.full(n_pass + 200, 0.7)])
    k = len(y)
    pos = np.column_stack([np.full(k, 1.2), y, z])
    seg = np.concatenate([np.full(len(t_app), APPROACH), np.full(n_pass, PAINT),
                          np.full(300, TURNAROUND), np.full(n_pass, PAINT), np.full(200, RETRACT)])
    pidx = np.concatenate([np.full(len(t_app), -1), np.zeros(n_pass, int), np.full(300, -1),
                           np.ones(n_pass, int), np.full(200, -1)])
    paint = seg == PAINT
    paint[len(t_app):len(t_app) + 100] = False  # brush switches on 100 samples into pass 0
    # TCP spray axis +x (toward a part at larger x), travel ±y.
    R = np.zeros((k, 3, 3))
    R[:, :, 2] = [1.0, 0.0, 0.0]
    R[:, :, 0] = [0.0, 1.0, 0.0]
    R[:, :, 1] = np.cross(R[:, :, 2], R[:, :, 0])
    q = np.zeros((k, 6))
    q[:, 0] = np.arctan2(y, 1.2)
    q[:, 4] = 0.5
    return JointTrajectory(
        t_s=np.arange(k) * DT, q=q, qd=np.gradient(q, DT, axis=0), qdd=np.zeros((k, 6)),
        tcp_pos_world=pos, tcp_rot_world=R, v_tcp_planned=np.where(paint, 0.5, 0.0),
        paint_on=paint, pass_index=pidx, segment=seg, s_pass_m=np.full(k, np.nan),
        robot_name="test", joint_names=tuple(f"j{i}" for i in range(6)))


def _pose(rotvec: list[float], xyz: list[float]) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = xyz
    return T


# A turned, raised base and a bent tool, so a missing inverse or a swapped frame shows.
ROBOT = SimpleNamespace(T_world_base=_pose([0.0, 0.0, 0.4], [-0.3, 0.2, 0.5]),
                        T_flange_tcp=_pose([0.0, np.pi / 4, 0.0], [0.085, 0.0, 0.245]))
LOAD = (7.0, np.array([0.0, 0.0, 0.12]))


def _decls(text: str) -> dict[str, str]:
    """Declared identifier → RAPID data type."""
    return {name: typ for typ, name in
            re.findall(r"^\s*(?:CONST|PERS|VAR) (\w+) (\w+)", text, re.M)}


@pytest.mark.parametrize("style", ["trigg", "paintl"])
def test_module_structure_and_declared_identifiers(style: str) -> None:
    traj = _traj()
    text = rapid_module(traj, ROBOT, load=LOAD, module_name="door 1", style=style,
                        max_spacing_m=0.1)
    lines = text.strip().splitlines()
    assert lines[0] == "MODULE door_1" and lines[-1] == "ENDMODULE"
    assert text.count("PROC main()") == 1 and text.count("ENDPROC") == 1
    decls = _decls(text)
    # Flying moves everywhere but at the start and the end of the program.
    main = text[text.index("PROC main()"):]
    zones = re.findall(r", (fine|z\d+), tBell;", main)
    assert zones[0] == "fine" and zones[-1] == "fine" and "fine" not in zones[1:-1]
    # Every target and speed used in a move instruction is declared with the right type.
    moves = re.findall(r"^\s*(MoveL|TriggL|PaintL) (\w+), (\w+),", text, re.M)
    assert moves
    for _, target, speed in moves:
        assert decls[target] == "robtarget"
        assert decls[speed] == "speeddata"
    vias = re.findall(r"^\s*MoveAbsJ (\w+), (\w+),", text, re.M)
    assert len(vias) > 3  # home, the approach, the turn-around and the retract
    for target, speed in vias:
        assert decls[target] == "jointtarget"
        assert speed == "v1000" or decls[speed] == "speeddata"
    # Every statement line inside the module ends with a semicolon.
    body = [ln.strip() for ln in lines[1:-1] if ln.strip() and not ln.strip().startswith("!")]
    for ln in body:
        assert ln.endswith(";") or ln in ("PROC main()", "ENDPROC"), ln
    # Quaternions are unit and confdata has 4 integers.
    for quat in re.findall(r"\],\[([-\d.]+),([-\d.]+),([-\d.]+),([-\d.]+)\],\[(-?\d+),", text):
        assert abs(np.linalg.norm(np.array(quat[:4], float)) - 1.0) < 1e-5


def _targets_world(text: str) -> dict[str, np.ndarray]:
    """Exported robtargets mapped back to world coordinates [m] through the base pose."""
    out = {}
    for n, v in re.findall(r"CONST robtarget (\w+) := \[\[([-\d.,]+)\]", text):
        p_base = np.array(v.split(","), float) / 1000.0
        out[n] = ROBOT.T_world_base[:3, :3] @ p_base + ROBOT.T_world_base[:3, 3]
    return out


def test_targets_lie_on_the_trajectory_in_world_frame() -> None:
    traj = _traj()
    text = rapid_module(traj, ROBOT, load=LOAD)
    for name, p in _targets_world(text).items():
        d = np.linalg.norm(traj.tcp_pos_world - p, axis=1)
        assert d.min() < 1e-5, name  # 0.01 mm: the 2-decimal mm rounding
    # Orientation: each quaternion maps back to the trajectory's TCP rotation.
    from scipy.spatial.transform import Rotation

    for n, q in re.findall(r"CONST robtarget (\w+) := \[\[[-\d.,]+\],\[([-\d.,]+)\]", text):
        w, x, y, z = np.array(q.split(","), float)
        R_world = ROBOT.T_world_base[:3, :3] @ Rotation.from_quat([x, y, z, w]).as_matrix()
        i = int(np.argmin(np.linalg.norm(traj.tcp_pos_world - _targets_world(text)[n], axis=1)))
        assert np.allclose(R_world, traj.tcp_rot_world[i], atol=1e-5), n


def test_tool_data_carries_the_tcp_and_the_load() -> None:
    text = rapid_module(_traj(), ROBOT, load=LOAD)
    (tool,) = re.findall(r"PERS tooldata tBell := \[TRUE,\[\[([-\d.,]+)\],\[([-\d.,]+)\]\],"
                         r"\[([\d.]+),\[([-\d.,]+)\]", text)
    assert np.allclose(np.array(tool[0].split(","), float), [85.0, 0.0, 245.0])
    w, x, y, z = np.array(tool[1].split(","), float)
    assert np.allclose([w, x, y, z], [np.cos(np.pi / 8), 0, np.sin(np.pi / 8), 0], atol=1e-6)
    assert float(tool[2]) == 7.0 and np.allclose(np.array(tool[3].split(","), float), [0, 0, 120])


def test_tool_load_comes_from_the_robot_model() -> None:
    from paintcell.output.export_rapid import tool_load
    from paintcell.robots import load_robot

    mass, cog = tool_load(load_robot("abb_paint"))
    # abb_paint.xml: the bell (7 kg, centre of mass 120 mm out along the flange axis).
    assert mass == pytest.approx(7.0) and np.allclose(cog, [0.0, 0.0, 0.12])


def test_brush_events_fire_where_the_trajectory_switches_paint() -> None:
    traj = _traj()
    text = rapid_module(traj, ROBOT, load=LOAD, style="trigg")
    on = re.findall(r"TriggL (\w+), \w+, tBrushOn, z1,", text)
    off = re.findall(r"TriggL (\w+), \w+, tBrushOff, z1,", text)
    assert len(on) == 2 and len(off) == 2
    # Pass 0's brush switches on 100 samples into the pass (see _traj): the brush-on target is
    # that sample, not the pass start.
    first_on = int(np.flatnonzero(traj.paint_on)[0])
    p = _targets_world(text)[on[0]]
    assert np.linalg.norm(traj.tcp_pos_world[first_on] - p) < 1e-5
    # ... and off at the last painted sample of each pass.
    for k, name in enumerate(off):
        last_on = int(np.flatnonzero(traj.paint_on & (traj.pass_index == k))[-1])
        assert np.linalg.norm(traj.tcp_pos_world[last_on] - _targets_world(text)[name]) < 1e-5
    # PaintL style: SetBrush follows the move that reaches the switching target (it acts from
    # the start of the next move, i.e. at that target).
    text = rapid_module(traj, ROBOT, load=LOAD, style="paintl")
    sets = re.findall(r"PaintL (\w+), \w+, z1, tBell;\n    SetBrush (\d);", text)
    assert [n for n, b in sets if b == "1"] == on and [n for n, b in sets if b == "0"] == off
    text = rapid_module(_traj(), ROBOT, load=LOAD, style="paintl")
    assert text.count("SetBrush 1;") == 2 and text.count("SetBrush 0;") == 2


def test_speeds_reproduce_trajectory_tcp_speed() -> None:
    traj = _traj()
    text = rapid_module(traj, ROBOT, load=LOAD, max_spacing_m=0.05)
    targets = {n: np.array(v.split(","), float) for n, v in
               re.findall(r"CONST robtarget (\w+) := \[\[([-\d.,]+)\]", text)}
    speeds = {n: float(v) for n, v in re.findall(r"CONST speeddata v_(\w+) := \[([\d.]+),", text)}
    # Re-measure: distance between consecutive targets of pass 0 over the trajectory's time.
    names = sorted((n for n in targets if n.startswith("p0_")), key=lambda n: int(n.split("_")[1]))
    idx = np.flatnonzero(traj.pass_index == 0)
    T_base_world = np.linalg.inv(ROBOT.T_world_base)
    pos_mm = (traj.tcp_pos_world[idx] @ T_base_world[:3, :3].T + T_base_world[:3, 3]) * 1000
    for a, b in zip(names[:-1], names[1:], strict=True):
        ia = int(np.argmin(np.linalg.norm(pos_mm - targets[a], axis=1)))
        ib = int(np.argmin(np.linalg.norm(pos_mm - targets[b], axis=1)))
        v_true = (np.linalg.norm(np.diff(pos_mm[ia:ib + 1], axis=0), axis=1).sum()
                  / (traj.t_s[idx[ib]] - traj.t_s[idx[ia]]))
        assert speeds[b] == pytest.approx(v_true, rel=1e-3)
    # Spacing respected: no two consecutive targets more than 50 mm apart.
    pts = np.array([targets[n] for n in names])
    assert np.linalg.norm(np.diff(pts, axis=0), axis=1).max() <= 50.0 + 1.0


def test_quaternion_and_confdata_conventions() -> None:
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("xyz", [0.3, -0.2, 1.1]).as_matrix()
    q = quat_wxyz_from_matrix(R)
    w, x, y, z = q
    R2 = Rotation.from_quat([x, y, z, w]).as_matrix()
    assert np.allclose(R, R2, atol=1e-12) and w >= 0
    assert confdata(np.radians([100, 0, 0, -10, 30, 200])) == (1, -1, 2, 0)
    assert confdata(np.radians([0, 0, 0, 0, -30, 0]))[3] & 1 == 1


def test_bad_options_raise() -> None:
    with pytest.raises(ValueError, match="style"):
        rapid_module(_traj(), ROBOT, load=LOAD, style="kuka")
    for bad in (0.0, float("nan"), -1.0):
        with pytest.raises(ValueError, match="spacing"):
            rapid_module(_traj(), ROBOT, load=LOAD, max_spacing_m=bad)


def test_a_rail_robot_writes_its_carriage_as_an_external_axis() -> None:
    """A robot on a rail (its program's first column the carriage [m]): every joint target
    holds the arm's six axes [deg] and the carriage [mm] as eax_a, every pass target its pass's
    carriage, the tool data the arm's; the module passes rapidchecker's independent grammar."""
    from tests.trust_cases import flat, rapid_parse, small_program

    arm = small_program()
    carriage = np.linspace(0.3, 0.5, len(arm.t_s))
    traj = JointTrajectory(**{**{n: getattr(arm, n) for n in (
        "t_s", "tcp_pos_world", "tcp_rot_world", "v_tcp_planned", "paint_on", "pass_index",
        "segment", "s_pass_m")}, "q": np.c_[carriage, arm.q], "qd": np.c_[carriage, arm.qd],
        "qdd": np.c_[carriage, arm.qdd]}, robot_name="rail",
        joint_names=("rail", *arm.joint_names))
    placed = SimpleNamespace(T_world_base=ROBOT.T_world_base, T_flange_tcp=ROBOT.T_flange_tcp)
    robot = SimpleNamespace(T_world_base=ROBOT.T_world_base, T_flange_tcp=np.eye(4),
                            rail=SimpleNamespace(arm=SimpleNamespace(placed=lambda T: placed)))
    text = rapid_module(traj, robot, load=LOAD, max_spacing_m=0.2)
    assert "MoveAbsJ" in flat(rapid_parse(text))
    joints = re.findall(r"CONST jointtarget (\w+) := \[\[([^\]]*)\],\[([-\d.]+),9E9", text)
    assert len(joints) >= 2
    for name, axes, eax in joints:
        deg = np.array(axes.split(","), float)
        i = int(np.argmin(np.abs(np.degrees(arm.q) - deg).max(axis=1)))   # the sample it is
        assert len(deg) == 6 and np.abs(np.degrees(arm.q[i]) - deg).max() < 1e-3, name
        assert abs(float(eax) - 1000 * carriage[i]) < 0.05, name
    first = np.flatnonzero(traj.segment == PAINT)[0]
    eaxes = re.findall(r"CONST robtarget p0_\d+ := .*,\[(-?[\d.]+),9E9", text)
    assert eaxes and all(abs(float(e) - 1000 * carriage[first]) < 0.05 for e in eaxes)
    assert "[[85.00,0.00,245.00]" in text          # the arm's tool, not the rail robot's
