"""`paintcell init`'s robot choice: the first robot model, in `AUTO_ROBOTS` order, whose base (or
rail) reaches every pose of the part's fast plan as `init` placed it; or a one-line refusal that
says what each reached and what the user can change (lengths in m).

A floor-standing arm is placed by `paintcell.robots.placement.find_base_pose` (the motion-scored
grid of 765 bases); when `verify` refuses the best-ranked base, the next feasible ones of the
motion ranking (at most `BASES_VERIFIED` in all) are checked with the full IK and `verify`. A
rail robot is placed on a small grid of rail frames running along the part
(world y, the part's longest extent as `init` presents it), the arm facing it (+x): each frame is
scored by `paintcell.robots.rail.best_rail_position` on every pass (closed-form IK, one carriage
position per pass). The frames where every pass is feasible are then checked cheapest first, at
most `RAIL_VERIFIED` of them: the full passes with `solve_rail_paths`, then `verify` (init builds
the joint program there, as `run` will, and sweeps it through the part's collision model:
`init_verify`); the first that passes both is chosen.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from paintcell.core.errors import PaintcellError

__all__ = ["AUTO_ROBOTS", "CellChoice", "choose_cell"]

#: Robots `init --robot auto` tries in turn: the IRB 4600-class floor arm (2.05 m reach), the
#: IRB 5500-class paint robot (2.975 m) on a floor base, the same arm on a rail.
AUTO_ROBOTS = ("abb_paint", "irb5500", "irb5500_rail")
#: Rail frames tried: distance of the rail behind the part's nearest pose [m] and height [m].
RAIL_DISTANCES_M = (0.8, 1.1, 1.4, 1.7, 2.0)
RAIL_HEIGHTS_M = (0.0, 0.5, 1.0)
#: Carriage positions scanned per pass while ranking rail frames (the check uses the default).
RAIL_SCAN = 21
#: At most this many reaching rail frames are checked with the full IK and `verify`.
RAIL_VERIFIED = 3
#: At most this many of a floor arm's bases (best motion score first) are checked with `verify`.
BASES_VERIFIED = 3


@dataclass(frozen=True, eq=False)
class CellChoice:
    """robot: the chosen name; T_base: (4, 4) its base (the rail frame for a rail robot);
    verdict: the placement's one line; why: one line naming what was tried before it."""

    robot: str
    T_base: np.ndarray
    verdict: str
    why: str


def choose_cell(robots: Sequence[str], paths: Sequence[np.ndarray],
                speeds_m_s: Sequence[np.ndarray], part_points_world: np.ndarray,
                part_label: str, floor_z_m: float = 0.0,
                verify: Callable[[str, np.ndarray], str | None] | None = None) -> CellChoice:
    """The first of `robots` that reaches every pose of `paths` ((M, 4, 4) T_world_tcp each).

    speeds_m_s: (M,) planned TCP speeds per path [m/s]; part_points_world: (K, 3) [m] (the motion
    score's clearance); part_label: the part file, for the refusal; verify(robot name, T_base):
    None when the cell is good, else why not in a few words (`init` builds the joint program
    there, as `run` will: a cell whose moves between passes leave the joint limits is not
    chosen). Raises PaintcellError (one line: what each robot reached and what to change) when
    none does.
    """
    from paintcell.robots import load_robot
    from paintcell.robots.placement import find_base_pose

    tried: list[str] = []
    for name in robots:
        robot = load_robot(name)
        if name.endswith("_rail"):
            def check(T_r: np.ndarray, n: str = name) -> str | None:
                return None if verify is None else verify(n, T_r)

            T, ok, verdict = _place_rail(robot, paths, check)
            if ok or not verdict.startswith("rail frames"):
                verify_here = False
            else:                       # every reaching frame's program failed: say why
                tried.append(f"{name} {verdict}")
                continue
        else:
            T, rep = find_base_pose(robot, paths, speeds_m_s=list(speeds_m_s),
                                    part_points_world=part_points_world, floor_z_m=floor_z_m,
                                    check_infeasible=False)
            ok, verdict = rep.feasible, rep.verdict
            verify_here = True
        if ok and verify is not None and verify_here:
            problem = verify(name, T)
            if problem is not None:             # the next bases of the motion ranking
                found, others = _next_base(robot, rep, paths, partial(verify, name))
                if found is None:
                    tried.append(f"{name} reaches every pose but {problem}" + (
                        f" (the next {len(others)} bases: {'; '.join(others)})" if others else ""))
                    continue
                T, verdict = found
                verdict += f" (the best-ranked base's program: {problem})"
        if ok:
            why = f"robot {name}" + (f", because {'; '.join(tried)}" if tried else
                                     f": the first of {', '.join(robots)} to reach every pose")
            return CellChoice(name, T, verdict, why)
        tried.append(f"{name} reaches no base ({_short(verdict)})")
    more = "" if len(robots) > 1 else ", or `--robot auto` to try every robot model"
    raise PaintcellError(
        f"no robot reaches every pose of {part_label} as init places it: {'; '.join(tried)}; "
        f"paint it in pieces (`--pieces 0` …) or patches, or write the cell by hand (robot, "
        f"[base], [part_placement]) in a scenario{more}, or a two-robot booth "
        f"(`[[parts]]` with a `[parts.part]` mesh table, as scenarios/crs_cowling_3_holes.toml "
        f"paints a cowling no robot reaches alone)")


def _next_base(robot: Any, rep: Any, paths: Sequence[np.ndarray],
               verify: Callable[[np.ndarray], str | None]
               ) -> tuple[tuple[np.ndarray, str] | None, list[str]]:
    """((T_base, its verdict) of the first of the next `BASES_VERIFIED` − 1 feasible bases of
    `find_base_pose`'s motion ranking (`rep`, its `PlacementReport`) where every pose is reached
    (full IK) and `verify` passes, or None when none is; why each base before it failed)."""
    from dataclasses import replace

    from paintcell.robots.ik import combined_report
    from paintcell.robots.paths import solve_paths

    ranked = sorted((m.cost, c) for c, m in (rep.motion or {}).items()
                    if m.feasible and c != rep.best)
    why: list[str] = []
    for _, c in ranked[:BASES_VERIFIED - 1]:
        T = rep.candidates[c]
        reach = combined_report(solve_paths(robot.placed(T), list(paths)))
        problem = verify(T) if reach.all_reachable else "it does not reach every pose"
        if problem is None:
            return (T.copy(), replace(rep, best=c, reachability=reach).verdict), why
        why.append(problem)
    return None, why


def _short(verdict: str) -> str:
    """The reachability half of a placement verdict ("…; irb5500: 46/237 poses out of reach")."""
    tail = verdict.rsplit("; ", 1)[-1]
    head = verdict.split(";", 1)[0].replace("NO fully reachable base: ", "")
    return f"{head}; {tail}" if tail != head else head


def _place_rail(robot: object, paths: Sequence[np.ndarray],
                verify: Callable[[np.ndarray], str | None] | None = None
                ) -> tuple[np.ndarray, bool, str]:
    """(T_world_rail (4, 4), every pose reached, one line) for a rail robot (module doc). The
    frames where every pass is feasible are checked in order of cost (full IK, then `verify`,
    at most `RAIL_VERIFIED` of them); the verdict starts "rail frames" when a checked frame
    reached all poses but failed `verify` (returned: the first such frame, whose failure the
    line quotes); none reached: the cheapest frame and its own verdict. The returned frame is
    always the one the line describes."""
    from paintcell.robots.ik import IKSettings, combined_report
    from paintcell.robots.rail import best_rail_position, placed_rail, rail_cost, solve_rail_paths

    st = IKSettings()
    xyz = np.concatenate([np.asarray(p)[:, :3, 3] for p in paths])
    y0 = float(0.5 * (xyz[:, 1].min() + xyz[:, 1].max()))
    ranked: list[tuple[float, int, np.ndarray]] = []
    for d in RAIL_DISTANCES_M:
        for z in RAIL_HEIGHTS_M:
            T = np.eye(4)
            T[:3, 3] = [float(xyz[:, 0].min()) - d, y0, z]
            placed = robot.placed(T)                          # type: ignore[attr-defined]
            pref = placed_rail(placed).arm.q_home
            cost, feasible = 0.0, True
            for p in paths:
                s_m, ok = best_rail_position(placed, np.asarray(p), pref, st, n_scan=RAIL_SCAN)
                if not ok:
                    feasible = False
                    break
                cost += rail_cost(placed, np.asarray(p), s_m, pref, st)[0]
            if feasible:
                ranked.append((cost, len(ranked), T))
    n = len(RAIL_DISTANCES_M) * len(RAIL_HEIGHTS_M)
    if not ranked:
        return np.eye(4), False, f"0/{n} rail frames feasible"
    ranked.sort(key=lambda c: (c[0], c[1]))
    problems: list[tuple[np.ndarray, str]] = []     # (frame, why its program failed)
    first: tuple[np.ndarray, bool, str] | None = None
    checked = ranked[:RAIL_VERIFIED]
    for _, _, T in checked:
        rep = combined_report(solve_rail_paths(robot.placed(T), paths))  # type: ignore[attr-defined]
        p = T[:3, 3]
        verdict = (f"{'rail found' if rep.all_reachable else 'NO fully reachable rail'}: "
                   f"{len(ranked)}/{n} rail frames feasible; rail at x {p[0]:.2f} m, "
                   f"height {p[2]:.2f} m; {rep.verdict}")
        first = first or (T, False, verdict)
        if not rep.all_reachable:
            continue
        problem = None if verify is None else verify(T)
        if problem is None:
            return T, True, verdict
        problems.append((T, problem))
    if problems:
        (T, why), p = problems[0], problems[0][0][:3, 3]
        return T, False, (f"rail frames: {len(ranked)}/{n} feasible, {len(problems)} of the "
                          f"{len(checked)} checked reach every pose but fail (the first, rail at "
                          f"x {p[0]:.2f} m, height {p[2]:.2f} m: {why})")
    assert first is not None  # ranked is not empty
    return first
