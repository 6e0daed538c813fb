"""Roof: gently curved B-spline, planform 1.6 m (along the car) × 1.3 m (across), radii ≈ 8 m along
the car and 3 m → 1 m toward the side rails, painted from above.

Cell: the roof lies horizontal, painted side up, centre 1.2 m in front of the origin at 1.0 m, its
1.6 m side across the view; the 5 passes (1.9 m long with the overspray) step over 1.68 m (the edge
passes sit outside the rails, where the normals lean out). No floor or pedestal base reaches that:
this arm covers ~1.3 m of depth at ±0.95 m across (`find_base_pose`: 0 of 1275 floor/pedestal bases
up to 2 m high feasible with the bell's spin fixed, 0 of 336 on pedestals of 0.5–2 m with free
spin). So the robot hangs inverted from an overhead beam 3.2 m up, over the near third of the roof
(x = 0.8 m) — the `find_base_pose` optimum over inverted bases (free bell spin, worst-case margin
0.14 rad), as ceiling-mounted paint robots paint roofs. The bell may spin about its axis (fixed
spin leaves no feasible base). Home holds the bell pointing down 0.75 m above the roof; the
approach and retract back off 0.3 m (0.1 m swept the flange into the roof). The turn-around after
pass 2 reconfigures the arm and comes ~0.2 m closer to the roof than the pass ends (brush off; no
contact).
"""

from sim.scenario import Placement, Scenario, Thresholds

SCENARIO = Scenario(
    name="roof",
    part="roof",
    part_placement=Placement(xyz_m=(1.2, 0.0, 1.0), rpy_rad=(0.0, 0.0, 1.5707963267948966)),
    base=Placement(xyz_m=(0.8, 0.0, 3.2), rpy_rad=(3.141592653589793, 0.0, 0.0)),
    # Right side first: the pass order (near pass first) the home and clearances are set for.
    planner={"first_side": "right"},
    trajectory={"q_home": (0.0, 0.0, 0.8, 3.14159, 1.6, 0.0), "ik_free_spin": True,
                "approach_clearance_m": 0.3, "retract_clearance_m": 0.3},
    # Achieved (fast / full): executed σ/μ 5.08 / 5.13 %, loss 0.22 / 0.28 pp (the spun bell's
    # footprint is not quite round), cycle 28.76 / 28.77 s. Limits: σ/μ + ~2 points, loss
    # + ~0.5 pp, cycle time + ~15 %.
    thresholds=Thresholds(
        reachability_pct=100.0,
        max_collisions=0,
        max_executed_nsd_pct=7.0,
        max_loss_pp=0.8,
        max_abs_loss_pp=0.8,  # a departure from the plan either way
        max_cycle_time_s=33.0,
    ),
)

if __name__ == "__main__":
    raise SystemExit(SCENARIO.main())
