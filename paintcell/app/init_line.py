"""`paintcell init BODY --line --takt T`: a paint line laid out for a whole car body from its takt
(a body every T seconds), checked by the booth's own program build before anything is written.

- Takt: pitch, conveyor speed, each robot's program plus its carriage's return home, the first
  robot count (`paintcell.booth.line_takt`).
- Allocation: panels to robots by zone (left and right floor robots for the side panels and
  fascias, top robots for the hood, roof and trunk, each top panel cut at the car's centre line
  between the left and right top robots), balanced by estimated time along the car
  (`paintcell.booth.line_allocation`; written as the booth's fixed `[allocation]`).
- Robots: `ARM` (the booth's IRB 5500: closed-form IK, which the booth's reach checks need) on
  rails along the conveyor, each centred on its passes' stretch of the car, its travel that
  stretch plus the body's travel while it paints (`TRACK_FACTOR` × half the line's travel over a
  takt at each end, as the booth's own rail margin) plus `RAIL_MARGIN_M`. Floor robots: rail
  `FLOOR_RAIL_Z_M` up, a gap of `SIDE_GAPS_M` beside the body's side (the first of those whose
  arm reaches every pass of its jobs in closed form, `paintcell.booth.booth.pass_feasible`).
  Top robots: elevated rails at the top panels' height less `TOP_DROPS_M`, `TOP_GAPS_M` beside
  them (the first that reaches).
- Count: from the first estimate up to `max_robots`, the smallest whose every robot's estimated
  program plus return fits the takt, every robot reaches its passes, and whose programs the
  booth builds (`paintcell.booth.booth_programs.booth_programs`: IK, moves, clearance from the
  whole body, the robots staggered apart) with every built program plus return within the takt;
  no count: one line naming why each failed.
- The plans are made once, at the fast resolution, without the film refinement (the written
  line refines each panel's film with every pass's duration held, `film_refine_pace`, so the
  durations estimated here are those it runs).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from paintcell.app.init_layout import ARM, HOME, TRAJECTORY_TRIES, rail_robots
from paintcell.booth.line_allocation import LinePanel, RobotShare, allocate_line, zone_of
from paintcell.booth.line_takt import LineTakt, first_count
from paintcell.core.errors import PaintcellError

__all__ = ["Line", "choose_line", "line_panels"]

#: Carriage top of a floor rail above the floor [m] (scenarios/booth.toml's side robots).
FLOOR_RAIL_Z_M = 0.3
#: Gap between the body's side (its panels' outermost point) and a floor rail frame [m], tried
#: in this order.
SIDE_GAPS_M = (1.9, 1.6, 2.2)
#: Gap beside the top panels' box of an elevated rail frame [m], tried in this order.
TOP_GAPS_M = (1.0, 0.7, 1.3)
#: Drop of an elevated rail frame below the top of its panels [m], tried for each gap.
TOP_DROPS_M = (0.05, 0.35)
#: Times half the body's travel over a takt that each end of a rail leaves for tracking [-]
#: (`paintcell.booth.booth_programs`' own rail margin is 1.25 × half the travel).
TRACK_FACTOR = 1.3
#: Further carriage travel at each end of a rail [m].
RAIL_MARGIN_M = 0.3
#: Home of a floor robot: carriage at 0, the arm folded low (the wrist centre ~1.75 m up) so an
#: elevated robot's carriage passes over it (scenarios/booth.toml's side robots).
SIDE_HOME = (0.0, 0.0, -0.6, 0.9, 0.0, 0.6, 0.0)


#: Planner table of a side panel or fascia: passes along the panel's straight direction (a car
#: side's is along the car: the passes run along the rails; the library door's default passes
#: bring its robot's flange onto the door).
SIDE_PLANNER: dict[str, Any] = {"orientation": "zero-curvature"}


def _planner(zone: str) -> dict[str, Any]:
    """A panel's planner table by its zone (top panels: the planner's defaults)."""
    return {} if zone == "top" else dict(SIDE_PLANNER)


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


def line_panels(pp: Any) -> list[LinePanel]:
    """The allocation's view of planned panels (`plan_parts`' plans; part frame = body frame):
    painted side, area-weighted centroid, pass durations and mean y."""
    out = []
    for surf, plan in zip(pp.surfaces, pp.plans, strict=True):
        w = surf.vertex_areas / surf.vertex_areas.sum()
        side = np.asarray(surf.regions.painted_direction, float)
        out.append(LinePanel(surf.name, tuple(side / np.linalg.norm(side)),
                             tuple(float(x) for x in w @ surf.vertices),
                             np.array([p.duration_s for p in plan.passes]),
                             np.array([float(np.mean(p.positions[:, 1])) for p in plan.passes])))
    return out


def _robot_frames(share: RobotShare, k: int, pts: np.ndarray, body_lo: np.ndarray,
                  body_hi: np.ndarray, track_m: float) -> list[tuple[str, Any]]:
    """Candidate robots of one share, in the order tried: (why, `BoothRobot`)."""
    lo, hi = pts.min(0), pts.max(0)
    half = round(float((hi[0] - lo[0]) / 2 + track_m + RAIL_MARGIN_M), 3)
    name = f"{share.zone}_{k}"
    out = []
    if share.zone in ("left", "right"):
        left = share.zone == "left"
        for gap in SIDE_GAPS_M:
            box_lo = np.array([lo[0], body_lo[1], 0.0])
            box_hi = np.array([hi[0], body_hi[1], FLOOR_RAIL_Z_M])
            r = rail_robots(2, box_lo, box_hi, gap, 0.0, ARM)[0 if left else 1]
            out.append((f"floor rail {gap} m beside the body's side, {FLOOR_RAIL_Z_M} m up",
                        replace(r, name=name, home=SIDE_HOME, rail_m=(-half, half))))
        return out
    left = share.zone == "top_left"
    for gap in TOP_GAPS_M:
        for drop in TOP_DROPS_M:
            box_lo = np.array([lo[0], body_lo[1], lo[2]])
            box_hi = np.array([hi[0], body_hi[1], hi[2]])
            r = rail_robots(2, box_lo, box_hi, gap, drop, ARM)[0 if left else 1]
            out.append((f"elevated rail {gap} m beside the body, {drop} m below its top "
                        "panels' top", replace(r, name=name, home=HOME, rail_m=(-half, half))))
    return out


class _Builder:
    """Each robot's program alone, as the booth builds it (`paintcell.booth.booth_job_programs`:
    IK, moves, clearance from the whole body), on the plans as the booth finishes them."""

    def __init__(self, booth: Any, pp: Any) -> None:
        from paintcell.booth.booth_plans import finish_plans

        self.fin = finish_plans(booth, pp, pp.plans)
        self.booth, self.pp = booth, pp
        self.part_of = np.concatenate([np.full(len(x.vertices), i)
                                       for i, x in enumerate(pp.surfaces)])

    def build(self, cand: Any, jobs: tuple[Any, ...], traj: dict[str, Any]) -> str | None:
        """Why robot `cand` cannot run `jobs` under `traj` (None: its program builds)."""
        from paintcell.booth.booth_clearance import BodyProbe
        from paintcell.booth.booth_job_programs import robot_programs
        from paintcell.booth.booth_programs import load_robots

        booth = replace(self.booth, robots=(cand,), allocation=None, trajectory=dict(traj))
        robot = load_robots(booth)[0]
        T_wb = booth.body_placement.matrix
        probe = BodyProbe(robot, self.fin.body, T_wb, self.part_of)
        try:
            robot_programs(booth, [robot], self.fin.plans, {0: jobs}, T_wb,
                           self.pp.T_body_parts, {}, [probe])
        except PaintcellError as exc:
            return str(exc).split("; ")[0][:160]
        return None


def _place(booth: Any, pp: Any, shares: list[RobotShare], track_m: float,
           builder: _Builder | None) -> tuple[list[Any], list[str], dict[str, Any]] | str:
    """Each share's robot: the first candidate frame that reaches every pass of its jobs in
    closed form and (with a builder) whose program alone builds, under the first `[trajectory]`
    table of `TRAJECTORY_TRIES` that gives every robot one; or why a share has none."""
    from paintcell.booth.booth import pass_feasible
    from paintcell.booth.booth_programs import load_robots

    body = np.concatenate([s.vertices for s in pp.surfaces])
    body_lo, body_hi = body.min(0), body.max(0)
    counts: dict[str, int] = {}
    frames = []
    for share in shares:
        counts[share.zone] = counts.get(share.zone, 0) + 1
        pts = np.concatenate([pp.surfaces[j.part].vertices for j in share.jobs])
        tcp = [pp.plans[j.part].tcp_frames(i) for j in share.jobs for i in range(j.first, j.end)]
        reach = []
        for text, cand in _robot_frames(share, counts[share.zone], pts, body_lo, body_hi,
                                        track_m):
            robot = load_robots(replace(booth, robots=(cand,), allocation=None))[0]
            if all(pass_feasible(robot, T) for T in tcp):
                reach.append((text, cand))
        if not reach:
            return f"{share.zone}_{counts[share.zone]} reaches no pass set of its jobs from " \
                   "any rail frame tried"
        frames.append(reach)
    if builder is None:
        return [f[0][1] for f in frames], [f[0][0] for f in frames], dict(TRAJECTORY_TRIES[0])
    why = ""
    for traj in TRAJECTORY_TRIES:
        robots, texts = [], []
        for share, reach in zip(shares, frames, strict=True):
            for text, cand in reach:
                bad = builder.build(cand, share.jobs, traj)
                if bad is None:
                    robots.append(cand)
                    texts.append(text)
                    break
                why = why or f"{cand.name}: {bad}"
            else:
                break
        if len(robots) == len(shares):
            return robots, texts, dict(traj)
    return f"no rail frame tried builds every robot's program (first: {why})"


def choose_line(booth: Any, pp: Any, takt: LineTakt, max_robots: int, verify: bool = True,
                say: Callable[[str], None] = print) -> Line:
    """The line (module doc) for `booth` (its mesh parts in the body frame, its conveyor at the
    takt's speed; robots are replaced) planned as `pp` (`plan_parts(booth, fast=True)` with
    `film_refine = false`). verify: build the programs (False: estimates and closed-form reach
    only). Raises PaintcellError (one line, why each count failed)."""
    from paintcell.booth.booth_programs import booth_programs

    panels = line_panels(pp)
    total = sum(takt.program_s([p.durations_s]) for p in panels)
    n0 = first_count(total, takt.takt_s)
    n_passes = [len(p.durations_s) for p in panels]
    track_m = TRACK_FACTOR * 0.5 * takt.conveyor_speed_m_s * takt.takt_s
    failed: list[str] = []
    builder: _Builder | None = None
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
                          f"at most in two pieces), so more robots give the {len(shares)} robots' "
                          "line")
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
            builder = _Builder(booth, pp)
        placed = _place(booth, pp, shares, track_m, builder)
        if isinstance(placed, str):
            failed.append(f"{n}: {placed}")
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
            continue
        built = [float(tr.duration_s) for tr in progs.static]
        real = [takt.robot_cycle_s(b) for b in built]
        if max(real) > takt.takt_s:
            worst = int(np.argmax(real))
            failed.append(f"{n}: {robots[worst].name}'s built program + return is "
                          f"{real[worst]:.1f} s > takt {takt.takt_s:g} s")
            continue
        cycle = float(max(len(tr.t_s) for tr in progs.trajs) - 1) * progs.trajs[0].dt_s
        return Line(cand, takt, shares, built, cycle, n0, n_passes, total, failed, frames,
                    {"start_delays_s": progs.record.get("start_delays_s", []),
                     "body_clearance": progs.record.get("body_clearance", {})})
    raise PaintcellError(
        f"no line of up to {max_robots} robots paints a body every {takt.takt_s:g} s "
        f"(conveyor {takt.conveyor_speed_m_s:.3f} m/s, estimated {total:.0f} s of programs, first "
        f"estimate {n0} robots): {' | '.join(failed) or 'the first estimate exceeds the limit'}; "
        "lengthen --takt or raise --max-robots")


def panel_booth(name: str, files: Sequence[Any], takt: LineTakt) -> Any:
    """The booth of the body's panels (each a `MeshPart` in the body frame, placed at the
    identity), robots to be laid out (a placeholder), the conveyor at the takt's speed, as
    `choose_line` plans it (film refinement off: `film_refine_pace` in the written line)."""
    from paintcell.booth.booth import BodyPart, Booth, BoothRobot, BoothThresholds
    from paintcell.booth.conveyor import Conveyor
    from paintcell.core.placement import Placement

    parts = tuple(BodyPart(f.stem, Placement(), {**_planner(zone_of(f.side, (0, 0, 0))),
                                                 "film_refine": False}, mesh=f) for f in files)
    return Booth(name=name, parts=parts, robots=(BoothRobot("placeholder"),),
                 conveyor=Conveyor(takt.conveyor_speed_m_s, (1.0, 0.0, 0.0)),
                 servo={"gain_inertia": "effective"},
                 trajectory=dict(TRAJECTORY_TRIES[0]),
                 film_refine_pace=True, robot_aware_speeds=False,
                 thresholds=BoothThresholds(min_bell_distance_m=0.6))
