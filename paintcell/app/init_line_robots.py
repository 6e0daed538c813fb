"""Where each robot of a paint line stands (`paintcell init BODY --line`,
`paintcell.app.init_line`): its station along the car, its side, where it parks, the candidate
rail frames of its zone (floor rails for the side panels, wall mounts 3 m up or elevated rails for
the top panels), the first of them from which it reaches every pass of its jobs in closed form
(`paintcell.booth.booth.pass_feasible`) and whose program the booth builds alone
(`ProgramBuilder`: IK, moves, clearance from the whole body).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from paintcell.app.init_layout import ARM, HOME, TRAJECTORY_TRIES, rail_robots
from paintcell.booth.line_allocation import RobotShare
from paintcell.core.errors import PaintcellError

__all__ = ["ProgramBuilder", "place_robots", "shorter_parks"]

#: Carriage top of a floor rail above the floor [m], tried in this order: 0.3 m as
#: scenarios/booth.toml's side robots, then on a pedestal for a robot whose passes reach high at
#: the car's centre line (a tailgate's or a high fascia's half: from 0.3 m up the arm's reach
#: ends short of it).
FLOOR_RAIL_Z_M = (0.3, 0.8, 1.3)
#: Gap between the body's side (its panels' outermost point) and a floor rail frame [m], tried
#: in this order for each carriage height.
SIDE_GAPS_M = (1.9, 1.6, 2.2)
#: Wall-mounted top robots (scenarios/booth.toml's roof_r: the IRB 5500 is a wall-mount paint
#: robot): base plate this far beside the body's side [m], tried in this order, `WALL_Z_M` up
#: [m], J1 horizontal toward the car, the carriage along the line. Above the floor robots'
#: arms, where an elevated rail at the roof's height stands in their way.
WALL_GAPS_M = (1.3, 1.6, 1.9)
WALL_Z_M = 3.0
#: Home of a wall-mounted robot: carriage at 0, the arm folded up over the car's centre line,
#: clear of the floor robots' arms below it at the car's sides (folded beside the body at window
#: height, as roof_r's home, its bell came within 0.1 m of a floor robot's painting a door's
#: window frame). Folded this high, its first moves down to the roof clear the floor robots' at
#: once: on the seed-1 SUV line (the floor robots parked at their stretches' ends) the top
#: robots' staggered starts are 0 and 5.0 s; folded at (−1.4, 0.4) on J2/J3, up to 13.9 s.
WALL_HOME = (0.0, 0.0, -1.5, 0.7, 0.0, 1.0, 0.0)
#: Further rail travel past a robot's stretch of the car, at the end it parks toward, when it
#: shares its side [m] (a top robot parks there, `TOP_PARK_M`).
PARK_M = 1.5
#: How far past its stretch a floor robot parks [m]: at the stretch's end, its arm folded low
#: beside the car's end. Parked 1.5 m further out, every program began and ended with a long
#: carriage move toward its neighbours' work, and the seed-1 SUV line's staggered starts reached
#: 18.5 s (cycle 83.5 s; 68.8 s parked at the stretches' ends, with `WALL_HOME`).
FLOOR_PARK_M = 0.0
#: How far past its stretch a top robot parks [m]: beyond the floor robots of its side, which
#: park at their stretches' ends at about the same x (the stretches of both end at the car's
#: ends), so the two folded arms do not stand over one spot.
TOP_PARK_M = 1.5
#: Where `shorter_parks` tries each robot's home along its rail, as a fraction of its home as
#: placed (1: parked at or past its stretch's end; 0: at its station, the rail's middle) [-].
PARK_TRIES = (0.0,)
#: Least distance between the rail centres of two robots of one zone [m].
STATION_SPACING_M = 1.5
#: Gap beside the top panels' box of an elevated rail frame [m], tried in this order.
TOP_GAPS_M = (1.0, 0.7, 1.3)
#: Drop of an elevated rail frame below the top of its panels [m], tried for each gap.
TOP_DROPS_M = (0.05, 0.35)
#: Further carriage travel at each end of a rail [m].
RAIL_MARGIN_M = 0.3
#: Least distance between the carriages of two floor robots of one side, centre to centre [m]:
#: an IRB 5500's rail carriage is about 1.2 m long (its riser plate; estimate), + 0.3 m between.
CARRIAGE_GAP_M = 1.5
#: Carriage positions a stretch's reach is scanned at, along the rail [m] (the booth's own
#: `paintcell.booth.booth.RAIL_STEP_M`).
STRETCH_STEP_M = 0.12
#: Home of a floor robot: carriage at 0, the arm folded low (the wrist centre ~1.75 m up) so an
#: elevated robot's carriage passes over it (scenarios/booth.toml's side robots).
SIDE_HOME = (0.0, 0.0, -0.6, 0.9, 0.0, 0.6, 0.0)


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
    """Each robot's side of the car (True: left) and where it parks along the line (+1: at or
    past its stretch's end toward the car's front, −1: toward its rear, 0: at its station).
    A lone top robot stands on the side with fewer floor robots; of the robots on one side,
    ordered front to rear, the front half park toward the front, the rear half toward the
    rear, the middle one toward the front on the left and the rear on the right (a parked arm
    would otherwise stand in a neighbour's stretch, which the booth's staggering cannot clear);
    so do two top robots across the car from each other (each folded over the body at home,
    they meet over the centre line). A robot alone on its side with no top partner parks at
    its station."""
    tops = [s.zone for s in shares if s.zone.startswith("top")]
    floor_left = sum(s.zone == "left" for s in shares)
    floor_right = sum(s.zone == "right" for s in shares)
    left = [s.zone == "left" or (s.zone == "top_left" and (len(tops) > 1
                                                           or floor_left <= floor_right))
            for s in shares]
    park = [0] * len(shares)
    for side in (True, False):
        for top in (False, True):       # the floor rail line and the wall or elevated one
            idx = sorted((i for i in range(len(shares)) if left[i] == side
                          and shares[i].zone.startswith("top") == top),
                         key=lambda i: -stations[i])
            for k, i in enumerate(idx):
                # the middle one (and a lone one) toward the front on the left, the rear on the
                # right
                park[i] = 1 if 2 * k + 1 < len(idx) else -1 if 2 * k + 1 > len(idx) \
                    else (1 if side else -1)
            if len(idx) == 1 and not (top and len(tops) > 1):
                park[idx[0]] = 0     # alone on its rail line, no top partner across: at station
    return left, park


def _robot_frames(share: RobotShare, k: int, pts: np.ndarray, x_m: float, left: bool,
                  park: int, body_lo: np.ndarray, body_hi: np.ndarray, track_m: float
                  ) -> list[tuple[str, Any]]:
    """Candidate robots of one share at station `x_m` on the car's left (or right), parked as
    `park` says (`_sides_and_parks`), in the order tried: (why, `BoothRobot`)."""
    from paintcell.booth.booth import BoothRobot
    from paintcell.core.placement import Placement

    reach = float(np.abs(pts[:, 0] - x_m).max())
    park_m = PARK_M if share.zone in ("left", "right") else TOP_PARK_M
    half = round(reach + (park_m if park else 0.0) + track_m + RAIL_MARGIN_M, 3)
    # the carriage runs along world +x on the left, −x on the right (the arm faces the car)
    home_m = reach + (TOP_PARK_M if share.zone not in ("left", "right") else FLOOR_PARK_M)
    home0 = round(park * home_m * (1.0 if left else -1.0), 3)
    name = f"{share.zone}_{k}" if share.zone in ("left", "right") \
        else f"top_{'left' if left else 'right'}_{k}"
    out = []
    if share.zone in ("left", "right"):
        for z in FLOOR_RAIL_Z_M:
            for gap in SIDE_GAPS_M:
                box_lo = np.array([x_m, body_lo[1], 0.0])
                box_hi = np.array([x_m, body_hi[1], z])
                r = rail_robots(2, box_lo, box_hi, gap, 0.0, ARM)[0 if left else 1]
                out.append((f"floor rail {gap} m beside the body's side, {z} m up",
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


def _carriage_x(robot: Any, tcp: list[np.ndarray]) -> np.ndarray:
    """(P, 2) the least and the most world x [m] of the carriage from which the rail robot
    (its rail the planner's) reaches each of the passes `tcp` (P × (M, 4, 4)) in closed form
    (`paintcell.robots.rail.feasible_positions`, every `STRETCH_STEP_M`); NaN where none does."""
    from paintcell.robots.ik import IKSettings
    from paintcell.robots.rail import feasible_positions, travel_m

    (lo, hi), T = travel_m(robot), robot.rail.T_world_rail
    n = max(2, int(np.ceil((hi - lo) / STRETCH_STEP_M)) + 1)
    grid = np.linspace(lo, hi, n)
    x = T[0, 3] + grid * T[0, 1]
    out = np.full((len(tcp), 2), np.nan)
    for i, Tp in enumerate(tcp):
        ok = feasible_positions(robot, Tp, grid, robot.rail.arm.q_home, IKSettings(),
                                need="ends")
        if ok.any():
            out[i] = x[ok].min(), x[ok].max()
    return out


def carriage_stretches(reach_x: list[np.ndarray], gap_m: float = CARRIAGE_GAP_M
                       ) -> list[tuple[float, float]] | str:
    """World x stretches [m] (lower, upper) for the carriages of the robots of one rail line,
    front (largest x) to rear, that keep neighbours `gap_m` apart: robot k's stretch ends where
    robot k + 1's begins + gap, the boundary midway in the room both leave. reach_x: per robot,
    (P, 2) the least and most carriage x from which it reaches each of its passes
    (`_carriage_x`). Returns the stretches (outer ends ±inf), or why two neighbours cannot be
    kept apart."""
    bounds = [np.inf]
    for k in range(len(reach_x) - 1):
        upper = float(np.nanmin(reach_x[k][:, 1])) - gap_m / 2     # robot k: every pass above
        lower = float(np.nanmax(reach_x[k + 1][:, 0])) + gap_m / 2  # robot k+1: every one below
        if not lower <= upper:
            return (f"robots {k + 1} and {k + 2} of one rail line need their carriages within "
                    f"{lower - upper + gap_m:.2f} m of each other (< {gap_m} m apart) to reach "
                    "their passes")
        bounds.append(0.5 * (lower + upper))
    bounds.append(-np.inf)
    return [(bounds[k + 1] + gap_m / 2 if k + 1 < len(reach_x) else -np.inf,
             bounds[k] - gap_m / 2 if k > 0 else np.inf) for k in range(len(reach_x))]


def _on_stretch(cand: Any, x_lo: float, x_hi: float) -> Any:
    """The `BoothRobot` cand with `carriage_m`: the world x stretch [x_lo, x_hi] [m] in its rail
    coordinate, within its rail (None: the whole rail)."""
    T = cand.base.matrix
    d = float(T[0, 1])                              # world x per metre of carriage travel
    s = sorted(((x_lo - T[0, 3]) / d, (x_hi - T[0, 3]) / d))
    lo, hi = max(s[0], cand.rail_m[0]), min(s[1], cand.rail_m[1])
    if lo <= cand.rail_m[0] and hi >= cand.rail_m[1]:
        return cand
    return replace(cand, carriage_m=(round(float(lo), 4), round(float(hi), 4)))


class ProgramBuilder:
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
        planner = load_robots(booth, stretch=True)[0]
        try:
            robot_programs(booth, [planner], self.fin.plans, {0: jobs}, T_wb,
                           self.pp.T_body_parts, {}, [probe])
        except PaintcellError as exc:
            return str(exc).split("; ")[0][:160]
        return None


def place_robots(booth: Any, pp: Any, shares: list[RobotShare], track_m: float,
           builder: ProgramBuilder | None) -> tuple[list[Any], list[str], dict[str, Any]] | str:
    """Each share's robot: the first candidate frame that reaches every pass of its jobs in
    closed form and (with a builder) whose program alone builds, under the first `[trajectory]`
    table of `TRAJECTORY_TRIES` that gives every robot one; or why a share has none."""
    from paintcell.booth.booth import pass_feasible
    from paintcell.booth.booth_programs import load_robots

    body = np.concatenate([s.vertices for s in pp.surfaces])
    T_wb = booth.body_placement.matrix
    body = body @ T_wb[:3, :3].T + T_wb[:3, 3]
    body_lo, body_hi = body.min(0), body.max(0)
    counts: dict[str, int] = {}
    frames = []
    pts = [np.concatenate([pp.surfaces[j.part].vertices for j in s.jobs]) @ T_wb[:3, :3].T
           + T_wb[:3, 3] for s in shares]
    stations = _stations(shares, pts)
    sides, parks = _sides_and_parks(shares, stations)
    tcps = [[T_wb @ pp.plans[j.part].tcp_frames(i) for j in share.jobs
             for i in range(j.first, j.end)] for share in shares]
    cands, nth = [], []
    for share, p, x, left, park in zip(shares, pts, stations, sides, parks, strict=True):
        counts[share.zone] = counts.get(share.zone, 0) + 1
        nth.append(counts[share.zone])
        cands.append(_robot_frames(share, counts[share.zone], p, x, left, park, body_lo,
                                   body_hi, track_m))
    # floor robots of one side share its rail line: each carriage to its own stretch of it
    for zone in ("left", "right"):
        idx = sorted((i for i, s in enumerate(shares) if s.zone == zone),
                     key=lambda i: -stations[i])
        if len(idx) < 2:
            continue
        reach = []
        for i in idx:
            for _, cand in cands[i]:
                robot = load_robots(replace(booth, robots=(cand,), allocation=None),
                                    track_m)[0]
                got = _carriage_x(robot, tcps[i])
                if not np.isnan(got).any():
                    break
            reach.append(got)
        stretch = carriage_stretches(reach)
        if isinstance(stretch, str):
            return f"the {zone} side: {stretch}"
        for i, (x_lo, x_hi) in zip(idx, stretch, strict=True):
            cands[i] = [(text + f", its carriage kept to x {x_lo:+.2f}..{x_hi:+.2f} m"
                         .replace("inf", "∞"), _on_stretch(c, x_lo, x_hi))
                        for text, c in cands[i]]
    for share, tcp, cand_list, k in zip(shares, tcps, cands, nth, strict=True):
        fits: list[tuple[str, Any]] = []         # the rail frames that reach every pass
        missed = None
        owner = [j.part for j in share.jobs for _ in range(j.first, j.end)]
        for text, cand in cand_list:
            robot = load_robots(replace(booth, robots=(cand,), allocation=None), stretch=True)[0]
            ok = [pass_feasible(robot, T) for T in tcp]
            if all(ok):
                fits.append((text, cand))
            elif missed is None or sum(not o for o in ok) < len(missed):
                missed = [o for o, k in zip(owner, ok, strict=True) if not k]
        if not fits:
            names = ", ".join(booth.parts[i].part for i in dict.fromkeys(missed or []))
            return (f"the {share.zone} robot {k} misses {len(missed or [])} "
                    f"pass(es) of {names} from every rail frame tried")
        frames.append(fits)
    if builder is None:
        return [f[0][1] for f in frames], [f[0][0] for f in frames], dict(TRAJECTORY_TRIES[0])
    why = ""
    for traj in TRAJECTORY_TRIES:
        robots, texts = [], []
        for share, fitting in zip(shares, frames, strict=True):
            for text, cand in fitting:
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


def shorter_parks(booth: Any, progs: Any, say: Callable[[str], None] = print
                  ) -> tuple[Any, dict[str, str]] | None:
    """Homes that shorten the staggered cycle of the verified line `booth` (its programs
    `progs`, `paintcell.booth.booth_programs.booth_programs`), or None when none does.

    Where a robot parks decides its program's first and last moves: parked at one end of its
    stretch and starting at the other, it runs the car's length at the start, its arm over its
    neighbours' first panels, and the booth's staggering holds one of them back. Each robot in
    turn (coordinate descent, one sweep) has its home tried at `PARK_TRIES` × its home as
    placed, inside its carriage's stretch; its program is built again on the verified plans
    (the same passes, speeds and rail margin: only the moves to and from home change), the
    booth is staggered again with the others' programs as verified, and the home is kept when
    the cycle (max over the robots of start delay + program) is shorter by a stagger step. A
    home whose program cannot be built, or whose arm cannot be kept apart from a neighbour's,
    is passed over. Returns the booth with the kept homes and, per moved robot, why (one
    phrase)."""
    from paintcell.booth.booth_job_programs import body_probe, load_robots, robot_programs
    from paintcell.booth.booth_programs import start_delays
    from paintcell.booth.booth_stagger import STAGGER_STEP_S

    dt = progs.static[0].dt_s
    shrink = float(progs.record.get("rail_tracking_margin_m", 0.0))
    counts = tuple(len(s.vertices) for s in progs.surfaces)
    T_wb = booth.body_placement.matrix
    robots, trajs = list(booth.robots), list(progs.static)
    models = list(progs.robots)

    def cycle_s(ts: list[Any], ms: list[Any]) -> float:
        d = start_delays(booth, ms, ts)
        return (max(len(t.t_s) + k for t, k in zip(ts, d, strict=True)) - 1) * dt

    best = cycle_s(trajs, models)
    why: dict[str, str] = {}
    for i, r in enumerate(robots):
        lo, hi = r.carriage_m if r.carriage_m is not None else r.rail_m
        for f in PARK_TRIES:
            home0 = float(np.clip(round(f * r.home[0], 3), np.ceil(lo * 1e3) / 1e3,
                                  np.floor(hi * 1e3) / 1e3)) + 0.0      # no −0.0
            if home0 == robots[i].home[0]:
                continue
            cand = replace(r, home=(home0, *r.home[1:]))
            alone = replace(booth, robots=(cand,), allocation=None)
            model = load_robots(alone)[0]
            try:
                traj = robot_programs(alone, load_robots(alone, shrink, stretch=True),
                                      progs.plans, {0: progs.jobs[i]}, T_wb, progs.T_body_parts,
                                      {}, [body_probe(alone, model, progs.body, counts)])[0]
                got = cycle_s([*trajs[:i], traj, *trajs[i + 1:]],
                              [*models[:i], model, *models[i + 1:]])
            except PaintcellError:
                continue
            if got <= best - STAGGER_STEP_S:
                say(f"init: {r.name} parked at {home0:+.2f} m on its rail: staggered cycle "
                    f"{got:.1f} s (was {best:.1f} s)")
                why[r.name] = (f"parked at {home0:+.2f} m on its rail, where the staggered "
                               f"cycle is {got:.1f} s against {best:.1f} s at {r.home[0]:+.2f} m")
                robots[i], trajs[i], models[i], best = cand, traj, model, got
    if not why:
        return None
    return replace(booth, robots=tuple(robots)), why
