"""Export a validated joint program as an ABB RAPID module.

Each paint pass becomes a chain of linear moves (`MoveL`/`TriggL`, or `PaintL` with the paint
option) through targets taken from the trajectory that was validated in simulation, each with its
own `speeddata` = distance ÷ time between the two targets in that trajectory, so the controller
reproduces the validated speed profile (slowdowns included). Moves between passes are `MoveAbsJ`
to joint targets (no configuration ambiguity). Brush on/off fires where the trajectory switches
paint on and off.

Targets are expressed in the robot base frame (`wobj0`), in millimetres, with the tool's TCP in
`tooldata`. Quaternions follow RAPID's [q1 = w, q2 = x, q3 = y, q4 = z] order.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from planning.transforms import quat_wxyz_from_matrix
from sim.joint_trajectory import PAINT, JointTrajectory

_EXT = "[9E9,9E9,9E9,9E9,9E9,9E9]"


@dataclass(frozen=True)
class RapidTarget:
    """One exported Cartesian target of a pass (base frame, mm / quaternion / speed mm/s)."""

    name: str
    pos_mm: np.ndarray
    quat_wxyz: np.ndarray
    conf: tuple[int, int, int, int]
    speed_mm_s: float
    brush: int | None  # 1: switch on at this target, 0: switch off, None: no change


def confdata(q: np.ndarray) -> tuple[int, int, int, int]:
    """ABB `confdata` [cf1, cf4, cf6, cfx] of a 6-axis joint vector [rad].

    cf1/cf4/cf6: quarter revolution of axes 1, 4 and 6 (floor(q / 90°)). cfx encodes the arm
    configuration bits of ABB's convention for ortho-parallel arms: bit 2 set when the wrist
    centre is behind axis 1 (backward), bit 1 when the elbow is down (q3 above the singular
    stretch), bit 0 when axis 5 is negative (wrist flipped).
    """
    cf = [int(np.floor(q[i] / (np.pi / 2))) for i in (0, 3, 5)]
    wrist_flip = 1 if q[4] < 0 else 0
    elbow_down = 1 if q[2] < -np.pi / 2 else 0
    backward = 1 if abs(q[1]) > np.pi / 2 else 0
    return cf[0], cf[1], cf[2], (backward << 2) | (elbow_down << 1) | wrist_flip


def _ident(name: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not s or not s[0].isalpha():
        s = "m" + s
    return s[:32]


def _pass_targets(traj: JointTrajectory, T_base_world: np.ndarray, idx: np.ndarray, k: int,
                  max_spacing_m: float) -> list[RapidTarget]:
    """Targets of one pass (sample indices `idx`, in time order) at most `max_spacing_m` apart."""
    pos_w = traj.tcp_pos_world[idx]
    on = traj.paint_on[idx]
    step = np.linalg.norm(np.diff(pos_w, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    # Keep: first, last, every brush toggle, and enough points in between to respect the spacing.
    toggles = np.flatnonzero(np.diff(on.astype(np.int8)) != 0) + 1
    n_seg = max(1, int(np.ceil(s[-1] / max_spacing_m)))
    regular = np.searchsorted(s, np.linspace(0.0, s[-1], n_seg + 1))
    keep = np.unique(np.concatenate([[0, len(idx) - 1], toggles, np.clip(regular, 0,
                                                                        len(idx) - 1)]))
    R_bw, p_bw = T_base_world[:3, :3], T_base_world[:3, 3]
    pos_b = (pos_w[keep] @ R_bw.T + p_bw) * 1000.0
    rot_b = np.einsum("ij,kjl->kil", R_bw, traj.tcp_rot_world[idx][keep])
    quats = quat_wxyz_from_matrix(rot_b)
    t = traj.t_s[idx][keep]
    targets = []
    for j, i in enumerate(keep):
        if j == 0:
            speed = float(np.linalg.norm(traj.tcp_pos_world[idx[0]] - traj.tcp_pos_world[
                idx[min(1, len(idx) - 1)]]) / max(traj.dt_s, 1e-9))
        else:
            speed = float((s[i] - s[keep[j - 1]]) / max(t[j] - t[j - 1], 1e-9))
        brush = None
        if j == 0 and on[i]:
            brush = 1
        elif j > 0 and on[i] != on[keep[j - 1]]:
            brush = 1 if on[i] else 0
        targets.append(RapidTarget(f"p{k}_{j}", pos_b[j], quats[j],
                                   confdata(traj.q[idx[i]]), speed * 1000.0, brush))
    if on[keep[-1]]:
        last = targets[-1]
        targets[-1] = RapidTarget(last.name, last.pos_mm, last.quat_wxyz, last.conf,
                                  last.speed_mm_s, 0)
    return targets


def rapid_module(traj: JointTrajectory, robot: Any, module_name: str = "paintcell",
                 style: str = "trigg", max_spacing_m: float = 0.05,
                 brush_signal: str = "doBrush") -> str:
    """RAPID module text of the program in `traj` for `robot`.

    robot: needs `T_world_base` (4, 4) and optionally `T_flange_tcp` (4, 4) for `tooldata`.
    style: "trigg" — `TriggL` with `TriggIO` on the digital output `brush_signal`; "paintl" —
        `PaintL` with `SetBrush` (ABB paint option).
    max_spacing_m: the longest stretch of a pass between two exported targets [m].
    """
    if style not in ("trigg", "paintl"):
        raise ValueError(f"unknown RAPID style {style!r}; use 'trigg' or 'paintl'")
    if max_spacing_m <= 0:
        raise ValueError("target spacing must be positive [m]")
    T_base_world = np.linalg.inv(np.asarray(robot.T_world_base, float))
    T_flange_tcp = np.asarray(getattr(robot, "T_flange_tcp", np.eye(4)), float)
    tq = quat_wxyz_from_matrix(T_flange_tcp[:3, :3])
    tp = T_flange_tcp[:3, 3] * 1000.0

    passes = sorted(int(k) for k in np.unique(traj.pass_index[traj.segment == PAINT]) if k >= 0)
    all_targets: list[list[RapidTarget]] = []
    starts_q = []
    for k in passes:
        idx = np.flatnonzero((traj.pass_index == k) & (traj.segment == PAINT))
        all_targets.append(_pass_targets(traj, T_base_world, idx, k, max_spacing_m))
        starts_q.append(traj.q[idx[0]])

    name = _ident(module_name)
    L: list[str] = [f"MODULE {name}"]
    L.append(f"  ! Generated by paintcell from a program validated in MuJoCo; {len(passes)} "
             f"passes, cycle time {traj.duration_s:.2f} s.")
    L.append("  ! Targets in the robot base frame (wobj0) [mm]; speeds reproduce the validated "
             "TCP speed between targets.")
    L.append(f"  PERS tooldata tBell := [TRUE,[[{tp[0]:.2f},{tp[1]:.2f},{tp[2]:.2f}],"
             f"[{tq[0]:.6f},{tq[1]:.6f},{tq[2]:.6f},{tq[3]:.6f}]],"
             "[5,[0,0,150],[1,0,0,0],0,0,0]];")
    if style == "trigg":
        L.append("  VAR triggdata tBrushOn;")
        L.append("  VAR triggdata tBrushOff;")
    home = np.degrees(traj.q[0])
    L.append("  CONST jointtarget jHome := [[" + ",".join(f"{a:.3f}" for a in home)
             + "]," + _EXT + "];")
    for k, q in zip(passes, starts_q, strict=True):
        L.append(f"  CONST jointtarget jStart{k} := [[" + ",".join(
            f"{a:.3f}" for a in np.degrees(q)) + "]," + _EXT + "];")
    for targets in all_targets:
        for tg in targets:
            p, qq, c = tg.pos_mm, tg.quat_wxyz, tg.conf
            L.append(f"  CONST robtarget {tg.name} := [[{p[0]:.2f},{p[1]:.2f},{p[2]:.2f}],"
                     f"[{qq[0]:.6f},{qq[1]:.6f},{qq[2]:.6f},{qq[3]:.6f}],"
                     f"[{c[0]},{c[1]},{c[2]},{c[3]}],{_EXT}];")
            L.append(f"  CONST speeddata v_{tg.name} := [{tg.speed_mm_s:.1f},500,5000,1000];")
    L.append("")
    L.append("  PROC main()")
    if style == "trigg":
        L.append(f"    TriggIO tBrushOn, 0 \\DOp:={brush_signal}, 1;")
        L.append(f"    TriggIO tBrushOff, 0 \\DOp:={brush_signal}, 0;")
    L.append("    MoveAbsJ jHome, v1000, fine, tBell;")
    for k, targets in zip(passes, all_targets, strict=True):
        L.append(f"    ! pass {k}")
        L.append(f"    MoveAbsJ jStart{k}, v1000, fine, tBell;")
        for j, tg in enumerate(targets):
            zone = "fine" if j == len(targets) - 1 else "z1"
            if style == "trigg":
                if tg.brush is None:
                    L.append(f"    MoveL {tg.name}, v_{tg.name}, {zone}, tBell;")
                else:
                    trig = "tBrushOn" if tg.brush else "tBrushOff"
                    L.append(f"    TriggL {tg.name}, v_{tg.name}, {trig}, {zone}, tBell;")
            else:
                if tg.brush is not None:
                    L.append(f"    SetBrush {tg.brush};")
                L.append(f"    PaintL {tg.name}, v_{tg.name}, {zone}, tBell;")
    L.append("    MoveAbsJ jHome, v1000, fine, tBell;")
    L.append("  ENDPROC")
    L.append("ENDMODULE")
    return "\n".join(L) + "\n"
