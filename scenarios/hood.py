"""Hood: gently doubly curved B-spline, planform 1.5 m (along the car) × 1.2 m, crowned (radii ≈ 6 m
along the car, ≈ 3.5 m across), painted from above.

Cell: the hood lies horizontal, painted side up, centre 1.2 m in front of the origin at 0.8 m, its
1.5 m side across the robot's view; the passes run across the view (1.8 m long with the overspray)
and step away from the robot over 1.33 m (edge passes included). That is the edge of this arm's
envelope: the far pass ends are 1.8 m from the base axis, the near pass 0.23 m from it. The robot
stands on a 0.35 m pedestal 0.9 m behind the hood centre — the `find_base_pose` optimum (0.065 rad
worst-case margin, fixed bell spin) among the bases whose IK samples are free of robot–part and
robot–robot contact: lower bases swing the upper arm through the hood's near edge, higher ones (or
free bell spin) fold the wrist into the robot's own base on the near pass. Passes start and end at
rest: the at-speed exit of the far pass carried the upper arm into the hood's near edge during the
retract; the retract cannot back off (the far pass end is at full stretch). Offsetting the right
side first gives 7 passes (the left first, 8: an extra edge pass 0.26 m outside, out of reach) at
the same predicted σ/μ.
"""

from sim.scenario import Placement, Scenario, Thresholds

SCENARIO = Scenario(
    name="hood",
    part="hood",
    part_placement=Placement(xyz_m=(1.2, 0.0, 0.8), rpy_rad=(0.0, 0.0, 1.5707963267948966)),
    base=Placement(xyz_m=(0.29, 0.0, 0.35)),
    planner={"first_side": "right"},
    trajectory={"q_home": (0.0, -0.6, 0.3, 0.0, 0.9, 0.0), "retract_clearance_m": 0.0,
                "join_at_speed": False},
    # Achieved (fast / full): executed σ/μ 4.77 / 4.58 %, loss −0.03 / −0.03 pp, cycle 34.44 /
    # 34.47 s. Limits: σ/μ + ~2 points, loss + ~0.5 pp, cycle time + ~15 %.
    thresholds=Thresholds(
        reachability_pct=100.0,
        max_collisions=0,
        max_executed_nsd_pct=7.0,
        max_loss_pp=0.5,
        max_abs_loss_pp=0.5,  # a departure from the plan either way
        max_cycle_time_s=40.0,
    ),
)

if __name__ == "__main__":
    raise SystemExit(SCENARIO.main())
