"""The paper's 1 m-radius cylinder section: 1.2 m long (axis) × 1.2 m of arc (1.2 rad), convex
side painted; passes parallel to the axis (the paper's zero-curvature case).

Cell: the part stands upright facing the robot, its axis horizontal (across the robot's view), its
centre 1.5 m in front of the origin and 1.3 m above the floor, so the lowest edge pass (TCP 0.44 m
up, bell pointing 34° upward) keeps the wrist off the floor. The robot stands on a 0.75 m
pedestal 1.74 m behind the part (`robots.placement.find_base_pose` on the fast and full plans:
worst-case margin 0.35 rad to the joint limits / wrist singularity). Home is a mid-height tuck
(TCP 0.57 m in front of the base at the part's centre height): a high home made the approach to
the bottom pass sweep the wrist through the part.
"""

from sim.scenario import Placement, Scenario, Thresholds, facing_robot

SCENARIO = Scenario(
    name="cylinder",
    part="cylinder_section",
    part_placement=Placement(xyz_m=(1.5, 0.0, 1.3), rpy_rad=facing_robot()),
    base=Placement(xyz_m=(-0.24, 0.2, 0.75), rpy_rad=(0.0, 0.0, -0.124)),
    # Passes parallel to the axis (part x), pinned as an angle and a side so the pass order the
    # cell is laid out for (bottom edge pass first, last at the top) does not hang on the sign
    # convention of principal directions or on a tie between the two offset orders.
    planner={"orientation": 3.141592653589793, "first_side": "right"},
    trajectory={"q_home": (0.0, -0.4, 1.0, 0.0, 0.5, 0.0)},
    # Achieved (fast / full): executed σ/μ 4.65 / 4.69 %, loss 0.01 / 0.01 pp, cycle 23.9 /
    # 23.9 s. Limits: σ/μ + ~2 points, loss a small margin, cycle time + ~15 %.
    thresholds=Thresholds(
        reachability_pct=100.0,
        max_collisions=0,
        max_executed_nsd_pct=7.0,
        max_loss_pp=0.5,
        max_abs_loss_pp=0.5,  # a departure from the plan either way
        max_cycle_time_s=28.0,
    ),
)

if __name__ == "__main__":
    raise SystemExit(SCENARIO.main())
