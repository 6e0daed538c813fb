"""IK speed on a door-sized raster: closed-form OPW (vectorized) vs Pinocchio warm-started DLS.

Door-sized path: a vertical 1.1 m × 0.8 m panel 1.4 m in front of the ABB-style arm, 5 horizontal
passes, 400 poses each (2,000 poses, 2.75 mm apart), standoff 0.25 m, spray axis +x.
Run: `.venv/bin/python benchmarks/ik.py`. Each figure is printed on one line with its unit.
"""

from __future__ import annotations

import time

import numpy as np

from paintcell.coverage.plan import tcp_frames
from paintcell.robots import load_robot
from paintcell.robots.ik import dls, opw_branches, solve_path
from paintcell.robots.opw import inverse


def door_paths(n_pass: int = 5, n_per_pass: int = 400) -> list[np.ndarray]:
    paths = []
    for k, z in enumerate(np.linspace(0.6, 1.4, n_pass)):
        y = np.linspace(-0.55, 0.55, n_per_pass)[:: 1 - 2 * (k % 2)]
        P = np.stack([np.full_like(y, 1.15), y, np.full_like(y, z)], axis=1)
        travel = np.tile([0.0, 1.0 - 2 * (k % 2), 0.0], (len(y), 1))
        paths.append(tcp_frames(P, np.tile([1.0, 0.0, 0.0], (len(y), 1)), travel))
    return paths


def best_of(fn, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    robot = load_robot("abb_paint")
    paths = door_paths()
    T_all = np.concatenate(paths)
    n = len(T_all)
    flange = robot.flange_poses(T_all)

    t_opw = best_of(lambda: inverse(robot.opw, flange))
    t_branches = best_of(lambda: [opw_branches(robot, p, robot.q_home) for p in paths])

    # Pinocchio DLS tracking, warm-started from the previous sample (first sample from OPW).
    q0 = solve_path(robot, paths[0][:1]).q[0]

    def track() -> None:
        for p in paths:
            q = q0 if p is paths[0] else q_last[0]
            for T in p:
                q, ok = dls(robot, T, q)
                assert ok
            q_last[0] = q

    q_last = [q0]
    t_dls = best_of(track, repeat=3)
    t_path = best_of(lambda: [solve_path(robot, p) for p in paths], repeat=3)

    print(f"poses: {n}")
    print(f"closed-form OPW, 8 branches, vectorized: {t_opw / n * 1e6:.2f} us/pose")
    print(f"closed-form OPW + continuity/limits per pass: {t_branches / n * 1e6:.2f} us/pose")
    print(f"Pinocchio DLS warm-started from previous sample: {t_dls / n * 1e6:.2f} us/pose")
    print(f"ratio DLS warm / OPW vectorized: {t_dls / t_opw:.1f} x")
    print(f"solve_path (branch choice + DLS refine + report): {t_path / n * 1e6:.2f} us/pose")


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
