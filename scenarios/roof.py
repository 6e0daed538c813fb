"""Roof: gently curved 1.6 m × 1.3 m, horizontal (painted side up) at 1.0 m, its long side
across the robot's reach."""

from sim.scenario import Placement, Scenario, Thresholds, facing_robot

SCENARIO = Scenario(
    name="roof",
    part="roof",
    part_placement=Placement(xyz_m=(1.2, 0.0, 1.0), rpy_rad=(0.0, 0.0, 1.5707963267948966)),
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
