"""A paint line's allocation of body panels to robots by zone, balanced by estimated time
(`paintcell init BODY --line`, `paintcell.app.init_line`).

Zones: a panel whose painted side points up (side · z ≥ `TOP_MIN_Z`) is a top panel (hood,
roof, trunk); one whose side points more along the car than across it is a fascia, taken by the
floor robots of the car's side it lies on (the lighter side when it straddles the middle); the
rest are side panels, left (side · y > 0) or right. The floor robots of each side take that
side's panels; the top robots sit on elevated rails, alternately left and right, and with two or
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

__all__ = ["TOP_MIN_Z", "LinePanel", "RobotShare", "allocate_line", "zone_of"]

#: A panel whose unit painted-side vector has at least this z is a top panel [-].
TOP_MIN_Z = 0.6
#: A fascia whose centroid lies within this of the car's centre line straddles it [m].
FASCIA_MID_M = 0.1
#: Bisection steps on the longest program (the bound's bracket shrinks 2⁻⁴⁰).
_BISECT_STEPS = 40


@dataclass(frozen=True)
class LinePanel:
    """A panel as the line's allocation sees it: name, painted side (body frame, unit), centroid
    (body frame) [m], its passes' planned durations [s] and their mean y in the body frame [m]
    (execution order)."""

    name: str
    side: tuple[float, float, float]
    centroid_m: tuple[float, float, float]
    durations_s: np.ndarray
    pass_y_m: np.ndarray


@dataclass(frozen=True)
class RobotShare:
    """One robot of the line: zone ("left", "right": floor rails; "top_left", "top_right":
    elevated rails), its jobs (part index, passes [first, end)) front to rear, and its estimated
    program [s]."""

    zone: str
    jobs: tuple[Job, ...]
    program_s: float


def zone_of(side: Sequence[float], centroid_m: Sequence[float]) -> str:
    """"top", "left", "right" or "fascia" (module doc)."""
    s = np.asarray(side, float)
    s = s / np.linalg.norm(s)
    if s[2] >= TOP_MIN_Z:
        return "top"
    if abs(s[0]) > abs(s[1]):
        return "fascia"
    return "left" if s[1] > 0 else "right"


def _pieces(p: int, panel: LinePanel, split: bool) -> list[tuple[str, Job]]:
    """A top panel's (zone, job) pieces: cut at the pass boundary nearest the centre line when
    its passes run along the car (their mean y changes sign once), else whole to the left."""
    n = len(panel.durations_s)
    y = np.asarray(panel.pass_y_m, float)
    if split and n >= 2:
        left = y > 0
        k = int(np.argmax(left != left[0])) if (left != left[0]).any() else 0
        if k > 0 and (left[k:] != left[0]).all():     # one sign change: two sides
            first, second = ("top_left", "top_right") if left[0] else ("top_right", "top_left")
            return [(first, Job(p, 0, k)), (second, Job(p, k, n))]
    return [("top_left" if not split or y.mean() >= 0 else "top_right", Job(p, 0, n))]


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

    for p in fascias:
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
          cost: Callable[[float], float]) -> list[list[Job]] | None:
    """Greedy fill of `jobs` (in order) into at most k robots, each robot's cost(program) ≤
    bound_s; a job that does not fit whole is cut once (module doc). None: more than k needed."""
    groups: list[list[Job]] = [[]]
    queue = list(jobs)
    while queue:
        j = queue.pop(0)
        used = sum(_job_s(panels, x) for x in groups[-1])
        if cost(used + _job_s(panels, j)) <= bound_s:
            groups[-1].append(j)
            continue
        cut = j.first
        if j.first == 0 and j.end == len(panels[j.part].durations_s):  # a whole job: cut once
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
              cost: Callable[[float], float]) -> list[list[Job]]:
    """The zone's jobs in at most k contiguous runs of least longest cost(program) (module
    doc)."""
    hi = cost(sum(_job_s(panels, j) for j in jobs))
    lo = 0.0
    best = _fill(panels, jobs, k, hi, cost)
    assert best is not None                          # one robot takes it all
    for _ in range(_BISECT_STEPS):
        mid = 0.5 * (lo + hi)
        got = _fill(panels, jobs, k, mid, cost)
        if got is None:
            lo = mid
        else:
            hi, best = mid, got
    return [g for g in best if g]


def allocate_line(panels: Sequence[LinePanel], n_robots: int,
                  cost: Callable[[float], float] = float) -> list[RobotShare]:
    """The line's robots for `n_robots` (module doc), zone by zone (left, right, top_left,
    top_right), each zone's robots front to rear. cost(program_s) -> the robot's time per body
    [s] (default: the program itself; `LineTakt.robot_cycle_s` adds the return home), the
    quantity balanced. Fewer robots than zones with work: ValueError. A zone more robots do
    not shorten (one job left per robot, each a piece already) takes no more, so fewer than
    `n_robots` may come back."""
    top_split = sum(zone_of(p.side, p.centroid_m) == "top" for p in panels) > 0
    zones = zone_jobs(panels, top_split and n_robots >= 2)
    if "top_right" in zones and n_robots < len(zones):     # one top robot: the whole top
        zones = zone_jobs(panels, False)
    if n_robots < len(zones):
        raise ValueError(f"{len(zones)} zones have work ({', '.join(zones)}); "
                         f"{n_robots} robots cannot cover them")
    count = dict.fromkeys(zones, 1)
    parts = {z: partition(panels, zones[z], 1, cost) for z in zones}

    def worst(z: str) -> float:
        return max(cost(sum(_job_s(panels, j) for j in g)) for g in parts[z])

    full: set[str] = set()                             # zones more robots do not shorten
    for _ in range(n_robots - len(zones)):
        open_ = [z for z in zones if z not in full]
        if not open_:
            break
        z = max(open_, key=lambda z: (worst(z), -list(zones).index(z)))
        got = partition(panels, zones[z], count[z] + 1, cost)
        if len(got) <= len(parts[z]):
            full.add(z)
            continue
        count[z] += 1
        parts[z] = got
    return [RobotShare(z, tuple(g), float(sum(_job_s(panels, j) for j in g)))
            for z in zones for g in parts[z]]
