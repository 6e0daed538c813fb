"""Benchmark of `paintcell.motion.trajectory.build_program` on the whole door program (ABB-style
arm).

The door plan comes from
`paintcell.coverage.algorithm.plan_coverage(paintcell.surface.parts.door(), default
bell, default PlannerSettings())` (its planning time is printed but is not part of the trajectory
build). The door stands upright 1.55 m in front of the arm's base, centre 1.1 m high, painted
side toward the robot, passes horizontal (the placement of benchmarks/execution.py). Prints the
build time split by stage (IK, joint-path splines, TOPP-RA, ruckig, 1 kHz sampling + FK +
reports) as the best of `--repeat` runs, and the program's cycle time, paint time and slowdowns.

    .venv/bin/python benchmarks/trajectory.py [--repeat 3] [--turnaround-max-dip 0.05] [--free-spin]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from paintcell.coverage.algorithm import plan_coverage
from paintcell.coverage.coverage_settings import PlannerSettings
from paintcell.motion.trajectory import TrajectorySettings, build_program
from paintcell.paint.applicator import Applicator
from paintcell.robots import load_robot
from paintcell.surface import parts

# The door placement of benchmarks/execution.py: standing, painted side (part +z) toward the
# robot (world −x), part x (extrusion, the pass direction) horizontal along world −y, centre
# 1.55 m ahead and 1.1 m high.
T_WORLD_DOOR = np.array([[0.0, 0.0, -1.0, 1.55],
                         [-1.0, 0.0, 0.0, 0.0],
                         [0.0, 1.0, 0.0, 1.1],
                         [0.0, 0.0, 0.0, 1.0]])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="build repetitions (best is printed)")
    ap.add_argument("--turnaround-max-dip", type=float, default=0.05,
                    help="TrajectorySettings.turnaround_max_dip_m [m] (inf: always direct)")
    ap.add_argument("--free-spin", action="store_true",
                    help="TrajectorySettings.ik_free_spin (bell free to spin about its axis)")
    args = ap.parse_args()

    t0 = time.perf_counter()
    plan = plan_coverage(parts.door(), Applicator.default(), PlannerSettings())
    t_plan = time.perf_counter() - t0
    robot = load_robot("abb_paint")
    settings = TrajectorySettings(turnaround_max_dip_m=args.turnaround_max_dip,
                                  ik_free_spin=args.free_spin)

    best_total, best = np.inf, None
    for _ in range(max(1, args.repeat)):
        t0 = time.perf_counter()
        traj = build_program(robot, plan, T_WORLD_DOOR, settings)
        total = time.perf_counter() - t0
        if total < best_total:
            best_total, best = total, traj
    assert best is not None
    timing = best.meta["timing_s"]
    n_samples = sum(len(p.times_s) for p in plan.passes)
    print(f"door plan: {len(plan.passes)} passes, {n_samples} TCP samples, "
          f"planned paint time {plan.paint_time_s:.3f} s (planning took {t_plan:.2f} s)")
    print(f"build_program total: {1e3 * best_total:.1f} ms (best of {args.repeat})")
    for stage in ("ik", "path", "toppra", "ruckig", "sampling"):
        print(f"  {stage:<9s} {1e3 * timing[stage]:8.1f} ms")
    print(f"program samples: {len(best.t_s)} at {1 / best.dt_s:.0f} Hz")
    print(f"cycle time: {best.duration_s:.3f} s")
    print(f"paint-on time: {best.paint_time_s:.3f} s")
    print(f"max TCP path deviation on passes: {1e3 * best.meta['max_path_deviation_m']:.4f} mm")
    print(f"turn-around dip toward the part: {1e3 * best.meta['turnaround_max_dip_m']:.1f} mm")
    for x in best.meta["turnarounds"]:
        print(f"  after pass {x['after_pass']}: {x['mode']}, dip {1e3 * x['dip_m']:.1f} mm, "
              f"{x['duration_s']:.3f} s (direct move: dip {1e3 * x['direct_dip_m']:.1f} mm, "
              f"{x['direct_duration_s']:.3f} s)")
    for w in best.meta["warnings"]:
        print(f"warning: {w}")
    slow = sum(s["duration_s"] for s in best.slowdowns)
    worst = max((s["max_speed_deficit_pct"] for s in best.slowdowns), default=0.0)
    print(f"slowdowns: {len(best.slowdowns)}, total {slow:.3f} s, worst deficit {worst:.1f} %")
    for s in best.slowdowns:
        print(f"  pass {s['pass']}: s {s['s_start_m']:.3f}-{s['s_end_m']:.3f} m, "
              f"{s['duration_s']:.3f} s, -{s['max_speed_deficit_pct']:.1f} %, "
              f"{', '.join(s['limiting'])}")


if __name__ == "__main__":
    main()
