"""IK of a whole program: every pass in order, each seeded with the end of the one before; a robot
on a rail gets its rail position per pass from `paintcell.robots.rail`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy.typing as npt

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
        results.append(res)
        seed = res.q[-1]
    return results
