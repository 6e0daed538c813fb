"""Front fender: doubly curved B-spline patch, planform 1.0 m (along the car) × 0.7 m (up), radii
≈ 0.45 m over the wheel arch to 1.4 m on top across the car's length, 0.6 m vertically.

Cell: the fender stands upright facing the robot (painted side toward −x, its length horizontal),
centre 1.4 m in front of the origin and 1.0 m up; horizontal passes (the planner's minimal-
altitude choice). The robot stands on a 0.75 m pedestal 1.66 m behind the part, 0.3 m aside
(`robots.placement.find_base_pose` with free spin on the fast and full plans: worst-case margin
0.30 rad). The pass ends turn the bell up to 36° sideways while the 45° bent head trails the
travel direction by 45°: holding the tool's x on the travel direction leaves at best 0.015 rad
of joint margin (J5 at its limit), so IK may spin the bell about its spray axis
(`ik_free_spin`; the bell is nearly round, and validation deposits with the executed tool axes).
Home is a mid-height tuck; the retract from the low last pass backs off 0.3 m first (0.1 m swept
the flange through the part on the way home).
"""

from sim.scenario import Placement, Scenario, Thresholds, facing_robot

SCENARIO = Scenario(
    name="fender",
    part="fender",
    part_placement=Placement(xyz_m=(1.4, 0.0, 1.0), rpy_rad=facing_robot()),
    base=Placement(xyz_m=(-0.26, 0.3, 0.75), rpy_rad=(0.0, 0.0, -0.197)),
    trajectory={"q_home": (0.0, -0.4, 1.0, 0.0, 0.5, 0.0), "ik_free_spin": True,
                "retract_clearance_m": 0.3},
    # Achieved (fast / full): executed σ/μ 7.53 / 7.25 %, loss −0.38 / −0.39 pp (the spun bell
    # lays a slightly more even film than planned), cycle 21.45 / 21.46 s. Limits: σ/μ + ~2
    # points, loss + ~0.5 pp, cycle time + ~15 %.
    thresholds=Thresholds(
        reachability_pct=100.0,
        max_collisions=0,
        max_executed_nsd_pct=9.5,
        max_loss_pp=0.2,
        # The time law departs from the plan by −0.38 pp (a joint-limit slowdown on pass 1 and
        # the free bell spin happen to even the film); hold that departure to ±0.6 pp.
        max_abs_loss_pp=0.6,
        max_cycle_time_s=25.0,
    ),
)

if __name__ == "__main__":
    raise SystemExit(SCENARIO.main())
