"""Placement search time: margin-only ranking vs the motion score
(paintcell.robots.placement_score).

Door plan (library door at 25 mm, the default planner) placed as scenarios/door.toml places it;
`find_base_pose` over the default facing grid (765 bases) for the ABB arm, and over a 2 × 3 grid
for the UR10 (DLS only: every candidate is solved iteratively).
Run: `PYTHONPATH=$PWD .venv/bin/python benchmarks/placement.py`. One figure per line with its unit.
"""

from __future__ import annotations

import time

import numpy as np

from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.paint.applicator import Applicator
from paintcell.robots import load_robot
from paintcell.robots.placement import facing_grid, find_base_pose
from paintcell.surface.parts import get_part


def main() -> None:
    from pathlib import Path

    from paintcell.app.scenario_files import load_scenario

    SCENARIO = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "door.toml")

    surface = get_part("door", resolution_m=0.025)
    plan = plan_coverage(surface, Applicator.default(), PlannerSettings(**SCENARIO.planner))
    T_wp = SCENARIO.part_placement.matrix
    paths = [T_wp @ plan.tcp_frames(i) for i in range(len(plan.passes))]
    speeds = [p.speeds_m_s for p in plan.passes]
    part = (T_wp[:3, :3] @ surface.vertices.T).T + T_wp[:3, 3]
    abb = load_robot("abb_paint")
    times = {}
    for score in ("margin", "motion"):
        t = time.perf_counter()
        T, rep = find_base_pose(abb, paths, score=score, speeds_m_s=speeds,
                                part_points_world=part, floor_z_m=0.0)
        times[score] = time.perf_counter() - t
        m = None if rep.motion is None else rep.motion.get(rep.best)
        print(f"abb_paint door, score={score}: {times[score]:.2f} s, {len(rep.scores)} bases, "
              f"chosen ({T[0, 3]:.2f}, {T[1, 3]:.2f}, {T[2, 3]:.2f}) m"
              + ("" if m is None else f", predicted film excess {m.predicted_film_excess_pct:.2f} %"
                 f", speed ratio {m.speed_ratio:.2f}, clearance {m.clearance_m:.3f} m"))
    print(f"motion / margin time ratio: {times['motion'] / times['margin']:.2f}")
    ur = load_robot("ur10")
    sub = [p[::4] for p in paths]
    centre = np.concatenate([p[:, :3, 3] for p in sub]).mean(axis=0)
    t = time.perf_counter()
    T, rep = find_base_pose(ur, sub, candidates=facing_grid(centre, dx=[-1.0, -0.8],
                                                             dy=[-0.2, 0.0, 0.2],
                                                             heights=[0.5]),
                            n_refine=3, speeds_m_s=[v[::4] for v in speeds], floor_z_m=0.0)
    print(f"ur10 door (every 4th pose), 6 bases: {time.perf_counter() - t:.2f} s; {rep.verdict}")


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
