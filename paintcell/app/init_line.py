"""`paintcell init BODY --line --takt T`: a paint line laid out for a whole car body from its takt
(a body every T seconds), checked by the booth's own program build before anything is written.

- Takt: pitch, conveyor speed, each robot's program plus its carriage's return home, the first
  robot count (`paintcell.booth.line_takt`).
- Allocation: panels to robots by zone (left and right floor robots for the side panels and
  fascias, top robots for the hood, roof and trunk, each top panel cut at the car's centre line
  between the left and right top robots), balanced by estimated time along the car
  (`paintcell.booth.line_allocation`; written as the booth's fixed `[allocation]`).
- Passes (`PASS_AXIS`): a side panel's along its straight direction, a top panel's along the
  car and a fascia's up and down it, so that both step across the car and are cut at the
  centre line between the left and right robots.
- Robots (`paintcell.app.init_line_robots`): IRB 5500s (closed-form IK, which the booth's
  reach checks need) on rails along the conveyor, each centred on its passes' stretch of the car,
  its travel that stretch plus the body's travel while it paints (`TRACK_FACTOR` × half the
  line's travel over a takt at each end, as the booth's own rail margin) and a margin; floor
  rails beside the body for the side zones, wall mounts 3 m up (else elevated rails) for the
  top; the first frame that reaches every pass of its jobs and whose program builds alone.
  Once the line is verified, each robot in turn is tried parked at its station instead of at
  its stretch's end (`shorter_parks`: its program built again, the booth staggered again); the
  homes that shorten the cycle are kept when the booth, building the line again, verifies the
  shorter cycle.
- The body rides on its skid: lifted until its lowest pass is `MIN_TCP_Z_M` above the floor.
- Count: from the first estimate up to `max_robots`, the smallest whose every robot's estimated
  program plus return fits the takt, every robot reaches its passes, and whose programs the
  booth builds (`paintcell.booth.booth_programs.booth_programs`: IK, moves, clearance from the
  whole body, the robots staggered apart) with the booth's cycle plus the carriages' return
  within the takt (`LineTakt.max_cycle_s`); no count: one line naming why each failed.
- The plans are made once, at the fast resolution, without the film refinement (the written
  line refines each panel's film with every pass's duration held, `film_refine_pace`, so the
  durations estimated here are those it plans). The verification, like the written line,
  plans again the passes a robot runs slower than asked under the speeds it reaches
  (`robot_aware_speeds`, at most 5 % longer cycle), so its cycle is that of re-planned
  programs; the run's, from refined plans, can differ a little and is checked against the
  written `max_cycle_time_s`. The written line blends each seam between two panels at its own
  share (`seam_shares = "per seam"`, `paintcell.booth.booth_seams`): only paint switches, not
  the motion.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from paintcell.app.init_layout import TRAJECTORY_TRIES
from paintcell.app.init_line_robots import ProgramBuilder, place_robots, shorter_parks
from paintcell.booth.line_allocation import (
    FLOOR_ROBOTS_PER_SIDE,
    LinePanel,
    RobotShare,
    allocate_line,
    check_body_frame,
    zone_of,
)
from paintcell.booth.line_takt import LineTakt, first_count
from paintcell.core.errors import PaintcellError
from paintcell.core.placement import triple

__all__ = ["Line", "choose_line", "line_panels"]

#: Lowest TCP height of a pass above the floor [m]; the body is lifted (its skid) until its
#: plan clears it (`paintcell init`'s own rule for a part: below it the wrist and the bell sweep
#: the floor).
MIN_TCP_Z_M = 0.6
#: Times half the body's travel over a takt that each end of a rail leaves for tracking [-]
#: (`paintcell.booth.booth_programs`' own rail margin is 1.25 × half the travel).
TRACK_FACTOR = 1.3
#: The line's film spec, written to its `[thresholds]` (each editable there): every panel's
#: executed σ/μ at most `LINE_PANEL_NSD_PCT` [%], the whole body's at most `LINE_BODY_NSD_PCT`
#: [%], and the seams between panels at most `LINE_SEAM_NSD_RATIO` × as uneven as the panels'
#: interiors (σ/μ ratio, `BoothThresholds.max_seam_nsd_ratio`) [-].
LINE_PANEL_NSD_PCT = 8.0
LINE_BODY_NSD_PCT = 7.0
LINE_SEAM_NSD_RATIO = 1.5


#: Planner table of a side panel or fascia: passes along the panel's straight direction (a car
#: side's is along the car: the passes run along the rails; the library door's default passes
#: bring its robot's flange onto the door).
SIDE_PLANNER: dict[str, Any] = {"orientation": "zero-curvature"}


def pass_orientation(mesh: Any, side: Sequence[float], axis: Sequence[float]) -> float:
    """The planner's pass angle [rad] (`paintcell.coverage.start_curve`: about the mean normal
    n̄, from its `tangent_basis` e1 toward e2) that runs a panel's passes along `axis` (body
    frame) projected on the plane ⟂ n̄. mesh: a trimesh in the body frame; side: toward the
    painter (n̄'s sign)."""
    from paintcell.coverage.start_curve import tangent_basis

    n = np.asarray(mesh.area_faces, float) @ np.asarray(mesh.face_normals, float)
    n = n / np.linalg.norm(n)
    if n @ np.asarray(side, float) < 0:
        n = -n
    e1, e2 = tangent_basis(n)
    a = np.asarray(axis, float)
    a = a - (a @ n) * n
    return round(float(np.arctan2(a @ e2, a @ e1)), 6)


#: Pass axis of a zone's panels (body frame): a top panel's passes along the car, a fascia's up
#: and down it, so the passes step across the car and the line cuts the panel at the centre
#: line between its left and right robots (the far half of a hood, a roof, a bumper or a
#: tailgate is beyond one side's reach); None: the straight direction (`SIDE_PLANNER`).
PASS_AXIS: dict[str, tuple[float, float, float] | None] = {
    "top": (1.0, 0.0, 0.0), "fascia": (0.0, 0.0, 1.0), "left": None, "right": None}


def _planner(zone: str, mesh: Any, side: Sequence[float]) -> dict[str, Any]:
    """A panel's planner table by its zone (`PASS_AXIS`)."""
    axis = PASS_AXIS[zone]
    return dict(SIDE_PLANNER) if axis is None else {"orientation": pass_orientation(mesh, side,
                                                                                     axis)}


@dataclass
class Line:
    """The chosen line: the booth as written (mesh parts, robots, fixed allocation, conveyor),
    its takt arithmetic, each robot's share and estimated and built program [s], the real booth
    cycle [s], the first estimate of the count, the panels' pass counts and whole programs'
    total [s], why each count before it failed, each robot's rail frame (why) and the build's
    record."""

    booth: Any
    takt: LineTakt
    shares: list[RobotShare]
    built_s: list[float]
    cycle_s: float
    first_count: int
    n_passes: list[int]
    total_s: float
    failed: list[str] = field(default_factory=list)
    frames: list[str] = field(default_factory=list)
    record: dict[str, Any] = field(default_factory=dict)


def line_panels(pp: Any, reverse: Sequence[bool] | None = None) -> list[LinePanel]:
    """The allocation's view of planned panels (`plan_parts`' plans; part frame = body frame):
    painted side, area-weighted centroid, pass durations and mean y, in the order the robots
    run them (reverse: per panel, its passes run last to first, `BodyPart.reverse`)."""
    out = []
    for i, (surf, plan) in enumerate(zip(pp.surfaces, pp.plans, strict=True)):
        w = surf.vertex_areas / surf.vertex_areas.sum()
        side = np.asarray(surf.regions.painted_direction, float)
        order = slice(None, None, -1 if reverse is not None and reverse[i] else 1)
        out.append(LinePanel(surf.name, triple(side / np.linalg.norm(side)),
                             triple(w @ surf.vertices),
                             np.array([p.duration_s for p in plan.passes])[order],
                             np.array([float(np.mean(p.positions[:, 1]))
                                       for p in plan.passes])[order],
                             (float(surf.vertices[:, 0].min()), float(surf.vertices[:, 0].max()))))
    return out


def top_first(plan: Any) -> bool:
    """Whether a plan's passes run top to bottom (its first pass's mean height ≥ its last's).
    A side panel is painted so: the floor robot starts each panel at its top edge, beside the top
    robots' roof and hood edges, and leaves it low (measured on the generated SUV: the right rear
    door planned bottom to top put the right rear floor robot's turn-arounds 0.5 m above the
    window frame at the end of the door, under the top robot's roof edge, at every start delay
    up to 20 s)."""
    z = [float(np.mean(p.positions[:, 2])) for p in plan.passes]
    return z[0] >= z[-1]


def choose_line(booth: Any, pp: Any, takt: LineTakt, max_robots: int, verify: bool = True,
                say: Callable[[str], None] = print) -> Line:
    """The line (module doc) for `booth` (its mesh parts in the body frame, its conveyor at the
    takt's speed; robots are replaced) planned as `pp` (`plan_parts(booth, fast=True)` with
    `film_refine = false`). verify: build the programs (False: estimates and closed-form reach
    only). Raises PaintcellError (one line, why each count failed)."""
    from paintcell.booth.booth_programs import booth_programs
    from paintcell.core.placement import Placement

    verts = np.concatenate([s.vertices for s in pp.surfaces])
    lps = line_panels(pp)
    check_body_frame(verts.min(0), verts.max(0), [p.side for p in lps],   # y's sign: the side
                     [p.centroid_m for p in lps])
    # the body on its skid: its lowest pass MIN_TCP_Z_M above the floor, as `init` lifts a part
    low = min(float(pl.tcp_frames(i)[:, 2, 3].min()) for pl in pp.plans
              for i in range(len(pl.passes)))
    booth = replace(booth, body_placement=Placement((0.0, 0.0, round(max(0.0, MIN_TCP_Z_M - low),
                                                                      3)), (0.0, 0.0, 0.0)))
    # a side panel's passes top to bottom (`top_first`): reversed where the planner began low
    booth = replace(booth, parts=tuple(
        replace(bp, reverse=not top_first(pl) and zone_of(lp.side, lp.centroid_m) in ("left",
                                                                                      "right"))
        for bp, pl, lp in zip(booth.parts, pp.plans, lps, strict=True)))
    panels = line_panels(pp, [bp.reverse for bp in booth.parts])
    total = sum(takt.program_s([p.durations_s]) for p in panels)
    n0 = first_count(total, takt.takt_s)
    n_passes = [len(p.durations_s) for p in panels]
    track_m = TRACK_FACTOR * 0.5 * takt.conveyor_speed_m_s * takt.takt_s
    failed: list[str] = []
    builder: ProgramBuilder | None = None
    seen: set[tuple[Any, ...]] = set()
    for n in range(1, max_robots + 1):
        if n < n0:
            continue
        try:
            shares = allocate_line(panels, n, takt.robot_cycle_s)
        except ValueError as exc:
            failed.append(f"{n}: {exc}")
            continue
        key = tuple((s.zone, s.jobs) for s in shares)
        if key in seen:      # every zone saturated: no larger count differs
            failed.append(f"{n}–{max_robots}: the zones' jobs cannot be cut further (each panel "
                          f"at most in two pieces, at most {FLOOR_ROBOTS_PER_SIDE} floor robot(s) "
                          f"a side), so more robots give the {len(shares)} robots' line")
            break
        seen.add(key)
        cycles = [takt.robot_cycle_s(s.program_s) for s in shares]
        if max(cycles) > takt.takt_s:
            worst = int(np.argmax(cycles))
            failed.append(f"{n}: the {shares[worst].zone} robot's program + return is "
                          f"{cycles[worst]:.1f} s estimated > takt {takt.takt_s:g} s")
            continue
        say(f"init: {len(shares)} robots, estimated programs + return "
            f"{', '.join(f'{c:.1f}' for c in cycles)} s; placing them")
        if verify and builder is None:
            builder = ProgramBuilder(booth, pp)
        placed = place_robots(booth, pp, shares, track_m, builder)
        if isinstance(placed, str):
            failed.append(f"{n}: {placed}")
            say(f"init: {failed[-1]}")
            continue
        robots, frames, traj = placed
        alloc = {r.name: tuple((j.part, j.first, j.end) for j in s.jobs)
                 for r, s in zip(robots, shares, strict=True)}
        cand = replace(booth, robots=tuple(robots), allocation=alloc, trajectory=traj)
        if not verify:
            return Line(cand, takt, shares, [], float("nan"), n0, n_passes, total, failed,
                        frames)
        say(f"init: building the {len(robots)} robots' programs (IK, moves, body clearance, "
            "staggering)")
        try:
            progs = booth_programs(cand, True, pp)
        except PaintcellError as exc:
            failed.append(f"{n}: the booth cannot build it ({str(exc).split('; ')[0][:160]})")
            say(f"init: {failed[-1]}")
            continue
        cycle = _cycle_s(progs)
        if cycle > takt.max_cycle_s():
            delays = progs.record.get("start_delays_s", [])
            failed.append(f"{n}: the booth's cycle {cycle:.1f} s (start delays "
                          f"{', '.join(f'{d:.1f}' for d in delays)} s) + the carriages' return "
                          f"{takt.robot_cycle_s(cycle) - cycle:.1f} s > takt {takt.takt_s:g} s")
            say(f"init: {failed[-1]}")
            continue
        cand, progs, frames = _parked(cand, progs, pp, frames, say)
        return Line(cand, takt, shares, [float(tr.duration_s) for tr in progs.static],
                    _cycle_s(progs), n0, n_passes, total, failed, frames,
                    {"start_delays_s": progs.record.get("start_delays_s", []),
                     "body_clearance": progs.record.get("body_clearance", {})})
    raise PaintcellError(
        f"no line of up to {max_robots} robots paints a body every {takt.takt_s:g} s "
        f"(conveyor {takt.conveyor_speed_m_s:.3f} m/s, estimated {total:.0f} s of programs, first "
        f"estimate {n0} robots): {' | '.join(failed) or 'the first estimate exceeds the limit'}; "
        "lengthen --takt or raise --max-robots")


def _cycle_s(progs: Any) -> float:
    """The booth's cycle [s]: its staggered programs' common clock."""
    return float(max(len(tr.t_s) for tr in progs.trajs) - 1) * progs.trajs[0].dt_s


def _parked(booth: Any, progs: Any, pp: Any, frames: list[str], say: Callable[[str], None]
            ) -> tuple[Any, Any, list[str]]:
    """The verified line `booth` (programs `progs`) with the homes of `shorter_parks` when the
    booth, building it again, verifies a shorter cycle; else as it was. frames: each robot's why,
    the moved robots' park appended."""
    from paintcell.booth.booth_programs import booth_programs

    moved = shorter_parks(booth, progs, say)
    if moved is None:
        return booth, progs, frames
    parked, why = moved
    say("init: building the robots' programs again with those homes")
    try:
        again = booth_programs(parked, True, pp)
    except PaintcellError as exc:
        say(f"init: kept the homes as placed ({str(exc).split('; ')[0][:160]})")
        return booth, progs, frames
    if _cycle_s(again) >= _cycle_s(progs):
        say(f"init: kept the homes as placed (cycle {_cycle_s(again):.1f} s against "
            f"{_cycle_s(progs):.1f} s)")
        return booth, progs, frames
    return parked, again, [f + (f", {why[r.name]}" if r.name in why else "")
                           for f, r in zip(frames, parked.robots, strict=True)]


def panel_booth(name: str, files: Sequence[Any], takt: LineTakt) -> Any:
    """The booth of the body's panels (each a `MeshPart` in the body frame, placed at the
    identity), robots to be laid out (a placeholder), the conveyor at the takt's speed, as
    `choose_line` plans it (film refinement off: `film_refine_pace` in the written line)."""
    import trimesh

    from paintcell.booth.booth import BodyPart, Booth, BoothRobot, BoothThresholds
    from paintcell.booth.conveyor import Conveyor
    from paintcell.core.placement import Placement

    parts = tuple(BodyPart(f.stem, Placement(), {
        **_planner(zone_of(f.side, (0, 0, 0)), trimesh.load(f.file, force="mesh"), f.side),
        "film_refine": False}, mesh=f) for f in files)
    return Booth(name=name, parts=parts, robots=(BoothRobot("placeholder"),),
                 conveyor=Conveyor(takt.conveyor_speed_m_s, (1.0, 0.0, 0.0)),
                 servo={"gain_inertia": "effective"},
                 trajectory=dict(TRAJECTORY_TRIES[0]),
                 film_refine_pace=True, robot_aware_speeds=True,
                 thresholds=BoothThresholds(min_bell_distance_m=0.6,
                                            max_executed_nsd_pct=LINE_PANEL_NSD_PCT,
                                            max_body_nsd_pct=LINE_BODY_NSD_PCT,
                                            max_seam_nsd_ratio=LINE_SEAM_NSD_RATIO))
