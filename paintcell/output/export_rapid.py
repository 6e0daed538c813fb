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
q4 = z] order.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from paintcell.core.transforms import quat_wxyz_from_matrix
from paintcell.motion.joint_trajectory import PAINT, JointTrajectory

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


#: RAPID's reserved words (ABB, Technical reference manual RAPID kernel, "Reserved words"), and
#: the predefined names and data types the module uses: an identifier may be none of them.
RESERVED = frozenset("""
    ALIAS AND BACKWARD CASE CONNECT CONST DEFAULT DIV DO ELSE ELSEIF ENDFOR ENDFUNC ENDIF
    ENDMODULE ENDPROC ENDRECORD ENDTEST ENDTRAP ENDWHILE ERROR EXIT FALSE FOR FROM FUNC GOTO IF
    INOUT LOCAL MOD MODULE NOSTEPIN NOT NOVIEW OR PERS PROC RAISE READONLY RECORD RETRY RETURN
    STEP SYSMODULE TEST THEN TO TRAP TRUE TRYNEXT UNDO VAR VIEWONLY WHILE WITH XOR TASK
    NUM BOOL STRING ROBTARGET JOINTTARGET SPEEDDATA ZONEDATA TOOLDATA WOBJDATA TRIGGDATA
    LOADDATA CONFDATA POSE POS ORIENT EXTJOINT FINE V1000 TOOL0 WOBJ0 LOAD0 MAIN TBELL JHOME
    TBRUSHON TBRUSHOFF MOVEL MOVEABSJ TRIGGL TRIGGIO PAINTL SETBRUSH SETDO
""".split())
_IDENT = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,31}$")
#: Characters a comment may carry beyond printable ASCII, spelt out (RAPID files are ISO 8859-1,
#: and a controller's editor shows nothing else reliably).
_SPELT = {"σ": "sigma", "μ": "mu", "µ": "u", "≤": "<=", "≥": ">=", "→": "->", "—": "-",
          "–": "-", "×": "x", "²": "2", "³": "3", "°": "deg"}


def rapid_ident(name: str, what: str = "module") -> str:
    """A valid RAPID identifier for `name`: letters, digits and `_`, starting with a letter, at
    most 32 characters, and none of `RESERVED` (case-insensitive, as RAPID is); a name that is
    one gets the prefix `m_`/`m`."""
    s = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not s or not s[0].isalpha():
        s = "m" + s
    s = s[:32]
    if s.upper() in RESERVED:
        s = ("m_" + s)[:32]
    if not _IDENT.match(s):  # cannot happen for the rules above; never write an invalid name
        raise ValueError(f"cannot make a RAPID identifier of {what} name {name!r}")
    return s


def comment_text(text: object) -> str:
    """`text` made safe for one RAPID comment line: printable ASCII only (a few symbols spelt
    out, others `?`), no control character, newline or line separator, at most 200 characters."""
    s = "".join(_SPELT.get(c, c) for c in str(text))
    s = "".join(c if " " <= c <= "~" else ("?" if c.isprintable() else " ") for c in s)
    s = re.sub(r" {2,}", " ", s).strip()
    return s if len(s) <= 200 else s[:197] + "..."


def _pass_targets(traj: JointTrajectory, T_base_world: np.ndarray, idx: np.ndarray, k: int,
                  max_spacing_m: float) -> list[RapidTarget]:
    """Targets of one pass (sample indices `idx`, in time order) at most `max_spacing_m` apart.

    The first target is where the pass starts (reached by the previous move); each later target
    carries the speed distance ÷ time from the previous target in the trajectory.
    """
    pos_world = traj.tcp_pos_world[idx]
    on = traj.paint_on[idx]
    step = np.linalg.norm(np.diff(pos_world, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    # Keep: first, last, every brush toggle, and enough points in between to respect the spacing.
    toggles = np.flatnonzero(np.diff(on.astype(np.int8)) != 0) + 1
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
        if (j == 0 and on[i]) or (j > 0 and on[i] and not on[keep[j - 1]]):
            brush = 1
        elif j > 0 and not on[i] and on[keep[j - 1]]:
            brush = 0
        if j == len(keep) - 1 and on[i]:
            brush = 0  # the brush goes off where the pass (and its painting) ends
        targets.append(RapidTarget(f"p{k}_{j}", pos_base_mm[j], quats[j],
                                   confdata(traj.q[idx[i]]), float(speed_mm_s[j]), brush))
    return targets


def _via_targets(traj: JointTrajectory, idx: np.ndarray, via_dt_s: float) -> list[tuple[
        np.ndarray, float]]:
    """Joint via points of a move between passes: (q [rad], TCP speed [mm/s]) every `via_dt_s`
    of the trajectory and at its end (the move's start is the previous segment's end)."""
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
        out.append((traj.q[i], max(dist / dt * 1000.0, MIN_VIA_SPEED_MM_S)))
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


def rapid_module(traj: JointTrajectory, robot: Any, module_name: str = "paintcell",
                 style: str = "trigg", max_spacing_m: float = 0.05, via_dt_s: float = 0.2,
                 brush_signal: str = "doBrush",
                 load: tuple[float, np.ndarray] | None = None,
                 validation: list[str] | None = None) -> str:
    """RAPID module text of the whole program in `traj` for `robot`.

    robot: needs `T_world_base` (4, 4) and `T_flange_tcp` (4, 4) for `tooldata`, and (unless
        `load` is given) `mjcf_path` + `flange_site_name` for the tool load.
    style: "trigg" — `TriggL` with `TriggIO` on the digital output `brush_signal`; "paintl" —
        `PaintL` with `SetBrush` (ABB paint option).
    max_spacing_m: the longest stretch of a pass between two exported targets [m].
    via_dt_s: time between joint via points on moves between passes [s].
    load: (mass [kg], centre of mass in the flange frame (3,) [m]) of the tool; None: from the
        robot model.
    validation: header comment lines saying whether and how the program was validated (from
        `validation_header`); None: the header makes no claim about validation.
    """
    if style not in ("trigg", "paintl"):
        raise ValueError(f"unknown RAPID style {style!r}; use 'trigg' or 'paintl'")
    if not _IDENT.match(brush_signal) or brush_signal.upper() in RESERVED:
        raise ValueError(f"brush signal {brush_signal!r} is not a RAPID identifier; name a "
                         "digital output like doBrush")
    for name, v in (("target spacing", max_spacing_m), ("via point interval", via_dt_s)):
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive finite number, got {v!r}")
    T_base_world = np.linalg.inv(np.asarray(robot.T_world_base, float))
    T_flange_tcp = np.asarray(robot.T_flange_tcp, float)
    tq = quat_wxyz_from_matrix(T_flange_tcp[:3, :3])
    tp = T_flange_tcp[:3, 3] * 1000.0
    mass, cog_m = load if load is not None else tool_load(robot)
    cog = np.asarray(cog_m, float) * 1000.0

    decl: list[str] = []
    proc: list[str] = []
    n_via = 0
    n_pass = 0
    segments = program_runs(traj)
    for is_paint, k, idx in segments:
        if is_paint:
            n_pass += 1
            proc.append(f"    ! pass {k}")
            for tg in _pass_targets(traj, T_base_world, idx, k, max_spacing_m):
                p, qq, c = tg.pos_mm, tg.quat_wxyz, tg.conf
                decl.append(f"  CONST robtarget {tg.name} := [[{p[0]:.2f},{p[1]:.2f},{p[2]:.2f}],"
                            f"[{qq[0]:.6f},{qq[1]:.6f},{qq[2]:.6f},{qq[3]:.6f}],"
                            f"[{c[0]},{c[1]},{c[2]},{c[3]}],{_EXT}];")
                decl.append(f"  CONST speeddata v_{tg.name} := [{tg.speed_mm_s:.1f},500,5000,"
                            "1000];")
                if style == "trigg":
                    if tg.brush is None:
                        proc.append(f"    MoveL {tg.name}, v_{tg.name}, {PASS_ZONE}, tBell;")
                    else:
                        trig = "tBrushOn" if tg.brush else "tBrushOff"
                        proc.append(f"    TriggL {tg.name}, v_{tg.name}, {trig}, {PASS_ZONE}, "
                                    "tBell;")
                else:
                    # SetBrush acts from the start of the next move, i.e. at this target.
                    proc.append(f"    PaintL {tg.name}, v_{tg.name}, {PASS_ZONE}, tBell;")
                    if tg.brush is not None:
                        proc.append(f"    SetBrush {tg.brush};")
        else:
            for q, v in _via_targets(traj, idx, via_dt_s):
                name = f"j{n_via}"
                n_via += 1
                decl.append(f"  CONST jointtarget {name} := [[" + ",".join(
                    f"{a:.3f}" for a in np.degrees(q)) + "]," + _EXT + "];")
                decl.append(f"  CONST speeddata v_{name} := [{v:.1f},500,5000,1000];")
                proc.append(f"    MoveAbsJ {name}, v_{name}, {VIA_ZONE}, tBell;")
    # The program ends standing still at home.
    last = proc[-1]
    proc[-1] = re.sub(r", (z\d+), tBell;$", ", fine, tBell;", last)

    name = rapid_ident(module_name)
    L: list[str] = [f"MODULE {name}"]
    L.append(f"  ! Generated by paintcell: {n_pass} passes, cycle time {traj.duration_s:.2f} s.")
    for line in validation or []:
        L.append(f"  ! {comment_text(line)}".rstrip())
    L.append("  ! Targets in the robot base frame (wobj0) [mm]; speeds reproduce the validated "
             "TCP speed between targets.")
    L.append(f"  PERS tooldata tBell := [TRUE,[[{tp[0]:.2f},{tp[1]:.2f},{tp[2]:.2f}],"
             f"[{tq[0]:.6f},{tq[1]:.6f},{tq[2]:.6f},{tq[3]:.6f}]],"
             f"[{mass:.2f},[{cog[0]:.1f},{cog[1]:.1f},{cog[2]:.1f}],[1,0,0,0],0,0,0]];")
    if style == "trigg":
        L.append("  VAR triggdata tBrushOn;")
        L.append("  VAR triggdata tBrushOff;")
    L.append("  CONST jointtarget jHome := [[" + ",".join(
        f"{a:.3f}" for a in np.degrees(traj.q[0])) + "]," + _EXT + "];")
    L.extend(decl)
    L.append("")
    L.append("  PROC main()")
    if style == "trigg":
        L.append(f"    TriggIO tBrushOn, 0 \\DOp:={brush_signal}, 1;")
        L.append(f"    TriggIO tBrushOff, 0 \\DOp:={brush_signal}, 0;")
    L.append("    MoveAbsJ jHome, v1000, fine, tBell;")
    L.extend(proc)
    L.append("  ENDPROC")
    L.append("ENDMODULE")
    return "\n".join(L) + "\n"


def validation_header(checks: Sequence[Any], plan_digest: str,
                      mismatches: Sequence[str] = ()) -> list[str]:
    """Header lines for a module exported from a results folder.

    checks: the thresholds' `Check`s re-derived from the folder's data (`paintcell validate`'s
    computation with the thresholds of its scenario.json), never the verdict metrics.json states;
    mismatches: where metrics.json disagrees with them (a hand-edited or stale file).
    VALIDATED needs at least one check, every check passed with a finite value, and no mismatch;
    it names the digest of the plan (which the folder's plan.json, trajectory and trace carry; a
    digest, not the run id, so reruns export byte-identical modules). Otherwise the header says,
    first, that the run is NOT VALIDATED and why, so nobody loads it on a robot thinking it was
    proven.
    """
    bad = [c for c in checks if not (c.passed and math.isfinite(float(c.value)))]
    if checks and not bad and not mismatches:
        return [f"VALIDATED in MuJoCo simulation: PASS, all {len(checks)} thresholds met "
                f"(plan {plan_digest[:16]})."]
    why = "; ".join([f"{c.name} {c.value:.6g} vs limit {c.limit:.6g}" for c in bad]
                    + [f"metrics.json does not match its data: {m}" for m in mismatches]) \
        or "no threshold checked"
    return ["!!! NOT VALIDATED: THIS RUN FAILED VALIDATION - DO NOT RUN ON A ROBOT AS IS !!!",
            f"Failed: {why}.",
            f"Exported with --allow-failed (plan {plan_digest[:16]})."]


def recorded_mismatches(metrics: dict[str, Any], checks: Sequence[Any], passed: bool,
                        rel_tol: float = 1e-6) -> list[str]:
    """Where a results folder's `metrics.json` disagrees with the checks re-derived from its data:
    its verdict, a check missing or extra, a value off by more than `rel_tol` (NaN, null or text
    included) or a check's verdict. Empty when metrics.json states what the data give."""
    out: list[str] = []
    if metrics.get("passed") is not passed:
        out.append(f"passed = {metrics.get('passed')!r}, the data give {passed}")
    rec = {c.get("name"): c for c in metrics.get("checks") or [] if isinstance(c, dict)}
    for c in checks:
        r = rec.pop(c.name, None)
        if r is None:
            out.append(f"check {c.name!r} is missing")
            continue
        v = r.get("value")
        same = isinstance(v, int | float) and not isinstance(v, bool) and (
            math.isclose(float(v), c.value, rel_tol=rel_tol, abs_tol=1e-12)
            if math.isfinite(c.value) else False)
        if not same and not (v is None and not math.isfinite(c.value)):
            out.append(f"{c.name} = {v!r}, the data give {c.value:.6g}")
        elif r.get("passed") is not c.passed:
            out.append(f"{c.name} passed = {r.get('passed')!r}, the data give {c.passed}")
    out.extend(f"check {n!r} is not one the scenario sets" for n in rec)
    return out
