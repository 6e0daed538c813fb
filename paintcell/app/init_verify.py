"""`paintcell init`'s check of a candidate cell, the way `run` will start it: the joint program
built on the fast plan (IK, moves between passes, time law: `pipeline.make_trajectory`), then
swept through the part's collision model — the robot's capsules and the part's convex slabs that
the MuJoCo execution collides, measured with `mujoco.mj_geomDistance` every 10 ms of the program
(`paintcell.booth.booth_clearance.BodyProbe`, the booth's check of a program against the
body).

- A program that comes within `CONTACT_M` of the part meets it (run counts the contact, and the
  poses it links, against honest reachability): the cell is refused, with the robot body, the
  depth and the time in the reason.
- A program that comes within `FOLD_BELOW_M` is built again with `[trajectory] fold_moves = true`
  (approach and retract pull the shoulder and elbow back toward the base before the wrist
  turns), and the folded program is kept when it keeps farther from the part. The margin is
  there because `init` checks the fast plan and a full run plans at 10 mm: on reach_hood_panel
  the fast program's move home passed 81 mm from the part and the full one's went 54 mm into it;
  folded, both kept ≥ 195 mm (`init` wrote no `fold_moves` then: a user added it by hand).
- A program that keeps clear of the part is replayed kinematically in the cell `run` builds
  (robot, part, floor, booth): one that collides there — the arm into itself, the floor — is
  refused like one that meets the part (`_replay`).
- A program that does not build is refused as it is (folding was tried there too: on the shared
  meshes it never made one build, and it cost noether_scan_with_holes 7 s).
- A program that builds but loses more than `MAX_LOST_SHARE` (20 %) of the plan's poses to the
  time law and the joint path (`paintcell.validation.honest_reach` without contacts: slowed
  > 10 % below the planned speed, joint jumps, configuration flips, IK misses) is refused as it
  is (folding changes only the moves to and from home): the run would fail its reachability
  and film. Found on noether_scan_with_holes: a rail frame at 0.000 rad joint margin built, and its
  run lost 215 of 426 poses to slowdowns (σ/μ 68 %, torque 1.75).
- A program that passes all of that but still slows a pose gets the robot-aware speeds `run`
  gives it (`_run_slowdowns`); a pose still slowed > 10 % then fails the run's
  `reachability_pct = 100`, and the cell is refused with the pass where it slows most, how slow,
  and how sharply its planned TCP path turns there. Found on bezier_part_scan_12_pieces: init
  wrote a rail cell whose run failed (23 of 235 poses slowed, σ/μ 17.35 % planned, 29.37 %
  executed): its passes' TCP paths zigzag by up to 22 mm across 2 cm samples on the scan.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from paintcell.core.errors import PaintcellError

__all__ = ["CONTACT_M", "FOLD_BELOW_M", "MAX_CAPPED_NSD_PCT", "MAX_LOST_SHARE",
           "ProgramCheck", "planned_nsd_pct"]

#: Closer than this to the part [m] is contact (the booth's default `body_clearance_m`).
CONTACT_M = 0.01
#: A program closer than this to the part [m] is built again with folded moves (module doc).
FOLD_BELOW_M = 0.1
#: The program is swept in windows of this length [s] (a program through the part stops early).
WINDOW_S = 1.0
#: A program losing more than this share of the plan's poses before execution is refused at
#: once: noether_scan_with_holes' rail loses 191 of 426 here and 215 in its run (σ/μ 68 %). One
#: that loses fewer is judged after the robot-aware speeds `run` applies (`_run_slowdowns`):
#: bezier_part_scan's rail cell loses 22 of 235 here and 23 in its run.
MAX_LOST_SHARE = 0.2
#: A cell whose robot-aware speeds leave the planned film above this σ/μ [%] is refused
#: (`_capped_film`): the spec init writes allows 10 % executed. Found on seeded roofs with a
#: sunroof and an arched fender (`paintcell generate roof_sunroof --seed 6`, `fender_arch --seed
#: 6`): the part planned at 2.6 % σ/μ, the irb5500's J2/J3 capped its speeds to 0.09 m/s in
#: places, the capped plan laid 12.0 % and the run failed on it with no pose slowed.
MAX_CAPPED_NSD_PCT = 9.5
#: The `[trajectory]` tables tried, in turn: the defaults, then folded moves.
TRIES: tuple[dict[str, Any], ...] = ({}, {"fold_moves": True})


class ProgramCheck:
    """`init_cell.choose_cell`'s `verify`: check(robot name, T_base (4, 4)) is None when the cell's
    program builds and keeps clear of the part, else why not in a few words.

    scenario(robot name, T_base, trajectory table): the candidate `Scenario`; plan: the fast
    `CoveragePlan`; surface: the part (its part frame) as planned, placed by the scenarios'
    `part_placement`; run_plan: the plan `run --fast` makes of it, when already made (None: made
    here when needed). `trajectory[name]` holds the `[trajectory]` table of the last cell of that
    robot that passed (`{}` or `{"fold_moves": True}`), `clearance_m[name]` its smallest distance
    to the part [m] (`FOLD_BELOW_M` when nothing came closer), `capped_nsd_pct[name]` the σ/μ
    [%] of the plan `run` makes under that cell's speed caps, when this check made it (a program
    that slows a pose > 10 % on init's plan and on run's; run also caps smaller slowdowns, which
    this does not measure).
    """

    def __init__(self, scenario: Callable[[str, np.ndarray, dict[str, Any]], Any], plan: Any,
                 surface: Any, run_plan: Any = None) -> None:
        self._scenario, self._plan, self._surface = scenario, plan, surface
        # the plan `run --fast` makes (film refined), made once when not given
        self._run_plan: Any = run_plan
        self.trajectory: dict[str, dict[str, Any]] = {}
        self.clearance_m: dict[str, float] = {}
        self.capped_nsd_pct: dict[str, float] = {}

    def __call__(self, name: str, T_base: np.ndarray) -> str | None:
        from paintcell.app.pipeline import load_robot_for, make_trajectory
        from paintcell.booth.booth_clearance import BodyProbe

        robot, probe = None, None
        best: tuple[float, dict[str, Any], Any, Any] | None = None   # gap, table, scenario, program
        failed: list[str] = []                     # why each try is not clear, in order
        for table in TRIES:
            scn = self._scenario(name, T_base, dict(table))
            robot = robot or load_robot_for(scn)
            try:
                traj = make_trajectory(scn, robot, self._plan)
            except PaintcellError as exc:
                failed.append(f"its program fails ({str(exc).split(';')[0]})")
                if not table:       # the default program does not build: refused as it is
                    break
                continue
            lost = _lost(self._plan, traj)
            if lost is not None:    # the passes themselves: folding cannot help
                failed.append(lost)
                break
            probe = probe or BodyProbe(robot, self._surface, scn.part_placement.matrix,
                                       np.zeros(len(self._surface.vertices), int))
            gap, hit = _sweep(probe, traj)
            bump = None if hit is not None else _replay(robot, self._surface,
                                                         scn.part_placement.matrix, traj)
            if bump is not None:
                failed.append(bump)
            elif hit is None:
                if best is None or gap > best[0]:
                    best = (gap, table, scn, traj)
            else:
                d = hit.min_distance_m
                how = f"{-d * 1e3:.0f} mm deep" if d < 0 else f"{d * 1e3:.0f} mm from it"
                body = hit.bodies[0] if hit.bodies else "the arm"
                failed.append(f"its program meets the part ({body} {how} at t = "
                              f"{hit.first_t_s:.1f} s)")
            if gap >= FOLD_BELOW_M:                # nothing within FOLD_BELOW_M: done
                break
        if best is not None:
            slow, capped = self._run_slowdowns(best[2], robot, best[3])
            if slow is not None:            # the passes themselves: folding cannot help
                return slow
            self.clearance_m[name], self.trajectory[name] = best[0], dict(best[1])
            self.capped_nsd_pct.pop(name, None)
            if capped is not None:
                self.capped_nsd_pct[name] = capped
            return None
        if len(failed) == 1 or failed[0] == failed[1]:
            return failed[0]
        return f"{failed[0]}; with fold_moves {failed[1].removeprefix('its ')}"

    def _run_slowdowns(self, scn: Any, robot: Any, traj: Any) -> tuple[str | None, float | None]:
        """(Why `run --fast` would lose poses to the time law on this cell, or None; the σ/μ [%]
        of the robot-aware plan's film when run will cap the plan's speeds, else None). A program of
        init's plan that slows no pose needs nothing more. One that does is built again as `run`
        builds it: on run's own plan (init plans without the film refinement; made once, it does
        not depend on the cell) — reach_hood_panel's irb5500 program slows 18 of 532 poses on
        init's plan and none on run's: accepted there — then, when that one slows a pose too,
        with the robot-aware speeds (`pipeline.robot_aware_run`:
        the slowdowns fed back into the speed QP as caps, kept while the program stays within
        5 % of the first one's cycle). A pose still slowed > 10 % below its planned speed fails
        the run's reachability (init writes `reachability_pct = 100`). Found on
        bezier_part_scan_12_pieces: init's rail cell lost 22 of 235 poses here (under
        `MAX_LOST_SHARE`), the run's robot-aware program was 5.7 % slower and dropped, and the
        run failed with 23 slowed poses (90.21 %, σ/μ 17.35 % planned, 29.37 % executed). On
        noether_wavy_with_hole init's program slows 6 of 71 poses and run's none: judging
        init's own plan would refuse a cell whose run passes."""
        from dataclasses import replace

        from paintcell.app.pipeline import make_plan, make_trajectory, robot_aware_run

        if _honest(self._plan, traj)["n_slowed_poses"] == 0:
            return None, None
        run_scn = replace(scn, fast_planner={})           # the scenario file init writes
        try:
            if self._run_plan is None:
                self._run_plan = make_plan(run_scn, self._surface, fast=True)
            first = make_trajectory(run_scn, robot, self._run_plan)
        except PaintcellError as exc:
            return f"its run's program fails ({str(exc).split(';')[0]})", None
        if _honest(self._run_plan, first)["n_slowed_poses"] == 0:
            return None, None   # the robot-aware rounds only cap what runs < 10 % slow: 32 s saved
        plan2, traj2 = robot_aware_run(run_scn, self._surface, robot, self._run_plan, first,
                                       fast=True)
        h = _honest(plan2, traj2)
        if h["n_slowed_poses"] == 0:
            nsd = planned_nsd_pct(plan2, self._surface)
            return _capped_film(nsd), nsd
        feedback = traj2.meta.get("speed_feedback", {})
        dropped = any("rejected_cycle_s" in r or "failed" in r for r in feedback.get("rounds", []))
        how = (" (the robot-aware program ran > 5 % longer and was dropped)"
               if dropped and not feedback.get("capped_passes") else " after robot-aware speeds")
        return (f"its run slows {h['n_slowed_poses']} of {h['n_poses']} poses > 10 % below the "
                f"planned speed{how}; {_slowest_pass(plan2, traj2)}"), None


def planned_nsd_pct(plan: Any, surface: Any) -> float:
    """σ/μ [%] over the skin's area of the film `plan` lays on the skin of `surface` (the part
    frame)."""
    from paintcell.paint.deposition import thickness
    from paintcell.paint.metrics import uniformity

    skin = surface.region_surface(("skin",))
    film = thickness(plan.applicator, plan.gun_samples(), skin.vertices, skin.normals)
    return float(uniformity(film, skin.vertex_areas).nsd_pct)


def _capped_film(nsd: float) -> str | None:
    """Why the film [σ/μ %, `planned_nsd_pct`] of a robot-aware plan (the speeds capped where
    the robot could not follow them, then re-planned) would fail the spec init writes, or
    None."""
    if nsd <= MAX_CAPPED_NSD_PCT:
        return None
    return (f"its robot-aware speeds (capped where the arm cannot follow the plan) leave the "
            f"planned film at {nsd:.1f} % σ/μ (at most {MAX_CAPPED_NSD_PCT:g} % kept)")


def _lost(plan: Any, traj: Any) -> str | None:
    """Why the program loses more than MAX_LOST_SHARE of the plan's poses before it runs (the
    honest-reachability causes but contact), or None."""
    from types import SimpleNamespace

    from paintcell.validation.honest_reach import honest_reachability

    h = honest_reachability(plan, traj, SimpleNamespace(contacts=()),  # type: ignore[arg-type]
                            traj.meta.get("reachability"))
    if h is None or h["n_lost"] <= MAX_LOST_SHARE * h["n_poses"]:
        return None
    why = h["verdict"].split(" (", 1)[-1].rstrip(")")
    return f"its time law and joint path lose {h['n_lost']} of {h['n_poses']} poses ({why})"


def _slowest_pass(plan: Any, traj: Any) -> str:
    """Where the program slows most: the pass with the most brush-on samples over the part > 10 %
    below the planned speed as the film sees it (÷ the flow the brush table commands, as honest
    reachability reads a slowdown), its slowest such speed ratio there and the sharpest turn of
    its planned TCP path between two samples."""
    from paintcell.motion.joint_trajectory import PAINT
    from paintcell.validation.honest_reach import nearest_pose, pose_arc_lengths

    v = (np.linalg.norm(np.gradient(traj.tcp_pos_world, traj.t_s, axis=0), axis=1)
         / np.asarray(traj.flow, float))
    on = (np.asarray(traj.segment) == PAINT) & (np.asarray(traj.v_tcp_planned) > 1e-9)
    ratio = np.full(len(v), np.inf)
    for i, (p, s) in enumerate(zip(plan.passes, pose_arc_lengths(plan), strict=True)):
        sel = np.flatnonzero(on & (np.asarray(traj.pass_index) == i))
        part = np.asarray(p.on_part, bool)[np.clip(nearest_pose(s, traj.s_pass_m[sel]), 0,
                                                   len(s) - 1)]
        ratio[sel[part]] = v[sel[part]] / traj.v_tcp_planned[sel[part]]
    slow = np.bincount(np.asarray(traj.pass_index)[ratio < 0.9], minlength=len(plan.passes))
    i = int(np.argmax(slow))
    worst = float(ratio[np.asarray(traj.pass_index) == i].min())
    return (f"pass {i} runs at {100 * worst:.0f} % of its planned speed at worst, its TCP path "
            f"turning up to {plan.passes[i].max_turn_deg:.0f}° between two samples")


def _honest(plan: Any, traj: Any) -> dict[str, Any]:
    """`honest_reachability` of a program before it runs (no contacts)."""
    from types import SimpleNamespace

    from paintcell.validation.honest_reach import honest_reachability

    h = honest_reachability(plan, traj, SimpleNamespace(contacts=()),  # type: ignore[arg-type]
                            traj.meta.get("reachability"))
    return h or {"n_slowed_poses": 0, "n_poses": 0, "n_lost": 0}


def _replay(robot: Any, surface: Any, T_world_part: np.ndarray, traj: Any) -> str | None:
    """The program replayed kinematically in the cell `run` builds (robot, part, floor and booth:
    `execution.cell.build_cell`): why it collides (the first event: bodies, depth, time), or None.
    The part sweep above keeps the arm clear of the part; this catches what it does not see — an
    arm folding into itself (a UR10 cell on noether_wavy_with_hole: wrist_2 in the forearm,
    4 mm, 4 events in its run) or the floor."""
    from paintcell.execution.cell import build_cell
    from paintcell.execution.execute import execute
    from paintcell.validation.validate_motion import collision_events

    events = collision_events(execute(build_cell(robot, surface, T_world_part), traj,
                                      mode="kinematic"))
    if not events:
        return None
    e = events[0]
    return (f"its program collides ({e['body1'].split('/')[-1]} with "
            f"{e['body2'].split('/')[-1]}, {e['max_depth_m'] * 1e3:.0f} mm, at t = "
            f"{e['t_start_s']:.1f} s; {len(events)} events)")


def _sweep(probe: Any, traj: Any) -> tuple[float, Any]:
    """(smallest distance to the part [m] up to FOLD_BELOW_M, the `Clearance` at CONTACT_M of
    the first `WINDOW_S` of the program that comes within CONTACT_M, or None). Window by
    window, so that a program through the part stops at its first contact."""
    t = traj.t_s
    cuts = np.searchsorted(t, np.arange(t[0], t[-1], WINDOW_S))
    gap = FOLD_BELOW_M
    for a, b in zip(cuts, [*cuts[1:], len(t) - 1], strict=True):
        c = probe.clearance(traj.q[a:b + 1], t[a:b + 1], FOLD_BELOW_M)
        gap = min(gap, c.min_distance_m)
        if c.min_distance_m < CONTACT_M:
            return gap, probe.clearance(traj.q[a:b + 1], t[a:b + 1], CONTACT_M)
    return gap, None
