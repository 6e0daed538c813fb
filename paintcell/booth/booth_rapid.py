"""One RAPID module per booth robot: its validated static program
(`paintcell.output.export_rapid`), with
MultiMove synchronisation and the conveyor tracking stated and coordinated.

- Synchronisation: every module declares the booth's task list and waits for the others with
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
- A rail robot: the carriage position goes in the external axis `eax_a` [mm] of every target (the
  track as a coordinated external axis).
"""

from __future__ import annotations

import re
from types import SimpleNamespace
from typing import Any

import numpy as np

from paintcell.core.transforms import quat_wxyz_from_matrix
from paintcell.motion.joint_trajectory import JointTrajectory
from paintcell.output.export_rapid import program_runs, rapid_ident, rapid_module, tool_load

_EXT_RE = r"\[9E9,9E9,9E9,9E9,9E9,9E9\]"


def _arm_view(robot: Any, traj: JointTrajectory) -> tuple[Any, JointTrajectory]:
    """(robot, traj) as the 6-axis exporter sees them; for a rail robot the arm alone in the rail
    frame, and the program without its rail column."""
    if getattr(robot, "rail", None) is None:
        return robot, traj
    arm = robot.rail.arm.placed(robot.T_world_base)
    a = {n: getattr(traj, n) for n in JointTrajectory._ARRAYS}
    a.update(q=traj.q[:, 1:], qd=traj.qd[:, 1:], qdd=traj.qdd[:, 1:])
    return arm, JointTrajectory(**a, robot_name=arm.name, joint_names=traj.joint_names[1:])


def _rail_values_mm(traj: JointTrajectory, via_dt_s: float) -> tuple[dict[int, float],
                                                                    list[float]]:
    """Carriage position [mm] per pass (constant while painting) and at each via point, in the
    order `paintcell.output.export_rapid.rapid_module` writes them (same segment and via
    selection)."""
    per_pass: dict[int, float] = {}
    vias: list[float] = []
    for is_paint, k, idx in program_runs(traj):
        if is_paint:
            per_pass[k] = 1000.0 * float(traj.q[idx[0], 0])
            continue
        t = traj.t_s[idx]
        picks = np.unique(np.concatenate([np.searchsorted(t, np.arange(t[0] + via_dt_s, t[-1],
                                                                        via_dt_s)),
                                          [len(idx) - 1]]))
        vias.extend(1000.0 * float(traj.q[idx[p], 0]) for p in picks)
    return per_pass, vias


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


def _pose_text(T: np.ndarray) -> str:
    """RAPID pose [[x,y,z],[q1,q2,q3,q4]] of a (4, 4) transform [m → mm]."""
    p, q = 1000.0 * T[:3, 3], quat_wxyz_from_matrix(T[:3, :3])
    return (f"[[{p[0]:.2f},{p[1]:.2f},{p[2]:.2f}],"
            f"[{q[0]:.6f},{q[1]:.6f},{q[2]:.6f},{q[3]:.6f}]]")


def booth_module(robot: Any, traj: JointTrajectory, name: str, task_names: list[str],
                 conveyor: Any, T_world_body: np.ndarray, delay_s: float = 0.0,
                 via_dt_s: float = 0.2,
                 flow_factor: float | tuple[float | None, ...] | None = None,
                 **options: Any) -> str:
    """RAPID module text of one booth robot's static program (module doc); T_world_body: (4, 4)
    the body at conveyor position 0 (the static cell the program was built in), the frame its
    pass targets are written in; delay_s: its start delay after the common start [s]
    (`paintcell.booth.booth_stagger.stagger_starts`); flow_factor: its bell flow
    relative to the applicator's (`paintcell.booth.booth_build`), stated in the header (a
    robot with several jobs: one per job). options: `rapid_module`'s style, max_spacing_m and
    validation (header lines)."""
    arm, arm_traj = _arm_view(robot, traj)
    T_world_body = np.asarray(T_world_body, float)
    # the exporter writes its Cartesian targets in its robot's base frame: give it the body's
    in_body = SimpleNamespace(T_world_base=T_world_body, T_flange_tcp=arm.T_flange_tcp)
    text = rapid_module(arm_traj, in_body, module_name=name, via_dt_s=via_dt_s,
                        load=tool_load(arm), **options)
    lines = [ln for ln in text.splitlines() if not ln.startswith("  ! Targets in the robot base")]
    if getattr(robot, "rail", None) is not None:
        per_pass, vias = _rail_values_mm(traj, via_dt_s)
        it = iter(vias)
        for i, ln in enumerate(lines):
            m = re.match(r"\s*CONST robtarget p(\d+)_\d+ :=", ln)
            if m:
                ext = f"[{per_pass[int(m.group(1))]:.1f},9E9,9E9,9E9,9E9,9E9]"
                lines[i] = re.sub(_EXT_RE, ext, ln)
            elif re.match(r"\s*CONST jointtarget j\d+ :=", ln):
                lines[i] = re.sub(_EXT_RE, f"[{next(it):.1f},9E9,9E9,9E9,9E9,9E9]", ln)
            elif re.match(r"\s*CONST jointtarget jHome :=", ln):
                lines[i] = re.sub(_EXT_RE, f"[{1000.0 * traj.q[0, 0]:.1f},9E9,9E9,9E9,9E9,9E9]",
                                  ln)
    u = conveyor.unit
    tasks = ",".join(f'["{t}"]' for t in task_names)
    head = [
        f"  ! Booth: task {name} of {len(task_names)} ({', '.join(task_names)}), synchronised "
        "with WaitSyncTask at the start and end.",
        f"  ! Conveyor tracking: validated at {conveyor.speed_m_s:.4f} m/s along "
        f"[{u[0]:.3f},{u[1]:.3f},{u[2]:.3f}] (world); pass moves in the conveyor work object "
        "wobjcnv1 (unit CNV1).",
        "  ! CNV1's base frame calibrated at the world origin, x along the line, at conveyor "
        "position 0; wobjcnv1's object frame: the body there.",
        "  ! Pass targets in the body frame [mm]; joint targets: the arm's axes [deg]; speeds "
        "reproduce the validated TCP speed between targets.",
        f"  PERS tasks booth_tasks{{{len(task_names)}}} := [{tasks}];",
        "  VAR syncident sync_start;",
        "  VAR syncident sync_end;",
        '  PERS wobjdata wobjcnv1 := [FALSE,FALSE,"CNV1",[[0,0,0],[1,0,0,0]],'
        f"{_pose_text(np.linalg.inv(conveyor_base_frame(conveyor)) @ T_world_body)}];",
    ]
    if getattr(robot, "rail", None) is not None:
        head.append("  ! Rail: the carriage is external axis eax_a [mm] of every target.")
    if isinstance(flow_factor, tuple):        # several jobs, each at its part's flow
        starts = traj.meta.get("job_first_pass_index", [])
        for k, (f, p0) in enumerate(zip(flow_factor, starts, strict=True)):
            if f is not None:
                head.append(f"  ! Bell flow of job {k + 1} (from pass p{p0}_): {f:.3f} x the "
                            "applicator's nominal rate (paintcell.booth.booth_build): set it "
                            "in the brush table.")
    elif flow_factor is not None:
        head.append(f"  ! Bell flow: {flow_factor:.3f} x the applicator's nominal rate (the "
                    "booth's common film build, paintcell.booth.booth_build): set it in the "
                    "brush table.")
    out: list[str] = []
    for ln in lines:
        if ln.startswith("  PERS tooldata tBell"):
            out.extend(head)
        if re.match(r"\s*(MoveL|TriggL|PaintL) ", ln):
            ln = ln.replace(", tBell;", r", tBell \WObj:=wobjcnv1;")
        out.append(ln)
        if ln.strip() == "MoveAbsJ jHome, v1000, fine, tBell;":
            out.append("    WaitSyncTask sync_start, booth_tasks;")
            if delay_s > 0:
                out.append(f"    WaitTime {delay_s:.3f};   ! staggered start: arm clearance")
            out.extend(["    ActUnit CNV1;", "    WaitWObj wobjcnv1;"])
    last = max(i for i, ln in enumerate(out) if ln.endswith(r"\WObj:=wobjcnv1;"))
    out.insert(last + 1, "    DropWObj wobjcnv1;")
    end = out.index("  ENDPROC")
    out[end:end] = ["    DeactUnit CNV1;", "    WaitSyncTask sync_end, booth_tasks;"]
    return "\n".join(out) + "\n"


def booth_rapid_modules(booth: Any, metrics: dict[str, Any], jobs: dict[int, tuple[Any, ...]],
                        static: list[JointTrajectory], robots: list[Any],
                        **options: Any) -> dict[str, str]:
    """{task name: module text} for every robot of a booth: its static program `static[i]`, its
    start delay and flow from the booth's `metrics` (allocation, film build), MultiMove
    synchronisation between the tasks. options: `rapid_module`'s style, max_spacing_m and
    validation."""
    # task and module names, also the .mod file names: RAPID identifiers (no path, no keyword)
    names = [rapid_ident(f"T_{r.name.upper()}") for r in booth.robots]
    delays = metrics["allocation"].get("start_delays_s", [0.0] * len(names))
    build = metrics.get("film_build", {}).get("parts", {})
    flows: list[Any] = []
    for i in range(len(names)):
        f = tuple(build.get(f"{j.part}:{booth.parts[j.part].part}", {}).get("flow_factor")
                  for j in jobs[i])
        flows.append(f[0] if len(f) == 1 else f)
    return {n: booth_module(rb, tr, n, names, booth.conveyor, booth.body_placement.matrix, d,
                            flow_factor=f, **options)
            for n, rb, tr, d, f in zip(names, robots, static, delays, flows, strict=True)}
