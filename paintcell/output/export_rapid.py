"""Export a validated joint program as an ABB RAPID module.

The whole validated program is exported in time order. Each paint pass becomes a chain of linear
moves (`MoveL`/`TriggL`, or `PaintL` with the paint option) through targets taken from the
trajectory that was validated in simulation, each with its own `speeddata` = distance ÷ time
between the two targets in that trajectory, so the controller reproduces the validated speed
profile (slowdowns included). The approach, the turn-arounds and the retract become flying
`MoveAbsJ` moves through joint targets sampled from the same trajectory (no configuration
ambiguity, the same off-part path that was checked for collisions). Every move is a flying move
(zones) except the first and the last, so the arm enters and leaves each pass at speed, as it did
in simulation; brush on/off fires where the trajectory switches paint on and off.

Targets are expressed in the robot base frame (`wobj0`), in millimetres, with the tool's TCP and
load in `tooldata` (from the robot model). Quaternions follow RAPID's [q1 = w, q2 = x, q3 = y,
q4 = z] order. A rail robot's carriage goes in the external axis `eax_a` [mm] of every target
(the track as a coordinated external axis); its joint targets hold the arm's six axes.

A cell of N robots on a conveyor (`MultiMove`, `cell_modules`) gets one module per robot, a
MultiMove task each:
- Synchronisation: every module declares the cell's task list and waits for the others with
  `WaitSyncTask` before its first move toward the part and after its program (the programs were
  validated on one clock starting together). The robots paint apart, each on its own part, so
  their moves are not paired one to one: `SyncMoveOn` (synchronised movement: the same number
  of moves with an `ID` argument in every task) does not apply; each task's timing inside the
  cycle is its validated program's.
- Conveyor tracking: the pass moves (MoveL / TriggL / PaintL) are given in the conveyor work
  object `wobjcnv1` (`wobjdata` with robhold FALSE, ufprog FALSE: a moving user frame, and ufmec
  the conveyor's mechanical unit CNV1, activated with `ActUnit`). Their targets are in the body's
  frame: the object frame (oframe) is the body at conveyor position 0 in the conveyor's base
  frame, so the controller adds the line motion to every target. `WaitWObj` picks the body up
  before the first move toward it, `DropWObj` releases it after the last pass move; the joint
  moves between passes (MoveAbsJ) are not coordinated. The header states the line speed and
  direction the programs were validated at and the conveyor base frame calibration they assume.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from paintcell.core.transforms import quat_wxyz_from_matrix
from paintcell.coverage.offset_polyline import arc_length
from paintcell.motion.flow import FLOW_STEP
from paintcell.motion.joint_trajectory import PAINT, JointTrajectory
from paintcell.output.rapid_text import IDENT, RESERVED, comment_text, rapid_ident

_EXT = "[9E9,9E9,9E9,9E9,9E9,9E9]"


#: Zone of moves inside a pass [mm]: small, so the TCP stays on the validated path.
PASS_ZONE = "z1"
#: Zone of the joint via points between passes: the path only has to stay clear of the part.
VIA_ZONE = "z20"
#: Lowest TCP speed written for a move between passes [mm/s] (a via near a stop would get ~0).
MIN_VIA_SPEED_MM_S = 50.0


@dataclass(frozen=True)
class RapidTarget:
    """One exported Cartesian target of a pass (base frame, mm / quaternion / speed mm/s)."""

    name: str
    pos_mm: np.ndarray
    quat_wxyz: np.ndarray
    conf: tuple[int, int, int, int]
    speed_mm_s: float
    brush: int | None  # n ≥ 1: on at brush-table level n from this target, 0: off, None: same


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


def _pass_targets(traj: JointTrajectory, q: np.ndarray, T_base_world: np.ndarray,
                  idx: np.ndarray, k: int, max_spacing_m: float) -> list[RapidTarget]:
    """Targets of one pass (sample indices `idx`, in time order) at most `max_spacing_m` apart
    (q: the arm's six joint columns of `traj.q` [rad], for the configuration).

    The first target is where the pass starts (reached by the previous move); each later target
    carries the speed distance ÷ time from the previous target in the trajectory.
    """
    pos_world = traj.tcp_pos_world[idx]
    on = traj.paint_on[idx]
    level = brush_numbers(traj.flow[idx])
    s = arc_length(pos_world)
    # Keep: first, last, every brush toggle and flow level change, and enough points in between
    # to respect the spacing.
    toggles = np.flatnonzero((np.diff(on.astype(np.int8)) != 0)
                             | (on[1:] & (np.diff(level) != 0))) + 1
    n_seg = max(1, int(np.ceil(s[-1] / max_spacing_m)))
    regular = np.searchsorted(s, np.linspace(0.0, s[-1], n_seg + 1))
    keep = np.unique(np.concatenate([[0, len(idx) - 1], toggles,
                                     np.clip(regular, 0, len(idx) - 1)]))
    R_base_world, p_base_world = T_base_world[:3, :3], T_base_world[:3, 3]
    pos_base_mm = (pos_world[keep] @ R_base_world.T + p_base_world) * 1000.0
    rot_base = np.einsum("ij,kjl->kil", R_base_world, traj.tcp_rot_world[idx][keep])
    quats = quat_wxyz_from_matrix(rot_base)
    t = traj.t_s[idx][keep]
    speed_mm_s = np.empty(len(keep))
    speed_mm_s[1:] = np.diff(s[keep]) / np.maximum(np.diff(t), 1e-9) * 1000.0
    # The move into the first target comes from the previous segment; give it the pass's
    # starting speed so the arm does not slow down into the pass.
    speed_mm_s[0] = speed_mm_s[1] if len(keep) > 1 else MIN_VIA_SPEED_MM_S
    targets = []
    for j, i in enumerate(keep):
        brush = None
        prev = keep[j - 1] if j > 0 else -1
        if on[i] and (j == 0 or not on[prev] or level[i] != level[prev]):
            brush = int(level[i])
        elif j > 0 and not on[i] and on[prev]:
            brush = 0
        if j == len(keep) - 1 and on[i]:
            brush = 0  # the brush goes off where the pass (and its painting) ends
        targets.append(RapidTarget(f"p{k}_{j}", pos_base_mm[j], quats[j],
                                   confdata(q[idx[i]]), float(speed_mm_s[j]), brush))
    return targets


def brush_numbers(flow: np.ndarray) -> np.ndarray:
    """Brush-table entry of each commanded flow ÷ the part's flow (`JointTrajectory.flow`):
    1 at full flow, n at 1 − (n − 1) · `FLOW_STEP` (the levels of `paintcell.motion.flow`)."""
    return 1 + np.round((1.0 - np.asarray(flow, float)) / FLOW_STEP).astype(np.int64)


def brush_flow_of(n: int) -> float:
    """The flow ÷ the part's flow [-] of brush-table entry n ≥ 1 (`brush_numbers`)."""
    return 1.0 - (n - 1) * FLOW_STEP


def _triggers(brush: int | None, levels: list[int], prev: int) -> str:
    """The `TriggL` trigger arguments of a pass target whose brush event is `brush`
    (`RapidTarget.brush`; the last event before it: `prev`), with the flow levels `levels` in
    use (empty: the program's flow is constant, no flow trigger)."""
    if brush is None:
        return ""
    if brush == 0:
        return "tBrushOff, "
    if not levels:
        return "tBrushOn, "
    if prev == 0:
        return f"tBrushOn \\T2:=tFlow{brush}, "
    return f"tFlow{brush}, "


def _via_targets(traj: JointTrajectory, idx: np.ndarray, via_dt_s: float
                 ) -> list[tuple[int, float]]:
    """Joint via points of a move between passes: (sample index, TCP speed [mm/s]) every
    `via_dt_s` of the trajectory and at its end (the move's start is the previous segment's
    end)."""
    t = traj.t_s[idx]
    picks = np.unique(np.concatenate([np.searchsorted(t, np.arange(t[0] + via_dt_s, t[-1],
                                                                    via_dt_s)),
                                      [len(idx) - 1]]))
    out = []
    prev = idx[0] - 1 if idx[0] > 0 else idx[0]
    for p in picks:
        i = idx[p]
        seg = traj.tcp_pos_world[prev:i + 1]
        dist = float(np.linalg.norm(np.diff(seg, axis=0), axis=1).sum())
        dt = max(float(traj.t_s[i] - traj.t_s[prev]), 1e-9)
        out.append((int(i), max(dist / dt * 1000.0, MIN_VIA_SPEED_MM_S)))
        prev = i
    return out


def tool_load(robot: Any) -> tuple[float, np.ndarray]:
    """(mass [kg], centre of mass in the flange frame [m]) of the tool, from the robot model.

    robot: needs `mjcf_path`, `flange_site_name`; the tool is the body carrying the flange site.
    """
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(robot.mjcf_path))
    site = model.site(robot.flange_site_name)
    body = int(site.bodyid[0])
    R_body_site = np.zeros(9)
    mujoco.mju_quat2Mat(R_body_site, site.quat)
    cog_site = R_body_site.reshape(3, 3).T @ (model.body_ipos[body] - site.pos)
    return float(model.body_mass[body]), cog_site


def program_runs(traj: JointTrajectory) -> list[tuple[bool, int, np.ndarray]]:
    """Contiguous runs of the program in time order: (is_paint, pass index, sample indices)."""
    paint = traj.segment == PAINT
    key = np.where(paint, traj.pass_index, -1)
    starts = np.flatnonzero(np.concatenate([[True], (key[1:] != key[:-1])
                                            | (paint[1:] != paint[:-1])]))
    ends = np.concatenate([starts[1:], [len(key)]])
    return [(bool(paint[a]), int(key[a]), np.arange(a, b)) for a, b in zip(starts, ends,
                                                                            strict=True)]


@dataclass(frozen=True)
class MultiMove:
    """One robot's task in a cell of several on a conveyor (module doc).

    tasks: every task's name, this one's included (RAPID identifiers, `task_names`).
    conveyor: has `unit` (3,) the line's direction in the world and `speed_m_s` [m/s].
    T_world_body: (4, 4) the body at conveyor position 0 (the static cell the program was built
        in): the frame its pass targets are written in.
    delay_s: the task's start delay after the common start [s].
    flow_factor: its bell flow relative to the applicator's, stated in the header (a robot with
        several jobs: one per job, None where a job's is not set).
    """

    tasks: tuple[str, ...]
    conveyor: Any
    T_world_body: np.ndarray
    delay_s: float = 0.0
    flow_factor: float | tuple[float | None, ...] | None = None


def task_names(robot_names: Sequence[str]) -> list[str]:
    """The MultiMove task (and module, and .mod file) name of each robot: a RAPID identifier."""
    return [rapid_ident(f"T_{n.upper()}") for n in robot_names]


def conveyor_base_frame(conveyor: Any) -> np.ndarray:
    """(4, 4) the conveyor's base frame in the world, as the modules assume the controller's
    CNV1 calibration: origin at the world origin, x along the line's direction of travel, z the
    world's up made orthogonal to it (a vertical line: the world's x)."""
    x = np.asarray(conveyor.unit, float)
    up = np.array([0.0, 0.0, 1.0]) if abs(x[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
    z = up - (up @ x) * x
    z /= np.linalg.norm(z)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return T


def _pose_text(p_mm: np.ndarray, q: np.ndarray) -> str:
    """RAPID pose [[x,y,z],[q1,q2,q3,q4]] of a position [mm] and a quaternion (w, x, y, z)."""
    return (f"[[{p_mm[0]:.2f},{p_mm[1]:.2f},{p_mm[2]:.2f}],"
            f"[{q[0]:.6f},{q[1]:.6f},{q[2]:.6f},{q[3]:.6f}]]")


def _multimove_head(mm: MultiMove, name: str, rail: bool, job_first_pass: list[int]) -> list[str]:
    """The declarations and header comments of a MultiMove task (module doc)."""
    u, n = mm.conveyor.unit, len(mm.tasks)
    T = np.linalg.inv(conveyor_base_frame(mm.conveyor)) @ mm.T_world_body   # wobjcnv1's oframe
    tasks = ",".join(f'["{t}"]' for t in mm.tasks)
    head = [
        f"  ! Booth: task {name} of {n} ({', '.join(mm.tasks)}), synchronised "
        "with WaitSyncTask at the start and end.",
        f"  ! Conveyor tracking: validated at {mm.conveyor.speed_m_s:.4f} m/s along "
        f"[{u[0]:.3f},{u[1]:.3f},{u[2]:.3f}] (world); pass moves in the conveyor work object "
        "wobjcnv1 (unit CNV1).",
        "  ! CNV1's base frame calibrated at the world origin, x along the line, at conveyor "
        "position 0; wobjcnv1's object frame: the body there.",
        "  ! Pass targets in the body frame [mm]; joint targets: the arm's axes [deg]; speeds "
        "reproduce the validated TCP speed between targets.",
        f"  PERS tasks booth_tasks{{{n}}} := [{tasks}];",
        "  VAR syncident sync_start;",
        "  VAR syncident sync_end;",
        '  PERS wobjdata wobjcnv1 := [FALSE,FALSE,"CNV1",[[0,0,0],[1,0,0,0]],'
        f"{_pose_text(1000.0 * T[:3, 3], quat_wxyz_from_matrix(T[:3, :3]))}];",
    ]
    if rail:
        head.append("  ! Rail: the carriage is external axis eax_a [mm] of every target.")
    if isinstance(mm.flow_factor, tuple):        # several jobs, each at its part's flow
        for k, (f, p0) in enumerate(zip(mm.flow_factor, job_first_pass, strict=True)):
            if f is not None:
                head.append(f"  ! Bell flow of job {k + 1} (from pass p{p0}_): {f:.3f} x the "
                            "applicator's nominal rate (paintcell.booth.booth_build): set it "
                            "in the brush table.")
    elif mm.flow_factor is not None:
        head.append(f"  ! Bell flow: {mm.flow_factor:.3f} x the applicator's nominal rate (the "
                    "booth's common film build, paintcell.booth.booth_build): set it in the "
                    "brush table.")
    return head


def rapid_module(traj: JointTrajectory, robot: Any, module_name: str = "paintcell",
                 style: str = "trigg", max_spacing_m: float = 0.05, via_dt_s: float = 0.2,
                 brush_signal: str = "doBrush", flow_signal: str = "aoFlow",
                 load: tuple[float, np.ndarray] | None = None,
                 validation: list[str] | None = None,
                 multimove: MultiMove | None = None) -> str:
    """RAPID module text of the whole program in `traj` for `robot`.

    robot: needs `T_world_base` (4, 4) and `T_flange_tcp` (4, 4) for `tooldata`, and (unless
        `load` is given) `mjcf_path` + `flange_site_name` for the tool load; a rail robot
        (`robot.rail` not None: `traj.q`'s first column is the carriage [m]) the same of its
        arm, `robot.rail.arm`.
    style: "trigg" — `TriggL` with `TriggIO` on the digital output `brush_signal` (and, where
        the program lowers the flow, the analog output `flow_signal`: the flow ÷ the part's);
        "paintl" — `PaintL` with `SetBrush` n (ABB paint option; brush-table entry n,
        `brush_numbers`).
    max_spacing_m: the longest stretch of a pass between two exported targets [m].
    via_dt_s: time between joint via points on moves between passes [s].
    load: (mass [kg], centre of mass in the flange frame (3,) [m]) of the tool; None: from the
        robot model.
    validation: header comment lines saying whether and how the program was validated (from
        `validation_header`); None: the header makes no claim about validation.
    multimove: this robot's task in a cell of several on a conveyor (module doc); None: a robot
        alone, its targets in its base frame.
    """
    if style not in ("trigg", "paintl"):
        raise ValueError(f"unknown RAPID style {style!r}; use 'trigg' or 'paintl'")
    for what, sig, like in (("brush signal", brush_signal, "a digital output like doBrush"),
                            ("flow signal", flow_signal, "an analog output like aoFlow")):
        if not IDENT.match(sig) or sig.upper() in RESERVED:
            raise ValueError(f"{what} {sig!r} is not a RAPID identifier; name {like}")
    for name, v in (("target spacing", max_spacing_m), ("via point interval", via_dt_s)):
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive finite number, got {v!r}")
    rail = getattr(robot, "rail", None) is not None
    arm = robot.rail.arm.placed(robot.T_world_base) if rail else robot
    q = traj.q[:, 1:] if rail else traj.q                       # the arm's six axes [rad]
    ext = [f"[{1000.0 * c:.1f},9E9,9E9,9E9,9E9,9E9]" for c in traj.q[:, 0]] if rail \
        else [_EXT] * len(q)                                    # the carriage [mm] as eax_a
    T_world_frame = arm.T_world_base if multimove is None else multimove.T_world_body
    T_base_world = np.linalg.inv(np.asarray(T_world_frame, float))
    T_flange_tcp = np.asarray(arm.T_flange_tcp, float)
    tq = quat_wxyz_from_matrix(T_flange_tcp[:3, :3])
    tp = T_flange_tcp[:3, 3] * 1000.0
    mass, cog_m = load if load is not None else tool_load(arm)
    cog = np.asarray(cog_m, float) * 1000.0
    tool = "tBell" if multimove is None else r"tBell \WObj:=wobjcnv1"    # of the pass moves

    decl: list[str] = []
    proc: list[str] = []
    # brush-table entries the program's flow uses besides full flow (`paintcell.motion.flow`)
    levels = sorted(set(brush_numbers(traj.flow[traj.paint_on]).tolist()) - {1})
    n_via = 0
    n_pass = 0
    last_pass_move = -1
    prev_brush = 0
    for is_paint, k, idx in program_runs(traj):
        if is_paint:
            n_pass += 1
            proc.append(f"    ! pass {k}")
            for tg in _pass_targets(traj, q, T_base_world, idx, k, max_spacing_m):
                c = tg.conf
                decl.append(f"  CONST robtarget {tg.name} := "
                            f"{_pose_text(tg.pos_mm, tg.quat_wxyz)[:-1]},"
                            f"[{c[0]},{c[1]},{c[2]},{c[3]}],{ext[idx[0]]}];")
                decl.append(f"  CONST speeddata v_{tg.name} := [{tg.speed_mm_s:.1f},500,5000,"
                            "1000];")
                trig = _triggers(tg.brush, levels, prev_brush)
                move = "PaintL" if style == "paintl" else "TriggL" if trig else "MoveL"
                proc.append(f"    {move} {tg.name}, v_{tg.name}, "
                            f"{trig if style == 'trigg' else ''}{PASS_ZONE}, {tool};")
                last_pass_move = len(proc)
                if style == "paintl" and tg.brush is not None:
                    # SetBrush acts from the start of the next move, i.e. at this target.
                    proc.append(f"    SetBrush {tg.brush};")
                if tg.brush is not None:
                    prev_brush = tg.brush
        else:
            for i, v in _via_targets(traj, idx, via_dt_s):
                name = f"j{n_via}"
                n_via += 1
                decl.append(f"  CONST jointtarget {name} := [[" + ",".join(
                    f"{a:.3f}" for a in np.degrees(q[i])) + "]," + ext[i] + "];")
                decl.append(f"  CONST speeddata v_{name} := [{v:.1f},500,5000,1000];")
                proc.append(f"    MoveAbsJ {name}, v_{name}, {VIA_ZONE}, tBell;")
    # The program ends standing still at home.
    proc[-1] = re.sub(r", (z\d+), (tBell[^;]*);$", r", fine, \2;", proc[-1])

    name = rapid_ident(module_name)
    L: list[str] = [f"MODULE {name}"]
    L.append(f"  ! Generated by paintcell: {n_pass} passes, cycle time {traj.duration_s:.2f} s.")
    for line in validation or []:
        L.append(f"  ! {comment_text(line)}".rstrip())
    if multimove is None:
        L.append("  ! Targets in the robot base frame (wobj0) [mm]; speeds reproduce the "
                 "validated TCP speed between targets.")
    else:
        L.extend(_multimove_head(multimove, name, rail,
                                 list(traj.meta.get("job_first_pass_index", []))))
        if last_pass_move >= 0:
            proc.insert(last_pass_move, "    DropWObj wobjcnv1;")
        proc.extend(["    DeactUnit CNV1;", "    WaitSyncTask sync_end, booth_tasks;"])
    L.append(f"  PERS tooldata tBell := [TRUE,{_pose_text(tp, tq)},"
             f"[{mass:.2f},[{cog[0]:.1f},{cog[1]:.1f},{cog[2]:.1f}],[1,0,0,0],0,0,0]];")
    if levels:
        L.append("  ! Brush table: the flow follows the validated time law where it is slower "
                 "than planned (paintcell.motion.flow); entry n is "
                 f"1 - {FLOW_STEP:g} (n - 1) x the part's flow. Used:")
        used = [f"{n} ({brush_flow_of(n):.2f})" for n in [1, *levels]]
        L.extend("  ! " + comment_text(", ".join(used[k:k + 10]))
                 for k in range(0, len(used), 10))
    if style == "trigg":
        L.append("  VAR triggdata tBrushOn;")
        L.append("  VAR triggdata tBrushOff;")
        L.extend(f"  VAR triggdata tFlow{n};" for n in [1, *levels] if levels)
    L.append("  CONST jointtarget jHome := [[" + ",".join(
        f"{a:.3f}" for a in np.degrees(q[0])) + "]," + ext[0] + "];")
    L.extend(decl)
    L.append("")
    L.append("  PROC main()")
    if style == "trigg":
        L.append(f"    TriggIO tBrushOn, 0 \\DOp:={brush_signal}, 1;")
        L.append(f"    TriggIO tBrushOff, 0 \\DOp:={brush_signal}, 0;")
        L.extend(f"    TriggIO tFlow{n}, 0 \\AOp:={flow_signal}, {brush_flow_of(n):.2f};"
                 for n in [1, *levels] if levels)
    L.append("    MoveAbsJ jHome, v1000, fine, tBell;")
    if multimove is not None:
        L.append("    WaitSyncTask sync_start, booth_tasks;")
        if multimove.delay_s > 0:
            L.append(f"    WaitTime {multimove.delay_s:.3f};   ! staggered start: arm clearance")
        L.extend(["    ActUnit CNV1;", "    WaitWObj wobjcnv1;"])
    L.extend(proc)
    L.append("  ENDPROC")
    L.append("ENDMODULE")
    return "\n".join(L) + "\n"


def cell_modules(cell: Any, metrics: dict[str, Any], jobs: dict[int, tuple[Any, ...]],
                 programs: Sequence[JointTrajectory], robots: Sequence[Any],
                 **options: Any) -> dict[str, str]:
    """{task name: module text} for every robot of a cell on a conveyor (module doc): robot i's
    static program `programs[i]` as task `task_names(...)[i]`, its start delay and flow from the
    run's `metrics` (allocation, film build). cell: has `robots` (each `.name`), `parts` (each
    `.part`, its name), `conveyor` and `body_placement.matrix`; jobs: {robot: its jobs, each
    with `.part`}. options: `rapid_module`'s style, max_spacing_m and validation."""
    names = task_names([r.name for r in cell.robots])
    delays = metrics["allocation"].get("start_delays_s", [0.0] * len(names))
    build = metrics.get("film_build", {}).get("parts", {})
    flows: list[Any] = []
    for i in range(len(names)):
        f = tuple(build.get(f"{j.part}:{cell.parts[j.part].part}", {}).get("flow_factor")
                  for j in jobs[i])
        flows.append(f[0] if len(f) == 1 else f)
    T_body = np.asarray(cell.body_placement.matrix, float)
    return {n: rapid_module(tr, rb, module_name=n, multimove=MultiMove(
                tuple(names), cell.conveyor, T_body, d, f), **options)
            for n, rb, tr, d, f in zip(names, robots, programs, delays, flows, strict=True)}
