"""A paint line's allocation of body panels to robots by zone, balanced by estimated time
(`paintcell init BODY --line`, `paintcell.app.init_line`).

Zones: a panel whose painted side points up (side · z ≥ `TOP_MIN_Z`) is a top panel (hood,
roof, trunk); one whose side points more along the car than across it is a fascia: centred
above every side panel's centroid (a tailgate, above the belt line) it is a top panel, else the
floor robots of each side take their half of it when its passes step across the car (cut at the
pass boundary nearest the centre line: a bumper's far half is beyond one side's reach), or the
whole of it on the side it lies on (the lighter side when it straddles the middle); the rest
are side panels, left (side · y > 0) or right. The floor robots of each side take that side's
panels; the top robots sit on elevated rails, alternately left and right, and with two or
more of them each top panel whose passes run along the car is cut at the pass boundary nearest
the car's centre line, its left piece to the left top robots, its right piece to the right.

Balance: within a zone the robots are lined up along the car and the zone's jobs, front to rear,
are cut into contiguous runs, one per robot — the linear-partition problem — by bisection on the
longest program with a greedy fill (each robot takes jobs while its program stays within the
bound). For whole jobs the greedy fill is exact (filling a robot as far as the bound allows never
needs more robots for the rest), so the bisection finds the least longest program; a job that
does not fit whole is cut once at a pass boundary, its first piece to the robot being filled,
the rest to the next (a booth job of two pieces, as `paintcell.booth.booth.job_options`).
Robots are given to the zone whose longest program is longest, one at a time.

Order: the floor robots of one side share its rail line, each carriage kept to its own stretch
of it (`paintcell.app.init_line_robots.carriage_stretches`), so a side's jobs go to its robots
whole (a side panel's passes run along the car: its pieces, cut at a pass boundary, would lie
at one stretch of the car and put two carriages on it). Every robot runs its jobs front to rear,
so neighbours chase each other down the car and the front one comes to the panel beside the
rear one's first after its own first jobs; the booth's staggering
(`paintcell.booth.booth_stagger`) holds one back where their paces differ. (Run away from each
other, both start at their common boundary and one waits for the other's whole first panel.)
The top robots run theirs rear to front, against the floor robots: a top robot's outer passes
(the roof's, the hood's and the tailgate's edges) lie beside the floor robots' top passes (the
window frames, the fender's and the bumpers' tops); measured on the generated SUV, run front to
rear too the left top robot ended on the tailgate as the rear floor robot ended on the rear
bumper below it, at every start delay up to 20 s; rear to front it kept 0.6 m from both left
floor robots at zero delay.

Why not the booth's enumeration (`paintcell.booth.booth.rank_allocations`): it tries every cut
of every part against every assignment of jobs to robots — a product over the parts of their cut
options times the robots' permutations, a few hundred for four robots and four parts, beyond
10¹² for ten robots and twelve panels. The partition here costs O(jobs · passes) per bisection
step, and keeps each robot on a contiguous stretch of the car, so robots of one side work
neighbouring panels in the order the body passes them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from paintcell.booth.booth import Job, estimate_s

__all__ = ["FLOOR_ROBOTS_PER_SIDE", "TOP_MIN_Z", "LinePanel", "RobotShare", "allocate_line",
           "check_body_frame", "floor_robots_max", "zone_of"]

#: A panel whose unit painted-side vector has at least this z is a top panel [-].
TOP_MIN_Z = 0.6
#: A fascia whose centroid lies within this of the car's centre line straddles it [m].
FASCIA_MID_M = 0.1
#: Most floor robots on one side of the car [robots]: two carriages on one floor rail line, each
#: on its own stretch of it (module doc); a third would stand on a stretch of about a panel.
FLOOR_ROBOTS_PER_SIDE = 2
#: Largest offset of the body's centre line from y = 0 the zones accept [m] (a body is
#: symmetric about it; sides, fascia halves and top pieces are told apart by the sign of y).
CENTRE_TOL_M = 0.05
#: Bisection steps on the longest program (the bound's bracket shrinks 2⁻⁴⁰).
_BISECT_STEPS = 40


@dataclass(frozen=True)
class LinePanel:
    """A panel as the line's allocation sees it: name, painted side (body frame, unit), centroid
    (body frame) [m], its passes' planned durations [s] and their mean y in the body frame [m]
    (execution order), and its extent along the car (min x, max x) [m]."""

    name: str
    side: tuple[float, float, float]
    centroid_m: tuple[float, float, float]
    durations_s: np.ndarray
    pass_y_m: np.ndarray
    x_range_m: tuple[float, float] | None = None

    @property
    def x_span_m(self) -> tuple[float, float]:
        """Its extent along the car [m] (the centroid's x when not given)."""
        return self.x_range_m or (self.centroid_m[0], self.centroid_m[0])


@dataclass(frozen=True)
class RobotShare:
    """One robot of the line: zone ("left", "right": floor rails; "top_left", "top_right":
    elevated rails), its jobs (part index, passes [first, end)) in the order it runs them (a floor
    robot front to rear, a top robot rear to front: module doc), and its estimated program
    [s]."""

    zone: str
    jobs: tuple[Job, ...]
    program_s: float


def check_body_frame(lo_m: Sequence[float], hi_m: Sequence[float],
                     sides: Sequence[Sequence[float]] = (),
                     centroids_m: Sequence[Sequence[float]] = ()) -> None:
    """Refuse (PaintcellError, one line) a body not laid out as the zones read it: its box
    [lo_m, hi_m] (body frame) [m] longer along x than along y; each side panel (`zone_of`; its
    painted side and centroid [m] given) on the side its painted side faces; and, when side
    panels face both ways (a whole body), the box's centre line on y = 0 within `CENTRE_TOL_M`.
    Otherwise panels go to the wrong side, and the top panels and fascias are cut off the centre
    line, silently."""
    from paintcell.core.errors import PaintcellError

    lo, hi = np.asarray(lo_m, float), np.asarray(hi_m, float)
    size = hi - lo
    mid = 0.5 * (lo[1] + hi[1])
    fix = (f"move the body file by {-mid:+.3f} m in y" if abs(mid) > CENTRE_TOL_M
           else "check its axes")
    if size[0] <= size[1]:
        raise PaintcellError(f"the body is {size[0]:.2f} m along x and {size[1]:.2f} m along y: "
                             "a paint line needs the car's length along x (its front toward "
                             "+x, z up); rotate the body file")
    zones = [zone_of(sd, c) for sd, c in zip(sides, centroids_m, strict=True)]
    for z, c in zip(zones, centroids_m, strict=True):
        if z in ("left", "right") and (c[1] > 0) != (z == "left"):
            raise PaintcellError(f"a panel facing {'+' if z == 'left' else '−'}y lies at y = "
                                 f"{c[1]:+.3f} m: a paint line needs the car's centre line on "
                                 f"y = 0 (its y from {lo[1]:+.3f} to {hi[1]:+.3f} m); {fix}")
    if {"left", "right"} <= set(zones) and abs(mid) > CENTRE_TOL_M:
        raise PaintcellError(f"the body's centre line lies at y = {mid:+.3f} m (its y from "
                             f"{lo[1]:+.3f} to {hi[1]:+.3f} m): a paint line needs it on y = 0 "
                             f"(±{CENTRE_TOL_M} m) to tell its sides apart; {fix}")


def zone_of(side: Sequence[float], centroid_m: Sequence[float]) -> str:
    """"top", "left", "right" or "fascia" (module doc)."""
    s = np.asarray(side, float)
    s = s / np.linalg.norm(s)
    if s[2] >= TOP_MIN_Z:
        return "top"
    if abs(s[0]) > abs(s[1]):
        return "fascia"
    return "left" if s[1] > 0 else "right"


def centre_cut(panel: LinePanel) -> int | None:
    """The pass boundary at the car's centre line: k such that passes [0, k) lie on one side
    (their mean y) and [k, n) on the other (the passes step across the car, as a top panel's
    passes along it or a fascia's passes up and down it), else None."""
    left = np.asarray(panel.pass_y_m, float) > 0
    if len(left) < 2 or not (left != left[0]).any():
        return None
    k = int(np.argmax(left != left[0]))
    return k if (left[k:] != left[0]).all() else None


def _pieces(p: int, panel: LinePanel, split: bool, zones: tuple[str, str] = ("top_left",
                                                                             "top_right")
            ) -> list[tuple[str, Job]]:
    """A panel's (zone, job) pieces: cut at the centre line (`centre_cut`) into its left piece
    for zones[0] and its right piece for zones[1], else whole to the left (split False, or the
    passes do not step across the car: the side its passes' mean y lies on)."""
    n = len(panel.durations_s)
    y = np.asarray(panel.pass_y_m, float)
    k = centre_cut(panel) if split else None
    if k is not None:
        first, second = zones if y[0] > 0 else zones[::-1]
        return [(first, Job(p, 0, k)), (second, Job(p, k, n))]
    return [(zones[0] if not split or y.mean() >= 0 else zones[1], Job(p, 0, n))]


def zone_jobs(panels: Sequence[LinePanel], top_split: bool) -> dict[str, list[Job]]:
    """Each zone's jobs, front to rear (the body's +x first). top_split: cut the top panels
    between the left and right top robots (module doc)."""
    zones: dict[str, list[Job]] = {"left": [], "right": [], "top_left": [], "top_right": []}
    fascias = []
    for p, panel in enumerate(panels):
        z = zone_of(panel.side, panel.centroid_m)
        if z == "top":
            for zone, job in _pieces(p, panel, top_split):
                zones[zone].append(job)
        elif z == "fascia":
            fascias.append(p)
        else:
            zones[z].append(Job(p, 0, len(panel.durations_s)))

    def load(z: str) -> float:
        return sum(float(np.sum(panels[j.part].durations_s)) for j in zones[z])

    belt = max((panels[j.part].centroid_m[2] for z in ("left", "right") for j in zones[z]),
               default=np.inf)
    for p in fascias:
        if panels[p].centroid_m[2] > belt and any(zones[z] for z in ("top_left", "top_right")):
            for zone, job in _pieces(p, panels[p], top_split):     # a tailgate: from above
                zones[zone].append(job)
            continue
        if centre_cut(panels[p]) is not None:   # each side's floor robots take their half
            for zone, job in _pieces(p, panels[p], True, ("left", "right")):
                zones[zone].append(job)
            continue
        y = panels[p].centroid_m[1]
        z = "left" if y > FASCIA_MID_M else "right" if y < -FASCIA_MID_M \
            else min(("right", "left"), key=load)
        zones[z].append(Job(p, 0, len(panels[p].durations_s)))
    for jobs in zones.values():
        jobs.sort(key=lambda j: (-panels[j.part].centroid_m[0], j.part, j.first))
    return {z: js for z, js in zones.items() if js}


def _job_s(panels: Sequence[LinePanel], j: Job) -> float:
    return estimate_s(np.asarray(panels[j.part].durations_s[j.first:j.end], float))


def _fill(panels: Sequence[LinePanel], jobs: list[Job], k: int, bound_s: float,
          cost: Callable[[float], float], cut_ok: bool = True) -> list[list[Job]] | None:
    """Greedy fill of `jobs` (in order) into at most k robots, each robot's cost(program) ≤
    bound_s; a job that does not fit whole is cut once (module doc; cut_ok False: never).
    None: more than k needed."""
    groups: list[list[Job]] = [[]]
    queue = list(jobs)
    while queue:
        j = queue.pop(0)
        used = sum(_job_s(panels, x) for x in groups[-1])
        if cost(used + _job_s(panels, j)) <= bound_s:
            groups[-1].append(j)
            continue
        cut = j.first
        if cut_ok and j.first == 0 and j.end == len(panels[j.part].durations_s):  # cut once
            for c in range(j.end - 1, j.first, -1):
                if cost(used + _job_s(panels, Job(j.part, j.first, c))) <= bound_s:
                    cut = c
                    break
        if cut > j.first:
            groups[-1].append(Job(j.part, j.first, cut))
            j = Job(j.part, cut, j.end)
        elif not groups[-1]:
            return None                               # one job alone exceeds the bound
        if len(groups) == k:
            return None
        groups.append([])
        queue.insert(0, j)
    return groups


def partition(panels: Sequence[LinePanel], jobs: list[Job], k: int,
              cost: Callable[[float], float], cut_ok: bool = True) -> list[list[Job]]:
    """The zone's jobs in at most k contiguous runs of least longest cost(program) (module
    doc; cut_ok False: whole jobs only)."""
    hi = cost(sum(_job_s(panels, j) for j in jobs))
    lo = 0.0
    best = _fill(panels, jobs, k, hi, cost, cut_ok)
    assert best is not None                          # one robot takes it all
    for _ in range(_BISECT_STEPS):
        mid = 0.5 * (lo + hi)
        got = _fill(panels, jobs, k, mid, cost, cut_ok)
        if got is None:
            lo = mid
        else:
            hi, best = mid, got
    return [g for g in best if g]


def floor_robots_max(panels: Sequence[LinePanel], jobs: Sequence[Job]) -> int:
    """Most robots a side's floor zone takes (`FLOOR_ROBOTS_PER_SIDE`)."""
    return FLOOR_ROBOTS_PER_SIDE


def allocate_line(panels: Sequence[LinePanel], n_robots: int,
                  cost: Callable[[float], float] = float) -> list[RobotShare]:
    """The line's robots for `n_robots` (module doc), zone by zone (left, right, top_left,
    top_right), each zone's robots front to rear. cost(program_s) -> the robot's time per body
    [s] (default: the program itself; `LineTakt.robot_cycle_s` adds the return home), the
    quantity balanced. Fewer robots than zones with work: ValueError. A zone more robots do
    not shorten (one job left per robot, each a piece already) takes no more, so fewer than
    `n_robots` may come back; a side's floor zone takes at most `floor_robots_max`."""
    top_split = sum(zone_of(p.side, p.centroid_m) == "top" for p in panels) > 0
    zones = zone_jobs(panels, top_split and n_robots >= 2)
    if "top_right" in zones and n_robots < len(zones):     # one top robot: the whole top
        zones = zone_jobs(panels, False)
    if n_robots < len(zones):
        raise ValueError(f"{len(zones)} zones have work ({', '.join(zones)}); "
                         f"{n_robots} robots cannot cover them")
    count = dict.fromkeys(zones, 1)
    parts = {z: partition(panels, zones[z], 1, cost) for z in zones}
    most = {z: floor_robots_max(panels, zones[z]) if z in ("left", "right") else n_robots
            for z in zones}

    def worst(z: str) -> float:
        return max(cost(sum(_job_s(panels, j) for j in g)) for g in parts[z])

    full: set[str] = set()                             # zones more robots do not shorten
    for _ in range(n_robots - len(zones)):
        open_ = [z for z in zones if z not in full]
        if not open_:
            break
        z = max(open_, key=lambda z: (worst(z), -list(zones).index(z)))
        if count[z] >= most[z]:
            full.add(z)
            continue
        got = partition(panels, zones[z], count[z] + 1, cost, z not in ("left", "right"))
        if len(got) <= len(parts[z]):
            full.add(z)
            continue
        count[z] += 1
        parts[z] = got
    return [RobotShare(z, tuple(g[::-1] if z.startswith("top") else g),
                       float(sum(_job_s(panels, j) for j in g)))
            for z in zones for g in parts[z]]
