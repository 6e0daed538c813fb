"""SUV front door: extruded outer skin 1.10 m × 0.80 m, upright, facing the robot.

Passes run along the zero-curvature direction (horizontal, along the extrusion), as the paper's
"door along zero curvature" case; `python scenarios/door.py` runs it end to end.
"""

from sim.scenario import Placement, Scenario, Thresholds, facing_robot

SCENARIO = Scenario(
    name="door",
    part="door",
    # Upright, 1.4 m in front of the base, centre 1.0 m above the floor (door on a skid).
    part_placement=Placement(xyz_m=(1.4, 0.0, 1.0), rpy_rad=facing_robot()),
    planner={"orientation": "zero-curvature"},
    # Home tucked back (TCP 0.8 m in front of the base) so the approach stays clear of the part.
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
