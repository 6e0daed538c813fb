"""RAPID export: structure of the module and the speed profile it encodes, re-measured."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

from planning.transforms import quat_wxyz_from_matrix
from sim.export_rapid import confdata, rapid_module
from sim.joint_trajectory import APPROACH, PAINT, RETRACT, TURNAROUND, JointTrajectory

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


ROBOT = SimpleNamespace(T_world_base=np.eye(4), T_flange_tcp=np.eye(4))


def _decls(text: str) -> dict[str, str]:
    """Declared identifier → RAPID data type."""
    return {name: typ for typ, name in
            re.findall(r"^\s*(?:CONST|PERS|VAR) (\w+) (\w+)", text, re.M)}


@pytest.mark.parametrize("style", ["trigg", "paintl"])
def test_module_structure_and_declared_identifiers(style: str) -> None:
    traj = _traj()
    text = rapid_module(traj, ROBOT, module_name="door 1", style=style, max_spacing_m=0.1)
    lines = text.strip().splitlines()
    assert lines[0] == "MODULE door_1" and lines[-1] == "ENDMODULE"
    assert text.count("PROC main()") == 1 and text.count("ENDPROC") == 1
    decls = _decls(text)
    # Every target and speed used in a move instruction is declared with the right type.
    moves = re.findall(r"^\s*(MoveL|TriggL|PaintL) (\w+), (\w+),", text, re.M)
    assert moves
    for _, target, speed in moves:
        assert decls[target] == "robtarget"
        assert decls[speed] == "speeddata"
    for target in re.findall(r"^\s*MoveAbsJ (\w+),", text, re.M):
        assert decls[target] == "jointtarget"
    # Every statement line inside the module ends with a semicolon.
    body = [ln.strip() for ln in lines[1:-1] if ln.strip() and not ln.strip().startswith("!")]
    for ln in body:
        assert ln.endswith(";") or ln in ("PROC main()", "ENDPROC"), ln
    # Quaternions are unit and confdata has 4 integers.
    for quat in re.findall(r"\],\[([-\d.]+),([-\d.]+),([-\d.]+),([-\d.]+)\],\[(-?\d+),", text):
        assert abs(np.linalg.norm(np.array(quat[:4], float)) - 1.0) < 1e-5


def test_brush_events_once_on_and_off_per_pass() -> None:
    text = rapid_module(_traj(), ROBOT, style="trigg")
    assert len(re.findall(r"TriggL \w+, \w+, tBrushOn,", text)) == 2
    assert len(re.findall(r"TriggL \w+, \w+, tBrushOff,", text)) == 2
    text = rapid_module(_traj(), ROBOT, style="paintl")
    assert text.count("SetBrush 1;") == 2 and text.count("SetBrush 0;") == 2


def test_speeds_reproduce_trajectory_tcp_speed() -> None:
    traj = _traj()
    text = rapid_module(traj, ROBOT, max_spacing_m=0.05)
    targets = {n: np.array(v.split(","), float) for n, v in
               re.findall(r"CONST robtarget (\w+) := \[\[([-\d.,]+)\]", text)}
    speeds = {n: float(v) for n, v in re.findall(r"CONST speeddata v_(\w+) := \[([\d.]+),", text)}
    # Re-measure: distance between consecutive targets of pass 0 over the trajectory's time.
    names = sorted((n for n in targets if n.startswith("p0_")), key=lambda n: int(n.split("_")[1]))
    idx = np.flatnonzero(traj.pass_index == 0)
    pos_mm = traj.tcp_pos_world[idx] * 1000
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
        rapid_module(_traj(), ROBOT, style="kuka")
    with pytest.raises(ValueError, match="spacing"):
        rapid_module(_traj(), ROBOT, max_spacing_m=0.0)
