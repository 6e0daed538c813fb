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
  Top robots: wall-mounted high beside the body (`WALL_GAPS_M`, `WALL_Z_M`: scenarios/booth.toml's
  roof_r), else elevated rails at the top panels' height less `TOP_DROPS_M`, `TOP_GAPS_M`
  beside them (the first that reaches and builds). Robots of one zone stand
  `STATION_SPACING_M` apart along the line at least.
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
#: Wall-mounted top robots (scenarios/booth.toml's roof_r: the IRB 5500 is a wall-mount paint
#: robot): base plate this far beside the body's side [m], tried in this order, `WALL_Z_M` up
#: [m], J1 horizontal toward the car, the carriage along the line. Above the floor robots'
#: arms, where an elevated rail at the roof's height stands in their way.
WALL_GAPS_M = (1.3, 1.6)
WALL_Z_M = 3.0
#: Home of a wall-mounted robot: carriage at 0, the arm folded over the body (roof_r's).
WALL_HOME = (0.0, 0.0, -0.9, 0.9, 0.0, 0.6, 0.0)
#: How far past its stretch of the car a robot parks when it shares its side [m].
PARK_M = 1.5
#: Least distance between the rail centres of two robots of one zone [m].
STATION_SPACING_M = 1.5
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


def _stations(shares: list[RobotShare], pts: list[np.ndarray]) -> list[float]:
    """Each robot's rail centre along the car [m]: its passes' stretch's middle, the robots of
    one zone (front to rear) at least `STATION_SPACING_M` apart (two on one panel's pieces would
    otherwise stand on one spot), the zone's stations moved back round their middle."""
    centre = [float((p[:, 0].min() + p[:, 0].max()) / 2) for p in pts]
    out = list(centre)
    for zone in dict.fromkeys(s.zone for s in shares):
        idx = [i for i, s in enumerate(shares) if s.zone == zone]
        x = [centre[i] for i in idx]
        for k in range(1, len(x)):
            x[k] = min(x[k], x[k - 1] - STATION_SPACING_M)
        shift = float(np.mean([centre[i] for i in idx]) - np.mean(x))
        for i, xi in zip(idx, x, strict=True):
            out[i] = xi + shift
    return out


def _sides_and_parks(shares: list[RobotShare], stations: list[float]
                     ) -> tuple[list[bool], list[int]]:
    """Each robot's side of the car (True: left) and where it parks along the line (+1: past
    its stretch toward the car's front, −1: toward its rear, 0: at its station). A lone top robot
    stands on the side with fewer floor robots; of the robots on one side, ordered front to
    rear, the front half park toward the front, the rear half toward the rear (a parked arm
    would otherwise stand in a neighbour's stretch, which the booth's staggering cannot clear)."""
    tops = [s.zone for s in shares if s.zone.startswith("top")]
    floor_left = sum(s.zone == "left" for s in shares)
    floor_right = sum(s.zone == "right" for s in shares)
    left = [s.zone == "left" or (s.zone == "top_left" and (len(tops) > 1
                                                           or floor_left <= floor_right))
            for s in shares]
    park = [0] * len(shares)
    for side in (True, False):
        idx = sorted((i for i in range(len(shares)) if left[i] == side),
                     key=lambda i: -stations[i])
        if len(idx) > 1:
            for k, i in enumerate(idx):
                park[i] = 1 if 2 * k + 1 < len(idx) else -1 if 2 * k + 1 > len(idx) else 0
    return left, park


def _robot_frames(share: RobotShare, k: int, pts: np.ndarray, x_m: float, left: bool,
                  park: int, body_lo: np.ndarray, body_hi: np.ndarray, track_m: float
                  ) -> list[tuple[str, Any]]:
    """Candidate robots of one share at station `x_m` on the car's left (or right), parked as
    `park` says (`_sides_and_parks`), in the order tried: (why, `BoothRobot`)."""
    from paintcell.booth.booth import BoothRobot
    from paintcell.core.placement import Placement

    reach = float(np.abs(pts[:, 0] - x_m).max())
    half = round(reach + (PARK_M if park else 0.0) + track_m + RAIL_MARGIN_M, 3)
    # the carriage runs along world +x on the left, −x on the right (the arm faces the car)
    home0 = round(park * (reach + PARK_M) * (1.0 if left else -1.0), 3)
    name = f"{share.zone}_{k}" if share.zone in ("left", "right") \
        else f"top_{'left' if left else 'right'}_{k}"
    out = []
    if share.zone in ("left", "right"):
        for gap in SIDE_GAPS_M:
            box_lo = np.array([x_m, body_lo[1], 0.0])
            box_hi = np.array([x_m, body_hi[1], FLOOR_RAIL_Z_M])
            r = rail_robots(2, box_lo, box_hi, gap, 0.0, ARM)[0 if left else 1]
            out.append((f"floor rail {gap} m beside the body's side, {FLOOR_RAIL_Z_M} m up",
                        replace(r, name=name, home=(home0, *SIDE_HOME[1:]),
                                rail_m=(-half, half))))
        return out
    for gap in WALL_GAPS_M:      # J1 horizontal toward the car, the carriage along the line
        y = float(body_hi[1] + gap if left else body_lo[1] - gap)
        rpy = (0.0, np.pi / 2, -np.pi / 2 if left else np.pi / 2)
        out.append((f"wall-mounted {gap} m beside the body, {WALL_Z_M} m up",
                    BoothRobot(name, f"{ARM}_rail", Placement((round(x_m, 4), round(y, 4),
                                                                WALL_Z_M), rpy),
                               (home0, *WALL_HOME[1:]), (-half, half))))
    for gap in TOP_GAPS_M:
        for drop in TOP_DROPS_M:
            box_lo = np.array([x_m, body_lo[1], pts[:, 2].min()])
            box_hi = np.array([x_m, body_hi[1], pts[:, 2].max()])
            r = rail_robots(2, box_lo, box_hi, gap, drop, ARM)[0 if left else 1]
            out.append((f"elevated rail {gap} m beside the body, {drop} m below its top "
                        "panels' top", replace(r, name=name, home=(home0, *HOME[1:]),
                                               rail_m=(-half, half))))
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
        self.seen: dict[tuple[Any, ...], str | None] = {}    # a share's build, every count

    def build(self, cand: Any, jobs: tuple[Any, ...], traj: dict[str, Any]) -> str | None:
        """Why robot `cand` cannot run `jobs` under `traj` (None: its program builds)."""
        key = (cand, jobs, tuple(sorted(traj.items())))
        if key not in self.seen:
            self.seen[key] = self._build(cand, jobs, traj)
        return self.seen[key]

    def _build(self, cand: Any, jobs: tuple[Any, ...], traj: dict[str, Any]) -> str | None:
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
    pts = [np.concatenate([pp.surfaces[j.part].vertices for j in s.jobs]) for s in shares]
    stations = _stations(shares, pts)
    sides, parks = _sides_and_parks(shares, stations)
    for share, p, x, left, park in zip(shares, pts, stations, sides, parks, strict=True):
        counts[share.zone] = counts.get(share.zone, 0) + 1
        tcp = [pp.plans[j.part].tcp_frames(i) for j in share.jobs for i in range(j.first, j.end)]
        reach = []
        for text, cand in _robot_frames(share, counts[share.zone], p, x, left, park, body_lo,
                                        body_hi, track_m):
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
