"""The paper's 1 m-radius cylinder section (1.2 m long, 1.2 m of arc), upright, convex side
toward the robot; passes parallel to the axis (the paper's 2.21 % case)."""

from sim.scenario import Placement, Scenario, Thresholds, facing_robot

SCENARIO = Scenario(
    name="cylinder",
    part="cylinder_section",
    part_placement=Placement(xyz_m=(1.5, 0.0, 1.0), rpy_rad=facing_robot()),
    trajectory={"q_home": (0.0, -0.6, 0.3, 0.0, 0.9, 0.0)},
    thresholds=Thresholds(
        reachability_pct=100.0,
        max_collisions=0,
        max_executed_nsd_pct=20.0,
        max_loss_pp=1.0,
        max_cycle_time_s=60.0,
    ),
)

if __name__ == "__main__":
    raise SystemExit(SCENARIO.main())
