"""Flat panel 1.0 m × 0.8 m (the paper's planar sheet), upright, facing the robot.

Cell: the panel stands upright 1.4 m in front of the origin, centre 1.0 m above the floor, its
1.0 m side horizontal; horizontal passes at the Fig. 5 planar index width. The robot stands on a
0.5 m pedestal 2.05 m behind the panel: the `robots.placement.find_base_pose` optimum on the
fast and full plans (worst-case margin 0.70 rad). The floor-level optimum (0.57 rad, 2.05 m
back) dragged the elbow and wrist along the floor on the lowest passes. Home is tucked back so
the approach stays clear of the part.
"""

from sim.scenario import Placement, Scenario, Thresholds, facing_robot

SCENARIO = Scenario(
    name="panel",
    part="panel",
    part_placement=Placement(xyz_m=(1.4, 0.0, 1.0), rpy_rad=facing_robot()),
    base=Placement(xyz_m=(-0.65, 0.1, 0.5), rpy_rad=(0.0, 0.0, -0.055)),
    trajectory={"q_home": (0.0, -0.6, 0.3, 0.0, 0.9, 0.0)},
    # Achieved (fast / full): executed σ/μ 4.21 / 4.17 %, loss 0.00 / 0.00 pp, cycle 28.58 /
    # 28.58 s. Limits: σ/μ + ~2 points, loss + 0.5 pp, cycle time + ~15 %.
    thresholds=Thresholds(
        reachability_pct=100.0,
        max_collisions=0,
        max_executed_nsd_pct=6.5,
        max_loss_pp=0.5,
        max_abs_loss_pp=0.5,  # a departure from the plan either way
        max_cycle_time_s=33.0,
    ),
)

if __name__ == "__main__":
    raise SystemExit(SCENARIO.main())
