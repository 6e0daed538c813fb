"""IK of a whole program: every pass in order, each seeded with the end of the one before; a robot
on a rail gets its rail position per pass from `paintcell.robots.rail`.

The plan keeps the bell's roll about its axis from one pass to the next
(`paintcell.coverage.plan.CoveragePlan.roll_signs`), so the wrist does not turn at the
turn-arounds; a pass the arm cannot hold that way (a pose out of reach, a joint jump) is solved
half-turned about the spray axis (`paintcell.core.transforms.half_turned`, the same film), and
that solution is kept where it holds the whole pass. The returned results hold the joint paths;
their FK, not the plan's frames, is what the program runs."""

from __future__ import annotations

from collections.abc import Sequence

import numpy.typing as npt

from paintcell.core.transforms import half_turned
from paintcell.robots.ik import IKPathResult, IKSettings, solve_path
from paintcell.robots.rail import solve_rail_paths
from paintcell.robots.robot import Robot

__all__ = ["solve_paths"]


def solve_paths(robot: Robot, paths: Sequence[npt.ArrayLike], q_seed: npt.ArrayLike | None = None,
                free_spin: bool = False, settings: IKSettings | None = None
                ) -> list[IKPathResult]:
    """`solve_path` for each pass in order; each pass is seeded with the end of the previous one.
    A robot on a rail (`robot.rail`) gets `paintcell.robots.rail.solve_rail_paths` (rail position
    per pass).

    The combined report: `ReachabilityReport.concatenate([r.reachability for r in results])`.
    """
    # a 7th, linear axis: paintcell.robots.rail resolves it
    if getattr(robot, "rail", None) is not None:
        return solve_rail_paths(robot, paths, q_seed=q_seed, free_spin=free_spin,
                                settings=settings)
    results = []
    seed = q_seed
    for T in paths:
        res = solve_path(robot, T, q_seed=seed, free_spin=free_spin, settings=settings)
        whole = (len(res.q), 0)
        if not free_spin and _score(res) < whole:
            alt = solve_path(robot, half_turned(T), q_seed=seed, settings=settings)
            if _score(alt) == whole:
                res = alt       # the whole pass held half-turned
        results.append(res)
        seed = res.q[-1]
    return results


def _score(res: IKPathResult) -> tuple[int, int]:
    """How well an IK result holds its pass: (reachable poses, − joint jumps)."""
    return res.reachability.n_reachable, -res.reachability.n_jumps
