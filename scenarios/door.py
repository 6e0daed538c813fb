"""SUV front door: extruded outer skin 1.10 m long × 0.80 m profile arc (flat-ish lower panel,
belt-line shoulder of radius ≈ 0.38 m), upright, facing the robot.

Cell: the door stands upright 1.4 m in front of the origin, centre 1.0 m above the floor (door on
a skid), painted side toward the robot. Passes run along the zero-curvature direction
(horizontal, along the extrusion), as the paper's "door along zero curvature" case. The robot
stands on the floor 2.0 m behind the door, 0.2 m aside: the floor-level optimum of
`robots.placement.find_base_pose` on the fast and full plans (worst-case margin 0.62 rad to the
joint limits / wrist singularity; a 0.5 m pedestal would add only 0.13 rad). Home is tucked back
(TCP 0.8 m in front of the base) so the approach stays clear of the part.
`python scenarios/door.py` runs it end to end.
"""

from sim.scenario import Placement, Scenario, Thresholds, facing_robot

SCENARIO = Scenario(
    name="door",
    part="door",
    part_placement=Placement(xyz_m=(1.4, 0.0, 1.0), rpy_rad=facing_robot()),
    base=Placement(xyz_m=(-0.64, 0.2, 0.0), rpy_rad=(0.0, 0.0, -0.111)),
    planner={"orientation": "zero-curvature"},
    trajectory={"q_home": (0.0, -0.6, 0.3, 0.0, 0.9, 0.0)},
    # Achieved (fast / full): executed σ/μ 6.83 / 6.77 %, loss 0.00 / 0.00 pp, cycle 22.59 /
    # 22.59 s. Limits: σ/μ + ~2 points, loss + 0.5 pp, cycle time + ~15 %.
    thresholds=Thresholds(
        reachability_pct=100.0,
        max_collisions=0,
        max_executed_nsd_pct=9.0,
        max_loss_pp=0.5,
        max_abs_loss_pp=0.5,  # a departure from the plan either way
        max_cycle_time_s=26.0,
    ),
)

if __name__ == "__main__":
    raise SystemExit(SCENARIO.main())
